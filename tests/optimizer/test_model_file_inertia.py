"""Spatial model files' ``com_offset`` and ``inertia_tensor`` (MODEL_FORMAT "Spatial models"):
read into the body's values, written back exactly, refused with one line naming the field when
the tensor is no rigid body's, has the wrong length, or sits beside ``inertia``, ``gyration`` or
``radius``, and refused in a planar file."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest
import yaml

from impulse_core.evaluate import evaluate
from impulse_core.kinematics.spatial import SPATIAL
from impulse_core.model.tree import SPATIAL_BODY_VALUES, design_vector
from optimizer.cli.main import main
from optimizer.config.model_file import format_model_file, load_model_file, parse_model
from optimizer.errors import ConfigError

REPO = Path(__file__).resolve().parents[2]
TENSOR = [0.004, 0.03, 0.031, 0.0005, -0.0002, 0.0001]


def general() -> dict:
    """configs/spatial_case3.yaml with the thigh's and a toe's centre of mass off their rods and
    full tensors (the thigh's instead of its radius)."""
    data = yaml.safe_load((REPO / "configs" / "spatial_case3.yaml").read_text())
    thigh = data["model"]["bodies"][0]
    del thigh["radius"]
    thigh |= {"com_offset": [0.01, -0.02], "inertia_tensor": list(TENSOR)}
    data["model"]["bodies"][3]["com_offset"] = [0.0, 0.005]  # a rod's tensor, its centre of mass off the axis
    return data


def test_the_keys_are_read_into_the_bodys_values() -> None:
    model = parse_model(general())
    thigh, toe = model.tree.bodies[0], model.tree.bodies[3]
    assert thigh.com_offset == (0.01, -0.02) and thigh.tensor == tuple(TENSOR)
    assert thigh.gyration == 0.0 and thigh.radius == 0.0  # the tensor IS the inertia about the centre of mass
    assert toe.com_offset == (0.0, 0.005) and toe.tensor == (0.0,) * 6 and toe.radius == 0.01
    plain = load_model_file(REPO / "configs" / "spatial_case3.yaml").tree
    assert all(b.com_offset == (0.0, 0.0) and b.tensor == (0.0,) * 6 for b in plain.bodies)


def test_written_and_read_back_exactly(tmp_path: Path) -> None:
    model = parse_model(general())
    text = format_model_file(model)
    assert "inertia_tensor: [0.004, 0.03, 0.031, 0.0005, -0.0002, 0.0001]" in text and "com_offset:" in text
    back = parse_model(yaml.safe_load(text))
    assert back.tree == model.tree
    np.testing.assert_array_equal(design_vector(back.tree, SPATIAL_BODY_VALUES),
                                  design_vector(model.tree, SPATIAL_BODY_VALUES))
    a = evaluate(model.tree, model.scene, space=SPATIAL).external
    b = evaluate(back.tree, back.scene, space=SPATIAL).external
    np.testing.assert_array_equal(a, b)


def _refused(data: dict, tmp_path: Path, capsys, pattern: str) -> None:
    with pytest.raises(ConfigError, match=pattern):
        parse_model(data)
    f = tmp_path / "bad.yaml"
    f.write_text(yaml.safe_dump(data), encoding="utf-8")
    assert main(["evaluate", "--json", str(f)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err


@pytest.mark.parametrize(
    "tensor, message",
    [
        ([0.004, 0.03, 0.031, 0.05, 0.0, 0.0], r"inertia_tensor: .* is not positive semidefinite"),
        ([0.004, 0.03, 0.04, 0.0, 0.0, 0.0], r"inertia_tensor: .* triangle inequality"),
        ([-0.001, 0.03, 0.031, 0.0, 0.0, 0.0], r"inertia_tensor: .* is not positive semidefinite"),
        ([0.004, 0.03, 0.031], r"inertia_tensor: must be \[ixx, iyy, izz, ixy, ixz, iyz\]"),
        ([0.004, 0.03, 0.031, 0.0, 0.0, 0.0, 0.0], r"inertia_tensor: must be \[ixx, iyy, izz, ixy, ixz, iyz\]"),
        (0.03, r"inertia_tensor: must be \[ixx, iyy, izz, ixy, ixz, iyz\]"),
        ([0.004, "x", 0.031, 0.0, 0.0, 0.0], r"inertia_tensor\[1\]"),
        ([0.004, 0.03, float("nan"), 0.0, 0.0, 0.0], r"inertia_tensor\[2\]"),
    ],
)
def test_a_tensor_of_no_rigid_body_is_refused_naming_the_field(tensor, message, tmp_path, capsys) -> None:
    data = general()
    data["model"]["bodies"][0]["inertia_tensor"] = tensor
    _refused(data, tmp_path, capsys, r"model\.bodies\[0\]\." + message)


@pytest.mark.parametrize("key, value", [("inertia", 0.04), ("gyration", 0.3), ("radius", 0.01)])
def test_a_tensor_beside_inertia_gyration_or_radius_is_refused(key, value, tmp_path, capsys) -> None:
    data = general()
    data["model"]["bodies"][0][key] = value
    _refused(data, tmp_path, capsys, rf"model\.bodies\[0\]\.inertia_tensor: .*'inertia_tensor' or '{key}', not both")


@pytest.mark.parametrize("value", [[0.01], [0.01, 0.02, 0.03], "x", [0.01, None]])
def test_a_bad_offset_is_refused_naming_the_field(value, tmp_path, capsys) -> None:
    data = general()
    data["model"]["bodies"][0]["com_offset"] = value
    _refused(data, tmp_path, capsys, r"model\.bodies\[0\]\.com_offset")


@pytest.mark.parametrize(
    "key, value, message",
    [
        ("com_offset", [0.0, 0.01], "a planar body's centre of mass lies in the plane: dz must be 0"),  # [dy, 0] is planar
        ("inertia_tensor", TENSOR, "needs 'model.space: spatial'"),
    ],
)
def test_a_planar_file_refuses_the_keys(key, value, message, tmp_path, capsys) -> None:
    data = yaml.safe_load((REPO / "configs" / "paper_case3.yaml").read_text())
    data["model"]["bodies"][1][key] = copy.copy(value)
    _refused(data, tmp_path, capsys, rf"model\.bodies\[1\]\.{key}: {message}")
