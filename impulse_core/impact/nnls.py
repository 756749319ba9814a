"""Non-negative least squares and least-distance programming (Lawson & Hanson, Solving Least
Squares Problems, 1974, ch. 23), in numpy: small, exact active-set solvers for the impulse splits.
"""

from __future__ import annotations

import numpy as np


def nnls(E: np.ndarray, f: np.ndarray, max_iter: int | None = None) -> np.ndarray:
    """argmin ||E x - f|| subject to x >= 0 (Lawson-Hanson active set, algorithm NNLS)."""
    E = np.asarray(E, dtype=float)
    f = np.asarray(f, dtype=float)
    m, n = E.shape
    x = np.zeros(n)
    passive = np.zeros(n, dtype=bool)
    tol = 10 * np.finfo(float).eps * np.linalg.norm(E, 1) * max(m, n)
    max_iter = 3 * n + 10 if max_iter is None else max_iter
    for _ in range(max_iter):
        w = E.T @ (f - E @ x)
        if passive.all() or np.max(np.where(passive, -np.inf, w)) <= tol:
            break
        passive[np.argmax(np.where(passive, -np.inf, w))] = True
        while True:
            z = np.zeros(n)
            z[passive] = np.linalg.lstsq(E[:, passive], f, rcond=None)[0]
            if np.all(z[passive] > 0):
                x = z
                break
            # the step along z - x that keeps x >= 0; a variable at 0 in both (x = z = 0, as one
            # just entered whose least-squares value is 0) blocks nothing: 0 / 0 would make alpha
            # NaN, and x all zeros (a wrong answer: the twin-contact test's LDP, residual 1 for 3e-16)
            blocking = passive & (z <= 0) & (x > z)
            alpha = np.min(x[blocking] / (x[blocking] - z[blocking])) if blocking.any() else 1.0
            x = x + alpha * (z - x)
            passive &= x > tol
            x[~passive] = 0.0
    return x


#: How far below its bound (relative to max |h|) :func:`least_distance`'s answer may leave a
#: constraint before it is rejected.
LDP_TOL = 1e-9


def least_distance(G: np.ndarray, h: np.ndarray) -> np.ndarray | None:
    """argmin ||z|| subject to G z >= h (Lawson-Hanson algorithm LDP); None if infeasible.

    The problem is homogeneous in h (z scales with it), so it is solved for h / max|h|: the
    algorithm's residual tests are then free of the units of h.
    """
    G = np.asarray(G, dtype=float)
    h = np.asarray(h, dtype=float)
    m, n = G.shape
    scale = float(np.max(np.abs(h))) if h.size else 0.0
    if scale == 0.0:
        return np.zeros(n)
    E = np.vstack([G.T, (h / scale)[None, :]])
    f = np.zeros(n + 1)
    f[-1] = 1.0
    u = nnls(E, f)
    r = E @ u - f
    if abs(r[-1]) <= 1e-12:  # f lies in the cone of E's columns: the constraints conflict
        return None
    z = -r[:n] / r[-1]
    # a constraint that conflicts only at rounding's level (a row of G at 1e-16 against an h of
    # 3e-9) leaves the residual ill-determined, and z from it can break the constraints by O(1):
    # such an answer is no answer (None), as the callers then keep what they had
    if np.min(G @ z - h / scale) < -LDP_TOL:
        return None
    return z * scale

