"""Exact derivatives of the whole landing in space (impulse_core.timedomain.landing_derivatives
with ``space=SPATIAL``).

Seeded spatial legs: a sprung two-rod leg whose shank is rolled and yawed out of the plane,
landing obliquely on one sticking contact (the implicit integrator, ROS2, forced: its replay in
space), and a splayed foot (toe and heel yawed about the vertical through the ankle) with
friction and a knee stop (contacts sliding along a 2D direction that turns with the slip, sliding
impacts on the circular cone's edge, the knee reaching its stop). For each:
- the replayed graph's values equal the numeric landing's (same step) to 1e-10;
- the exact derivatives agree with central differences of the numeric landing at the same step
  along seeded random directions over lengths, masses, angles, rpy angles and joint-law values,
  the event sequence the same at +- the step; so do the derivatives w.r.t. the scene's values
  (the splayed foot: friction, speed, restitution and the knee's stop restitution; the two-rod
  leg, whose tip starts sliding: friction and speed), one at a time;
- a planar leg read as spatial gives the planar gradient (the entries both have; the plane's base
  angle is the spatial base angle plus the rotation coordinate about z).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from impulse_core.kinematics.spatial import SPATIAL
from impulse_core.model.joints import FREE, JointLaw
from impulse_core.model.rods import rotation_rpy
from impulse_core.model.tree import Body, Scene, Tree
from impulse_core.timedomain.landing import IMPLICIT, LandingSettings
from impulse_core.timedomain.landing_derivatives import (
    SCALARS,
    apply_theta,
    design_names,
    design_theta,
    landing_gradient,
    sequence_signature,
    taped_run,
)
from tests.conftest import report
from tests.impulse_core.test_compliant_spatial import rpy_of
from tests.impulse_core.test_landing_derivatives import (
    EPS,
    G,
    SCENE_EPS,
    STEP,
    _jacobian_of,
    _stop_leg,
    assert_directions_carry_the_jacobian,
    assert_replay_is_the_landing,
    moved_scene,
)

CASES = ("two_rod", "splayed_stop")
#: The two-rod leg's integrator: ROS2 (its replay in space).
IMPLICIT_SETTINGS = LandingSettings(integrator=IMPLICIT)


def _two_rod_leg() -> tuple[Tree, tuple[JointLaw, ...], Scene, LandingSettings]:
    """A thigh and a shank rolled 0.2 and yawed 0.15 rad at a sprung, damped knee, landing on the
    shank's tip with a lateral velocity and a roll rate, plastically, with friction 0.4: the tip
    sticks, then starts sliding (its direction the cone's fixed point) and slides on."""
    bodies = (Body("thigh", None, 0.4, 2.0, -1.2),
              Body("shank", 0, 0.4, 1.0, -0.6, contacts=(1.0,), rpy=(0.2, 0.0, 0.15), radius=0.01))
    laws = (FREE, JointLaw(stiffness=60.0, damping=0.8, rest=-0.55))
    scene = Scene(speed=1.5, velocity_x=0.2, velocity_z=0.15, angular_velocity_x=0.3, restitution=0.0, friction=0.4,
                  gravity=G, duration=0.03)
    return Tree(bodies), laws, scene, IMPLICIT_SETTINGS


def _splayed_stop_leg() -> tuple[Tree, tuple[JointLaw, ...], Scene, LandingSettings]:
    """The planar stop leg (test_landing_derivatives) with its toe and heel turned about the
    vertical through the ankle by seeded angles up to 0.5 rad, rods of radius 5 mm, the knee's
    upper stop 3 mrad from touchdown, friction 0.8 and an oblique approach."""
    tree, laws, scene = _stop_leg()
    rng = np.random.default_rng(11)
    phi = tree.bodies[0].angle + tree.bodies[1].angle
    bodies = list(tree.bodies[:2])
    for b in tree.bodies[2:]:
        turn = rotation_rpy((0.0, rng.uniform(-0.5, 0.5), 0.0))  # about the vertical, in the leg's frame
        R = rotation_rpy((0.0, 0.0, -phi)) @ turn @ rotation_rpy((0.0, 0.0, phi))
        bodies.append(replace(b, rpy=rpy_of(R), radius=0.005))
    knee = tree.bodies[1].angle
    laws = (laws[0], replace(laws[1], limits=(knee - 0.1, knee + 0.003)), *laws[2:])
    scene = replace(scene, friction=0.8, velocity_z=0.2, angular_velocity_x=0.3, angular_velocity_y=-0.2, duration=0.02)
    return Tree(tuple(bodies)), laws, scene, LandingSettings()


def _case(name: str) -> tuple[Tree, tuple[JointLaw, ...], Scene, LandingSettings]:
    return _two_rod_leg() if name == "two_rod" else _splayed_stop_leg()


#: Each case's slow-slip splits at its nominal design (``run.slip_halvings``: filled by ``gradients``).
HALVINGS: dict = {}


@pytest.fixture(scope="module")
def gradients() -> dict:
    out = {}
    for name in CASES:
        tree, laws, scene, settings = _case(name)
        out[name] = landing_gradient(tree, scene, laws, settings, step=STEP, space=SPATIAL)
        HALVINGS[name] = list(taped_run(tree, scene, laws, STEP, settings, SPATIAL)[2].slip_halvings)
    return out


def _objectives(name: str, theta: np.ndarray, halvings: list[int] | None = None) -> tuple[np.ndarray, tuple]:
    """The objectives and event sequence of the numeric landing at theta; with ``halvings``, along
    those slow-slip splits (the nominal run's: the branch the derivatives hold)."""
    tree, laws, scene, settings = _case(name)
    t, l = apply_theta(tree, laws, theta, SPATIAL)
    r, tape, run = taped_run(t, scene, l, STEP, settings, SPATIAL, halvings=halvings)
    values = np.concatenate([[getattr(r, k) for k in SCALARS], r.total_external, r.final_angles])
    return values, sequence_signature(tape, run)


def _jacobian(g) -> np.ndarray:
    return np.vstack([g.jacobian[k] for k in SCALARS] + [g.jacobian["total_external"], g.jacobian["final_angles"]])


def _searched(g) -> np.ndarray:
    """Entries a direction may move: lengths, masses, angles, rpy angles, radii that are not 0,
    springs, dampers, and the rest angles and stops that the laws give."""
    J = _jacobian(g)
    return np.array([n.endswith(("length", "mass", "angle", "roll", "pitch", "yaw", "stiffness", "damping"))
                     or (n.endswith("radius") and g.theta[i] > 0)
                     or (n.endswith(("rest", "limits[0]", "limits[1]")) and bool(np.any(J[:, i])))
                     for i, n in enumerate(g.names)])


def test_the_cases_have_what_they_are_named_for(gradients):
    two_rod, splayed = gradients["two_rod"], gradients["splayed_stop"]
    assert two_rod.result.integrator == "implicit" and splayed.result.integrator == "rk4"
    assert any(e.kind == "stop" for e in splayed.result.events)
    # sliding between impacts and sliding impacts (the cone's edge against a 2D slip)
    assert any(item[0] == "step" and any(item[1][1]) for item in splayed.sequence)
    assert any(1 in item[4][1] for item in splayed.sequence if item[0] == "impact")
    assert any(2 in item[4][1] for item in two_rod.sequence if item[0] == "impact")  # a sticking impact
    slides = [item[1][1] for item in two_rod.sequence if item[0] == "step"]
    assert (0,) in slides and (1,) in slides  # sticking, then sliding
    for name, g in gradients.items():
        tree, laws, _, _ = _case(name)
        assert g.names == design_names(tree, SPATIAL) and np.array_equal(g.theta, design_theta(tree, laws, SPATIAL))
        assert len(g.values["final_angles"]) == tree.n_bodies + 2  # rotation coordinates, then joints
        J = _jacobian(g)
        assert np.all(np.isfinite(J))
        yaw = [i for i, n in enumerate(g.names) if n.endswith(".yaw") and g.theta[i] != 0]
        assert yaw and np.max(np.abs(J[:, yaw])) > 1e-3 * np.max(np.abs(J))  # out of the plane matters
        # the event sequence is reported: the taped run's
        _, sequence = _objectives(name, g.theta)
        assert g.sequence == sequence and any(item[0] == "impact" for item in g.sequence)


@pytest.mark.parametrize("name", CASES)
def test_replayed_values_equal_the_landing(gradients, name):
    assert_replay_is_the_landing(gradients[name])


@pytest.mark.parametrize("name", CASES)
def test_gradients_agree_with_central_differences(gradients, name):
    """Two seeded random directions over every searched entry: J u against central differences
    of the numeric landing at the same step, the event sequence unchanged at both ends and the
    slow slip's steps split as at theta (a split moved by a step is a jump of the objective:
    ``landing_derivatives``' module docstring; the two-rod leg's slip, slowing to its stop, takes
    one more step of h / 1024 at +-EPS along the first direction)."""
    g = gradients[name]
    J = _jacobian(g)
    rng = np.random.default_rng(7)
    scale = np.maximum(1.0, np.abs(g.theta)) * _searched(g)
    worst = 0.0
    for _ in range(2):
        u = rng.standard_normal(len(g.theta)) * scale
        plus, seq_plus = _objectives(name, g.theta + EPS * u, HALVINGS[name])
        minus, seq_minus = _objectives(name, g.theta - EPS * u, HALVINGS[name])
        assert seq_plus == g.sequence and seq_minus == g.sequence
        fd, exact = (plus - minus) / (2 * EPS), J @ u
        error = np.abs(fd - exact) / np.maximum(np.abs(exact), 1e-6)
        assert np.all(error <= 1e-4), error
        worst = max(worst, float(np.max(error)))
    report("landing-gradient-spatial", f"{name}: {len(g.result.events)} events, J u vs central differences {worst:.1e}")


@pytest.mark.parametrize(("name", "value"), [("splayed_stop", "friction"), ("splayed_stop", "speed"),
                                             ("splayed_stop", "restitution"), ("splayed_stop", "shank.stop_restitution"),
                                             ("two_rod", "friction"), ("two_rod", "speed")])
def test_scene_derivatives_agree_with_central_differences(gradients, name, value):
    """Along one scene value: its column of the scene Jacobian against central differences of the
    numeric landing at the same step, the event sequence unchanged at both ends and the slow
    slip's steps split as at the nominal scene (the two-rod leg's, left to split on their own at
    friction +-SCENE_EPS, differ by 3e-4 of the derivative)."""
    tree, laws, scene, settings = _case(name)
    g = gradients[name]
    column = _jacobian_of(g.scene_jacobian)[:, g.scene_names.index(value)]
    assert np.max(np.abs(column)) > 1e-3
    ends = []
    for h in (SCENE_EPS, -SCENE_EPS):
        s, l = moved_scene(tree, laws, scene, value, h)
        r, tape, run = taped_run(tree, s, l, STEP, settings, SPATIAL, halvings=HALVINGS[name])
        assert sequence_signature(tape, run) == g.sequence
        ends.append(np.concatenate([[getattr(r, k) for k in SCALARS], r.total_external, r.final_angles]))
    fd = (ends[0] - ends[1]) / (2 * SCENE_EPS)
    error = np.abs(fd - column) / np.maximum(np.abs(column), 1e-6)
    assert np.all(error <= 1e-4), error
    report("landing-gradient-spatial", f"{name}: d/d {value} vs central differences {np.max(error):.1e}")


@pytest.mark.parametrize("name", CASES)
def test_directions_carry_the_jacobian_along_them(gradients, name):
    """Forward mode along seeded directions (slip directions and cores swept too) is the full
    Jacobian times them."""
    tree, laws, scene, settings = _case(name)
    assert_directions_carry_the_jacobian(gradients[name], tree, laws, scene, settings, SPATIAL)


def test_a_planar_leg_read_as_spatial_gives_the_planar_gradient():
    """The planar stop leg (knee stop, springs, a second touchdown) landed as a spatial tree: each
    entry theta has in the plane has the same derivative in space (1e-8 of the largest), and the
    plane's base angle is the base's ``angle`` plus the rotation coordinate about z."""
    tree, laws, scene = _stop_leg()
    scene = replace(scene, duration=0.015)
    planar = landing_gradient(tree, scene, laws, step=STEP)
    spatial = landing_gradient(tree, scene, laws, step=STEP, space=SPATIAL)
    assert any(e.kind == "stop" for e in planar.result.events)
    at = [spatial.names.index(n) for n in planar.names]
    for k in SCALARS:
        ours, theirs = spatial.jacobian[k][at], planar.jacobian[k]
        assert np.max(np.abs(ours - theirs)) <= 1e-8 * np.max(np.abs(theirs)), k
    ours, theirs = spatial.jacobian["total_external"][:, at], planar.jacobian["total_external"]
    assert np.max(np.abs(ours - theirs)) <= 1e-8 * np.max(np.abs(theirs))
    angles = spatial.jacobian["final_angles"][:, at]
    base = angles[2] + (np.arange(len(at)) == planar.names.index("thigh.angle"))
    theirs = planar.jacobian["final_angles"]
    assert np.max(np.abs(np.vstack([base, angles[3:]]) - theirs)) <= 1e-8 * np.max(np.abs(theirs))
    assert np.max(np.abs(angles[:2])) <= 1e-10 * np.max(np.abs(theirs))  # nothing turns out of the plane


def test_a_landing_whose_base_turned_past_the_chart_is_refused(monkeypatch):
    """The replay does not follow a re-centring of the base's rotation coordinates (a base that
    turned more than RECHART rad): the derivatives are refused with a NumericalError saying so,
    not given along the wrong coordinates."""
    from impulse_core.errors import NumericalError
    from impulse_core.timedomain import landing_derivatives
    from impulse_core.timedomain.events import run as module  # the run loop re-centres

    tree, laws, scene, settings = _two_rod_leg()
    monkeypatch.setattr(module, "RECHART", 1e-3)
    monkeypatch.setattr(landing_derivatives, "RECHART", 1e-3)
    with pytest.raises(NumericalError, match="re-centred"):
        landing_gradient(tree, replace(scene, duration=0.005), laws, settings, step=STEP, space=SPATIAL)


def test_approaches_share_one_structure_and_each_keeps_its_slip_floor():
    """Landings that differ only in their approach (speed, lateral velocity, spin) share one
    symbolic structure (the approach is not in its graphs), and the structure's slip floor is each
    run's own (1e-9 max(1, speed, |v_x|)): a slip of 1e-8 m/s, between two runs' floors, turns a
    sliding contact's direction to the slip in the slow run's replay and keeps the mode's in the
    fast one's, as each numeric landing does (:func:`landing.slip_direction`)."""
    from impulse_core.timedomain.events.rows import _Mode, slip_direction
    from impulse_core.timedomain.events.run import _Landing
    from impulse_core.timedomain.landing_derivatives import _symbolic

    tree, laws, scene, settings = _two_rod_leg()
    fast = replace(scene, speed=150.0, velocity_x=-0.4, angular_velocity_x=-0.1)
    slow, quick = (_Landing(tree, s, laws, settings, SPATIAL) for s in (scene, fast))
    sym = _symbolic(slow, laws)
    assert _symbolic(quick, laws) is sym
    assert slow.speed_tol < 1e-8 < quick.speed_tol
    q = slow.q0
    v = np.random.default_rng(5).normal(size=slow.nv)
    slip = slow.point(q, v).slip[0]
    v *= 1e-8 / np.linalg.norm(slip)  # the contact's slip speed 1e-8 m/s
    u = slip / np.linalg.norm(slip)
    d = (u + 1.5 * np.array([-u[1], u[0]])) / np.hypot(1.0, 1.5)  # 56 degrees from the slip
    mode = _Mode(closed=np.array([True]), slip=d[None, :], stop=np.zeros(slow.nv, int))
    turned = []
    for run in (slow, quick):
        p = np.append(design_theta(tree, laws, SPATIAL), [run.mu, run.speed_tol])
        (ours,), _ = sym.follow(mode)(np.concatenate([q, v]), p, d, np.zeros(1))
        theirs = slip_direction(run.point(q, v), d[None, :], np.zeros(1))[0]
        assert np.max(np.abs(ours - theirs)) <= 1e-12
        turned.append(np.max(np.abs(ours - d)) > 0.1)
    assert turned == [True, False]


def test_a_projection_carried_across_a_crease_is_marked_and_refused(monkeypatch):
    """A projection whose position correction carries a resting contact across a heightfield's
    grid line takes the next cell's rows (``_Landing.project``), which the replay's projection
    (the rows where the step ended) does not follow: the run marks each such projection on its
    tape, and the derivatives are refused where one is, with a NumericalError saying so."""
    from pathlib import Path

    from impulse_core.errors import NumericalError
    from impulse_core.timedomain import landing_derivatives
    from impulse_core.timedomain.landing_derivatives import taped_run
    from optimizer.config.model_file import load_model_file

    m = load_model_file(Path(__file__).parent / "data" / "crease_valley_puck.yaml")
    scene = replace(m.scene, duration=0.01)  # before the puck's first crossing
    kept = landing_derivatives.taped_run
    result, tape, run = kept(m.tree, scene, m.joints, 2.5e-4, space=m.space)
    assert "crease_project" not in [entry[0] for entry in tape]
    landing_gradient(m.tree, scene, m.joints, step=2.5e-4, space=m.space)  # replayed

    def marked(*args, **kwargs):  # the same run, one of its projections marked as carried across
        result, tape, run = kept(*args, **kwargs)
        at = [entry[0] for entry in tape].index("project", len(tape) // 2)
        return result, tape[: at + 1] + [("crease_project",)] + tape[at + 1 :], run

    monkeypatch.setattr(landing_derivatives, "taped_run", marked)
    with pytest.raises(NumericalError, match="across a grid line of scene.heightfield"):
        landing_gradient(m.tree, scene, m.joints, step=2.5e-4, space=m.space)
