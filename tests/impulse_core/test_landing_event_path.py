"""The landing's event path, made cheaper without changing a result: each shortcut against the
plain computation it replaces (bit for bit where the arithmetic is the same), and landings that
take the shortcuts against the same landings without them."""

from __future__ import annotations

import math

import numpy as np
import pytest

from impulse_core.timedomain.events.location import _ROOT_SAMPLES, _hermite_root


def _reference_root(g0: float, d0: float, g1: float, d1: float) -> float:
    """The first sign change of the cubic Hermite fit on the samples by np.polyval, then bisection."""
    coeffs = np.array([2 * g0 + d0 - 2 * g1 + d1, -3 * g0 - 2 * d0 + 3 * g1 - d1, d0, g0])
    below = np.flatnonzero(np.polyval(coeffs, _ROOT_SAMPLES) < 0)
    if not below.size or below[0] == 0:
        return math.nan
    a, b = _ROOT_SAMPLES[below[0] - 1], _ROOT_SAMPLES[below[0]]
    for _ in range(40):
        m = 0.5 * (a + b)
        a, b = (m, b) if np.polyval(coeffs, m) >= 0 else (a, m)
    return float(b)


@pytest.mark.parametrize("code", ["python", "c"])
def test_the_hermite_root_is_numpys_polyval_bit_for_bit(code):
    """The event location's cubic root (Horner's rule on the samples written out; and as the
    compiled library's, which step code c locates with) equals np.polyval's sampling and
    bisection bit for bit: gaps that dip and come back, cross once, stay above, start below, and
    unknown slopes."""
    from impulse_core.impact import lemke_c

    root_of = _hermite_root if code == "python" else lemke_c.hermite_root(_ROOT_SAMPLES)
    if root_of is None:
        pytest.skip("no C compiler")
    rng = np.random.default_rng(3)
    found = 0
    for k in range(2000):
        g0, g1 = rng.uniform(0.0, 1.0), rng.uniform(-1.0, 1.0) * (k % 4 != 0)
        d0, d1 = rng.standard_normal(2) * 4.0
        if k % 7 == 0:
            g0 = -abs(g0)  # below at the start
        root, ref = root_of(g0, d0, g1, d1), _reference_root(g0, d0, g1, d1)
        assert (math.isnan(root) and math.isnan(ref)) or root == ref
        found += not math.isnan(root)
    assert 500 < found < 1800
    assert math.isnan(root_of(1.0, math.nan, -1.0, 0.0))


def _landing_records(run, h: float) -> tuple:
    r = run.run(h)
    return r, [(e.time, e.kind, e.external, e.tangential, e.internal, e.stop, e.v_plus) for e in r.events]


def _assert_same(a: tuple, b: tuple) -> None:
    (ra, ea), (rb, eb) = a, b
    assert len(ea) == len(eb) and ra.n_steps == rb.n_steps
    for x, y in zip(ea, eb):
        assert x[:2] == y[:2] and all(np.array_equal(u, w) for u, w in zip(x[2:], y[2:]))
    assert np.array_equal(ra.q_final, rb.q_final) and np.array_equal(ra.v_final, rb.v_final)
    assert np.array_equal(ra.total_external, rb.total_external)


def _cases():
    from dataclasses import replace

    from impulse_core.kinematics.spatial import PLANAR, SPATIAL
    from impulse_core.model.joints import FREE, JointLaw
    from impulse_core.model.tree import Body, Scene, Tree
    from optimizer.config.model_file import load_model_file
    from tests.impulse_core.test_landing_spatial import _splayed_leg

    m = load_model_file("configs/landing_case3.yaml")  # the toes' first bounces: flights between them
    yield m.tree, replace(m.scene, duration=0.0095), m.joints, PLANAR, 2.7e-3
    tree, laws, scene = _splayed_leg(1, 1.0)  # space: sliding, sticking, stops
    yield tree, replace(scene, duration=0.006), laws, SPATIAL, 5e-4
    tree = Tree((  # a stiff joint between close stops, in flight between elastic bounces: it rests on its stops
        Body("b0", None, 0.2124, 1.165, -0.1229, contacts=(0.0,)),
        Body("b1", 0, 0.2857, 2.982, -0.0596, gyration=0.2695),
    ))
    laws = (FREE, JointLaw(stiffness=134.8, damping=0.02406, limits=(-0.1484, -0.04115)))
    yield tree, Scene(speed=1.9218, restitution=1.0, gravity=9.81, duration=0.2), laws, PLANAR, 1e-3


def test_the_event_shortcuts_change_no_result(monkeypatch):
    """Landings whose events take the shortcuts (no rows to resolve after a bounce: the flight
    mode; nothing to project) equal, bit for bit, the same landings through the contact LCP and
    the placement every time (events, impulses, final state)."""
    from impulse_core.timedomain.events.run import _Landing
    from impulse_core.timedomain.landing import VM_CODE, LandingSettings

    for tree, scene, laws, space, h in _cases():
        settings = LandingSettings(step_code=VM_CODE, integrator="rk4")
        fast = _landing_records(_Landing(tree, scene, laws, settings, space), h)
        with monkeypatch.context() as patch:
            patch.setattr(_Landing, "rests_nowhere", staticmethod(lambda contacts, stops: False))
            patch.setattr(_Landing, "in_place", lambda self, pt, q, mode: False)
            plain = _landing_records(_Landing(tree, scene, laws, settings, space), h)
        assert len(fast[1]) >= 15
        _assert_same(fast, plain)


def test_a_joint_pressed_onto_its_stop_in_flight_is_resolved_by_the_lcp(monkeypatch):
    """In flight, a joint at its stop at rest, its spring pressing it on (rest angle beyond the
    stop): the mode choice keeps the stop row (the LCP's answer), as without the flight shortcut;
    pressed away from it, the joint is free (the flight mode)."""
    from impulse_core.kinematics.spatial import PLANAR
    from impulse_core.model.joints import FREE, JointLaw
    from impulse_core.model.tree import Body, Scene, Tree
    from impulse_core.timedomain.events.run import _Landing
    from impulse_core.timedomain.landing import LandingSettings

    tree = Tree((Body("b0", None, 0.2, 1.0, -0.1, contacts=(0.0,)), Body("b1", 0, 0.3, 2.0, -0.06)))
    for rest, side in ((0.0, 1), (-0.1, 0)):
        laws = (FREE, JointLaw(stiffness=100.0, rest=rest, limits=(-0.15, -0.04)))
        run = _Landing(tree, Scene(speed=1.0, gravity=9.81, duration=0.1), laws, LandingSettings(), PLANAR)
        q = run.q0 + np.array([0.0, 1.0, 0.0, 0.0])  # a metre up: no contact near the ground
        q[3] = -0.04
        mode = run.resolve(q, np.zeros(4), run.flight())
        with monkeypatch.context() as patch:
            patch.setattr(_Landing, "rests_nowhere", staticmethod(lambda contacts, stops: False))
            plain = run.resolve(q, np.zeros(4), run.flight())
        assert mode.stop[3] == plain.stop[3] == side and not mode.closed.any() and not plain.closed.any()


def test_redundancy_from_the_singular_values_alone_is_the_null_spaces():
    """:func:`redundant` (every impact asks it) from the singular values alone agrees with the
    left null space of :func:`row_space_split` on independent rows, twin rows, rows dependent to
    rounding and more rows than columns."""
    from impulse_core.impact.laws import redundant, row_space_split

    rng = np.random.default_rng(11)
    seen = set()
    for k in range(300):
        rows, cols = int(rng.integers(1, 9)), int(rng.integers(2, 12))
        J = rng.standard_normal((rows, cols)) * np.exp(rng.uniform(-3, 3, cols))  # columns in unlike units
        if k % 3 == 0 and rows > 1:
            J[-1] = J[0] * (1.0 + 1e-14 * (k % 2))  # twins (to rounding)
        answer = redundant(J)
        assert answer == (row_space_split(J)[1].shape[1] > 0)
        seen.add(answer)
    assert seen == {True, False}


def test_components_along_directions_add_as_numpys_sum():
    """:func:`_along` (every point of the landing projects its Jacobians on the normals and
    tangents) adds the components in numpy's order: equal bit for bit to the broadcast sum."""
    from impulse_core.timedomain.events.point import _along

    rng = np.random.default_rng(5)
    for k in range(200):
        nc, d = int(rng.integers(1, 6)), int(rng.integers(1, 4))
        directions = rng.standard_normal((nc, d))
        rows = rng.standard_normal((nc, d) + ((int(rng.integers(1, 15)),) if k % 2 else ()))
        expected = (directions.reshape(directions.shape + (1,) * (rows.ndim - 2)) * rows).sum(axis=1)
        assert np.array_equal(_along(directions, rows), expected)


def test_the_compiled_point_is_the_virtual_machines_bit_for_bit():
    """With ``step_code`` c the numpy path's dynamics at a point (:func:`landing_function`: gaps,
    normals, Jacobians, mass matrix, forces, momenta; two or three calls per event) run as C
    through the compile cache: the same numbers bit for bit as CasADi's virtual machine, in the
    plane (case 3) and in space (a splayed leg), at random states."""
    from impulse_core.kinematics.spatial import PLANAR, SPATIAL
    from impulse_core.timedomain.events.run import _Landing
    from impulse_core.timedomain.landing import C_CODE, NUMPY_CODE, LandingSettings
    from optimizer.config.model_file import load_model_file
    from tests.impulse_core.test_landing_spatial import _splayed_leg

    m = load_model_file("configs/landing_case3.yaml")
    rng = np.random.default_rng(2)
    for (tree, laws, scene), space in (((m.tree, m.joints, m.scene), PLANAR), (_splayed_leg(0, 0.4), SPATIAL)):
        c, vm = (_Landing(tree, scene, laws, LandingSettings(step_code=code, integrator="rk4"), space)
                 for code in (C_CODE, NUMPY_CODE))
        assert c.call._buf is not vm.call._buf
        for _ in range(20):
            q, v = c.q0 + rng.uniform(-0.3, 0.3, c.nv), rng.uniform(-3.0, 3.0, c.nv)
            c.call.call(q, v)
            vm.call.call(q, v)
            for a, b in zip(c.call.flat, vm.call.flat):
                assert np.array_equal(a, b)


def test_adding_zero_impulses_leaves_the_totals_as_they_are():
    """:meth:`_Landing.add` skips an impulse that is 0 everywhere (a flight's step, a projection
    without rows): the totals stay as adding it would leave them, to the bit (sums of +0 never
    make -0); a tangential impulse alone is added."""
    from impulse_core.timedomain.events.run import _Landing
    from impulse_core.timedomain.landing import NUMPY_CODE, LandingSettings
    from optimizer.config.model_file import load_model_file

    m = load_model_file("configs/landing_case3.yaml")
    run = _Landing(m.tree, m.scene, m.joints, LandingSettings(step_code=NUMPY_CODE))
    q, v, _, totals = run.first_impact()
    names = ("normal", "tangential", "impulse", "vectors")
    before = [getattr(totals, k).copy() for k in names]
    zero = np.zeros(2 * run.nc)
    zero[1::2] = -0.0
    run.add(totals, zero, q, v)
    for k, b in zip(names, before):
        a = getattr(totals, k)
        assert np.array_equal(a, b) and np.array_equal(np.signbit(a), np.signbit(b))
    sliding = np.zeros(2 * run.nc)
    sliding[run.nc] = 1e-3
    run.add(totals, sliding, q, v)
    assert totals.tangential[0] == before[1][0] + 1e-3 and totals.impulse[0] == before[2][0] + 1e-3


def test_a_points_figures_are_alongs_bit_for_bit():
    """A point's plane figures (the normal and tangent components of the Jacobian rows and of the
    bias, taken in one product over [J | bias]) equal _along's, bit for bit and in its memory order
    (matmul rounds otherwise on other strides: the slip); a point at the last point's q sharing its
    geometry equals one evaluated afresh; a flight's witnesses from the gaps and normal speeds alone
    equal those from the whole point; and the projection's position correction (its normal and
    stop rows alone) equals the one from the mode's whole rows."""
    from dataclasses import fields

    from optimizer.config.model_file import load_model_file
    from impulse_core.timedomain.events.point import _Point, _along, tangent_basis
    from impulse_core.timedomain.events.rows import _Mode, _mode_rows
    from impulse_core.timedomain.events.run import _Landing
    from impulse_core.timedomain.landing import NUMPY_CODE, LandingSettings

    m = load_model_file("configs/landing_case3.yaml")
    run = _Landing(m.tree, m.scene, m.joints, LandingSettings(step_code=NUMPY_CODE))
    rng = np.random.default_rng(5)
    for _ in range(20):
        q, v = run.q0 + 0.1 * rng.standard_normal(run.nv), rng.standard_normal(run.nv)
        pt = run._evaluate(q, v)
        run.call.call(q, v)
        o, f = run.call.out, run.call.flat
        normal = o[1].T.copy()
        tangent = tangent_basis(normal)
        J, bias = o[2].reshape(run.nc, 2, run.nv), f[3].reshape(run.nc, 2)
        ref = {"Jn": _along(normal, J), "Jt": _along(tangent[:, 0], J)[:, None], "bn": _along(normal, bias),
               "bt": _along(tangent[:, 0], bias)[:, None]}
        for name, x in ref.items():
            y = getattr(pt, name)
            assert y.tobytes() == x.tobytes() and y.strides == x.strides, name
        assert pt.slip.tobytes() == (ref["Jt"] @ v).tobytes()
        v2 = rng.standard_normal(run.nv)
        shared, fresh = run._evaluate(q, v2, like=pt), run._evaluate(q, v2)
        for field in fields(_Point):
            a, b = np.asarray(getattr(shared, field.name)), np.asarray(getattr(fresh, field.name))
            assert a.tobytes() == b.tobytes() and a.strides == b.strides, field.name
        run._last = None  # a flight's witnesses without a point: its gaps and speeds, and the rest unwatched
        gap, vn = run.gaps_and_speeds(q, v)
        assert gap.tobytes() == pt.gap.tobytes() and vn.tobytes() == pt.vn(v).tobytes()
        flight = run.flight()
        flight.slip[:] = rng.choice([-1.0, 0.0, 1.0], (run.nc, 1))  # open contacts keep a slip from before
        w, r = run.witness_and_rate(q, v, flight)
        zero = np.zeros(run.nc)
        values = np.concatenate([pt.gap, zero, run.mu * zero, flight.slip[:, 0] * pt.slip[:, 0], q - run.joints.lo,
                                 run.joints.hi - q, np.zeros(run.nv)]) / run.witness_scale + 1.0
        values[run.unwatched(flight)] = np.inf
        rates = np.concatenate([pt.vn(v), run.unknown_rates[0], v, -v, run.unknown_rates[1]]) / run.settings.gap_tolerance
        assert w.tobytes() == values.tobytes() and r.tobytes() == rates.tobytes()
        mode = _Mode(rng.random(run.nc) < 0.6, np.zeros(run.nc), rng.choice([-1, 0, 1], run.nv) * run.joints.stopped)
        rows = _mode_rows(pt, mode, run.mu)
        n = rows.n
        if n:  # the correction from the mode's whole rows, as before
            residual = np.zeros(n)
            on = rows.contact >= 0
            residual[on] = pt.gap[rows.contact[on]]
            d = rows.dof[~on]
            residual[~on] = -mode.stop[d] * (q[d] - np.where(mode.stop[d] > 0, run.joints.hi[d], run.joints.lo[d]))
            minv_gt = np.linalg.solve(pt.M, rows.G[:n].T)
            expected = minv_gt @ np.linalg.lstsq(rows.G[:n] @ minv_gt, residual, rcond=None)[0]
            assert run.position_correction(pt, q, mode).tobytes() == expected.tobytes()
