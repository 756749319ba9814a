"""A joint so stiff that only RK4 at its stable step follows it does not hang a landing: the case-3 leg
(``configs/landing_case3.yaml``) with a heel of 1e12 N m/rad did not end its 5 ms in 150 s of CPU (``auto``:
ROS2, then Radau IIA, whose Newton iterations failed on every step: 17 tries a step of 5e-11 s). Now
``auto``'s Radau IIA run gives way to RK4 once its tries fall behind RK4's stable step
(:data:`RK4_PACE`), which lands it (0.5124 N s of peak impulse, as at 1e8 and 1e10 N m/rad; on Radau
the heel's oscillation was damped away: 0.413), and a landing that RK4 could not follow within
:data:`LANDING_STEPS` is refused before any step, naming the joint."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from impulse_core.errors import ModelError
from impulse_core.timedomain.events.run import _Landing
from impulse_core.timedomain.events.settings import BALANCE_CHECK, LANDING_STEPS, RK4_PACE_AFTER
from impulse_core.timedomain.landing import (
    IMPLICIT, RADAU, RK4, LandingProgress, LandingSettings, follows_oscillation, landing,
)
from optimizer.cli.main import main
from optimizer.config.model_file import load_model_file

CASE3 = Path(__file__).resolve().parents[2] / "configs" / "landing_case3.yaml"
HEEL = 2  # model.bodies[2]: the heel, the first joint with stiffness 10 N m/rad


def _stiff_heel(stiffness: float, duration: float):
    model = load_model_file(CASE3)
    assert model.tree.bodies[HEEL].name == "heel"
    joints = list(model.joints)
    joints[HEEL] = replace(joints[HEEL], stiffness=stiffness)
    return model, replace(model.scene, duration=duration), tuple(joints)


class _Enough(Exception):
    """Raised from the progress callback: the test has seen what it looks for."""


@pytest.mark.parametrize(("stiffness", "duration"), [(1e12, 0.3), (1e14, 0.005)])
def test_a_spring_rk4_cannot_follow_within_the_budget_is_refused_before_any_step(monkeypatch, stiffness,
                                                                                 duration) -> None:
    model, scene, joints = _stiff_heel(stiffness, duration)

    def step(self, *args):
        raise AssertionError("a step was taken")

    monkeypatch.setattr(_Landing, "step", step)
    with pytest.raises(ModelError) as refused:
        landing(model.tree, scene, joints, LandingSettings(), model.space)
    message = str(refused.value)
    assert message.startswith(f"model.bodies[2].stiffness: heel's joint stiffness {stiffness:.3g} N m/rad")
    assert "\n" not in message and f"over the {LANDING_STEPS} a landing may plan" in message
    fits = float(message.split("at most ")[1].split(" N m/rad fits")[0])  # what it says would fit does
    assert stiffness / 1e4 < fits < stiffness
    run = _Landing(model.tree, scene, tuple(replace(j, stiffness=0.99 * fits) if i == HEEL else j
                                            for i, j in enumerate(joints)), LandingSettings(), model.space)
    follows_oscillation(run)


def test_a_stiff_damper_is_left_to_the_implicit_integrators() -> None:
    """A damper's rate as fast as that spring's: ROS2 and Radau IIA follow its decay, so no refusal
    before the runs (they are ``auto``'s to try)."""
    model, scene, joints = _stiff_heel(10.0, 0.3)
    heel = replace(joints[HEEL], damping=1e6)
    run = _Landing(model.tree, scene, joints[:HEEL] + (heel,) + joints[HEEL + 1:], LandingSettings(), model.space)
    assert 3.0 * 0.3 * run.rate / 2.0 > LANDING_STEPS  # RK4 at its stable step would be over the budget
    follows_oscillation(run)


def test_autos_radau_run_gives_way_to_rk4_once_its_tries_fall_behind_rk4s_stable_step(monkeypatch) -> None:
    """1e12 N m/rad over 5 ms: ROS2 from duration / 200 gives way (RK4_PACE), Radau IIA from the same
    step (h x rate 962) does too, after RK4_PACE_AFTER x duration / h tries, not steps (before: it took
    17 tries a step, each 5e-11 s, and crawled on), and RK4 from its stable step follows."""
    model, scene, joints = _stiff_heel(1e12, 0.005)
    h = 0.005 / 200.0
    runs, original = [], _Landing.run

    def watched(self, step, *args, **kwargs):
        runs.append((self, step))
        return original(self, step, *args, **kwargs)

    def progress(p: LandingProgress) -> None:
        run = runs[-1][0]
        if run.method == RK4:
            raise _Enough
        assert run.radau_tries <= RK4_PACE_AFTER * 200 + 100, f"Radau IIA went on: {run.radau_tries} tries"

    monkeypatch.setattr(_Landing, "run", watched)
    with pytest.raises(_Enough):
        landing(model.tree, scene, joints, LandingSettings(), model.space, progress)
    assert [(run.method, step) for run, step in runs] == [(IMPLICIT, h), (RADAU, h), (RK4, runs[2][0].stable_step())]
    assert runs[1][0].radau_tries > RK4_PACE_AFTER * 200


def test_the_cli_refuses_it_in_one_line_with_status_2(tmp_path: Path, capsys) -> None:
    text = CASE3.read_text()
    assert text.index("stiffness: 10.0") < text.index("name: toe1_proximal")  # the first: the heel's
    path = tmp_path / "stiff_heel.yaml"
    path.write_text(text.replace("stiffness: 10.0", "stiffness: 1.0e12", 1))
    assert main(["evaluate", "--json", str(path)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and "Traceback" not in err
    assert f"{path}: model.bodies[2].stiffness: heel's joint stiffness 1e+12 N m/rad" in err


@pytest.mark.slow
def test_the_stiff_heel_lands_as_rk4_from_its_stable_step_does() -> None:
    """The whole 5 ms (36 s): ``auto``'s landing is RK4's from its stable step to the bit, its momentum
    balance closes, and its peak impulse is that of the heel at 1e10 N m/rad within 1e-4."""
    model, scene, joints = _stiff_heel(1e12, 0.005)
    r = landing(model.tree, scene, joints, LandingSettings(), model.space)
    reference = landing(model.tree, scene, joints, LandingSettings(integrator=RK4), model.space)
    assert r.integrator == RK4 and r.integrator_switch.startswith("Radau IIA's tries averaged")
    for a, b in ((r.trajectory[0], reference.trajectory[0]), (r.trajectory[1], reference.trajectory[1]),
                 (r.final_angles, reference.final_angles), (r.total_external, reference.total_external)):
        np.testing.assert_array_equal(a, b)
    assert (r.n_steps, r.step, r.error_estimate) == (reference.n_steps, reference.step, reference.error_estimate)
    assert r.converged and r.momentum_balance < BALANCE_CHECK
    softer = landing(model.tree, scene, _stiff_heel(1e10, 0.005)[2], LandingSettings(), model.space)
    assert abs(r.peak_external_norm - softer.peak_external_norm) < 1e-4 * softer.peak_external_norm


def test_a_radau_run_asked_for_whose_tries_overrun_fails_naming_the_joint(monkeypatch) -> None:
    """Radau IIA asked for, 1e12 N m/rad over 5 ms: its tries overrun their budget (lowered here to
    RADAU_TRIES / 16 x STEP_BUDGET x duration / h: 800 tries, instead of 51,200 that took 34 s),
    and the landing fails at once, naming the joint law, instead of retrying at ever shorter steps
    (before: runs at h / 8 and h / 32 crawled alike, 36 s and over 140 s of CPU)."""
    from impulse_core.errors import NumericalError
    from impulse_core.timedomain.events import run as events_run

    model, scene, joints = _stiff_heel(1e12, 0.005)
    monkeypatch.setattr(events_run, "RADAU_TRIES", events_run.RADAU_TRIES / 16.0)
    runs, original = [], _Landing.run

    def watched(self, step, *args, **kwargs):
        runs.append((self.method, step))
        assert len(runs) == 1, f"a second run: {runs}"
        return original(self, step, *args, **kwargs)

    monkeypatch.setattr(_Landing, "run", watched)
    with pytest.raises(NumericalError) as failed:
        landing(model.tree, scene, joints, LandingSettings(integrator=RADAU), model.space)
    message = str(failed.value)
    assert message.startswith("Radau IIA tried more than") and "heel's joint stiffness 1e+12" in message
    assert runs == [(RADAU, 0.005 / 200.0)]


def test_a_run_at_a_step_too_short_for_the_budget_is_refused_with_its_cause() -> None:
    """Where a retry's step (retry_factor after a run overran at a small fraction of the duration)
    would take over LANDING_STEPS steps while RK4 at its stable step would not: a NumericalError with
    the failure that shortened the step; a step within the budget is let through."""
    from impulse_core.errors import NumericalError
    from impulse_core.timedomain.landing import afford

    model = load_model_file(CASE3)
    run = _Landing(model.tree, model.scene, model.joints, LandingSettings(), model.space)
    T = float(model.scene.duration)
    afford(run, 3.0 * T / LANDING_STEPS)
    with pytest.raises(NumericalError) as refused:
        afford(run, 2.9 * T / LANDING_STEPS, "the landing took more than 64 x 200 steps by t = 1e-06 s")
    message = str(refused.value)
    assert message.startswith("the landing would take over 5.42e+05 steps at step")
    assert "(the landing took more than 64 x 200 steps by t = 1e-06 s; the fastest joint law: " in message
