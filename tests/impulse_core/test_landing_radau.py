"""The two-stage Radau IIA step (``integrator="radau"``, :meth:`_Landing.radau_step`) on random file
33096, a 22 g, 7 cm rod on a 7.0 N m s/rad damper (h x rate 632 at duration / 200): stiffly
accurate where ROS2 is not, so its long steps keep the momentum balance
(``studies/whole_landing/stiff_speed.md``, 2026-11-27, branch ``stiff38``)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from impulse_core.timedomain.events.forces import _unstacked, impulse_vector
from impulse_core.timedomain.events.run import _Landing
from impulse_core.timedomain.events.settings import AUTO_RADAU, MOMENTUM_BALANCE
from impulse_core.timedomain.landing import (
    IMPLICIT, NUMPY_CODE, RADAU, RK4, VM_CODE, LandingProgress, LandingSettings, landing, landing_difference,
)
from optimizer.config.model_file import load_model_file

DATA = Path(__file__).parent / "data"


def _run(integrator: str, code: str = NUMPY_CODE, duration: float | None = None):
    model = load_model_file(DATA / "stiff_rod_33096.yaml")
    scene = model.scene if duration is None else replace(model.scene, duration=duration)
    settings = LandingSettings(integrator=integrator, step_code=code)
    return model, _Landing(model.tree, scene, model.joints, settings, model.space)


def _resting_state(run: _Landing, after: float):
    """The RK4 run's (q, v, mode) at its first step's end past ``after`` (the rod's tip resting)."""
    reached, seen = [0.0], []

    def progress(p) -> None:
        reached[0] = p.t

    def until(q, v, mode, totals) -> bool:
        if reached[0] > after:
            seen.append((q.copy(), v.copy(), mode.copy()))
            return True
        return False

    run.run(run.stable_step(), progress, until=until)
    return seen[0]


def _balance(run: _Landing, q, v, q1, v1, impulse, h) -> float:
    """The step's momentum residual (N s, the weight's impulse included)."""
    p0 = run.point(q, v).momentum[:, 0].copy()
    pt = run.point(q1, v1)
    applied = impulse_vector(pt.normal, *_unstacked(impulse, run.nc, run.dims - 1))
    return float(np.max(np.abs(pt.momentum[:, 0] - p0 - applied - run.weight(h))))


def test_radau_keeps_a_stiff_resting_step_accurate_where_ros2_does_not() -> None:
    """A step of 128 / rate (0.43 ms) from a resting state 2 ms after touchdown, against RK4 at
    0.1 / rate: Radau IIA's end within 1e-7 rad and its momentum residual within the landing's
    share for the step; ROS2's end 2e-5 rad off (its error, not the momentum map's, the same
    with the exact Jacobian), its residual hundreds of shares (what split its steps)."""
    model, ref = _run(RK4, VM_CODE)
    q, v, mode = _resting_state(ref, 2e-3)
    assert mode.closed.any()
    h = 128.0 / ref.rate
    n = 1280
    qr, vr = q, v
    for _ in range(n):
        qr, vr, _ = ref.step(qr, vr, mode, h / n)
    _, radau = _run(RADAU)
    _, ros2 = _run(IMPLICIT)
    T = float(model.scene.duration)
    p_touch = ref.mass * float(np.max(np.abs(model.scene.velocity)))  # the touchdown momentum
    share = MOMENTUM_BALANCE * max(p_touch, ref.mass * model.scene.gravity * T) / T * h
    q1, v1, impulse = radau.radau_step(q, v, mode, h)
    assert np.max(np.abs(q1 - qr)) < 1e-7 and np.max(np.abs(v1 - vr)) < 1e-5
    assert _balance(radau, q, v, q1, v1, impulse, h) < 0.5 * share
    q2, v2, impulse2 = ros2.implicit_step(q, v, mode, h)
    assert np.max(np.abs(q2 - qr)) > 1e-6
    assert _balance(ros2, q, v, q2, v2, impulse2, h) > 10.0 * share


def test_radau_lands_the_first_9_ms_as_rk4_does_in_far_fewer_steps() -> None:
    """Cut to 9 ms (the rate of the balance per second the full file's; the cut's shorter
    MIN_BOUNCE lets 24 impacts through): Radau IIA at duration / 200 of the full file takes the
    same impacts as RK4 at its stable step, at the same times (within 1e-9 s) and within 1e-6 of
    its answer (1.4e-7), in under a sixth of its steps (the balance splits Radau's steps after
    the impacts only)."""
    model, _ = _run(RK4)
    T, cut = float(model.scene.duration), 0.009
    _, rk4 = _run(RK4, VM_CODE, cut)
    _, radau = _run(RADAU, NUMPY_CODE, cut)
    a = rk4.run(rk4.stable_step(), share=cut / T)
    b = radau.run(T / 200.0, share=cut / T)
    assert len(a.events) == len(b.events) == 24
    assert max(abs(x.time - y.time) for x, y in zip(a.events, b.events)) < 1e-9
    assert landing_difference(a, b) < 1e-6
    assert b.n_steps * 6 < a.n_steps  # 198 against 1456
    from optimizer.report.text import _landing_lines

    said = [line for line in _landing_lines(model, replace(b, tolerance=1e-3)) if line.startswith("accuracy:")]
    assert len(said) == 1 and "Radau IIA (order 3)" in said[0]  # the text report names it


class _Enough(Exception):
    """Raised from the progress callback: the test has seen what it looks for."""


def test_autos_implicit_run_gives_way_to_radau_from_its_first_step(monkeypatch) -> None:
    """``auto`` takes ROS2 (h x rate 632); the momentum balance splits its steps, it gives way
    (RK4_PACE) at t = 1.6 ms, and the landing goes on with Radau IIA from the same first step
    (h x rate over AUTO_RADAU), not RK4 from its stable step (63.5 s against 14.0 s whole)."""
    model, run = _run("auto", VM_CODE)
    h = run.first_step()
    assert run.method == IMPLICIT and h * run.rate > AUTO_RADAU
    runs, original = [], _Landing.run

    def watched(self, step, *args, **kwargs):
        runs.append((self.method, step))
        return original(self, step, *args, **kwargs)

    def progress(p: LandingProgress) -> None:
        if p.run > 0:
            raise _Enough

    monkeypatch.setattr(_Landing, "run", watched)
    with pytest.raises(_Enough):
        landing(model.tree, model.scene, model.joints, LandingSettings(), model.space, progress)
    assert runs == [(IMPLICIT, h), (RADAU, h)]


def test_derivatives_replay_the_rk4_landing_where_the_landing_went_on_with_radau(monkeypatch) -> None:
    """The derivatives do not replay Radau IIA's steps: where ``landing()`` ended on it, their step
    is that of the same landing on RK4 (``replayed_step``), elsewhere ``landing()``'s own."""
    from impulse_core.timedomain import landing_derivatives

    asked, result = [], []

    def fake(tree, scene, laws, settings, space):
        asked.append(settings.integrator)
        return replace(result[0], integrator=RK4, step=2e-5) if settings.integrator == RK4 else result[0]

    monkeypatch.setattr(landing_derivatives, "landing", fake)
    model, _ = _run("auto")
    for ended, want, calls in ((RADAU, 2e-5, ["auto", RK4]), (IMPLICIT, 1e-3, ["auto"]), (RK4, 1e-3, ["auto"])):
        result[:] = [landing_derivatives.LandingResult((), np.zeros(1), np.zeros(1), None, np.zeros(1), np.zeros(1),
                                                       np.zeros(1), 0.0, 0.0, 0.0, 1.0, 1e-3, 1, integrator=ended)]
        asked.clear()
        step = landing_derivatives.replayed_step(model.tree, model.scene, model.joints, LandingSettings(), model.space)
        assert step == want and asked == calls


def test_a_radau_step_whose_iterations_fail_is_split_in_two(monkeypatch) -> None:
    """Where Radau IIA's Newton iterations do not converge over h (faked here beyond h / 4), the
    step is two of h / 2, split so again: here four of h / 4 in a row, their impulses summed;
    beyond RADAU_SPLITS halvings the step is NaN, for ``balanced_step`` to halve; a piece as short
    as RK4's stable step is an RK4 step (random file 60147: steps across a slip's stop failed, and
    an event location's trial step, NaN, reached the witnesses' least squares, which failed)."""
    model, run = _run(RK4, VM_CODE)
    q, v, mode = _resting_state(run, 2e-3)
    _, radau = _run(RADAU)
    h = 64.0 / radau.rate
    once = _Landing.radau_once

    def failing(self, q, v, mode, step):
        if step > 0.3 * h:
            return np.full_like(q, np.nan), np.full_like(v, np.nan), np.full(2 * self.nc, np.nan)
        return once(self, q, v, mode, step)

    quarters, impulses = (q, v), []
    for _ in range(4):
        *quarters, p = radau.radau_once(*quarters, mode, h / 4)
        impulses.append(p)
    impulse = (impulses[0] + impulses[1]) + (impulses[2] + impulses[3])  # the halves' sums
    monkeypatch.setattr(_Landing, "radau_once", failing)
    q1, v1, p1 = radau.radau_step(q, v, mode, h)
    np.testing.assert_array_equal(np.concatenate([q1, v1, p1]), np.concatenate([*quarters, impulse]))
    assert not np.isfinite(radau.radau_step(q, v, mode, h, splits=1)[0]).any()
    short = 0.99 * radau.stable_step()  # failing at every length: RK4 takes a piece it is stable on
    monkeypatch.setattr(_Landing, "radau_once", lambda self, q, v, mode, step: failing(self, q, v, mode, h))
    np.testing.assert_array_equal(np.concatenate(radau.radau_step(q, v, mode, short)),
                                  np.concatenate(radau.rk4_step(q, v, mode, short)))
    pieces, impulses = (q, v), []
    for _ in range(4):  # 4 x short: split twice, down to RK4's stable step
        *pieces, p = radau.rk4_step(*pieces, mode, short)
        impulses.append(p)
    np.testing.assert_array_equal(np.concatenate(radau.radau_step(q, v, mode, 4.0 * short)),
                                  np.concatenate([*pieces, (impulses[0] + impulses[1]) + (impulses[2] + impulses[3])]))


def _split_alike_landing():
    from optimizer.design_space import study_landing

    m = load_model_file(DATA / "radau_split_alike_371.yaml")
    settings = study_landing(1e-3)
    return m, settings, landing(m.tree, m.scene, m.joints, settings, m.space)


def test_radaus_finer_run_asks_a_smaller_share_where_the_balance_split_the_coarser() -> None:
    """At the default tolerance: the landing study's trial 371, which ``auto`` lands on Radau IIA,
    its runs at h and h / 2 split alike by the momentum balance before the peak impact (so they
    agreed to 6.9e-8 while 2.9e-3 off the limit): the finer run of its pair asks a smaller share,
    and the pair's difference sees the split steps' error."""
    _, _, r = _split_alike_landing()
    assert r.integrator == RADAU and r.converged
    assert r.share < 1.0  # the finer runs' steps split at smaller shares than the first's
    assert r.error_estimate > 1e-5  # the split steps' error, not the 6.9e-8 of a pair split alike


@pytest.mark.slow
def test_radaus_estimate_on_a_pair_the_balance_split_bounds_its_error() -> None:
    """The same landing against RK4 at a quarter of RK4's stable step (the share as small): the
    error within the estimate and the tolerance (before: 2.9e-3 against an estimate of 6.9e-8)."""
    m, settings, r = _split_alike_landing()
    rk4 = _Landing(m.tree, m.scene, m.joints, replace(settings, integrator=RK4), m.space)
    reference = rk4.run(min(r.step, rk4.stable_step()) / 4.0, share=r.share)
    error = landing_difference(r, reference)
    assert error <= r.error_estimate and error <= 1e-3
