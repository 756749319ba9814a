"""Whole landings found wrong by a random sweep of model files: ``contacts: all`` (contacts above
the ground hit at t = 0 by the paper's assumption), redundant contacts (the split of the impulse
is not unique), and a stiff joint that passes its stop and turns back within one step."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from impulse_core.evaluate import evaluate
from impulse_core.impact.laws import ImpactModel
import impulse_core.timedomain.events.run as events_run
from impulse_core.kinematics.spatial import PLANAR, SPATIAL
from impulse_core.model.joints import FREE, JointLaw
from impulse_core.model.tree import Body, ContactSelection, JointKind, Scene, Tree
from impulse_core.timedomain.events.run import _Landing
from impulse_core.timedomain.landing import LandingSettings, landing

SETTINGS = LandingSettings(step=1e-3)


@pytest.mark.parametrize("space", [PLANAR, SPATIAL], ids=["planar", "spatial"])
def test_a_contact_above_the_ground_hits_at_t0_and_then_flies_free(space):
    """A tilted rod with ``contacts: all``: its upper contact takes its share of the first impact
    (the lcp rung's answer) and is then in the air, not held at its height: the momentum balance
    holds (a contact kept closed 4 cm above the ground was projected down onto it, 2e-2), and it
    touches down later by itself."""
    rod = Tree((Body("rod", None, 0.4, 0.5, -0.3, contacts=(0.5, 1.0)),))
    scene = Scene(speed=0.6, velocity_x=0.8, restitution=0.0, selection=ContactSelection.ALL, gravity=9.81,
                  duration=0.2)
    r = landing(rod, scene, (), SETTINGS, space)
    first = evaluate(rod, scene, ImpactModel.LCP, space)
    assert np.max(np.abs(r.events[0].external - first.external)) <= 1e-9 * np.max(first.external)
    assert r.momentum_balance <= 1e-6
    later = [e for e in r.events[1:] if e.external[0] > 0]
    assert later and later[0].time > 0.01  # the upper contact (0.5) lands on its own, later


def test_redundant_frictionless_contacts_take_the_lcp_rungs_split():
    """Two rods welded into one body with four contacts in a row on the ground (a plank: three
    base DOFs, four rows): Newton's law fixes the velocity after, not the split; the landing's
    first event takes the lcp rung's smallest-norm non-negative split and counts the impact as
    non-unique."""
    plank = Tree((
        Body("a", None, 0.3, 1.0, 0.0, contacts=(0.0, 1.0)),
        Body("b", 0, 0.2, 0.7, 0.0, joint=JointKind.FIXED, contacts=(0.5, 1.0)),
    ))
    scene = Scene(speed=2.0, restitution=0.5, angular_velocity=1.5, selection=ContactSelection.ALL, gravity=9.81,
                  duration=0.05)
    r = landing(plank, scene, (), SETTINGS)
    first = evaluate(plank, scene, ImpactModel.LCP)
    assert not first.split_unique
    assert np.max(np.abs(r.events[0].external - first.external)) <= 1e-9 * np.max(first.external)
    assert r.non_unique >= 1
    assert math.isclose(np.sum(r.events[0].external), np.sum(first.external), rel_tol=1e-12)


def test_a_stop_passed_and_left_within_one_step_is_an_event():
    """A light stiff joint between close stops and an elastic contact: the spring turns the joint
    back within one step, so the step's end is inside the stops; the crossing must still be
    located (the step's cubic fit, and a witness negative at the located instant). Missed, the
    joint sat 4e-5 rad past its stop until the next touchdown's projection moved it back
    (momentum balance 2.3e-4 > the contract's 1e-4) and the event count grew as the step shrank
    (453, 979, 1639 at 1, 0.5, 0.25 ms); located, it converges (78 events at every step)."""
    tree = Tree((
        Body("b0", None, 0.2124, 1.165, -0.1229, contacts=(0.0,)),
        Body("b1", 0, 0.2857, 2.982, -0.0596, gyration=0.2695),
    ))
    laws = (FREE, JointLaw(stiffness=134.8, damping=0.02406, limits=(-0.1484, -0.04115)))
    scene = Scene(speed=1.9218, restitution=1.0, gravity=9.81, duration=0.2)
    runs = []
    for h in (1e-3, 5e-4):
        run = _Landing(tree, scene, laws, LandingSettings(), PLANAR)
        r = run.run(h)
        q = r.trajectory[1]
        assert np.max(q[:, 3]) <= laws[1].limits[1] + 1e-9 and np.min(q[:, 3]) >= laws[1].limits[0] - 1e-9
        assert r.momentum_balance <= 1e-6
        runs.append(r)
    assert [e.kind for e in runs[0].events] == [e.kind for e in runs[1].events]
    assert sum(e.kind == "stop" for e in runs[0].events) >= 10


def test_a_step_whose_joint_passes_its_stop_and_returns_is_a_graze():
    """The step's cubic (Hermite) fit of a free joint's angle, from its ends' angles and rates:
    inside the stops at both ends, moving in, then out, past the upper stop in between: the
    step is cut there (as for a contact's gap that dips and comes back)."""
    tree = Tree((Body("b0", None, 0.2, 1.0, -0.1, contacts=(0.0,)), Body("b1", 0, 0.3, 2.0, -0.06)))
    laws = (FREE, JointLaw(stiffness=100.0, limits=(-0.15, -0.04)))
    run = _Landing(tree, Scene(speed=1.0, gravity=9.81, duration=0.1), laws, LandingSettings(), PLANAR)
    free = run.first_impact()[2]
    free.closed[:] = False
    free.stop[:] = 0
    q0 = run.q0 + np.array([0.0, 1.0, 0.0, 0.0])  # a metre up: no contact near the ground
    q0[3] = -0.04 - 1e-4
    q1, v0, v1 = q0.copy(), np.array([0.0, 0.0, 0.0, 1.0]), np.array([0.0, 0.0, 0.0, -1.0])
    fraction = run.grazing(q0, v0, q1, v1, free, 1e-3)  # peak 1.5e-4 rad past the stop, mid-step
    assert fraction is not None and 0 < fraction < 0.5  # the first sample past the stop
    assert run.grazing(q0, v0, q1, -v1, free, 1e-3) is None  # moving in and on out: the step's end sees it


def test_a_run_that_overruns_its_step_budget_is_retried_at_half_the_step(monkeypatch):
    """A run whose steps the momentum balance splits beyond the budget (a light rod spinning
    fast) is a step too long, as a diverging one: ``landing`` halves it and answers (it raised).
    Here the budget is lowered to 1 x T / h so that the first step (2 ms, 111 steps) overruns."""
    tree = Tree((Body("b0", None, 0.2124, 1.165, -0.1229, contacts=(0.0,)),
                 Body("b1", 0, 0.2857, 2.982, -0.0596, gyration=0.2695)))
    laws = (FREE, JointLaw(stiffness=134.8, damping=0.02406, limits=(-0.1484, -0.04115)))
    scene = Scene(speed=1.9218, restitution=1.0, gravity=9.81, duration=0.2)
    first = _Landing(tree, scene, laws, LandingSettings(), PLANAR).first_step()
    monkeypatch.setattr(events_run, "STEP_BUDGET", 1.0)  # where the run loop reads it
    r = landing(tree, scene, laws, LandingSettings(), PLANAR)
    assert r.step <= first / 4 and r.n_steps <= r.duration / r.step


TIP_ON_NEXT_ROOT = Path(__file__).resolve().parent / "data" / "tip_on_next_root.yaml"


def test_a_contact_at_its_twins_point_rests_and_does_not_touch_down_again(monkeypatch):
    """A random spatial leg (data/tip_on_next_root.yaml, the sweep's f25) whose rod's tip contact
    sits on the next rod's root contact: once both rest there, the contact LCP loads either one
    and leaves the other unloaded, not pulling away. Opened, the unloaded one touched down again
    at the loaded one's drift (one gap tolerance) microseconds later with an impulse of rounding:
    685 touchdowns in 0.05 s, 15 in 8 ms here. It rests on (a plastic touchdown rests from then
    on): the landing has the real touchdowns only and obeys the laws (first event the friction
    rung's, impulses >= 0 inside the cone, the momentum balance)."""
    from optimizer.config.model_file import load_model_file

    model = load_model_file(TIP_ON_NEXT_ROOT)
    scene = replace(model.scene, duration=0.008)
    step = 2.5e-4  # the run's first step at the file's 0.05 s, where the chatter was found
    r = _Landing(model.tree, scene, model.joints, LandingSettings(max_events=300), model.space).run(step)
    assert len(r.events) <= 8
    assert all(e.kind == "touchdown" and e.external.sum() > 1e-9 for e in r.events)
    first = evaluate(model.tree, scene, ImpactModel.FRICTION, model.space)  # the twins' split is not unique
    assert r.events[0].external.sum() == pytest.approx(first.external.sum(), rel=1e-9)
    assert np.sum(r.events[0].tangential, axis=0) == pytest.approx(np.sum(first.tangential, axis=0), rel=1e-9, abs=1e-12)
    for e in r.events:
        assert np.all(e.external >= -1e-12 * e.external.max())  # the cone solver's rounding: -1e-32
        assert np.all(np.linalg.norm(e.tangential, axis=1) <= scene.friction * e.external + 1e-12)
    assert r.momentum_balance <= 1e-5


def test_twin_contacts_share_the_impact_alike_in_the_landing_and_the_friction_rung():
    """The same leg's touchdown: b3's tip and b4's root are one point of one motion (twins), so
    only their sum is defined; both the landing's first event and the friction rung give each
    twin half (the smallest-norm split, inside the cone), so the two agree contact by contact and
    joint by joint (1e-9), not only in sum (their solvers reached different splits)."""
    from optimizer.config.model_file import load_model_file

    model = load_model_file(TIP_ON_NEXT_ROOT)
    scene = replace(model.scene, duration=0.001)
    e = _Landing(model.tree, scene, model.joints, LandingSettings(), model.space).run(2.5e-4).events[0]
    first = evaluate(model.tree, scene, ImpactModel.FRICTION, model.space)
    assert not first.split_unique
    scale = np.max(first.external)
    assert np.max(np.abs(e.external - first.external)) <= 1e-9 * scale
    assert np.max(np.abs(e.tangential - first.tangential)) <= 1e-9 * scale
    assert np.max(np.abs(e.internal_magnitude - first.internal_magnitude)) <= 1e-9 * np.max(first.internal_magnitude)
    assert first.external[3] == pytest.approx(first.external[4], rel=1e-12) and first.external[3] > 0.1 * scale
    assert np.linalg.norm(first.tangential[3]) <= scene.friction * first.external[3] * (1 + 1e-9)


def test_twin_contacts_reaching_the_cone_beside_a_sliding_one_slide_too():
    """Random file 20656 (data/edge_twins_20656.yaml: two contacts at one point, on two rods
    hinged at the tip of a third, and a third contact on one of them; friction 0.3). At 0.0181
    s the acceleration LCP puts all three on the cone's edge with no slip acceleration; the third
    slid, which moved its friction onto the twins, and they stuck a rounding outside the cone:
    the run stalled ("chatters"). Contacts reaching the edge now slide until none does, and
    the landing goes on past that instant with its momentum balance."""
    from optimizer.config.model_file import load_model_file

    model = load_model_file(Path(__file__).parent / "data" / "edge_twins_20656.yaml")
    run = _Landing(model.tree, replace(model.scene, duration=0.025), model.joints, LandingSettings(), model.space)
    r = run.run(run.first_step())
    assert r.duration == pytest.approx(0.025) and r.momentum_balance < 1e-4  # a stall raises NumericalError


def test_an_impact_budget_passed_names_the_contact_or_stop_and_an_elastic_one():
    """Past ``max_events`` the run stops naming who took the last impacts; where that contact or
    stop has restitution 1 it says an elastic one pressed down bounces without end (random file
    20144 bounced at e = 1 ever faster, 20000 impacts by 18 ms). A flat rod bouncing on both
    ends at e = 1, and a sprung joint pressed onto its stop at stop restitution 1."""
    from impulse_core.errors import NumericalError

    flat = Tree((Body("plank", None, 0.1, 1.0, 0.0, contacts=(0.0, 1.0)),))
    scene = Scene(speed=0.01, restitution=1.0, gravity=9.81, duration=1.0)
    with pytest.raises(NumericalError, match=r"more than 20 impacts .*: contact plank\[0\] took 21 of the last 21 "
                                             r"at restitution 1 \(.*lower scene\.restitution\)"):
        _Landing(flat, scene, (), LandingSettings(max_events=20), PLANAR).run(1e-3)
    leg = Tree((Body("plank", None, 0.1, 1.0, 0.0, contacts=(0.0, 1.0)), Body("flap", 0, 0.05, 0.1, 0.5)))
    laws = (FREE, JointLaw(stiffness=5.0, rest=0.8, limits=(-0.5, 0.5), stop_restitution=1.0))
    with pytest.raises(NumericalError, match=r"the stop of flap took \d+ of the last 21 at restitution 1 "
                                             r"\(.*lower flap\.stop_restitution\)"):
        _Landing(leg, replace(scene, restitution=0.0), laws, LandingSettings(max_events=20), PLANAR).run(1e-3)
    with pytest.raises(NumericalError, match=r"took \d+ of the last 21$"):  # e < 1: no advice
        inelastic = (FREE, replace(laws[1], stop_restitution=0.99))
        _Landing(leg, replace(scene, restitution=0.0), inelastic, LandingSettings(max_events=20), PLANAR).run(1e-3)


def test_the_joint_laws_rate_is_the_generalized_eigenvalue_and_survives_a_massless_direction():
    """joint_law_rate: the largest eigenvalue of M^-1 D, or the square root of M^-1 K's
    (scipy's generalized symmetric eigenproblem as the reference, a random 4 x 4 M). Where a
    massless direction's eigenvalue rounds below 0 (random file 60603: the Cholesky factor
    failed, exit 1 "Matrix is not positive definite"), the rate is that of M with the eigenvalue
    floored at eps x the largest: huge, finite."""
    import scipy.linalg

    from impulse_core.timedomain.landing import joint_law_rate

    rng = np.random.default_rng(3)
    R = np.linalg.qr(rng.standard_normal((4, 4)))[0]
    damping, stiffness = np.array([0.0, 0.5, 0.2, 1.0]), np.array([3.0, 0.0, 7.0, 1.0])
    M = R @ np.diag([2.0, 1.0, 0.3, 0.05]) @ R.T
    top_d = scipy.linalg.eigh(np.diag(damping), M, eigvals_only=True)[-1]
    top_k = scipy.linalg.eigh(np.diag(stiffness), M, eigvals_only=True)[-1]
    assert joint_law_rate(M, damping, stiffness) == pytest.approx(max(top_d, np.sqrt(top_k)), rel=1e-9)
    massless = R @ np.diag([2.0, 1.0, 0.3, -1e-13]) @ R.T  # below 0: the floor, eps x 2, sets the rate
    with pytest.raises(np.linalg.LinAlgError):
        np.linalg.cholesky(massless)
    rate = joint_law_rate(massless, damping, stiffness)
    assert np.isfinite(rate) and rate > 1e12


def test_an_undamped_spring_wound_along_a_massless_direction_is_refused():
    """Random file 60603 (data/swinging_60603.yaml): the base b0 is a rod of radius 0 and b1's joint
    turns about b0's axis, its spring (no damper) 0.18 rad from its rest. b0 spinning with b1's
    joint turning back moves no mass, and with a radius r the spring swings that spin at a rate
    ~ 1 / r, keeping its 0.1 J: b1's angle at T was 1.151 rad at r = 3 mm, 1.412 at 1 mm, the rest
    of the landing alike to 1e-4. At radius 0 the landing is no such limit (it diverged after 15 s,
    Radau IIA's Newton iterations failing from h down to 1e-10 s): refused at once, naming the
    joint. With a damper on it, its spring at its balance, or a radius, the leg is taken."""
    from impulse_core.errors import ModelError
    from optimizer.config.model_file import load_model_file

    model = load_model_file(Path(__file__).resolve().parent / "data" / "swinging_60603.yaml")
    tree, joints = model.tree, model.joints

    def build(tree: Tree = tree, joints: tuple[JointLaw, ...] = joints) -> _Landing:
        return _Landing(tree, model.scene, joints, LandingSettings(), model.space)

    with pytest.raises(ModelError, match=r"^model\.bodies\[1\]\.stiffness: b1's spring .* starts 0\.176 rad from "
                       r"its balance along it \(0\.0996 J\).* give the rod a radius \(the rods of radius 0: b0\) "
                       r"or damp the joint$"):
        build()
    for law in (replace(joints[1], damping=0.05), replace(joints[1], rest=tree.bodies[1].angle)):
        build(joints=joints[:1] + (law,) + joints[2:])
    build(Tree((replace(tree.bodies[0], radius=1e-3),) + tuple(tree.bodies[1:])))


@pytest.mark.parametrize("space", ["planar", "spatial"])
def test_a_position_correction_moves_no_momentum(space):
    """The projection after a step or event corrects positions at fixed generalized velocity, which
    would change the linear momentum (rotating bodies' centres move) with no impulse to count
    (random file 60624: 348 corrections moved 1.1e-4 of its momentum, above the contract's balance).
    The correction's momentum is given back through the base's translation before the velocity
    projection: with no rows to project on (a flight with contacts 1 mm below the ground), the
    momentum after equals the momentum before to rounding, where the correction alone moves it by
    1e-5 or more; with resting contacts (gaps of 1e-6 m off), the compiled projection gives numpy's
    answer (random leg, random velocity)."""
    from impulse_core.timedomain.events.run import _Landing
    from impulse_core.timedomain.landing import NUMPY_CODE, VM_CODE, LandingSettings
    from tests.impulse_core.test_landing import _random_leg
    from tests.impulse_core.test_landing_spatial import _splayed_leg

    tree, laws, scene = _random_leg(4) if space == "planar" else _splayed_leg(2)
    where = PLANAR if space == "planar" else SPATIAL
    runs = {code: _Landing(tree, scene, laws, LandingSettings(step_code=code), where) for code in (NUMPY_CODE, VM_CODE)}
    ref = runs[NUMPY_CODE]
    rng = np.random.default_rng(7)
    q, v = ref.q0.copy(), rng.standard_normal(ref.nv)
    q[1] -= 1e-3  # the base lowered: the touching contacts 1 mm below the ground
    momentum = ref.point(q, v).momentum[:, 0].copy()
    q1, v1, p = ref.placed(q, v, ref.flight())
    assert np.abs(ref.point(q1, v).momentum[:, 0] - momentum).max() > 1e-5 * np.abs(momentum).max()
    assert not p.any() and np.abs(ref.point(q1, v1).momentum[:, 0] - momentum).max() <= 1e-13 * np.abs(momentum).max()
    q[1] += 1e-3 - 1e-6 * rng.uniform(-1.0, 1.0)  # resting contacts off by up to 1e-6 m
    mode = ref.flight()
    mode.closed[:] = np.abs(ref.point(q, v).gap) < 1e-5
    assert mode.closed.any()
    numpy_answer = np.concatenate(ref.placed(q, v, mode))
    compiled = np.concatenate(runs[VM_CODE].fast.project(q, v, mode))
    assert np.abs(compiled - numpy_answer).max() <= 1e-11 * np.abs(numpy_answer).max()
