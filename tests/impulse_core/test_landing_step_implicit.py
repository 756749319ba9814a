"""The landing's compiled ROS2 step (impulse_core.timedomain.landing_step, ``method="implicit"``)
equals the numpy step (landing._Landing.implicit_step) in every kind of mode, plane and space; a
mode's own function on the virtual machine (ModeFunctions) equals the general one to the bit; and
a stiff landing runs alike on the compiled and the numpy step."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from impulse_core.kinematics.spatial import PLANAR, SPATIAL
from impulse_core.timedomain import landing_step
from impulse_core.timedomain.events.point import momentum_terms
from impulse_core.timedomain.events.run import _Landing
from impulse_core.timedomain.landing import IMPLICIT, NUMPY_CODE, RK4, VM_CODE, LandingSettings, landing_difference
from tests.impulse_core.test_landing import _light_tip_leg
from tests.impulse_core.test_landing_spatial import _splayed_leg
from tests.impulse_core.test_landing_step import _case3, _legs, _random_mode, _rel, compare_step
from tests.impulse_core.test_landing_step_spatial import _compare_ends, _random_state, _tolerance


def _pair(tree, laws, scene, space=None) -> tuple[_Landing, _Landing]:
    """The landing on the virtual machine's compiled ROS2 step, and on numpy's."""
    runs = [_Landing(tree, scene, laws, LandingSettings(step_code=code, integrator=IMPLICIT), space or PLANAR)
            for code in (VM_CODE, NUMPY_CODE)]
    assert runs[0].fast is not None and runs[1].fast is None
    return runs[0], runs[1]


def _kinds(run: _Landing, mode) -> set[str]:
    closed, friction = mode.closed, run.mu > 0
    return ({"sticking"} if np.any(closed & ~mode.sliding) and friction else set()) \
        | ({"sliding"} if np.any(closed & mode.sliding) else set()) \
        | ({"stop"} if np.any(mode.stop) else set()) | ({"flight"} if not _rests(mode) else set())


def _rests(mode) -> bool:
    return bool(np.any(mode.closed) or np.any(mode.stop))


@pytest.mark.parametrize("leg", ["case3", "random", "offsets", "light"])
def test_the_compiled_implicit_step_equals_the_numpy_step(leg):
    """Random (q, v) near touchdown in random modes (flight, closed sticking or sliding either way,
    on either stop) at steps up to 2 ms (h x rate up to 2e3 on the light tip): the compiled ROS2
    step's state and contact impulses equal numpy's to 1e-12, its end's witnesses and rates too,
    and its momentum balance but for the weight (StepEnd.balance) numpy's (momentum_change) to
    1e-12 of the momenta and impulse; a redundant mode is left to numpy."""
    tree, laws, scene = {"case3": _case3, "random": lambda: list(_legs())[4], "offsets": lambda: list(_legs())[6],
                         "light": _light_tip_leg}[leg]()
    fast, ref = _pair(tree, laws, scene)
    rng = np.random.default_rng(5)
    kinds = set()
    for k in range(12):
        q = fast.q0 + 0.02 * rng.standard_normal(fast.nv)
        v = rng.standard_normal(fast.nv)
        mode, h = _random_mode(rng, fast), float(rng.uniform(1e-4, 2e-3))
        if k == 0:
            mode.closed[:], mode.slip[:], mode.stop[:] = False, 0.0, 0
        q1, v1, impulse, end = compare_step(fast, ref, ref.implicit_step, q, v, mode, h)
        if end is None:
            continue
        kinds |= _kinds(fast, mode)
        p0 = ref.point(q, v).momentum[:, 0]
        scale = max(np.max(np.abs(p0)), np.max(np.abs(end.momentum1)), np.max(np.abs(impulse)))
        assert np.max(np.abs(end.balance - ref.momentum_change(p0, q1, v1, impulse))) <= 1e-12 * scale
        assert _rel(end.terms, _numpy_terms(ref, q, v, end)) <= 1e-12
    assert kinds >= {"flight", "sliding", "stop"} | ({"sticking"} if fast.mu > 0 else set())


def _numpy_terms(ref: _Landing, q: np.ndarray, v: np.ndarray, end) -> np.ndarray:  # type: ignore[no-untyped-def]
    """A compiled step's momentum terms at its start (q, v) and its end (StepEnd.terms) by numpy:
    momentum_terms of each end's point."""
    return np.concatenate([momentum_terms(ref.point(q, v).M, v, ref.dims),
                           momentum_terms(ref.point(end.q, end.v).M, end.v, ref.dims)])


@pytest.mark.parametrize("leg", [1, 2])
def test_the_compiled_spatial_implicit_step_equals_the_numpy_step(leg):
    """Space (two tangents per contact, the sliding direction turning with the slip, regularised
    below random cores): the compiled ROS2 step equals numpy's to 1e-12 (or rounding's share of
    an ill-conditioned mode), its end's figures too; flight, sticking, sliding and stops met."""
    tree, laws, scene = _splayed_leg(leg, 1.0 if leg == 1 else 0.0)
    fast, ref = _pair(tree, laws, scene, SPATIAL)
    rng = np.random.default_rng(leg)
    kinds = set()
    for k in range(10):
        q, v, pt, mode, h = _random_state(rng, fast, ref, k, 2e-3)
        mode.core[:] = rng.uniform(0.0, 2.0, fast.nc) * np.linalg.norm(pt.slip, axis=1)
        tol = _tolerance(ref, q, v, mode)
        end = fast.fast.step(q, v, h, mode)  # at the given cores
        assert (end is None) == mode.redundant
        rq, rv, rimpulse = ref.implicit_step(q, v, mode, h)
        if end is None:
            continue
        kinds |= _kinds(fast, mode)
        assert _rel(end.q, rq) <= tol and _rel(end.v, rv) <= tol and _rel(end.impulse, rimpulse) <= tol
        assert _rel(end.terms, _numpy_terms(ref, q, v, end)) <= 1e-12
        a, b = mode.copy(), mode.copy()  # the landing's step: steered, then its end's figures
        q1, v1, impulse = fast.step(q, v, a, h)
        rq, rv, rimpulse = ref.step(q, v, b, h)
        assert _rel(q1, rq) <= tol and _rel(v1, rv) <= tol and _rel(impulse, rimpulse) <= tol
        _compare_ends(fast, ref, q, v, q1, v1, a, tol)
    assert kinds >= {"flight", "stop"} | ({"sticking", "sliding"} if fast.mu > 0 else set())


@pytest.mark.parametrize("method", [RK4, IMPLICIT])
def test_a_modes_own_function_equals_the_general_one(method, monkeypatch):
    """On the virtual machine a mode asked for SPECIALISE_AFTER times gets its own step and
    projection (the mode's inputs as constants): fewer instructions, the same numbers to the bit."""
    monkeypatch.setattr(landing_step, "SPECIALISE_AFTER", 2)
    tree, laws, scene = list(_legs())[4]
    run = _Landing(tree, scene, laws, LandingSettings(step_code=VM_CODE, integrator=method))
    rng = np.random.default_rng(11)
    specialised = 0
    for _ in range(6):
        q, v = run.q0 + 0.02 * rng.standard_normal(run.nv), rng.standard_normal(run.nv)
        mode = _random_mode(rng, run)
        if run.fast.numbers(mode) is None:
            continue
        general, own = (run.fast.step(q, v, 1e-3, mode) for _ in range(2))  # the second: the mode's own
        step_function = run.fast.modes._modes[landing_step._rows_key(run.fast.numbers(mode))][1]
        specialised += step_function is not None
        for a, b in zip(vars(general).values(), vars(own).values()):
            assert np.array_equal(a, b)
        first, second = (run.fast.project(general.q, general.v, mode) for _ in range(2))
        assert first is None or all(np.array_equal(a, b) for a, b in zip(first, second))
    assert specialised >= 4
    general_function = run.fast.modes.f
    assert run.fast.modes.specialised().n_instructions() < general_function.n_instructions()


def test_a_stiff_landing_runs_alike_on_the_compiled_implicit_step():
    """The light tip (a 2 cm, 20 g damped rod: ROS2 at h x rate ~ 1e2) for 10 ms at 0.1 ms: the
    compiled steps (each mode's own function after 32 steps) take the numpy run's decisions
    (steps the momentum balance split, events) and land 1e-9 from it."""
    tree, laws, scene = _light_tip_leg()
    scene = replace(scene, duration=0.01)
    fast, ref = _pair(tree, laws, scene)
    r, expected = fast.run(1e-4), ref.run(1e-4)
    assert r.integrator == expected.integrator == IMPLICIT and expected.n_steps > 200  # split steps
    assert (r.n_steps, [e.kind for e in r.events]) == (expected.n_steps, [e.kind for e in expected.events])
    assert len(expected.events) > 20
    assert max(abs(a.time - b.time) for a, b in zip(r.events, expected.events)) <= 1e-9 * scene.duration
    assert landing_difference(r, expected) <= 1e-9
    assert _rel(r.q_final, expected.q_final) <= 1e-9 and _rel(r.v_final, expected.v_final) <= 1e-9
    assert any(entry[1] is not None for entry in fast.fast.modes._modes.values())  # a mode's own function ran
