"""Lemke's method as C (impulse_core.impact.lemke_c) returns the Python code's z bit for bit:
on random LCPs (symmetric positive definite, nonsymmetric, with repeated columns, some ending
on rays, with and without a covering vector), on the landing's kind of impact LCP (the plane's
friction LCP of three toes), and on its early answers (not finite, q >= 0)."""

from __future__ import annotations

import numpy as np
import pytest

from impulse_core.impact import coulomb
from impulse_core.impact.coulomb import lemke, unilateral_lcp, use_compiled_lemke


def _both(M, q, cover=None):
    use_compiled_lemke(False)
    try:
        a = lemke(M, q, cover)
    finally:
        compiled = use_compiled_lemke()
    b = lemke(M, q, cover)
    return a, b, compiled


def _same(a, b) -> bool:
    return (a is None and b is None) or (a is not None and b is not None and a.tobytes() == b.tobytes())


@pytest.fixture(autouse=True)
def _restore():
    before = coulomb._KERNEL
    yield
    coulomb._KERNEL = before


def test_compiled_lemke_equals_python_bit_for_bit():
    if not use_compiled_lemke():
        pytest.skip("no C compiler")
    rng = np.random.default_rng(7)
    rays = solved = 0
    for k in range(600):
        n = int(rng.integers(1, 14))
        A = rng.normal(size=(n, n)) if k % 4 else rng.integers(-2, 3, size=(n, n)).astype(float)
        M = A @ A.T if k % 3 else A  # small integers: ties in the ratio test
        if k % 5 == 0 and n > 1:
            M[:, 0] = M[:, 1]  # degenerate ties
        q = rng.normal(size=n) if k % 4 else rng.integers(-2, 2, size=n).astype(float)
        a, b, _ = _both(M, q, rng.uniform(0.5, 2.0, n) if k % 4 == 1 else None)
        assert _same(a, b), k
        rays += a is None
        solved += a is not None
    assert rays > 50 and solved > 50  # both endings seen
    for _ in range(200):  # the landing's impact LCP: three toes, friction 0.5, e = 0.8
        J = rng.normal(size=(6, 11))
        W = J @ np.linalg.inv(np.diag(rng.uniform(0.05, 2.0, 11))) @ J.T
        M, q = unilateral_lcp(W, rng.normal(size=6), np.arange(3), np.full(3, 0.8), np.full(3, 0.5))
        a, b, _ = _both(M, q)
        assert a is not None and _same(a, b)
    for M, q in [(np.eye(3), np.array([1.0, np.nan, -1.0])), (np.full((2, 2), np.inf), -np.ones(2)),
                 (np.eye(2), np.array([-0.0, 1.0]))]:
        a, b, _ = _both(M, q)
        assert _same(a, b)
