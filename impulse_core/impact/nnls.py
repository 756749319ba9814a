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
            blocking = passive & (z <= 0)
            alpha = np.min(x[blocking] / (x[blocking] - z[blocking]))
            x = x + alpha * (z - x)
            passive &= x > tol
            x[~passive] = 0.0
    return x


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
    return -r[:n] / r[-1] * scale
