"""The text report and JSON record of one evaluation."""

from __future__ import annotations

import dataclasses
import json

from impulse_core.evaluate import evaluate
from impulse_core.model.tree import Body, JointKind, Scene, Tree
from optimizer.config.model_file import ModelFile, Reference
from optimizer.report.text import contact_names, format_report, joint_names, result_record, velocity_names, warnings


def test_names() -> None:
    tree = Tree(
        (
            Body("hip", None, 1.0, 1.0, 0.0, contacts=(0.0,)),
            Body("toe", 0, 1.0, 1.0, 0.5, contacts=(1.0, 0.5)),
            Body("weld", 1, 1.0, 1.0, 0.5, joint=JointKind.FIXED),
            Body("heel", 0, 1.0, 1.0, -0.5, contacts=(1.0,)),
        )
    )
    assert contact_names(tree) == ("hip[0]", "toe[0]", "toe[1]", "heel[0]")
    assert joint_names(tree) == ("toe", "weld", "heel")
    assert [name for name, _ in velocity_names(tree)] == ["base vx", "base vy", "base omega", "toe rate", "heel rate"]


def test_energy_gain_is_flagged(leg_tree: Tree, leg_scene: Scene) -> None:
    result = evaluate(leg_tree, leg_scene)
    model = ModelFile(leg_tree, leg_scene)
    assert not any("energy gained" in w for w in warnings(model, result))
    gained = dataclasses.replace(result, energy_after=2 * result.energy_before)
    assert any(w.startswith("energy gained") for w in warnings(model, gained))
    assert "energy gained: +100.0%" in format_report(model, gained, "leg.yaml")
    assert result_record(model, gained, "leg.yaml")["energy_gained"] is True


def test_reference_beside_ours(leg_tree: Tree, leg_scene: Scene) -> None:
    result = evaluate(leg_tree, leg_scene)
    ref = Reference(external=(None, 2 * result.external[1]), internal_norm=result.internal_norm, note="Table 2")
    report = format_report(ModelFile(leg_tree, leg_scene, ref), result, "leg.yaml")
    foot1 = next(line for line in report.splitlines() if line.startswith("foot[1]"))
    assert foot1.split()[-2:] == [f"{2 * result.external[1]:.4f}", "-50.0%"]
    foot0 = next(line for line in report.splitlines() if line.startswith("foot[0]"))
    assert foot0.split()[-1] == "-"
    norm = next(line for line in report.splitlines() if line.startswith("internal_norm"))
    assert norm.split()[-1] == "+0.0%"
    assert "reference: Table 2" in report


def test_record_is_plain_json(leg_tree: Tree, leg_scene: Scene) -> None:
    record = result_record(ModelFile(leg_tree, leg_scene), evaluate(leg_tree, leg_scene), "leg.yaml")
    assert json.loads(json.dumps(record, allow_nan=False)) == record


def test_a_landing_off_its_momentum_balance_is_warned_about(leg_tree: Tree, leg_scene: Scene) -> None:
    """A whole landing whose own momentum balance is beyond the contract's 1e-4 (random file
    32843 reached 1e-2) is reported with a warning naming the figure; one within it is not."""
    from impulse_core.timedomain.landing import BALANCE_CHECK, LandingSettings
    from optimizer.evaluation.model_choice import _whole_landing

    scene = dataclasses.replace(leg_scene, duration=0.004, gravity=9.81)
    model = ModelFile(leg_tree, scene)
    landed = _whole_landing(leg_tree, scene, (), LandingSettings(), requested=True)
    assert landed.result.momentum_balance <= BALANCE_CHECK
    assert not any("momentum balance" in w for w in warnings(model, landed))
    off = dataclasses.replace(landed, result=dataclasses.replace(landed.result, momentum_balance=1.2e-2))
    said = [w for w in warnings(model, off) if "momentum balance" in w]
    assert len(said) == 1 and "0.012" in said[0]
    assert "0.012" in format_report(model, off, "leg.yaml")
    assert "0.012" in " ".join(result_record(model, off, "leg.yaml")["warnings"])


def test_a_landing_whose_runs_end_apart_says_which_figures_did_not_converge(leg_tree: Tree, leg_scene: Scene) -> None:
    """A whole landing whose step halving stopped because its runs' final angles did not approach
    each other (random file 32924's figures: 1.61, then 0.897, the impulses within 1.3e-3) is
    reported with one warning naming the final angles and both comparisons' differences, not the
    generic unmet-tolerance one; the JSON's keys are those of a converged landing."""
    from impulse_core.timedomain.landing import LandingSettings
    from optimizer.evaluation.model_choice import _whole_landing

    scene = dataclasses.replace(leg_scene, duration=0.004, gravity=9.81)
    model = ModelFile(leg_tree, scene)
    landed = _whole_landing(leg_tree, scene, (), LandingSettings(), requested=True)
    halving = ((6.52e-4, 1.63e-4, 7.3e-4, 2.7e-4, 1.61), (1.63e-4, 4.08e-5, 1.26e-3, 4.7e-4, 0.897))
    apart = dataclasses.replace(landed, result=dataclasses.replace(
        landed.result, error_estimate=0.897, halving=halving, runs_apart=True))
    said = [w for w in warnings(model, apart) if "converge" in w]
    assert len(said) == 1 and "final angles did not converge" in said[0]
    assert all(x in said[0] for x in ("1.61", "0.897", "0.0013", "0.00047", "4.08e-05"))
    assert said[0] in result_record(model, apart, "leg.yaml")["warnings"]
    assert set(result_record(model, apart, "leg.yaml")) == set(result_record(model, landed, "leg.yaml"))
    unmet = dataclasses.replace(landed, result=dataclasses.replace(landed.result, error_estimate=0.897))
    assert [w for w in warnings(model, unmet) if "converge" in w][0].startswith("the landing did not converge")


def test_a_landing_whose_halving_stalled_says_so_with_its_differences(leg_tree: Tree, leg_scene: Scene) -> None:
    """A whole landing whose step halving stopped because a step eight times shorter did not halve
    the runs' difference (random file 60838's figures: 2.3e-3, then 1.0e-2, 7.4e-3 and 5.0e-3) is
    reported with one warning naming those comparisons and the estimate, not the generic one."""
    from impulse_core.timedomain.landing import LandingSettings
    from optimizer.evaluation.model_choice import _whole_landing

    scene = dataclasses.replace(leg_scene, duration=0.004, gravity=9.81)
    model = ModelFile(leg_tree, scene)
    landed = _whole_landing(leg_tree, scene, (), LandingSettings(), requested=True)
    h = 7.62e-5
    halving = ((h, h / 4, 0.0, 3.17e-3, 1.39e-2), (h / 4, h / 8, 0.0, 2.32e-3, 8.02e-4),
               (h / 8, h / 16, 0.0, 1.03e-2, 8.08e-4), (h / 16, h / 32, 0.0, 7.43e-3, 6.45e-4),
               (h / 32, h / 64, 0.0, 5.01e-3, 2.03e-4))
    stalled = dataclasses.replace(landed, result=dataclasses.replace(
        landed.result, error_estimate=5.01e-3, halving=halving))
    said = [w for w in warnings(model, stalled) if "converge" in w]
    assert len(said) == 1 and "step halving stopped" in said[0] and "0.014" not in said[0]
    assert all(x in said[0] for x in ("0.0023", "0.01 ", "0.0074", "0.005 ", "1.19e-06", "uncertain to about 0.005",
                                      "shrank 8-fold"))
    assert said[0] in result_record(model, stalled, "leg.yaml")["warnings"]
    halved = dataclasses.replace(landed, result=dataclasses.replace(
        landed.result, error_estimate=1.1e-3, halving=halving[:4] + ((h / 32, h / 64, 0.0, 1.1e-3, 2.03e-4),)))
    assert [w for w in warnings(model, halved) if "converge" in w][0].startswith("the landing did not converge to its "
                                                                                 "tolerance: error")


def test_a_landing_whose_impacts_gain_energy_says_when_and_how_much() -> None:
    """Random file 33016: a lone rod landing on its tip at e = 1, mu 0.5. Its second impact sticks
    the tip and raises the kinetic energy (Newton's restitution with Coulomb friction can: Kane's
    paradox), which the report names with its time and energies; frictionless, the same landing's
    impacts keep the energy (e = 1: to 1e-9) and nothing is said."""
    from impulse_core.kinematics.spatial import SPATIAL
    from impulse_core.timedomain.landing import LandingSettings
    from optimizer.evaluation.model_choice import _whole_landing

    rod = Tree((Body("rod", None, 0.0744988, 0.93267, -2.72775, rpy=(-0.194306, 0.283336, 0.0), contacts=(1.0,),
                     radius=0.01),))
    scene = Scene(speed=2.94541, restitution=1.0, friction=0.5, gravity=9.81, duration=0.05)
    landed = _whole_landing(rod, scene, (), LandingSettings(), requested=True, space=SPATIAL)
    gains = landed.result.gaining_events
    assert len(gains) == 1 and gains[0].energy_after > 1.1 * gains[0].energy_before
    model = ModelFile(rod, scene, space=SPATIAL)
    said = [w for w in warnings(model, landed) if "raised the kinetic energy" in w]
    assert len(said) == 1 and f"t = {gains[0].time:.6g} s" in said[0] and f"{gains[0].energy_after:.6g} J" in said[0]
    assert said[0] in result_record(model, landed, "rod.yaml")["warnings"]
    smooth = dataclasses.replace(scene, friction=0.0)
    kept = _whole_landing(rod, smooth, (), LandingSettings(), requested=True, space=SPATIAL)
    assert len(kept.result.events) >= 2 and not kept.result.gaining_events
    assert all(abs(e.energy_after - e.energy_before) <= 1e-9 * e.energy_before for e in kept.result.events)
    assert not any("raised the kinetic energy" in w for w in warnings(ModelFile(rod, smooth, space=SPATIAL), kept))
