"""The landing's impulsive jam (``_Landing.jam``): Painleve's paradox resolved by an impact
without collision.

- The classic Painleve rod (a uniform rod of mass m and length 2 l on its tip, at theta to the
  ground, the tip sliding away from under its centre at speed V; critical friction 4/3), by hand:
  the contact's Delassus matrix in (n, t) is W = (1/m) [[1 + 3 c^2, -3 s c], [-3 s c, 1 + 3 s^2]]
  (s = sin theta, c = cos theta; inertia m l^2 / 3), so A = n M^-1 (n - mu u t)^T = (1 + 3 c^2 -
  3 mu s c) / m with u = -1, negative above mu = (1 + 3 c^2) / (3 s c). The jam's sliding phase
  (Darboux-Keller along the cone's edge) stops the slip at the normal impulse p = m V / (mu (1 +
  3 s^2) - 3 s c), compressing the contact to A p < 0; the plastic phase then sticks it. In all the
  impulse that stops the tip, -W^-1 (0, -V): P_n = (3 m / 4) s c V, P_t = (m / 4) (1 + 3 c^2) V,
  inside the cone exactly when A < 0 (the h -> 0 limit of velocity-level time stepping). In
  space (the same rod read as spatial, and with a slip out of the plane) the slip's direction
  turns during the sliding phase, and the total is again the impulse that stops the tip.
- Random files that stopped with Painleve's paradox now land through a jam, obeying the laws:
  data/painleve_20120.yaml (spatial: events stalled with the contact problem unsolvable) and
  data/jam_40029.yaml (planar terrain: A fell to 0 while pressed, the force without bound, test
  in test_landing_terrain.py).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from impulse_core.kinematics.spatial import PLANAR, SPATIAL
from impulse_core.model.joints import FREE
from impulse_core.model.tree import Body, Scene, Tree
from impulse_core.timedomain.events.paradox import darboux_keller_slide
from impulse_core.timedomain.events.rows import _Mode
from impulse_core.timedomain.events.run import _Landing
from impulse_core.timedomain.landing import LandingSettings
from tests.impulse_core.test_landing_spatial import _assert_event_laws, _momentum_error, _rates

G = 9.81
THETA = math.radians(60.0)  # the rod's angle to the ground
MU = 2.0  # above the critical (1 + 3 c^2) / (3 s c) = 1.347 at 60 degrees
V = 1.3  # the tip's slip speed, away from under the centre (-x)


def _rod(space, mu: float = MU) -> _Landing:
    """A uniform 1 kg, 1 m rod (l = 0.5 m) whose tip (its far end) rests on the ground at THETA,
    the centre above and to the right of the tip."""
    gyration = {} if space is PLANAR else {"radius": 0.01, "gyration": math.sqrt(1.0 / 12.0)}
    rod = Body("rod", None, 1.0, 1.0, math.pi + THETA, contacts=(1.0,), **gyration)
    scene = Scene(speed=1.0, restitution=0.0, friction=mu, gravity=G, duration=0.05)
    return _Landing(Tree((rod,)), scene, (FREE,), LandingSettings(), space)


def _sliding(run: _Landing, tip_velocity: np.ndarray) -> tuple[np.ndarray, np.ndarray, _Mode]:
    """(q, v, mode) at touchdown with the rod translating at ``tip_velocity`` (world, along the
    ground), its tip closed and sliding along it."""
    q, v = run.q0.copy(), np.zeros(run.nv)
    v[: len(tip_velocity)] = tip_velocity
    slip = run.point(q, v).slip[0]
    mode = _Mode(np.array([True]), (slip / np.linalg.norm(slip))[None, :], np.zeros(run.nv, int))
    return q, v, mode


def _stopping_impulse(run: _Landing, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """-W^-1 (J v): the tip's impulse (normal, tangents) that stops it, W = J M^-1 J^T."""
    pt = run.point(q, v)
    J = np.vstack([pt.Jn[:1], pt.Jt[0]])
    return -np.linalg.solve(J @ np.linalg.solve(pt.M, J.T), J @ v)


def test_the_painleve_rod_jams_to_the_hand_derived_impulse():
    run = _rod(PLANAR)
    q, v, mode = _sliding(run, np.array([-V, 0.0]))
    s, c, m = math.sin(THETA), math.cos(THETA), 1.0
    assert run.sliding_jams(q, v, mode).tolist() == [0]  # A < 0
    # the sliding phase alone: p = m V / (mu (1 + 3 s^2) - 3 s c), along the edge, tangential +mu p
    pt = run.point(q, v)
    J = np.vstack([pt.Jn[:1], pt.Jt[0]])
    W = J @ np.linalg.solve(pt.M, J.T)
    assert W == pytest.approx(np.array([[1 + 3 * c**2, -3 * s * c], [-3 * s * c, 1 + 3 * s**2]]) / m, rel=1e-12)
    p, p_t = darboux_keller_slide(W, pt.slip[0], MU)
    assert p == pytest.approx(m * V / (MU * (1 + 3 * s**2) - 3 * s * c), rel=1e-12)
    assert p_t == pytest.approx([MU * p], rel=1e-12)  # against the slip (-x): along +x
    A = (1 + 3 * c**2 - 3 * MU * s * c) / m
    assert (W @ [p, p_t[0]])[0] == pytest.approx(A * p, rel=1e-12) and A < 0  # compressed
    # the whole jam: the impulse that stops the tip, inside the cone
    v_plus, event, new = run.jam(q, v, mode, 0.0, 0)
    assert event.jam and event.kind == "touchdown"
    assert event.external[0] == pytest.approx(0.75 * m * s * c * V, rel=1e-12)
    assert event.tangential[0] == pytest.approx(0.25 * m * (1 + 3 * c**2) * V, rel=1e-12)
    assert abs(event.tangential[0]) < MU * event.external[0]
    after = run.point(q, v_plus)
    assert abs(after.vn(v_plus)[0]) <= 1e-12 and abs(after.slip[0, 0]) <= 1e-12  # it sticks
    assert new.closed[0] and not new.sliding[0]
    # momentum: the centre's velocity changes by the contact impulse / m
    change = after.momentum[:, 0] - pt.momentum[:, 0]
    assert change == pytest.approx([event.tangential[0], event.external[0]], abs=1e-12)
    assert event.energy_after < event.energy_before


def test_below_the_critical_friction_the_rod_does_not_jam():
    run = _rod(PLANAR, mu=1.2)  # A = (1.75 - 3.6 x 0.433) / m = 0.19 / m > 0
    q, v, mode = _sliding(run, np.array([-V, 0.0]))
    assert run.sliding_jams(q, v, mode).size == 0
    q, v, mode = _sliding(_rod(PLANAR), np.array([V, 0.0]))  # sliding towards the centre: A > 0
    assert _rod(PLANAR).sliding_jams(q, v, mode).size == 0


@pytest.mark.parametrize("lateral", [0.0, 0.6])
def test_the_painleve_rod_in_space_jams_to_the_impulse_that_stops_its_tip(lateral):
    """The sliding phase in space (RK4 in the normal impulse, the slip's direction turning where
    it has a lateral part): in the plane the hand answer; with the lateral slip the total is the
    impulse that stops the tip, -W^-1 (J v), and it lies inside the circular cone."""
    run = _rod(SPATIAL)
    q, v, mode = _sliding(run, np.array([-V, 0.0, lateral]))
    assert run.sliding_jams(q, v, mode).tolist() == [0]
    v_plus, event, new = run.jam(q, v, mode, 0.0, 0)
    stop = _stopping_impulse(run, q, v)
    assert event.external[0] == pytest.approx(stop[0], rel=1e-9)
    assert event.tangential[0] == pytest.approx(stop[1:], rel=1e-9, abs=1e-12)
    assert np.linalg.norm(event.tangential[0]) < MU * event.external[0]
    if lateral == 0.0:
        s, c = math.sin(THETA), math.cos(THETA)
        assert event.external[0] == pytest.approx(0.75 * s * c * V, rel=1e-9)
        assert event.tangential[0] == pytest.approx([0.25 * (1 + 3 * c**2) * V, 0.0], rel=1e-9, abs=1e-12)
    after = run.point(q, v_plus)
    assert np.max(np.abs([after.vn(v_plus)[0], *after.slip[0]])) <= 1e-9 * V
    assert new.closed[0] and not new.sliding[0]


def _data_model(name: str):
    from optimizer.config.model_file import load_model_file

    return load_model_file(Path(__file__).parent / "data" / name)


def jam_spied_run(model) -> tuple[_Landing, object, list]:
    """``model``'s landing run at its first step, and each jam taken: (q, v, contact, the jam's
    (v_plus, event, mode))."""
    run = _Landing(model.tree, model.scene, model.joints, LandingSettings(), model.space)
    jams: list = []
    jam = run.jam

    def spy(q, v, mode, t, contact):
        out = jam(q, v, mode, t, contact)
        jams.append((q, v, contact, out))
        return out

    run.jam = spy
    return run, run.run(run.first_step()), jams


def test_a_stalled_painleve_slide_lands_through_a_jam():
    """Random file 20120 (data/painleve_20120.yaml; spatial, friction 1): at 0.1086 s a light
    rod's tip slides where A < 0 and gravity presses it; the events stalled and the run stopped
    with Painleve's paradox. Now the tip jams there (one event, kind "touchdown", ``jam``): every
    event obeys the laws (impulse in the cone, pushing, Newton at e = 0, no energy gained), the
    jammed tip leaves it at rest along the normal, and the linear momentum changes by the counted impulses (the
    jam's included) minus the weight's. Where the tip jams is the run's: at its first step h, 0.108687 s with the
    slow slip's steps split (``slip_splits``, the default), 0.108629 s regularised (slip_splits 0); the runs at
    h / 2, h / 4, h / 8 jam there again and again, either way (the stall's times are the step's)."""
    model = _data_model("painleve_20120.yaml")
    run, r, jams = jam_spied_run(model)
    assert [e.time for e in r.events if e.jam] == [pytest.approx(0.108687, abs=1e-6)]
    assert len(jams) == 1
    q, v, contact, (v_plus, event, _) = jams[0]
    assert contact == 0 and event.external[0] > 0
    # the sliding phase ended with the compression (the slip turned until A > 0): the tip leaves
    # it at rest along the normal (Newton at e = 0: complementary), slower along the ground
    before, after = run.point(q, v).slip[contact], run.point(q, v_plus).slip[contact]
    assert abs(run.point(q, v_plus).vn(v_plus)[contact]) <= 1e-12
    assert np.linalg.norm(after) < 0.2 * np.linalg.norm(before)
    _assert_event_laws(run, r, model.scene)
    assert _momentum_error(run, r, model.scene) <= 1e-5
    assert r.momentum_balance <= 1e-5
    assert r.inexact == 0
    e = next(e for e in r.events if e.jam)
    assert np.all(_rates(q, e.v_plus) == pytest.approx(v_plus, abs=1e-12))
