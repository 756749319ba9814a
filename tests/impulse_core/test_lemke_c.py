"""Lemke's method as C (impulse_core.impact.lemke_c) returns the Python code's z bit for bit:
on random LCPs (symmetric positive definite, nonsymmetric, with repeated columns, some ending
on rays, with and without a covering vector), on the landing's kind of impact LCP (the plane's
friction LCP of three toes), and on its early answers (not finite, q >= 0); and so does
solve_unilateral with the LCP built, scaled and solved as C (rows with and without friction,
stops sharing no tangent row, restitution 0 to 1, a NaN falling back to Python)."""

from __future__ import annotations

import numpy as np
import pytest

from impulse_core.errors import NumericalError
from impulse_core.impact.coulomb import lemke, solve_unilateral, unilateral_lcp
from impulse_core.impact.lemke_c import compiled_lemke


@pytest.fixture(scope="module")
def kernel():
    """Lemke's method as C, or a skip without a C compiler."""
    compiled = compiled_lemke()
    if compiled is None:
        pytest.skip("no C compiler")
    return compiled


def _both(kernel, M, q, cover=None):
    return lemke(M, q, cover), lemke(M, q, cover, kernel=kernel)


def _same(a, b) -> bool:
    return (a is None and b is None) or (a is not None and b is not None and a.tobytes() == b.tobytes())


def test_compiled_lemke_equals_python_bit_for_bit(kernel):
    rng = np.random.default_rng(7)
    rays = solved = 0
    for k in range(600):
        n = int(rng.integers(1, 14))
        A = rng.normal(size=(n, n)) if k % 4 else rng.integers(-2, 3, size=(n, n)).astype(float)
        M = A @ A.T if k % 3 else A  # small integers: ties in the ratio test
        if k % 5 == 0 and n > 1:
            M[:, 0] = M[:, 1]  # degenerate ties
        q = rng.normal(size=n) if k % 4 else rng.integers(-2, 2, size=n).astype(float)
        a, b = _both(kernel, M, q, rng.uniform(0.5, 2.0, n) if k % 4 == 1 else None)
        assert _same(a, b), k
        rays += a is None
        solved += a is not None
    assert rays > 50 and solved > 50  # both endings seen
    for _ in range(200):  # the landing's impact LCP: three toes, friction 0.5, e = 0.8
        J = rng.normal(size=(6, 11))
        W = J @ np.linalg.inv(np.diag(rng.uniform(0.05, 2.0, 11))) @ J.T
        M, q = unilateral_lcp(W, rng.normal(size=6), np.arange(3), np.full(3, 0.8), np.full(3, 0.5))
        a, b = _both(kernel, M, q)
        assert a is not None and _same(a, b)
    for M, q in [(np.eye(3), np.array([1.0, np.nan, -1.0])), (np.full((2, 2), np.inf), -np.ones(2)),
                 (np.eye(2), np.array([-0.0, 1.0]))]:
        a, b = _both(kernel, M, q)
        assert _same(a, b)


def _unilateral(kernel, *args):
    try:
        a = solve_unilateral(*args)
    except NumericalError:
        a = None
    try:
        b = solve_unilateral(*args, kernel)
    except NumericalError:
        b = None
    return a, b


def test_compiled_unilateral_equals_python_bit_for_bit(kernel):
    rng = np.random.default_rng(11)
    for k in range(300):
        n = int(rng.integers(1, 6))
        friction = rng.random(n) < 0.7 if k % 4 else np.zeros(n, bool)  # some rows frictionless (stops)
        owner = np.flatnonzero(friction)
        m = len(owner)
        J = rng.normal(size=(n + m, 9))
        if k % 7 == 0 and n > 1:
            J[1] = J[0]  # twin rows
        W = J @ np.diag(rng.uniform(0.1, 3.0, 9)) @ J.T
        u = rng.normal(size=n + m) * (10.0 if k % 3 else 1e-3)
        e = rng.choice([0.0, 0.5, 0.8, 1.0], n)
        mu = np.full(m, rng.choice([0.3, 0.5, 1.0]))
        a, b = _unilateral(kernel, W, u, owner, e, mu)
        assert (a is None) == (b is None), k
        if a is not None:
            for name in ("normal", "tangential", "velocity", "slip"):
                assert getattr(a, name).tobytes() == getattr(b, name).tobytes(), (k, name)
    W, u = np.eye(2), np.array([np.nan, -1.0])  # not finite: Python's answer (an error) either way
    a, b = _unilateral(kernel, W, u, np.array([0]), np.array([0.5]), np.array([0.5]))
    assert a is None and b is None


def test_compiled_lemke_in_threads(kernel):
    """The compiled calls' work arrays are per thread: LCPs of one size solved in four threads at
    once give each its own answer."""
    from concurrent.futures import ThreadPoolExecutor

    rng = np.random.default_rng(2)
    problems = []
    for _ in range(64):
        A = rng.normal(size=(8, 8))
        problems.append((A @ A.T + np.eye(8), rng.normal(size=8)))
    expected = [lemke(M, q) for M, q in problems]

    def solve_all(_):
        return all(_same(lemke(M, q, kernel=kernel), z) for (M, q), z in zip(problems * 20, expected * 20))

    with ThreadPoolExecutor(4) as pool:
        assert all(pool.map(solve_all, range(4)))
