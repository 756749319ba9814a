"""The first instant on uneven ground (``lcp`` and ``friction`` where the ground is not flat).

Checked independently: a uniform slope of angle a is flat ground turned by a, so the first
instant on the slope equals the flat rungs (checked against oracles elsewhere) on the same model
turned by -a, with the impulses turned back: normal and tangential impulses and joint impulse
magnitudes to 1e-9 (seeded random trees and approaches; lcp, and friction sticking and sliding;
planar terrain and spatial heightfield). And the whole landing's first event is the same answer.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from fidelity_scenes import PAPER_SCENE, UNEVEN, case2

from impulse_core.errors import ModelError
from impulse_core.evaluate import evaluate
from impulse_core.impact.coulomb import ContactMode
from impulse_core.impact.laws import ImpactModel
from impulse_core.kinematics.spatial import SPATIAL
from impulse_core.model.heightfield import Heightfield
from impulse_core.model.rods import rotation_rpy
from impulse_core.model.terrain import Terrain
from impulse_core.model.tree import ContactSelection, Scene, Tree
from impulse_core.timedomain.first_instant import REASON, first_instant
from impulse_core.timedomain.landing import LandingSettings, landing
from tests.conftest import random_tree
from tests.impulse_core.test_compliant_spatial import random_spatial_trees, rotated, rotated_scene

SEED = 20261126
TOL = 1e-9


def slope_terrain(a: float) -> Terrain:
    return Terrain((-10.0, 10.0), (-10.0 * math.tan(a), 10.0 * math.tan(a)))


def slope_heightfield(a: float) -> Heightfield:
    x = np.array([-10.0, 10.0])
    return Heightfield.from_arrays(x, np.array([-10.0, 10.0]), np.tile(x[:, None] * math.tan(a), (1, 2)))


def turned_planar(tree: Tree, scene: Scene, a: float) -> tuple[Tree, Scene]:
    """The planar tree and approach turned by -a about z."""
    base = dataclasses.replace(tree.bodies[0], angle=tree.bodies[0].angle - a)
    c, s = math.cos(a), math.sin(a)
    vx, vy = scene.velocity_x, -scene.speed
    return Tree((base, *tree.bodies[1:])), dataclasses.replace(scene, velocity_x=c * vx + s * vy, speed=-(-s * vx + c * vy))


def _close(a: np.ndarray, b: np.ndarray, scale: float) -> float:
    return float(np.max(np.abs(np.asarray(a) - np.asarray(b)), initial=0.0)) / scale


def assert_same_impact(on_slope, flat, model: ImpactModel) -> float:
    """The slope's answer is the flat one's (impulses are per contact along the local normal and
    tangents, which the turn maps to +y and x, z); returns the largest relative difference."""
    scale = max(float(np.max(np.abs(flat.external))), 1e-300)
    worst = max(_close(on_slope.external, flat.external, scale), _close(on_slope.tangential, flat.tangential, scale),
                _close(on_slope.internal_magnitude, flat.internal_magnitude, scale))
    assert worst <= TOL, worst
    assert on_slope.active == flat.active and on_slope.model is flat.model is model
    assert on_slope.energy_after == pytest.approx(flat.energy_after, rel=1e-9, abs=1e-12 * flat.energy_before)
    if model is ImpactModel.FRICTION:
        assert on_slope.modes == flat.modes
    return worst


def _planar_cases(rng: np.random.Generator, n: int):
    for k in range(n):
        tree = random_tree(rng, int(rng.integers(2, 5)), p_fixed=0.0, p_contact=0.8, mass_ratio=5.0,
                           length_range=(0.1, 0.6))
        selection = ContactSelection.ALL if k % 2 else ContactSelection.LOWEST
        scene = Scene(speed=float(rng.uniform(1.0, 3.0)), velocity_x=float(rng.uniform(-0.8, 0.8)),
                      angular_velocity=float(rng.uniform(-2.0, 2.0)), restitution=float(rng.uniform(0.0, 0.9)),
                      selection=selection)
        yield tree, scene, float(rng.uniform(-0.35, 0.35))


@pytest.mark.parametrize("mu", [0.0, 0.15, 3.0])
def test_a_planar_slope_is_flat_ground_turned(mu: float):
    """lcp (mu 0) and friction: mostly sliding at mu 0.15, sticking at mu 3."""
    rng = np.random.default_rng(SEED + int(100 * mu))
    modes: set[ContactMode] = set()
    for tree, scene, a in _planar_cases(rng, 8):
        scene = dataclasses.replace(scene, friction=mu)
        slope = dataclasses.replace(scene, terrain=slope_terrain(a))
        flat_tree, flat_scene = turned_planar(tree, scene, a)
        for model in (ImpactModel.LCP, ImpactModel.FRICTION) if mu else (ImpactModel.LCP,):
            on_slope = first_instant(tree, slope, model)
            flat = evaluate(flat_tree, flat_scene, model)
            assert_same_impact(on_slope, flat, model)
            assert on_slope.reason.startswith("requested; " + REASON)
            modes |= set(on_slope.modes or ())
    if mu:
        assert (ContactMode.SLIDING if mu < 1 else ContactMode.STICKING) in modes, modes


@pytest.mark.parametrize("mu", [0.0, 0.15, 3.0])
def test_a_spatial_slope_is_flat_ground_turned(mu: float):
    """h = x tan a is flat ground turned by a about z: the spatial model turned by -a about z
    (its base, its velocity and angular velocity) lands on flat ground with the same impulses;
    [t_x, t_z] are the slope's tangents, the flat ground's x and z once turned."""
    rng = np.random.default_rng(SEED + 7 + int(100 * mu))
    modes: set[ContactMode] = set()
    for k, tree in enumerate(random_spatial_trees(rng, 5)):
        a = float(rng.uniform(-0.35, 0.35))
        scene = Scene(speed=float(rng.uniform(1.0, 3.0)), velocity_x=float(rng.uniform(-0.6, 0.6)),
                      velocity_z=float(rng.uniform(-0.6, 0.6)), angular_velocity=float(rng.uniform(-1, 1)),
                      angular_velocity_x=float(rng.uniform(-1, 1)), angular_velocity_y=float(rng.uniform(-1, 1)),
                      restitution=float(rng.uniform(0.0, 0.9)), friction=mu,
                      selection=ContactSelection.ALL if k % 2 else ContactSelection.LOWEST)
        R = rotation_rpy((0.0, 0.0, -a))
        slope = dataclasses.replace(scene, heightfield=slope_heightfield(a))
        for model in (ImpactModel.LCP, ImpactModel.FRICTION) if mu else (ImpactModel.LCP,):
            on_slope = first_instant(tree, slope, model, SPATIAL)
            flat = evaluate(rotated(tree, R), rotated_scene(scene, R), model, SPATIAL)
            assert_same_impact(on_slope, flat, model)
            modes |= set(on_slope.modes or ())
    if mu:
        assert (ContactMode.SLIDING if mu < 1 else ContactMode.STICKING) in modes, modes


def test_on_flat_ground_it_is_the_flat_rung():
    """A flat terrain's first instant (forced through the landing's law) is the flat rung's."""
    rng = np.random.default_rng(SEED + 1)
    for tree, scene, _ in _planar_cases(rng, 4):
        for model, mu in ((ImpactModel.LCP, 0.0), (ImpactModel.FRICTION, 0.4)):
            scene = dataclasses.replace(scene, friction=mu)
            assert_same_impact(first_instant(tree, scene, model), evaluate(tree, scene, model), model)


def test_the_landing_first_event_is_the_first_instant():
    """On the uneven terrain, with friction, springs' gravity and a duration: the landing's first
    event is the first instant (equal to rounding: one law)."""
    scene = dataclasses.replace(PAPER_SCENE, terrain=UNEVEN, selection=ContactSelection.LOWEST, friction=0.4,
                                gravity=9.81, duration=2e-3)
    run = landing(case2(), scene, (), LandingSettings(tolerance=1.0, max_refinements=1))
    first = run.events[0]
    for model, mu in ((ImpactModel.FRICTION, 0.4), (ImpactModel.LCP, 0.0)):
        event = first if mu else landing(case2(), dataclasses.replace(scene, friction=0.0), (),
                                         LandingSettings(tolerance=1.0, max_refinements=1)).events[0]
        instant = first_instant(case2(), scene, model)
        scale = float(np.max(instant.external))
        assert _close(event.external, instant.external, scale) <= TOL
        assert _close(event.tangential, instant.tangential, scale) <= TOL
        assert _close(event.internal_magnitude, instant.internal_magnitude, scale) <= TOL
    assert instant.active == (1,)  # the toe on the ramp touches first


def test_newton_and_decoupled_are_refused_on_uneven_ground():
    scene = dataclasses.replace(PAPER_SCENE, terrain=UNEVEN)
    for model in (ImpactModel.NEWTON, ImpactModel.DECOUPLED, ImpactModel.FRICTION_RELAXED):
        with pytest.raises(ModelError, match=r"^model: .* assumes flat ground"):
            first_instant(case2(), scene, model)


def test_the_joint_torques_are_the_flat_rung_s():
    """The torque impulses (from the compiled response to the impulse vectors) on flat ground."""
    rng = np.random.default_rng(SEED + 2)
    for tree, scene, _ in _planar_cases(rng, 3):
        scene = dataclasses.replace(scene, friction=0.5)
        a, b = first_instant(tree, scene, ImpactModel.FRICTION), evaluate(tree, scene, ImpactModel.FRICTION)
        np.testing.assert_allclose(a.internal_torque, b.internal_torque, atol=1e-9 * np.max(b.external))
        np.testing.assert_allclose(a.v_plus, b.v_plus, atol=1e-9 * max(1.0, np.max(np.abs(b.v_minus))))


def test_the_first_instant_never_pulls_and_names_its_separating_contacts():
    """The lcp and friction rungs' impulses are >= 0: ``pulling`` is empty, also where a contact
    that takes part is left without impulse (then ``separating``, its impulse 0)."""
    rng = np.random.default_rng(SEED + 4)
    separated = 0
    for tree, scene, a in _planar_cases(rng, 8):
        scene = dataclasses.replace(scene, selection=ContactSelection.ALL, friction=0.4, terrain=slope_terrain(a))
        for model in (ImpactModel.LCP, ImpactModel.FRICTION):
            r = first_instant(tree, scene, model)
            assert r.pulling == () and np.all(r.external >= 0.0)
            assert all(r.external[i] <= 1e-12 * np.max(r.external) for i in r.separating)
            separated += len(r.separating)
    assert separated >= 2


def test_the_spatial_joint_torques_are_the_flat_rung_s():
    """In space, with friction (both tangents, [t_x, t_z], in the torques' impulse vectors): on
    flat ground the first instant's torque impulses, joint forces and v_plus are the flat rung's."""
    rng = np.random.default_rng(SEED + 3)
    for tree in random_spatial_trees(rng, 4):
        scene = Scene(speed=float(rng.uniform(1.0, 3.0)), velocity_x=float(rng.uniform(-0.6, 0.6)),
                      velocity_z=float(rng.uniform(-0.6, 0.6)), angular_velocity_x=float(rng.uniform(-1, 1)),
                      restitution=0.3, friction=0.4, selection=ContactSelection.ALL)
        a = first_instant(tree, scene, ImpactModel.FRICTION, SPATIAL)
        b = evaluate(tree, scene, ImpactModel.FRICTION, SPATIAL)
        scale = float(np.max(b.external))
        assert np.abs(b.tangential).max() > 1e-3 * scale  # friction acts in these cases
        np.testing.assert_allclose(a.internal, b.internal, rtol=0, atol=1e-9 * scale)
        np.testing.assert_allclose(a.internal_torque, b.internal_torque, rtol=0, atol=1e-9 * scale)
        np.testing.assert_allclose(a.v_plus, b.v_plus, rtol=0, atol=1e-9 * max(1.0, np.max(np.abs(b.v_minus))))


@pytest.mark.parametrize("model", [ImpactModel.LCP, ImpactModel.FRICTION])
def test_redundant_contacts_on_a_slope_split_as_on_flat_ground(model: ImpactModel):
    """A plank lying on the slope on three contacts (one rigid body: redundant rows): the lcp
    rung's smallest-norm split, and with friction the flat rung's split, turned."""
    from impulse_core.model.tree import Body

    for a in (-0.3, 0.2):
        tree = Tree((Body("plank", None, 0.8, 2.0, a, contacts=(0.0, 0.5, 1.0)),))
        scene = Scene(speed=2.0, velocity_x=0.4, angular_velocity=0.0, restitution=0.5, friction=0.3)
        on_slope = first_instant(tree, dataclasses.replace(scene, terrain=slope_terrain(a)), model)
        flat = evaluate(*turned_planar(tree, scene, a), model)
        assert not on_slope.split_unique and on_slope.active == (0, 1, 2)
        assert_same_impact(on_slope, flat, model)
