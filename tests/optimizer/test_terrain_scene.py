"""The proposed ``scene.terrain`` / ``scene.base_x`` keys, read before the model-file parser knows them."""

from __future__ import annotations

from pathlib import Path

import pytest

from impulse_core.terrain import FLAT, Terrain
from optimizer.errors import ConfigError
from optimizer.model_file import load_yaml
from optimizer.terrain_scene import load_terrain_scene, parse_terrain_scene

ROOT = Path(__file__).resolve().parents[2]
BASE = """
scene:
  speed: 2.0
  restitution: 0.5
{extra}
model:
  bodies:
    - {{name: a, length: 1.0, mass: 1.0, angle: -0.5, contacts: [1.0]}}
"""


def _parse(extra: str):
    return parse_terrain_scene(load_yaml(BASE.format(extra=extra)))


def test_without_the_keys_the_ground_is_flat():
    ts = _parse("")
    assert ts.terrain == FLAT and ts.base_x == 0.0 and ts.model.scene.speed == 2.0


def test_terrain_and_base_x_are_read():
    ts = _parse("  terrain: [[-1, 0], [0.5, 0.0], [1e0, 2E-2]]\n  base_x: -0.25")
    assert ts.terrain == Terrain((-1.0, 0.5, 1.0), (0.0, 0.0, 0.02))
    assert ts.base_x == -0.25


@pytest.mark.parametrize(
    "extra, message",
    [
        ("  terrain: []", r"^scene\.terrain: must be a non-empty list"),
        ("  terrain: [[0, 0], [1]]", r"^scene\.terrain\[1\]: must be a pair"),
        ("  terrain: [[0, 0], [1, yes]]", r"^scene\.terrain\[1\]\[1\]: must be a finite number"),
        ("  terrain: [[0, 0], [0, 1]]", r"^scene\.terrain\[1\]: x must increase strictly"),
        ("  terrain: [[0, .nan]]", r"^scene\.terrain\[0\]\[1\]: must be a finite number"),
        ("  base_x: east", r"^scene\.base_x: must be a finite number"),
        ("  terain: [[0, 0]]", r"^scene\.terain: unknown key"),
    ],
)
def test_bad_terrain_is_named_by_its_path(extra, message):
    with pytest.raises(ConfigError, match=message):
        _parse(extra)


def test_uneven_terrain_config_loads():
    ts = load_terrain_scene(ROOT / "configs" / "uneven_terrain.yaml")
    assert ts.terrain == Terrain((-1.0, 0.45, 0.75), (0.0, 0.0, 0.04))
    assert ts.model.tree.n_bodies == 5 and len(ts.model.tree.contacts) == 2
