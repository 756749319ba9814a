"""The ladder of rigid impact models (impulse_core.impact.laws): each rung against an
independent solver or its defining law, and the automatic choice of rung.

Independent quantities come from the numpy model (tests/planar_numpy.py: its own Jacobians and
mass matrix) and independent solutions from cvxpy (Clarabel) solving the same convex programs:
- LCP: min 1/2 lambda^T A lambda - b^T lambda s.t. lambda >= 0 (A = J M^-1 J^T, b = -(1+e) J v-),
- FRICTION: min 1/2 |v+ + e v-|_M^2 over |lambda_t| <= mu lambda_n (Moreau's law, convex relaxation),
both written as sum of squares with M = C C^T (numpy Cholesky). Where contacts are redundant the
split is not unique: the unique post-impact velocity is compared, then the smallest-norm split
(a second cvxpy program: min |lambda| over the optimal set).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from pathlib import Path

import cvxpy as cp
import numpy as np
import pytest

from impulse_core import evaluate as evaluate_module
from impulse_core.impact.laws import ImpactModel, coulomb_impulse, decoupled_impulse
from impulse_core.evaluate import evaluate
from impulse_core.model.tree import Body, ContactSelection, Scene, Tree
from tests import planar_numpy as pn
from tests.conftest import contact_independence, delassus_condition, leg_with_heel_and_toe, random_tree, report
from tests.impulse_core.test_redundant import CASES as REDUNDANT_CASES

CONFIGS = Path(__file__).resolve().parents[2] / "configs"
#: cvxpy (Clarabel, default tolerances) agrees with the exact solvers to about 1e-8 here; the
#: tolerance leaves room for ill-conditioned draws.
CVXPY_TOL = 1e-6
#: Delassus conditions above this are left out of the cvxpy comparisons (cvxpy, not the core, loses digits).
COND_LIMIT = 1e6


# --------------------------------------------------------------------------------------------
# Scenes and the independent model
# --------------------------------------------------------------------------------------------
@functools.lru_cache(maxsize=None)
def random_scenes(seed: int, count: int, friction: bool = False) -> tuple[tuple[str, Tree, Scene], ...]:
    """Seeded random trees with 2-6 contacts, all hitting, independent and conditioned below
    ``COND_LIMIT``; random speed, restitution and (with ``friction``) Coulomb coefficient."""
    rng = np.random.default_rng(seed)
    out: list[tuple[str, Tree, Scene]] = []
    while len(out) < count:
        tree = random_tree(rng, int(rng.integers(1, 8)), max_contacts_per_body=2, p_contact=0.7)
        if not 2 <= len(tree.contacts) <= 6 or not contact_independence(tree)[0]:
            continue
        if delassus_condition(tree) > COND_LIMIT:
            continue
        mu = float(rng.choice([0.1, 0.3, 0.6, 1.0, 2.0])) if friction else 0.0
        scene = Scene(speed=float(rng.uniform(0.5, 5.0)), restitution=float(rng.uniform(0.0, 1.0)), friction=mu,
                      selection=ContactSelection.ALL)
        out.append((f"s{seed}-{len(out)}-{tree.n_bodies}b-{len(tree.contacts)}c", tree, scene))
    return tuple(out)


LCP_SCENES = random_scenes(3001, 40)
FRICTION_SCENES = random_scenes(3002, 30, friction=True)


@dataclasses.dataclass(frozen=True)
class Numpy:
    """The contact problem built by the numpy model: normal and tangent Jacobians of the active
    contacts, M, its Cholesky factor C (M = C C^T), the approach velocity and the momentum scale."""

    Jn: np.ndarray
    Jt: np.ndarray
    M: np.ndarray
    C: np.ndarray
    v_minus: np.ndarray
    momentum: float

    @property
    def A(self) -> np.ndarray:
        return self.Jn @ np.linalg.solve(self.M, self.Jn.T)


def numpy_model(tree: Tree, active: tuple[int, ...], speed: float) -> Numpy:
    pl = pn.place(tree)
    jac = [pn.point_jacobian(tree, pl, pl.contact_body[c], pl.contacts[c])[0] for c in active]
    M = pn.mass_matrix(tree, pl)
    v = np.zeros(pl.nv)
    v[1] = -speed
    return Numpy(
        Jn=np.array([j[1] for j in jac]).reshape(len(active), pl.nv),
        Jt=np.array([j[0] for j in jac]).reshape(len(active), pl.nv),
        M=M,
        C=np.linalg.cholesky(M),
        v_minus=v,
        momentum=sum(b.mass for b in tree.bodies) * speed,
    )


def cvxpy_lcp(m: Numpy, e: float) -> np.ndarray:
    """The frictionless impact LCP as its QP, min 1/2 |C^-1 J^T lambda + (1+e) C^T v-|^2, lambda >= 0."""
    G = np.linalg.solve(m.C, m.Jn.T)
    lam = cp.Variable(m.Jn.shape[0])
    cp.Problem(cp.Minimize(0.5 * cp.sum_squares(G @ lam + (1 + e) * m.C.T @ m.v_minus)), [lam >= 0]).solve(
        solver=cp.CLARABEL
    )
    return np.asarray(lam.value)


def cvxpy_friction(m: Numpy, e: float, mu: float) -> tuple[np.ndarray, np.ndarray]:
    """Moreau's impact law, convex relaxation: min 1/2 |v+ + e v-|_M^2 over |lambda_t| <= mu lambda_n."""
    n = m.Jn.shape[0]
    Gn, Gt = np.linalg.solve(m.C, m.Jn.T), np.linalg.solve(m.C, m.Jt.T)
    ln, lt = cp.Variable(n), cp.Variable(n)
    weighted = Gn @ ln + Gt @ lt + (1 + e) * m.C.T @ m.v_minus  # C^T (v+ + e v-)
    cp.Problem(cp.Minimize(0.5 * cp.sum_squares(weighted)), [cp.abs(lt) <= mu * ln]).solve(solver=cp.CLARABEL)
    return np.asarray(ln.value), np.asarray(lt.value)


def energy_norm(m: Numpy, dv: np.ndarray) -> float:
    """sqrt(dv^T M dv) relative to the approach: velocities of rods of any size on one scale."""
    return float(np.sqrt(abs(dv @ m.M @ dv)) / np.sqrt(m.v_minus @ m.M @ m.v_minus))


def _active(res) -> np.ndarray:
    return res.external[list(res.active)]


# --------------------------------------------------------------------------------------------
# LCP
# --------------------------------------------------------------------------------------------
def check_complementarity(res, m: Numpy, scene: Scene) -> float:
    """lambda >= 0, y = v+_n + e v-_n >= 0 (independent Jacobian on the core's v_plus),
    lambda_i y_i = 0, all to 1e-9 of the natural scales; M dv = J^T lambda. Returns the worst
    relative complementarity product."""
    lam = _active(res)
    y = m.Jn @ res.v_plus + scene.restitution * (m.Jn @ res.v_minus)
    assert lam.min() >= 0.0
    assert y.min() >= -1e-9 * scene.speed, y
    product = float(np.max(np.abs(lam * y)) / (m.momentum * scene.speed))
    assert product <= 1e-9
    assert np.allclose(m.M @ (res.v_plus - res.v_minus), m.Jn.T @ lam, rtol=0, atol=1e-9 * m.momentum)
    return product


def test_lcp_scenes_include_pulling_newton_answers():
    """The premise: many of these scenes make Newton's law pull, so the LCP is not trivially Newton."""
    pulling = sum(bool(evaluate(t, s, ImpactModel.NEWTON).pulling) for _, t, s in LCP_SCENES)
    report("contact models", f"LCP scenes: {len(LCP_SCENES)}, of which Newton's law pulls in {pulling}")
    assert pulling >= 10


def test_lcp_complementarity_and_cvxpy():
    worst_cvx = worst_product = 0.0
    for name, tree, scene in LCP_SCENES:
        res = evaluate(tree, scene, ImpactModel.LCP)
        assert res.model is ImpactModel.LCP and res.split_unique and not res.pulling
        m = numpy_model(tree, res.active, scene.speed)
        worst_product = max(worst_product, check_complementarity(res, m, scene))
        ref = cvxpy_lcp(m, scene.restitution)
        err = float(np.linalg.norm(_active(res) - ref) / np.linalg.norm(ref))
        worst_cvx = max(worst_cvx, err)
        assert err < CVXPY_TOL, name
        # separating: exactly the contacts with zero impulse
        assert set(res.separating) == {c for c, x in zip(res.active, _active(res)) if x == 0.0}
    report("contact models", f"LCP vs cvxpy on {len(LCP_SCENES)} random scenes: worst relative impulse error "
           f"{worst_cvx:.1e}; worst |lambda_i y_i| / (momentum speed) {worst_product:.1e}")


def test_automatic_choice_is_lcp_exactly_where_newton_pulls():
    for _, tree, scene in LCP_SCENES:
        auto = evaluate(tree, scene)
        newton = evaluate(tree, scene, ImpactModel.NEWTON)
        lcp = evaluate(tree, scene, ImpactModel.LCP)
        scale = max(newton.external_norm, 1e-300)
        if newton.pulling:
            assert auto.model is ImpactModel.LCP
            assert "pull" in auto.reason and auto.reason.startswith("automatic")
            assert np.array_equal(auto.external, lcp.external)
            assert auto.separating, "an LCP answer where Newton pulls must release a contact"
        else:  # Newton == LCP, so Newton, the cheaper, runs
            assert auto.model is ImpactModel.NEWTON
            assert np.allclose(lcp.external, newton.external, rtol=1e-9, atol=1e-12 * scale)
            assert np.allclose(lcp.v_plus, newton.v_plus, rtol=1e-9, atol=1e-12 * np.abs(newton.v_plus).max())


def test_lcp_never_gains_energy_on_a_landing_and_scales_with_one_plus_e():
    """Every contact closing (w = -speed): E+ - E- = (1 - e)/2 lambda^T w <= 0; and the LCP is
    homogeneous, lambda(e) = (1 + e) lambda(0), so E+ - E- = (1 - e^2) (E+(e=0) - E-)."""
    for _, tree, scene in LCP_SCENES:
        res = evaluate(tree, scene, ImpactModel.LCP)
        plastic = evaluate(tree, dataclasses.replace(scene, restitution=0.0), ImpactModel.LCP)
        e, tol = scene.restitution, 1e-9 * res.energy_before
        assert res.energy_after <= res.energy_before + tol
        w = -scene.speed * np.ones(len(res.active))
        assert math.isclose(res.energy_after - res.energy_before, (1 - e) / 2 * _active(res) @ w, abs_tol=tol)
        assert np.allclose(res.external, (1 + e) * plastic.external, rtol=1e-9, atol=1e-12 * res.external_norm)
        expected = (1 - e**2) * (plastic.energy_after - plastic.energy_before)
        assert math.isclose(res.energy_after - res.energy_before, expected, abs_tol=tol)


@pytest.mark.parametrize("name", list(REDUNDANT_CASES))
def test_redundant_contacts_under_every_rung(name):
    """Singular Delassus matrix: every rung runs, says the split is not unique, and the
    complementarity rungs give the smallest-norm non-negative split of the unique answer."""
    tree = REDUNDANT_CASES[name]
    scene = Scene(selection=ContactSelection.ALL, restitution=0.8, speed=3.43, friction=0.5)
    results = {model: evaluate(tree, scene, model) for model in ImpactModel}
    for model, res in results.items():
        assert res.model is model and not res.split_unique, model
        assert np.all(np.isfinite(res.external)) and np.all(np.isfinite(res.v_plus))
    m = numpy_model(tree, results[ImpactModel.LCP].active, scene.speed)
    lcp = results[ImpactModel.LCP]
    check_complementarity(lcp, m, scene)
    # cvxpy: the unique v_plus, then the smallest-norm split that produces it
    ref = cvxpy_lcp(m, scene.restitution)
    v_ref = lcp.v_minus + np.linalg.solve(m.M, m.Jn.T @ ref)
    assert energy_norm(m, lcp.v_plus - v_ref) < CVXPY_TOL
    lam = cp.Variable(len(ref))
    cp.Problem(cp.Minimize(cp.sum_squares(lam)), [lam >= 0, m.Jn.T @ lam == m.Jn.T @ _active(lcp)]).solve(
        solver=cp.CLARABEL
    )
    assert np.linalg.norm(_active(lcp) - lam.value) <= CVXPY_TOL * np.linalg.norm(lam.value)
    for model in (ImpactModel.FRICTION, ImpactModel.FRICTION_RELAXED):
        friction = results[model]
        ln, lt = _active(friction), friction.tangential[list(friction.active)]
        assert ln.min() >= 0 and np.all(np.abs(lt) <= 0.5 * ln + 1e-12 * m.momentum)


# --------------------------------------------------------------------------------------------
# Friction
# --------------------------------------------------------------------------------------------
def test_friction_scenes_mix_sticking_and_sliding():
    stick = slide = 0
    for _, tree, scene in FRICTION_SCENES:
        res = evaluate(tree, scene, ImpactModel.FRICTION_RELAXED)
        ln, lt = _active(res), res.tangential[list(res.active)]
        on_edge = np.abs(lt) >= scene.friction * ln * (1 - 1e-9)
        slide += int(np.sum(on_edge & (ln > 0)))
        stick += int(np.sum(~on_edge))
    report("contact models", f"friction scenes: {len(FRICTION_SCENES)}; contacts sticking {stick}, on the cone's "
           f"edge (sliding) {slide}")
    assert stick >= 10 and slide >= 10


def test_friction_in_the_cone_conserves_momentum_and_equals_cvxpy():
    worst_cvx = worst_v = 0.0
    for name, tree, scene in FRICTION_SCENES:
        res = evaluate(tree, scene, ImpactModel.FRICTION_RELAXED)
        assert res.model is ImpactModel.FRICTION_RELAXED
        m = numpy_model(tree, res.active, scene.speed)
        ln, lt = _active(res), res.tangential[list(res.active)]
        mu, tol = scene.friction, 1e-9 * m.momentum
        # inside the Coulomb cone
        assert ln.min() >= 0 and np.all(np.abs(lt) <= mu * ln + tol), name
        # momentum: M dv = Jn^T ln + Jt^T lt; linear momentum change = sum of the contact impulses
        pl = pn.place(tree)
        every = range(tree.n_bodies)
        P0, L0 = pn.momentum(tree, pl, res.v_minus, every, np.zeros(2))
        P1, L1 = pn.momentum(tree, pl, res.v_plus, every, np.zeros(2))
        assert np.allclose(P1 - P0, [lt.sum(), ln.sum()], rtol=0, atol=tol)
        moment = sum(pn.cross2(pl.contacts[c], np.array([t, n])) for c, n, t in zip(res.active, ln, lt))
        size = np.abs(pl.tip).max() + np.abs(pl.origin).max()
        assert math.isclose(L1 - L0, moment, rel_tol=0, abs_tol=tol * size)
        # joints: force impulse = subtree momentum change - contact impulses on the subtree
        for k in range(1, tree.n_bodies):
            sub = pn.descendants(tree, k)
            dP = pn.momentum(tree, pl, res.v_plus, sub, np.zeros(2))[0] - pn.momentum(
                tree, pl, res.v_minus, sub, np.zeros(2))[0]
            F = sum((np.array([t, n]) for c, n, t in zip(res.active, ln, lt) if pl.contact_body[c] in sub),
                    np.zeros(2))
            assert np.allclose(res.internal[k - 1][:2], dP - F, rtol=0, atol=tol), (name, k)
        # tangent velocity reported = independent tangent Jacobian on v_plus
        assert np.allclose(res.tangent_velocity, m.Jt @ res.v_plus, rtol=0, atol=1e-9 * scene.speed)
        # the same convex program, solved by cvxpy
        ln_ref, lt_ref = cvxpy_friction(m, scene.restitution, mu)
        v_ref = res.v_minus + np.linalg.solve(m.M, m.Jn.T @ ln_ref + m.Jt.T @ lt_ref)
        err_v = energy_norm(m, res.v_plus - v_ref)
        worst_v = max(worst_v, err_v)
        assert err_v < CVXPY_TOL, name
        if res.split_unique:
            ref = np.concatenate([ln_ref, lt_ref])
            err = float(np.linalg.norm(np.concatenate([ln, lt]) - ref) / np.linalg.norm(ref))
            worst_cvx = max(worst_cvx, err)
            assert err < CVXPY_TOL, name
    report("contact models", f"friction vs cvxpy on {len(FRICTION_SCENES)} random scenes: worst relative impulse "
           f"error {worst_cvx:.1e} (unique splits), post-impact velocity (energy norm) {worst_v:.1e}")


def test_friction_kkt_conditions():
    """The law's conditions on Moreau's weighted velocity y = (v+ + e v-) at each contact:
    y_n >= mu |y_t| everywhere; equality where the contact carries impulse; y = 0 where it sticks
    (inside the cone); on the cone's edge the friction impulse opposes y_t."""
    for name, tree, scene in FRICTION_SCENES:
        res = evaluate(tree, scene, ImpactModel.FRICTION_RELAXED)
        if not res.split_unique:
            continue
        m = numpy_model(tree, res.active, scene.speed)
        mu, e, tol = scene.friction, scene.restitution, 1e-8 * scene.speed
        ln, lt = _active(res), res.tangential[list(res.active)]
        yn = m.Jn @ (res.v_plus + e * res.v_minus)
        yt = m.Jt @ (res.v_plus + e * res.v_minus)
        assert np.all(yn >= mu * np.abs(yt) - tol), name
        carries = ln > 1e-9 * m.momentum
        assert np.allclose(yn[carries], mu * np.abs(yt[carries]), rtol=0, atol=tol), name
        inside = carries & (np.abs(lt) < mu * ln * (1 - 1e-6))
        assert np.allclose(yt[inside], 0.0, atol=tol) and np.allclose(yn[inside], 0.0, atol=tol), name
        edge = carries & ~inside
        assert np.all(lt[edge] * yt[edge] <= tol * m.momentum), name


def test_friction_energy_never_grows():
    """For a landing the law's answer is (1 + e) times the plastic one, so
    E+ - E- = (1 - e^2) (E+(e = 0) - E-) <= 0."""
    for _, tree, scene in FRICTION_SCENES:
        res = evaluate(tree, scene, ImpactModel.FRICTION_RELAXED)
        plastic = evaluate(tree, dataclasses.replace(scene, restitution=0.0), ImpactModel.FRICTION_RELAXED)
        e, tol = scene.restitution, 1e-9 * res.energy_before
        assert res.energy_after <= res.energy_before + tol
        expected = (1 - e**2) * (plastic.energy_after - plastic.energy_before)
        assert math.isclose(res.energy_after - res.energy_before, expected, abs_tol=tol)


def test_friction_reduces_to_lcp_when_mu_is_zero():
    for _, tree, scene in LCP_SCENES[:20]:
        lcp = evaluate(tree, scene, ImpactModel.LCP)
        res = evaluate(tree, scene, ImpactModel.FRICTION)
        assert res.model is ImpactModel.FRICTION and "LCP answer" in res.reason
        assert np.all(res.tangential == 0.0)
        assert np.allclose(res.external, lcp.external, rtol=1e-10, atol=1e-12 * lcp.external_norm)
        assert np.allclose(res.v_plus, lcp.v_plus, rtol=1e-10, atol=1e-12 * np.abs(lcp.v_plus).max())
        assert np.allclose(res.internal, lcp.internal, rtol=1e-10, atol=1e-12 * lcp.external_norm)
        # and continuously: a tiny mu changes little
        tiny = evaluate(tree, dataclasses.replace(scene, friction=1e-9))
        assert np.allclose(tiny.external, lcp.external, rtol=1e-6, atol=1e-8 * lcp.external_norm)


def test_friction_sticks_when_mu_is_huge():
    """mu = 1e3: where the cone is not active the contact sticks (tangential velocity 0) and
    meets Newton's restitution. The other contacts carrying impulse sit on the cone's edge with a
    normal impulse near 0: contacts that would separate while sliding, held tangentially by the
    relaxation (contact_models docstring, known limits); they are counted, not asserted away."""
    sticking = edge = 0
    for _, tree, scene in FRICTION_SCENES:
        res = evaluate(tree, dataclasses.replace(scene, friction=1e3), ImpactModel.FRICTION_RELAXED)
        m = numpy_model(tree, res.active, scene.speed)
        ln, lt = _active(res), res.tangential[list(res.active)]
        carries = ln > 1e-9 * m.momentum
        inside = carries & (np.abs(lt) < 1e3 * ln * (1 - 1e-6))
        assert np.allclose(res.tangent_velocity[inside], 0.0, atol=1e-8 * scene.speed)
        assert np.allclose(res.contact_velocity[inside], scene.restitution * scene.speed, atol=1e-8 * scene.speed)
        sticking += int(inside.sum())
        edge += int((carries & ~inside).sum())
    report("contact models", f"mu = 1e3: {sticking} contacts stick (v_t = 0 to 1e-8 speed), {edge} on the cone's "
           f"edge with a near-zero normal impulse (the relaxation's tangential grip of separating contacts)")
    assert sticking >= 2 * edge


def test_coulomb_impulse_is_homogeneous_and_matches_lcp_solver():
    """The NNLS in the cone's edge coordinates, on a made-up metric factor: doubling the target
    doubles the impulses; mu = 0 gives no tangential impulse."""
    rng = np.random.default_rng(5)
    E_n, E_t, f = rng.normal(size=(6, 3)), rng.normal(size=(6, 3)), rng.normal(size=6)
    ln, lt = coulomb_impulse(E_n, E_t, f, 0.4)
    ln2, lt2 = coulomb_impulse(E_n, E_t, 2 * f, 0.4)
    assert np.allclose(ln2, 2 * ln) and np.allclose(lt2, 2 * lt)
    assert np.all(coulomb_impulse(E_n, E_t, f, 0.0)[1] == 0.0)


# --------------------------------------------------------------------------------------------
# Selection
# --------------------------------------------------------------------------------------------
def test_frictionless_scene_without_pulling_runs_newton_and_builds_no_friction_terms(monkeypatch):
    """Nothing but the Newton path: no metric function, no tangent rows, no friction function."""

    def forbidden(*args, **kwargs):
        raise AssertionError("a frictionless scene without pulling contacts built more than the Newton model")

    monkeypatch.setattr(evaluate_module, "compiled_metric", forbidden)
    monkeypatch.setattr(evaluate_module, "compiled_friction", forbidden)
    res = evaluate(leg_with_heel_and_toe(), Scene(selection=ContactSelection.ALL))
    assert res.model is ImpactModel.NEWTON and not res.pulling and res.external.min() > 0
    assert res.tangent_velocity is None and np.all(res.tangential == 0.0)
    assert "every Newton impulse is >= 0" in res.reason


def test_pulling_scene_gets_the_lcp_and_friction_scene_gets_friction(monkeypatch):
    name, tree, scene = next(s for s in LCP_SCENES if evaluate(s[1], s[2], ImpactModel.NEWTON).pulling)
    calls = []
    monkeypatch.setattr(evaluate_module, "compiled_friction", lambda *a: calls.append(a))
    res = evaluate(tree, scene)
    assert res.model is ImpactModel.LCP and not calls, "the LCP must not build the friction function"
    monkeypatch.undo()
    res = evaluate(tree, dataclasses.replace(scene, friction=0.5))
    assert res.model is ImpactModel.FRICTION and res.tangent_velocity is not None
    assert "scene.friction = 0.5 > 0" in res.reason


def test_requested_rungs_run_and_say_so():
    tree, scene = leg_with_heel_and_toe(), Scene(selection=ContactSelection.ALL, friction=0.3)
    for model in ImpactModel:
        res = evaluate(tree, scene, model)
        assert res.model is model and res.reason.startswith("requested")
        if model not in (ImpactModel.FRICTION, ImpactModel.FRICTION_RELAXED):
            assert "scene.friction = 0.3 is ignored" in res.reason and np.all(res.tangential == 0.0)


# --------------------------------------------------------------------------------------------
# Decoupled (paper eq. 14)
# --------------------------------------------------------------------------------------------
def test_decoupled_is_eq_14():
    """lambda_i = -(1 + e) v_i / sum_j A_ij, A from the numpy model."""
    for _, tree, scene in LCP_SCENES[:10]:
        res = evaluate(tree, scene, ImpactModel.DECOUPLED)
        m = numpy_model(tree, res.active, scene.speed)
        expected = (1 + scene.restitution) * scene.speed / m.A.sum(axis=1)
        assert np.allclose(_active(res), expected, rtol=1e-10)
        assert np.allclose(decoupled_impulse(m.A, (1 + scene.restitution) * scene.speed * np.ones(len(m.A))),
                           expected)


def _symmetric_cases() -> dict[str, Tree]:
    """Designs whose Newton impulses are all equal: one contact, a flat rod on its two ends, a flat
    rod on three points, a vertical shank with two mirror-image feet."""
    rng = np.random.default_rng(17)
    single = {f"single-{k}": random_tree(rng, k + 1, p_contact=1.0, max_contacts_per_body=1) for k in range(4)}
    feet = Tree((
        Body("shank", None, 0.6, 2.0, -math.pi / 2),
        Body("left", 0, 0.2, 0.3, -0.7, contacts=(1.0,)),
        Body("right", 0, 0.2, 0.3, 0.7, contacts=(1.0,)),
    ))  # fmt: skip
    return {
        **single,
        "rod-two-ends": Tree((Body("rod", None, 1.0, 2.0, 0.0, contacts=(0.0, 1.0)),)),
        "rod-three-points": Tree((Body("rod", None, 1.0, 2.0, 0.0, contacts=(0.0, 0.5, 1.0)),)),
        "mirror-feet": feet,
    }


@pytest.mark.parametrize("name", list(_symmetric_cases()))
def test_decoupled_equals_newton_when_all_impulses_are_equal(name):
    tree = _symmetric_cases()[name]
    selection = ContactSelection.LOWEST if name.startswith("single") else ContactSelection.ALL
    scene = Scene(selection=selection, restitution=0.8, speed=3.43)
    newton = evaluate(tree, scene, ImpactModel.NEWTON)
    lam = _active(newton)
    assert np.allclose(lam, lam[0], rtol=1e-12), "premise: equal impulses"
    decoupled = evaluate(tree, scene, ImpactModel.DECOUPLED)
    assert np.allclose(decoupled.external, newton.external, rtol=1e-12)
    assert np.allclose(decoupled.v_plus, newton.v_plus, rtol=1e-12, atol=1e-12 * scene.speed)


def test_decoupled_differs_otherwise_and_its_error_is_measured():
    errors = []
    for _, tree, scene in LCP_SCENES:
        newton = evaluate(tree, scene, ImpactModel.NEWTON)
        decoupled = evaluate(tree, scene, ImpactModel.DECOUPLED)
        errors.append(float(np.linalg.norm(decoupled.external - newton.external) / newton.external_norm))
    # the leg of the conftest: unequal impulses, so eq. 14 misses eq. 11
    leg = leg_with_heel_and_toe()
    scene = Scene(selection=ContactSelection.ALL)
    newton, decoupled = evaluate(leg, scene, ImpactModel.NEWTON), evaluate(leg, scene, ImpactModel.DECOUPLED)
    leg_error = float(np.linalg.norm(decoupled.external - newton.external) / newton.external_norm)
    assert leg_error > 1e-3
    assert not np.allclose(decoupled.contact_velocity, scene.restitution * scene.speed, rtol=1e-6)
    report("contact models", f"decoupled (eq. 14) vs Newton (eq. 11), relative error of the external impulses: "
           f"leg {leg_error:.1%}; {len(errors)} random scenes median {np.median(errors):.1%}, worst "
           f"{max(errors):.0%}")
    assert np.median(errors) > 1e-3


@pytest.mark.parametrize("case", ["paper_case1", "paper_case2", "paper_case3"])
def test_decoupled_error_on_the_paper_cases(case):
    path = CONFIGS / f"{case}.yaml"
    if not path.exists():
        pytest.skip(f"{path} not written yet")
    from optimizer.config.model_file import load_model_file

    model = load_model_file(path)
    newton = evaluate(model.tree, model.scene, ImpactModel.NEWTON)
    decoupled = evaluate(model.tree, model.scene, ImpactModel.DECOUPLED)
    ext = float(np.linalg.norm(decoupled.external - newton.external) / newton.external_norm)
    internal = float(np.linalg.norm(decoupled.internal_magnitude - newton.internal_magnitude)
                     / max(newton.internal_norm, 1e-300))
    report("contact models", f"{case}: decoupled vs Newton external {ext:.2%}, internal {internal:.2%} "
           f"(external norm {decoupled.external_norm:.4f} vs {newton.external_norm:.4f} N s)")
    assert evaluate(model.tree, model.scene).model is ImpactModel.NEWTON


# --------------------------------------------------------------------------------------------
# The NNLS behind the LCP and friction rungs
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("shape", [(11, 4), (6, 6), (8, 12), (3, 5), (20, 3)])
def test_nnls_path_equals_scipy_and_the_fallback_is_exercised(shape, monkeypatch):
    """The rungs' NNLS (block principal pivoting, Lawson-Hanson fallback) against
    scipy.optimize.nnls: same residual (unique), same x where E has full column rank; every
    problem is also solved with the block pivoting switched off (Lawson-Hanson alone)."""
    from scipy.optimize import nnls as scipy_nnls

    from impulse_core.impact import laws as contact_models

    rng = np.random.default_rng(shape[0] * 100 + shape[1])
    fallbacks = 0
    original = contact_models._block_pivoting
    for k in range(40):
        E = rng.normal(size=shape) * rng.choice([1e-3, 1.0, 1e3], size=shape[1])
        if k % 4 == 3 and shape[1] > 1:  # a dependent column, as with redundant contacts
            E[:, -1] = E[:, 0] * 2.0
        f = rng.normal(size=shape[0]) * rng.choice([1e-3, 1.0, 1e3])
        fallbacks += original(E / np.linalg.norm(E, axis=0), f / np.abs(f).max()) is None
        x_ref, r_ref = scipy_nnls(E, f)
        for block in (True, False):
            if not block:
                monkeypatch.setattr(contact_models, "_block_pivoting", lambda E, f: None)
            x = contact_models.complementarity_impulse(E, f)
            monkeypatch.undo()
            assert x.min() >= 0
            assert np.linalg.norm(E @ x - f) <= r_ref * (1 + 1e-9) + 1e-12 * np.linalg.norm(f)
            if np.linalg.matrix_rank(E) == shape[1] and shape[0] >= shape[1]:
                assert np.allclose(x, x_ref, rtol=1e-8, atol=1e-10 * np.abs(x_ref).max())
    report("contact models", f"NNLS {shape}: block pivoting fell back to Lawson-Hanson in {fallbacks} of 40")


@pytest.mark.parametrize("kind", ["mass", "length", "both"])
def test_lcp_on_extreme_values(kind):
    """Mass ratios to 1e9 and lengths from 0.1 mm to 10 m (test_extremes.py's trees, all contacts
    hitting, many of them pulling under Newton's law): the LCP answer stays finite and meets
    complementarity to the digits the conditioning leaves, ERROR_FACTOR eps kappa_M kappa_A
    (the bound test_extremes.py measured for eq. 11); the friction rung stays finite and in the cone."""
    from tests.impulse_core.test_extremes import EPS, ERROR_FACTOR, extreme_trees, scaled_mass_condition

    scene = Scene(selection=ContactSelection.ALL, restitution=0.8)
    pulling = 0
    trees = extreme_trees(kind)[::2]
    for i, tree in enumerate(trees):
        res = evaluate(tree, scene, ImpactModel.LCP)
        pulling += bool(evaluate(tree, scene, ImpactModel.NEWTON).pulling)
        m = numpy_model(tree, res.active, scene.speed)
        lam = _active(res)
        y = m.Jn @ res.v_plus + scene.restitution * (m.Jn @ res.v_minus)
        tol = max(ERROR_FACTOR * EPS * scaled_mass_condition(tree) * delassus_condition(tree), 1e-12)
        assert lam.min() >= 0 and y.min() >= -tol * scene.speed, i
        assert np.max(np.abs(lam * y)) <= tol * m.momentum * scene.speed, i
        fric = evaluate(tree, dataclasses.replace(scene, friction=0.5))
        ln, lt = _active(fric), fric.tangential[list(fric.active)]
        assert np.all(np.isfinite(fric.v_plus)) and np.all(np.abs(lt) <= 0.5 * ln + 1e-9 * m.momentum), i
    report("contact models", f"extreme {kind}: LCP complementarity within eps kappa on {len(trees)} "
           f"trees ({pulling} pulling under Newton)")
