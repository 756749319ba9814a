"""The whole landing on a planar ``scene.terrain`` where a resting contact passes a breakpoint.

Beyond a breakpoint the ground's normal is the next segment's. A contact that slides into a
valley meets the far slope moving into it (an impact, with the file's restitution); one that
slides off a ledge or over a ridge finds the ground falling away and flies. The landing locates
the crossing and handles it as an event (``_Landing.vertex_crossing``). Before, the step went on
past the breakpoint and the projection put the contact back onto the next segment: the valley's
impact plastic and unreported, the ledge's a pull (a negative normal impulse) that held the
contact down on the slope.

- data/ridge_valley.yaml (hand-made, a puck that does not turn): the laws by hand: it leaves the
  ledge at x = -0.2 and lands on the slope after the parabola's flight; the impact at the
  valley's breakpoint meets Newton's restitution along the far slope's normal and keeps the
  velocity along it; the kinetic energy changes only by gravity's work and the events' losses;
  no penetration; the first event is the lcp rung's; the momentum balance.
- data/ridge_40056.yaml (random file, two contacts on a sprung leg): no projection pulls (-1.1
  N s before) and the contract's checks (first event, momentum balance, no penetration).
- data/jam_40029.yaml (random file, friction 0.3): not at a breakpoint; a sliding tip reaches
  Painleve's paradox and jams (an impulsive jam: ``_Landing.jam``).
- studies/whole_landing/terrain_valley_rest.yaml (hand-made, shortened): a puck rocking across a
  valley's breakpoint at restitution 0 comes to rest in the corner, held by both slopes' rows
  (frictionless and at friction 0.1): at x = 0, velocity 0, settled; the weight is the two rows'
  forces summed along their own normals; the energy leaves at events only. A corner whose row
  would pull is released, and so is one that an impact sends up a slope.
- data/crease_valley_puck.yaml (hand-made, spatial): a puck held by gravity in a heightfield's
  valley crease at restitution 0.9, where the position projections after the steps carry it
  across the crease: each such projection takes the rows of the cell it places the contact on
  (the contact leaves it at rest on that cell) and its impulse is booked along them (the
  momentum balance to rounding; random file 32843).
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from impulse_core.impact.laws import ImpactModel
from impulse_core.timedomain.first_instant import first_instant
from impulse_core.timedomain.events.run import _Landing
from impulse_core.timedomain.landing import LandingSettings, landing

DATA = Path(__file__).resolve().parent / "data"
G = 9.81


def _model(name: str):
    from optimizer.config.model_file import load_model_file

    return load_model_file(DATA / name)


def _run(model, pulls: list | None = None):
    """The landing of ``model`` at its first step; ``pulls`` collects every projection's normal
    impulses (the resting contacts' share of each step's impulse that the projection adds)."""
    run = _Landing(model.tree, model.scene, model.joints, LandingSettings(), model.space)
    if pulls is not None:
        project = run.project

        def spy(q, v, mode):
            q1, v1, p = project(q, v, mode)
            pulls.append(p[: run.nc].copy())
            return q1, v1, p

        run.project = spy
    return run, run.run(run.first_step())


def _common_laws(model, run: _Landing, r) -> None:
    """The contract's checks: the first event the lcp rung's (1e-9), the momentum balance (1e-4),
    no contact below the ground at any step's end or event (1e-9 m)."""
    first = first_instant(model.tree, model.scene, ImpactModel.LCP, model.space)  # --model lcp on uneven ground
    scale = np.max(first.external)
    assert np.max(np.abs(r.events[0].external - first.external)) <= 1e-9 * scale
    assert r.momentum_balance <= 1e-4
    times, states = r.trajectory
    gaps = np.array([run.point(q, np.zeros(run.nv)).gap for q in states])
    assert gaps.min() >= -1e-9


def test_a_puck_flies_off_the_ledge_and_bounces_in_the_valley():
    model = _model("ridge_valley.yaml")
    pulls: list = []
    run, r = _run(model, pulls)
    _common_laws(model, run, r)
    e, m = model.scene.restitution, 0.5
    assert len(r.events) >= 3  # the first touchdown, the slope's after the ledge, the valley's (1 before)
    # plastic on the flat top, it slides at 1.2 m/s to the ledge (x = -0.25 -> -0.2) and leaves it
    # horizontally; the parabola meets the slope of 1/4 after 2 v / (4 g)
    assert np.allclose(r.events[0].v_plus[:2], [1.2, 0.0], atol=1e-12)
    ledge = 0.05 / 1.2
    flight = 2 * 1.2 * 0.25 / G
    assert r.events[1].time == pytest.approx(ledge + flight, rel=1e-9)
    assert np.allclose(r.events[1].v_minus[:2], [1.2, -G * flight], rtol=1e-9)
    times, states = r.trajectory
    flying = (times > ledge + 1e-3) & (times < ledge + flight - 1e-3)
    assert flying.any() and all(run.point(q, np.zeros(run.nv)).gap[0] > 1e-5 for q in states[flying])
    # the impact at the valley's breakpoint (x = 0): along the far slope's normal, Newton's
    # restitution; along its tangent, the velocity kept (frictionless); the puck does not turn
    n = np.array([-0.05, 0.2]) / math.hypot(0.05, 0.2)
    t = np.array([n[1], -n[0]])
    valley = []
    for ev in r.events[1:]:
        q = states[np.flatnonzero(times == ev.time)[-1]]
        if abs(run.point(q, np.zeros(run.nv)).contacts[0, 0]) <= 1e-9:
            valley.append(ev)
    assert len(valley) == 1
    v0, v1 = valley[0].v_minus[:2], valley[0].v_plus[:2]
    assert n @ v0 < -0.5
    assert n @ v1 == pytest.approx(-e * (n @ v0), rel=1e-9)
    assert t @ v1 == pytest.approx(t @ v0, rel=1e-9)
    assert valley[0].external[0] == pytest.approx(m * (1 + e) * -(n @ v0), rel=1e-9)
    assert np.all(np.abs([ev.v_plus[2] for ev in r.events]) <= 1e-12)
    # the energy leaves at the events only (no resting force works on a frictionless puck)
    lost = sum(ev.energy_before - ev.energy_after for ev in r.events[1:])
    assert r.energy_final - r.gravity_work == pytest.approx(r.events[0].energy_after - lost, rel=1e-6)
    assert min(p.min() for p in pulls) >= -1e-15  # no pull but rounding's (-1.5e-17 N s on AVX-512's kernels)


def test_a_contact_sliding_off_a_breakpoint_is_not_pulled_down():
    model = _model("ridge_40056.yaml")
    pulls: list = []
    run, r = _run(model, pulls)
    _common_laws(model, run, r)
    p0 = float(np.max(np.abs(run.point(run.q0, r.events[0].v_minus).momentum[:, 0])))
    # the projections' normal impulses: drift corrections (4e-8 of p0 here), no pull (-1.1 N s, 7.6e-2 of p0, before)
    assert min(p.min() for p in pulls) >= -1e-5 * p0
    full = landing(model.tree, model.scene, model.joints, LandingSettings(), model.space)
    assert full.momentum_balance <= 1e-4
    assert np.max(np.abs(full.events[0].external - r.events[0].external)) <= 1e-12 * np.max(r.events[0].external)


def test_the_derivatives_refuse_a_breakpoint_crossing():
    """The derivatives' replay has no witness for a breakpoint: it refuses such a landing (naming
    scene.terrain) rather than replaying the crossing's event as a step; the taped sequence names it."""
    from impulse_core.errors import NumericalError
    from impulse_core.timedomain.landing_derivatives import landing_gradient, sequence_signature, taped_run

    model = _model("ridge_valley.yaml")
    _, tape, run = taped_run(model.tree, model.scene, model.joints, 0.005)
    assert [s[2] for s in sequence_signature(tape, run) if s[0] == "vertex"] == [(0,)] * 3  # two ledges, the valley
    with pytest.raises(NumericalError, match="scene.terrain"):
        landing_gradient(model.tree, model.scene, model.joints, step=0.005)


def test_a_slide_into_painleves_paradox_lands_through_an_impulsive_jam():
    """Random file 40029 (data/jam_40029.yaml, friction 0.3): from 0.11 s b3's tip slides pressed
    down while its row's effective inverse mass with friction, A = n M^-1 (n - mu u t)^T, falls
    from 0.46 of its frictionless value to 0 at 0.1423 s, 0.25 m from any breakpoint; the force
    -B / A then grows without bound (74 N to 1e5-1e9 N within the last microsecond) and the run
    diverged there at every step, stopping with Painleve's paradox named. Now the run that
    diverged is repeated watching A, and the tip jams where A falls below JAM_WATCH of its
    frictionless value (one event, kind "touchdown", ``jam``): the impulse along the cone's edge
    (the dynamic jam's limit: the slide's force integrated until the slip stops), p = -s / (W_tn
    - mu u W_tt) by hand from the contact's Delassus matrix, after which the tip sticks; the
    contract's checks hold (first event, momentum balance, no penetration), the jam's impulse in
    the totals. With friction 0.2 the same file lands without a jam."""
    from tests.impulse_core.test_landing_jam import jam_spied_run

    model = _model("jam_40029.yaml")
    run, r, jams = jam_spied_run(model)
    first = first_instant(model.tree, model.scene, ImpactModel.FRICTION, model.space)  # --model friction
    assert np.max(np.abs(r.events[0].external - first.external)) <= 1e-9 * np.max(first.external)
    assert r.momentum_balance <= 1e-5
    times, states = r.trajectory
    assert min(run.point(q, np.zeros(run.nv)).gap.min() for q in states) >= -1e-9
    events = [e for e in r.events if e.jam]
    assert len(events) == len(jams) == 1 and events[0].kind == "touchdown"
    assert events[0].time == pytest.approx(0.1422, abs=1e-4)
    q, v, contact, (v_plus, event, mode) = jams[0]
    assert contact == 0 and mode.closed[0] and not mode.sliding[0]
    pt = run.point(q, v)
    J = np.vstack([pt.Jn[:1], pt.Jt[0]])
    W = J @ np.linalg.solve(pt.M, J.T)
    u = np.sign(pt.slip[0, 0])
    assert (W[0, 0] - 0.3 * u * W[0, 1]) / W[0, 0] < 1e-3  # A nearly 0 (JAM_WATCH)
    p = -pt.slip[0, 0] / (W[1, 0] - 0.3 * u * W[1, 1])
    assert event.external[0] == pytest.approx(p, rel=1e-6)
    assert event.tangential[0] == pytest.approx(-0.3 * u * p, rel=1e-6)  # on the cone's edge
    after = run.point(q, v_plus)
    assert abs(after.slip[0, 0]) <= 1e-9 and 0.0 <= after.vn(v_plus)[0] <= 1e-3 * abs(pt.slip[0, 0])
    # the totals hold the jam: the run's own momentum balance (above) and the impulse counted
    assert r.total_external[0] > event.external[0]
    calmer = replace(model.scene, friction=0.2)
    r = _Landing(model.tree, calmer, model.joints, LandingSettings(), model.space).run(run.first_step())
    assert not any(e.jam for e in r.events)


# ------------------------------------------------------------------------------------------
# A contact coming to rest in a valley's corner (studies/whole_landing/terrain_valley_rest.yaml)

VALLEY = Path(__file__).resolve().parents[2] / "studies" / "whole_landing" / "terrain_valley_rest.yaml"


def _valley(duration: float, **scene):
    """The valley file's puck, its landing shortened to ``duration`` (s) and ``scene`` replaced."""
    from dataclasses import replace

    model = _model(VALLEY)
    return replace(model, scene=replace(model.scene, duration=duration, **scene))


def _corner_run(model):
    """The landing at its first step, with the totals and time where a contact first rests in a
    corner (None: never), and each record's (t0, t1, mechanical energy at t1)."""
    run = _Landing(model.tree, model.scene, model.joints, LandingSettings(), model.space)
    entry: dict = {}
    energies: list = []
    record = run.record

    def spy_record(totals, t0, v0, t1, q1, v1):
        pt = run.point(q1, v1)
        energies.append((t0, t1, pt.kinetic + 0.5 * G * pt.contacts[0, 1]))  # the puck's mass 0.5, its contact at its centre
        record(totals, t0, v0, t1, q1, v1)

    def until(q, v, mode, totals):
        if "t" not in entry and mode.cornered.any():
            entry.update(t=totals.times[-1], impulse=totals.impulse.copy(), normal=totals.normal.copy(), totals=totals)
        return False

    run.record = spy_record
    r = run.run(run.first_step(), until=until)
    return run, r, entry, energies


def _in_the_corner(run: _Landing, r, T: float) -> None:
    """At rest at the breakpoint x = 0 (the contact), its velocity 0, settled, held in the corner."""
    q = r.q_final
    assert abs(run.point(q, np.zeros(run.nv)).contacts[0, 0]) <= 1e-12
    assert np.max(np.abs(r.v_final)) <= 1e-12
    assert r.settled_at is not None and r.settled_at < T
    assert list(run.seated) == [1]  # the valley's breakpoint


def test_a_puck_rocking_in_a_valley_comes_to_rest_in_its_corner():
    """Frictionless, restitution 0: the crossings accumulate towards 0.75 s (Zeno), then the
    contact rests in the corner, held by both slopes' rows; the weight is the sum of the two rows'
    forces along their own normals; the energy leaves at events only."""
    T, m = 1.0, 0.5
    model = _valley(T)
    run, r, entry, energies = _corner_run(model)
    _common_laws(model, run, r)
    _in_the_corner(run, r, T)
    assert 0.7 < entry["t"] < 0.8
    assert len(r.events) < 200
    # resting in the corner from entry to T: the ground's impulse (the vector sum of both rows')
    # is the weight's, straight up; the corner's normal is the mean of the slopes' (+y here)
    weight = m * G * (T - entry["t"])
    totals = entry["totals"]
    assert np.allclose(totals.impulse - entry["impulse"], [0.0, weight], rtol=0, atol=1e-9 * weight)
    assert totals.normal[0] - entry["normal"][0] == pytest.approx(weight, rel=1e-9)
    # each row along its own segment's normal, both pushing: lambda_l n_l + lambda_r n_r = (0, m g)
    pt = run.point(r.q_final, np.zeros(run.nv))
    mode = run.flight()
    mode.closed[0], mode.corner[0] = True, 1
    rows, (a, lam) = run.mode_solution(pt, mode)
    n_l, n_r = run.valleys[1]
    assert rows.n == 2 and lam[0] > 0 and lam[1] > 0
    assert np.allclose(lam[0] * n_l + lam[1] * n_r, [0.0, m * G], rtol=0, atol=1e-12)
    assert lam[0] == pytest.approx(m * G / (2 * n_l[1]), rel=1e-12)
    assert np.max(np.abs(a)) <= 1e-12
    # no energy lost or gained but at events (jumps at t0 == t1): gravity's work balances the
    # kinetic energy along every step (to 1e-9; the located step that ends just past a breakpoint
    # to 2e-5, as before the corner: 1.5e-5 at 0.18 s), and an event only takes energy away
    scale = r.events[0].energy_after
    steps = [(t0, t1, e1 - e0) for (_, _, e0), (t0, t1, e1) in zip(energies, energies[1:])]
    assert all(abs(d) <= 2e-5 * scale for t0, t1, d in steps if t1 > t0)
    assert sum(abs(d) <= 1e-9 * scale for t0, t1, d in steps if t1 > t0) >= 0.9 * sum(t1 > t0 for t0, t1, _ in steps)
    assert all(d <= 1e-12 * scale for t0, t1, d in steps if t1 == t0)


def test_with_friction_a_puck_rests_in_the_valley_and_stays():
    """Friction 0.1 (below the slopes' 1 in 4): it rocks less far, comes to rest in the corner and
    stays there (no slip started on the corner's frictionless rows)."""
    T = 0.5
    model = _valley(T, friction=0.1)
    run, r, entry, _ = _corner_run(model)
    _common_laws(model, run, r)
    _in_the_corner(run, r, T)
    assert entry["t"] < 0.3
    times, states = r.trajectory
    resting = times > entry["t"]
    assert resting.any() and np.ptp(states[resting][:, 0]) <= 1e-12


def test_with_friction_a_puck_stops_in_a_shallow_valley_and_stays():
    """Friction 0.3 above the slopes' 1 in 20: the puck slides into the valley, crosses its
    breakpoint (an event: the far slope's impact with friction), stops on the far slope and sticks
    there: no corner, no creep."""
    from impulse_core.model.terrain import Terrain

    T = 0.3
    model = _valley(T, friction=0.3, base_x=-0.0502, terrain=Terrain.from_points([[-0.2, 0.01], [0.0, 0.0], [0.2, 0.01]]))
    run, r, entry, _ = _corner_run(model)
    _common_laws(model, run, r)
    assert "t" not in entry and list(run.seated) == [-1]
    assert len(r.events) == 3 and r.events[2].external[0] > 0  # touchdown, the slope's, the far slope's at x = 0
    assert np.max(np.abs(r.v_final)) <= 1e-12 and r.settled_at is not None and r.settled_at < 0.05
    times, states = r.trajectory
    still = times > r.settled_at + 0.01
    assert still.any() and np.ptp(states[still][:, 0]) <= 1e-12
    assert 0.0 < run.point(r.q_final, np.zeros(run.nv)).contacts[0, 0] < 1e-3


def _corner_state(terrain):
    """A landing of the valley's puck on ``terrain`` and the state at rest with its contact at the
    breakpoint x = 0 held in the corner (breakpoint 1)."""
    from impulse_core.model.terrain import Terrain

    model = _valley(0.1, terrain=Terrain.from_points(terrain))
    run = _Landing(model.tree, model.scene, model.joints, LandingSettings(), model.space)
    run.touchdown()
    q = np.array([-0.05, 0.0, 0.0])
    mode = run.flight()
    mode.closed[0], mode.corner[0] = True, 1
    run.seat(mode)
    return run, q, mode


def test_a_corner_that_a_row_would_pull_on_is_released():
    """Left when one row's force would pull: in a valley whose far slope still falls (the weight
    outside the corner's normals) the mode LCP unloads the steep slope's row and the contact leaves
    the corner; in the symmetric valley both rows push and it stays."""
    run, q, mode = _corner_state([[-0.2, 0.05], [0.0, 0.0], [0.2, 0.05]])
    assert run.resolve(q, np.zeros(3), mode).corner[0] == 1
    run, q, mode = _corner_state([[-0.2, 0.1], [0.0, 0.0], [0.2, -0.02]])
    rows, (_, lam) = run.mode_solution(run.point(q, np.zeros(3)), mode)
    assert lam[0] < 0 < lam[1]  # the corner's own split pulls on the steep slope
    left = run.resolve(q, np.zeros(3), mode)
    assert left.corner[0] == -1 and not left.closed[0]  # it opens, and touches the far slope again


def test_a_puck_pushed_up_a_slope_leaves_the_corner():
    """An impact that sends the point up one slope faster than the plastic speed releases the
    corner (the row it leaves rests no more), and the landing's steps then carry it up the slope."""
    run, q, mode = _corner_state([[-0.2, 0.05], [0.0, 0.0], [0.2, 0.05]])
    n_l, n_r = run.valleys[1]
    t_r = np.array([n_r[1], -n_r[0]])  # up the right slope
    v = np.array([*(0.05 * t_r + 1e-3 * -n_r), 0.0])  # up the slope, into it at 1 mm/s
    v_plus, event, after = run.impact(q, v, mode, 0.0, np.array([0]), "touchdown")
    assert after.corner[0] == -1
    assert n_r @ v_plus[:2] == pytest.approx(0.0, abs=1e-12)  # plastic on the right slope
    assert n_l @ v_plus[:2] > 1e-2  # leaving the left one
    assert event.external[0] > 0


def _saddle_particle(d: float, x0: float, velocity: np.ndarray, T: float) -> np.ndarray:
    """An independent answer: a particle on the frictionless saddle y = d x z without gravity,
    from (x0, 0) with ``velocity`` less its normal component (a plastic touchdown), by Lagrange's
    equations in (x, z) (mass matrix I + grad h grad h^T, h's Hessian [[0, d], [d, 0]]) at a
    tolerance of 1e-12: its position and velocity (world, 3 each) at ``T``."""
    from scipy.integrate import solve_ivp

    def rhs(_t: float, s: np.ndarray) -> list:
        x, z, xd, zd = s
        g = np.array([d * z, d * x])
        return [xd, zd, *-np.linalg.solve(np.eye(2) + np.outer(g, g), g * (2 * d * xd * zd))]

    n = np.array([0.0, 1.0, -d * x0]) / math.hypot(1.0, d * x0)
    v = velocity - (n @ velocity) * n
    x, z, xd, zd = solve_ivp(rhs, (0.0, T), [x0, 0.0, v[0], v[2]], rtol=1e-12, atol=1e-13).y[:, -1]
    return np.array([x, d * x * z, z, xd, d * (xd * z + x * zd), zd])


def test_a_contact_sliding_across_a_twisted_heightfield_cell_follows_the_surface():
    """data/twist_puck.yaml: a frictionless puck, no gravity, slides across the saddle h = 0.5 x z
    (one twisted bilinear cell), along x and z, so the surface rises under its straight path: it
    rests after its plastic touchdown, the ground pushing it along its path, and ends where a
    particle on the saddle does by Lagrange's equations (1e-9). The contact rows' bias carries
    the normal's turn under the sliding point (n' . p'); without it the contact problem missed
    the normal acceleration 2 d x' z' / |N| (here 3e-5 m off at the end, and random file 30992
    took 4,400 plastic touchdowns 1.9e-8 s apart where the contact problem opened a sinking
    contact)."""
    model = _model("twist_puck.yaml")
    run = _Landing(model.tree, model.scene, model.joints, LandingSettings(), model.space)
    r = run.run(run.first_step())
    assert len(r.events) == 1 and r.total_external[0] > r.events[0].external[0] > 0  # pushed all along
    expected = _saddle_particle(0.5, -0.1, np.array([1.0, -0.05005, 1.0]), 0.3)
    contact = r.q_final[:3] + [0.05, 0.0, 0.0]  # the puck's centre, half its length along x (it does not turn)
    assert np.abs(r.q_final[3:6]).max() <= 1e-12
    assert np.abs(np.concatenate([contact, r.v_final[:3]]) - expected).max() <= 1e-9
    assert r.energy_final == pytest.approx(r.events[0].energy_after, rel=1e-12)  # frictionless, no gravity
    assert r.momentum_balance <= 1e-12


def test_a_contact_sliding_across_a_heightfield_crease_meets_the_slope_by_its_laws():
    """data/crease_puck.yaml: a frictionless puck slides at 0.5 m/s along x on a flat cell into
    the next cell, a slope of 1 in 4 (a crease at the grid line x = 0), at restitution 0.5. The
    crossing is an event at t = 0.1 s: an impact on the slope by the restitution law, impulse m (1
    + e) |v_n| along the slope's normal (v_n = 0.5 m/s x n_x), the normal velocity after -e v_n;
    the bounces that follow fall by e each, down to the plastic speed; the momentum balances.
    Before, the crossing was left to a step's projection: plastic and frictionless whatever the
    laws, no event (random file 30882: 0.38 N s so, its balance 1.9e-4)."""
    model = _model("crease_puck.yaml")
    run = _Landing(model.tree, model.scene, model.joints, LandingSettings(), model.space)
    r = run.run(run.first_step())
    m, e = 0.5, 0.5
    n = np.array([-0.25, 1.0, 0.0]) / math.hypot(0.25, 1.0)
    vn = 0.5 * n[0]
    crease = [ev for ev in r.events if ev.time > 0]
    first = crease[0]
    assert first.kind == "touchdown" and first.time == pytest.approx(0.1, abs=1e-9)
    assert first.external[0] == pytest.approx(m * (1 + e) * abs(vn), rel=1e-9)
    assert n @ first.v_plus[:3] == pytest.approx(-e * (n @ first.v_minus[:3]), rel=1e-9)
    assert n @ first.v_minus[:3] == pytest.approx(vn, rel=1e-6)
    ratios = [b.external[0] / a.external[0] for a, b in zip(crease, crease[1:-1])]
    assert len(ratios) >= 5 and np.allclose(ratios, e, rtol=1e-4)
    assert r.momentum_balance <= 1e-8


def test_a_projection_that_carries_a_contact_across_a_crease_acts_on_the_cell_it_places_it_on():
    """data/crease_valley_puck.yaml: a frictionless puck at restitution 0.9 slides along a
    heightfield's valley crease (cells of slope 1 in 4 either side), held there by gravity. Each
    step runs on one cell and ends in the other's ground, and the position projection after it
    carries the contact across the crease. The projection's velocity rows are those of the cell
    it places the contact on, so that afterwards the contact neither approaches nor leaves that
    cell (the unilateral row at rest), and its impulse is booked along those rows: the momentum
    balances to rounding. Before (random file 32843), the rows were the other cell's: the contact
    left each projection approaching its new cell at up to 0.25 m/s, ending the next step 1e-4 m
    into it, and the impulse was booked along the new cell's normal while it had acted along the
    old one's: this file's balance 6.9e-4, 32843's 1.2e-2."""
    model = _model("crease_valley_puck.yaml")
    scene = replace(model.scene, duration=0.08)  # its first 0.08 s: 39 carried projections
    run = _Landing(model.tree, scene, model.joints, LandingSettings(), model.space)
    speeds, carried = [], []
    project = run.project

    def watched(q, v, mode):
        q1, v1, p = project(q, v, mode)
        pt = run.point(q1, v1)
        speeds.append(float(np.max(np.abs(pt.vn(v1)[mode.closed]), initial=0.0)))
        carried.append(bool(np.any(mode.closed & (run.pieces(q, v) != run.pieces(q1, v1)))))
        return q1, v1, p

    run.project = watched
    r = run.run(2.5e-4)
    assert sum(carried) >= 10, sum(carried)  # the crossings this file is about
    assert max(speeds) <= 1e-9
    assert r.momentum_balance <= 1e-10
    assert r.v_final[0] == pytest.approx(2.0, rel=1e-12)  # no slope along the crease: v_x is kept
    assert abs(run.point(r.q_final, r.v_final).contacts[0, 2]) <= 1e-3  # still in the crease
