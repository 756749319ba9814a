"""Redundant contacts: more contact normals than independent directions (STYLE.md numerics note).

Three contacts on one rigid body (a planar rigid body's normal velocities span only vy and
omega), two coincident contacts, contacts spread over bodies welded by fixed joints. The Delassus
matrix is singular: the post-impact velocity is unique, the split of the impulse is not.
``evaluate`` must detect it (``split_unique`` False) and, on the NEWTON rung, return the
smallest-norm non-negative split that meets the restitution law; the raw undamped solve must be
shown to be garbage, so that the guard is known to matter. Where no non-negative split meets
Newton's law, the automatic choice runs the LCP rung instead (test_contact_models.py).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from impulse_core.impact.laws import ImpactModel
from impulse_core.evaluate import PIVOT_TOL, approach_velocity, compiled_model, evaluate
from impulse_core.model.tree import BODY_VALUES, Body, ContactSelection, JointKind, Scene, Tree, design_vector, with_values
from tests import planar_numpy as pn
from tests.conftest import random_tree, relative_error, report
from tests.pinocchio_reference import build

SCENE = Scene(selection=ContactSelection.ALL, restitution=0.8, speed=3.43)

DESIGNED = {
    # a flat uniform rod on three points
    "rod-three-points": Tree((Body("rod", None, 1.0, 2.0, 0.0, contacts=(0.0, 0.5, 1.0)),)),
    # tilted, off-centre centre of mass, uneven points (an impossible touchdown, but contacts: all)
    "rod-three-points-tilted": Tree((Body("rod", None, 1.0, 2.0, 0.3, contacts=(0.0, 0.3, 1.0), com=0.4),)),
    "rod-two-coincident": Tree((Body("rod", None, 1.0, 2.0, -0.5, contacts=(1.0, 1.0)),)),
    "leg-two-coincident": Tree(
        (Body("thigh", None, 0.7, 1.0, -1.9), Body("shank", 0, 0.5, 1.0, 0.4, contacts=(1.0, 1.0)))
    ),
    "welded-three-rods": Tree(
        (
            Body("a", None, 1.0, 1.0, 0.0, contacts=(0.0,)),
            Body("b", 0, 0.5, 0.5, -0.4, joint=JointKind.FIXED, contacts=(1.0,)),
            Body("c", 0, 0.3, 0.4, 0.6, at=0.5, joint=JointKind.FIXED, contacts=(1.0,)),
        )
    ),
    # the conftest leg with its foot welded to the shank: heel tip, toe middle and toe tip
    "leg-welded-foot": Tree(
        (
            Body("thigh", None, 0.7, 1.0, -1.4),
            Body("shank", 0, 0.7, 1.0, -0.3),
            Body("heel", 1, 0.1, 0.1, -1.14, joint=JointKind.FIXED, contacts=(1.0,)),
            Body("toe1", 1, 0.3, 0.25, 1.4, joint=JointKind.FIXED, contacts=(0.5,)),
            Body("toe2", 3, 0.15, 0.15, -0.4, joint=JointKind.FIXED, contacts=(1.0,)),
        )
    ),
    # found by a seeded search (seed 3): the smallest-norm split pulls, a non-negative one exists,
    # so evaluate's answer comes from least_distance
    "rod-least-distance": Tree(
        (
            Body("b0", None, 0.38283510206496285, 5.471655788621528, 1.9563882731017355,
                 contacts=(0.18754468317091455, 0.7891213552704708, 0.045902549748612076),
                 com=0.7853318179464187, gyration=0.07148430701235542),
        )
    ),
}


def _random_redundant_trees() -> dict[str, Tree]:
    """Random trees with three contacts put on one body (or on a welded pair)."""
    rng = np.random.default_rng(9001)
    out = {}
    for k in range(12):
        tree = random_tree(rng, int(rng.integers(1, 7)), p_contact=0.4, p_fixed=0.3)
        b = int(rng.integers(tree.n_bodies))
        bodies = list(tree.bodies)
        bodies[b] = dataclasses.replace(bodies[b], contacts=tuple(float(c) for c in rng.uniform(0, 1, 3)))
        out[f"random-{k}-{tree.n_bodies}b"] = Tree(tuple(bodies))
    return out


CASES = {**DESIGNED, **_random_redundant_trees()}


def _independent_rows(J: np.ndarray) -> list[int]:
    """A maximal set of linearly independent rows, greedily in order (numpy rank)."""
    keep: list[int] = []
    for i in range(J.shape[0]):
        trial = keep + [i]
        sub = J[trial] / np.linalg.norm(J[trial], axis=1, keepdims=True)
        if np.linalg.matrix_rank(sub, tol=1e-9) == len(trial):
            keep = trial
    return keep


def _min_norm_nonnegative_split(tree: Tree, scene: Scene) -> tuple[np.ndarray | None, np.ndarray]:
    """Independent reference (numpy model, exhaustive active sets): the smallest-norm lambda with
    J M^-1 J^T lambda = -(1+e) J v- and lambda >= 0 (None if there is none), and the smallest-norm
    lambda without the sign constraint.

    Every solution is lambda_0 + N z (lambda_0 the smallest-norm one, N an orthonormal basis of the
    left null space of J, |lambda|^2 = |lambda_0|^2 + |z|^2). The optimum's active set S (the
    contacts at zero) makes z the smallest-norm solution of (lambda_0 + N z)_S = 0, and any other
    set whose such solution is feasible gives a feasible, hence no smaller, point: so the best
    feasible point over all 2^n sets is the optimum.
    """
    pl = pn.place(tree)
    J = pn.normal_jacobian(tree, pl)
    A = J @ np.linalg.solve(pn.mass_matrix(tree, pl), J.T)
    v = np.zeros(pl.nv)
    v[1] = -scene.speed
    rhs = -(1 + scene.restitution) * (J @ v)
    U, sv, _ = np.linalg.svd(J)  # left null space of J itself (row scaling would change it)
    rank = int(np.sum(sv > 1e-9 * sv.max()))
    R, N = U[:, :rank], U[:, rank:]
    lam0 = R @ np.linalg.solve(R.T @ A @ R, R.T @ rhs)
    n = len(lam0)
    best = None
    for mask in range(2**n):
        S = [i for i in range(n) if mask >> i & 1]
        if S:
            z, *_ = np.linalg.lstsq(N[S], -lam0[S], rcond=None)
            if np.abs(N[S] @ z + lam0[S]).max() > 1e-10 * np.abs(lam0).max():
                continue
        else:
            z = np.zeros(N.shape[1])
        lam = lam0 + N @ z
        if lam.min() >= -1e-10 * np.abs(lam0).max() and (best is None or lam @ lam < best @ best):
            best = lam
    return best, lam0


def test_cases_are_redundant():
    """The premise: every case has dependent contact normals (numpy rank)."""
    for name, tree in CASES.items():
        J = pn.normal_jacobian(tree, pn.place(tree))
        assert len(_independent_rows(J)) < J.shape[0], name


@pytest.mark.parametrize("name", list(CASES))
def test_evaluate_handles_redundant_contacts(name):
    tree = CASES[name]
    res = evaluate(tree, SCENE, ImpactModel.NEWTON)
    pl = pn.place(tree)
    scale = sum(b.mass for b in tree.bodies) * SCENE.speed
    assert not res.split_unique
    assert np.all(np.isfinite(res.external)) and np.all(np.isfinite(res.v_plus))
    # restitution at every contact, as reported and recomputed from v_plus
    target = SCENE.restitution * SCENE.speed
    assert np.allclose(res.contact_velocity, target, rtol=0, atol=1e-9 * SCENE.speed)
    assert np.allclose(pn.normal_jacobian(tree, pl) @ res.v_plus, target, rtol=0, atol=1e-9 * SCENE.speed)
    # momentum balance of the whole tree (linear, and angular about the base origin)
    every = range(tree.n_bodies)
    P0, L0 = pn.momentum(tree, pl, res.v_minus, every, np.zeros(2))
    P1, L1 = pn.momentum(tree, pl, res.v_plus, every, np.zeros(2))
    F, Mz = pn.contact_wrench(pl, res.external, res.active, every, np.zeros(2))
    assert np.allclose(P1 - P0, F, rtol=0, atol=1e-9 * scale)
    size = np.abs(pl.tip).max() + np.abs(pl.origin).max()
    assert math.isclose(L1 - L0, Mz, rel_tol=0, abs_tol=1e-9 * scale * size)
    # every joint: force impulse = subtree momentum change - external impulses on the subtree
    for k in range(1, tree.n_bodies):
        sub = pn.descendants(tree, k)
        dP = (pn.momentum(tree, pl, res.v_plus, sub, np.zeros(2))[0]
              - pn.momentum(tree, pl, res.v_minus, sub, np.zeros(2))[0])
        F_sub, _ = pn.contact_wrench(pl, res.external, res.active, sub, np.zeros(2))
        assert np.allclose(res.internal[k - 1][:2], dP - F_sub, rtol=0, atol=1e-9 * scale), f"joint {k}"
    # the split: non-negative where possible, and the smallest such (exhaustive reference)
    reference, lam_free = _min_norm_nonnegative_split(tree, SCENE)
    if reference is None:
        assert res.pulling, "no non-negative split exists, yet no contact is reported pulling"
        assert np.allclose(res.external, lam_free, rtol=1e-7, atol=1e-9 * scale)
    else:
        assert not res.pulling
        assert res.external.min() >= -1e-12 * scale
        assert np.allclose(res.external, reference, rtol=1e-6, atol=1e-7 * np.abs(reference).max())
    report("redundant", f"{name}: external {np.array2string(res.external, precision=4)}"
           + (" (pulling: no non-negative split)" if reference is None else ""))


def test_every_path_of_the_guard_is_exercised():
    """Among the cases: splits that are the smallest-norm one, splits that need least_distance
    (the smallest-norm split pulls, a non-negative one exists), and sets with no non-negative
    split (pulling contacts reported)."""
    kinds = {"min-norm": 0, "least-distance": 0, "no-nonnegative": 0}
    for tree in CASES.values():
        reference, lam_free = _min_norm_nonnegative_split(tree, SCENE)
        if reference is None:
            kinds["no-nonnegative"] += 1
        elif lam_free.min() < 0:
            kinds["least-distance"] += 1
        else:
            kinds["min-norm"] += 1
    report("redundant", f"cases per path: {kinds}")
    assert all(v >= 1 for v in kinds.values()), kinds


@pytest.mark.parametrize("name", list(CASES))
def test_post_impact_velocity_equals_pinocchio_without_the_redundant_rows(name):
    """v_plus is unique: Pinocchio's impulseDynamics on a maximal independent subset of the
    contacts gives the same v_plus (the dropped rows are affine combinations of the kept ones,
    and every contact approaches at the same speed, so their restitution law follows)."""
    tree = CASES[name]
    res = evaluate(tree, SCENE, ImpactModel.NEWTON)
    keep = tuple(_independent_rows(pn.normal_jacobian(tree, pn.place(tree))))
    v_pin, lam_pin = build(tree).impulse(res.v_minus, SCENE.restitution, keep)
    assert relative_error(res.v_plus, v_pin, max(np.linalg.norm(v_pin), np.linalg.norm(res.v_minus))) < 1e-9
    # the total impulse is unique too
    assert math.isclose(res.external.sum(), lam_pin.sum(), rel_tol=1e-9)


def test_three_points_under_a_flat_uniform_rod_share_equally():
    """Golden value, derived by hand: a flat uniform rod of mass m landing on contacts at both ends
    and the middle stops rotating-free (v+ = e v straight up), so the impulses sum to (1 + e) m v
    with no net moment about the centre: lambda_1 = lambda_3 = a, lambda_2 = (1 + e) m v - 2a.
    The smallest norm has a = (1 + e) m v / 3: each contact takes a third."""
    res = evaluate(DESIGNED["rod-three-points"], SCENE)
    third = (1 + 0.8) * 2.0 * 3.43 / 3
    assert np.allclose(res.external, third, rtol=1e-12)
    assert np.allclose(res.v_plus, [0.0, 0.8 * 3.43, 0.0], atol=1e-12)


@pytest.mark.parametrize("name", ["rod-two-coincident", "leg-two-coincident"])
def test_coincident_contacts_share_one_contacts_impulse(name):
    """Two contacts at one point act as one contact: each takes half of the single contact's
    impulse (Pinocchio, one contact), and v_plus is the single contact's."""
    tree = CASES[name]
    res = evaluate(tree, SCENE)
    v_pin, lam_pin = build(tree).impulse(res.v_minus, SCENE.restitution, (0,))
    assert np.allclose(res.external, lam_pin[0] / 2, rtol=1e-10)
    assert relative_error(res.v_plus, v_pin, np.linalg.norm(res.v_minus)) < 1e-10
    single = Tree(tree.bodies[:-1] + (dataclasses.replace(tree.bodies[-1], contacts=(1.0,)),))
    assert math.isclose(evaluate(single, SCENE).external[0], res.external.sum(), rel_tol=1e-10)


@pytest.mark.parametrize("name", list(DESIGNED))
def test_the_guard_matters(name, rng):
    """Without the guard: the compiled ``impact`` Function's undamped L^T D L solve divides by a
    pivot of rounding size, and numpy's dense solve is no better. Over a few perturbations of the
    design by 1e-13 (far below any physical meaning) the raw split is non-finite, negative or
    O(1) away from the guarded one, while ``evaluate`` does not move."""
    tree = CASES[name]
    topology = tree.topology()
    impact = compiled_model(topology).impact
    v = approach_velocity(topology, SCENE.speed)
    guarded = evaluate(tree, SCENE).external
    p0 = design_vector(tree)
    n = len(BODY_VALUES) * tree.n_bodies
    fractions = [i for i in range(len(p0)) if i >= n or BODY_VALUES[i % len(BODY_VALUES)] in ("at", "com")]
    raw_bad = 0
    for _ in range(6):
        p = p0 + rng.normal(size=len(p0)) * 1e-13
        p[fractions] = np.clip(p[fractions], 0.0, 1.0)
        out = impact(p=p, v_minus=v, restitution=SCENE.restitution)
        assert np.array(out["delassus_pivots"]).min() < PIVOT_TOL  # what sends evaluate to the guard
        lam = np.array(out["external"]).ravel()
        if not np.all(np.isfinite(lam)) or lam.min() < 0 or relative_error(lam, guarded) > 1e-3:
            raw_bad += 1
        again = evaluate(with_values(tree, p), SCENE)
        assert not again.split_unique
        assert np.allclose(again.external, guarded, rtol=1e-9, atol=1e-9 * np.abs(guarded).max())
    assert raw_bad >= 1, "the undamped solve happened to be right every time"
    # numpy's dense solve of the singular Delassus matrix
    pl = pn.place(tree)
    J = pn.normal_jacobian(tree, pl)
    A = J @ np.linalg.solve(pn.mass_matrix(tree, pl), J.T)
    rhs = (1 + SCENE.restitution) * SCENE.speed * np.ones(len(J))
    try:
        lam_np = np.linalg.solve(A, rhs)
    except np.linalg.LinAlgError:
        lam_np = None
    assert lam_np is None or not np.all(np.isfinite(lam_np)) or relative_error(lam_np, guarded) > 1e-3 \
        or lam_np.min() < 0 or np.linalg.cond(A) > 1e14


@pytest.mark.parametrize("factor", [1e-3, 1e3, 1e6, 1e8])
def test_redundant_split_scales_with_mass(factor):
    """Impulses are homogeneous of degree one in the masses (every M entry scales, the velocities
    do not change): the guarded split must be too, whatever the units. The rod whose split comes
    from ``least_distance``. Fails for factors >= 1e6 (core bug, reported): least_distance is not
    scale invariant (test_nnls.py), so heavy designs (or high speeds) get an inaccurate split
    and, from impulses of about 1e7 N s, a pulling one."""
    rod = DESIGNED["rod-least-distance"].bodies[0]
    base = evaluate(Tree((rod,)), SCENE)
    heavy = evaluate(Tree((dataclasses.replace(rod, mass=rod.mass * factor),)), SCENE)
    assert not base.pulling and not heavy.pulling
    assert relative_error(heavy.external / factor, base.external) < 1e-9


# --------------------------------------------------------------------------------------------
# With friction: one split for every solver (least_norm_law_split)

def _welded_spatial(seed: int) -> tuple[Tree, Scene]:
    """A spatial rigid body of two welded rods on three contacts (9 rows, 6 directions), landing
    obliquely with friction: the split is not unique."""
    rng = np.random.default_rng(seed)
    rods = (Body("a", None, 0.36, 0.25, -2.4, contacts=(0.7, 1.0), radius=0.015,
                 axis=tuple(rng.normal(size=3))),
            Body("b", 0, 0.11, 0.95, -1.0, at=0.94, joint=JointKind.FIXED, contacts=(0.62,), com=0.4,
                 rpy=tuple(rng.uniform(-0.3, 0.3, 3))))
    scene = Scene(selection=ContactSelection.ALL, restitution=float(rng.choice([0.0, 1.0])), friction=1.0,
                  speed=3.2, velocity_x=float(rng.uniform(-0.3, 0.3)), velocity_z=float(rng.uniform(-0.3, 0.3)))
    return Tree(rods), scene


def _law_rows(tree: Tree, scene: Scene):
    """The impact's rows as the rung forms them: J (normal rows, x rows, z rows), A, u, and the
    cone law's answer."""
    from impulse_core.evaluate import _Impact, _metric, active_contacts, pre_impact_velocity
    from impulse_core.impact.cone import cone_impact
    from impulse_core.kinematics.spatial import SPATIAL, values_space

    space = values_space(tree, SPATIAL)
    topology = tree.topology(active_contacts(tree, scene, space=space))
    c = _Impact(tree, scene, topology, space, design_vector(tree, space.body_values),
                pre_impact_velocity(topology, scene, space))
    J, A, _, _ = _metric(c, tangent=True)
    u = J @ c.v_minus
    return J, A, u, cone_impact(A, u, scene.restitution, scene.friction)


@pytest.mark.parametrize("seed", range(4))
def test_the_law_split_is_one_whatever_split_it_starts_from(seed):
    """least_norm_law_split from the law's answer and from another answer of the same impact
    (moved along the rows' null space, still inside the polygon): the same split (1e-12), with
    the same effect (J^T lambda), the law kept, no larger a norm."""
    from impulse_core.impact.cone import POLYGON
    from impulse_core.impact.laws import least_norm_law_split, row_space_split

    tree, scene = _welded_spatial(seed)
    J, A, u, law = _law_rows(tree, scene)
    n = len(law.normal)
    lam = np.concatenate([law.normal, law.tangential.T.ravel()])
    args = (J, A, u, np.arange(n))
    first = least_norm_law_split(*args, law.normal, law.tangential, scene.restitution, scene.friction, POLYGON)
    assert first is not None
    split = np.concatenate([first[0], first[1].T.ravel()])
    assert np.max(np.abs(J.T @ (split - lam))) <= 1e-12 * np.max(np.abs(J.T @ lam))
    assert np.linalg.norm(split) <= np.linalg.norm(lam) * (1 + 1e-12)
    assert np.all(first[0] >= 0) and np.all(np.linalg.norm(first[1], axis=1) <= scene.friction * first[0] * (1 + 1e-9))
    _, N = row_space_split(J)
    assert N.shape[1] > 0
    moved = None
    for t in (0.3, 0.1, 0.03, 0.01):  # another answer: the first step along the null space that stays admissible
        other = split + t * np.max(np.abs(split)) * N[:, seed % N.shape[1]]
        on, ot = other[:n], other[n:].reshape(2, n).T
        if np.all(on >= 0) and np.all(np.linalg.norm(ot, axis=1) <= np.cos(np.pi / POLYGON) * scene.friction * on):
            moved = least_norm_law_split(*args, on, ot, scene.restitution, scene.friction, POLYGON)
            break
    assert moved is not None
    assert np.max(np.abs(moved[0] - first[0])) <= 1e-12 * np.max(first[0])
    assert np.max(np.abs(moved[1] - first[1])) <= 1e-12 * np.max(first[0])


LAW_SPLIT_CASES = ["welded0", "welded1", "welded2", "welded3", "9005", "9106", "9110", "9360", "9387", "9008", "9557",
                   "12600"]


def _law_split_case(case: str):
    """A redundant spatial impact with friction: a welded body or a random file's (tests/impulse_core/data)."""
    from pathlib import Path

    from optimizer.config.model_file import load_model_file

    if case.startswith("welded"):
        return _welded_spatial(int(case[-1]))
    model = load_model_file(Path(__file__).parent / "data" / f"redundant_friction_{case}.yaml")
    return model.tree, model.scene


@pytest.mark.parametrize("case", LAW_SPLIT_CASES)
def test_the_law_split_is_the_smallest_the_circular_law_allows(case):
    """The split against an independent convex program (cvxpy, Clarabel): the smallest norm with
    the split's effect, zero on its separating rows, a sliding pair's impulse mu lambda_n against its
    slip, a sticking pair's in the circular cone (not the polygon). And the split meets its modes'
    equations exactly (restitution and sticking rows to 1e-12, not to the cone solver's 1e-9)."""
    import cvxpy as cp

    from impulse_core.impact.cone import POLYGON
    from impulse_core.impact.laws import least_norm_law_split

    tree, scene = _law_split_case(case)
    J, A, u, law = _law_rows(tree, scene)
    n, e, mu = len(law.normal), scene.restitution, scene.friction
    normal, tangential = least_norm_law_split(J, A, u, np.arange(n), law.normal, law.tangential, e, mu, POLYGON)
    split = np.concatenate([normal, tangential.T.ravel()])
    after, scale = u + A @ split, np.max(np.abs(u))
    gap, slip = after[:n] + e * u[:n], np.column_stack([after[n : 2 * n], after[2 * n :]])
    lam = cp.Variable(3 * n)
    ln, lt = lam[:n], cp.vstack([lam[n : 2 * n], lam[2 * n :]])
    rules = [J.T @ lam == J.T @ split, ln >= 0]
    for i in range(n):
        if gap[i] > 1e-9 * scale:
            rules += [ln[i] == 0, lt[:, i] == 0]
        elif np.linalg.norm(slip[i]) > 1e-9 * scale:
            rules += [lt[:, i] == -mu * ln[i] * slip[i] / np.linalg.norm(slip[i])]
        else:
            rules += [cp.norm(lt[:, i]) <= mu * ln[i]]
            assert np.linalg.norm(slip[i]) <= 1e-12 * scale  # exactly sticking
    assert np.all(np.abs(gap[normal > 0]) <= 1e-12 * scale)  # exactly the restitution law
    cp.Problem(cp.Minimize(cp.sum_squares(lam)), rules).solve(solver=cp.CLARABEL, tol_gap_abs=1e-12, tol_gap_rel=1e-12,
                                                               tol_feas=1e-12)
    assert np.linalg.norm(split) <= np.linalg.norm(lam.value) * (1 + 1e-9)
    assert np.max(np.abs(split - lam.value)) <= 1e-5 * np.max(normal) + 1e-15  # 9557: every row separates
    assert np.all(np.linalg.norm(tangential, axis=1) <= mu * normal * (1 + 1e-12))


@pytest.mark.parametrize("case", LAW_SPLIT_CASES)
def test_the_friction_rung_and_the_landing_report_one_split(case):
    """The landing's first event and the friction rung on the same redundant impact: the same
    impulses and modes, both exact (random files 9005, 9106, 9110 differed by 0.076, 0.48 and 0.29
    before: each solver's own split; 9360 by rounding noise on zero tangential impulses, 9387 by
    2.8e-3: the cone's Newton stage stalled on the singular rows in the landing's call; 9008 by
    1.3e-9: a sticking contact on the cone's rim, each solver 1e-9 from the law at its own point; 12600 by
    0.54: the cone solver's velocities 2e-9 from its modes' own, the split refused)."""
    from pathlib import Path

    from impulse_core.kinematics.spatial import SPATIAL
    from impulse_core.timedomain.first_instant import first_instant
    from optimizer.config.model_file import load_model_file

    space = SPATIAL
    if case.startswith("welded"):
        tree, scene = _welded_spatial(int(case[-1]))
    else:
        model = load_model_file(Path(__file__).parent / "data" / f"redundant_friction_{case}.yaml")
        tree, scene, space = model.tree, model.scene, model.space
    rung = evaluate(tree, scene, ImpactModel.FRICTION, space=space)
    instant = first_instant(tree, scene, ImpactModel.FRICTION, space=space)  # the landing's first event
    assert not rung.split_unique
    for a, b in ((instant.external, rung.external), (instant.tangential, rung.tangential),
                 (instant.internal_magnitude, rung.internal_magnitude)):  # MODEL_FORMAT's relative difference, per list
        assert np.max(np.abs(a - b), initial=0.0) <= 1e-9 * np.max(np.abs(b), initial=0.0)
    assert instant.modes == rung.modes
    assert rung.notes == instant.notes == ()  # the exact circular cone in both


def test_surely_independent_never_overrules_the_svd():
    """redundant()'s bound without an SVD (laws._surely_independent) settles "independent" only
    where the SVD's rank test says so too: on random rows of mixed units, with zero columns, and
    with a row within 1e-16 .. 1e-2 of a multiple of another (both sides of RANK_TOL)."""
    from impulse_core.impact.laws import _rank, _surely_independent

    rng = np.random.default_rng(3)
    settled = near = 0
    for k in range(3000):
        r = int(rng.integers(1, 8))
        c = int(rng.integers(r, 14))
        J = rng.normal(size=(r, c)) * rng.choice([1e-6, 1.0, 1e6], c)
        if k % 2 and r > 1:
            J[-1] = J[0] * rng.uniform(-2.0, 2.0) + rng.normal(size=c) * 10.0 ** rng.uniform(-16.0, -2.0)
            near += 1
        if k % 5 == 0:
            J[:, rng.integers(0, c)] = 0.0
        if _surely_independent(J):
            settled += 1
            assert _rank(J) == r, k
    assert settled > 1000 and near > 1000
