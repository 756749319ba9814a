"""Exact derivatives of the whole landing along its event sequence
(impulse_core.timedomain.landing_derivatives).

Seeded cases: a leg whose second contact touches down after the first (frictionless), one whose
knee reaches its stop (springs with given rest angles, a stop restitution), one with friction
(contacts sticking and sliding between impacts, sliding and sticking impacts), and one whose toe
ends in a light, short damped rod (the implicit integrator, forced); all with
springs, dampers and gravity. For each:
- the replayed graph's values equal the numeric landing's (same step) to 1e-10;
- the exact derivatives agree with central differences of the numeric landing at the same step,
  along seeded random directions over lengths, masses, angles and joint-law values, where the
  event sequence (modes, event witnesses, impact modes, step counts) is the same at +- the step;
- so do the derivatives w.r.t. the scene's values (friction, speed, restitution) and a joint's
  stop restitution, one at a time (the friction case: sliding and sticking, restitution 0.07 with
  rows the plastic rules zero; the stop leg: the knee's stop hit at stop restitution 0.3).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from impulse_core.errors import NumericalError
from impulse_core.kinematics.spatial import PLANAR
from impulse_core.model.joints import FREE, JointLaw
from impulse_core.model.tree import Body, Scene, Tree
from impulse_core.timedomain.landing import LandingSettings, landing
from impulse_core.timedomain.landing_derivatives import (
    SCALARS,
    apply_theta,
    design_names,
    design_theta,
    landing_gradient,
    scene_names,
    scene_theta,
    sequence_signature,
    taped_run,
)
from tests.impulse_core.test_landing import _random_leg

G = 9.81
STEP = 5e-4
#: Central differences' step, relative to max(1, |theta_i|) along the direction.
EPS = 1e-6
#: Central differences' step for a scene value (absolute): at EPS the rounding of the objectives
#: (1e-10 relative) is 1e-4 of the smallest restitution derivatives.
SCENE_EPS = 1e-5


def _stop_leg() -> tuple[Tree, tuple[JointLaw, ...], Scene]:
    """A leg whose knee flexes onto its upper stop (restitution 0.3) 6 mrad from touchdown."""
    knee = -0.6
    bodies = (Body("thigh", None, 0.4, 2.0, -1.2), Body("shank", 0, 0.4, 1.0, knee),
              Body("toe", 1, 0.15, 0.08, 1.4, contacts=(1.0,)), Body("heel", 1, 0.1, 0.05, -0.9, contacts=(1.0,)))
    laws = (FREE, JointLaw(stiffness=40.0, damping=0.5, rest=knee + 0.05, limits=(knee - 0.1, knee + 0.006),
                           stop_restitution=0.3),
            JointLaw(stiffness=5.0, damping=0.05), JointLaw(stiffness=4.0, damping=0.05, rest=-0.85))
    return Tree(bodies), laws, Scene(speed=2.0, velocity_x=0.2, restitution=0.3, gravity=G, duration=0.04)


def _stiff_leg() -> tuple[Tree, tuple[JointLaw, ...], Scene]:
    """The stop leg with a 2 cm, 20 g damped rod at the toe's end (its damper's rate 1e5 1/s)."""
    tree, laws, scene = _stop_leg()
    toe = replace(tree.bodies[2], contacts=())
    tip = Body("toe_tip", 2, 0.02, 0.02, 0.3, contacts=(1.0,))
    return (Tree((*tree.bodies[:2], toe, tree.bodies[3], tip)), (*laws, JointLaw(stiffness=2.0, damping=0.3)),
            replace(scene, duration=0.006))


def _case(name: str) -> tuple[Tree, tuple[JointLaw, ...], Scene]:
    if name == "stiff":
        return _stiff_leg()
    if name == "second_touchdown":
        tree, laws, scene = _random_leg(3)
        return tree, laws, replace(scene, friction=0.0)
    if name == "stop":
        return _stop_leg()
    if name == "offsets":  # the stop leg with centres of mass off the rods (PLANAR_OFFSET)
        tree, laws, scene = _stop_leg()
        return Tree(tuple(replace(b, com_offset=(dy, 0.0)) for b, dy in zip(tree.bodies, (0.02, -0.015, 0.01, 0.0)))), laws, scene
    tree, laws, scene = _random_leg(0)  # mu = 1
    return tree, laws, scene


CASES = ("second_touchdown", "stop", "friction", "stiff", "offsets")
#: the stiff case forces the implicit integrator (ROS2): ``auto`` would take RK4 from its stable step
SETTINGS = {"stiff": LandingSettings(integrator="implicit")}


def _settings(name: str) -> LandingSettings:
    return SETTINGS.get(name, LandingSettings())


@pytest.fixture(scope="module")
def gradients() -> dict:
    out = {}
    for name in CASES:
        tree, laws, scene = _case(name)
        out[name] = landing_gradient(tree, scene, laws, _settings(name), step=STEP)
    return out


def _objectives(tree, laws, scene, theta, settings: LandingSettings = LandingSettings()) -> tuple[np.ndarray, tuple]:
    t, l = apply_theta(tree, laws, theta)
    r, tape, run = taped_run(t, scene, l, STEP, settings)
    return np.concatenate([[getattr(r, k) for k in SCALARS], r.total_external, r.final_angles]), sequence_signature(tape, run)


def _jacobian(g) -> np.ndarray:
    return _jacobian_of(g.jacobian)


def _searched(g) -> np.ndarray:
    """Entries a direction may move: lengths, masses, angles, springs, dampers, and the rest
    angles and stops that the laws give (contact fractions and `at` sit on their bounds)."""
    J = _jacobian(g)
    return np.array([n.endswith(("length", "mass", "angle", "stiffness", "damping", "com_y"))
                     or (n.endswith(("rest", "limits[0]", "limits[1]")) and bool(np.any(J[:, i])))
                     for i, n in enumerate(g.names)])


def test_the_cases_have_what_they_are_named_for(gradients):
    second = gradients["second_touchdown"].result
    assert second.touchdown_time[0] == 0.0 and second.touchdown_time[1] > 1e-3  # contact 1 lands later
    assert any(e.kind == "stop" for e in gradients["stop"].result.events)
    seq = gradients["friction"].sequence
    slips = {s for item in seq if item[0] == "step" for closed, slip in [item[1][:2]] for c, s in zip(closed, slip) if c}
    assert slips >= {-1, 0} and (1 in slips or -1 in slips)  # sticking and sliding between impacts
    impact_modes = {m for item in seq if item[0] == "impact" for m in item[4][1]}
    assert impact_modes >= {2} and impact_modes & {1, -1}  # sticking and sliding impacts
    assert gradients["stiff"].result.integrator == "implicit"
    assert all(g.result.integrator == "rk4" for name, g in gradients.items() if name != "stiff")
    for g in gradients.values():
        law = [n for n in g.names if n.endswith("stiffness")]
        assert law and np.all(np.isfinite(_jacobian(g)))


@pytest.mark.parametrize("name", CASES)
def test_replayed_values_equal_the_landing(gradients, name):
    assert_replay_is_the_landing(gradients[name])


def assert_replay_is_the_landing(g) -> None:
    """The replay's objectives are the numeric landing's (the same run, replayed)."""
    r = g.result
    for k in SCALARS:
        assert g.values[k] == pytest.approx(getattr(r, k), rel=1e-10, abs=1e-12), k
    assert np.max(np.abs(g.values["total_external"] - r.total_external)) <= 1e-10 * np.max(np.abs(r.total_external))
    assert np.max(np.abs(g.values["final_angles"] - r.final_angles)) <= 1e-10


@pytest.mark.parametrize("name", ["stiff", "friction"])
def test_directions_carry_the_jacobian_along_them(gradients, name):
    """Forward mode along seeded directions over theta and the scene's values (the replay's
    operations swept along them, no Jacobian formed) gives the full Jacobian times them."""
    tree, laws, scene = _case(name)
    assert_directions_carry_the_jacobian(gradients[name], tree, laws, scene, _settings(name))


def assert_directions_carry_the_jacobian(g, tree, laws, scene, settings, space=PLANAR) -> None:
    """:func:`landing_gradient` along 3 seeded directions is ``g``'s Jacobian (theta's columns,
    then the scene's; a frictionless scene's friction, NaN, not moved) times them, to 1e-12 of
    the largest entry; the values are ``g``'s."""
    full = np.hstack([_jacobian_of(g.jacobian), _jacobian_of(g.scene_jacobian)])
    D = np.random.default_rng(13).normal(size=(full.shape[1], 3))
    undefined = np.isnan(full).any(axis=0)
    D[undefined], full[:, undefined] = 0.0, 0.0
    along = landing_gradient(tree, scene, laws, settings, step=STEP, space=space, directions=D)
    expected = full @ D
    assert np.max(np.abs(_jacobian_of(along.jacobian) - expected)) <= 1e-12 * np.max(np.abs(expected))
    assert along.sequence == g.sequence and all(np.array_equal(along.values[k], g.values[k]) for k in g.values)


@pytest.mark.parametrize("name", CASES)
def test_gradients_agree_with_central_differences(gradients, name):
    """Two seeded random directions over every searched entry: J u against central differences
    of the numeric landing at the same step, the event sequence unchanged at both ends."""
    tree, laws, scene = _case(name)
    g = gradients[name]
    J = _jacobian(g)
    rng = np.random.default_rng(7)
    scale = np.maximum(1.0, np.abs(g.theta)) * _searched(g)
    for _ in range(2):
        u = rng.standard_normal(len(g.theta)) * scale
        plus, seq_plus = _objectives(tree, laws, scene, g.theta + EPS * u, _settings(name))
        minus, seq_minus = _objectives(tree, laws, scene, g.theta - EPS * u, _settings(name))
        assert seq_plus == g.sequence and seq_minus == g.sequence
        fd, exact = (plus - minus) / (2 * EPS), J @ u
        assert np.all(np.abs(fd - exact) <= 1e-4 * np.maximum(np.abs(exact), 1e-6)), np.abs(fd - exact) / np.abs(exact)


def test_the_stop_and_the_rest_angle_have_their_derivatives(gradients):
    """Along the knee's stop alone and its rest angle alone (coordinate directions)."""
    tree, laws, scene = _case("stop")
    g = gradients["stop"]
    J = _jacobian(g)
    for entry in ("shank.limits[1]", "shank.rest"):
        i = g.names.index(entry)
        assert np.max(np.abs(J[:, i])) > 1e-3
        u = np.zeros(len(g.theta))
        u[i] = 1.0
        plus, seq_plus = _objectives(tree, laws, scene, g.theta + EPS * u)
        minus, seq_minus = _objectives(tree, laws, scene, g.theta - EPS * u)
        assert seq_plus == g.sequence and seq_minus == g.sequence
        fd = (plus - minus) / (2 * EPS)
        assert np.all(np.abs(fd - J[:, i]) <= 1e-4 * np.maximum(np.abs(J[:, i]), 1e-6)), entry


def test_theta_round_trip_and_names():
    tree, laws, _ = _stop_leg()
    theta = design_theta(tree, laws)
    assert len(theta) == len(design_names(tree))
    t, l = apply_theta(tree, laws, theta)
    assert t == tree and l == laws
    assert "shank.limits[1]" in design_names(tree) and "thigh.length" in design_names(tree)


def test_peak_ties_and_the_reported_step():
    """Without a step the landing's own reported step is replayed; the peaks name their event."""
    tree, laws, scene = _stop_leg()
    scene = replace(scene, duration=0.01)
    settings = LandingSettings(tolerance=1e-2)
    g = landing_gradient(tree, scene, laws, settings)
    assert g.result.step == landing(tree, scene, laws, settings).step
    for k in ("peak_external_norm", "peak_internal_norm", "peak_max_internal"):
        i, _ = g.peak_events[k]
        assert i in g.ties[k]
    assert g.values["peak_external_norm"] == pytest.approx(g.result.events[g.peak_events["peak_external_norm"][0]].external_norm)
    assert "settled_at" not in g.values


def test_redundant_rows_are_refused():
    """A plank resting on both ends with friction sticks on four rows over three DOFs: the force
    split is not unique, so there is no derivative."""
    plank = Tree((Body("plank", None, 0.6, 3.0, 0.0, contacts=(0.0, 1.0)),))
    scene = Scene(speed=0.5, restitution=0.0, friction=1.0, gravity=G, duration=0.05)
    with pytest.raises(NumericalError, match="redundant"):
        landing_gradient(plank, scene, (), step=1e-3)


def test_centres_of_mass_off_the_rods_are_design_values(gradients):
    """theta carries each body's com_y where a centre of mass is off its rod (the values
    PLANAR_OFFSET reads), and the landing depends on them."""
    g = gradients["offsets"]
    assert "thigh.com_y" in g.names and not any(n.endswith("com_y") for n in gradients["stop"].names)
    J = _jacobian(g)
    assert np.max(np.abs(J[:, g.names.index("thigh.com_y")])) > 1e-3 * np.max(np.abs(J))


def moved_scene(tree: Tree, laws: tuple[JointLaw, ...], scene: Scene, name: str, h: float
                ) -> tuple[Scene, tuple[JointLaw, ...]]:
    """The scene and laws with the scene value ``name`` (:func:`scene_names`) moved by ``h``."""
    if "." not in name:
        return replace(scene, **{name: getattr(scene, name) + h}), laws
    b = [body.name for body in tree.bodies].index(name.split(".")[0])
    out = list(laws)
    out[b] = replace(out[b], stop_restitution=out[b].stop_restitution + h)
    return scene, tuple(out)


@pytest.mark.parametrize(("name", "value"), [("friction", "friction"), ("friction", "speed"), ("friction", "restitution"),
                                             ("stop", "speed"), ("stop", "restitution"), ("stop", "shank.stop_restitution")])
def test_scene_derivatives_agree_with_central_differences(gradients, name, value):
    """Along one scene value: its column of the scene Jacobian against central differences of the
    numeric landing at the same step, the event sequence unchanged at both ends."""
    tree, laws, scene = _case(name)
    g = gradients[name]
    i = g.scene_names.index(value)
    column = _jacobian_of(g.scene_jacobian)[:, i]
    assert np.max(np.abs(column)) > 1e-3
    ends = []
    for h in (SCENE_EPS, -SCENE_EPS):
        s, l = moved_scene(tree, laws, scene, value, h)
        r, tape, run = taped_run(tree, s, l, STEP)
        assert sequence_signature(tape, run) == g.sequence
        ends.append(np.concatenate([[getattr(r, k) for k in SCALARS], r.total_external, r.final_angles]))
    fd = (ends[0] - ends[1]) / (2 * SCENE_EPS)
    assert np.all(np.abs(fd - column) <= 1e-4 * np.maximum(np.abs(column), 1e-6)), np.abs(fd - column) / np.abs(column)


def test_the_scene_values_and_their_names(gradients):
    """Friction, speed, restitution, then each joint's stop restitution; a joint that never hits a
    stop has 0 derivatives, and a frictionless scene's friction column is NaN (not a derivative:
    friction's rows are not there)."""
    tree, laws, scene = _stop_leg()
    g = gradients["stop"]
    assert g.scene_names == scene_names(tree) == ("friction", "speed", "restitution", "shank.stop_restitution",
                                                  "toe.stop_restitution", "heel.stop_restitution")
    assert np.array_equal(g.scene_theta, scene_theta(tree, scene, laws)) and list(g.scene_theta) == [0.0, 2.0, 0.3, 0.3, 0.0, 0.0]
    J = _jacobian_of(g.scene_jacobian)
    assert np.all(np.isnan(J[:, 0])) and np.all(J[:, 4:] == 0) and np.all(np.isfinite(J[:, 1:]))
    assert np.all(np.isfinite(_jacobian_of(gradients["friction"].scene_jacobian)))
    assert g.jacobian["final_angles"].shape == (len(g.values["final_angles"]), len(g.theta))  # theta's as before


def _jacobian_of(jacobian: dict) -> np.ndarray:
    return np.vstack([jacobian[k] for k in SCALARS] + [jacobian["total_external"], jacobian["final_angles"]])


def test_one_structure_serves_every_positive_friction():
    """mu is a symbol of the operations, not built in: landings at two positive frictions share
    their symbolic structure, and the replay at the second is still its landing."""
    from impulse_core.timedomain.landing_derivatives import _symbolic

    tree, laws, scene = _case("friction")
    other = replace(scene, friction=0.98)
    assert _symbolic(taped_run(tree, scene, laws, STEP)[2], laws) is _symbolic(taped_run(tree, other, laws, STEP)[2], laws)
    assert_replay_is_the_landing(landing_gradient(tree, other, laws, step=STEP))


def test_the_taped_run_keeps_the_balance_share_of_its_tolerance():
    """The derivatives' run (:func:`taped_run`) asks its steps the momentum balance's share that
    :func:`landing` gives its first run at the settings' tolerance (:func:`balance_share`): random
    file 70000 (spatial; its steps split by the balance) at tolerance 1e-5 is the run at share
    1e-2 to the bit, not the one at the default's share, whose steps split otherwise."""
    import pickle
    from pathlib import Path

    from impulse_core.timedomain.events.run import _Landing
    from impulse_core.timedomain.events.settings import balance_share
    from optimizer.config.model_file import load_model_file

    m = load_model_file(Path(__file__).parent / "data" / "random_70000.yaml")
    settings, h = LandingSettings(tolerance=1e-5), 2e-3
    taped, _, _ = taped_run(m.tree, m.scene, m.joints, h, settings, m.space)

    def run(share: float):
        return _Landing(m.tree, m.scene, m.joints, settings, m.space).run(h, share=share)

    assert balance_share(1e-5) == pytest.approx(1e-2)
    same, default = run(balance_share(1e-5)), run(1.0)
    assert pickle.dumps(taped) == pickle.dumps(same)
    assert taped.n_steps != default.n_steps
