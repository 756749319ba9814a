"""The compliant rung in space against MuJoCo: ``footopt export``'s MJCF of a spatial model (a
freejoint base, hinges about each rod's axis) dropped on flat ground with the same contact law
(``optimizer.validation.mujoco_bridge.drop_spatial``), as tests/optimizer/test_mujoco.py does in
the plane. Same step, same number of steps, contact steps throughout: 1e-4 relative on every
external and internal impulse (MuJoCo's regulariser differs by ~(1 - d) = 1e-4; measured ~4e-6).

Unlike the plane, the two integrators are not the same map step for step in space: MuJoCo turns
the base by the exponential of omega dt (its quaternion), the rung steps its rotation vector
linearly. Both are first order and agree in the limit; over a long free flight with the tree
spinning fast the states part at O(dt) and a later touchdown's impulse differs by more (a random
tree spinning at 33 rad/s whose second contact lands after 29 ms of flight: 2e-4; its state
before that touchdown 1e-3, 2.4e-4, 4.5e-5 apart at 120, 480, 1920 steps per period). The 1e-4
check takes landings whose contacts all touch down within 5 ms; that case is checked to converge.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

pytest.importorskip("mujoco")

from impulse_core.kinematics.spatial import SPATIAL  # noqa: E402
from impulse_core.timedomain.compliant import (  # noqa: E402
    CompliantSettings,
    ContactLaw,
    damping_ratio_for_restitution,
    relative_difference,
    simulate_impact,
)
from optimizer.config.model_file import load_model_file  # noqa: E402
from optimizer.validation.mujoco_bridge import drop_spatial  # noqa: E402
from tests.conftest import report  # noqa: E402
from tests.impulse_core.test_compliant_spatial import OBLIQUE, random_spatial_trees, yaw_splayed_case3  # noqa: E402
from tests.optimizer.test_heightfield_cli import SPATIAL_CASE  # noqa: E402

AGREE = 1e-4
CONSTRAINT = CompliantSettings(law=ContactLaw.CONSTRAINT, stiffness=1e7, steps_per_period=120, flight_step=None)


def _cases():
    model = load_model_file(SPATIAL_CASE)
    rng = np.random.default_rng(20261128)
    return [("spatial_case3", model.tree, model.scene), ("yaw-splayed case3", yaw_splayed_case3(), OBLIQUE)] + [
        (f"random {k}", t, OBLIQUE) for k, t in enumerate(random_spatial_trees(rng, 3))
    ]


def test_constraint_law_agrees_with_mujoco_in_space():
    worst, checked = 0.0, 0
    for name, tree, scene in _cases():
        ours = simulate_impact(tree, scene, CONSTRAINT, space=SPATIAL)
        if np.nanmax(ours.touchdown_time) > 5e-3:
            continue  # a long flight first (module docstring)
        checked += 1
        mj = drop_spatial(tree, scene, CONSTRAINT, ours.n_steps, ours.timestep)
        ext = relative_difference([(mj.external, ours.external)])
        internal = relative_difference([(mj.internal_magnitude, ours.internal_magnitude)])
        worst = max(worst, ext, internal)
        assert ext < AGREE and internal < AGREE, name
        np.testing.assert_allclose(mj.external_vector, ours.external_vector, atol=AGREE * ours.external_norm)
        np.testing.assert_allclose(mj.internal, ours.internal, atol=AGREE * max(ours.internal_norm, 1e-300))
        np.testing.assert_allclose(mj.v_plus, ours.v_plus, atol=10 * AGREE * np.abs(ours.v_plus).max())
        touched = np.isfinite(ours.touchdown_time)
        assert np.array_equal(np.isfinite(mj.touchdown_time), touched)
        assert np.all(np.abs(mj.touchdown_time[touched] - ours.touchdown_time[touched]) <= 1.01 * ours.timestep)
        assert not mj.loaded_at_end
    assert checked >= 4
    report("mujoco", f"spatial, constraint law 1e7/s^2, {checked} trees: worst relative difference {worst:.1e}")


def test_after_a_long_spinning_flight_mujoco_and_the_rung_converge_together():
    """The state before a touchdown that follows 25 ms of fast-spinning flight: the difference
    from MuJoCo falls as the step (first order: the rotation updates differ, module docstring)."""
    tree = next(t for name, t, _ in _cases() if name == "random 2")
    gaps = []
    for n in (120, 480):
        st = dataclasses.replace(CONSTRAINT, max_time=0.025, steps_per_period=n)
        ours = simulate_impact(tree, OBLIQUE, st, space=SPATIAL)
        mj = drop_spatial(tree, OBLIQUE, st, ours.n_steps, ours.timestep)
        gaps.append(np.abs(ours.v_plus - mj.v_plus).max() / np.abs(ours.v_plus).max())
    report("mujoco", f"spatial, 25 ms spinning flight, state vs MuJoCo at 120, 480 steps: {gaps[0]:.1e}, {gaps[1]:.1e}")
    assert 3.0 < gaps[0] / gaps[1] < 6.0


def test_the_spatial_agreement_check_can_fail():
    """Control: MuJoCo with 1 % more contact damping is told apart at the same tolerance."""
    _, tree, scene = _cases()[1]
    ours = simulate_impact(tree, scene, CONSTRAINT, space=SPATIAL)
    zeta = 1.01 * damping_ratio_for_restitution(scene.restitution)
    mj = drop_spatial(tree, scene, dataclasses.replace(CONSTRAINT, damping_ratio=zeta), ours.n_steps, ours.timestep)
    assert relative_difference([(mj.external, ours.external)]) > AGREE


def test_penalty_law_agrees_with_mujoco_in_space_as_contacts_stiffen():
    """One contact on random spatial chains, MuJoCo's solref from its effective mass at
    touchdown: the laws differ by how finite accelerations act during a contact, falling as
    k^-1/2 or faster (with contacts loaded together MuJoCo couples them in its constraint solve: not checked)."""
    from impulse_core.model.tree import Body, Tree
    from tests.impulse_core.test_compliant_spatial import spatialize

    rng = np.random.default_rng(20261129)
    one = Tree((Body("thigh", None, 0.5, 2.0, -1.3), Body("shank", 0, 0.5, 1.0, 0.5),
                Body("foot", 1, 0.2, 0.3, 1.2, contacts=(1.0,))))
    for tree in (spatialize(rng, one), spatialize(rng, one)):
        errors = []
        for k in (1e6, 1e8):
            st = CompliantSettings(law=ContactLaw.PENALTY, stiffness=k, steps_per_period=120, flight_step=None)
            ours = simulate_impact(tree, OBLIQUE, st, space=SPATIAL)
            mj = drop_spatial(tree, OBLIQUE, st, ours.n_steps, ours.timestep, effective_mass=ours.effective_mass)
            errors.append(relative_difference([(mj.external, ours.external),
                                               (mj.internal_magnitude, ours.internal_magnitude)]))
        report("mujoco", f"spatial chain, penalty law vs MuJoCo at 1e6, 1e8 N/m: {errors[0]:.1e}, {errors[1]:.1e}")
        assert errors[1] < 2e-3  # measured 1.4e-6 and 1.4e-3 on these two spinning chains
        assert errors[0] / errors[1] > 5.0  # at least ~ k^-1/2 (measured 10x and 25x over two decades)
