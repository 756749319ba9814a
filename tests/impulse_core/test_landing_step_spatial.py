"""The landing's compiled RK4 step in space (impulse_core.timedomain.landing_step with a
heightfield and two tangents per contact) equals the numpy step in every kind of mode (flight,
sticking, sliding with the direction turning with the slip or held at the mode's, regularised
below the step's core, stops), on flat ground and on a heightfield, and whole spatial landings
run alike on every step code."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from impulse_core.kinematics.spatial import SPATIAL
from impulse_core.timedomain.events.rows import _Mode, _mode_rows
from impulse_core.timedomain.events.run import _Landing
from impulse_core.timedomain.landing import C_CODE, NUMPY_CODE, VM_CODE, LandingSettings, landing, landing_difference
from tests.impulse_core.test_landing_spatial import _spinning_pair, _splayed_leg
from tests.impulse_core.test_landing_step import _rel


def _file(name: str, friction: float, duration: float | None = None):
    from optimizer.config.model_file import load_model_file

    m = load_model_file(f"configs/{name}.yaml")
    scene = replace(m.scene, friction=friction, duration=duration or m.scene.duration)
    return m.tree, m.joints, scene


def _legs():
    yield _splayed_leg(0, 0.4)
    yield _splayed_leg(1, 1.0)
    yield _splayed_leg(2, 0.0)  # frictionless: no tangent rows
    yield _file("spatial_case3", 0.5)  # 14 DOF, 4 contacts, splayed toes
    yield _file("spatial_heightfield", 0.6)  # a heightfield: the normals turn the rows


def _random_mode(rng: np.random.Generator, run: _Landing, slip: np.ndarray) -> _Mode:
    """Closed contacts (60 %), half of them sliding: along their slip turned by up to 60 degrees
    (the direction follows the slip), or against it (the mode's own direction); random stops."""
    closed = rng.random(run.nc) < 0.6
    sliding = closed & (rng.random(run.nc) < 0.5) & (run.mu > 0)
    turn = rng.uniform(-1.0, 1.0, run.nc) + np.where(rng.random(run.nc) < 0.25, np.pi, 0.0)
    c, s = np.cos(turn), np.sin(turn)
    d = np.column_stack([c * slip[:, 0] - s * slip[:, 1], s * slip[:, 0] + c * slip[:, 1]])
    d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)
    stop = np.zeros(run.nv, int)
    dofs = list(run.fast.stop_dofs)
    stop[dofs] = rng.choice([-1, 0, 1], len(dofs))
    return _Mode(closed, np.where(sliding[:, None], d, 0.0), stop)


def _random_state(rng: np.random.Generator, fast: _Landing, ref: _Landing, k: int, h_max: float
                  ) -> tuple[np.ndarray, np.ndarray, object, _Mode, float]:
    """Case k of a random spatial step: (q, v) near touchdown (slow at odd k), the point at them,
    a random mode (:func:`_random_mode`; flight at k = 0, its stops kept) with its redundancy, and
    a step length in [1e-4, h_max]."""
    q = fast.q0 + 0.02 * rng.standard_normal(fast.nv)
    v = rng.standard_normal(fast.nv) * (0.05 if k % 2 else 1.0)
    pt = ref.point(q, v)
    mode, h = _random_mode(rng, fast, pt.slip), float(rng.uniform(1e-4, h_max))
    if k == 0:
        mode.closed[:], mode.slip[:] = False, 0.0
    mode.redundant = ref.redundant(pt, mode)
    return q, v, pt, mode, h


def _tolerance(ref: _Landing, q: np.ndarray, v: np.ndarray, mode: _Mode) -> float:
    """1e-12, or rounding's 1e-16 times the condition number of the mode's Delassus matrix at
    (q, v) where that is larger (all contacts of a splayed leg sticking: 3e7 seen, the two paths'
    impulses then 2e-10 apart: numpy's pivoted LU against the compiled elimination)."""
    rows = _mode_rows(ref.point(q, v), mode, ref.mu)
    if not rows.G.shape[0] or mode.redundant:
        return 1e-12
    W = rows.G @ np.linalg.solve(ref.point(q, v).M, rows.F.T)
    return max(1e-12, 1e-16 * float(np.linalg.cond(W)))


def _compare_ends(fast: _Landing, ref: _Landing, q, v, q1, v1, mode: _Mode, tol: float) -> None:
    """The compiled step's end figures against the numpy path's at its ends (to ``tol``)."""
    end = fast.ended(q1, v1, mode)
    w, r = fast.witness_and_rate(q1, v1, mode)
    rw, rr = ref.witness_and_rate(q1, v1, mode)
    finite = np.isfinite(rw)
    assert np.array_equal(finite, np.isfinite(w)) and np.array_equal(np.isnan(r), np.isnan(rr))
    assert _rel(w[finite], rw[finite]) <= tol and _rel(r[~np.isnan(r)], rr[~np.isnan(rr)]) <= tol
    p0, p1 = ref.point(q, v), ref.point(q1, v1)
    assert end.slip.shape == end.ft.shape == (fast.nc, 2) and end.normal.shape == (fast.nc, 3)
    assert _rel(end.slip, p1.slip) <= 1e-12
    assert _rel(end.momentum0, p0.momentum[:, 0]) <= 1e-12 and _rel(end.momentum1, p1.momentum[:, 0]) <= tol
    assert _rel(end.gap0, p0.gap) <= 1e-12 and _rel(end.vn0, p0.vn(v)) <= 1e-12
    assert _rel(end.normal, p1.normal) <= 1e-12 and end.kinetic == pytest.approx(p1.kinetic, rel=1e-12)


@pytest.mark.parametrize("leg", range(5))
def test_the_compiled_spatial_step_equals_the_numpy_step(leg):
    """Random (q, v) near touchdown in random modes (flight, closed sticking, sliding along a
    slip that turns within the step or against it, stops) with random cores (the sliding
    direction regularised below them, or exact above): the compiled step's state, impulses,
    ends' figures and witnesses equal the numpy path's to 1e-12 (or rounding's share of an
    ill-conditioned mode, :func:`_tolerance`); a redundant mode is left to numpy; the compiled
    projection equals numpy's (velocities to 10 x that, corrections and impulses to 100 x). Every
    kind is met: a turning direction, one held at d, one regularised, a step that steers
    (:meth:`_Landing.steer`) with a positive core."""
    tree, laws, scene = list(_legs())[leg]
    fast = _Landing(tree, scene, laws, LandingSettings(step_code=VM_CODE, integrator="rk4"), SPATIAL)
    ref = _Landing(tree, scene, laws, LandingSettings(step_code=NUMPY_CODE, integrator="rk4"), SPATIAL)
    assert fast.fast is not None and ref.fast is None
    rng = np.random.default_rng(leg)
    kinds, projected, steered = set(), 0, 0
    for k in range(16):
        q = fast.q0 + 0.02 * rng.standard_normal(fast.nv)
        v = rng.standard_normal(fast.nv) * (0.05 if k % 2 else 1.0)  # slow: slip below the core
        pt = ref.point(q, v)
        mode, h = _random_mode(rng, fast, pt.slip), float(rng.uniform(1e-4, 2e-3))
        if k == 0:  # flight
            mode.closed[:], mode.slip[:] = False, 0.0
        mode.redundant = ref.redundant(pt, mode)
        speed = np.linalg.norm(pt.slip, axis=1)
        mode.core[:] = rng.uniform(0.0, 2.0, fast.nc) * speed
        tol = _tolerance(ref, q, v, mode)
        moving = mode.closed & mode.sliding
        along = moving & (np.sum(pt.slip * mode.slip, axis=1) > 0)
        kinds |= {"turning"} if np.any(along) else set()
        kinds |= {"held"} if np.any(moving & ~along) else set()
        kinds |= {"regularised"} if np.any(along & (speed < mode.core)) else set()
        kinds |= {"sticking"} if np.any(mode.closed & ~mode.sliding) and fast.mu > 0 else set()
        kinds |= {"flight"} if not np.any(mode.closed) else set()
        # the step itself, at the given core
        end = fast.fast.step(q, v, h, mode)
        assert (end is None) == mode.redundant
        rq, rv, rimpulse = ref.rk4_step(q, v, mode, h)
        if end is not None:
            assert _rel(end.q, rq) <= tol and _rel(end.v, rv) <= tol and _rel(end.impulse, rimpulse) <= tol
        # the landing's step (steered), its end's figures and the projection after it
        a, b = mode.copy(), mode.copy()
        q1, v1, impulse = fast.step(q, v, a, h)
        rq, rv, rimpulse = ref.step(q, v, b, h)
        assert _rel(a.core, b.core) <= 1e-12 or np.max(b.core) == 0.0 == np.max(a.core)
        steered += bool(np.any(b.core > 0))
        assert _rel(q1, rq) <= tol and _rel(v1, rv) <= tol and _rel(impulse, rimpulse) <= tol
        if mode.redundant:
            assert fast.ended(q1, v1, a) is None
            continue
        _compare_ends(fast, ref, q, v, q1, v1, a, tol)
        compiled = fast.fast.project(q1, v1, a) is not None and not np.any(~a.closed & (fast.ended(q1, v1).gap < 0)) \
            and not np.any((a.stop == 0) & (fast.beyond(q1) != 0))
        projected += compiled
        (pq, pv, pimpulse), (rq, rv, rimpulse) = fast.project(q1, v1, a), ref.project(q1, v1, b)
        scale = max(np.max(np.abs(v1)), np.max(np.abs(rv)))  # a locked tree projects v to rounding's 1e-11
        # v is projected at the corrected q, which the two reach up to 100 tol apart: 10 tol on v (1.75 tol
        # measured on an AVX2 machine, where numpy's kernels round otherwise than on the AVX-512 one)
        assert _rel(pq - q1, rq - q1) <= 100 * tol and np.max(np.abs(pv - rv)) <= 10 * tol * scale
        assert _rel(pimpulse, rimpulse) <= 100 * tol or np.max(np.abs(rimpulse)) == 0.0 == np.max(np.abs(pimpulse))
    assert projected >= 2
    expected = {"flight"} | ({"turning", "held", "regularised", "sticking"} if fast.mu > 0 else set())
    assert expected <= kinds
    assert steered >= 1 or fast.mu == 0


def test_a_redundant_spatial_mode_is_left_to_numpy():
    """Least-norm forces are not the compiled solve's: a mode marked redundant takes the numpy
    step (no compiled end), as does a non-finite compiled result."""
    tree, laws, scene = _splayed_leg(1, 1.0)
    run = _Landing(tree, scene, laws, LandingSettings(step_code=VM_CODE, integrator="rk4"), SPATIAL)
    mode = _Mode(np.ones(run.nc, bool), np.zeros((run.nc, 2)), np.zeros(run.nv, int), redundant=True)
    q1, v1, _ = run.step(run.q0, np.zeros(run.nv), mode, 1e-3)
    assert run.ended(q1, v1, mode) is None
    mode.redundant = False
    assert run.fast.step(run.q0, np.full(run.nv, np.nan), 1e-3, mode) is None


def test_the_direction_turns_with_the_slip_within_the_step():
    """A sliding contact's force follows its slip within the step (not the mode's d): a step whose
    slip turns differs from the same step with the direction frozen at d (the plane's law)."""
    tree, laws, scene = _splayed_leg(1, 1.0)
    run = _Landing(tree, scene, laws, LandingSettings(step_code=VM_CODE, integrator="rk4"), SPATIAL)
    rng = np.random.default_rng(7)
    q, v = run.q0 + 0.02 * rng.standard_normal(run.nv), rng.standard_normal(run.nv)
    slip = run.point(q, v).slip
    closed = np.ones(run.nc, bool)
    d = slip / np.linalg.norm(slip, axis=1, keepdims=True)
    turned = np.column_stack([d[:, 0] * 0.8 - d[:, 1] * 0.6, d[:, 0] * 0.6 + d[:, 1] * 0.8])  # 37 degrees off
    follows = run.fast.step(q, v, 1e-3, _Mode(closed, d, np.zeros(run.nv, int)))
    started = run.fast.step(q, v, 1e-3, _Mode(closed, turned, np.zeros(run.nv, int)))
    # u = s / |s| in both (d only picks the side): the same step
    assert _rel(started.v, follows.v) <= 1e-12
    u = follows.slip / np.linalg.norm(follows.slip, axis=1, keepdims=True)
    assert _rel(follows.ft, -run.mu * follows.fn[:, None] * u) <= 1e-12  # against the slip at the step's end


def _shortened(case: tuple, duration: float) -> tuple:
    """(tree, laws, scene) landing for ``duration`` only (leg 1: 55 impacts in 15 ms)."""
    tree, laws, scene = case
    return tree, laws, replace(scene, duration=duration)


@pytest.mark.parametrize("case", ["leg0", "leg1", pytest.param("leg3", marks=pytest.mark.slow), "case3", "heightfield",
                                  "spinning"])
def test_spatial_landings_run_alike_on_the_compiled_step(case):
    """Whole spatial landings (random splayed legs with friction and stops, spatial case 3 for
    0.05 s with friction, the heightfield file, a base turning beyond the chart: re-centred
    coordinates): the virtual machine's compiled steps take the numpy run's decisions (steps,
    events) and land 1e-9 from it."""
    tree, laws, scene = {
        "leg0": lambda: _splayed_leg(0, 0.4), "leg1": lambda: _shortened(_splayed_leg(1, 1.0), 0.015),
        "leg3": lambda: _splayed_leg(3, 1.0, 0.0), "case3": lambda: _file("spatial_case3", 0.5, 0.05),
        "heightfield": lambda: _file("spatial_heightfield", 0.6, 0.02), "spinning": _spinning_pair,
    }[case]()
    h = 2e-3 if case == "spinning" else 5e-4
    ref = _Landing(tree, scene, laws, LandingSettings(step_code=NUMPY_CODE, integrator="rk4"), SPATIAL).run(h)
    r = _Landing(tree, scene, laws, LandingSettings(step_code=VM_CODE, integrator="rk4"), SPATIAL).run(h)
    assert (r.n_steps, len(r.events)) == (ref.n_steps, len(ref.events)) and len(r.events) >= 2
    assert [e.kind for e in r.events] == [e.kind for e in ref.events]
    assert landing_difference(r, ref) <= 1e-9
    assert _rel(r.q_final, ref.q_final) <= 1e-9 and _rel(r.v_final, ref.v_final) <= 1e-8


def test_a_spatial_landing_runs_alike_in_c():
    """The step compiled to C (through the default compile cache) lands as numpy does."""
    tree, laws, scene = _splayed_leg(0, 0.4)
    ref = _Landing(tree, scene, laws, LandingSettings(step_code=NUMPY_CODE, integrator="rk4"), SPATIAL).run(5e-4)
    r = _Landing(tree, scene, laws, LandingSettings(step_code=C_CODE, integrator="rk4"), SPATIAL).run(5e-4)
    assert (r.n_steps, len(r.events)) == (ref.n_steps, len(ref.events))
    assert landing_difference(r, ref) <= 1e-9 and _rel(r.q_final, ref.q_final) <= 1e-9


@pytest.mark.parametrize("integrator, order", [("rk4", 5), ("implicit", 3)])
def test_a_step_s_momentum_balance_on_a_heightfield_has_its_integrator_s_order(integrator, order):
    """Spatial case 3's toes held on the heightfield's rising cell, sliding at 5 m/s under
    gravity: their normals turn within a step. A step's momentum balance takes each stage's force
    along its own normal and tangents, so its residual falls as h^5 under RK4 and h^3 under ROS2
    (per step; measured ratios 32 and 8 per halving). Along the end's normals alone it fell as
    h^2 (ratio 4: random file 30649's steps split to h / 2^13). The compiled step's vectors and
    balance equal the numpy step's."""
    tree, laws, scene = _file("spatial_heightfield", 0.6)
    runs = [_Landing(tree, replace(scene, gravity=9.81), laws, LandingSettings(step_code=code, integrator=integrator),
                     SPATIAL) for code in (VM_CODE, NUMPY_CODE)]
    q, v = runs[0].q0.copy(), np.zeros(runs[0].nv)
    v[:3] = [4.0, 0.0, 3.0]
    pt = runs[1].point(q, v)
    mode = _Mode(np.ones(pt.gap.size, bool), pt.slip / np.linalg.norm(pt.slip, axis=1, keepdims=True),
                 np.zeros(v.size, int))
    assert np.ptp(pt.normal[:, 0]) > 0.05 and not runs[1].redundant(pt, mode)
    residuals = []
    for h in (1e-3, 5e-4):
        (q1, v1, impulse), (rq, rv, rimpulse) = (run.step(q, v, mode.copy(), h) for run in runs)
        fast, ref = runs
        assert np.min(rimpulse[: ref.nc]) > 0  # every toe pressed
        balance = ref.momentum_change(pt.momentum[:, 0], rq, rv, rimpulse)
        assert _rel(fast.vectors, ref.vectors) <= 1e-12 and _rel(fast.ended(q1, v1).balance, balance) <= 1e-9
        residuals.append(np.max(np.abs(balance - ref.weight(h))))
    assert residuals[0] / residuals[1] >= 2.0 ** order / 2.0


def test_a_heightfield_landing_s_totals_take_the_steps_vectors():
    """Over a 0.15 s landing of spatial case 3 on the heightfield with friction (66 events), the
    run's momentum balance (its totals' impulse vectors against the momentum change) closes to
    1.4e-9 of the touchdown momentum; with the steps' impulses along their ends' normals instead
    of their stages' (a planted mistake) it was 2.6e-8."""
    tree, laws, scene = _file("spatial_heightfield", 0.6)
    r = landing(tree, replace(scene, gravity=9.81, duration=0.15, restitution=0.3), laws, LandingSettings(), SPATIAL)
    assert r.converged and len(r.events) > 20
    assert r.momentum_balance <= 6e-9
