"""The landing's compiled RK4 step (impulse_core.timedomain.landing_step) equals the numpy step
(rows built and solved per stage) on random modes and legs, its end figures equal the numpy
witnesses and momenta, C equals the virtual machine, and a landing runs alike on every code."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from impulse_core.model.terrain import Terrain
from impulse_core.model.tree import Tree
from impulse_core.timedomain.events.location import location_offsets
from impulse_core.timedomain.events.rows import _Mode
from impulse_core.timedomain.events.run import _Landing
from impulse_core.timedomain.landing import C_CODE, NUMPY_CODE, VM_CODE, LandingSettings, landing_difference
from impulse_core.timedomain.landing_step import (
    compiled_step_function,
    landing_projection_function,
    landing_step_function,
)
from tests.impulse_core.test_landing import _random_leg


def _case3(friction: float = 0.5, terrain: Terrain | None = None):
    from optimizer.config.model_file import load_model_file

    m = load_model_file("configs/landing_case3.yaml")
    scene = replace(m.scene, friction=friction, terrain=terrain or m.scene.terrain)
    return m.tree, m.joints, scene


def _legs():
    yield _case3()
    yield _case3(0.0)
    yield _case3(0.8, Terrain((-1.0, 1.0), (-0.15, 0.05)))  # sloped: the normals turn the rows
    for seed in range(3):
        tree, laws, scene = _random_leg(seed)
        yield tree, laws, scene
    tree, laws, scene = _random_leg(1)  # centres of mass off the rods (PLANAR_OFFSET's design vector)
    yield Tree(tuple(replace(b, com_offset=(0.01 * (k % 3 - 1), 0.0)) for k, b in enumerate(tree.bodies))), laws, scene


def _random_mode(rng: np.random.Generator, run: _Landing) -> _Mode:
    closed = rng.random(run.nc) < 0.6
    slip = np.where(closed & (rng.random(run.nc) < 0.5), rng.choice([-1.0, 1.0], run.nc), 0.0)
    stop = np.zeros(run.nv, int)
    dofs = list(run.fast.stop_dofs)
    stop[dofs] = rng.choice([-1, 0, 1], len(dofs))
    return _Mode(closed, slip, stop)


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(np.asarray(a) - b), initial=0.0) / max(float(np.max(np.abs(b), initial=0.0)), 1e-300))


def compare_step(fast: _Landing, ref: _Landing, reference_step, q: np.ndarray, v: np.ndarray, mode: _Mode, h: float):
    """One step of ``fast`` (a compiled code) against ``reference_step`` of the numpy run ``ref``
    (rk4_step, implicit_step) from (q, v) in ``mode`` (its redundancy marked as resolve() marks
    it): the step, its impulses and its end's witnesses and rates to 1e-12; returns (q1, v1,
    impulse, the compiled end or None where the mode is left to numpy)."""
    mode.redundant = ref.redundant(ref.point(q, v), mode)
    q1, v1, impulse = fast.step(q, v, mode, h)
    end = fast.ended(q1, v1, mode)
    assert (end is None) == mode.redundant  # the compiled path answered, but for least-norm forces
    rq, rv, rimpulse = reference_step(q, v, mode, h)
    assert _rel(q1, rq) <= 1e-12 and _rel(v1, rv) <= 1e-12
    assert _rel(impulse, rimpulse) <= 1e-12 or np.max(np.abs(rimpulse)) == 0.0 == np.max(np.abs(impulse))
    w, r = fast.witness_and_rate(q1, v1, mode)
    rw, rr = ref.witness_and_rate(q1, v1, mode)
    finite = np.isfinite(rw)
    assert np.array_equal(finite, np.isfinite(w)) and np.array_equal(np.isnan(r), np.isnan(rr))
    assert _rel(w[finite], rw[finite]) <= 1e-12 and _rel(r[~np.isnan(r)], rr[~np.isnan(rr)]) <= 1e-12
    return q1, v1, impulse, end


@pytest.mark.parametrize("leg", range(7))
def test_the_compiled_step_equals_the_numpy_step(leg):
    """Random (q, v) near touchdown in random modes (closed, sliding either way, on either stop;
    a redundant one, e.g. more rows than DOFs, is the numpy path's least-norm split):
    the compiled step's state, contact impulses, momenta, kinetic energy, and its end's witnesses
    and their rates, equal the numpy path's to 1e-12 (relative to each list's largest entry); the
    compiled projection's velocities to 1e-12, its position correction and impulses to 1e-10 (the
    numpy path's least squares against the compiled elimination)."""
    tree, laws, scene = list(_legs())[leg]
    fast = _Landing(tree, scene, laws, LandingSettings(step_code=VM_CODE, integrator="rk4"))
    ref = _Landing(tree, scene, laws, LandingSettings(step_code=NUMPY_CODE, integrator="rk4"))
    rng = np.random.default_rng(leg)
    projected = 0
    for _ in range(12):
        q = fast.q0 + 0.02 * rng.standard_normal(fast.nv)
        v = rng.standard_normal(fast.nv)
        mode, h = _random_mode(rng, fast), float(rng.uniform(1e-4, 2e-3))
        q1, v1, impulse, end = compare_step(fast, ref, ref.rk4_step, q, v, mode, h)
        if end is None:
            continue
        p0, p1 = ref.point(q, v), ref.point(q1, v1)
        assert _rel(end.momentum0, p0.momentum[:, 0]) <= 1e-12 and _rel(end.momentum1, p1.momentum[:, 0]) <= 1e-12
        assert _rel(end.gap0, p0.gap) <= 1e-12 and _rel(end.vn0, p0.vn(v)) <= 1e-12
        assert _rel(end.normal, p1.normal) <= 1e-12 and end.kinetic == pytest.approx(p1.kinetic, rel=1e-12)
        # the projection after the step: compiled where the placement is the mode's, else numpy's
        compiled = fast.fast.project(q1, v1, mode) is not None and not np.any(~mode.closed & (end.gap < 0)) \
            and not np.any((mode.stop == 0) & (fast.beyond(q1) != 0))
        projected += compiled
        (pq, pv, pimpulse), (rq, rv, rimpulse) = fast.project(q1, v1, mode), ref.project(q1, v1, mode)
        assert _rel(pq - q1, rq - q1) <= 1e-10 and _rel(pv, rv) <= 1e-12
        assert _rel(pimpulse, rimpulse) <= 1e-10 or np.max(np.abs(rimpulse)) == 0.0 == np.max(np.abs(pimpulse))
    assert projected >= 2


def test_a_redundant_mode_is_left_to_numpy():
    """Least-norm forces (identical toes on one point) are not the compiled solve's: numpy answers."""
    tree, laws, scene = _case3()
    run = _Landing(tree, scene, laws, LandingSettings(step_code=VM_CODE))
    mode = _Mode(np.ones(run.nc, bool), np.zeros(run.nc), np.zeros(run.nv, int), redundant=True)
    q1, v1, _ = run.step(run.q0, np.zeros(run.nv), mode, 1e-3)
    assert run.ended(q1, v1, mode) is None


def test_c_equals_the_virtual_machine(tmp_path, monkeypatch):
    """The step and projection compiled to C through the compile cache give the virtual
    machine's numbers."""
    monkeypatch.setenv("FOOTOPT_CACHE_DIR", str(tmp_path))
    tree, laws, scene = _random_leg(0)
    run = _Landing(tree, scene, laws, LandingSettings(step_code=VM_CODE, integrator="rk4"))
    compiled_step_function.cache_clear()
    key = (run.topology, scene.terrain, run.fast.stop_dofs)
    compiled = compiled_step_function(*key)
    assert len(list(tmp_path.iterdir())) >= 2  # both built into this cache
    rng = np.random.default_rng(3)
    for c, vm in zip(compiled, (landing_step_function(*key), landing_projection_function(*key))):
        assert c is not vm
        args = [rng.uniform(-1, 1, vm.size1_in(i)) for i in range(vm.n_in())]
        for a, b in zip(c.call(args), vm.call(args)):
            a, b = a.full(), b.full()
            assert np.max(np.abs(a - b)) <= 1e-12 * max(1.0, float(np.max(np.abs(b))))
    compiled_step_function.cache_clear()  # the next test's C comes from the default cache


@pytest.fixture(scope="module")
def case3_on_numpy() -> tuple:
    """Case 3 for 0.1 s at a coarse step: (tree, laws, scene) and its landing on the numpy step,
    the reference of every compiled code (landed once)."""
    tree, laws, scene = _case3()
    scene = replace(scene, duration=0.1)
    return (tree, laws, scene), _Landing(tree, scene, laws, LandingSettings(step_code=NUMPY_CODE)).run(2e-3)


@pytest.mark.parametrize("code", [VM_CODE, C_CODE])
def test_a_landing_runs_alike_on_every_step_code(code, case3_on_numpy):
    """Case 3 for 0.1 s at a coarse step (impacts, toe bounces, stops, sliding): the compiled
    steps take the numpy run's decisions (steps, events) and land 1e-10 from it."""
    (tree, laws, scene), ref = case3_on_numpy
    r = _Landing(tree, scene, laws, LandingSettings(step_code=code)).run(2e-3)
    assert (r.n_steps, len(r.events)) == (ref.n_steps, len(ref.events))
    assert landing_difference(r, ref) <= 1e-10
    assert _rel(r.q_final, ref.q_final) <= 1e-10 and _rel(r.v_final, ref.v_final) <= 1e-8


def test_an_unknown_step_code_is_an_error():
    from impulse_core.errors import ModelError

    tree, laws, scene = _case3()
    with pytest.raises(ModelError, match="step_code"):
        _Landing(tree, scene, laws, LandingSettings(step_code="fortran"))


def test_the_first_step_is_rk4s_longest_stable_one():
    """landing()'s default first step: RK4's stability limit for the joint laws at touchdown
    (case 3: 2 / 750 1/s = 2.7 ms, between 0.3 s / 200 and / 100), duration / 100 without joint
    laws, duration / 200 for the implicit integrator; a given step is kept."""
    tree, laws, scene = _case3()
    T = scene.duration
    run = _Landing(tree, scene, laws, LandingSettings())
    assert run.method == "rk4" and T / 200 < run.first_step() < T / 100
    assert run.first_step() * run.rate == pytest.approx(2.0, rel=1e-12)
    assert _Landing(tree, scene, (), LandingSettings()).first_step() == pytest.approx(T / 100, rel=1e-12)
    implicit = _Landing(tree, scene, laws, LandingSettings(integrator="implicit"))
    assert implicit.first_step() == pytest.approx(T / 200, rel=1e-12)
    assert _Landing(tree, scene, laws, LandingSettings(step=1e-3)).first_step() == 1e-3


def test_auto_takes_rk4_from_its_stable_step_up_to_its_threshold(monkeypatch):
    """Without a given step, ``auto`` takes RK4 from its stable step (2 / rate) unless duration /
    200 times the rate exceeds AUTO_IMPLICIT (32), then ROS2 from duration / 200; with a given
    step, RK4 while that step is stable (RK4_STABLE). Random file 30039 (h x rate 3.6), on both
    sides of a threshold moved to its own h x rate, and the light-tipped leg over the study's 0.15 s (about 200)."""
    from pathlib import Path

    import impulse_core.timedomain.events.run as events_run
    import impulse_core.timedomain.landing as landing_module
    from optimizer.config.model_file import load_model_file
    from tests.impulse_core.test_landing import _light_tip_leg

    m = load_model_file(Path(__file__).parent / "data" / "random_30039.yaml")
    T = m.scene.duration
    run = _Landing(m.tree, m.scene, m.joints, LandingSettings(), m.space)
    assert run.method == "rk4" and run.first_step() == pytest.approx(2.0 / run.rate, rel=1e-12)
    x = T / 200 * run.rate
    assert 2.0 < x < landing_module.AUTO_IMPLICIT == 32.0
    for threshold, method, step in ((x * (1 + 1e-9), "rk4", 2.0 / run.rate), (x * (1 - 1e-9), "implicit", T / 200)):
        monkeypatch.setattr(events_run, "AUTO_IMPLICIT", threshold)  # where _Landing reads it
        r = _Landing(m.tree, m.scene, m.joints, LandingSettings(), m.space)
        assert (r.method, r.first_step()) == (method, pytest.approx(step, rel=1e-12))
    monkeypatch.undo()
    given = 1.01 * 2.0 / run.rate
    assert _Landing(m.tree, m.scene, m.joints, LandingSettings(step=given), m.space).method == "implicit"
    assert _Landing(m.tree, m.scene, m.joints, LandingSettings(step=given / 1.02), m.space).method == "rk4"
    tree, laws, scene = _light_tip_leg()
    scene = replace(scene, duration=0.15)  # the study's
    stiff = _Landing(tree, scene, laws, LandingSettings())
    assert scene.duration / 200 * stiff.rate > 32.0 and stiff.method == "implicit"


@pytest.mark.parametrize("seed, sloped, offsets", [(1, False, False), (9, True, False), (1, False, True)])
def test_random_legs_land_alike_on_the_compiled_step(seed, sloped, offsets):
    """Random legs (30 and 35 events: toe bounces, stops, sliding), one on a slope, one with its
    centres of mass off the rods: the virtual machine's compiled steps take the numpy run's
    decisions and land 1e-10 from it."""
    tree, laws, scene = _random_leg(seed)
    if offsets:
        tree = Tree(tuple(replace(b, com_offset=(0.02, 0.0)) for b in tree.bodies))
    if sloped:
        scene = replace(scene, terrain=Terrain((-1.0, 1.0), (-0.1, 0.05)))
    ref = _Landing(tree, scene, laws, LandingSettings(step_code=NUMPY_CODE)).run(5e-4)
    r = _Landing(tree, scene, laws, LandingSettings(step_code=VM_CODE)).run(5e-4)
    assert (r.n_steps, len(r.events)) == (ref.n_steps, len(ref.events))
    assert landing_difference(r, ref) <= 1e-10 and _rel(r.q_final, ref.q_final) <= 1e-10


@pytest.mark.parametrize("code", [NUMPY_CODE, VM_CODE])
def test_an_event_takes_the_step_that_located_it(code, monkeypatch):
    """locate() returns the step it found the crossing with (its bracket's end, already taken by
    the run or a trial): that step is a fresh step of its length from the same state, to the
    bit, with its end's witnesses, a watched one past the location threshold (the bracket's
    crossing end, not its last trial)."""
    tree, laws, scene = _case3()
    run = _Landing(tree, scene, laws, LandingSettings(step_code=code))
    located = []
    locate = run.locate

    def recording(q, v, mode, first, watch):
        found = locate(q, v, mode, first, watch)
        located.append((q.copy(), v.copy(), mode.copy(), watch, found))
        return found

    monkeypatch.setattr(run, "locate", recording)
    run.run(2e-3)
    assert len(located) >= 10
    for q, v, mode, watch, found in located:
        q1, v1, impulse = run.step(q, v, mode, found.tau)
        w, r = run.witness_and_rate(q1, v1, mode)
        assert np.array_equal(q1, found.q) and np.array_equal(v1, found.v) and np.array_equal(impulse, found.impulse)
        assert np.array_equal(w, found.w) and np.array_equal(r, found.r, equal_nan=True)
        w0, r0 = run.witness_and_rate(q, v, mode)
        offset = location_offsets(w0[watch] - 1.0, np.isfinite(r0[watch]))  # locate()'s window
        assert np.any(found.w[watch] - 1.0 + offset < 0.0)  # the bracket's crossing end


def test_a_modes_solution_is_kept_per_point():
    """_Landing.mode_solution keeps the rows and forces of the modes asked at the last point:
    equal to fresh ones for every mode there, and fresh again at a new point."""
    from impulse_core.timedomain.events.forces import _accelerations
    from impulse_core.timedomain.events.rows import _mode_rows

    tree, laws, scene = _case3()
    run = _Landing(tree, scene, laws, LandingSettings(step_code=VM_CODE))
    rng = np.random.default_rng(5)
    for _ in range(3):
        q, v = run.q0 + 0.02 * rng.standard_normal(run.nv), rng.standard_normal(run.nv)
        pt = run.point(q, v)
        for mode in [_random_mode(rng, run) for _ in range(4)] * 2:
            rows, (a, lam) = run.mode_solution(pt, mode)
            fresh = _mode_rows(pt, mode, run.mu)
            ra, rlam = _accelerations(pt, fresh)
            assert np.array_equal(rows.G, fresh.G) and np.array_equal(rows.F, fresh.F)
            assert np.array_equal(a, ra) and np.array_equal(lam, rlam)


def test_along_and_the_unilateral_lcp_as_written_out():
    """The shortcuts of _along (one direction: no sum) and of unilateral_lcp's matrix (filled in
    place) equal their written-out forms: the per-contact sum and the block matrix of the law."""
    from impulse_core.impact.coulomb import unilateral_lcp
    from impulse_core.timedomain.events.point import _along

    rng = np.random.default_rng(2)
    for shape in [(4, 1), (4, 1, 5), (0, 1, 5), (4, 2), (4, 2, 5), (4, 3, 5)]:
        d, r = rng.standard_normal(shape[:2]), rng.standard_normal(shape)
        assert np.array_equal(_along(d, r), (d.reshape(d.shape + (1,) * (r.ndim - 2)) * r).sum(axis=1))
    for n, m in [(3, 2), (1, 0), (4, 4), (2, 1)]:
        W, u = rng.standard_normal((n + m, n + m)), rng.standard_normal(n + m)
        owner, e, mu = rng.choice(n, m, replace=False), rng.uniform(0, 1, n), rng.uniform(0, 1, m)
        Wnn, Wnt, Wtn, Wtt = W[:n, :n], W[:n, n:], W[n:, :n], W[n:, n:]
        E, eye, zero = np.zeros((m, n)), np.eye(m), np.zeros((m, m))
        E[np.arange(m), owner] = mu
        block = np.block([[Wnn, Wnt, -Wnt, np.zeros((n, m))], [Wtn, Wtt, -Wtt, eye], [-Wtn, -Wtt, Wtt, eye],
                          [E, -eye, -eye, zero]])
        M, q = unilateral_lcp(W, u, owner, e, mu)
        assert np.array_equal(M, block)
        assert np.array_equal(q, np.concatenate([(1 + e) * u[:n], u[n:], -u[n:], np.zeros(m)]))


def test_resolve_marks_a_mode_redundant_exactly_when_its_rows_are(monkeypatch):
    """Every mode resolve() chooses in a landing (two identical toes on one point) carries the
    redundant flag of its own rows: where its checks kept the first answer (the flag is that
    answer's) and where they changed it (here made to, with the flag flipped: it is recomputed)."""
    from tests.impulse_core.test_landing import _identical_toes

    tree, laws, scene = _identical_toes()
    run = _Landing(tree, scene, laws, LandingSettings(step_code=VM_CODE, integrator="rk4"))
    chosen = []
    resolve = run.resolve

    def recording(q, v, mode, *when):
        new = resolve(q, v, mode, *when)
        chosen.append((q.copy(), v.copy(), mode.copy(), new.copy()))
        return new

    monkeypatch.setattr(run, "resolve", recording)
    run.run(1e-3)
    assert len(chosen) >= 10 and any(new.redundant for *_, new in chosen)
    for q, v, _, new in chosen:
        assert new.redundant == run.redundant(run.point(q, v), replace(new, redundant=False))
    checks = run.consistent_slip

    def changing(pt, v, mode, acc_tol):
        out = checks(pt, v, mode, acc_tol).copy()
        out.redundant = not out.redundant
        return out

    monkeypatch.setattr(run, "consistent_slip", changing)
    for q, v, mode, _ in chosen:
        new = resolve(q, v, mode)
        assert new.redundant == run.redundant(run.point(q, v), replace(new, redundant=False))
