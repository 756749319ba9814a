"""Fuzzed study and model files (seeded): deleted keys, wrong types, NaN/inf, negative values,
unknown keys and garbage YAML. Every invalid file ends with exit 2 and one line naming the field
(or the YAML line), never a traceback; a file that stays valid runs (model files) or loads
(study files)."""

from __future__ import annotations

import copy
import json
import math
import random
import re
from pathlib import Path

import pytest
import yaml

from optimizer.cli.main import main
from optimizer.config.study_config import load_study
from optimizer.errors import ConfigError
from tests.optimizer.conftest import TINY_STUDY_YAML
from tests.optimizer.imports.test_leg import SPATIAL_LEG, rod_urdf

REPO = Path(__file__).resolve().parents[2]
TOP = "scene|model|name|seed|storage|design_space|constraints|objectives|search|leg|notes|reference|the top level"
FIELD = re.compile(rf"^footopt: error: .*(line \d+|: (?:{TOP})[\w.\[\]]*:|: empty file)", re.M)
BAD_VALUES = [None, True, "ten", [], {}, [1, 2, 3], -1.0, 0.0, math.nan, math.inf, -math.inf, 1e308, -5, "1e-3x"]


def _paths(node, prefix=()):
    """Every (path, value) in a nested dict/list."""
    yield prefix, node
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    for k, v in items:
        yield from _paths(v, (*prefix, k))


def _mutate(data, rng: random.Random):
    """One random mutation of a copy of ``data`` (a loaded YAML document), or garbage text."""
    data = copy.deepcopy(data)
    paths = [p for p, _ in _paths(data) if p]
    path = rng.choice(paths)
    *head, last = path
    parent = data
    for k in head:
        parent = parent[k]
    kind = rng.randrange(4)
    if kind == 0 and isinstance(parent, dict):
        del parent[last]
    elif kind == 1 and isinstance(parent, dict):
        parent[str(last) + rng.choice(["x", "_", "s"])] = parent.pop(last)  # a misspelt key
    else:
        parent[last] = rng.choice(BAD_VALUES)
    return data


def _dump(data) -> str:
    text = json.dumps(data, allow_nan=True)  # NaN/Infinity as JSON writes them: not YAML numbers
    return text.replace("NaN", ".nan").replace("-Infinity", "-.inf").replace("Infinity", ".inf")


GARBAGE = ["scene: [1, 2\n", "{{{", "model:\n  bodies:\n    - name: a\n   length: 1\n", "\t- x", ": :", "a: b: c"]


def _check(status: int, err: str) -> None:
    assert "Traceback" not in err, err
    assert status in (0, 1, 2), (status, err)
    if status == 2:
        assert FIELD.search(err), err


@pytest.mark.parametrize("seed", range(4))
def test_fuzzed_model_files(seed: int, tmp_path: Path, capsys) -> None:
    rng = random.Random(seed)
    bases = [yaml.safe_load((REPO / "configs" / f).read_text()) for f in ("paper_case2.yaml", "uneven_terrain.yaml")]
    invalid = 0
    for k in range(60):
        text = rng.choice(GARBAGE) if k % 15 == 0 else _dump(_mutate(rng.choice(bases), rng))
        f = tmp_path / f"m{k}.yaml"
        f.write_text(text, encoding="utf-8")
        status = main(["evaluate", "--json", str(f)])
        _check(status, capsys.readouterr().err)
        invalid += status == 2
    assert invalid >= 20  # the fuzzer does reach the validation


@pytest.mark.parametrize("seed", range(4))
def test_fuzzed_study_files(seed: int, tmp_path: Path, capsys) -> None:
    rng = random.Random(100 + seed)
    base = yaml.safe_load((REPO / "configs" / "quick_study.yaml").read_text())
    base |= yaml.safe_load(TINY_STUDY_YAML)
    invalid = 0
    for k in range(60):
        text = rng.choice(GARBAGE) if k % 15 == 0 else _dump(_mutate(base, rng))
        f = tmp_path / f"s{k}.yaml"
        f.write_text(text, encoding="utf-8")
        try:
            load_study(f)
        except ConfigError:
            status = main(["optimize", str(f), "--out", str(tmp_path / f"run{k}")])
            _check(status, capsys.readouterr().err)
            assert status == 2
            invalid += 1
    assert invalid >= 20


@pytest.mark.parametrize("seed", range(3))
def test_fuzzed_spatial_model_files(seed: int, tmp_path: Path, capsys) -> None:
    """The same on spatial files (rpy, axis, radius, 3-vector approaches; with and without
    friction: the circular cone's solver meets the fuzz too)."""
    rng = random.Random(200 + seed)
    base = yaml.safe_load((REPO / "configs" / "spatial_case3.yaml").read_text())
    frictional = copy.deepcopy(base)
    frictional["scene"]["friction"] = 0.6
    invalid = 0
    for k in range(40):
        f = tmp_path / f"sp{k}.yaml"
        f.write_text(_dump(_mutate(rng.choice([base, frictional]), rng)), encoding="utf-8")
        status = main(["evaluate", "--json", str(f)])
        _check(status, capsys.readouterr().err)
        invalid += status == 2
    assert invalid >= 10


@pytest.mark.parametrize("seed", range(2))
def test_fuzzed_general_spatial_model_files(seed: int, tmp_path: Path, capsys) -> None:
    """The same on spatial files whose bodies carry ``com_offset`` and ``inertia_tensor``."""
    rng = random.Random(300 + seed)
    base = yaml.safe_load((REPO / "configs" / "spatial_case3.yaml").read_text())
    for i, b in enumerate(base["model"]["bodies"]):
        b["com_offset"] = [0.002 * i, -0.001 * i]
        if i % 2 == 0:
            del b["radius"]
            b["inertia_tensor"] = [0.002 * b["mass"], 0.04 * b["mass"], 0.041 * b["mass"], 1e-6, -2e-6, 3e-6]
    invalid = 0
    for k in range(40):
        f = tmp_path / f"g{k}.yaml"
        f.write_text(_dump(_mutate(base, rng)), encoding="utf-8")
        status = main(["evaluate", "--json", str(f)])
        _check(status, capsys.readouterr().err)
        invalid += status == 2
    assert invalid >= 10


def _landing_model(duration: float = 0.005) -> dict:
    """configs/landing_case3.yaml landing for ``duration`` s (each run well under a second)."""
    data = yaml.safe_load((REPO / "configs" / "landing_case3.yaml").read_text())
    data["scene"]["duration"] = duration
    return data


@pytest.mark.parametrize("key, value", [("angle", 1e12), ("angle", -1e308), ("rest", 1e12)])
def test_a_far_angle_is_refused_not_run_forever(key: str, value: float, tmp_path: Path, capsys) -> None:
    """Found by the fuzzer: a joint at 1e12 rad (finite) made a 5 ms landing run for ever, its
    steps lost in the angle's rounding; a rest there took seconds to fail."""
    data = _landing_model()
    data["model"]["bodies"][7][key] = value
    f = tmp_path / "far.yaml"
    f.write_text(_dump(data), encoding="utf-8")
    assert main(["evaluate", "--json", str(f)]) == 2
    err = capsys.readouterr().err
    assert f"model.bodies[7].{key}: must be an angle within [-1e+06, 1e+06] rad" in err, err
    study = yaml.safe_load(TINY_STUDY_YAML) | {"leg": {"thigh": {"angle": value}}}
    f.write_text(_dump(study), encoding="utf-8")
    with pytest.raises(ConfigError, match=r"leg.thigh.angle: must be an angle within"):
        load_study(f)


def test_a_urdf_loop_is_refused_not_walked_for_ever(tmp_path: Path, capsys) -> None:
    """Found by the fuzzer: a joint whose parent hangs below its child made ``footopt import`` walk
    the loop for ever."""
    text = rod_urdf(SPATIAL_LEG).replace('<parent link="hip"/><child link="thigh"/>',
                                         '<parent link="shank"/><child link="thigh"/>')
    src = tmp_path / "loop.urdf"
    src.write_text(text, encoding="utf-8")
    assert main(["import", str(src), "--root", "base", "--ankle", "shank", "-o", str(tmp_path / "o.yaml")]) == 2
    err = capsys.readouterr().err
    assert "joint 'thigh_joint': closes a loop (thigh <- shank <- thigh)" in err and err.count("\n") == 1, err
