"""The landing's compiled Radau IIA step (impulse_core.timedomain.landing_step, ``method="radau"``:
RADAU_UNROLLED simplified Newton iterations in one CasADi function, called again from its Z until
they converge) equals the numpy step (landing._Landing.radau_newton) in every kind of mode, plane
and space; a split step keeps no compiled end; and a stiff landing
runs alike on the compiled and the numpy step (``studies/whole_landing/stiff_speed.md``, branch
``radauc``)."""

from __future__ import annotations

import numpy as np

from impulse_core.kinematics.spatial import PLANAR, SPATIAL
from impulse_core.timedomain import landing_step
from impulse_core.timedomain.events.run import _Landing
from impulse_core.timedomain.events.stepping import _newton_verdict
from impulse_core.timedomain.landing import NUMPY_CODE, RADAU, RK4, VM_CODE, LandingSettings, landing_difference
from tests.impulse_core.test_landing import _light_tip_leg
from tests.impulse_core.test_landing_radau import _resting_state, _run
from tests.impulse_core.test_landing_spatial import _splayed_leg
from tests.impulse_core.test_landing_step import _legs, _random_mode, _rel
from tests.impulse_core.test_landing_step_implicit import _kinds
from tests.impulse_core.test_landing_step_spatial import _compare_ends, _random_state, _tolerance


def _pair(tree, laws, scene, space=PLANAR) -> tuple[_Landing, _Landing]:
    """The landing on the virtual machine's compiled Radau IIA step, and on numpy's."""
    runs = [_Landing(tree, scene, laws, LandingSettings(step_code=code, integrator=RADAU), space)
            for code in (VM_CODE, NUMPY_CODE)]
    assert runs[0].fast is not None and runs[1].fast is None
    return runs[0], runs[1]


def _unrolled(end) -> int:
    """The compiled iterations' verdict (:func:`landing._newton_verdict`): 1 converged, -1 not
    contracting, 0 neither within RADAU_UNROLLED."""
    verdict, last = 0, np.inf
    for size in end.newton:
        verdict, last = _newton_verdict(float(size), last), float(size)
        if verdict:
            return verdict
    return 0


def _compare(fast: _Landing, ref: _Landing, q, v, mode, h: float, tol: float) -> int | None:
    """The landing's step on the compiled code (its calls chained) against numpy's from (q, v) in
    ``mode``: NaN alike, else the state to ``tol``, the impulses to 10 ``tol`` (a call's
    iterations go on past numpy's converged one: 7e-12 seen), its end's witnesses and balance;
    its first call's verdict (1 converged, 0 gone on in another call, -1 not contracting), or None
    where the mode is numpy's (redundant)."""
    end = fast.compiled(q, v, mode, h)
    if end is None:
        return None
    a = mode.copy()
    q1, v1, impulse = fast.step(q, v, a, h)
    rq, rv, rimpulse = ref.step(q, v, mode.copy(), h)
    assert np.isfinite(q1).all() == np.isfinite(rq).all()
    if not np.isfinite(rq).all():
        return -1
    assert _rel(q1, rq) <= tol and _rel(v1, rv) <= tol and _rel(impulse, rimpulse) <= 10.0 * tol
    last = fast.ended(q1, v1, a)
    assert last is not None
    if fast.dims == 3:
        _compare_ends(fast, ref, q, v, q1, v1, a, tol)
    p0 = ref.point(q, v).momentum[:, 0]
    scale = max(np.max(np.abs(p0)), np.max(np.abs(last.momentum1)), np.max(np.abs(impulse)))
    assert np.max(np.abs(last.balance - ref.momentum_change(p0, q1, v1, impulse))) <= 10.0 * tol * scale
    w, r = fast.witness_and_rate(q1, v1, a)
    rw, rr = ref.witness_and_rate(q1, v1, a)
    finite = np.isfinite(rw)
    assert np.array_equal(finite, np.isfinite(w)) and _rel(w[finite], rw[finite]) <= tol
    return _unrolled(end)


def test_the_compiled_radau_step_equals_the_numpy_step():
    """Random (q, v) near touchdown in random modes (flight, closed sticking or sliding either way,
    on either stop) at steps up to 2 ms on a random leg, 8 ms on the light tip (a 2 cm, 20 g damped
    rod: h x rate up to 8e3): the compiled step's state, impulses, end's witnesses and momentum
    balance equal numpy's to 1e-12 (impulses 1e-11), where its first call's iterations converged
    and where they went on in another; a redundant mode is numpy's."""
    verdicts, kinds = [], set()
    for leg, (tree, laws, scene) in enumerate((list(_legs())[4], _light_tip_leg())):
        fast, ref = _pair(tree, laws, scene)
        rng = np.random.default_rng(7 + leg)
        for k in range(10):
            q = fast.q0 + 0.02 * rng.standard_normal(fast.nv)
            v = rng.standard_normal(fast.nv)
            mode, h = _random_mode(rng, fast), float(rng.uniform(1e-4, 2e-3)) * (1.0 + 3.0 * leg)
            if k == 0:
                mode.closed[:], mode.slip[:], mode.stop[:] = False, 0.0, 0
            mode.redundant = ref.redundant(ref.point(q, v), mode)
            verdict = _compare(fast, ref, q, v, mode, h, 1e-12)
            if verdict is not None:
                verdicts.append(verdict)
                kinds |= _kinds(fast, mode) if verdict >= 0 else set()
    assert {1, 0} <= set(verdicts) and kinds >= {"flight", "sliding", "sticking", "stop"}


def test_the_compiled_spatial_radau_step_equals_the_numpy_step():
    """Space (two tangents per contact, the sliding direction turning with the slip, regularised
    below random cores): the compiled Radau IIA step equals numpy's to 1e-12 (or rounding's share
    of an ill-conditioned mode), its end's figures too."""
    tree, laws, scene = _splayed_leg(1, 1.0)
    fast, ref = _pair(tree, laws, scene, SPATIAL)
    rng = np.random.default_rng(1)
    kinds = set()
    for k in range(6):
        q, v, pt, mode, h = _random_state(rng, fast, ref, k, 1e-3)
        if k == 0:
            mode.stop[:] = 0
            mode.redundant = ref.redundant(pt, mode)
        if _compare(fast, ref, q, v, mode, h, _tolerance(ref, q, v, mode)) in (0, 1):
            kinds |= _kinds(fast, mode)
    assert kinds >= {"flight", "sticking", "sliding"}


def test_the_compiled_iterations_converge_on_a_stiff_resting_step():
    """33096's rod resting 2 ms after touchdown, steps of 2 to 512 / rate: the compiled Newton
    iterations contract (the matrix's stages right: each correction above the tolerance over 10 x
    smaller than the last), converge within one call up to 128 / rate, and get to 3.9 tolerances
    at 512 (with A in place of A^2 in the matrix's spring term: 103), and the step's end is
    numpy's to 1e-12 (impulses 1e-11: the call's iterations go on past numpy's converged one)."""
    _, ref = _run(RK4, VM_CODE)
    q, v, mode = _resting_state(ref, 2e-3)
    _, fast = _run(RADAU, VM_CODE)
    _, numpy = _run(RADAU, NUMPY_CODE)
    for ratio in (2.0, 32.0, 128.0, 512.0):
        h = ratio / ref.rate
        end = fast.compiled(q, v, mode, h)
        above = end.newton[:-1] > 1.0
        assert np.all(end.newton[1:][above] < 0.1 * end.newton[:-1][above])
        assert _unrolled(end) == (1 if ratio <= 128.0 else 0) and end.newton[-1] < 10.0
        rq, rv, rimpulse = numpy.radau_newton(q, v, mode, h)
        q1, v1, impulse = fast.radau_once(q, v, mode, h)
        assert _rel(q1, rq) <= 1e-12 and _rel(v1, rv) <= 1e-12 and _rel(impulse, rimpulse) <= 1e-11


def test_a_split_compiled_step_keeps_no_compiled_end(monkeypatch):
    """A step whose compiled iterations fail over h (faked beyond h / 4) is four compiled steps of
    h / 4; the last piece's end is not the step's (its start, its balance): ``ended`` has none."""
    _, ref = _run(RK4, VM_CODE)
    q, v, mode = _resting_state(ref, 2e-3)
    _, fast = _run(RADAU, VM_CODE)
    h = 64.0 / fast.rate
    once = _Landing.radau_once

    def failing(self, q, v, mode, step):
        return self.failed_step() if step > 0.3 * h else once(self, q, v, mode, step)

    monkeypatch.setattr(_Landing, "radau_once", failing)
    q1, v1, _ = fast.radau_step(q, v, mode, h)
    assert np.isfinite(q1).all() and fast.ended(q1, v1, mode) is None
    assert fast.ended(*fast.radau_step(q, v, mode, 0.25 * h)[:2], mode) is not None


def test_33096s_first_9_ms_land_alike_on_the_compiled_radau_step(monkeypatch):
    """33096 cut to 9 ms at duration / 200 (24 impacts; each mode's own function after 4 steps):
    the compiled steps take the numpy run's steps and events, 1e-9 from it."""
    monkeypatch.setattr(landing_step, "SPECIALISE_AFTER", 4)
    model, _ = _run(RK4)
    T, cut = float(model.scene.duration), 0.009
    _, fast = _run(RADAU, VM_CODE, cut)
    _, numpy = _run(RADAU, NUMPY_CODE, cut)
    a, b = fast.run(T / 200.0, share=cut / T), numpy.run(T / 200.0, share=cut / T)
    assert len(a.events) == len(b.events) == 24 and a.n_steps == b.n_steps
    assert max(abs(x.time - y.time) for x, y in zip(a.events, b.events)) < 1e-11
    assert landing_difference(a, b) < 1e-9 and a.step_code == VM_CODE and b.step_code == NUMPY_CODE
    assert a.integrator == RADAU
