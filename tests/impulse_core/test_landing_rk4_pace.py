"""``auto``'s implicit first run gives way (to Radau IIA above AUTO_RADAU, else RK4) where the
momentum balance splits its steps below RK4's stable step
(:data:`impulse_core.timedomain.events.settings.RK4_PACE`; random file 32700, a 74 g rod hinged by
a damper of 2 N m s: ``studies/whole_landing/stiff_speed.md``)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from impulse_core.timedomain.events.run import _Landing
from impulse_core.timedomain.events.settings import AUTO_RADAU
from impulse_core.timedomain.landing import IMPLICIT, LandingProgress, LandingSettings, landing
from optimizer.config.model_file import load_model_file

DATA = Path(__file__).parent / "data"


class _Enough(Exception):
    """Raised from the progress callback: the test has seen what it looks for."""


def _model_and_run(settings: LandingSettings):
    model = load_model_file(DATA / "stiff_rod_32700.yaml")
    return model, _Landing(model.tree, model.scene, model.joints, settings, model.space)


def test_autos_implicit_run_gives_way_once_its_steps_fall_behind_rk4s_stable_step() -> None:
    settings = LandingSettings()
    model, run = _model_and_run(settings)
    assert run.method == IMPLICIT  # auto: duration / 200 x rate over AUTO_IMPLICIT
    h = run.first_step()
    # 44.7: Radau IIA follows from ROS2's first step (AUTO_RADAU; RK4 from its stable step while it was 100:
    # 37.7 s against Radau's 19.9 s on 2026-11-28, settings.AUTO_RADAU)
    assert h * run.rate > AUTO_RADAU
    implicit_times: list[float] = []

    def progress(p: LandingProgress) -> None:
        if p.run > 0:  # the next integrator's first run has begun
            assert p.step == h  # Radau IIA from ROS2's first step (RK4 would start at its stable step)
            raise _Enough
        assert p.step == h
        implicit_times.append(p.t)
        # before: the balance split the implicit steps to ~1e-7 s after touchdown and the run went
        # on until its step budget (64 x 200 steps) ran out at t = 0.167 s, 52 s of the landing's 117 s
        assert p.t < 0.01, f"the implicit run went on to t = {p.t:.3g} s"

    with pytest.raises(_Enough):
        landing(model.tree, model.scene, model.joints, settings, model.space, progress)
    assert implicit_times and max(implicit_times) < 1e-3


def test_an_implicit_integrator_asked_for_keeps_its_run() -> None:
    settings = replace(LandingSettings(), integrator=IMPLICIT)
    model, run = _model_and_run(settings)
    h = run.first_step()

    def progress(p: LandingProgress) -> None:
        assert p.step == h  # no RK4 run: one integrator, the one asked for
        if p.t > 3e-4:  # past where auto's run gives way (1.2e-4 s)
            raise _Enough

    with pytest.raises(_Enough):
        landing(model.tree, model.scene, model.joints, settings, model.space, progress)
