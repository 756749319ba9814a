"""Rigid impacts in sequence on a terrain: equal to the core's evaluation on flat ground, one
impact per touchdown on uneven ground, complementarity when Newton's law would pull."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from fidelity_scenes import PAPER_SCENE, UNEVEN, case2, case3

from impulse_core.evaluate import evaluate
from impulse_core.timedomain.sequential import SequentialSettings, sequential_impacts
from impulse_core.model.terrain import Terrain
from impulse_core.model.tree import Body, Scene, Tree
from tests.conftest import random_tree, report


@pytest.mark.parametrize("make", [case2, case3])
def test_flat_simultaneous_contacts_equal_the_core(make):
    tree = make()
    rigid = evaluate(tree, PAPER_SCENE)
    seq = sequential_impacts(tree, PAPER_SCENE)
    assert len(seq.events) == 1 and seq.touchdown_order == tuple(range(len(tree.contacts)))
    np.testing.assert_allclose(seq.external, rigid.external, rtol=1e-10)
    np.testing.assert_allclose(seq.internal_magnitude, rigid.internal_magnitude, rtol=1e-9)
    np.testing.assert_allclose(seq.v_plus, rigid.v_plus, rtol=1e-9, atol=1e-9)
    assert seq.energy_after == pytest.approx(rigid.energy_after, rel=1e-12)


def test_uneven_terrain_gives_one_impact_per_touchdown():
    seq = sequential_impacts(case2(), PAPER_SCENE, terrain=UNEVEN)
    assert [e.contacts for e in seq.events] == [(1,), (0,)]
    assert seq.touchdown_order == (1, 0)
    assert seq.touchdown_time[0] == pytest.approx(0.0054, abs=2e-4)  # ~18 mm at ~3.4 m/s
    assert not seq.energy_gain
    # the toe's impulse is along the ramp's normal
    normal = np.array([-0.04, 0.30]) / np.hypot(0.04, 0.30)
    np.testing.assert_allclose(seq.external_vector[1] / seq.external[1], normal, atol=1e-12)
    # one contact per impact: each restitution is met at its own touchdown (checked in the event)
    assert all(len(e.impulses) == 1 and e.impulses[0] > 0 for e in seq.events)


def test_flight_step_converges():
    coarse = sequential_impacts(case2(), PAPER_SCENE, SequentialSettings(flight_step=4e-4), terrain=UNEVEN)
    fine = sequential_impacts(case2(), PAPER_SCENE, SequentialSettings(flight_step=5e-5), terrain=UNEVEN)
    np.testing.assert_allclose(coarse.external, fine.external, rtol=1e-7)
    assert coarse.touchdown_time[0] == pytest.approx(fine.touchdown_time[0], abs=1e-9)


def test_complementarity_when_newton_would_pull(rng):
    """The impact law at a touchdown, on the Delassus matrices of seeded random trees (several
    contacts, straight-down approach): impulses >= 0, post-impact normal velocities >= -e times the
    approach, complementary (1e-9); where eq. 11 asks a contact to pull, it separates instead.
    The law is the landing's without friction (:func:`impulse_core.timedomain.landing.rigid_impact`:
    Lemke's method on the LCP, redundant rows the smallest-norm split), which the model uses."""
    from impulse_core.impact.coulomb import solve_unilateral
    from impulse_core.impact.laws import least_norm_split, redundant
    from impulse_core.timedomain.compliant import _Evaluator, compiled_step, touchdown_configuration
    from impulse_core.model.tree import design_vector

    e = 0.5
    pulling = 0
    for _ in range(40):
        tree = random_tree(rng, 4, p_contact=1.0, max_contacts_per_body=2)
        ev = _Evaluator(compiled_step(tree.topology(), Terrain()), design_vector(tree), 0.0)
        q = touchdown_configuration(tree)
        v = np.zeros(len(q))
        v[1] = -2.0
        s = ev(q, v)
        A = s.Jn @ s.minv_jnt
        u = s.rate.copy()
        lam = solve_unilateral(A, u, np.zeros(0, int), np.full(len(u), e), np.zeros(0)).normal
        lam = least_norm_split(s.Jn, lam) if redundant(s.Jn) else lam
        w = u + A @ lam + e * u
        scale = np.abs(u).max()
        assert np.all(lam >= 0.0)
        assert np.all(w >= -1e-9 * scale)
        assert abs(lam @ w) <= 1e-9 * scale * max(1.0, np.abs(lam).max())
        if np.linalg.cond(A) < 1e8 and np.any(np.linalg.solve(A, -(1 + e) * u) < -1e-9):
            pulling += 1
            assert np.any(lam == 0.0)
    assert pulling >= 3  # the check met contacts that eq. 11 makes pull


@pytest.mark.parametrize("module", ["impulse_core.model.terrain", "impulse_core.timedomain.compliant", "impulse_core.timedomain.sequential"])
def test_terrain_modules_import_only_casadi_and_numpy(module):
    """Dependency direction (STYLE.md), as tests/impulse_core/test_imports.py checks the others."""
    import json
    import subprocess
    import sys
    from pathlib import Path

    code = (
        f"import json, sys, {module}\n"
        "print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in "
        "['yaml', 'optuna', 'scipy', 'matplotlib', 'cvxpy', 'mujoco'])))"
    )
    root = Path(__file__).resolve().parents[2]
    out = subprocess.run([sys.executable, "-c", code], cwd=root, capture_output=True, text=True, check=True)
    assert json.loads(out.stdout.strip().splitlines()[-1]) == []


def test_a_scene_carrying_its_terrain_is_used():
    """Both time-domain models take ``scene.terrain`` and ``scene.base_x`` without arguments, and
    an argument overrides the scene's."""
    import dataclasses

    from impulse_core.timedomain.compliant import CompliantSettings, simulate_impact

    scene = dataclasses.replace(PAPER_SCENE, terrain=UNEVEN, base_x=0.0)
    assert sequential_impacts(case2(), scene).touchdown_order == (1, 0)
    assert simulate_impact(case2(), scene, CompliantSettings(steps_per_period=30)).touchdown_order == (1, 0)
    assert sequential_impacts(case2(), PAPER_SCENE, terrain=UNEVEN).touchdown_order == (1, 0)
    shifted = sequential_impacts(case2(), dataclasses.replace(scene, base_x=0.01))
    assert shifted.touchdown_time[0] != sequential_impacts(case2(), scene).touchdown_time[0]


# --------------------------------------------------------------------------------------------
# With friction: the landing's exact Newton-Coulomb law at each touchdown


def _spied_events(monkeypatch) -> dict:
    """Record every impact of the sequential model's landing (``_Landing.impact``: the run, q, v;
    ``rigid_impact``: the point, its rows, their restitutions, the law's answer), every resting
    step's contact impulses (``_Landing.tally_joints`` of a step with closed contacts: mu, normal
    and tangential impulses per contact) and the state the run ends in (``_Landing.result``)."""
    from impulse_core.timedomain import landing as module
    from impulse_core.timedomain.events import impacts as impacts_module, paradox as paradox_module
    from impulse_core.timedomain.events.run import _Landing

    seen: dict = {"impacts": [], "laws": [], "rest": [], "end": []}
    impact, law, tally, result = _Landing.impact, module.rigid_impact, _Landing.tally_joints, _Landing.result

    def spy_impact(self, q, v, mode, t, contacts, kind):
        seen["impacts"].append((self, q.copy(), v.copy()))
        return impact(self, q, v, mode, t, contacts, kind)

    def spy_law(pt, v, rows, e, mu, kernel=None):
        out = law(pt, v, rows, e, mu, kernel)
        seen["laws"].append((pt, rows, np.array(e), out))
        return out

    def spy_tally(self, totals, q0, v0, q1, v1, impulses, dt, loaded, *vectors):
        if loaded and dt > 0:  # a step (or the part of one up to an event) with resting contacts
            fn, ft = impulses[: self.nc], impulses[self.nc :].reshape(self.dims - 1, self.nc).T
            seen["rest"].append((self.mu, fn.copy(), ft.copy()))
        return tally(self, totals, q0, v0, q1, v1, impulses, dt, loaded, *vectors)

    def spy_result(self, totals, q, v, *args):
        pt = self.point(q, v)
        seen["end"][:] = [(pt.momentum[:, 0].copy(), pt.gap.copy(), pt.vn(v).copy())]
        return result(self, totals, q, v, *args)

    monkeypatch.setattr(_Landing, "impact", spy_impact)
    for law_user in (impacts_module, paradox_module):  # the impacts, and the jams and bridges
        monkeypatch.setattr(law_user, "rigid_impact", spy_law)
    monkeypatch.setattr(_Landing, "tally_joints", spy_tally)
    monkeypatch.setattr(_Landing, "result", spy_result)
    return seen


def _check_laws(seen: dict, mu: float) -> tuple[int, int]:
    """Newton's restitution (each row's restitution: the scene's, or 0 where the approach was
    plastic) with complementarity and Coulomb's law at each impact's contacts (1e-9), and each
    impact's momentum balance (the contact impulse vectors equal the change of the tree's linear
    momentum, 1e-12); returns how many contacts stuck and slid."""
    from impulse_core.timedomain.landing import contact_impulses

    stuck = slid = 0
    for (run, q, v), (pt, rows, e, impact) in zip(seen["impacts"], seen["laws"], strict=True):
        idx = rows.contact[rows.contact >= 0]
        before, after = pt.Jn[idx] @ v, pt.Jn[idx] @ impact.v_plus
        slip_before, slip = pt.Jt[idx] @ v, pt.Jt[idx] @ impact.v_plus  # n x (d - 1)
        lam, t = impact.normal[idx], impact.tangential[idx]
        scale = max(float(np.max(np.abs(np.concatenate([before, slip_before.ravel()])))), 1e-12)
        big = max(float(np.max(lam)), float(np.linalg.norm(pt.momentum[:, 0])))  # N s: the impact's, or the tree's
        assert np.all((e == 0) | (e == run.e)) and np.all((e == run.e) | (-before <= 1e-4) | (run.min_bounce > 0))
        assert np.all(lam >= -1e-9 * big) and np.all(after + e * before >= -1e-9 * scale)
        assert abs(lam @ (after + e * before)) <= 1e-9 * scale * big
        size = np.linalg.norm(t, axis=1)
        assert np.all(size <= mu * lam + 1e-9 * big)
        for k in range(len(idx)):
            if lam[k] <= 1e-6 * big or mu == 0:  # a re-touch of rounding's size: the cone above is all it shows
                continue
            speed = float(np.linalg.norm(slip[k]))
            if speed > 1e-9 * scale:  # sliding: on the cone's edge, against the slip
                slid += 1
                assert size[k] == pytest.approx(mu * lam[k], abs=1e-9 * big)
                np.testing.assert_allclose(t[k] / size[k], -slip[k] / speed, atol=1e-7)
            else:
                stuck += 1
        F = contact_impulses(pt, impact.normal, impact.tangential).sum(axis=1)
        change = run.point(q, impact.v_plus).momentum[:, 0] - pt.momentum[:, 0]  # the base's subtree: the tree
        np.testing.assert_allclose(change, F, atol=1e-12 * max(1.0, float(np.max(np.abs(pt.momentum)))))
    return stuck, slid


def _check_rest(seen: dict) -> int:
    """Resting contacts: over every step with a closed contact, each contact's normal impulse is
    >= 0 and its tangential impulse inside Coulomb's cone (1e-9 of the step's largest); returns
    how many such steps there were."""
    for mu, fn, ft in seen["rest"]:
        tol = 1e-9 * max(float(np.max(np.abs(fn))), 1e-300)
        assert np.all(fn >= -tol)
        assert np.all(np.linalg.norm(ft, axis=1) <= mu * fn + tol)
    return len(seen["rest"])


def _random_scene(rng, k: int, space: str):
    """The k-th seeded random tree and scene on the uneven terrain (in space: a heightfield of it
    and a cross slope); k = 2 and 5 plastic, odd k low friction."""
    from impulse_core.kinematics.spatial import SPATIAL
    from impulse_core.model.heightfield import Heightfield
    from impulse_core.model.tree import Scene

    tree = random_tree(rng, int(rng.integers(2, 5)), p_fixed=0.0, p_contact=1.0, length_range=(0.1, 0.5))
    mu, e = (0.2, 0.0 if k == 5 else 0.3) if k % 2 else (1.5, 0.0 if k == 2 else 0.5)
    scene = Scene(speed=2.0, velocity_x=float(rng.uniform(-0.5, 0.5)), angular_velocity=float(rng.uniform(-2, 2)),
                  restitution=e, friction=mu, terrain=Terrain((-1.0, 0.0, 0.3), (0.05, 0.0, 0.06)))
    kw = {}
    if space == "spatial":
        x, z = np.array([-1.0, 0.0, 0.3]), np.array([-1.0, 1.0])
        field = Heightfield.from_arrays(x, z, np.array([[0.05], [0.0], [0.06]]) + 0.04 * z[None, :])
        scene = dataclasses.replace(scene, terrain=Terrain(), heightfield=field, velocity_z=0.3,
                                    angular_velocity_x=0.5)
        kw = {"space": SPATIAL}
    return tree, scene, kw


def _check_sequence(seen: dict, seq, n_contacts: int) -> None:
    """Over the whole sequence the contact impulse vectors equal the change of the tree's momentum
    (no gravity; RK4 keeps it to the landing's momentum balance); the totals include the events'
    sums; at the end no contact approaches the ground below it or untouched."""
    p0 = seen["laws"][0][0].momentum[:, 0]
    p1, gap, vn = seen["end"][0]
    np.testing.assert_allclose(p1 - p0, seq.external_vector.sum(axis=0), atol=1e-4 * np.max(np.abs(p0)))
    events = np.zeros(n_contacts)
    for ev in seq.events:
        events[list(ev.contacts)] += ev.impulses
    assert np.all(seq.external >= events - 1e-12 * np.max(seq.external))
    touched = np.isfinite(seq.touchdown_time)
    assert not np.any((vn < 0) & ((gap < 0) | ~touched)) or seq.end >= 0.1 * (1 - 1e-12)


@pytest.mark.parametrize("space", ["planar", "spatial"])
def test_friction_at_each_touchdown_meets_the_laws(monkeypatch, space):
    """Seeded random trees on the uneven terrain (in space: a heightfield of it and a cross
    slope) with friction: every impact meets Newton's restitution (plastic below 1e-4 m/s),
    complementarity, Coulomb's cone (sliding: on its edge against the slip) and balances
    momentum; resting contacts push inside the cone; over the whole sequence the impulse vectors
    equal the change of the tree's momentum (no gravity), the totals include the events' sums
    (resting phases add to them), and no contact is left approaching. Scenes 0 (sticking,
    elastic), 2 (sticking and sliding, plastic), 3 (sliding, elastic) and 5 (resting) are landed."""
    rng = np.random.default_rng(20261126)
    seen = _spied_events(monkeypatch)
    stuck = slid = events = repeated = rested = 0
    for k in range(6):
        tree, scene, kw = _random_scene(rng, k, space)
        if k in (1, 4):  # drawn, so the later scenes stay the same; not landed: the kinds of 3 and 0
            continue
        for v in seen.values():
            v.clear()
        seq = sequential_impacts(tree, scene, **kw)
        assert len(seq.events) == len(seen["laws"]) >= 1
        s, d = _check_laws(seen, scene.friction)
        stuck, slid, events = stuck + s, slid + d, events + len(seen["laws"])
        rested += _check_rest(seen)
        touches = np.bincount([c for ev in seq.events for c in ev.contacts], minlength=len(tree.contacts))
        repeated += int(np.any(touches > 1))
        _check_sequence(seen, seq, len(tree.contacts))
        assert seq.modes is not None and len(seq.modes) == len(tree.contacts)
        assert not seq.energy_gain
    assert stuck > 0 and slid > 0 and events > 6 and (rested > 0 or space == "planar"), (stuck, slid, events, rested)


@pytest.mark.parametrize("mu", [0.1, 2.0])
def test_flat_simultaneous_contacts_with_friction_equal_the_friction_rung(mu):
    """Case 2 landing obliquely on flat ground, every contact at once: one impact, the friction
    rung's impulses, tangential impulses, modes and velocities."""
    from impulse_core.impact.laws import ImpactModel

    scene = dataclasses.replace(PAPER_SCENE, friction=mu, velocity_x=0.8, angular_velocity=1.0, restitution=0.3)
    rigid = evaluate(case2(), scene, ImpactModel.FRICTION)
    seq = sequential_impacts(case2(), scene)
    assert len(seq.events) == 1
    scale = float(np.max(rigid.external))
    np.testing.assert_allclose(seq.external, rigid.external, atol=1e-10 * scale)
    np.testing.assert_allclose(seq.tangential, rigid.tangential, atol=1e-10 * scale)
    np.testing.assert_allclose(seq.internal_magnitude, rigid.internal_magnitude, atol=1e-9 * scale)
    np.testing.assert_allclose(seq.v_plus, rigid.v_plus, atol=1e-9)
    assert seq.modes == rigid.modes


@pytest.mark.parametrize("mu", [0.1, 2.0])
def test_in_space_flat_simultaneous_contacts_with_friction_equal_the_friction_rung(mu):
    """The yaw-splayed case 3 (heel and toes at one height) landing obliquely and rolling on flat
    ground: one impact, the spatial friction rung's (the circular cone) impulses and modes."""
    from impulse_core.impact.laws import ImpactModel
    from impulse_core.kinematics.spatial import SPATIAL
    from tests.impulse_core.test_compliant_spatial import OBLIQUE, yaw_splayed_case3

    scene = dataclasses.replace(OBLIQUE, friction=mu, restitution=0.3)
    rigid = evaluate(yaw_splayed_case3(), scene, ImpactModel.FRICTION, SPATIAL)
    seq = sequential_impacts(yaw_splayed_case3(), scene, space=SPATIAL)
    assert len(seq.events) == 1 and len(seq.events[0].contacts) == 4
    scale = float(np.max(rigid.external))
    np.testing.assert_allclose(seq.external, rigid.external, atol=1e-9 * scale)
    np.testing.assert_allclose(seq.tangential, rigid.tangential, atol=1e-9 * scale)
    np.testing.assert_allclose(seq.internal_magnitude, rigid.internal_magnitude, atol=1e-9 * scale)
    assert seq.modes == rigid.modes


def test_friction_names_its_model_and_frictionless_stays_as_it_was():
    plain = sequential_impacts(case2(), PAPER_SCENE, terrain=UNEVEN)
    assert plain.modes is None and not np.any(plain.tangential) and all(e.tangential is None for e in plain.events)
    rough = sequential_impacts(case2(), dataclasses.replace(PAPER_SCENE, friction=0.4), terrain=UNEVEN)
    assert rough.model.startswith("newton-coulomb") and rough.touchdown_order == (1, 0)
    assert np.all(np.abs(rough.tangential) > 0)


# --------------------------------------------------------------------------------------------
# Resting contacts: a plastic contact that the tree turns into the ground rests and pushes

CHATTER_HEIGHTFIELD = Path(__file__).resolve().parent / "data" / "chatter_heightfield.yaml"


def _chattering_trees():
    """Seeded random planar trees spinning onto the uneven terrain with restitution 0 (seed 7,
    trees 0, 1 and 6): each chattered past 1000 impacts without resting contacts."""
    rng = np.random.default_rng(7)
    out = []
    for k in range(7):
        tree = random_tree(rng, int(rng.integers(2, 5)), p_fixed=0.0, p_contact=1.0, length_range=(0.1, 0.5))
        scene = Scene(speed=2.0, velocity_x=float(rng.uniform(-0.5, 0.5)), angular_velocity=float(rng.uniform(-8, 8)),
                      restitution=0.0, terrain=Terrain((-1.0, 0.0, 0.3), (0.05, 0.0, 0.06)))
        if k in (0, 1, 6):
            out.append((tree, scene))
    return out


@pytest.mark.parametrize("mu", [0.0, pytest.param(0.6, marks=pytest.mark.slow)])  # friction at rest by default:
def test_chattering_contacts_rest_and_meet_the_laws(monkeypatch, mu):  # test_a_resting_phase_converges_in_the_step
    """Trees whose plastic contact the tree keeps turning into the ground (they chattered before)
    now run: every impact meets Newton's law (plastic) with complementarity and the cone, resting
    contacts push inside it, the momentum balance holds over the sequence, nothing is left
    approaching, and the resting phases add to ``external`` beyond the events' sums. Two of the
    rests end by lift-off before max_time (mu 0: at 95.6 and 77.8 ms; 0.6: 97 and 61 ms)."""
    seen = _spied_events(monkeypatch)
    rested = ended = 0
    for tree, scene in _chattering_trees():
        for v in seen.values():
            v.clear()
        seq = sequential_impacts(tree, dataclasses.replace(scene, friction=mu))
        assert 1 <= len(seq.events) < 20
        _check_laws(seen, mu)
        assert _check_rest(seen) > 0
        _check_sequence(seen, seq, len(tree.contacts))
        events = np.zeros(len(tree.contacts))
        for ev in seq.events:
            events[list(ev.contacts)] += ev.impulses
        rested += int(np.any(seq.external > events + 1e-3 * np.max(seq.external)))
        ended += int(seq.end < 0.1 * (1 - 1e-9))
        assert not seq.energy_gain
    assert rested == 3 and ended == 2  # two rests end (lift-off) before max_time, one is pressed to it


def test_chattering_heightfield_file_rests(monkeypatch):
    """The spatial fuzz file (data/chatter_heightfield.yaml) runs: one plastic touchdown, then its
    rod's tip rests and pushes, and the laws hold as above."""
    from optimizer.config.model_file import load_model_file

    model = load_model_file(CHATTER_HEIGHTFIELD)
    seen = _spied_events(monkeypatch)
    seq = sequential_impacts(model.tree, model.scene, space=model.space)
    _check_laws(seen, 0.0)
    assert _check_rest(seen) > 0
    _check_sequence(seen, seq, len(model.tree.contacts))
    assert len(seq.events) == 1 and seq.external[4] > 2.0 * seq.events[0].impulses[-1]


def test_compliant_rung_approaches_the_resting_contact_as_it_stiffens():
    """A seeded tree spinning into the ground (seed 7, tree 1) lands plastically on one contact,
    which then rests and pushes until max_time (0.1 s; 22 of its 51 N s are the resting phase's).
    The compliant rung (penalty law, damping ratio 10: restitution 0.0024) at increasing
    stiffness approaches its totals, external and internal (measured: 3.6e-2, 1.4e-2, 2.5e-3,
    8.3e-4 of external at 1e5 ... 1e8 N/m; internal 4.6e-2 ... 1.2e-3)."""
    from impulse_core.timedomain.compliant import (CompliantSettings, CompliantStatus, relative_difference,
                                                   simulate_impact)

    tree, scene = _chattering_trees()[1]
    seq = sequential_impacts(tree, scene)
    events = sum(ev.impulses.sum() for ev in seq.events)
    assert seq.end == pytest.approx(0.1) and seq.external.sum() > events + 10.0  # a long resting phase
    errors = []
    for k in (1e5, 1e6, 1e7, 1e8):
        c = simulate_impact(tree, scene, CompliantSettings(stiffness=k, damping_ratio=10.0, settle_fraction=0.0,
                                                           record=False))
        assert c.status is CompliantStatus.TIMEOUT  # still pressed at max_time, as the rigid contact
        errors.append((relative_difference([(c.external, seq.external)]),
                       relative_difference([(c.internal_magnitude, seq.internal_magnitude)])))
    report("sequential", "resting contact, compliant (penalty, zeta 10) vs sequential at 1e5..1e8 N/m: external "
           + " ".join(f"{e:.1e}" for e, _ in errors) + ", internal " + " ".join(f"{i:.1e}" for _, i in errors))
    ext, internal = np.array(errors).T
    assert np.all(np.diff(ext) < 0) and ext[-1] < 2e-3 and ext[-1] < ext[0] / 20
    assert internal[-1] < 1e-2 and internal[-1] < internal[0] / 5


@pytest.mark.parametrize("mu", [0.0, 0.5])
def test_a_plastic_landing_at_rest_ends_at_once(mu):
    """A rod lying on a slope, landing plastically along the slope's normal: the impact stops it
    (the first instant's answer), its contacts rest unloaded, and the run ends at the impact (a
    contact resting unloaded does not hold it to max_time, 0.1 s)."""
    from impulse_core.timedomain.first_instant import first_instant
    from impulse_core.impact.laws import ImpactModel

    slope = Terrain((-1.0, 1.0), (-0.2, 0.2))  # 0.2 rad
    tree = Tree((Body("rod", None, 1.0, 1.0, float(np.arctan(0.2)), contacts=(0.0, 1.0)),))
    n = np.array([-0.2, 1.0]) / np.hypot(0.2, 1.0)
    scene = Scene(speed=1.0, restitution=0.0, friction=mu, terrain=slope)
    scene = dataclasses.replace(scene, velocity_x=float(-2.0 * n[0]), speed=float(2.0 * n[1]))
    seq = sequential_impacts(tree, scene)
    first = first_instant(tree, scene, ImpactModel.FRICTION if mu else ImpactModel.LCP)
    # at the impact (frictionless), or within a few steps (two sticking contacts on one rod are
    # redundant rows: their least-norm forces start at rounding's size, 0.3 ms measured)
    assert len(seq.events) == 1 and seq.end <= (0.0 if mu == 0 else 1e-3)
    np.testing.assert_allclose(seq.external, first.external, rtol=1e-9)
    np.testing.assert_allclose(seq.v_plus, 0.0, atol=1e-9)


def test_a_resting_phase_converges_in_the_step():
    """Tree 6 of the chattering ones with friction 0.6: resting contacts (4.7 of the 23 N s) that end by
    lift-off at 61 ms; halving the step twice changes neither the totals nor the events (1e-6)."""
    tree, scene = _chattering_trees()[2]
    scene = dataclasses.replace(scene, friction=0.6)
    coarse = sequential_impacts(tree, scene, SequentialSettings(flight_step=2e-4))
    fine = sequential_impacts(tree, scene, SequentialSettings(flight_step=5e-5))
    events = sum(ev.impulses.sum() for ev in fine.events)
    assert fine.external.sum() > events + 1.0 and fine.end < 0.1  # a resting phase that ends
    scale = float(np.max(fine.external))
    np.testing.assert_allclose(coarse.external, fine.external, atol=1e-6 * scale)
    np.testing.assert_allclose(coarse.tangential, fine.tangential, atol=1e-6 * scale)
    np.testing.assert_allclose(coarse.internal_magnitude, fine.internal_magnitude, atol=1e-6 * scale)
    assert [e.time for e in coarse.events] == pytest.approx([e.time for e in fine.events], abs=1e-9)
    assert coarse.end == pytest.approx(fine.end, abs=1e-6)
