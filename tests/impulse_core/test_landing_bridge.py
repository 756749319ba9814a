"""The landing's Moreau-Jean bridge (``_Landing.bridge``): events that stall where no Painleve jam
explains them are crossed by velocity-level time steps.

- By hand: a uniform plank lying on flat ground on its two ends, sliding at V along x. Each
  Moreau-Jean step of length dt takes the free velocity (V, -g dt, 0) to the rigid law with e = 0
  and Coulomb friction mu: the normal impulse m g dt (half at each end, by the plank's symmetry)
  stops the fall; the slip goes on where V > mu g dt, so the friction impulse is -mu m g dt and
  the velocity after is (V - mu g dt, 0, 0) exactly; where V <= mu g dt the plank sticks: (0, 0, 0),
  the friction impulse -m V. Over a span s of n steps: V - mu g s, the position x0 + dt sum of
  the velocities after each step, and the totals' impulses m g s and -mu m g s. In space the
  same plank read as spatial, sliding along z as well: the slip's direction is kept.
- Random files 60337 (planar, friction 1: b5's two contacts 0.35 mm apart and two others cycled
  between modes at one instant, 5.7e-15 s an event), 60147 and 30891 (spatial) ended with exit 1
  ("the landing chatters"); they land through a bridge, meeting the contract's checks. (60337 no
  longer stalls once the position corrections keep the momentum; 30891's run is the test here.)
- The derivatives' replay does not follow a bridge: it says so.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import impulse_core.timedomain.landing_derivatives as derivatives
from impulse_core.errors import NumericalError
from impulse_core.evaluate import evaluate
from impulse_core.impact.laws import ImpactModel
from impulse_core.kinematics.spatial import PLANAR, SPATIAL
from impulse_core.model.joints import FREE
from impulse_core.model.tree import Body, Scene, Tree
from impulse_core.timedomain.events.paradox import BRIDGE_STEPS
from impulse_core.timedomain.events.rows import _Mode
from impulse_core.timedomain.events.run import _Landing
from impulse_core.timedomain.events.settings import SLIP_SPLITS
from impulse_core.timedomain.events.tally import _Totals
from impulse_core.timedomain.landing import LandingSettings, landing
from optimizer.config.model_file import load_model_file
from optimizer.evaluation.model_choice import TimeDomainResult
from optimizer.report.text import warnings

G = 9.81
MU = 0.4
MASS = 2.0
DATA = Path(__file__).parent / "data"


def _plank(space) -> _Landing:
    """A uniform 2 kg, 1 m plank lying along x on its two ends (flat ground)."""
    extra = {} if space is PLANAR else {"radius": 0.01, "gyration": math.sqrt(1.0 / 12.0)}
    plank = Body("plank", None, 1.0, MASS, 0.0, contacts=(0.0, 1.0), **extra)
    scene = Scene(speed=1.0, restitution=0.5, friction=MU, gravity=G, duration=0.1)  # the bridge: e = 0
    return _Landing(Tree((plank,)), scene, (FREE,), LandingSettings(), space)


def _resting(run: _Landing, slip: np.ndarray) -> tuple[np.ndarray, np.ndarray, _Mode]:
    """(q, v, mode) with the plank on the ground translating at ``slip`` (x; space: x, z)."""
    q, v = run.q0.copy(), np.zeros(run.nv)
    v[0] = slip[0]
    if len(slip) > 1:
        v[2] = slip[1]
    mode = run.flight()
    mode.closed[:] = True
    return q, v, mode


def _translation(run: _Landing, v: np.ndarray) -> np.ndarray:
    """The plank's velocity along the ground (x; space: x, z)."""
    return v[[0]] if run.planar else v[[0, 2]]


@pytest.mark.parametrize("space", [PLANAR, SPATIAL], ids=["planar", "spatial"])
@pytest.mark.parametrize("speed", [0.3, 1e-4], ids=["slides", "sticks"])
def test_a_bridge_step_is_moreau_jeans_by_hand(space, speed):
    run = _plank(space)
    direction = np.array([1.0]) if space is PLANAR else np.array([0.6, 0.8])
    q, v, mode = _resting(run, speed * direction)
    dt = 1e-3
    q1, v1, impulses, closed = run.bridge_step(q, v, mode, mode.closed, dt)
    fn, ft = impulses[: run.nc], impulses[run.nc :].reshape(run.dims - 1, run.nc).T
    assert closed.tolist() == [True, True]
    assert fn == pytest.approx([MASS * G * dt / 2] * 2, rel=1e-12)
    slides = speed > MU * G * dt
    after = (speed - MU * G * dt) * direction if slides else np.zeros_like(direction)
    assert _translation(run, v1) == pytest.approx(after, abs=1e-13)
    rest = np.delete(v1, [0] if space is PLANAR else [0, 2])
    assert np.max(np.abs(rest)) < 1e-13  # no fall, no turn
    friction = -(MU * MASS * G * dt if slides else MASS * speed) * direction
    assert ft.sum(axis=0) == pytest.approx(friction, rel=1e-10, abs=1e-15)
    if slides:  # Coulomb at each end: on the cone's edge, against the slip
        for k in range(2):
            assert ft[k] == pytest.approx(-MU * fn[k] * direction, rel=1e-10)
    assert q1 == pytest.approx(q + dt * v1, abs=1e-15)


@pytest.mark.parametrize("space", [PLANAR, SPATIAL], ids=["planar", "spatial"])
def test_a_bridge_crosses_its_span_and_counts_its_impulses(space):
    run = _plank(space)
    direction = np.array([1.0]) if space is PLANAR else np.array([0.6, 0.8])
    speed, span = 0.5, 0.02
    q, v, mode = _resting(run, speed * direction)
    totals = _Totals(np.zeros(run.nc), np.zeros((run.nc, run.dims - 1)))
    totals.impulse, totals.vectors = np.zeros(run.dims), np.zeros((run.dims, run.nc))
    q1, v1, mode1, t1 = run.bridge(q, v, mode, 0.1, totals, span)
    dt = span / BRIDGE_STEPS
    assert t1 == pytest.approx(0.1 + span, rel=1e-15)
    assert _translation(run, v1) == pytest.approx((speed - MU * G * span) * direction, rel=1e-12)
    travelled = dt * sum(speed - MU * G * dt * k for k in range(1, BRIDGE_STEPS + 1))
    assert _translation(run, q1 - q) == pytest.approx(travelled * direction, rel=1e-12)
    assert totals.normal.sum() == pytest.approx(MASS * G * span, rel=1e-12)
    assert totals.tangential.sum(axis=0) == pytest.approx(-MU * MASS * G * span * direction, rel=1e-10)
    assert totals.impulse[1] == pytest.approx(MASS * G * span, rel=1e-12)  # the world sum (y: up)
    assert totals.steps == BRIDGE_STEPS
    assert run.bridges == [(pytest.approx(0.1), span)]
    assert mode1.closed.tolist() == [True, True]  # the modes after: both ends resting, sliding along v
    assert mode1.slip[0] == pytest.approx(direction, rel=1e-9)


def test_a_stalled_random_landing_goes_on_through_a_bridge():
    """Random file 30891 (data/refused_30891.yaml, spatial, friction 1): its events stall at
    0.0646 s (a slow slip turning at each event, no Painleve jam); the run crosses them by a bridge
    and goes on, its momentum balanced, its impacts lawful, its first event the first-impact answer,
    the report naming the bridge (cut 2 ms after it). Where they stall is the run's: at its first
    step h 0.06462 s with the slow slip's steps split (the default), 0.06428 s regularised
    (slip_splits 0); at h / 2 0.06429 and 0.06428 s."""
    model = load_model_file(DATA / "refused_30891.yaml")
    tree, scene, settings = model.tree, model.scene, LandingSettings()
    run = _Landing(tree, scene, model.joints, settings, model.space)
    r = run.run(run.first_step(), until=lambda q, v, mode, totals: bool(run.bridges)
                and totals.times[-1] > run.bridges[0][0] + run.bridges[0][1] + 2e-3)
    assert r.bridges and 0.0646 < r.bridges[0][0] < 0.0647 and r.duration > r.bridges[0][0] + 2e-3
    # the bridge's steps are first order in the momentum where the velocity jumps ((A(q1) - A(q)) dv
    # a step): 1.5e-4 of the touchdown momentum over this cut run's 8 bridges, 1.1e-5 over the landing
    assert r.momentum_balance < 1e-3
    for e in r.events:  # the impacts' laws (pushing, inside the cone, no energy gained)
        assert np.all(e.external >= -1e-12 * np.max(np.abs(e.external)))
        assert np.all(np.linalg.norm(e.tangential, axis=1) <= scene.friction * e.external * (1 + 1e-9) + 1e-12)
        assert e.energy_after <= e.energy_before * (1 + 1e-9) + 1e-12
    first = evaluate(tree, scene, ImpactModel.FRICTION, model.space)  # the contract's first event
    assert np.max(np.abs(r.events[0].external - first.external)) <= 1e-9 * np.max(np.abs(first.external))
    reported = replace(r, error_estimate=0.0, tolerance=settings.tolerance)  # as landing() gives it
    said = warnings(model, TimeDomainResult("landing", "", reported, r.events[0].v_minus, settings))
    assert any(w.startswith("events stalled") and f"t = {r.bridges[0][0]:.6g} s" in w for w in said)


def test_the_derivatives_replay_refuses_a_bridge(monkeypatch):
    run = _plank(PLANAR)
    q, v, mode = _resting(run, np.array([0.5]))
    real = derivatives.taped_run

    def taped(*args, **kwargs):
        result, tape, landed = real(*args, **kwargs)
        return result, [("bridge", q, v, mode, 1e-3), *tape], landed

    monkeypatch.setattr(derivatives, "taped_run", taped)
    with pytest.raises(NumericalError, match="Moreau-Jean"):
        derivatives.landing_gradient(run.tree, run.scene, (FREE,), LandingSettings(), step=0.01)


@pytest.mark.parametrize("space", [PLANAR, SPATIAL], ids=["planar", "spatial"])
def test_a_bridge_step_keeps_the_linear_momentum_across_a_velocity_jump(space):
    """A tumbling plank 2 mm above the ground whose far end strikes it within one Moreau-Jean step:
    the momentum at the step's end is the start's plus the weight's and the contact's impulses, to
    rounding (``balance_kept``). Taking the velocity after at q + dt v+ while the forces were at q
    changes it by dt times the jump in the Coriolis terms (first order: random file 60690's
    balance 1.1e-4 through two bridges)."""
    run = _plank(space)
    q, v, mode = run.q0.copy(), np.zeros(run.nv), run.flight()
    q[1] += 2e-3
    v[1], v[2 if space is PLANAR else 5] = -1.0, -5.0  # the far end falls at 6 m/s, the near one at 1 m/s
    dt = 1e-3
    q1, v1, impulses, closed = run.bridge_step(q, v, mode, mode.closed, dt)
    assert closed.tolist() == [False, True] and impulses[1] > 0.1  # the far end struck
    totals = _Totals(np.zeros(run.nc), np.zeros((run.nc, run.dims - 1)))
    totals.impulse, totals.vectors = np.zeros(run.dims), np.zeros((run.dims, run.nc))
    run.add(totals, impulses, q, v)
    change = run.point(q1, v1).momentum[:, 0] - run.point(q, v).momentum[:, 0]
    assert np.max(np.abs(change - run.weight(dt) - totals.impulse)) <= 1e-14 * MASS * 6.0
    shift = v1 - (q1 - q) / dt  # q1 = q + dt v+; v1 = v+ shifted along the base's translation alone
    assert np.max(np.abs(shift[run.dims:])) <= 1e-9 and 0 < np.max(np.abs(shift)) <= 1e-2


@pytest.mark.parametrize("divisor, splits, start", [(400, 0, 0.17765), (800, 0, 0.17458), (400, SLIP_SPLITS, 0.23461)],
                         ids=["jam_fails", "diverges_after_jams", "split_jam_fails"])
def test_painleves_paradox_that_a_jam_cannot_end_is_bridged(divisor, splits, start):
    """Random file 60690 (data/singular_stage_60690.yaml: a light rod on its tip, friction 0.3),
    its slow slip's direction regularised (slip_splits 0, as the file was found): at T / 400 the
    jam at t = 0.1777 s no longer stops the tip's slip (`take_jam` raised its Painleve error,
    exit 1); at T / 800 a step sliding into the paradox right after two jams diverged. Split
    (the default), the runs at T / 100, T / 400 and T / 800 jam from 0.174 s on and meet, at
    0.2346 s, a jam that does not end the slip (no divergence). Each run now crosses there by a
    bridge and goes on, its momentum balanced (cut at the bridge's end)."""
    model = load_model_file(DATA / "singular_stage_60690.yaml")
    run = _Landing(model.tree, model.scene, model.joints, LandingSettings(slip_splits=splits), model.space)
    with np.errstate(all="ignore"):
        r = run.run(model.scene.duration / divisor, until=lambda q, v, mode, totals: bool(run.bridges))
    assert len(r.bridges) == 1 and r.bridges[0][0] == pytest.approx(start, abs=1e-5)
    assert run._jams[1] >= 1  # the run had met the paradox
    assert r.momentum_balance <= 1e-5


def test_a_paradox_that_outlasts_a_jam_is_bridged_from_after_it():
    """Random file 61645 (data/unjammed_61645.yaml: a lone 79 g rod on a heightfield, friction 1):
    its run at h / 2 jams the tip at t = 0.367425 s (0.367424 s regularised, slip_splits 0), and the
    mode after that jam slides in the paradox again, where a second jam at that instant cannot be
    taken (exit 1 before). The run now
    keeps the jam (its event and impulse) and crosses from the state after it by a bridge; the
    landing converges (two runs) with its momentum balanced, the jam the last event."""
    model = load_model_file(DATA / "unjammed_61645.yaml")
    r = landing(model.tree, model.scene, model.joints, LandingSettings(), space=model.space)
    jams = [e for e in r.events if e.jam]
    assert r.converged and len(jams) == 1 and jams[0] is r.events[-1]
    assert len(r.bridges) == 1 and r.bridges[0][0] == jams[0].time == pytest.approx(0.367425, abs=1e-6)
    assert r.momentum_balance <= 1e-6


def test_a_bridge_that_blows_up_stops_the_run_as_its_divergence(monkeypatch):
    """Random file 32113 (data/turning_slip_32113.yaml, the whole 0.3 s): its first run diverges
    after a slide, and the bridge from that step's start blows up too (its rotation coordinates
    overflowed the chart, an OverflowError that reached the CLI as an internal error). The run
    now stops with the divergence, which :func:`landing` answers with a shorter step: the first
    run raises Diverged. Its slow slip's direction regularised (slip_splits 0, as the file was
    found); split (the default), the first run does not diverge."""
    from impulse_core.timedomain.events.settings import Diverged

    m = load_model_file(DATA / "turning_slip_32113.yaml")
    run = _Landing(m.tree, m.scene, m.joints, LandingSettings(slip_splits=0), space=m.space)
    tried = []
    real = _Landing.bridge
    monkeypatch.setattr(_Landing, "bridge", lambda self, *a: tried.append(a[3]) or real(self, *a))
    with pytest.raises(Diverged, match="diverged"):
        run.run(run.first_step())
    assert tried and not run.bridges  # the bridge was tried, and blew up
