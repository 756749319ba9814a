"""The compliant rung's adaptive integration (Dormand-Prince 5(4) between located contact switches):
its answer at a tolerance against the same model's converged answer, the honesty of its error
estimate, the momentum balance, and the location of the contact switches."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from fidelity_scenes import PAPER_SCENE, UNEVEN

from impulse_core.model.tree import Body, Scene, Tree, design_vector
from impulse_core.timedomain.adaptive import simulate_adaptive
from impulse_core.timedomain.compliant import (
    CompliantSettings,
    CompliantStatus,
    ContactLaw,
    clipped_restitution,
    compiled_dynamics,
    compliant_difference,
    damping_ratio_for_restitution,
    simulate_impact,
    simulate_to_tolerance,
)
from optimizer.config.model_file import load_model_file
from tests.conftest import random_tree, report

TOL = 1e-4
#: The converged answer: the adaptive integration at this local tolerance (its error is ~4e-11).
CONVERGED = 1e-9
LAWS = [(ContactLaw.PENALTY, 1e6), (ContactLaw.CONSTRAINT, 1e8)]


def _check_against_converged(tree: Tree, scene: Scene, settings: CompliantSettings) -> tuple[float, float]:
    """The rung at TOL and its error against the converged answer: within 2e-4, its estimate
    at most TOL, above the error and within 5 x of it. (error, estimate)."""
    ours = simulate_to_tolerance(tree, scene, settings, TOL)
    converged = simulate_adaptive(tree, scene, settings, CONVERGED)
    error = compliant_difference(ours, converged)
    assert ours.integrator == "dopri5" and ours.tolerance == TOL
    assert ours.touchdown_order == converged.touchdown_order and ours.status is converged.status
    assert error <= 2e-4 and ours.error_estimate <= TOL
    assert error <= ours.error_estimate <= 5.0 * error, (error, ours.error_estimate)
    return error, ours.error_estimate


@pytest.mark.parametrize("law, stiffness", LAWS)
def test_the_uneven_terrain_example_at_1e4_is_within_2e4_of_its_converged_answer(law, stiffness):
    m = load_model_file("optimizer/examples/uneven_terrain.yaml")
    error, estimate = _check_against_converged(m.tree, m.scene, CompliantSettings(law=law, stiffness=stiffness))
    report("compliant-adaptive", f"uneven terrain, {law.value}: error {error:.1e}, estimate {estimate:.1e} at {TOL:g}")


def test_the_converged_answer_is_the_fixed_steps_limit():
    """The adaptive answer at 1e-9 is the limit the fixed-step rung converges to: the fixed steps'
    distance to it (external and internal impulses) halves as their step does (first order)."""
    m = load_model_file("optimizer/examples/uneven_terrain.yaml")
    st = CompliantSettings(record=False)
    converged = simulate_adaptive(m.tree, m.scene, st, CONVERGED)
    distances = [
        compliant_difference(simulate_impact(m.tree, m.scene, dataclasses.replace(st, steps_per_period=n)), converged)
        for n in (7680, 15360, 30720)
    ]
    report("compliant-adaptive", "fixed steps at 7680, 15360, 30720 per period vs the adaptive answer at "
           f"{CONVERGED:g}: " + ", ".join(f"{d:.1e}" for d in distances))
    assert distances[2] < 1e-5
    assert all(0.4 < b / a < 0.6 for a, b in zip(distances, distances[1:]))


@pytest.mark.parametrize("seed", [0, 3])
@pytest.mark.parametrize("law, stiffness", LAWS)
def test_a_random_tree_on_uneven_terrain_is_within_2e4_of_its_converged_answer(seed, law, stiffness):
    tree = random_tree(np.random.default_rng(100 + seed), 5)
    scene = dataclasses.replace(PAPER_SCENE, terrain=UNEVEN)
    error, estimate = _check_against_converged(tree, scene, CompliantSettings(law=law, stiffness=stiffness))
    report("compliant-adaptive", f"random tree {seed}, {law.value}: error {error:.1e}, estimate {estimate:.1e}")


@pytest.mark.parametrize("law, stiffness", LAWS)
def test_the_momentum_balance_closes_to_the_tolerance(law, stiffness):
    """Under gravity, the change of the tree's linear momentum over the landing equals the
    contact impulses minus the weight's, to the tolerance (relative to the contact impulse)."""
    m = load_model_file("optimizer/examples/uneven_terrain.yaml")
    g = 9.81
    r = simulate_to_tolerance(m.tree, m.scene, CompliantSettings(law=law, stiffness=stiffness, gravity=g), TOL)
    fn, p = compiled_dynamics(m.tree.topology()), design_vector(m.tree)
    momentum = [np.array(fn(q, v, p, g)[5])[:, 0] for q, v in ((r.q_minus, r.v_minus), (r.q_plus, r.v_plus))]
    weight = sum(b.mass for b in m.tree.bodies) * g * r.duration
    imbalance = momentum[1] - momentum[0] - r.external_vector.sum(axis=0) - [0.0, -weight]
    contact = np.linalg.norm(r.external_vector.sum(axis=0))
    report("compliant-adaptive", f"momentum balance, {law.value}, g = {g}: {np.abs(imbalance).max() / contact:.1e}")
    assert np.abs(imbalance).max() <= TOL * contact


PUCK = Tree((Body("puck", None, 0.2, 1.0, 0.0, contacts=(0.5,)),))


def test_the_release_is_located_where_the_force_vanishes():
    """A puck on a penalty pad (its contact under its centre of mass: m x'' = -k x - c x'): it
    touches down 1e-12 m / v0 after the start, releases when k x + c x' falls to 0, at
    (pi - 2 asin zeta) / omega_d later, and leaves at e v0 (:func:`clipped_restitution`): the
    event lands on that instant to rounding, and the rebound is the closed form's."""
    k, v0, e = 1e5, 1.0, 0.8
    r = simulate_adaptive(PUCK, Scene(speed=v0, restitution=e), CompliantSettings(stiffness=k), 1e-12)
    zeta = damping_ratio_for_restitution(e)
    omega_d = math.sqrt(k / PUCK.bodies[0].mass) * math.sqrt(1 - zeta**2)
    contact_time = (math.pi - 2 * math.asin(zeta)) / omega_d
    assert r.status is CompliantStatus.SEPARATED
    assert r.touchdown_time[0] == pytest.approx(1e-12 / v0, rel=1e-9)
    assert r.release_time[0] - r.touchdown_time[0] == pytest.approx(contact_time, rel=1e-12, abs=0)
    assert r.v_plus[1] == pytest.approx(clipped_restitution(zeta) * v0, rel=1e-11)
    assert r.duration == r.release_time[0]  # separated at the release: it moves up


def test_fixed_steps_stay_fixed():
    """--steps-per-period's path: semi-implicit Euler at the given step, no estimate."""
    m = load_model_file("optimizer/examples/uneven_terrain.yaml")
    r = simulate_impact(m.tree, m.scene, CompliantSettings(steps_per_period=60))
    assert r.integrator == "euler" and r.steps_per_period is None and r.error_estimate is None
