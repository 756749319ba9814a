"""Study files with a spatial design space: the keys round-trip, the planar study's resolved form
does not change, and every bad value is one ConfigError naming its field."""

from __future__ import annotations

from pathlib import Path

import pytest

from optimizer.config.study_config import format_study, load_study, parse_study
from optimizer.design_space import SplayMode
from optimizer.errors import ConfigError

REPO = Path(__file__).resolve().parents[2]


def study(**changes) -> dict:
    data = {
        "design_space": {"toes": [2, 3], "toe_segments": [1, 2], "space": "spatial", "splay": [0.0, 0.5]},
        "constraints": {"support_margin": 0.02},
        "objectives": ["external_norm", "internal_norm"],
        "search": {"method": "outer", "trials": 8},
    }
    for dotted, value in changes.items():
        *head, last = dotted.split("__")
        m = data
        for k in head:
            m = m.setdefault(k, {})
        if value is KeyError:
            m.pop(last, None)
        else:
            m[last] = value
    return data


def test_shipped_spatial_study_loads_and_round_trips(tmp_path: Path):
    config = load_study(REPO / "configs" / "splayed_study.yaml")
    assert config.space.spatial and config.space.splay.mode is SplayMode.SYMMETRIC
    assert config.space.splay.splay == (0.0, 0.8) and config.limits.support_margin == 0.02
    again = tmp_path / "resolved.yaml"
    again.write_text(format_study(config, "resolved"), encoding="utf-8")
    assert load_study(again) == config


def test_per_toe_round_trips_and_planar_text_has_no_spatial_keys(tmp_path: Path):
    config = parse_study(study(design_space__splay_mode="per_toe", design_space__splay=[-0.4, 0.6]))
    assert config.space.splay.mode is SplayMode.PER_TOE and config.space.splay.splay == (-0.4, 0.6)
    path = tmp_path / "s.yaml"
    path.write_text(format_study(config), encoding="utf-8")
    assert load_study(path) == config
    planar = format_study(load_study(REPO / "configs" / "quick_study.yaml"))
    assert "splay" not in planar and "  space:" not in planar and "support_margin" not in planar


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"design_space__space": "3d"}, r"^design_space\.space: must be one of planar, spatial, got '3d'"),
        ({"design_space__space": KeyError}, r"^design_space\.splay: needs design_space\.space: spatial"),
        ({"design_space__space": "planar", "design_space__splay": KeyError,
          "design_space__splay_mode": "per_toe"}, r"^design_space\.splay_mode: needs design_space\.space: spatial"),
        ({"design_space__splay": [0.5, 0.2]}, r"^design_space\.splay: min 0\.5 is above max 0\.2$"),
        ({"design_space__splay": [-0.1, 0.2]}, r"^design_space\.splay\[0\]: the symmetric splay is >= 0"),
        ({"design_space__splay": [0.0, 1.6]}, r"^design_space\.splay: a toe's yaw must stay within"),
        ({"design_space__splay_mode": "per_toe", "design_space__splay": [-1.6, 0.2]},
         r"^design_space\.splay: a toe's yaw must stay within"),
        ({"design_space__splay": "wide"}, r"^design_space\.splay: must be a list \[min, max\] of numbers"),
        ({"design_space__splay": [0.0, "x"]}, r"^design_space\.splay\[1\]: must be a number"),
        ({"design_space__splay_mode": "fan"}, r"^design_space\.splay_mode: must be one of symmetric, per_toe"),
        ({"constraints__support_margin": "big"}, r"^constraints\.support_margin: must be a number"),
        ({"constraints__support_margin": float("nan")}, r"^constraints\.support_margin: must be a finite number"),
        ({"design_space__space": "planar", "design_space__splay": KeyError},
         r"^constraints\.support_margin: needs design_space\.space: spatial"),
        ({"search__method": "inner", "landings": {"count": 4, "roll": [0.0, 0.1]}},
         r"^landings\.roll: the inner search varies speed, velocity_x, angular_velocity, restitution, velocity_z, "
         r"roll_rate only"),
        ({"search__method": "inner", "landings": {"count": 4, "pitch": [0.0, 0.1]}},
         r"^landings\.pitch: the inner search varies"),
        ({"search__method": "inner", "objectives": ["peak_external_norm"], "scene": {"duration": 0.05},
          "landings": {"count": 4, "speed": [3.0, 3.5], "roll": [0.0, 0.1]}},
         r"^landings\.roll: the inner search over whole landings varies speed, velocity_x, angular_velocity, "
         r"restitution, velocity_z, roll_rate, friction only"),
        ({"search__method": "inner", "scene": {"friction": 0.5}},
         r"^scene\.friction: the inner search optimises frictionless landings only"),
        ({"landings": {"count": 4, "terrain_step": [0.0, 0.01]}}, r"^landings\.terrain_step: a step is a planar terrain"),
        ({"design_space__space": "planar", "design_space__splay": KeyError, "constraints__support_margin": KeyError,
          "landings": {"count": 4, "roll": [0.0, 0.1]}}, r"^landings\.roll: needs design_space\.space: spatial"),
    ],
)
def test_bad_values_name_the_field(changes: dict, message: str):
    with pytest.raises(ConfigError, match=message) as e:
        parse_study(study(**changes))
    assert "\n" not in str(e.value)
