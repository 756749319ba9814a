"""The compliant and sequential rungs in space (``model.space: spatial``) and on heightfields.

Laws checked (seeded random cases):
- a planar tree read as spatial gives the planar answer (flat ground, and a planar terrain y(x)
  written as a heightfield constant along z);
- a flat heightfield is flat ground; a heightfield that is one tilted plane gives the answer of
  flat ground with the whole scene rotated (the gap and normal are the plane's);
- the impulse of the contact forces and gravity equals the change of the tree's momentum;
- as the contacts stiffen, the compliant answer converges to the rigid (eq. 11) one, and the
  sequential rung on flat ground with level contacts is eq. 11.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from fidelity_scenes import PAPER_SCENE, UNEVEN, case2, case3, chain, rod

from impulse_core.errors import ModelError, NumericalError
from impulse_core.evaluate import evaluate
from impulse_core.kinematics.spatial import SPATIAL
from impulse_core.model.heightfield import Heightfield, flat_heightfield
from impulse_core.model.rods import body_rotation, rotation_rpy
from impulse_core.model.tree import Body, ContactSelection, Scene, Tree
from impulse_core.timedomain.compliant import (
    CompliantSettings,
    CompliantStatus,
    ContactLaw,
    chart_rates,
    chart_rotation,
    compliant_difference,
    relative_difference,
    simulate_impact,
    simulate_to_tolerance,
    subtree_masses,
)
from impulse_core.timedomain.sequential import sequential_impacts
from tests.conftest import random_tree, report

SEED = 20261127
SOFT = CompliantSettings(stiffness=1e6)
TOL = 1e-4


def as_heightfield(terrain) -> Heightfield:
    """A planar profile y(x) as a heightfield constant along z."""
    return Heightfield(terrain.x, (0.0,), tuple((y,) for y in terrain.y))


def spatialize(rng: np.random.Generator, tree: Tree) -> Tree:
    """Random fixed rotations, joint axes and radii (as tests/impulse_core/test_spatial.py)."""
    return Tree(
        tuple(
            dataclasses.replace(
                b,
                rpy=tuple(rng.uniform(-1.0, 1.0, 3)),
                axis=tuple(rng.normal(size=3)),
                radius=float(rng.uniform(0, min(0.05, b.gyration * b.length))),
            )
            for b in tree.bodies
        )
    )


def random_spatial_trees(rng: np.random.Generator, n: int) -> list[Tree]:
    return [
        spatialize(rng, random_tree(rng, int(rng.integers(2, 5)), p_contact=0.6, mass_ratio=5.0, length_range=(0.1, 0.6)))
        for _ in range(n)
    ]


def rpy_of(R: np.ndarray) -> tuple[float, float, float]:
    """(roll, pitch, yaw) of R = Rz(yaw) Ry(pitch) Rx(roll)."""
    return (
        math.atan2(R[2, 1], R[2, 2]),
        -math.asin(max(-1.0, min(1.0, R[2, 0]))),
        math.atan2(R[1, 0], R[0, 0]),
    )


def rotated(tree: Tree, R: np.ndarray) -> Tree:
    """The tree with its base (hence the whole tree) turned by R about the world origin."""
    base = tree.bodies[0]
    turned = dataclasses.replace(base, rpy=rpy_of(R @ body_rotation(base)), axis=(0.0, 0.0, 1.0), angle=0.0)
    np.testing.assert_allclose(body_rotation(turned), R @ body_rotation(base), atol=1e-14)
    return Tree((turned, *tree.bodies[1:]))


def rotated_scene(scene: Scene, R: np.ndarray) -> Scene:
    v = R @ np.array(scene.velocity)
    w = R @ np.array(scene.angular_velocity_3d)
    return dataclasses.replace(
        scene, speed=-v[1], velocity_x=v[0], velocity_z=v[2], angular_velocity_x=w[0], angular_velocity_y=w[1],
        angular_velocity=w[2],
    )


def yaw_splayed_case3(splay: float = 0.35) -> Tree:
    """Case 3 with its outer toes turned about the vertical through the ankle (the design space's
    spatial foot: rpy = Rz(-phi) Ry(psi) Rz(phi), phi the shank's absolute angle): every contact
    stays at its planar height, so heel and toes touch down together."""
    tree = case3()
    phi = tree.bodies[0].angle + tree.bodies[1].angle
    bodies = list(tree.bodies)
    for i, psi in ((3, -splay), (7, splay)):  # toe1 and toe3 proximal rods
        R = rotation_rpy((0.0, 0.0, -phi)) @ rotation_rpy((0.0, psi, 0.0)) @ rotation_rpy((0.0, 0.0, phi))
        bodies[i] = dataclasses.replace(bodies[i], rpy=rpy_of(R))
    return Tree(tuple(bodies))


OBLIQUE = dataclasses.replace(
    PAPER_SCENE, velocity_x=0.2, velocity_z=0.3, angular_velocity_x=0.5, angular_velocity_y=-0.3, angular_velocity=0.2
)


# --------------------------------------------------------------------------------------------
# Rotation coordinates


def test_chart_rates_are_the_angular_velocity_of_the_chart_rotation():
    rng = np.random.default_rng(SEED)
    for _ in range(10):
        a, da = rng.uniform(-1, 1, 3), rng.normal(size=3)
        h = 1e-6
        Rdot = (chart_rotation(a + h * da) - chart_rotation(a - h * da)) / (2 * h)
        W = Rdot @ chart_rotation(a).T
        w = np.array([W[2, 1], W[0, 2], W[1, 0]])
        np.testing.assert_allclose(chart_rates(a) @ da, w, atol=1e-8)
        import casadi as ca

        np.testing.assert_allclose(np.array(ca.DM(chart_rotation(ca.SX(ca.DM(a))))), chart_rotation(a), atol=1e-15)


# --------------------------------------------------------------------------------------------
# Planar files read as spatial


def test_planar_trees_read_as_spatial_give_the_planar_compliant_and_sequential_answers():
    rng = np.random.default_rng(SEED + 1)
    worst = 0.0
    cases = [(case2(), PAPER_SCENE), (chain(), PAPER_SCENE), (rod(), PAPER_SCENE)]
    for _ in range(4):
        tree = random_tree(rng, int(rng.integers(2, 5)), mass_ratio=5.0, length_range=(0.1, 0.6))
        scene = Scene(speed=float(rng.uniform(1, 4)), restitution=float(rng.uniform(0.2, 1.0)),
                      velocity_x=float(rng.uniform(-0.5, 0.5)), angular_velocity=float(rng.uniform(-1, 1)))
        cases.append((tree, scene))
    for tree, scene in cases:
        for law in ContactLaw:
            st = dataclasses.replace(SOFT, law=law, stiffness=1e6 if law is ContactLaw.PENALTY else 1e7)
            planar = simulate_impact(tree, scene, st)
            spatial = simulate_impact(tree, scene, st, space=SPATIAL)
            d = compliant_difference(spatial, planar)
            worst = max(worst, d)
            assert d < 1e-10, (law, d)
            assert spatial.n_steps == planar.n_steps and spatial.status is planar.status
            np.testing.assert_allclose(spatial.internal, planar.internal, atol=1e-10 * planar.internal_norm + 1e-300)
            np.testing.assert_allclose(spatial.v_plus[[0, 1, 5]], planar.v_plus[:3], atol=1e-9)
            np.testing.assert_allclose(spatial.v_plus[2:5], 0.0, atol=1e-12)
        try:
            planar_seq = sequential_impacts(tree, scene)
        except NumericalError:  # a random tree whose contacts chatter: so must the spatial run
            with pytest.raises(NumericalError, match="chatter"):
                sequential_impacts(tree, scene, space=SPATIAL)
            continue
        spatial_seq = sequential_impacts(tree, scene, space=SPATIAL)
        d = relative_difference([(spatial_seq.external, planar_seq.external),
                                 (spatial_seq.internal_magnitude, planar_seq.internal_magnitude)])
        assert d < 1e-10 and len(spatial_seq.events) == len(planar_seq.events)
        np.testing.assert_allclose(spatial_seq.v_plus[[0, 1, 5]], planar_seq.v_plus[:3], atol=1e-9)
    report("compliant-spatial", f"planar trees read as spatial: compliant rung within {worst:.1e} of the planar answer")


def test_a_planar_terrain_as_a_heightfield_gives_the_planar_answer():
    """configs/uneven_terrain.yaml's ramp, constant along z: the toe on the ramp first, the heel
    5 ms later; the compliant (to its tolerance) and sequential rungs as in the plane."""
    field = as_heightfield(UNEVEN)
    planar = simulate_to_tolerance(case2(), dataclasses.replace(PAPER_SCENE, terrain=UNEVEN), SOFT, 1e-3)
    spatial = simulate_to_tolerance(case2(), dataclasses.replace(PAPER_SCENE, heightfield=field), SOFT, 1e-3,
                                    space=SPATIAL)
    assert planar.touchdown_order == spatial.touchdown_order == (1, 0)
    assert compliant_difference(spatial, planar) < 1e-10
    assert spatial.error_estimate == pytest.approx(planar.error_estimate, rel=1e-8)
    assert spatial.error_estimate <= 1e-3
    rigid_planar = sequential_impacts(case2(), PAPER_SCENE, terrain=UNEVEN)
    rigid_spatial = sequential_impacts(case2(), PAPER_SCENE, terrain=field, space=SPATIAL)
    d = relative_difference([(rigid_spatial.external, rigid_planar.external),
                             (rigid_spatial.internal_magnitude, rigid_planar.internal_magnitude)])
    assert d < 1e-10
    np.testing.assert_allclose(rigid_spatial.touchdown_time, rigid_planar.touchdown_time, atol=1e-12)


def test_a_flat_heightfield_is_flat_ground():
    rng = np.random.default_rng(SEED + 2)
    for tree in random_spatial_trees(rng, 3) + [yaw_splayed_case3()]:
        level = float(rng.uniform(-0.5, 0.5))
        grid = Heightfield.from_arrays([-1.0, 0.0, 2.0], [-1.0, 1.0], np.full((3, 2), level))
        plain = simulate_impact(tree, OBLIQUE, SOFT, space=SPATIAL)
        on_field = simulate_impact(tree, dataclasses.replace(OBLIQUE, heightfield=grid), SOFT, space=SPATIAL)
        assert compliant_difference(on_field, plain) < 1e-9
        np.testing.assert_allclose(on_field.q_minus[1] - plain.q_minus[1], level, atol=1e-12)
        assert evaluate(tree, dataclasses.replace(OBLIQUE, heightfield=grid), space=SPATIAL).external_norm == (
            pytest.approx(evaluate(tree, OBLIQUE, space=SPATIAL).external_norm, rel=1e-12)
        )
        assert tuple(plain.touchdown_order) == tuple(on_field.touchdown_order)
        flat = flat_heightfield(level)
        one_point = simulate_impact(tree, OBLIQUE, SOFT, terrain=flat, space=SPATIAL)
        assert compliant_difference(one_point, plain) < 1e-9


def test_a_tilted_plane_heightfield_equals_flat_ground_with_the_scene_rotated():
    """Flat ground under a scene turned by R^T is the plane n . p = 0, n = R^T e_y, as a
    heightfield (a bilinear grid of a linear function is that plane): the same impulses, the
    velocity after turned back, step for step (the base's rotation coordinates are a rotation
    vector, which turns with the scene): to rounding, not just to the rung's tolerance."""
    rng = np.random.default_rng(SEED + 3)
    worst = 0.0
    trees = random_spatial_trees(rng, 4) + [yaw_splayed_case3()]
    for tree in trees:
        Rt = rotation_rpy(tuple(rng.uniform(-0.3, 0.3, 3)))  # world <- flat world: R^T
        n = Rt @ np.array([0.0, 1.0, 0.0])
        x = z = np.linspace(-4.0, 4.0, 3)
        heights = -(n[0] * x[:, None] + n[2] * z[None, :]) / n[1]
        field = Heightfield.from_arrays(x, z, heights)
        flat_result = simulate_impact(tree, OBLIQUE, SOFT, space=SPATIAL)
        tilted = simulate_impact(
            rotated(tree, Rt), dataclasses.replace(rotated_scene(OBLIQUE, Rt), heightfield=field), SOFT, space=SPATIAL
        )
        d = compliant_difference(tilted, flat_result)
        worst = max(worst, d)
        assert d < 1e-10
        assert tilted.n_steps == flat_result.n_steps
        np.testing.assert_allclose(tilted.external_vector, flat_result.external_vector @ Rt.T,
                                   atol=1e-10 * flat_result.external_norm)
        scale = np.abs(flat_result.v_plus).max()
        np.testing.assert_allclose(tilted.v_plus[:3], Rt @ flat_result.v_plus[:3], atol=1e-10 * scale)
        np.testing.assert_allclose(tilted.v_plus[3:6], Rt @ flat_result.v_plus[3:6], atol=1e-10 * scale)
        np.testing.assert_allclose(tilted.v_plus[6:], flat_result.v_plus[6:], atol=1e-10 * scale)
        assert tilted.touchdown_order == flat_result.touchdown_order
    report("compliant-spatial", f"tilted-plane heightfield vs rotated flat scene: {worst:.1e} (5 random cases)")


# --------------------------------------------------------------------------------------------
# Momentum balance


def _momentum_error(tree: Tree, scene: Scene, r, gravity: float) -> float:
    """|P+ - P- - (contact impulses + gravity's)| / |P+ - P-|: the tree's linear momentum read from
    the integrated state through the tree's own kinematics, the impulses from the forces."""
    from impulse_core.timedomain.compliant import touchdown_evaluator

    evaluate_step, _ = touchdown_evaluator(tree, scene, gravity, space=SPATIAL)
    P0 = evaluate_step(r.q_minus, r.v_minus).momentum[:, 0].copy()
    v_rates = r.v_plus.copy()  # v_plus is the core's velocity: back to the rotation coordinates' rates
    v_rates[3:6] = np.linalg.solve(chart_rates(r.q_plus[3:6]), r.v_plus[3:6])
    P1 = evaluate_step(r.q_plus, v_rates).momentum[:, 0].copy()
    impulse = r.external_vector.sum(axis=0) + np.array([0.0, -gravity * subtree_masses(tree)[0] * r.duration, 0.0])
    return float(np.linalg.norm(P1 - P0 - impulse) / np.linalg.norm(P1 - P0))


FIELD = Heightfield.from_arrays([-0.5, 0.3, 0.9], [-0.4, 0.0, 0.4],
                                [[0.0, 0.01, 0.0], [0.02, 0.0, -0.01], [0.04, 0.03, 0.05]])


@pytest.mark.parametrize("gravity", [0.0, 9.81])
def test_the_compliant_landing_balances_momentum(gravity):
    """On an uneven heightfield, landing obliquely: the impulse of the contact forces and of
    gravity over the landing equals the change of the tree's linear momentum to the rung's
    tolerance (within 3 x of it at 1e-4), and the difference is the integrator's: it falls as the
    step (first order, a factor 4 from 240 to 960 steps per contact period)."""
    rng = np.random.default_rng(SEED + 4)
    scene = dataclasses.replace(OBLIQUE, heightfield=FIELD)
    st = dataclasses.replace(SOFT, gravity=gravity)
    worst = 0.0
    trees = random_spatial_trees(rng, 2) + [yaw_splayed_case3()]
    for tree in trees:
        r = simulate_to_tolerance(tree, scene, st, TOL, space=SPATIAL)
        assert r.status in (CompliantStatus.SEPARATED, CompliantStatus.SETTLED)
        error = _momentum_error(tree, scene, r, gravity)
        worst = max(worst, error)
        assert error < 3 * r.tolerance, error
    coarse, fine = (
        _momentum_error(trees[-1], scene, simulate_impact(trees[-1], scene, dataclasses.replace(st, steps_per_period=n),
                                                          space=SPATIAL), gravity)
        for n in (240, 960)
    )
    assert 3.0 < coarse / fine < 5.0
    report("compliant-spatial", f"momentum balance (g = {gravity}): worst relative error {worst:.1e} at tolerance "
           f"{TOL:g}; 240 -> 960 steps per period: {coarse:.1e} -> {fine:.1e}")


def test_the_sequential_rung_balances_momentum_in_space():
    from impulse_core.timedomain.compliant import touchdown_evaluator

    tree = yaw_splayed_case3()
    scene = dataclasses.replace(OBLIQUE, heightfield=FIELD)
    r = sequential_impacts(tree, scene, space=SPATIAL)
    assert len(r.events) >= 2 and len(r.touchdown_order) == 4
    evaluate_step, q0 = touchdown_evaluator(tree, scene, 0.0, space=SPATIAL)
    from impulse_core.evaluate import pre_impact_velocity

    v0 = pre_impact_velocity(tree.topology(), scene, SPATIAL)
    P0 = evaluate_step(q0, v0).momentum[:, 0].copy()
    v_rates = r.v_plus.copy()
    v_rates[3:6] = np.linalg.solve(chart_rates(r.q_plus[3:6]), r.v_plus[3:6])
    P1 = evaluate_step(r.q_plus, v_rates).momentum[:, 0].copy()
    np.testing.assert_allclose(P1 - P0, r.external_vector.sum(axis=0), atol=1e-10 * np.linalg.norm(P1 - P0))


# --------------------------------------------------------------------------------------------
# Stiff limit: the rigid rungs


def test_the_compliant_rung_converges_to_newton_in_space():
    """Yaw-splayed case 3 (heel and three toes level, toes off the plane) landing obliquely,
    turning about all three axes: MuJoCo's soft-constraint law (every contact's gap follows the
    same oscillator while all push) converges to eq. 11 as it stiffens; the one-contact penalty
    law on random spatial trees too."""
    tree = yaw_splayed_case3()
    scene = dataclasses.replace(OBLIQUE, selection=ContactSelection.ALL)
    rigid = evaluate(tree, scene, space=SPATIAL)
    assert rigid.model.value == "newton"
    errors = []
    for k in (1e6, 1e7, 1e8, 1e9):
        c = simulate_impact(tree, scene, CompliantSettings(law=ContactLaw.CONSTRAINT, stiffness=k,
                                                           steps_per_period=480), space=SPATIAL)
        assert c.active == (0, 1, 2, 3)
        errors.append(relative_difference([(c.external, rigid.external), (c.internal_magnitude, rigid.internal_magnitude)]))
    report("compliant-spatial", "yaw-splayed case 3, constraint law vs newton at 1e6 ... 1e9: "
           + " ".join(f"{e:.1e}" for e in errors))
    assert errors[-1] < 6e-3
    assert all(a > 2.5 * b for a, b in zip(errors, errors[1:]))  # ~ k^-1/2: sqrt(10) per decade

    rng = np.random.default_rng(SEED + 5)
    one = Tree((Body("thigh", None, 0.5, 2.0, -1.3), Body("shank", 0, 0.5, 1.0, 0.5),
                Body("foot", 1, 0.2, 0.3, 1.2, contacts=(1.0,))))
    for tree in [spatialize(rng, one), spatialize(rng, one)]:
        rigid = evaluate(tree, OBLIQUE, space=SPATIAL)
        errs = []
        for k in (1e6, 1e8):
            c = simulate_impact(tree, OBLIQUE, CompliantSettings(stiffness=k, steps_per_period=960), space=SPATIAL)
            errs.append(relative_difference([(c.external, rigid.external), (c.internal_magnitude, rigid.internal_magnitude)]))
        report("compliant-spatial", f"one contact, random spatial chain, penalty vs newton at 1e6, 1e8: {errs[0]:.1e} {errs[1]:.1e}")
        assert errs[1] < 0.015 and 5 < errs[0] / errs[1] < 20, errs


def test_the_sequential_rung_on_level_contacts_is_newton_in_space():
    tree = yaw_splayed_case3()
    scene = dataclasses.replace(PAPER_SCENE, velocity_z=0.3)  # level contacts, same approach speed
    rigid = evaluate(tree, scene, space=SPATIAL)
    seq = sequential_impacts(tree, scene, space=SPATIAL)
    assert len(seq.events) == 1
    d = relative_difference([(seq.external, rigid.external), (seq.internal_magnitude, rigid.internal_magnitude)])
    assert d < 1e-9
    np.testing.assert_allclose(seq.v_plus, rigid.v_plus, atol=1e-9 * np.abs(rigid.v_plus).max())


# --------------------------------------------------------------------------------------------
# Refusals


def test_a_planar_terrain_that_is_not_flat_is_refused_in_space():
    with pytest.raises(ModelError, match=r"scene\.terrain"):
        simulate_impact(case2(), dataclasses.replace(PAPER_SCENE, terrain=UNEVEN), SOFT, space=SPATIAL)
    field = as_heightfield(UNEVEN)
    with pytest.raises(ModelError, match=r"scene\.heightfield"):
        evaluate(case2(), dataclasses.replace(PAPER_SCENE, heightfield=field), space=SPATIAL)
