"""Model-file validation at the edges of each range (``optimizer.config.model_file.parse_model``):
a value just outside is refused with one line naming its field, the edge itself is accepted; and a
spatial rod's radius gives the solid cylinder's inertia across it, by hand."""

from __future__ import annotations

import copy
import math

import pytest

from optimizer.config.model_file import load_yaml, parse_model
from optimizer.errors import ConfigError
from tests.optimizer.conftest import LEG_YAML

LEG = load_yaml(LEG_YAML)


def _with(path: str, value: object) -> dict:
    """LEG with ``value`` at ``path`` (dots and [i]), e.g. 'model.bodies[2].contacts'."""
    data = copy.deepcopy(LEG)
    keys = [int(k) if k.isdigit() else k for k in path.replace("[", ".").replace("]", "").split(".")]
    node = data
    for k in keys[:-1]:
        node = node[k]
    node[keys[-1]] = value
    return data


BAD = [
    ("scene.speed", 0.0, "scene.speed: "),
    ("scene.velocity", [0.5, 0.0], "scene.velocity[1]: "),  # sliding along the ground: no approach
    ("scene.restitution", 1.0 + 1e-9, "scene.restitution: "),
    ("scene.restitution", -1e-9, "scene.restitution: "),
    ("scene.friction", -1e-9, "scene.friction: "),
    ("scene.gravity", -1e-9, "scene.gravity: "),
    ("scene.contact_tolerance", -1e-9, "scene.contact_tolerance: "),
    ("model.bodies[2].contacts", [-1e-9], "model.bodies[2].contacts[0]: "),
    ("model.bodies[2].contacts", [1.0 + 1e-9], "model.bodies[2].contacts[0]: "),
    ("model.bodies[1].inertia", -1e-9, "model.bodies[1].inertia: "),
    ("model.bodies[1].gyration", -1e-9, "model.bodies[1].gyration: "),
    ("model.bodies[1].at", 1.0 + 1e-9, "model.bodies[1].at: "),
    ("model.bodies[1].limits", [-0.2, 0.5 - 1e-9], "model.bodies[1].limits: "),  # the angle is 0.5
    ("model.bodies[1].limits", [0.5 + 1e-9, 0.9], "model.bodies[1].limits: "),
]


@pytest.mark.parametrize(("path", "value", "start"), BAD, ids=[f"{p}={v}" for p, v, _ in BAD])
def test_a_value_just_outside_its_range_is_refused_naming_its_field(path: str, value: object, start: str) -> None:
    data = _with(path, value)
    if path == "scene.velocity":
        del data["scene"]["speed"]
    with pytest.raises(ConfigError) as caught:
        parse_model(data)
    message = str(caught.value)
    assert message.startswith(start) and "\n" not in message, message


GOOD = [
    ("scene.restitution", 0.0), ("scene.restitution", 1.0), ("scene.friction", 0.0), ("scene.gravity", 0.0),
    ("scene.contact_tolerance", 0.0), ("model.bodies[2].contacts", [0.0, 1.0]), ("model.bodies[1].inertia", 0.0),
    ("model.bodies[1].gyration", 0.0), ("model.bodies[1].at", 0.0), ("model.bodies[1].limits", [0.5, 0.9]),
    ("model.bodies[1].limits", [-0.2, 0.5]),
]


@pytest.mark.parametrize(("path", "value"), GOOD, ids=[f"{p}={v}" for p, v in GOOD])
def test_the_edge_of_each_range_is_accepted(path: str, value: object) -> None:
    parse_model(_with(path, value))


def test_a_rods_radius_gives_the_solid_cylinders_inertia_across_it() -> None:
    """m (3 r^2 + L^2) / 12 across, m r^2 / 2 about the axis (a uniform solid cylinder)."""
    data = _with("model.bodies[1].radius", 0.08)
    data["model"]["space"] = "spatial"
    b = parse_model(data).tree.bodies[1]
    m, L, r = 1.0, 0.5, 0.08
    assert b.inertia == pytest.approx(m * (3 * r * r + L * L) / 12, rel=1e-12)
    assert b.axial_inertia == pytest.approx(m * r * r / 2, rel=1e-12)
    assert math.isclose(parse_model(LEG).tree.bodies[1].inertia, m * L * L / 12, rel_tol=1e-12)
