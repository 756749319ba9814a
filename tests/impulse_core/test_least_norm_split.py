"""The smallest-norm admissible split of redundant contacts' impulses
(``impulse_core.impact.laws.least_norm_split``), checked against its definition on seeded random
redundant rows: the same effect, never a pulling entry (not even rounding's -1e-17), and the
optimality (KKT) conditions of min |x|^2 subject to J^T x = J^T lambda, x >= 0.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import nnls as scipy_nnls

from impulse_core.impact.laws import least_norm_split


def _redundant_case(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """m contact rows of rank r < m on 6 DOFs, and an admissible (>= 0) impulse with some zeros."""
    r = int(rng.integers(1, 4))
    m = int(rng.integers(r + 1, 7))
    J = rng.normal(size=(m, r)) @ rng.normal(size=(r, 6))
    lam = np.maximum(rng.normal(size=m), 0.0) * rng.uniform(0.1, 10.0)
    return J, lam


@pytest.mark.parametrize("seed", range(4))
def test_the_split_is_admissible_has_the_same_effect_and_is_the_smallest(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for _ in range(50):
        J, lam = _redundant_case(rng)
        x = least_norm_split(J, lam)
        scale = max(float(np.abs(lam).max()), 1e-300)
        assert np.all(x >= 0.0), x  # exactly: a split that pulls by rounding is still pulling
        assert np.allclose(J.T @ x, J.T @ lam, rtol=0, atol=1e-10 * scale * np.abs(J).max())
        assert np.linalg.norm(x) <= np.linalg.norm(lam) * (1 + 1e-12)
        # KKT: x = J y + mu with mu >= 0 on the zero entries of x only, i.e. the part of x in
        # J's left null space is a non-negative combination of the unit rows where x = 0
        U, s, _ = np.linalg.svd(J / np.linalg.norm(J, axis=0))
        N = U[:, int(np.sum(s > 1e-9 * s.max())):]
        zero = x <= 1e-12 * scale
        if zero.any():
            _, residual = scipy_nnls(N.T[:, zero], N.T @ x)
        else:
            residual = float(np.linalg.norm(N.T @ x))
        assert residual <= 1e-9 * scale, (x, residual)
