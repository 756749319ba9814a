"""The core's Lawson-Hanson solvers: ``nnls`` against scipy.optimize.nnls, ``least_distance`` by
its constraints and KKT conditions (and by homogeneity: min |z| s.t. G z >= k h is k times the
k = 1 answer)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import nnls as scipy_nnls

from impulse_core.impact.nnls import least_distance, nnls

SHAPES = [(5, 3), (10, 10), (20, 8), (3, 6), (8, 1), (1, 4)]


@pytest.mark.parametrize("shape", SHAPES)
def test_nnls_equals_scipy(shape, rng):
    m, n = shape
    for _ in range(20):
        E = rng.normal(size=(m, n))
        f = rng.normal(size=m) * rng.choice([1e-3, 1.0, 1e3])
        x = nnls(E, f)
        x_ref, r_ref = scipy_nnls(E, f)
        assert x.min() >= 0
        scale = np.linalg.norm(f)
        assert abs(np.linalg.norm(E @ x - f) - r_ref) <= 1e-10 * scale
        if m >= n:  # full column rank: the minimiser is unique
            assert np.allclose(x, x_ref, rtol=1e-8, atol=1e-10 * max(np.abs(x_ref).max(), scale))


def test_nnls_on_problems_with_known_answers(rng):
    # an interior solution: plain least squares
    E = rng.normal(size=(6, 3))
    x_true = np.array([1.0, 2.0, 0.5])
    assert np.allclose(nnls(E, E @ x_true), x_true, rtol=1e-12)
    # everything pushes negative: zero
    E = np.eye(3)
    assert np.array_equal(nnls(E, -np.ones(3)), np.zeros(3))
    # rank-deficient (duplicated column): same residual as scipy
    E = rng.normal(size=(5, 2))
    E = np.hstack([E, E[:, :1]])
    f = rng.normal(size=5)
    assert abs(np.linalg.norm(E @ nnls(E, f) - f) - scipy_nnls(E, f)[1]) < 1e-10


@pytest.mark.parametrize("k", [1e-8, 1e-3, 1e3, 1e8])
def test_nnls_is_homogeneous(k, rng):
    E = rng.normal(size=(7, 4))
    f = rng.normal(size=7)
    x = nnls(E, f)
    assert np.allclose(nnls(E, k * f), k * x, rtol=1e-9, atol=1e-12 * k)
    assert np.allclose(nnls(k * E, f), x / k, rtol=1e-9, atol=1e-12 / k)


def _check_ldp(G: np.ndarray, h: np.ndarray, z: np.ndarray) -> None:
    """Feasible, and KKT for min |z|^2/2 s.t. G z >= h: z = G_A^T u with u >= 0 on the active
    constraints A (complementarity), which for this convex problem makes z the minimiser."""
    scale = max(np.abs(h).max(), 1e-300)
    slack = G @ z - h
    assert slack.min() >= -1e-9 * scale
    active = slack <= 1e-8 * scale
    if not active.any():
        assert np.linalg.norm(z) <= 1e-9 * scale
        return
    u, r = scipy_nnls(G[active].T, z)
    assert r <= 1e-7 * max(np.linalg.norm(z), scale), "z is not a non-negative combination of active rows"


@pytest.mark.parametrize("m,n", [(1, 1), (3, 2), (5, 3), (8, 4), (2, 5)])
def test_least_distance_meets_constraints_and_kkt(m, n, rng):
    for _ in range(25):
        G = rng.normal(size=(m, n))
        z0 = rng.normal(size=n)
        slack = np.where(rng.random(m) < 0.5, 0.0, rng.uniform(0, 1, m))
        h = G @ z0 - slack  # z0 is feasible
        z = least_distance(G, h)
        assert z is not None, "a feasible problem reported infeasible"
        _check_ldp(G, h, z)
        assert np.linalg.norm(z) <= np.linalg.norm(z0) + 1e-9


def test_least_distance_known_answers():
    # z >= 1 in one dimension
    assert np.allclose(least_distance(np.array([[1.0]]), np.array([1.0])), [1.0])
    # the half-plane x + y >= 2: the closest point is (1, 1)
    assert np.allclose(least_distance(np.array([[1.0, 1.0]]), np.array([2.0])), [1.0, 1.0])
    # satisfied at the origin
    assert np.allclose(least_distance(np.eye(3), -np.ones(3)), np.zeros(3))


@pytest.mark.parametrize("m,n", [(2, 1), (4, 2), (6, 3)])
def test_least_distance_returns_none_when_infeasible(m, n, rng):
    for _ in range(20):
        G = rng.normal(size=(m, n))
        g = rng.normal(size=n)
        # g z >= 1 and -g z >= 1 cannot both hold; the other rows are anything
        G[0], G[1] = g, -g
        h = rng.normal(size=m)
        h[0], h[1] = 1.0, rng.uniform(0.1, 2.0)
        assert least_distance(G, h) is None
    # a zero row asking for a positive value
    assert least_distance(np.zeros((1, 2)), np.array([1.0])) is None


@pytest.mark.parametrize("k", [1e-6, 1e-3, 1e3, 1e6, 1e9])
def test_least_distance_is_homogeneous(k, rng):
    """min |z| s.t. G z >= k h is k times the k = 1 answer: the units of h (in evaluate: N s,
    so heavy designs or high speeds mean large h) must not matter. Fails for k >= 1e6 (core
    bug, reported): the LDP-by-NNLS reduction recovers z = -r[:n] / r[-1] with r[-1] of order
    1/(1 + |z|^2) and tests infeasibility with the absolute thresholds |r| <= 1e-12,
    |r[-1]| <= 1e-14: from |z| ~ 1e6 digits go (e.g. G = [[1]], h = [1e6] gives 1000022.1),
    from |z| ~ 1e7 it answers None (infeasible) to a feasible problem."""
    for _ in range(10):
        G = rng.normal(size=(4, 3))
        h = G @ rng.normal(size=3) - np.where(rng.random(4) < 0.5, 0.0, 1.0)
        z = least_distance(G, h)
        zk = least_distance(G, k * h)
        assert zk is not None, f"feasible problem reported infeasible at scale {k:g}"
        assert np.allclose(zk, k * z, rtol=1e-9, atol=1e-12 * k * np.linalg.norm(z))
    # and infeasibility does not depend on the scale either
    G = np.array([[1.0], [-1.0]])
    assert least_distance(G, k * np.array([1.0, 1.0])) is None


#: The twin-contact landing's least-norm split (test_landing_edge_cases, twin contacts reaching the
#: cone): the LDP min |z| s.t. G z >= h whose third row of G is rounding (1e-16) against an h of
#: 2.7e-9. Its NNLS once entered a variable whose least-squares value was 0 (0 / 0 in the step:
#: NaN, then x all zeros, residual 1 where scipy's is 3e-16), and the LDP's answer broke its
#: constraints by O(1).
TWIN_G = np.array([
    [-0.6512015628594275, 0.2755658261276951, 1.1169744227477746e-16],
    [0.6512015628594272, -0.27556582612769565, -8.482232998841035e-17],
    [1.1102230246251565e-16, 4.85722573273506e-16, 1.7088398216353577e-17],
    [0.0, 1.1102230246251565e-16, -8.933825901280557e-17],
    [-0.03626246496373703, 0.4586411454519866, -0.7071067811865475],
    [-0.35445847275231024, -0.2933016497752042, 0.7071067811865475],
    [0.3544584727523101, 0.2933016497752041, 0.7071067811865475],
    [0.036262464963736946, -0.45864114545198686, -0.7071067811865475],
    [-0.31819600778857315, -0.7519427952271905, -8.206877163270672e-17],
    [0.31819600778857327, 0.7519427952271908, 9.232181056252913e-17],
])
TWIN_H = np.array([-0.9999999999999999, -1.0, 2.668578357655526e-09, -0.20301755192295945, -0.4632626580934025, -0.13673734190719752, -0.4632626580934025, -0.13673734190719752, -0.16326265729252823, 0.16326265889367525])


def test_nnls_where_an_entering_variable_solves_to_zero():
    """No NaN step (warnings are errors here) and scipy's residual, to 1e-6 of |f| on this
    ill-conditioned problem (a column of 3e-9: x = 3.7e8)."""
    E = np.vstack([TWIN_G.T, TWIN_H[None, :]])
    f = np.zeros(4)
    f[-1] = 1.0
    with np.errstate(all="raise"):
        x = nnls(E, f)
    assert x.min() >= 0 and np.linalg.norm(E @ x - f) <= 1e-6 + scipy_nnls(E, f)[1]


def test_least_distance_never_answers_outside_its_constraints(rng):
    """The twin contacts' LDP: no answer (its callers keep their admissible impulse) rather than
    one that breaks a constraint; seeded near-degenerate LDPs (a row of G scaled to rounding):
    every answer meets G z >= h to 1e-9 of max |h|."""
    assert least_distance(TWIN_G, TWIN_H) is None
    for _ in range(300):
        m, n = rng.integers(2, 9), rng.integers(1, 5)
        G, h = rng.normal(size=(m, n)), rng.normal(size=m)
        G[rng.integers(m)] *= rng.choice([1e-16, 1e-12, 1.0])
        z = least_distance(G, h)
        if z is not None:
            assert np.min(G @ z - h) >= -1e-9 * np.max(np.abs(h))
