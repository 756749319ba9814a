"""The compliant rung: the clipped spring-damper's restitution, the dynamics it integrates, and its
convergence to the rigid laws as the contacts stiffen."""

from __future__ import annotations

import math

import numpy as np
import pytest
from fidelity_scenes import PAPER_SCENE, UNEVEN, case2, case3, chain, rod
from scipy.integrate import solve_ivp

from impulse_core.timedomain.compliant import (
    CompliantSettings,
    CompliantStatus,
    ContactLaw,
    clipped_restitution,
    compiled_dynamics,
    damping_ratio_for_restitution,
    simulate_impact,
    touchdown_configuration,
)
from impulse_core.errors import ModelError
from impulse_core.evaluate import evaluate
from impulse_core.impact.delassus import mass_matrix_function
from impulse_core.kinematics.spatial import dof_layout
from impulse_core.model.terrain import signed_gap
from impulse_core.model.tree import Body, Scene, Tree, design_vector
from tests.conftest import random_tree, report


def textbook_restitution(zeta: float) -> float:
    return math.exp(-zeta * math.pi / math.sqrt(1 - zeta * zeta))


def integrated_restitution(zeta: float) -> float:
    """x'' = -x - 2 zeta x' while the force x + 2 zeta x' >= 0 (omega_n = 1, x'(0) = 1), by an
    adaptive Runge-Kutta with an event at the release: independent of the closed form."""

    def rhs(t, y):
        return [y[1], -y[0] - 2 * zeta * y[1]]

    def release(t, y):
        return y[0] + 2 * zeta * y[1] if t > 0 else 1.0

    release.terminal, release.direction = True, -1
    sol = solve_ivp(rhs, (0.0, 200.0), [0.0, 1.0], events=release, rtol=1e-12, atol=1e-14, method="DOP853")
    return -sol.y_events[0][0][1]


@pytest.mark.parametrize("zeta", [0.01, 0.0744, 0.3, 0.7, 0.999, 1.0, 1.001, 1.5, 4.0, 30.0])
def test_clipped_restitution_matches_direct_integration(zeta):
    assert clipped_restitution(zeta) == pytest.approx(integrated_restitution(zeta), rel=1e-8, abs=1e-12)


def test_damping_ratio_for_restitution_inverts_and_differs_from_textbook():
    for e in (0.05, 0.135, 0.3, 0.8, 0.99, 1.0):
        assert clipped_restitution(damping_ratio_for_restitution(e)) == pytest.approx(e, rel=1e-12)
    zeta = damping_ratio_for_restitution(0.8)
    zeta_textbook = -math.log(0.8) / math.sqrt(math.pi**2 + math.log(0.8) ** 2)
    assert textbook_restitution(zeta_textbook) == pytest.approx(0.8)
    assert zeta == pytest.approx(0.07436, abs=1e-5)
    assert zeta_textbook == pytest.approx(0.07085, abs=1e-5)
    # the textbook ratio, used with a contact that cannot pull, rebounds about 1 % too fast
    assert clipped_restitution(zeta_textbook) == pytest.approx(0.8081, abs=1e-4)
    report("compliant", f"e = 0.8: clipped zeta {zeta:.5f}, textbook {zeta_textbook:.5f}")


def test_zero_restitution_needs_infinite_damping():
    with pytest.raises(ModelError, match="restitution"):
        damping_ratio_for_restitution(0.0)
    with pytest.raises(ModelError, match="restitution"):
        simulate_impact(rod(), Scene(speed=1.0, restitution=0.0))


def test_friction_and_bad_settings_are_refused():
    with pytest.raises(ModelError, match="friction"):
        simulate_impact(rod(), Scene(friction=0.5))
    with pytest.raises(ModelError, match=r"compliant\.stiffness"):
        CompliantSettings(stiffness=-1.0)
    for bad in ({"stiffness": 1e300}, {"stiffness": 1e-300}, {"steps_per_period": 1e300}):  # 1e300: ran for ever
        with pytest.raises(ModelError, match=rf"compliant\.{next(iter(bad))}: must be in \["):
            CompliantSettings(**bad)
    with pytest.raises(ModelError, match=r"compliant\.impedance"):
        CompliantSettings(impedance=1.0)


# --------------------------------------------------------------------------------------------
# The dynamics


def _mass_matrix_at(tree: Tree, q: np.ndarray) -> np.ndarray:
    """M at configuration q through the core's own mass_matrix_function (angles written into a
    copy of the tree): an independent path to the configuration-dependent mass matrix."""
    layout = dof_layout(tree.topology())
    bodies = list(tree.bodies)
    bodies[0] = Body(**{**bodies[0].__dict__, "angle": float(q[2])})
    for b in range(1, tree.n_bodies):
        if layout.body_dof[b] is not None:
            bodies[b] = Body(**{**bodies[b].__dict__, "angle": float(q[layout.body_dof[b]])})
    t = Tree(tuple(bodies))
    return np.array(mass_matrix_function(t.topology())(design_vector(t))[0])


def test_coriolis_terms_equal_finite_differences_of_the_mass_matrix(rng):
    """h(q, v) = (dM/dt) v - d/dq (v^T M v)/2 by central differences of the core's mass matrix,
    against the compiled function's M^-1 (tau_g - h) with gravity off."""
    tree = random_tree(rng, 5)
    topology = tree.topology()
    nv = dof_layout(topology).nv
    fn = compiled_dynamics(topology)
    p = design_vector(tree)
    for _ in range(3):
        q = rng.normal(size=nv)
        v = rng.normal(size=nv) * 3.0
        M = _mass_matrix_at(tree, q)
        eps = 1e-6
        Mdot_v = (_mass_matrix_at(tree, q + eps * v) - _mass_matrix_at(tree, q - eps * v)) @ v / (2 * eps)
        dT = np.array(
            [
                v @ (_mass_matrix_at(tree, q + eps * e) - _mass_matrix_at(tree, q - eps * e)) @ v / (4 * eps)
                for e in np.eye(nv)
            ]
        )
        h_fd = Mdot_v - dT
        free = np.array(fn(q, v, p, 0.0)[3]).ravel()
        np.testing.assert_allclose(-M @ free, h_fd, rtol=1e-6, atol=1e-6 * np.abs(h_fd).max())


def test_free_flight_conserves_energy_and_momentum(rng):
    """RK4 on the compiled dynamics (gravity off): kinetic energy and linear momentum constant;
    with gravity the momentum falls at m g."""
    tree = random_tree(rng, 4)
    topology = tree.topology()
    nv = dof_layout(topology).nv
    fn = compiled_dynamics(topology)
    p = design_vector(tree)
    total_mass = sum(b.mass for b in tree.bodies)

    def run(g: float, steps: int = 400, dt: float = 2e-4):
        q, v = rng.normal(size=nv), rng.normal(size=nv) * 5.0

        def acc(qq, vv):
            return np.array(fn(qq, vv, p, g)[3]).ravel()

        out0 = fn(q, v, p, g)
        for _ in range(steps):
            k1 = (v, acc(q, v))
            k2 = (v + dt / 2 * k1[1], acc(q + dt / 2 * k1[0], v + dt / 2 * k1[1]))
            k3 = (v + dt / 2 * k2[1], acc(q + dt / 2 * k2[0], v + dt / 2 * k2[1]))
            k4 = (v + dt * k3[1], acc(q + dt * k3[0], v + dt * k3[1]))
            q = q + dt / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
            v = v + dt / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        out1 = fn(q, v, p, g)
        return float(out0[4]), float(out1[4]), np.array(out0[5])[:, 0], np.array(out1[5])[:, 0], steps * dt

    E0, E1, P0, P1, _ = run(0.0)
    assert E1 == pytest.approx(E0, rel=1e-7)
    np.testing.assert_allclose(P1, P0, atol=1e-9 * max(1.0, np.abs(P0).max()))
    _, _, P0, P1, T = run(9.81)
    np.testing.assert_allclose(P1 - P0, [0.0, -total_mass * 9.81 * T], atol=1e-8)


def test_touchdown_configuration_puts_the_lowest_contact_on_the_terrain():
    tree = case2()
    q = touchdown_configuration(tree, UNEVEN, base_x=0.0)
    C = np.array(compiled_dynamics(tree.topology())(q, np.zeros(len(q)), design_vector(tree), 0.0)[0]).T
    gaps = signed_gap(UNEVEN, C).gap
    assert gaps.min() == pytest.approx(0.0, abs=1e-12)
    assert np.argmin(gaps) == 1  # the toe, over the ramp
    assert gaps[0] == pytest.approx(0.0184, abs=1e-3)
    assert q[0] == 0.0 and q[2] == tree.bodies[0].angle


# --------------------------------------------------------------------------------------------
# Convergence to the rigid laws


@pytest.mark.parametrize(
    "law, stiffness", [(ContactLaw.PENALTY, (1e5, 1e6, 1e7, 1e8)), (ContactLaw.CONSTRAINT, (1e6, 1e7, 1e8, 1e9))]
)
@pytest.mark.parametrize("make", [rod, chain], ids=["rod", "chain"])
def test_one_contact_converges_to_newton(law, stiffness, make):
    """One contact: the stiff limit is Newton's law exactly (eq. 11 with one row). The error
    falls as k^-1/2 (the configuration moves during a contact of duration ~ k^-1/2) plus the
    step's ~0.2 / steps_per_period; internal impulses converge with it."""
    tree = make()
    rigid = evaluate(tree, PAPER_SCENE)
    errors = []
    for k in stiffness:
        c = simulate_impact(tree, PAPER_SCENE, CompliantSettings(law=law, stiffness=k, steps_per_period=960))
        assert c.status is CompliantStatus.SEPARATED and c.active == (0,)
        ext = abs(c.external[0] / rigid.external[0] - 1)
        internal = np.max(np.abs(c.internal_magnitude / rigid.internal_magnitude - 1)) if tree.n_bodies > 1 else 0.0
        errors.append(max(ext, internal))
    report(
        "compliant", f"1 contact, {make.__name__}, {law.value}: error vs Newton " + " ".join(f"{x:.1e}" for x in errors)
    )
    assert errors[-1] < 2.5e-3
    assert errors[-1] < errors[0] / 10


def test_one_contact_restitution_is_met():
    """The contact leaves with -e times its approach velocity (the clipped-law damping)."""
    c = simulate_impact(rod(), PAPER_SCENE, CompliantSettings(stiffness=1e8, steps_per_period=960))
    rigid = evaluate(rod(), PAPER_SCENE)
    layout_v = rigid.v_plus
    np.testing.assert_allclose(c.v_plus, layout_v, rtol=0, atol=2e-3 * np.abs(layout_v).max())
    assert c.energy_after < c.energy_before


def test_constraint_law_converges_to_newton_with_simultaneous_contacts():
    """Heel and toe touching at once: every contact's gap follows the same oscillator while all
    push, so the stiff limit of MuJoCo's soft-constraint law is eq. 11."""
    rigid = evaluate(case2(), PAPER_SCENE)
    errors = []
    for k in (1e7, 1e8, 1e9):
        c = simulate_impact(
            case2(), PAPER_SCENE, CompliantSettings(law=ContactLaw.CONSTRAINT, stiffness=k, steps_per_period=480)
        )
        errors.append(np.max(np.abs(c.external / rigid.external - 1)))
        assert abs(c.release_time[0] - c.release_time[1]) <= 2.5 * c.timestep  # both leave together
    report("compliant", "case 2, constraint law: ext error vs Newton " + " ".join(f"{x:.1e}" for x in errors))
    assert errors[-1] < 1.5e-3 and errors[-1] < errors[0] / 3


def test_penalty_law_limit_differs_from_newton_when_contacts_are_coupled():
    """Force-level pads with one stiffness: each contact rings at its own frequency (sqrt(k / m_i)),
    so contacts release at different times and the stiff limit is not eq. 11. Case 3's three toe
    pads are three times stiffer than case 2's one on the same (lumped) toe: the limits differ."""
    out = {}
    for name, make in (("case2", case2), ("case3", case3)):
        rigid = evaluate(make(), PAPER_SCENE)
        c = simulate_impact(make(), PAPER_SCENE, CompliantSettings(stiffness=1e8, steps_per_period=480))
        out[name] = c.external / rigid.external - 1
        out[name + " release"] = c.release_time
    report(
        "compliant",
        f"penalty law at 1e8 N/m vs Newton: case2 {np.round(out['case2'], 4)}, case3 {np.round(out['case3'], 4)}",
    )
    assert np.max(np.abs(out["case2"])) < 3e-3  # weakly coupled, similar periods: close to Newton
    heel, toe = out["case3 release"][:2]
    assert toe < 0.7 * heel  # three pads on the lumped toe: it rings faster than the heel
    assert abs(out["case3"][0]) > 3e-3  # case 3's heel: 0.4 % off eq. 11 and not closing with k


def test_elastic_impact_conserves_energy():
    for law, k in ((ContactLaw.PENALTY, 1e7), (ContactLaw.CONSTRAINT, 1e8)):
        c = simulate_impact(
            case2(), Scene(speed=3.43, restitution=1.0), CompliantSettings(law=law, stiffness=k, steps_per_period=120)
        )
        assert c.damping_ratio == 0.0
        assert c.energy_after == pytest.approx(c.energy_before, rel=2e-4)
        assert not c.energy_gain or c.energy_after / c.energy_before - 1 < 2e-4


def test_uneven_terrain_touchdown_order_and_convergence_to_sequential_impacts():
    """Toe on the ramp first, heel about 5 ms later; as the contacts stiffen, the impulses approach
    the sequential rigid model's (a Newton impact per touchdown, free flight between)."""
    from impulse_core.timedomain.sequential import sequential_impacts

    rigid = sequential_impacts(case2(), PAPER_SCENE, terrain=UNEVEN)
    errors, internal = [], []
    for k in (1e6, 1e7, 1e8):
        c = simulate_impact(case2(), PAPER_SCENE, CompliantSettings(stiffness=k, steps_per_period=240), terrain=UNEVEN)
        assert c.touchdown_order == (1, 0) and c.status is CompliantStatus.SEPARATED
        assert c.touchdown_time[1] == pytest.approx(0.0, abs=1e-12)
        assert c.touchdown_time[0] == pytest.approx(rigid.touchdown_time[0], abs=2e-5)
        np.testing.assert_allclose(c.external_vector[1] / c.external[1], [-0.1322, 0.9912], atol=1e-3)  # ramp normal
        errors.append(np.max(np.abs(c.external / rigid.external - 1)))
        internal.append(np.max(np.abs(c.internal_magnitude / rigid.internal_magnitude - 1)))
    report(
        "compliant",
        "uneven terrain, penalty: error vs sequential rigid, external "
        + " ".join(f"{x:.1e}" for x in errors)
        + ", internal "
        + " ".join(f"{x:.1e}" for x in internal),
    )
    assert errors[-1] < 2e-3 and errors[-1] < errors[0] / 3
    assert internal[-1] < 2e-2 and internal[-1] < internal[0] / 5


def test_gravity_adds_its_impulse():
    """Over the integration, the momentum change equals the contact plus gravity impulses, to the
    semi-implicit Euler's first order in the step (halving per doubled step count)."""
    tree = chain()
    g = 9.81
    fn = compiled_dynamics(tree.topology())
    p = design_vector(tree)
    m = sum(b.mass for b in tree.bodies)
    mismatch = []
    for n in (60, 240):
        c = simulate_impact(tree, PAPER_SCENE, CompliantSettings(stiffness=1e6, gravity=g, steps_per_period=n))
        P0 = np.array(fn(c.q_minus, c.v_minus, p, g)[5])[:, 0]
        P1 = np.array(fn(c.q_plus, c.v_plus, p, g)[5])[:, 0]
        mismatch.append(np.abs(P1 - P0 - c.external_vector.sum(axis=0) - [0.0, -m * g * c.duration]).max())
    assert mismatch[1] < 1e-3 * c.external_norm and mismatch[1] < 0.35 * mismatch[0]


def test_force_profile_integrates_to_the_impulse():
    c = simulate_impact(case2(), PAPER_SCENE, CompliantSettings(stiffness=1e6))
    np.testing.assert_allclose(c.force.sum(axis=0) * c.timestep, c.external, rtol=1e-12)
    assert c.force.shape == (c.n_steps, 2) and np.all(c.force >= 0)
    assert np.all(c.max_penetration > 0)


def test_runge_kutta_flight_between_touchdowns_is_converged():
    """The free flight between the toe's and the heel's touchdowns: Runge-Kutta 4 flight steps of
    1e-4 s and of 2.5e-5 s give the same answer, which contact steps throughout (first order)
    approach as the step shrinks, at a fraction of their cost."""
    st = dict(stiffness=1e7, steps_per_period=240)
    coarse = simulate_impact(case2(), PAPER_SCENE, CompliantSettings(**st, flight_step=1e-4), terrain=UNEVEN)
    fine = simulate_impact(case2(), PAPER_SCENE, CompliantSettings(**st, flight_step=2.5e-5), terrain=UNEVEN)
    np.testing.assert_allclose(coarse.external, fine.external, rtol=1e-8)
    np.testing.assert_allclose(coarse.internal_magnitude, fine.internal_magnitude, rtol=1e-7)
    assert coarse.n_flight_steps > 20 and coarse.n_steps < 400
    gaps = []
    for n in (240, 960):
        euler = simulate_impact(
            case2(), PAPER_SCENE, CompliantSettings(stiffness=1e7, steps_per_period=n, flight_step=None), terrain=UNEVEN
        )
        hybrid = simulate_impact(
            case2(), PAPER_SCENE, CompliantSettings(stiffness=1e7, steps_per_period=n), terrain=UNEVEN
        )
        assert euler.n_flight_steps == 0 and euler.n_steps > 10 * hybrid.n_steps
        gaps.append(np.max(np.abs(euler.external / hybrid.external - 1)))
    report(
        "compliant", f"uneven: contact-step flight vs RK4 flight at 240, 960 steps/period: {gaps[0]:.1e}, {gaps[1]:.1e}"
    )
    assert gaps[1] < 0.35 * gaps[0] and gaps[1] < 5e-4


def test_touchdown_order_groups_simultaneous_contacts():
    from impulse_core.timedomain.compliant import touchdown_order

    t = np.array([3e-13, 0.0, np.nan, 5e-3, 1e-13])
    assert touchdown_order(t, 1e-6) == (0, 1, 4, 3)
    assert touchdown_order(t, 1e-14) == (1, 4, 0, 3)


def test_a_slow_landing_under_gravity_settles():
    """At 1 cm/s under gravity the pad never lets go: the integration ends when the contact is at
    rest (SETTLED), with the weight carried and the momentum balance closed."""
    puck = Tree((Body("puck", None, 0.2, 1.0, 0.0, contacts=(0.5,)),))
    g, k = 9.81, 1e5
    c = simulate_impact(
        puck, Scene(speed=0.01, restitution=0.5), CompliantSettings(stiffness=k, gravity=g, max_time=0.5)
    )
    assert c.status is CompliantStatus.SETTLED
    assert np.isnan(c.release_time[0]) or c.release_time[0] == pytest.approx(c.duration, abs=2 * c.timestep)
    assert abs(c.v_plus[1]) < 1e-4
    assert c.external[0] == pytest.approx(0.01 + g * c.duration, rel=2e-2)  # m v0 + m g T
    assert c.max_penetration[0] > g / k  # at least the static deflection


def test_doubled_fixed_steps_meet_their_tolerance_and_estimate_their_error():
    """simulate_to_tolerance's doubling of fixed steps at 1e-4 on the uneven-terrain example: its
    error against the limit of the same model (Richardson from 7,680 and 15,360 steps per period)
    is below 2e-4, and its estimate is that error within a factor of 2 (first order: the last
    difference)."""
    from dataclasses import replace

    from impulse_core.timedomain.compliant import DOUBLING, CompliantSettings, simulate_impact, simulate_to_tolerance
    from optimizer.config.model_file import load_model_file

    m = load_model_file("configs/uneven_terrain.yaml")
    base = CompliantSettings(steps_per_period=120.0)
    ours = simulate_to_tolerance(m.tree, m.scene, base, 1e-4, method=DOUBLING)
    fine, finer = (simulate_impact(m.tree, m.scene, replace(base, steps_per_period=n)) for n in (7680.0, 15360.0))
    errors = []
    for a, b, c in ((ours.external, fine.external, finer.external),
                    (ours.internal_magnitude, fine.internal_magnitude, finer.internal_magnitude)):
        limit = 2 * c - b
        errors.append(np.max(np.abs(a - limit)) / np.max(np.abs(limit)))
    true_error = max(errors)
    assert ours.error_estimate <= 1e-4 and true_error <= 2e-4
    assert 0.5 * true_error <= ours.error_estimate <= 2.0 * true_error
    assert ours.steps_per_period > 120.0 and ours.tolerance == 1e-4 and ours.integrator == "euler"
