"""The whole landing in space (impulse_core.timedomain.landing with ``space=SPATIAL``).

- a planar leg read as spatial gives the planar landing (the plane is the spatial case
  restricted): the same events, final angles, base and totals, and nothing out of the plane;
- the first event equals the spatial first-impact answer (the circular-cone friction rung);
- seeded random legs with yaw-splayed toes, springs, dampers, stops, gravity and friction:
  linear momentum in x, y and z changes by the contact impulses minus the weight times T;
- at every event: Newton's restitution (e = 0: no contact approaching after), the circular
  friction cone, no energy gained;
- a plank landing obliquely and sliding (hand derivation): the sliding impact, friction against
  the slip in x and z, the stopping time and distance, the momentum balance in z.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from impulse_core.errors import ModelError
from impulse_core.evaluate import evaluate
from impulse_core.impact.laws import ImpactModel
from impulse_core.kinematics.spatial import SPATIAL
from impulse_core.model.joints import FREE, JointLaw
from impulse_core.model.rods import rotation_rpy
from impulse_core.model.tree import Body, ContactSelection, Scene, Tree
from impulse_core.timedomain.compliant import chart_rates
from impulse_core.timedomain.events.choice import _followed_slip
from impulse_core.timedomain.events.run import _Landing
from impulse_core.timedomain.events.settings import SLIP_SPLITS
from impulse_core.timedomain.events.stepping import balanced_length
from impulse_core.timedomain.landing import SETTLE_SPEED, LandingResult, LandingSettings, landing
from tests.conftest import report
from tests.impulse_core.test_compliant_spatial import rpy_of
from tests.impulse_core.test_landing import G, _random_leg

#: The fixed Runge-Kutta step of the comparisons (s).
STEP = 5e-4


def _rates(q: np.ndarray, velocity: np.ndarray) -> np.ndarray:
    """The chart rates q' of a reported (world) generalized velocity at q (the inverse of
    ``compliant.world_velocity``)."""
    v = velocity.copy()
    v[3:6] = np.linalg.solve(chart_rates(q[3:6]), velocity[3:6])
    return v


def _splayed_leg(seed: int, friction: float | None = None, restitution: float | None = None):
    """:func:`test_landing._random_leg` with its toes and heel turned about the vertical through the
    ankle by up to 0.5 rad (each keeps its planar height, so the touchdowns stay), an oblique
    approach (lateral velocity, a roll and yaw rate)."""
    tree, laws, scene = _random_leg(seed)
    rng = np.random.default_rng(1000 + seed)
    phi = tree.bodies[0].angle + tree.bodies[1].angle
    bodies = list(tree.bodies[:2])
    for b in tree.bodies[2:]:
        R = rotation_rpy((0.0, 0.0, -phi)) @ rotation_rpy((0.0, rng.uniform(-0.5, 0.5), 0.0)) @ rotation_rpy((0.0, 0.0, phi))
        bodies.append(replace(b, rpy=rpy_of(R), radius=0.005))
    scene = replace(scene, velocity_z=rng.uniform(-0.4, 0.4), angular_velocity_x=rng.uniform(-0.5, 0.5),
                    angular_velocity_y=rng.uniform(-0.5, 0.5))
    if friction is not None:
        scene = replace(scene, friction=friction)
    if restitution is not None:
        scene = replace(scene, restitution=restitution)
    return Tree(tuple(bodies)), laws, scene


# --------------------------------------------------------------------------------------------
# The plane is the spatial landing restricted


def _planar_view(tree: Tree, r: LandingResult) -> tuple[np.ndarray, np.ndarray]:
    """A spatial landing's final angles as the plane's (base absolute angle, joints) and its
    out-of-plane figures (phi_x, phi_y, base z)."""
    angles = np.concatenate([[tree.bodies[0].angle + r.final_angles[2]], r.final_angles[3:]])
    return angles, np.array([r.final_angles[0], r.final_angles[1], r.final_base[2]])


def _off_the_rods(tree: Tree, seed: int) -> Tree:
    """``tree`` with every centre of mass up to 3 cm off its rod in the plane (``com_offset`` [d, 0])."""
    rng = np.random.default_rng(500 + seed)
    return Tree(tuple(replace(b, com_offset=(rng.uniform(-0.03, 0.03), 0.0)) for b in tree.bodies))


@pytest.mark.parametrize("seed, offsets", [(0, False), (1, False), pytest.param(2, False, marks=pytest.mark.slow),
                                           pytest.param(3, False, marks=pytest.mark.slow), (5, False), (1, True),
                                           pytest.param(2, True, marks=pytest.mark.slow)])  # 5: a slow-slipping toe
def test_a_planar_leg_read_as_spatial_lands_as_in_the_plane(seed, offsets):
    """Random planar legs (springs, dampers, stops, gravity, friction 0, 0.4 or 1; ``offsets``: the
    centres of mass off the rods, which move the landing by more than 1e-3 rad) at one step:
    the same events; event times within 1e-8 s and impulses within 1e-6 of the peak (an event's
    time is located to a gap tolerance / approach speed, up to 1e-8 s on the slow re-contacts,
    which moves their impulses); final angles and base within 1e-10 relative, total impulses
    within 1e-9 (leg 1 off the rods: a toe's cascade of 27 bounces in 0.5 ms amplifies rounding;
    the spatial compiled step and projection, each equal to numpy's to 2e-16, land 3.9e-10 from
    the plane, the spatial numpy path 1.5e-11); nothing out of the plane (1e-12). Measured: 6e-9
    s, 4.3e-7, 2.1e-12, 1e-21."""
    tree, laws, scene = _random_leg(seed)
    if offsets:
        rods = _Landing(tree, scene, laws, LandingSettings()).run(STEP).final_angles
        tree = _off_the_rods(tree, seed)
    planar = _Landing(tree, scene, laws, LandingSettings()).run(STEP)
    spatial = _Landing(tree, scene, laws, LandingSettings(), SPATIAL).run(STEP)
    if offsets:
        assert np.max(np.abs(planar.final_angles - rods)) > 1e-3
    assert len(spatial.events) == len(planar.events) and len(planar.events) > 5
    peak = max(float(np.max(e.external)) for e in planar.events)
    for a, b in zip(planar.events, spatial.events):
        assert a.kind == b.kind and abs(a.time - b.time) <= 1e-8
        assert np.max(np.abs(a.external - b.external)) <= 1e-6 * peak
        assert np.max(np.abs(a.tangential - b.tangential[:, 0])) <= 1e-6 * peak
        assert np.max(np.abs(b.tangential[:, 1])) <= 1e-12 * peak
    angles, out_of_plane = _planar_view(tree, spatial)
    assert np.max(np.abs(angles - planar.final_angles)) <= 1e-10 * np.max(np.abs(planar.final_angles))
    assert np.max(np.abs(out_of_plane)) <= 1e-12
    assert np.max(np.abs(spatial.final_base[:2] - planar.final_base)) <= 1e-10 * np.max(np.abs(planar.final_base))
    for ours, theirs in ((spatial.total_external, planar.total_external), (spatial.total_tangential[:, 0], planar.total_tangential)):
        assert np.max(np.abs(ours - theirs)) <= 1e-9 * max(np.max(np.abs(theirs)), 1e-300)
    assert spatial.settled_at == pytest.approx(planar.settled_at, abs=1e-8) if planar.settled_at else spatial.settled_at is None
    report("landing-spatial", f"planar leg {seed} read as spatial: {len(planar.events)} events, final angles within "
           f"{np.max(np.abs(angles - planar.final_angles)):.1e} rad")


# --------------------------------------------------------------------------------------------
# The first event


@pytest.mark.parametrize("seed, friction", [(0, 0.0), (1, 0.4), (2, 1.0)])
def test_the_first_event_is_the_spatial_first_impact(seed, friction):
    """The event at t = 0 equals the first-impact friction rung in space (the circular cone) for
    the same file, springs and gravity notwithstanding (1e-9)."""
    tree, laws, scene = _splayed_leg(seed, friction)
    r = _Landing(tree, scene, laws, LandingSettings(), SPATIAL).run(STEP)
    first = evaluate(tree, scene, ImpactModel.FRICTION if friction else ImpactModel.LCP, space=SPATIAL)
    e = r.events[0]
    scale = float(np.max(first.external))
    assert e.time == 0.0
    assert np.max(np.abs(e.external - first.external)) <= 1e-9 * scale
    tangential = first.tangential if friction else np.zeros_like(e.tangential)
    assert np.max(np.abs(e.tangential - tangential)) <= 1e-9 * scale
    assert np.max(np.abs(e.internal_magnitude - first.internal_magnitude)) <= 1e-9 * np.max(first.internal_magnitude)
    assert np.max(np.abs(e.v_plus - first.v_plus)) <= 1e-9 * np.max(np.abs(first.v_plus))


def test_the_first_event_of_a_rod_with_redundant_rows_is_the_friction_rung():
    """A spatial rod on two contacts at once (no radius: its spin about its axis moves no contact,
    so its six normal and tangent rows have rank 5 and the split is not unique): where the cone
    law's first stage already meets the exact law (here no friction is needed), both the rung and
    the landing keep that split, and call it exact (random file f3233 differed by 2.5e-2, the
    landing reporting a 16-gon answer that met the law to 1e-15)."""
    rod = Body("rod", None, 0.6086513836842471, 0.12869524721135167, -0.3537749148197058,
               contacts=(0.0, 1.0), com=0.3238727742098868,
               rpy=(0.03398477982693249, 0.45787543109885787, -0.5539628068940361),
               axis=(1.6766851867116903, 0.13358925703774388, -1.9115174940354598))
    tree = Tree((rod,))
    scene = Scene(speed=2.660804556105821, restitution=1.0, friction=1.0, selection=ContactSelection.ALL,
                  gravity=G, duration=0.01)
    first = evaluate(tree, scene, ImpactModel.FRICTION, space=SPATIAL)
    r = _Landing(tree, scene, (FREE,), LandingSettings(), SPATIAL).run(STEP)
    e = r.events[0]
    assert not first.split_unique and first.notes == () and r.inexact == 0
    scale = float(np.max(first.external))
    assert np.max(np.abs(e.external - first.external)) <= 1e-9 * scale
    assert np.max(np.abs(e.tangential - first.tangential)) <= 1e-9 * scale
    # the spin about the rod's axis carries no mass (it is not unique): the energy after is
    assert e.energy_after == pytest.approx(first.energy_after, rel=1e-9)


# --------------------------------------------------------------------------------------------
# Momentum and the laws at every event


def _momentum_error(run: _Landing, r: LandingResult, scene: Scene) -> float:
    """|change of linear momentum - (contact impulses - weight T)| / |initial momentum| (x, y, z);
    checks that the run's own ``momentum_balance`` reports it (over max(|p0|, m g T))."""
    mass = sum(b.mass for b in run.tree.bodies)
    p0 = run.point(run.q0, r.events[0].v_minus).momentum[:, 0]
    p1 = run.point(r.q_final, _rates(r.q_final, r.v_final)).momentum[:, 0]
    tx, tz = r.total_tangential.sum(axis=0)
    impulse = np.array([tx, r.total_external.sum() - mass * G * scene.duration, tz])
    residual = float(np.max(np.abs(p1 - p0 - impulse)))
    reference = max(float(np.max(np.abs(p0))), mass * G * scene.duration)
    assert r.momentum_balance == pytest.approx(residual / reference, rel=1e-6, abs=1e-13)
    return residual / float(np.max(np.abs(p0)))


def _assert_event_laws(run: _Landing, r: LandingResult, scene: Scene) -> None:
    """Every event: impulses pushing, inside the circular cone, no energy gained; with e = 0
    every contact that took an impulse leaves at rest (Newton), none approaches."""
    times, states = r.trajectory
    for e in r.events:
        assert np.all(e.external >= -1e-12 * np.max(np.abs(e.external)))  # 0 to rounding: -5e-37 seen
        assert np.all(np.linalg.norm(e.tangential, axis=1) <= scene.friction * e.external * (1 + 1e-9) + 1e-12)
        assert e.energy_after <= e.energy_before * (1 + 1e-9) + 1e-12
        if scene.restitution == 0:
            q = states[np.flatnonzero(times == e.time)[-1]]
            pt = run.point(q, _rates(q, e.v_plus))
            vn = pt.vn(_rates(q, e.v_plus))
            speed = np.max(np.abs(e.v_minus))
            hit = e.external > 0
            assert np.all(np.abs(vn[hit]) <= 1e-6 * speed)
            assert np.all(vn[pt.gap <= 1e-9] >= -1e-6 * speed)
    assert all(b.time >= a.time for a, b in zip(r.events, r.events[1:]))


@pytest.mark.parametrize("seed, friction, restitution", [(0, 0.4, None), (1, 1.0, 0.0), (2, 0.4, 0.0), (3, 1.0, None)])
def test_splayed_legs_balance_momentum_and_obey_the_laws(seed, friction, restitution):
    """Random yaw-splayed legs with springs, dampers, stops, gravity and friction, oblique
    approach, RK4 at 5e-4 s: linear momentum in x, y, z changes by the contact impulses (normal and
    tangential, impulsive and continuous) minus the weight times T, to 1e-6 relative; the laws
    at every event (:func:`_assert_event_laws`)."""
    tree, laws, scene = _splayed_leg(seed, friction, restitution)
    run = _Landing(tree, scene, laws, LandingSettings(integrator="rk4"), SPATIAL)
    r = run.run(STEP)
    error = _momentum_error(run, r, scene)
    assert error <= 1e-6
    assert r.inexact == 0  # every impact and mode choice met the exact circular-cone law
    assert np.max(np.abs(r.total_tangential[:, 1])) > 1e-4 * np.max(np.abs(r.total_tangential))  # friction along z acts
    assert np.max(np.abs(r.final_angles[:2])) > 1e-6  # the base turned out of the plane
    _assert_event_laws(run, r, scene)
    report("landing-spatial", f"splayed leg {seed}: {len(r.events)} events, momentum balance {error:.1e}")


# --------------------------------------------------------------------------------------------
# A hand derivation out of the plane


def test_an_oblique_plank_slides_against_its_slip_and_stops_where_coulomb_says():
    """A plank landing flat, plastic, moving at (vx, -vy, vz): the sliding impact takes mu m vy of
    the tangential speed |v_t| against the slip, then friction mu m g decelerates it along the same
    line until it sticks at t* = (|v_t| - mu vy) / (mu g), having slid (|v_t| - mu vy)^2 / (2 mu g)
    along (vx, vz) / |v_t|; x and z momentum are all taken by the tangential impulses."""
    m, vx, vy, vz, mu, T = 3.0, 0.9, 0.5, -0.8, 0.4, 0.6
    plank = Tree((Body("plank", None, 0.6, m, 0.0, contacts=(0.0, 1.0), radius=0.02),))
    scene = Scene(speed=vy, velocity_x=vx, velocity_z=vz, restitution=0.0, friction=mu, gravity=G, duration=T)
    r = _Landing(plank, scene, (), LandingSettings(), SPATIAL).run(2e-3)
    speed = math.hypot(vx, vz)
    along = np.array([vx, vz]) / speed
    first = r.events[0]
    assert first.external.sum() == pytest.approx(m * vy, rel=1e-9)
    np.testing.assert_allclose(first.tangential.sum(axis=0), -mu * m * vy * along, rtol=1e-9)
    v1 = speed - mu * vy
    t_stop = v1 / (mu * G)
    np.testing.assert_allclose(r.final_base[[0, 2]], v1**2 / (2 * mu * G) * along, rtol=1e-6)
    fastest = max(abs(along[0]), abs(along[1]))
    assert r.settled_at == pytest.approx(t_stop - SETTLE_SPEED / (fastest * mu * G), abs=1e-6)
    np.testing.assert_allclose(r.total_tangential.sum(axis=0), -m * np.array([vx, vz]), rtol=1e-9)
    assert r.total_external.sum() == pytest.approx(m * vy + m * G * T, rel=1e-9)
    np.testing.assert_allclose(r.final_angles, 0.0, atol=1e-9)


# --------------------------------------------------------------------------------------------
# Uneven ground: the sequential rung's touchdowns


def test_on_a_heightfield_the_touchdowns_are_the_sequential_rungs():
    """configs/spatial_heightfield.yaml (frictionless, e = 0.8, gravity) until just after its last
    first touchdown: the toes touch one after another and then the heel, each impact at the
    sequential rigid rung's time and with its impulse (both integrate the flight between; 1e-9).
    The first event is over the contacts that touch the heightfield, not the tree's lowest."""
    from impulse_core.timedomain.landing import landing
    from impulse_core.timedomain.sequential import SequentialSettings, sequential_impacts
    from optimizer.config.model_file import load_model_file

    m = load_model_file("configs/spatial_heightfield.yaml")
    scene = replace(m.scene, gravity=G, duration=0.0036)
    r = landing(m.tree, scene, (), LandingSettings(tolerance=1e-8), space=SPATIAL)
    rigid = sequential_impacts(m.tree, scene, SequentialSettings(gravity=G), space=SPATIAL)
    assert len(r.events) == len(m.tree.contacts) == len(rigid.touchdown_order)
    for e in r.events:
        (c,) = np.flatnonzero(e.external)
        assert e.time == pytest.approx(rigid.touchdown_time[c], abs=1e-9)
        assert e.external[c] == pytest.approx(rigid.external[c], rel=1e-9)
    assert r.touchdown_order == rigid.touchdown_order


# --------------------------------------------------------------------------------------------
# A posture out of the plane: static equilibrium


def _tripod_and_pole() -> tuple[Tree, tuple, Scene]:
    """A plank along x with a welded cross rod along +z (three contacts: a triangle), and a pole
    at the plank's middle standing up (rpy turns its x axis to +y) on a sprung, damped joint
    about the world x axis (its axis y after rpy): the pole leans sideways, towards -z."""
    from impulse_core.model.joints import FREE, JointLaw
    from impulse_core.model.tree import JointKind

    tree = Tree((
        Body("plank", None, 0.6, 2.0, 0.0, contacts=(0.0, 1.0), radius=0.01),
        Body("cross", 0, 0.3, 0.5, 0.0, at=0.5, joint=JointKind.FIXED, rpy=(0.0, -math.pi / 2, 0.0), contacts=(1.0,),
             radius=0.01),
        Body("pole", 0, 0.5, 0.5, 0.2, at=0.5, rpy=(0.0, 0.0, math.pi / 2), axis=(0.0, 1.0, 0.0), radius=0.01),
    ))
    laws = (FREE, FREE, JointLaw(stiffness=5.0, damping=0.5, rest=0.3))
    return tree, laws, Scene(speed=0.5, restitution=0.0, gravity=G, duration=2.0)


def test_a_sideways_sprung_pole_settles_where_spring_and_gravity_balance():
    """Frictionless, plastic: the tripod settles flat (no turn) and the pole, leaning in the
    y-z plane (height (L / 2) cos theta), where k (theta - rest) = m g (L / 2) sin theta; the base
    slides sideways (no friction: the centre of mass keeps its z), and the ground carries the
    weight over T plus the touchdown momentum."""
    from scipy.optimize import brentq

    from impulse_core.timedomain.landing import landing

    tree, laws, scene = _tripod_and_pole()
    r = landing(tree, scene, laws, LandingSettings(tolerance=1e-5), space=SPATIAL)
    k, rest, m, half = 5.0, 0.3, 0.5, 0.25
    theta = brentq(lambda th: k * (th - rest) - m * G * half * math.sin(th), 0.0, 1.5)
    assert r.converged and r.settled_at is not None and r.settled_at < scene.duration
    np.testing.assert_allclose(r.final_angles[:3], 0.0, atol=1e-9)
    assert r.final_angles[-1] == pytest.approx(theta, abs=1e-6)
    assert r.final_base[1] == pytest.approx(0.0, abs=1e-9) and r.final_base[2] > 1e-3
    total = sum(b.mass for b in tree.bodies)
    assert r.total_external.sum() == pytest.approx(total * (G * scene.duration + scene.speed), rel=1e-6)
    report("landing-spatial", f"sideways pole settles at {r.final_angles[-1]:.9f} rad, static {theta:.9f}")


TRIPOD_MJCF = """
<mujoco>
  <compiler angle="radian"/>
  <option timestep="2e-4" gravity="0 -9.81 0" integrator="implicitfast"/>
  <worldbody>
    <geom type="plane" size="5 5 0.1" pos="0 -0.002 0" quat="0.70710678 -0.70710678 0 0" condim="1"/>
    <body name="plank" pos="0 0 0">
      <freejoint name="base"/>
      <inertial pos="0.3 0 0" mass="2" diaginertia="1e-4 0.06005 0.06005"/>
      <geom type="sphere" size="0.002" pos="0 0 0" condim="1" solref="0.002 1"/>
      <geom type="sphere" size="0.002" pos="0.6 0 0" condim="1" solref="0.002 1"/>
      <body name="cross" pos="0.3 0 0">
        <inertial pos="0 0 0.15" mass="0.5" diaginertia="0.0037625 0.0037625 2.5e-5"/>
        <geom type="sphere" size="0.002" pos="0 0 0.3" condim="1" solref="0.002 1"/>
      </body>
      <body name="pole" pos="0.3 0 0">
        <joint name="pole" type="hinge" axis="-1 0 0" stiffness="5" springref="0.3" damping="0.5"/>
        <inertial pos="0 0.25 0" mass="0.5" diaginertia="0.0104291667 2.5e-5 0.0104291667"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def test_the_settled_sideways_pole_matches_mujoco():
    """MuJoCo (a freejoint base, soft frictionless contacts, its own joint spring and damper; the
    same rods' inertias) settles the tripod's sideways pole within 2e-3 rad of the landing model
    (measured 6e-5), the base within 1e-3 rad of flat and its sideways slide within 1e-4 m."""
    mujoco = pytest.importorskip("mujoco")
    from impulse_core.timedomain.landing import landing

    tree, laws, scene = _tripod_and_pole()
    ours = landing(tree, scene, laws, LandingSettings(), space=SPATIAL)
    m = mujoco.MjModel.from_xml_string(TRIPOD_MJCF)
    d = mujoco.MjData(m)
    d.qpos[m.joint("pole").qposadr[0]] = tree.bodies[2].angle
    d.qvel[1] = -scene.speed
    for _ in range(int(scene.duration / m.opt.timestep)):
        mujoco.mj_step(m, d)
    assert abs(d.qpos[m.joint("pole").qposadr[0]] - ours.final_angles[-1]) < 2e-3
    assert 2 * math.acos(min(1.0, abs(d.qpos[3]))) < 1e-3 and np.max(np.abs(ours.final_angles[:3])) < 1e-9
    assert abs(d.qpos[2] - ours.final_base[2]) < 1e-4


# --------------------------------------------------------------------------------------------
# A base that turns many times: the rotation coordinates re-centred


def _spinning_pair() -> tuple[Tree, tuple, Scene]:
    """A sprung two-rod body thrown down spinning at 25 rad/s about z: it bounces off, turns
    about 20 rad in the air and lands again."""
    bodies = (Body("a", None, 0.3, 1.0, -0.3, contacts=(0.0, 1.0)), Body("b", 0, 0.2, 0.3, 1.0, contacts=(1.0,)))
    laws = (FREE, JointLaw(stiffness=5.0, damping=0.05))
    scene = Scene(speed=0.5, velocity_x=0.3, angular_velocity=25.0, restitution=0.9, friction=0.3, gravity=G,
                  duration=0.9)
    return Tree(bodies), laws, scene


def test_a_base_turning_many_times_lands_as_in_the_plane():
    """Beyond RECHART rad the base's rotation coordinates are re-centred on its orientation (the
    chart is singular at 2 pi: the run stopped at 5 rad before). A planar body read as spatial
    that turns about 20 rad: the same events (times 1e-12 s), final angles (the rotation vector
    continued, not wrapped: phi_z = the planar base's turn) and base within 1e-10, the momentum
    balance met. Measured: 3e-15 s, 3e-13 rad."""
    tree, laws, scene = _spinning_pair()
    planar = _Landing(tree, scene, laws, LandingSettings()).run(2e-3)
    run = _Landing(tree, scene, laws, LandingSettings(), SPATIAL)
    spatial = run.run(2e-3)
    assert len(planar.events) == len(spatial.events) >= 2
    assert max(abs(a.time - b.time) for a, b in zip(planar.events, spatial.events)) <= 1e-12
    angles, out_of_plane = _planar_view(tree, spatial)
    assert abs(angles[0] - tree.bodies[0].angle) > 3 * math.pi  # beyond the chart: re-centred
    assert np.max(np.abs(angles - planar.final_angles)) <= 1e-10 * np.max(np.abs(planar.final_angles))
    assert np.max(np.abs(out_of_plane)) <= 1e-12
    assert np.max(np.abs(spatial.final_base[:2] - planar.final_base)) <= 1e-10 * np.max(np.abs(planar.final_base))
    assert spatial.momentum_balance <= 1e-6
    times, states = spatial.trajectory
    assert np.max(np.abs(np.diff(states[:, 5]))) < 1.0  # the reported turn is continuous
    report("landing-spatial", f"a base turning {angles[0] - tree.bodies[0].angle:.1f} rad: final angles within "
           f"{np.max(np.abs(angles - planar.final_angles)):.1e} rad of the plane's")


def test_re_centring_the_rotation_coordinates_moves_nothing(monkeypatch):
    """A tumbling spatial landing (an oblique splayed leg given a fast roll) with the coordinates
    re-centred often (beyond 0.3 rad) against rarely (the default). The re-centring is a change
    of coordinates, exact at its instant; RK4's truncation error (O(h^4)) depends on the
    coordinates it steps, so the runs differ by that: the same events, and final angles, base,
    totals and velocities closer than the default run is to itself at half the step (measured
    1.4e-6 against 5.4e-6 at 2 ms; 7e-8 at 1 ms, the O(h^4) ratio; a re-centring that left the
    rates phi' for the angular velocity S(phi) phi' moves them by 1e-1)."""
    from impulse_core.timedomain.events import run as module  # the run loop re-centres

    tree, laws, scene = _splayed_leg(1, friction=0.4, restitution=0.7)
    scene = replace(scene, angular_velocity_x=15.0, duration=0.12)
    rare, finer = (_Landing(tree, scene, laws, LandingSettings(), SPATIAL).run(h) for h in (4 * STEP, 2 * STEP))
    monkeypatch.setattr(module, "RECHART", 0.3)
    often = _Landing(tree, scene, laws, LandingSettings(), SPATIAL).run(4 * STEP)
    assert len(rare.events) == len(often.events) == len(finer.events)
    assert np.linalg.norm(rare.final_angles[:3]) > 0.6  # re-centred at least twice
    for name in ("final_angles", "final_base", "total_external", "v_final"):
        a, b, c = (getattr(r, name) for r in (rare, often, finer))
        assert np.max(np.abs(a - b)) <= np.max(np.abs(a - c)), name


def _light_damped_tip() -> tuple[Tree, tuple[JointLaw, ...], Scene]:
    """A random spatial model that took minutes (studies/whole_landing/spatial_chatter.md, f400,
    rounded): an 11 cm base and a 3 cm, 22 g rod on a damper whose rate is 2e5 1/s, bouncing off
    (e = 1) into flight; the implicit integrator at h x rate = 50."""
    bodies = (Body("b0", None, 0.11, 0.107, -2.06, radius=0.0015),
              Body("b1", 0, 0.033, 0.022, -2.42, at=0.33, com=0.12, contacts=(0.0,), rpy=(0.53, -0.31, -0.43)))
    laws = (FREE, JointLaw(stiffness=1.93, damping=0.224, limits=(-2.555, -2.397), stop_restitution=0.78))
    scene = Scene(speed=3.67, velocity_x=0.64, velocity_z=0.46, restitution=1.0, friction=0.3, gravity=G,
                  duration=2e-3)
    return Tree(bodies), laws, scene


def test_the_momentum_balanced_step_grows_by_its_residual():
    """Where the balance sets the step (ROS2 at h x rate >> 1, after a split), the next trial
    doubles only where the residual's ratio, grown as dt^2, stays within the share: measured 227
    accepted steps for 239 step calls (doubling after every split: 212 for 425, each accepted
    step cost a rejected trial; as if it grew as dt^3, too cautious: 286 for 298), and the balance
    holds. Runs at h and h / 2 whose steps the balance set stay one run (lengths h / 2^k), which
    :func:`landing` tells by their equal step counts."""
    tree, laws, scene = _light_damped_tip()
    run = _Landing(tree, scene, laws, LandingSettings(step=2.5e-4, integrator="implicit"), SPATIAL)
    calls = {"step": 0, "balanced_step": 0}
    for name in calls:
        method = getattr(run, name)

        def counted(*args, _method=method, _name=name):
            calls[_name] += 1
            return _method(*args)

        setattr(run, name, counted)
    r = run.run(2.5e-4)
    assert len(r.events) == 1 and r.momentum_balance < 2e-5
    report("landing balanced steps", f"light damped tip: {calls['balanced_step']} accepted steps, "
                                     f"{calls['step']} step calls")
    assert calls["balanced_step"] > 100  # the balance sets the step
    assert calls["step"] < 1.1 * calls["balanced_step"] and calls["step"] < 270
    half = run.run(1.25e-4)
    assert half.n_steps == r.n_steps and np.array_equal(half.final_angles, r.final_angles)


def test_the_balanced_length_doubles_where_the_order_allows():
    """2 dt once the ratio times 2^p is within 1 (p = 2: ROS2, 4: RK4), else dt."""
    assert balanced_length(1e-3, 0.25, 2) == 2e-3 and balanced_length(1e-3, 0.26, 2) == 1e-3
    assert balanced_length(1e-3, 1 / 16, 4) == 2e-3 and balanced_length(1e-3, 0.07, 4) == 1e-3
    assert balanced_length(1e-3, 0.0, 2) == 2e-3


def test_a_momentum_residual_at_roundings_level_does_not_hold_the_steps():
    """Random file 32787 (data/rounding_balance_32787.yaml: springs of 295 and 90 N m/rad on
    43 g and 55 g rods) in its run at h / 64 with the balance's share 2^-12 (:func:`landing`
    after three runs split alike), just after the 0.51 m rod's tip stuck
    (data/rounding_balance_32787_state.json). Each step's residual there is rounding's, 6e-16 to
    1e-14 N s of the tree's 12.5 N s at every length, while its share at h / 2^13 is 9e-16 N s:
    the steps stayed at h / 2^14 (the floor) or twice it, 1e8 to 2e8 of them for the rest (no end
    in 240 s). Now a residual within BALANCE_ROUNDING x eps of its terms closes the step and the
    next may double: the steps grow back, and each residual stays within its share or rounding."""
    run, _, kept, mode = _kept_state("rounding_balance_32787")
    q, v, trial, rate, floor = kept["q"], kept["v"], kept["trial"], kept["rate"], kept["floor"]
    lengths, over = [], []
    for _ in range(30):
        p0 = run.point(q, v).momentum[:, 0].copy()
        q1, v1, impulse, dt, grown = run.balanced_step(q, v, mode, trial, rate, floor)
        end = run.ended(q1, v1, mode)
        balance = end.balance if end is not None else run.momentum_change(p0, q1, v1, impulse)
        residual = float(np.max(np.abs(balance - run.weight(dt))))
        over.append(residual / max(rate * dt, run.balance_rounding(q, v, q1, v1, end, p0, balance, run.weight(dt))))
        q, v = q1, v1
        lengths.append(dt)
        trial = min(kept["h"], grown)
    report("landing balance rounding", f"32787 stuck tip: 30 steps from {lengths[0]:.3g} s to {lengths[-1]:.3g} s, "
                                       f"{sum(lengths):.3g} s in all; largest residual / bound {max(over):.3g}")
    assert max(over) <= 1.0
    assert lengths[-1] >= 2**8 * floor and sum(lengths) > 1e3 * 30 * floor


def _data_model(name: str):
    """A random file kept in tests/impulse_core/data, read as footopt reads it."""
    from optimizer.config.model_file import load_model_file

    return load_model_file(Path(__file__).parent / "data" / name)


def test_bounces_of_a_driven_contact_shrink_by_restitution_to_rest():
    """Random file 12372 (data/bounce_plateau_12372.yaml: a light rod on a stiff spring, e =
    0.8) drives its contact into the ground at about 1.8e4 m/s^2 between bounces. Each bounce is
    located within 2 LOCATE_DEPTH gap tolerances of zero, where the last one left from, so the
    bounces shrink by about e and end plastic. Located 0.1..0.2 tolerances deep (the old
    window), the drive's work over that depth held them at ~1e-4 m/s: 20000 impacts by 0.5 ms."""
    model = _data_model("bounce_plateau_12372.yaml")
    r = _Landing(model.tree, model.scene, model.joints, LandingSettings(max_events=300), model.space).run(5e-5)
    impulses = np.array([e.external[1] for e in r.events])
    assert len(r.events) < 60 and np.all(impulses > 0)
    ratios = impulses[10:-1] / impulses[9:-2]  # the bounces after the spin's first ones, but the plastic last
    assert np.all((ratios > 0.7) & (ratios < 0.9)), ratios
    assert abs(r.momentum_balance) < 1e-6


def test_a_divergence_through_a_singular_mass_matrix_says_so():
    """Random file 20069 (data/zero_radius_20069.yaml): two rods of zero radius; after the impact
    they pass, in flight, a posture where the mass matrix's condition number passes 1e10 and
    spin up without bound (the kinetic energy stays 1.09 J until the step fails), at any step.
    The error says why; with 5 mm rods the same landing runs."""
    from impulse_core.timedomain.landing import Diverged

    model = _data_model("zero_radius_20069.yaml")
    with pytest.raises(Diverged, match=r"diverged at t = 0\.002853 s .*mass matrix is near singular there"):
        _Landing(model.tree, model.scene, model.joints, LandingSettings(), model.space).run(2e-3)
    thick = replace(model.tree, bodies=tuple(replace(b, radius=0.005) for b in model.tree.bodies))
    r = _Landing(thick, model.scene, model.joints, LandingSettings(), model.space).run(2e-3)
    assert r.momentum_balance < 1e-4


def test_zero_radius_rods_out_of_line_are_named_where_they_spin_about_their_own_axes():
    """Random file 32365 (data/zero_radius_plane_32365.yaml: two rods of zero radius on a hinge)
    diverges in flight as its hinge nears 0.2061 rad, where the child's axis lies in the plane of
    the base's axis and the hinge axis (the rods 11 degrees apart, not in line): both rods can
    spin about their own axes there, the hinge taking the difference, moving no mass. The note
    names that posture, not only rods in line."""
    model = _data_model("zero_radius_plane_32365.yaml")
    run = _Landing(model.tree, model.scene, model.joints, LandingSettings(), model.space)
    q = run.q0.copy()
    q[6] = 0.2061  # the hinge where the child's axis crosses that plane (run.q0: 0.693 rad)
    assert run.singular_note(run.q0) == ""
    note = run.singular_note(q)
    assert "near singular" in note and "plane of its parent's and its hinge's" in note


def _kept_state(name: str, state: str | None = None):
    """data/NAME.yaml's landing at the state kept in data/NAME_state.json (or STATE_state.json),
    in the run's chart (its first impact taken): (run, the first impact's totals, the kept values
    with q and v as arrays, the kept mode)."""
    import json

    from impulse_core.timedomain.events.rows import _Mode

    model = _data_model(f"{name}.yaml")
    kept = json.loads((Path(__file__).parent / "data" / f"{state or name}_state.json").read_text())
    run = _Landing(model.tree, model.scene, model.joints, LandingSettings(), model.space)
    totals = run.first_impact()[3]  # and the run's chart
    kept["q"], kept["v"] = np.array(kept["q"]), np.array(kept["v"])
    mode = _Mode(np.array(kept["closed"]), np.array(kept["slip"]), np.array(kept["stop"]), kept["redundant"],
                 np.array(kept["core"]))
    return run, totals, kept, mode


def test_resting_contacts_of_one_rigid_body_stick_where_they_can():
    """Random file 20606 (data/redundant_stick_20606.yaml: five contacts with friction 1 on a
    base and its welded rod, one on a hinged rod) at 0.1822 s (the kept state and mode,
    data/redundant_stick_20606_state.json): the base is at rest and its four contacts are
    redundant. The acceleration-level contact problem then has both answers, and Lemke's pivots
    gave the sliding one; its least-norm forces in the mode's own solve disagreed with it and
    the run switched slip directions at every event (4000 events at 6e-11 s each, no end in
    240 s). The four contacts now stick (their forces inside the cone, no slip acceleration),
    and the landing ends (10 events; tests/impulse_core/test_landing.py's laws hold on it)."""
    from impulse_core.timedomain.events.forces import _contact_forces

    run, _, kept, mode = _kept_state("redundant_stick_20606")
    q, v = kept["q"], kept["v"]
    new = run.resolve(q, v, mode)
    base_contacts = [0, 1, 3, 4]
    assert new.closed.all() and not new.sliding[base_contacts].any() and new.sliding[2]
    pt = run.point(q, v)
    rows, (a, lam) = run.mode_solution(pt, new)
    fn, ft = _contact_forces(rows, lam, run.mu, run.nc)
    assert np.all(fn > 0.1) and np.all(run.mu * fn[base_contacts] - np.linalg.norm(ft[base_contacts], axis=1) > 0.1 * fn[base_contacts])
    assert np.max(np.abs((pt.Jt @ a + pt.bt)[base_contacts])) < 1e-12


def test_a_slow_slip_turned_past_a_right_angle_comes_to_rest():
    """Random file 20693 (data/turned_slip_20693.yaml: friction 0.3) at 0.1710 s (the kept state
    and mode, data/turned_slip_20693_state.json): two contacts slide at 2e-5 and 4e-5 m/s under
    a lateral drive, their slips turned to a right angle from the directions they slid along.
    They used to slide on along the new slip and turn again 1e-5 s later (an event each time;
    the 0.2 s landing ran for minutes). Below PLASTIC_SPEED such a slip now comes to rest at the
    event, as a plastic impact does: after the event their slip is zero, the new mode holds at
    its start (no witness negative), and the momentum changes by the counted impulses."""
    run, totals, kept, mode = _kept_state("turned_slip_20693")
    q, v = kept["q"], kept["v"]
    before, p0 = totals.impulse.copy(), run.point(q, v).momentum[:, 0]
    q1, v1, new = run.event(q, v, mode, 0.171, totals)
    turned = kept["turned"]
    assert np.max(np.linalg.norm(run.point(q1, v1).slip[turned], axis=1)) < 1e-12
    w, _ = run.witness_and_rate(q1, v1, new)
    assert np.all(w >= 0), np.flatnonzero(w < 0)
    change = run.point(q1, v1).momentum[:, 0] - p0
    assert np.max(np.abs(change - (totals.impulse - before))) < 1e-12 * max(1.0, np.max(np.abs(p0)))


def test_an_arrest_takes_no_squeeze_of_a_nearly_redundant_pair():
    """Random file 31088 (data/squeeze_31088.yaml: a heightfield, friction 1, six rods) at
    0.2647 s (the kept state and mode, data/squeeze_31088_state.json): contact 0 (b2[0]) sticks
    and contact 5 (b4[1]), 9.4 cm away on a rod hinged to it through another, slides at 9e-5 m/s,
    its slip turned past a right angle. With both sticking the pair's rows are nearly redundant
    (the mode needs 5e5 N of friction against 25 N and 9 N of normal force), and the arrest's
    projection took the pair's squeeze: 595 N s tangential at contact 0 against 1.8 N s normal,
    and later ones pulled; the momentum balance cannot see it (it sums to zero), the totals
    carried it. Now the arrest's impulse at every contact lies in the friction cone of its
    normal impulse, which does not pull, and the momentum changes by the counted impulses."""
    run, totals, kept, mode = _kept_state("squeeze_31088")
    q, v = kept["q"], kept["v"]
    normal, tangential, impulse = totals.normal.copy(), totals.tangential.copy(), totals.impulse.copy()
    p0 = run.point(q, v).momentum[:, 0]
    q1, v1 = run.arrest(q, v, mode, totals)
    fn, ft = totals.normal - normal, np.linalg.norm(totals.tangential - tangential, axis=1)
    assert np.all(fn >= -1e-12) and np.all(ft <= run.mu * fn + 1e-12), (fn, ft)
    change = run.point(q1, v1).momentum[:, 0] - p0
    assert np.max(np.abs(change - (totals.impulse - impulse))) < 1e-12 * max(1.0, np.max(np.abs(p0)))


def test_an_arrest_of_a_redundant_pair_takes_the_modes_own_split():
    """Random file 31088 later in the same run (data/squeeze_31088_redundant_state.json): contact
    5 turned at 2.5e-6 m/s beside contact 0 sticking, and with both sticking the rows are
    redundant (REDUNDANT): the mode's forces are their least-norm pushing split, which holds, so
    the arrest is taken. Its projection solved the rows to rounding and took the pair's squeeze:
    1.95e4 N s tangential at each contact, 84 and 2,103 N s normal. It now takes the mode's own split
    (least-norm on the redundant rows, pushing): every contact's impulse below the plastic speed
    times the tree's mass, none pulling, and the momentum changes by the counted impulses."""
    from impulse_core.timedomain.landing import PLASTIC_SPEED

    run, totals, kept, mode = _kept_state("squeeze_31088", "squeeze_31088_redundant")
    q, v = kept["q"], kept["v"]
    normal, tangential, impulse = totals.normal.copy(), totals.tangential.copy(), totals.impulse.copy()
    p0 = run.point(q, v).momentum[:, 0]
    q1, v1 = run.arrest(q, v, mode, totals)
    assert not np.array_equal(v1, v)  # taken
    fn, ft = totals.normal - normal, np.linalg.norm(totals.tangential - tangential, axis=1)
    assert np.all(fn >= -1e-12) and np.all(np.hypot(fn, ft) < PLASTIC_SPEED * run.mass), (fn, ft)
    change = run.point(q1, v1).momentum[:, 0] - p0
    assert np.max(np.abs(change - (totals.impulse - impulse))) < 1e-12 * max(1.0, np.max(np.abs(p0)))


def _stale_arrest(run, totals, kept, mode):
    """The arrest at ``kept``'s state: (slips before, slips after, normal and tangential impulses
    per contact, whether it was taken)."""
    q, v = kept["q"], kept["v"]
    normal, tangential = totals.normal.copy(), totals.tangential.copy()
    q1, v1 = run.arrest(q, v, mode, totals)
    fn, ft = totals.normal - normal, np.linalg.norm(totals.tangential - tangential, axis=1)
    return run.point(q, v).slip, run.point(q1, v1).slip, fn, ft, v1 is not v


@pytest.mark.parametrize("held", [False, True])
def test_an_arrest_leaves_a_fast_slip_that_the_impacts_mode_calls_sticking_sliding(monkeypatch, held):
    """Random file 31088 (data/squeeze_31088_stale_state.json, from the run before the squeeze
    fix): the mode an impact leaves keeps the slip flags of the mode before it, and there it calls
    contacts 1 and 2 sticking while they slip at 1.2e-2 m/s; contact 0's slip has turned at
    2.2e-9 m/s. The arrest's probe mode slides those two along their slips (only slips slower
    than PLASTIC_SPEED are arrested): it holds, the arrest is taken, the two keep their slips,
    every impulse is below PLASTIC_SPEED times the tree's mass and none pulls by more than a
    thousandth of that (contact 0: -1.7e-9 N s, the normal-tangent coupling of zeroing its slip,
    :meth:`_Landing.arrest`). With them sticking the mode did not hold and the arrest was refused;
    where it held (``held``: the gate patched open, as before the squeeze fix) the projection
    took their slips to zero, 0.012 N s at each."""
    from impulse_core.timedomain.landing import PLASTIC_SPEED

    run, totals, kept, mode = _kept_state("squeeze_31088", "squeeze_31088_stale")
    if held:
        monkeypatch.setattr(_Landing, "held_by_its_forces", lambda self, q, v, mode: True)
    fast = kept["fast"]
    slip, slip1, fn, ft, taken = _stale_arrest(run, totals, kept, mode)
    assert taken
    assert np.all(np.linalg.norm(slip[fast], axis=1) > 100 * PLASTIC_SPEED)
    kept_slip = np.linalg.norm(slip1[fast] - slip[fast], axis=1) / np.linalg.norm(slip[fast], axis=1)
    assert np.all(kept_slip < 1e-3), kept_slip
    assert np.linalg.norm(slip1[kept["turned"]]) < 1e-12
    scale = PLASTIC_SPEED * run.mass  # the arrested slip's impulse scale
    assert np.all(fn >= -1e-3 * scale) and np.all(np.hypot(fn, ft) < scale), (fn, ft)


def test_a_slow_slip_square_to_its_acceleration_stops_and_slides_again_from_rest():
    """Random file 32113 (data/turning_slip_32113.yaml: friction 0.5, a 25 g rod's tip the only
    closed contact) at its first refused arrest (data/turning_slip_32113_state.json): the tip
    slides at 1e-7 m/s and no mode with it sticking holds. Left sliding, its acceleration was
    square to its slip whichever way it was flagged: the slip turned by a right angle at each
    event, 1e-8 s apart, until the stall error (exit 1). Its rows are well conditioned and
    stopping it takes a slight impulse, so the arrest takes it (:meth:`_Landing.slight_arrest`):
    the slip is zero, every impulse below PLASTIC_SPEED times the tree's mass and no pull beyond
    a thousandth of that, the momentum changes by the counted impulses, and the mode after slides
    the tip from rest along a slip its acceleration follows. The landing now ends (estimate 8e-4)."""
    from impulse_core.timedomain.landing import PLASTIC_SPEED

    run, totals, kept, mode = _kept_state("turning_slip_32113")
    q, v = kept["q"], kept["v"]
    normal, tangential, impulse = totals.normal.copy(), totals.tangential.copy(), totals.impulse.copy()
    p0 = run.point(q, v).momentum[:, 0]
    assert 0 < np.linalg.norm(run.point(q, v).slip[kept["turned"]]) < PLASTIC_SPEED
    q1, v1 = run.arrest(q, v, mode, totals)
    assert v1 is not v and not run.refused.size
    assert np.linalg.norm(run.point(q1, v1).slip[kept["turned"]]) < 1e-12
    fn, ft = totals.normal - normal, np.linalg.norm(totals.tangential - tangential, axis=1)
    scale = PLASTIC_SPEED * run.mass
    assert np.all(fn >= -1e-3 * scale) and np.all(np.hypot(fn, ft) < scale), (fn, ft)
    change = run.point(q1, v1).momentum[:, 0] - p0
    assert np.max(np.abs(change - (totals.impulse - impulse))) < 1e-12 * max(1.0, np.max(np.abs(p0)))
    q2, v2, after = run.modes_after(q1, v1, mode, 0.2142, totals, v)
    assert after.closed[kept["turned"]].all() and after.sliding[kept["turned"]].all()
    assert not run.wrong_slip(run.point(q2, v2), v2, after, 0.0)[0].any()


def test_a_slow_slip_that_friction_cannot_stop_turning_at_each_event_is_a_stall(monkeypatch):
    """Random file 30891 (data/refused_30891.yaml: friction 1, three rods on flat ground): at
    0.0643 s contact 0 (b2[0]) slides at 2e-6 m/s and its slip turns past a right angle every
    1e-7 s. Arresting it needs the mode with it sticking, which would take 9.4e4 N of friction at
    it and at contact 2 (a nearly redundant pair; the arrest's projection was a squeeze of 67 N
    s): it is not arrested, slides on, and each event gives the mode back, 7e5 such events to
    the landing's end (no end in 400 s). More than REPEATS of them in a row are a stall whatever
    their length: the run crosses it by a Moreau-Jean bridge (``_Landing.bridge``) and goes on;
    with no bridge left (MAX_BRIDGES) the error names the contact (within 20000 steps and events).
    The run at its first step h meets the stall at 0.0646 s with the slow slip's steps split (the
    default; 0.0643 s regularised, and at h / 2, h / 4 either way)."""
    import impulse_core.timedomain.events.paradox as paradox_module  # where the bridges are counted
    from impulse_core.errors import NumericalError

    model = _data_model("refused_30891.yaml")
    calls = [0]

    def until(*_):
        calls[0] += 1
        return calls[0] > 20000

    run = _Landing(model.tree, model.scene, model.joints, LandingSettings(), model.space)
    r = run.run(run.first_step(), until=lambda *a: until() or run.bridges)
    assert run.bridges and 0.0646 < run.bridges[0][0] < 0.0647 and r.duration > run.bridges[0][0]
    calls[0] = 0
    monkeypatch.setattr(paradox_module, "MAX_BRIDGES", 0)
    run = _Landing(model.tree, model.scene, model.joints, LandingSettings(), model.space)
    message = r"chatters at t = 0\.0646.* slow slip of contacts b2\[0\] turns at each event"
    with pytest.raises(NumericalError, match=message):
        run.run(run.first_step(), until=until)


def test_a_starting_slip_that_cycles_is_searched_until_its_acceleration_follows_it(monkeypatch):
    """Random file 30249 (data/random_30249.yaml: friction 0.5): at 0.2126 s a contact on its
    cone's edge starts sliding; turning its slip to its acceleration cycled ((0.20, -0.98), then
    (-0.93, -0.36), whose acceleration points 122 degrees away) and the run took an event every
    5e-11 s without end. Now every mode choice of the landing leaves each contact that starts
    sliding accelerating along its slip (``wrong_slip`` empty), the search being needed at least
    once, and the landing ends with its momentum balanced (1e-4). The arrest sticks the turned
    slips as it did when this was found (``held_arrest`` patched): now a slip that turns at the
    cone's edge, as this contact's does at 0.2126 s, is not arrested (the mode with it sticking
    does not hold), slides on and needs no search."""
    model = _data_model("random_30249.yaml")
    searched, original = [0], _Landing.consistent_slip

    def sticking(self, q, v, mode, turned):
        stuck = mode.copy()
        stuck.slip[turned] = 0.0
        stuck.redundant = self.redundant(self.point(q, v), stuck)
        return stuck

    def checked(self, pt, v, mode, acc_tol):
        out = original(self, pt, v, mode, acc_tol)
        assert not self.wrong_slip(pt, v, out, acc_tol)[0].any()
        return out

    def counted(self, *args):
        searched[0] += 1
        return search(self, *args)

    search = _Landing.searched_slip
    monkeypatch.setattr(_Landing, "consistent_slip", checked)
    monkeypatch.setattr(_Landing, "searched_slip", counted)
    monkeypatch.setattr(_Landing, "held_arrest", sticking)
    r = landing(model.tree, model.scene, model.joints, LandingSettings(), model.space)
    assert searched[0] >= 1 and r.momentum_balance <= 1e-4


@pytest.mark.parametrize("angle", [2.0, -2.5, 0.3])
def test_the_followed_slip_is_along_a_constant_drive_not_against_it(angle):
    """A slip acceleration that does not depend on the slip (a constant drive g): the slip it
    follows is g / |g| (to 1e-12), not -g / |g|, where d x g changes sign too (found first in the
    scan for these angles' opposites); in the plane the sign along the drive, and none where the
    acceleration turns against either sign."""
    g = 3.0 * np.array([math.cos(angle), math.sin(angle)])
    found = _followed_slip(lambda d: (float(d[0] * g[1] - d[1] * g[0]), float(d @ g)), 2, 1e-9)
    np.testing.assert_allclose(found, g / 3.0, atol=1e-12)
    assert _followed_slip(lambda d: (0.0, float(-2.0 * d[0])), 1, 1e-9)[0] == -1.0
    assert _followed_slip(lambda d: (0.0, -1.0), 1, 1e-9) is None


@pytest.mark.parametrize("scale", [1.0, 3.0, 10.0])
def test_only_a_slip_slower_than_the_contracts_plastic_speed_is_arrested(scale):
    """Random file 20693's kept state (data/turned_slip_20693_state.json) with every velocity
    scaled: of the contacts whose slip turned past a right angle, those slower than the
    contract's 1e-4 m/s come to rest at the event (``arrest``), the faster ones keep their slip
    (changed only through the others' arrest: 1.18e-4 -> 0.98e-4 m/s at 3 x), and nothing moves
    when none is that slow."""
    run, totals, kept, mode = _kept_state("turned_slip_20693")
    q, v = kept["q"], scale * kept["v"]
    speed = np.linalg.norm(run.point(q, v).slip, axis=1)
    turned = np.zeros(run.nc, bool)
    turned[kept["turned"]] = True
    slow = turned & (speed < 1e-4)
    assert (turned & ~slow).any() or scale == 1.0
    q1, v1 = run.arrest(q, v, mode, totals)
    after = np.linalg.norm(run.point(q1, v1).slip, axis=1)
    assert np.all(after[slow] < 1e-12)
    assert np.all(after[turned & ~slow] > 0.5 * speed[turned & ~slow])  # moved only through the slow ones' arrest
    if not slow.any():
        assert np.array_equal(v1, v)


def test_a_redundant_modes_forces_push_where_a_pushing_split_exists():
    """Random file 30804 (data/redundant_pull_30804.yaml: friction 0.3) at 0.0785 s (the kept
    state and mode, data/redundant_pull_30804_state.json): four contacts slide, three of them on
    one line of one rigid body (a welded rod's two ends and a hinged rod's root), so their rows
    are redundant and the split of their forces is not unique. The least-norm split gave the
    hinged rod's tip (contact 4) -2.2e-9 N, falling, while Lemke's split of the same rows (which
    chose the mode) loaded it: its force witness fired every 4.5e-10 s, the same mode came back
    and the run stopped (the stall). The mode's forces are now the least-norm split of those
    that push: every normal force >= 0, the rows met, each sliding contact's friction mu f_n
    against its slip, and the mode holds at its own event."""
    from impulse_core.timedomain.events.forces import _contact_forces

    run, _, kept, mode = _kept_state("redundant_pull_30804")
    q, v = kept["q"], kept["v"]
    new = run.resolve(q, v, mode)
    closed = np.flatnonzero(new.closed)
    assert list(closed) == [0, 1, 3, 4] and new.redundant and new.sliding[closed].all()
    pt = run.point(q, v)
    rows, (a, lam) = run.mode_solution(pt, new)
    assert np.linalg.matrix_rank(rows.G) < rows.n  # redundant rows: the split is not unique
    fn, ft = _contact_forces(rows, lam, run.mu, run.nc)
    assert np.all(fn[closed] >= -1e-12 * np.max(fn)) and fn[2] == 0.0  # Signorini: pushing, the open one free
    assert np.max(np.abs(rows.G @ a + rows.b)) < 1e-9  # the closed rows stay at rest along their normals
    u = new.slip[closed]
    assert np.allclose(ft[closed], -run.mu * fn[closed, None] * u, rtol=0, atol=1e-12)  # Coulomb: sliding
    assert np.all(pt.gap[closed] > -1e-12)
    w = run.witness(q, v, new)
    assert np.all(w >= 1.0 - 1e-3), w[w < 1.0]  # the mode holds at its own event: no witness fires


def test_events_that_give_back_the_mode_they_stopped_are_a_stall_naming_the_contacts(monkeypatch):
    """A plank resting flat whose mode choice (patched) makes both contacts slide from rest
    along +x: friction then accelerates each slip along -x, against the mode's, so the slip
    witness fires about 1e-10 s after every event, and the event gives the same mode back
    (random file 30891 did so at 4e-12 s, each event with two slip searches of 0.4 s, for hours:
    neither the 1e-12 s stall guard nor the event budget ended it within minutes). More than
    REPEATS such events shorter than REPEAT_SPAN are a stall; with no Moreau-Jean bridge left to
    cross it (MAX_BRIDGES 0 here: the patched mode choice would stall after each), its error names
    the contacts that slide against their own slip acceleration."""
    import impulse_core.timedomain.events.paradox as paradox_module  # where the bridges are counted
    from impulse_core.errors import NumericalError
    from impulse_core.timedomain.events.settings import REPEATS

    monkeypatch.setattr(paradox_module, "MAX_BRIDGES", 0)

    plank = Tree((Body("plank", None, 0.6, 3.0, 0.0, contacts=(0.0, 1.0), radius=0.02),))
    scene = Scene(speed=0.5, restitution=0.0, friction=0.4, gravity=G, duration=0.1)
    original, events = _Landing.resolve, [0]

    def against(self, q, v, mode, t=0.0):
        events[0] += 1
        new = original(self, q, v, mode, t).copy()
        new.slip[new.closed] = (1.0, 0.0)
        return new

    monkeypatch.setattr(_Landing, "resolve", against)
    run = _Landing(plank, scene, (), LandingSettings(), SPATIAL)
    with pytest.raises(NumericalError, match=r"chatters at t = .* plank\[0\], plank\[1\] start to slide from rest"):
        run.run(2e-3, until=lambda *_: events[0] > 1000)  # (no impacts: the event budget never ends it)
    assert events[0] <= REPEATS + 5


@pytest.mark.parametrize("duration", [0.035, pytest.param(None, marks=pytest.mark.slow)])
def test_a_tumbling_flight_after_the_impacts_stops_the_halving_unmet(duration):
    """Random file 32924 (data/tumbling_32924.yaml: a 0.31 kg base and two rods of radius 0 on
    springs, mu 0.3, e 0.25, a spinning approach): five impacts by 0.029 s, then a tumbling flight
    of 0.21 s whose end a 1e-10 change of its starting velocity moves by 1e-2 rad. Cut at 0.035 s
    the halving converges (runs at h and h / 4, 5.7e-4; the default case, ~8 s); the whole
    landing's runs at h, h / 4 and h / 16 end 1.61, then 0.90 apart in their final angles with
    their impulses within 1.3e-3, and the halving stops there, unmet (slow: ~90 s of CPU; it went
    on halving, each run twice the last, before :func:`runs_apart`)."""
    from optimizer.config.model_file import load_model_file

    model = load_model_file(Path(__file__).resolve().parent / "data" / "tumbling_32924.yaml")
    scene = model.scene if duration is None else replace(model.scene, duration=duration)
    r = landing(model.tree, scene, model.joints, LandingSettings(), model.space)
    if duration is not None:
        assert r.converged and not r.runs_apart
        return
    assert r.runs_apart and not r.converged and len(r.halving) == 2 and len(r.events) == 5
    (_, _, _, _, first), (_, _, peaks, totals, last) = r.halving
    assert min(first, last) > 0.5 and max(peaks, totals) < 2e-3 and r.error_estimate == last


def _lone_rod(radius: float = 0.0) -> tuple[Tree, Scene]:
    """Random file 33016: a lone rod (the base, no joint) landing on its tip at e = 1, mu 0.5, cut
    to 0.15 s (two impacts): at radius 0 nothing but the core's axial floor (1e-14 of its inertia
    across) gives its spin about its own axis any inertia."""
    rod = Body("rod", None, 0.0744988, 0.93267, -2.72775, rpy=(-0.194306, 0.283336, 0.0), contacts=(1.0,),
               radius=radius)
    return Tree((rod,)), Scene(speed=2.94541, restitution=1.0, friction=0.5, gravity=G, duration=0.15)


def test_a_rod_of_radius_0_does_not_spin_about_its_own_axis_and_its_landing_converges():
    """The spin of a rod of radius 0 about its own axis moves no mass: its velocity, which only
    rounding in the impacts and steps would drive (eps x the torques over the floor's inertia), is
    held at 0 (``MASSLESS``), so runs at two steps end in the same turn (random file 33016: before,
    that spin's rate at T differed by 10 rad/s between runs, its turn by 2 pi, and the halving
    never converged: 1.6 apart at 0.15 s) and ``landing()`` converges. A rod with a radius has no
    such motion: nothing is removed. The derivatives' replay refuses the landing that held it."""
    from impulse_core.errors import NumericalError
    from impulse_core.timedomain.landing_derivatives import landing_gradient

    tree, scene = _lone_rod()
    runs = [_Landing(tree, scene, (), LandingSettings(), SPATIAL) for _ in range(2)]
    for run in runs:
        run.tape = []
    coarse, fine = (run.run(h) for run, h in zip(runs, (1e-3, 5e-4)))
    assert len(coarse.events) == len(fine.events) == 2
    # rounding still moves the turn at T by up to ~2e-3 (the floor's spin before it is held: AVX-512
    # and AVX2 kernels of OpenBLAS end 1.5e-3 and 1.8e-4 apart); before the hold, 2 pi
    np.testing.assert_allclose(coarse.final_angles, fine.final_angles, atol=5e-3)
    assert any(entry[0] == "unspun" for entry in runs[1].tape)
    r = landing(tree, scene, (), LandingSettings(), SPATIAL)
    assert r.converged and r.error_estimate <= 1e-3 and not r.runs_apart
    with pytest.raises(NumericalError, match="radius 0 spun about its own axis"):
        landing_gradient(tree, scene, (), LandingSettings(), step=1e-3, space=SPATIAL)
    wide = _Landing(*_lone_rod(0.01), (), LandingSettings(), SPATIAL)
    wide.tape = []
    wide.run(1e-3)
    assert wide.tape and not any(entry[0] == "unspun" for entry in wide.tape)


def test_an_impact_that_gains_energy_is_newtons_and_coulombs_law():
    """Random file 33016's second impact (the lone rod with a radius of 1 cm, e = 1, mu 0.5) raises
    the kinetic energy, and that is the law's (Kane's paradox), hand-checked at the tip: the tip
    sticks (tangential velocity after 0), its normal velocity reverses whole (e = 1), the friction
    impulse is inside the cone, and the energy gained is half the tangential impulse times the slip
    before (the normal part's work vanishes at e = 1): positive, friction pushing along the slip."""
    from scipy.spatial.transform import Rotation

    tree, scene = _lone_rod(0.01)
    r = _Landing(tree, replace(scene, duration=0.05), (), LandingSettings(), SPATIAL).run(1e-3)
    gained = r.gaining_events
    assert len(gained) == 1
    ev = gained[0]
    times, states = r.trajectory
    q = states[int(np.argmin(np.abs(times - ev.time)))]
    rod = tree.bodies[0]
    axis = (Rotation.from_rotvec(q[3:6]).as_matrix() @ rotation_rpy(rod.rpy) @ rotation_rpy((0.0, 0.0, rod.angle)))[:, 0]
    before, after = (v[:3] + np.cross(v[3:6], rod.length * axis) for v in (ev.v_minus, ev.v_plus))
    assert after[1] == pytest.approx(-before[1], rel=1e-9) and before[1] < 0
    np.testing.assert_allclose(after[[0, 2]], 0.0, atol=1e-9 * abs(before[1]))
    p_t = ev.tangential[0]
    assert np.hypot(*p_t) < 0.5 * ev.external[0]
    work = 0.5 * float(p_t @ before[[0, 2]])
    assert work > 0.1 * ev.energy_before
    assert ev.energy_after - ev.energy_before == pytest.approx(work, rel=1e-9)


def test_a_rod_of_radius_0_with_its_centre_of_mass_off_its_axis_is_refused_by_the_landing():
    """Random file 60145: a lone rod of radius 0 whose centre of mass is off its axis turns about
    the axis through that centre with only the core's floor as inertia, and the turn moves its
    contact (W_nn 3.6e12), so the landing would follow the floor: it chattered (exit 1 after 17 s),
    and with the offset in the plane, read as spatial, diverged. The landing refuses it at once,
    naming the field; with a radius, or with the offset on the axis (33016's rod: its spin moves no
    contact), it goes on."""
    rod = Body("b0", None, 0.0976535, 0.104383, 2.67899, contacts=(1.0,), com_offset=(0.0274305, 0.00668402))
    scene = Scene(speed=3.89731, restitution=0.459858, friction=0.5, gravity=G, duration=0.141701)
    for offset in ((0.0274305, 0.00668402), (0.0274305, 0.0)):
        with pytest.raises(ModelError, match=r"^model\.bodies\[0\]\.com_offset: .*give the rod a radius"):
            _Landing(Tree((replace(rod, com_offset=offset),)), scene, (), LandingSettings(), SPATIAL)
    _Landing(Tree((replace(rod, radius=0.005),)), scene, (), LandingSettings(), SPATIAL)
    _Landing(*_lone_rod(), (), LandingSettings(), SPATIAL)


def test_a_slow_slip_splits_its_steps_so_that_the_runs_converge_at_rk4s_order():
    """Random file 61600 (data/slow_slip_61600.yaml: a 32 g base rod under a 1.7 kg rod, mu 0.5)
    slides after touchdown at 0.13 to 2.8 m/s, where the step's regularisation core h mu f_n w
    (:meth:`_Landing.steer`) was 4 to 8 m/s at its first step: with the direction regularised on
    every step, the core's first-order error made the whole landing's runs converge at first
    order (8.4e-2 ... 4.1e-4 down to h / 128, 655 s). Asked (``LandingSettings.slip_splits``), such a
    step is halved instead (:meth:`_Landing.slip_length`): over the first 3 ms of sliding, runs at h and h / 4 agree
    within 1e-6 of the largest velocity (measured 7.5e-8; with the direction regularised on every
    step, 1.07 of 20.3 rad/s), and the whole landing (8.8 s) converges at its first halving
    (estimate 9.1e-8)."""
    model = _data_model("slow_slip_61600.yaml")
    scene = replace(model.scene, duration=0.003)
    run = _Landing(model.tree, scene, model.joints, LandingSettings(slip_splits=SLIP_SPLITS), model.space)
    h = run.first_step()
    coarse, fine = run.run(h), run.run(h / 4.0)
    assert [e.kind for e in fine.events] == ["touchdown"]
    assert fine.n_steps > 200  # split below h / 4 where the slip is slow
    scale = float(np.max(np.abs(fine.v_final)))
    assert float(np.max(np.abs(coarse.v_final - fine.v_final))) <= 1e-6 * scale
    assert float(np.max(np.abs(coarse.q_final - fine.q_final))) <= 1e-7


@pytest.mark.parametrize("seed", [0, 5])
def test_a_planar_slip_read_in_space_is_not_split(seed):
    """A planar leg read as spatial slides in its plane: its slip keeps its line, where the
    regularised direction is s / |s| exactly, so ``slip_splits`` splits none of its steps
    (``SLIP_TURN``): the run is the one without it, to the bit (split, leg 0's final angles
    moved by 4e-10 of the plane's, beyond what reading the plane in space may change)."""
    tree, laws, scene = _random_leg(seed)
    plain = _Landing(tree, scene, laws, LandingSettings(), SPATIAL).run(STEP)
    asked = _Landing(tree, scene, laws, LandingSettings(slip_splits=SLIP_SPLITS), SPATIAL).run(STEP)
    assert asked.n_steps == plain.n_steps
    assert np.array_equal(asked.final_angles, plain.final_angles)
    assert np.array_equal(asked.total_external, plain.total_external)
