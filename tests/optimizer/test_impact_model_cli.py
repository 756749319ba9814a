"""``footopt evaluate --model``: every rung of the impact-model ladder runs from the command line,
the report and the JSON say which one ran and why, and energy is reported (and a gain flagged)
for each rung."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from impulse_core.impact.laws import ImpactModel
from impulse_core.evaluate import evaluate
from optimizer.cli.main import IMPACT_MODEL_CHOICES, main
from optimizer.config.model_file import load_model_file
from tests.optimizer.conftest import LEG_YAML, PULLING_YAML

#: A rod landing tilted on two points with e = 1: the decoupled approximation (eq. 14) creates
#: kinetic energy, eq. 11 and the complementarity law do not.
TILTED_ROD_YAML = """\
scene: {speed: 2.0, restitution: 1.0, contacts: all}
model:
  bodies:
    - {name: rod, length: 0.3, mass: 1.0, angle: -0.6, contacts: [0.05, 0.8]}
"""

FRICTION_LEG_YAML = LEG_YAML.replace("restitution: 0.5", "restitution: 0.5\n  friction: 0.4")


def _record(capsys) -> dict:
    (line,) = capsys.readouterr().out.splitlines()
    return json.loads(line)


#: The choices that run a rigid rung on flat ground ('auto' included).
RIGID_CHOICES = ("auto", *(m.value for m in ImpactModel))


def test_the_choices_are_auto_and_every_rung() -> None:
    assert IMPACT_MODEL_CHOICES == ("auto", "decoupled", "newton", "lcp", "friction", "friction-relaxed", "sequential", "compliant", "landing")


@pytest.mark.parametrize("choice", RIGID_CHOICES)
def test_every_rung_runs_and_says_so(choice: str, leg_file: Path, capsys) -> None:
    assert main(["evaluate", "--json", "--model", choice, str(leg_file)]) == 0
    record = _record(capsys)
    model = load_model_file(leg_file)
    expected = evaluate(model.tree, model.scene, None if choice == "auto" else ImpactModel(choice))
    assert record["impact_model"] == expected.model.value == ("newton" if choice == "auto" else choice)
    assert record["impact_reason"] == expected.reason
    assert record["impact_reason"].startswith("automatic" if choice == "auto" else "requested")
    assert record["external"] == expected.external.tolist()
    assert record["internal"] == expected.internal_magnitude.tolist()
    assert {"external", "internal", "external_norm", "internal_norm"} <= set(record)
    assert record["energy_before"] == expected.energy_before and record["energy_after"] == expected.energy_after
    assert main(["evaluate", "--model", choice, str(leg_file)]) == 0
    out = capsys.readouterr().out
    assert f"model:   {expected.model.value}: {expected.model.description}" in out
    assert f"why:     {expected.reason}" in out
    assert "kinetic energy [J]: before" in out


def test_pulling_scene_runs_the_lcp_by_default(write, capsys) -> None:
    path = write(PULLING_YAML, "pulling.yaml")
    assert main(["evaluate", "--json", str(path)]) == 0
    record = _record(capsys)
    assert record["impact_model"] == "lcp" and min(record["external"]) >= 0.0
    assert main(["evaluate", "--json", "--model", "newton", str(path)]) == 0
    assert min(_record(capsys)["external"]) < 0.0


def test_friction_scene_runs_the_friction_rung_by_default(write, capsys) -> None:
    path = write(FRICTION_LEG_YAML, "friction.yaml")
    assert main(["evaluate", "--json", str(path)]) == 0
    record = _record(capsys)
    assert record["impact_model"] == "friction" and "scene.friction = 0.4 > 0" in record["impact_reason"]
    assert any(t != 0.0 for t in record["tangential"])
    assert all(abs(t) <= 0.4 * n + 1e-12 for n, t in zip(record["external"], record["tangential"], strict=True))
    assert main(["evaluate", str(path)]) == 0
    out = capsys.readouterr().out
    assert "tangential [N s]" in out and "slip after [m/s]" in out and "normal and tangential along +x" in out
    assert "the convex friction law's relaxation" not in out  # the exact law: no hop
    assert main(["evaluate", "--model", "friction-relaxed", str(path)]) == 0
    out = capsys.readouterr().out
    assert "faster than restitution while carrying impulse (the convex friction law's relaxation)" in out
    assert main(["evaluate", "--json", "--model", "lcp", str(path)]) == 0
    record = _record(capsys)
    assert record["tangential"] == [0.0, 0.0] and "scene.friction = 0.4 is ignored" in record["impact_reason"]


def test_an_energy_gain_is_flagged_for_the_rung_that_makes_it(write, capsys) -> None:
    path = write(TILTED_ROD_YAML, "rod.yaml")
    gained = {}
    for choice in ("decoupled", "newton", "lcp", "friction"):
        assert main(["evaluate", "--json", "--model", choice, str(path)]) == 0
        record = _record(capsys)
        gained[choice] = record["energy_gained"]
        if choice != "decoupled":  # e = 1: the exact rungs conserve energy (to rounding)
            assert abs(record["energy_after"] - record["energy_before"]) <= 1e-12 * record["energy_before"]
    assert gained == {"decoupled": True, "newton": False, "lcp": False, "friction": False}
    assert main(["evaluate", "--model", "decoupled", str(path)]) == 0
    out = capsys.readouterr().out
    assert "warning: energy gained" in out and "under the decoupled model" in out


def test_an_unknown_model_is_a_usage_error(leg_file: Path, capsys) -> None:
    assert main(["evaluate", "--model", "mujoco", str(leg_file)]) == 2
    err = capsys.readouterr().err
    assert "--model" in err and "invalid choice" in err


def test_leg_yaml_is_what_the_tests_think() -> None:
    """Guard for the edits above: the replacements hit."""
    assert "friction: 0.4" in FRICTION_LEG_YAML and "restitution: 0.5" in LEG_YAML
