"""The unilateral impact law with a restitution per normal row and a friction coefficient per
tangent pair (joint stops beside contacts: ``solve_unilateral`` in the plane, ``cone_unilateral``
in space), checked row by row against the law on seeded random problems: each row is held to its
own e and each pair to its own mu, not to another row's.
"""

from __future__ import annotations

import numpy as np
import pytest

from impulse_core.impact.cone import cone_unilateral
from impulse_core.impact.coulomb import solve_unilateral


def _problem(rng: np.random.Generator, tangents: int):
    n = int(rng.integers(2, 5))
    owner = np.flatnonzero(rng.random(n) < 0.7)
    if owner.size == 0:
        owner = np.array([0])
    size = n + tangents * owner.size
    A = rng.normal(size=(size, size))
    W = A @ A.T + 0.05 * np.eye(size)
    u = rng.normal(size=size)
    u[:n] = -np.abs(u[:n]) - 0.1  # every normal row approaching
    e = rng.uniform(0.0, 1.0, n)
    mu = rng.uniform(0.05, 1.5, owner.size)
    return W, u, owner, e, mu


def _check_law(W, u, owner, e, mu, normal, tangential) -> None:
    """Signorini-Newton per row with its e; Coulomb per pair with its mu (maximal dissipation:
    a slipping pair's impulse is mu lambda_n against the slip)."""
    n, m = normal.size, owner.size
    t = tangential.reshape(m, -1)
    v = u + W @ np.concatenate([normal, t.T.ravel()])
    scale_l = max(float(normal.max()), 1e-300)
    scale_v = float(np.abs(u).max())
    gap = v[:n] + e * u[:n]
    assert normal.min() >= -1e-12 * scale_l
    assert gap.min() >= -1e-9 * scale_v
    assert np.abs(normal * gap).max() <= 1e-9 * scale_l * scale_v
    slip = v[n:].reshape(-1, m).T
    for k, i in enumerate(owner):
        assert np.linalg.norm(t[k]) <= mu[k] * normal[i] * (1 + 1e-9) + 1e-12 * scale_l, (k, t[k], mu[k], normal[i])
        speed = np.linalg.norm(slip[k])
        if speed > 1e-8 * scale_v:
            assert np.allclose(t[k], -mu[k] * normal[i] * slip[k] / speed, rtol=0, atol=1e-8 * scale_l), k


@pytest.mark.parametrize("seed", range(6))
def test_the_planar_law_holds_row_by_row_with_each_rows_coefficients(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for _ in range(15):
        W, u, owner, e, mu = _problem(rng, 1)
        sol = solve_unilateral(W, u, owner, e, mu)
        _check_law(W, u, owner, e, mu, sol.normal, sol.tangential)


@pytest.mark.parametrize("seed", range(6))
def test_the_circular_law_holds_row_by_row_with_each_rows_coefficients(seed: int) -> None:
    rng = np.random.default_rng(100 + seed)
    checked = 0
    for _ in range(15):
        W, u, owner, e, mu = _problem(rng, 2)
        r = cone_unilateral(W, u, owner, e, mu)
        if not r.exact:  # the polygon's answer (the caller warns): not the circle's law
            continue
        _check_law(W, u, owner, e, mu, r.normal, r.tangential)
        checked += 1
    assert checked >= 12
