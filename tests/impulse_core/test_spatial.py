"""Spatial models (MODEL_FORMAT "Spatial models"): the same core in space.

Independent checks: Pinocchio (a free-flyer base, ``JointModelRevoluteUnaligned`` joints placed
by ``rpy``; ``impulseDynamics`` for the impulses, ``rnea`` for the joint impulses); planar trees
read as spatial give the planar answers; the frictionless complementarity law at each contact
and the momentum balance; derivatives against central differences.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
import pytest

from impulse_core.evaluate import evaluate, pre_impact_velocity
from impulse_core.impact.delassus import norms_gradient_function, response_function
from impulse_core.impact.laws import ImpactModel
from impulse_core.kinematics.spatial import PLANAR, SPATIAL
from impulse_core.model.rods import body_rotation, rotation_rpy, unit_axis
from impulse_core.model.tree import SPATIAL_BODY_VALUES, ContactSelection, JointKind, Scene, Tree, design_vector
from tests.conftest import random_tree, report

SEED = 20261125
N_TREES = 40
#: Trees whose Delassus matrix is worse conditioned than this are left out of the 1e-8
#: comparison (both codes lose digits in proportion; see test_pinocchio.py).
DELASSUS_COND_LIMIT = 1e5
SCENE = Scene(
    speed=2.0,
    restitution=0.5,
    selection=ContactSelection.ALL,
    velocity_x=0.3,
    velocity_z=-0.2,
    angular_velocity=0.4,
    angular_velocity_x=0.5,
    angular_velocity_y=-0.3,
)


def spatialize(rng: np.random.Generator, tree: Tree) -> Tree:
    """The tree with random fixed rotations, joint axes and radii (at most the radius of
    gyration across the rod: a real body's principal moments obey the triangle inequality)."""
    bodies = [
        dataclasses.replace(
            b,
            rpy=tuple(rng.uniform(-1.0, 1.0, 3)),
            axis=tuple(rng.normal(size=3)),
            radius=float(rng.uniform(0, min(0.05, b.gyration * b.length))),
        )
        for b in tree.bodies
    ]
    return Tree(tuple(bodies))


@functools.lru_cache(maxsize=None)
def spatial_trees() -> tuple[Tree, ...]:
    rng = np.random.default_rng(SEED)
    return tuple(spatialize(rng, random_tree(rng, int(rng.integers(1, 8)), p_contact=0.5)) for _ in range(N_TREES))


def _delassus(tree: Tree, scene: Scene) -> np.ndarray:
    topology = tree.topology()
    out = response_function(topology, SPATIAL)(
        p=design_vector(tree, SPATIAL_BODY_VALUES),
        v_minus=pre_impact_velocity(topology, scene, SPATIAL),
        external=np.zeros(len(tree.contacts)),
    )
    return np.array(out["delassus"])


def pinocchio_errors(trees) -> tuple[np.ndarray, int]:  # type: ignore[no-untyped-def]
    """The worst relative errors against Pinocchio (external impulses, post-impact velocities,
    revolute joint impulse magnitudes; Pinocchio merges welded bodies) over the trees whose
    Delassus matrix is well conditioned, and how many were compared."""
    from optimizer.validation.pinocchio_bridge import build_spatial, joint_force_impulses

    worst = np.zeros(3)
    compared = 0
    for tree in trees:
        if np.linalg.cond(_delassus(tree, SCENE)) > DELASSUS_COND_LIMIT:
            continue
        r = evaluate(tree, SCENE, ImpactModel.NEWTON, space=SPATIAL)
        pt = build_spatial(tree)
        v_plus, lam = pt.impulse(r.v_minus, SCENE.restitution, r.active)
        joints = joint_force_impulses(pt, r.v_minus, v_plus, r.active, lam)
        ours = {b.name: r.internal_magnitude[i - 1] for i, b in enumerate(tree.bodies) if i and b.joint is JointKind.REVOLUTE}
        scale = max(np.abs(lam).max(), 1e-300)
        errors = [
            np.abs(lam - r.external[list(r.active)]).max() / scale,
            np.abs(v_plus - r.v_plus).max() / np.abs(r.v_plus).max(),
            max((abs(joints[n] - m) for n, m in ours.items()), default=0.0) / scale,
        ]
        worst = np.maximum(worst, errors)
        compared += 1
    return worst, compared


def test_random_spatial_trees_match_pinocchio() -> None:
    """External impulses, post-impact velocities and joint impulse magnitudes (revolute joints;
    Pinocchio merges welded bodies) against Pinocchio within 1e-8 (relative)."""
    worst, compared = pinocchio_errors(spatial_trees())
    report("spatial", f"{compared} random spatial trees vs Pinocchio: external {worst[0]:.1e}, v_plus {worst[1]:.1e}, "
           f"joint impulses {worst[2]:.1e}")
    assert compared >= N_TREES // 2
    assert worst.max() < 1e-8, worst


@pytest.mark.parametrize("model", [ImpactModel.NEWTON, ImpactModel.LCP, ImpactModel.DECOUPLED])
def test_planar_trees_read_as_spatial_give_the_planar_answers(model: ImpactModel) -> None:
    rng = np.random.default_rng(SEED + 1)
    scene = dataclasses.replace(SCENE, velocity_z=0.0, angular_velocity_x=0.0, angular_velocity_y=0.0)
    for _ in range(15):
        tree = random_tree(rng, int(rng.integers(1, 8)), p_contact=0.6)
        try:
            planar = evaluate(tree, scene, model, space=PLANAR)
        except Exception as e:  # eq. 14 undefined, say: the spatial run must fail the same way
            with pytest.raises(type(e)):
                evaluate(tree, scene, model, space=SPATIAL)
            continue
        spatial = evaluate(tree, scene, model, space=SPATIAL)
        scale = max(np.abs(planar.external).max(), 1e-300)
        assert np.abs(spatial.external - planar.external).max() <= 1e-10 * scale
        assert np.abs(spatial.internal_magnitude - planar.internal_magnitude).max(initial=0.0) <= 1e-10 * scale
        v = spatial.v_plus
        assert np.allclose(v[[0, 1, 5]], planar.v_plus[:3], rtol=1e-9, atol=1e-9 * np.abs(planar.v_plus).max())
        assert np.allclose(v[[2, 3, 4]], 0.0, atol=1e-9 * np.abs(planar.v_plus).max())


def test_the_lcp_law_and_the_momentum_balance_hold_in_space() -> None:
    """Each contact: lambda >= 0, v+ + e v- >= 0 along the normal, their product 0; the change of
    the tree's linear momentum equals the sum of the normal impulses (along y)."""
    checked = 0
    for tree in spatial_trees():
        r = evaluate(tree, SCENE, ImpactModel.LCP, space=SPATIAL)
        topology = tree.topology(r.active)
        out = response_function(topology, SPATIAL)(
            p=design_vector(tree, SPATIAL_BODY_VALUES), v_minus=r.v_minus, external=r.external[list(r.active)]
        )
        J = np.array(out["contact_jacobian"])
        lam = r.external[list(r.active)]
        y = J @ r.v_plus + SCENE.restitution * (J @ r.v_minus)
        speed = SCENE.speed
        assert lam.min() >= 0.0
        assert y.min() >= -1e-9 * speed
        assert np.abs(lam * y).max() <= 1e-9 * speed * max(lam.max(), 1e-300)
        mass = sum(b.mass for b in tree.bodies)
        momentum = _linear_momentum(tree, r.v_plus) - _linear_momentum(tree, r.v_minus)
        assert np.allclose(momentum, [0.0, lam.sum(), 0.0], atol=1e-9 * mass * speed)
        checked += 1
    assert checked == N_TREES


def _linear_momentum(tree: Tree, v: np.ndarray) -> np.ndarray:
    """sum_b m_b v_G(b), by finite rotations of numpy (independent of the CasADi graph)."""
    R, O, axis_world = [], [], []
    omega, vel = [], []
    n_revolute = 0
    total = np.zeros(3)
    for i, b in enumerate(tree.bodies):
        if b.parent is None:
            R.append(body_rotation(b))
            O.append(np.zeros(3))
            omega.append(v[3:6])
            vel.append(v[0:3])
        else:
            P = R[b.parent]
            frame = P @ rotation_rpy(b.rpy)
            R.append(frame @ body_rotation(dataclasses.replace(b, rpy=(0.0, 0.0, 0.0))))
            O.append(O[b.parent] + P @ np.array([b.at * tree.bodies[b.parent].length, 0.0, 0.0]))
            w = omega[b.parent].copy()
            u = vel[b.parent] + np.cross(omega[b.parent], O[i] - O[b.parent])
            if b.joint is JointKind.REVOLUTE:
                w = w + v[6 + n_revolute] * (frame @ unit_axis(b))
                n_revolute += 1
            omega.append(w)
            vel.append(u)
        G = O[i] + R[i] @ np.array([b.com * b.length, 0.0, 0.0])
        total += b.mass * (vel[i] + np.cross(omega[i], G - O[i]))
    return total


def test_a_straight_chain_without_radius_has_unique_impulses() -> None:
    """At radius 0 a straight chain has no inertia about its axis (a singular mass matrix): the
    impulses still come out, equal to the planar ones, and finite."""
    from impulse_core.model.tree import Body

    chain = Tree(
        (
            Body("a", None, 0.5, 1.0, -1.2, contacts=(0.5,)),
            Body("b", 0, 0.4, 0.5, 0.0, contacts=(1.0,)),
            Body("c", 1, 0.3, 0.2, 0.0, axis=(1.0, 0.0, 0.0)),  # a joint about the chain's own axis
        )
    )
    scene = Scene(speed=2.0, restitution=0.3, selection=ContactSelection.ALL)
    spatial = evaluate(chain, scene, ImpactModel.NEWTON, space=SPATIAL)
    planar_chain = Tree(tuple(dataclasses.replace(b, axis=(0.0, 0.0, 1.0)) for b in chain.bodies[:2]) + (
        dataclasses.replace(chain.bodies[2], axis=(0.0, 0.0, 1.0), joint=JointKind.FIXED),))
    planar = evaluate(planar_chain, scene, ImpactModel.NEWTON, space=PLANAR)
    assert np.all(np.isfinite(spatial.v_plus))
    assert np.allclose(spatial.external, planar.external, rtol=1e-10)
    assert np.allclose(spatial.internal_magnitude, planar.internal_magnitude, rtol=1e-9, atol=1e-12)


def test_gradients_of_both_norms_in_space_match_central_differences() -> None:
    """d external_norm / dp and d internal_norm / dp with respect to every design value (rpy,
    axis and radius included), adjoint against central differences."""
    tree = next(t for t in spatial_trees() if len(t.contacts) >= 2 and t.n_bodies >= 3)
    topology = tree.topology()
    p0 = design_vector(tree, SPATIAL_BODY_VALUES)
    v = pre_impact_velocity(topology, SCENE, SPATIAL)
    f = norms_gradient_function(topology, SPATIAL)
    out = f(p=p0, v_minus=v, restitution=SCENE.restitution)
    for key in ("external_norm", "internal_norm"):
        grad = np.array(out[f"d_{key}"]).ravel()
        fd = np.zeros_like(p0)
        for k in range(p0.size):
            h = 1e-6 * max(1.0, abs(p0[k]))
            up, down = p0.copy(), p0.copy()
            up[k] += h
            down[k] -= h
            fd[k] = (float(f(p=up, v_minus=v, restitution=SCENE.restitution)[key])
                     - float(f(p=down, v_minus=v, restitution=SCENE.restitution)[key])) / (2 * h)
        assert np.abs(grad - fd).max() <= 1e-6 * np.abs(grad).max(), key
        n = len(SPATIAL_BODY_VALUES)
        spatial_entries = [b * n + j for b in range(tree.n_bodies) for j in range(len(SPATIAL_BODY_VALUES) - 7, n)]
        assert np.abs(grad[spatial_entries]).max() > 1e-6 * np.abs(grad).max(), key  # rpy, axis, radius matter


def test_spatial_bodies_in_a_planar_evaluation_and_the_relaxation_in_space_are_refused() -> None:
    from impulse_core.errors import ModelError

    tree = spatial_trees()[0]
    with pytest.raises(ModelError, match="friction-relaxed"):
        evaluate(tree, dataclasses.replace(SCENE, friction=0.5), ImpactModel.FRICTION_RELAXED, space=SPATIAL)
    with pytest.raises(ModelError, match=r"model.bodies\[0\]"):
        evaluate(tree, SCENE, space=PLANAR)


# --- friction: the circular cone ---------------------------------------------------------------


def _frictional(tree: Tree, mu: float):
    from impulse_core.evaluate import _Impact, _metric

    scene = dataclasses.replace(SCENE, friction=mu)
    r = evaluate(tree, scene, space=SPATIAL)
    topology = tree.topology(r.active)
    c = _Impact(tree, scene, topology, SPATIAL, design_vector(tree, SPATIAL_BODY_VALUES), r.v_minus)
    J, A, _, _ = _metric(c, tangent=True)
    return r, A, J @ r.v_minus


def test_exact_friction_meets_the_law_at_every_contact_in_space() -> None:
    """On random spatial trees at three friction coefficients: sign, complementarity, the
    circular cone, sliding against the slip (each to 1e-9), whenever the exact law was met; the
    polyhedral fallback (with its warning) stays rare and only on degenerate contact sets."""
    exact, total, worst = 0, 0, 0.0
    for mu in (0.2, 0.6, 1.5):
        for tree in spatial_trees():
            r, A, u = _frictional(tree, mu)
            total += 1
            if r.notes:
                assert "polyhedral" in r.notes[0] and np.linalg.cond(A) > 1e12
                continue
            exact += 1
            worst = max(worst, _law_violation(r, u, mu))
    report("spatial", f"exact friction (circular cone) on {total} scenes: law met on {exact}, worst residual {worst:.1e}")
    assert worst <= 1e-9
    assert exact >= 0.95 * total


def _law_violation(r, u: np.ndarray, mu: float) -> float:
    """The worst violation of the law at the result's active contacts (relative), from the
    velocities the result reports (not the solver's own check)."""
    active = list(r.active)
    n = len(active)
    lam, t = r.external[active], r.tangential[active]
    gap = r.contact_velocity + SCENE.restitution * u[:n]
    slip = r.tangent_velocity
    scale_l, scale_v = max(lam.max(), 1e-300), np.abs(u).max()
    out = [-lam.min() / scale_l, -gap.min() / scale_v, np.abs(lam * gap).max() / (scale_l * scale_v)]
    out.append((np.linalg.norm(t, axis=1) - mu * lam).max() / scale_l)
    moving = np.linalg.norm(slip, axis=1) > 1e-9 * scale_v
    if moving.any():
        direction = slip[moving] / np.linalg.norm(slip[moving], axis=1)[:, None]
        out.append(np.abs(t[moving] + mu * lam[moving, None] * direction).max() / scale_l)
    return max(out)


def test_the_cone_law_is_found_where_the_16_gons_active_set_is_wrong() -> None:
    """Random landing 30891 at t = 0.0761 s (friction 1, two resting contacts, the contact
    problem at the acceleration level: W and the free accelerations u as its resolve built them):
    the two contacts' tangent rows are nearly dependent (W's smallest eigenvalue 9e-8 of 6). The
    16-gon's LCP slides contact 1 and sticks contact 0; Newton's rounds from it cycle between
    (stick, slide) and (slide, slide) and meet no law, so the polyhedral answer was returned
    (``exact`` False), whose slip the landing's mode could not follow: an event every 4.5e-12 s.
    The law's answer (contact 0 slides at 1.7e-3 m/s^2 on its cone, contact 1 sticks inside it)
    is found from a finer polygon's answer (FINER), and meets every part of the law."""
    from impulse_core.impact import cone

    W = np.array([
        [3.329708965028877, 0.26200041781229944, 0.19303193719583914, 0.09036419792432827, -0.3328934517640359, 0.33015480128422536],
        [0.26200041781230815, 4.582210295337912, -0.03484402931790501, -0.05547290681472182, 0.3182065168229635, 0.4436889142311729],
        [0.1930319371958449, -0.03484402931790689, 0.9525278384745904, 0.7967750450818689, -0.6597886886731377, 0.35110655963340226],
        [0.09036419792433355, -0.055472906814724166, 0.7967750450818675, 0.8837981609500838, 0.3717160477619515, -0.19304272473223014],
        [-0.3328934517640379, 0.3182065168229571, -0.6597886886731456, 0.37171604776194533, 5.290044840175961, -1.405801493937594],
        [0.3301548012842282, 0.4436889142311741, 0.35110655963340387, -0.193042724732228, -1.4058014939375902, 2.1246218895379823],
    ])
    u = np.array([-23.743707079823334, -47.54399998616358, 1.761180824339612, 3.1545356431289053, 1.4952180665467085, -7.432065507367405])
    owner, e, mu = np.array([0, 1]), np.zeros(2), np.ones(2)
    scale_v = float(np.max(np.abs(u)))
    assert cone._rounds(W, u, owner, e, mu, *cone._polyhedral(W, u, owner, e, mu), scale_v) is None
    r = cone.cone_unilateral(W, u, owner, e, mu)
    assert r.exact
    n, t = r.normal, r.tangential
    v = u + W @ np.concatenate([n, t[:, 0], t[:, 1]])
    slip = np.column_stack([v[2:4], v[4:6]])
    speed = np.linalg.norm(slip, axis=1)
    assert np.all(n > 1.0) and np.max(np.abs(v[:2])) < 1e-12 * scale_v  # pushing, resting: Signorini
    assert np.all(np.linalg.norm(t, axis=1) <= mu * n * (1 + 1e-12))  # within the cone
    assert speed[0] > 1e-3 and speed[1] < 1e-12 * scale_v  # contact 0 slides, contact 1 sticks
    assert np.allclose(t[0], -mu[0] * n[0] * slip[0] / speed[0], rtol=0, atol=1e-9 * n.max())  # against its slip
    assert np.linalg.norm(t[1]) < 0.999 * mu[1] * n[1]  # inside its cone


def test_the_solvers_own_law_check_flags_friction_along_the_slip() -> None:
    """law_residuals (what decides between the exact and the polyhedral answer) sees a sliding
    impulse that pushes along the slip instead of against it, and a separating contact pulled."""
    from impulse_core.impact.cone import law_residuals

    W = np.diag([2.0, 3.0, 3.0])
    u = np.array([-1.0, 2.0, 0.0])  # approaching and slipping along +x
    e, mu = 0.5, 0.3
    lam_n = (1 + e) / 2.0
    right = np.array([lam_n]), np.array([[-mu * lam_n, 0.0]])  # slip stays +x (2 - 0.675 > 0)
    wrong = np.array([lam_n]), np.array([[mu * lam_n, 0.0]])
    assert max(law_residuals(W, u, e, mu, *right).values()) <= 1e-15
    assert law_residuals(W, u, e, mu, *wrong)["sliding opposes slip"] > 0.1
    assert law_residuals(W, u, e, mu, np.array([-0.1]), np.zeros((1, 2)))["normal >= 0"] > 0.5


def _one_contact_law(W: np.ndarray, u: np.ndarray, e: float, mu: float) -> np.ndarray:
    """An independent solver for one contact (rows n, x, z): separating, sticking, or sliding in
    the direction theta where the slip is parallel to (cos, sin), found by scanning theta and
    bisecting the sign changes. Returns the impulse (n, x, z)."""
    if u[0] * (1 + e) >= 0:
        return np.zeros(3)
    stick = np.linalg.solve(W, -np.array([(1 + e) * u[0], u[1], u[2]]))
    if stick[0] >= 0 and np.hypot(stick[1], stick[2]) <= mu * stick[0]:
        return stick

    def impulse(theta: float) -> np.ndarray:
        d = np.array([1.0, -mu * np.cos(theta), -mu * np.sin(theta)])
        return d * (-(1 + e) * u[0] / (W[0] @ d))

    def cross(theta: float) -> float:
        slip = (u + W @ impulse(theta))[1:]
        return slip[0] * np.sin(theta) - slip[1] * np.cos(theta)

    grid = np.linspace(0, 2 * np.pi, 3601)
    for a, b in zip(grid[:-1], grid[1:]):
        if cross(a) * cross(b) > 0:
            continue
        for _ in range(200):
            m = 0.5 * (a + b)
            a, b = (m, b) if cross(a) * cross(m) > 0 else (a, m)
        lam = impulse(0.5 * (a + b))
        slip = (u + W @ lam)[1:]
        if lam[0] >= 0 and slip @ np.array([np.cos(a), np.sin(a)]) > 0:
            return lam
    raise AssertionError("no sliding direction found")


def test_one_contact_friction_matches_an_independent_solver() -> None:
    """Single-contact spatial trees: the impulse equals a direct solution of the law (mode by mode,
    the sliding direction by bisection on the slip's angle) to 1e-9."""
    rng = np.random.default_rng(SEED + 7)
    compared = 0
    while compared < 20:
        tree = spatialize(rng, random_tree(rng, int(rng.integers(1, 6)), p_contact=0.0))
        tree = Tree(tuple(dataclasses.replace(b, contacts=(float(rng.uniform()),) if i == tree.n_bodies - 1 else ())
                          for i, b in enumerate(tree.bodies)))
        mu = float(rng.uniform(0.05, 1.5))
        r, A, u = _frictional(tree, mu)
        if len(r.active) != 1:
            continue
        expected = _one_contact_law(A, u, SCENE.restitution, mu)
        got = np.array([r.external[0], *r.tangential[0]])
        assert np.abs(got - expected).max() <= 1e-9 * max(np.abs(expected).max(), 1e-12), (got, expected)
        compared += 1


def test_planar_trees_with_friction_read_as_spatial_give_the_planar_answers() -> None:
    """The circular cone restricted to the plane is the planar law (Lemke on its LCP): the same
    impulses, no lateral friction."""
    rng = np.random.default_rng(SEED + 3)
    compared = 0
    for _ in range(20):
        tree = random_tree(rng, int(rng.integers(1, 8)), p_contact=0.6)
        mu = float(rng.uniform(0.1, 1.5))
        scene = dataclasses.replace(SCENE, velocity_z=0.0, angular_velocity_x=0.0, angular_velocity_y=0.0, friction=mu)
        planar = evaluate(tree, scene, space=PLANAR)
        if not planar.split_unique:
            continue
        spatial = evaluate(tree, scene, space=SPATIAL)
        scale = np.abs(planar.external).max()
        assert np.abs(spatial.external - planar.external).max() <= 1e-10 * scale
        assert np.abs(spatial.tangential[:, 0] - planar.tangential).max() <= 1e-10 * scale
        assert np.abs(spatial.tangential[:, 1]).max() <= 1e-10 * scale
        assert spatial.modes == planar.modes
        compared += 1
    assert compared >= 10


# --- extremes --------------------------------------------------------------------------------


def _scaled_condition(A: np.ndarray) -> float:
    d = 1.0 / np.sqrt(np.abs(np.diag(A)))
    return float(np.linalg.cond(A * d[:, None] * d[None, :]))


@pytest.mark.parametrize("kind", ["mass", "length"])
def test_extreme_spatial_trees_stay_finite_and_match_pinocchio(kind: str) -> None:
    """Mass ratios to 1e6, or lengths from 1 mm to 3 m, in space: finite impulses that agree with
    Pinocchio to 2e3 eps kappa_M kappa_A (both backward stable, losing the digits the conditioning
    takes: tests/impulse_core/test_extremes.py), and the LCP law at every contact."""
    from impulse_core.impact.delassus import mass_matrix_function
    from optimizer.validation.pinocchio_bridge import build_spatial

    rng = np.random.default_rng({"mass": 201, "length": 202}[kind])
    options = {"mass": dict(mass_ratio=1e6), "length": dict(length_range=(1e-3, 3.0))}[kind]
    worst = 0.0
    for _ in range(15):
        tree = spatialize(rng, random_tree(rng, int(rng.integers(2, 8)), p_contact=0.5, **options))
        r = evaluate(tree, SCENE, ImpactModel.NEWTON, space=SPATIAL)
        assert np.all(np.isfinite(r.external)) and np.all(np.isfinite(r.v_plus))
        topology = tree.topology()
        M, J = (np.array(x) for x in mass_matrix_function(topology, SPATIAL)(design_vector(tree, SPATIAL_BODY_VALUES)))
        bound = max(1e-12, 2e3 * np.finfo(float).eps * _scaled_condition(M) * _scaled_condition(_delassus(tree, SCENE)))
        _, lam = build_spatial(tree).impulse(r.v_minus, SCENE.restitution, r.active)
        error = np.abs(lam - r.external).max() / np.abs(lam).max()
        assert error <= bound, (error, bound)
        worst = max(worst, error / bound)
        lcp = evaluate(tree, SCENE, ImpactModel.LCP, space=SPATIAL)
        gap = J @ lcp.v_plus + SCENE.restitution * (J @ lcp.v_minus)  # every contact hits (selection all)
        speed = np.abs(J @ lcp.v_minus).max()
        assert lcp.external.min() >= 0.0 and gap.min() >= -1e-6 * speed
        assert np.abs(lcp.external * gap).max() <= 1e-6 * speed * lcp.external.max()
    report("spatial", f"extreme {kind}: 15 spatial trees, impulse error vs Pinocchio at most {worst:.1e} of eps kappa_M kappa_A")


def test_the_named_spaces_survive_pickling():
    """A forked worker unpickles its study: the module's spaces come back as themselves (the code
    asks ``space is SPATIAL``), any other space as an equal copy."""
    import pickle

    from impulse_core.kinematics.spatial import PLANAR_OFFSET

    for space in (PLANAR, PLANAR_OFFSET, SPATIAL):
        assert pickle.loads(pickle.dumps(space)) is space
    other = dataclasses.replace(SPATIAL, name="other")
    assert pickle.loads(pickle.dumps(other)) == other
