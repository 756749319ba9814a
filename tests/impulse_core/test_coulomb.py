"""Exact Coulomb friction at impact (impulse_core.impact.coulomb): Lemke's method against an
exact enumeration of complementary bases, and the impact law checked contact by contact on
seeded random trees with the independent numpy model (its own Jacobians and mass matrix):
Newton's restitution (unilateral), the friction cone, sliding against the post-impact slip,
momentum balance; the paper's case 3 against the exact Newton-Coulomb values the friction issue
quotes; mu -> 0 is the LCP rung."""

from __future__ import annotations

import dataclasses
import itertools
import json
from pathlib import Path

import numpy as np
import pytest

from impulse_core.evaluate import evaluate
from impulse_core.impact.coulomb import ContactMode, lemke
from impulse_core.impact.laws import ImpactModel
from optimizer.cli.main import main
from optimizer.config.model_file import load_model_file
from tests import planar_numpy as pn
from tests.conftest import report
from tests.impulse_core.test_contact_models import FRICTION_SCENES, _active, numpy_model

CONFIGS = Path(__file__).resolve().parents[2] / "configs"


def enumerate_lcp(M: np.ndarray, q: np.ndarray) -> list[np.ndarray]:
    """Every solution of the LCP (M, q) with a nonsingular principal block, by trying each of the
    2^n sets of variables allowed to be positive."""
    n = q.size
    out = []
    for basic in itertools.product((False, True), repeat=n):
        b = np.array(basic)
        z = np.zeros(n)
        if b.any():
            try:
                z[b] = np.linalg.solve(M[np.ix_(b, b)], -q[b])
            except np.linalg.LinAlgError:
                continue
        w = M @ z + q
        if z.min() >= -1e-10 and w.min() >= -1e-10:
            out.append(z)
    return out


@pytest.mark.parametrize("seed", range(40))
def test_lemke_equals_the_enumeration_on_p_matrices(seed: int) -> None:
    """A P-matrix LCP has exactly one solution: Lemke's equals the enumeration's."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 7))
    A = rng.standard_normal((n, n))
    M = A @ A.T + 0.1 * np.eye(n) + (rng.standard_normal((n, n)) * 0.3 if seed % 2 else 0)  # some nonsymmetric
    if np.any(
        [np.linalg.det(M[np.ix_(s, s)]) <= 0 for k in range(1, n + 1) for s in itertools.combinations(range(n), k)]
    ):
        M = A @ A.T + 0.1 * np.eye(n)
    q = rng.standard_normal(n)
    (expected,) = enumerate_lcp(M, q)
    z = lemke(M, q)
    assert z is not None and z.min() >= 0
    np.testing.assert_allclose(z, expected, atol=1e-10 * max(1.0, np.abs(expected).max()))


def _reference_lemke(M: np.ndarray, q: np.ndarray, cover: np.ndarray) -> np.ndarray | None:
    """Lemke's method as the textbook writes it (numpy arrays, pivots row by row): the reference
    that :func:`lemke`'s whole-tableau pivots and Python ratio test must follow pivot for pivot."""
    n = q.size
    if np.all(q >= 0):
        return np.zeros(n)
    T = np.hstack([np.eye(n), -M, -cover[:, None], q[:, None]])
    basis = list(range(n))
    tol = 1e-12 * max(1.0, float(np.max(np.abs(T[:, :-1]))))

    def pivot(row: int, column: int) -> None:
        T[row] /= T[row, column]
        for r in range(n):
            if r != row:
                T[r] -= T[r, column] * T[row]
        basis[row] = column

    first = int(np.argmin(q / cover))
    pivot(first, 2 * n)
    entering = n + first
    for _ in range(50 * n + 50):
        rows = np.flatnonzero(T[:, entering] > tol)
        if rows.size == 0:
            return None
        ratios = T[rows, -1] / T[rows, entering]
        ties = rows[ratios <= ratios.min() + tol * (1.0 + abs(ratios.min()))]
        row = next((int(r) for r in ties if basis[r] == 2 * n), int(ties[0]))
        leaving = basis[row]
        pivot(row, entering)
        if leaving == 2 * n:
            z = np.zeros(n)
            for r, var in enumerate(basis):
                if n <= var < 2 * n:
                    z[var - n] = T[r, -1]
            return np.maximum(z, 0.0)
        entering = leaving + n if leaving < n else leaving - n
    return None


def test_lemke_pivots_as_the_textbook_does() -> None:
    """:func:`lemke` (whole-tableau pivots, the ratio test in Python floats: the landing's events
    solve thousands of these) gives the textbook pivoting's answer bit for bit, on LCPs of 1 to 5
    contacts with friction (:func:`unilateral_lcp`; twin contacts and contacts at rest make ties,
    whose order changes the answer), with the default and random covering vectors."""
    from impulse_core.impact.coulomb import unilateral_lcp

    rng = np.random.default_rng(7)
    solved = rays = 0
    for trial in range(300):
        n = int(rng.integers(1, 6))
        A = rng.standard_normal((2 * n, n + 2))
        if trial % 2 and n > 1:  # twin contacts: identical rows, ties in the ratio test
            A[1], A[n + 1] = A[0], A[n]
        u = A @ rng.standard_normal(n + 2)
        u[n:] *= rng.random(n) < 0.5  # some at rest tangentially: zeros in q, more ties
        e = rng.uniform(0.0, 1.0, n) * (trial % 3 > 0)  # some at the acceleration level (e = 0)
        M, q = unilateral_lcp(A @ A.T, u, np.arange(n), e, rng.uniform(0.2, 1.0, n))
        cover = np.ones(q.size) if trial % 4 else rng.uniform(0.5, 2.0, q.size)
        z, ref = lemke(M, q, cover), _reference_lemke(M, q, cover)
        assert (z is None) == (ref is None)
        if z is not None:
            assert np.array_equal(z, ref)
            solved += 1
        rays += z is None
    assert solved > 250 and rays < 30


def test_lemke_reports_a_problem_without_solution() -> None:
    """z >= 0 with -z - 1 >= 0 has no solution: a ray, None."""
    assert lemke(np.array([[-1.0]]), np.array([-1.0])) is None


def _law_residuals(res, m, scene) -> dict[str, float]:
    """How far the result is from each part of the law at each contact, in velocity or impulse
    units relative to the scene's speed and momentum (0 where it holds)."""
    mu, e = scene.friction, scene.restitution
    ln, lt = _active(res), res.tangential[list(res.active)]
    v_plus = m.v_minus + np.linalg.solve(m.M, m.Jn.T @ ln + m.Jt.T @ lt)  # the numpy model's own response
    yn = m.Jn @ v_plus + e * (m.Jn @ m.v_minus)
    vt = m.Jt @ v_plus
    sliding = np.abs(vt) > 1e-7 * scene.speed
    return {
        "v_plus": float(np.abs(v_plus - res.v_plus).max()) / scene.speed,
        "normal >= 0": float(max(0.0, -ln.min())) / m.momentum,
        "restitution >= 0": float(max(0.0, -yn.min())) / scene.speed,
        "complementarity": float(np.abs(ln * yn).max()) / (m.momentum * scene.speed),
        "cone": float(max(0.0, (np.abs(lt) - mu * ln).max())) / m.momentum,
        "sliding opposes slip": float(np.abs(lt[sliding] + mu * ln[sliding] * np.sign(vt[sliding])).max(initial=0.0))
        / m.momentum,
    }


def test_the_law_holds_at_every_contact_of_random_trees() -> None:
    worst: dict[str, float] = {}
    modes = {m: 0 for m in ContactMode}
    for name, tree, scene in FRICTION_SCENES:
        res = evaluate(tree, scene)
        assert res.model is ImpactModel.FRICTION and res.reason.startswith("automatic")
        m = numpy_model(tree, res.active, scene.speed)
        for law, r in _law_residuals(res, m, scene).items():
            worst[law] = max(worst.get(law, 0.0), r)
            assert r < 1e-8, (name, law, r)  # Delassus conditions up to 1e6 leave about 1e-9
        for mode in res.modes:
            modes[mode] += 1
    report("coulomb", "exact friction on 30 random trees, worst residuals: "
           + ", ".join(f"{k} {v:.1e}" for k, v in worst.items()))  # fmt: skip
    report("coulomb", "modes: " + ", ".join(f"{k.value} {v}" for k, v in modes.items()))
    assert min(modes.values()) >= 3  # every mode was exercised


def test_momentum_balance_with_friction() -> None:
    for name, tree, scene in FRICTION_SCENES:
        res = evaluate(tree, scene)
        ln, lt = _active(res), res.tangential[list(res.active)]
        pl = pn.place(tree)
        every = range(tree.n_bodies)
        P0, _ = pn.momentum(tree, pl, res.v_minus, every, np.zeros(2))
        P1, _ = pn.momentum(tree, pl, res.v_plus, every, np.zeros(2))
        tol = 1e-9 * sum(b.mass for b in tree.bodies) * scene.speed
        np.testing.assert_allclose(P1 - P0, [lt.sum(), ln.sum()], rtol=0, atol=tol, err_msg=name)


@pytest.mark.parametrize(("mu", "heel"), [(0.3, 0.3322), (1.0, 0.6612)])
def test_paper_case_3_with_friction_is_the_exact_law(mu: float, heel: float) -> None:
    """Issue #12's exact Newton-Coulomb values on case 3: heel 0.3322 N s at mu = 0.3 (the
    relaxation gave 0.3984), 0.6612 at mu = 1 (1.2125); the heel leaves at e v = 2.744 m/s (the
    relaxation: 3.98)."""
    model = load_model_file(CONFIGS / "paper_case3.yaml")
    scene = dataclasses.replace(model.scene, friction=mu)
    exact = evaluate(model.tree, scene)
    relaxed = evaluate(model.tree, scene, ImpactModel.FRICTION_RELAXED)
    assert abs(exact.external[0] - heel) < 5e-5
    assert relaxed.external[0] > heel * 1.15  # the relaxation's bias, as the issue measured it
    np.testing.assert_allclose(exact.contact_velocity, scene.restitution * scene.speed, rtol=1e-10)
    assert exact.modes[0] is ContactMode.SLIDING


def test_json_carries_modes_tangential_and_the_relaxations_warning(tmp_path: Path, capsys) -> None:
    text = (CONFIGS / "paper_case3.yaml").read_text().replace("friction: 0.0", "friction: 0.3")
    assert "friction: 0.3" in text
    f = tmp_path / "case3_mu03.yaml"
    f.write_text(text)
    assert main(["evaluate", "--json", str(f)]) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["model"] == "friction" and record["modes"] == ["sliding"] * 4
    assert abs(record["external"][0] - 0.3322) < 5e-5 and len(record["tangential"]) == 4
    assert record["warnings"] == []
    assert main(["evaluate", "--json", "--model", "friction-relaxed", str(f)]) == 0
    relaxed = json.loads(capsys.readouterr().out)
    assert relaxed["model"] == "friction-relaxed" and any("not Coulomb's law" in w for w in relaxed["warnings"])


@pytest.mark.parametrize("seed", range(30))
def test_the_law_holds_for_oblique_approaches(seed: int) -> None:
    """Random Delassus matrices W = J M^-1 J^T and approaches with tangential velocity (a landing
    with horizontal or turning motion): restitution, cone, and sliding against the slip."""
    from impulse_core.impact.coulomb import coulomb_impact

    rng = np.random.default_rng(1000 + seed)
    n, nv = int(rng.integers(1, 5)), 8
    J = rng.standard_normal((2 * n, nv))
    R = rng.standard_normal((nv, nv))
    W = J @ np.linalg.solve(R @ R.T + 0.1 * np.eye(nv), J.T)
    v = rng.standard_normal(2 * n)
    v[:n] = -np.abs(v[:n]) - 0.1  # every contact closing
    mu, e = float(rng.choice([0.1, 0.5, 1.0, 3.0])), float(rng.uniform(0, 1))
    r = coulomb_impact(W, v, e, mu)
    np.testing.assert_allclose(r.velocity, v + W @ np.concatenate([r.normal, r.tangential]), atol=1e-12)
    vn, vt = r.velocity[:n], r.velocity[n:]
    scale = np.abs(v).max()
    assert r.normal.min() >= 0 and (vn + e * v[:n]).min() >= -1e-10 * scale
    assert np.abs(r.normal * (vn + e * v[:n])).max() <= 1e-10 * scale * max(1.0, r.normal.max())
    assert np.all(np.abs(r.tangential) <= mu * r.normal + 1e-12)
    for i in range(n):
        if r.modes[i] is ContactMode.SLIDING:
            assert r.tangential[i] == pytest.approx(-mu * r.normal[i] * np.sign(vt[i]), abs=1e-10)
        elif r.modes[i] is ContactMode.STICKING:
            assert abs(vt[i]) <= 1e-8 * scale


def _case3_variants(count: int, rng: np.random.Generator):
    """Case 3 with its angles moved +-0.1 rad, masses x exp(+-0.3), random friction and approach."""
    from impulse_core.model.tree import BODY_VALUES, design_vector, with_values

    model = load_model_file(CONFIGS / "paper_case3.yaml")
    tree, n_body = model.tree, len(BODY_VALUES)
    for k in range(count):
        p = design_vector(tree)
        p[BODY_VALUES.index("angle") : n_body * tree.n_bodies : n_body] += rng.uniform(-0.1, 0.1, tree.n_bodies)
        p[BODY_VALUES.index("mass") : n_body * tree.n_bodies : n_body] *= np.exp(rng.uniform(-0.3, 0.3, tree.n_bodies))
        scene = dataclasses.replace(
            model.scene,
            friction=float(rng.choice([0.2, 0.5, 1.0, 3.0])),
            velocity_x=float(rng.uniform(-1.5, 1.5)),
            angular_velocity=float(rng.uniform(-1, 1)),
        )
        yield f"case3-{k}", with_values(tree, p), scene


def test_derivatives_along_the_mode_equal_finite_differences() -> None:
    """d(impulses)/d(design values) by the implicit function theorem on the reported modes, against
    central differences of evaluate() where the modes stay the same on both sides."""
    from impulse_core.evaluate import friction_derivatives
    from impulse_core.model.tree import BODY_VALUES, design_vector, with_values

    rng = np.random.default_rng(11)
    checked, worst, modes = 0, 0.0, set()
    for name, tree, scene in _case3_variants(8, rng):
        res, d_normal, d_tangential = friction_derivatives(tree, scene)
        assert res.split_unique, name
        modes |= set(res.modes)
        p = design_vector(tree)
        inner = [
            b * len(BODY_VALUES) + BODY_VALUES.index(v)
            for b in range(tree.n_bodies)
            for v in ("length", "mass", "angle")
        ]
        for k in rng.choice(inner, size=8, replace=False):  # values inside their bounds ("at" and contacts sit at 1)
            h = 1e-6 * max(1.0, abs(p[k]))
            hi, lo = p.copy(), p.copy()
            hi[k] += h
            lo[k] -= h
            up, down = evaluate(with_values(tree, hi), scene), evaluate(with_values(tree, lo), scene)
            if up.modes != res.modes or down.modes != res.modes or up.active != res.active:
                continue
            act = list(res.active)
            fd_n = (up.external[act] - down.external[act]) / (2 * h)
            fd_t = (up.tangential[act] - down.tangential[act]) / (2 * h)
            scale = max(1.0, float(np.abs(d_normal).max()), float(np.abs(d_tangential).max()))
            err = max(np.abs(fd_n - d_normal[:, k]).max(), np.abs(fd_t - d_tangential[:, k]).max()) / scale
            worst = max(worst, err)
            checked += 1
            assert err < 1e-6, (name, k, err)
    report("coulomb", f"derivatives along the mode vs central differences: {checked} columns, worst {worst:.1e}, "
           f"modes {sorted(m.value for m in modes)}")  # fmt: skip
    assert checked >= 40 and {ContactMode.STICKING, ContactMode.SLIDING} <= modes


@pytest.mark.parametrize("seed", range(20))
def test_a_contact_without_normal_impulse_takes_no_friction(seed: int) -> None:
    """Coulomb's law, |t| <= mu n: a contact the law leaves without normal impulse (it moves away)
    has exactly no tangential impulse, in the plane (Lemke's LCP) and in space (the cone's
    polygon, then Newton), not the 1e-17 that Lemke's basic friction variables can keep."""
    from impulse_core.impact.cone import cone_unilateral
    from impulse_core.impact.coulomb import solve_unilateral

    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 5))
    for tangents in (1, 2):
        A = rng.normal(size=(n * (1 + tangents), n * (1 + tangents)))
        W = A @ A.T + 0.1 * np.eye(len(A))
        u = rng.normal(size=len(A))
        u[: n // 2] = np.abs(u[: n // 2]) + 0.5  # some contacts move away
        e, mu, owner = np.full(n, 0.5), np.full(n, float(rng.choice([0.3, 1.0]))), np.arange(n)
        if tangents == 1:
            sol = solve_unilateral(W, u, owner, e, mu)
            normal, tangential = sol.normal, sol.tangential[:, None]
        else:
            law = cone_unilateral(W, u, owner, e, mu)
            normal, tangential = law.normal, law.tangential
        unloaded = normal <= 0
        assert not np.any(tangential[unloaded]), (tangents, normal, tangential)
        assert np.all(np.linalg.norm(tangential, axis=1) <= mu * normal + 1e-12)
