"""Exact Coulomb friction at impact in space: the circular cone.

The law at each contact (``coulomb`` module, with a 2D tangential impulse t and slip v+_t):
0 <= lambda_n _|_ v+_n + e v-_n >= 0; |t| <= mu lambda_n; v+_t != 0 => t = -mu lambda_n v+_t / |v+_t|.
On a circular cone it is no longer an LCP. Two stages, as in Siconos (a polyhedral LCP for the
structure, then the exact cone by a Newton method on the nonsmooth equations):

1. The polyhedral law of Stewart & Trinkle (1996): the cone replaced by its inscribed regular
   ``POLYGON``-gon, an LCP solved by Lemke's method. Its friction can fall short of the cone's
   by a relative 1 - cos(pi / k) (1.9 % at k = 16) and its slip direction by pi / k.
2. From that answer's modes (separating, sticking, sliding), Newton's method on the exact
   equations of each mode: sticking rows v+ = 0 with v+_n = -e v-_n; sliding rows v+_n = -e v-_n
   and t + mu lambda_n v+_t / |v+_t| = 0; separating rows zero impulse. The result is accepted only
   if the whole law holds at every contact (``law_residuals``: sign, complementarity, cone,
   sliding direction, each to 1e-9 of the impact's scale); a sticking guess whose tangential
   impulse leaves the cone turns sliding and a sliding guess whose slip vanishes turns sticking,
   a few rounds. If no round meets the law, the polyhedral answer is returned with ``exact``
   False (the caller warns with the bound above).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from impulse_core.impact.coulomb import ContactMode, scaled_lemke

#: Sides of the polygon that stands for the cone in stage 1.
POLYGON = 16
#: Relative tolerance of the law's checks and of Newton's convergence.
LAW_TOL = 1e-9
#: Mode-correction rounds of stage 2.
ROUNDS = 6


@dataclass(frozen=True)
class ConeImpact:
    """Impulses (N s) at n contacts: ``normal`` (n,), ``tangential`` (n, 2) along the two tangent
    rows (x, z); ``velocity`` after the impact, normal rows then x rows then z rows; ``modes``;
    ``exact``: the circular cone's law holds (else: the polyhedral answer)."""

    normal: np.ndarray
    tangential: np.ndarray
    velocity: np.ndarray
    modes: tuple[ContactMode, ...]
    exact: bool


def polygon_directions(k: int = POLYGON) -> np.ndarray:
    """The k unit directions of the inscribed polygon (2 x k)."""
    angles = 2 * np.pi * np.arange(k) / k
    return np.vstack([np.cos(angles), np.sin(angles)])


def _rows(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Indices of the normal, x and z rows of W (normal rows, then x rows, then z rows)."""
    return np.arange(n), n + np.arange(n), 2 * n + np.arange(n)


def polyhedral_impact(W: np.ndarray, v_minus: np.ndarray, restitution: float, mu: float, k: int = POLYGON):
    """Stage 1: (normal (n,), tangential (n, 2)) of the Stewart-Trinkle LCP with a k-gon cone."""
    n = W.shape[0] // 3
    N, X, Z = _rows(n)
    D = polygon_directions(k)
    G = np.zeros((2 * n, n * k))  # tangential impulse (x rows, z rows) = G beta
    for i in range(n):
        G[i, i * k : (i + 1) * k] = D[0]
        G[n + i, i * k : (i + 1) * k] = D[1]
    T = np.concatenate([X, Z])
    Wnn, Wnt, Wtn, Wtt = W[np.ix_(N, N)], W[np.ix_(N, T)], W[np.ix_(T, N)], W[np.ix_(T, T)]
    E = np.kron(np.eye(n), np.ones((1, k)))
    M = np.block(
        [
            [Wnn, Wnt @ G, np.zeros((n, n))],
            [G.T @ Wtn, G.T @ Wtt @ G, E.T],
            [mu * np.eye(n), -E, np.zeros((n, n))],
        ]
    )
    q = np.concatenate([(1.0 + restitution) * v_minus[N], G.T @ v_minus[T], np.zeros(n)])
    s = 1.0 / np.sqrt(np.maximum(np.abs(np.diag(Wnn)), np.finfo(float).tiny))  # unit velocity diagonals
    z = scaled_lemke(M, q, np.concatenate([s, np.repeat(s, k), 1.0 / s]), v_minus, "the polyhedral Coulomb impact LCP")
    t = G @ z[n : n + n * k]
    return z[:n], np.column_stack([t[:n], t[n:]])


def law_residuals(
    W: np.ndarray, v_minus: np.ndarray, restitution: float, mu: float, normal: np.ndarray, tangential: np.ndarray
) -> dict[str, float]:
    """The worst violation of each part of the law, relative to the impact's scale (impulses to
    the largest normal impulse, velocities to the largest approach speed)."""
    n = normal.size
    N, X, Z = _rows(n)
    v = v_minus + W @ np.concatenate([normal, tangential[:, 0], tangential[:, 1]])
    slip = np.column_stack([v[X], v[Z]])
    gap = v[N] + restitution * v_minus[N]
    scale_l = max(float(np.max(np.abs(normal), initial=0.0)), np.finfo(float).tiny)
    scale_v = max(float(np.max(np.abs(v_minus), initial=0.0)), np.finfo(float).tiny)
    t_norm = np.linalg.norm(tangential, axis=1)
    s_norm = np.linalg.norm(slip, axis=1)
    sliding = s_norm > LAW_TOL * scale_v
    opposing = tangential[sliding] + mu * normal[sliding, None] * slip[sliding] / s_norm[sliding, None]
    return {
        "normal >= 0": max(0.0, -float(np.min(normal, initial=0.0))) / scale_l,
        "restitution >= 0": max(0.0, -float(np.min(gap, initial=0.0))) / scale_v,
        "complementarity": float(np.max(np.abs(normal * gap), initial=0.0)) / (scale_l * scale_v),
        "cone": max(0.0, float(np.max(t_norm - mu * normal, initial=0.0))) / scale_l,
        "sliding opposes slip": float(np.max(np.abs(opposing), initial=0.0)) / scale_l,
    }


def _equations(W, v_minus, e, mu, modes, lam):
    """The exact law's equations F(lambda) = 0 for fixed modes and their Jacobian, or None
    where a sliding contact has no slip (its direction is undefined)."""
    n = len(modes)
    N, X, Z = _rows(n)
    v = v_minus + W @ lam
    eye = np.eye(3 * n)
    F, J = [], []
    for i, mode in enumerate(modes):
        if mode is ContactMode.SEPARATING:
            F += [lam[N[i]], lam[X[i]], lam[Z[i]]]
            J += [eye[N[i]], eye[X[i]], eye[Z[i]]]
            continue
        F.append(v[N[i]] + e * v_minus[N[i]])
        J.append(W[N[i]])
        if mode is ContactMode.STICKING:
            F += [v[X[i]], v[Z[i]]]
            J += [W[X[i]], W[Z[i]]]
            continue
        s = np.array([v[X[i]], v[Z[i]]])
        norm = np.linalg.norm(s)
        if norm == 0.0:
            return None
        u = s / norm
        P = (np.eye(2) - np.outer(u, u)) / norm  # d(s / |s|) / ds
        dS = np.vstack([W[X[i]], W[Z[i]]])
        for a, r in enumerate((X[i], Z[i])):
            F.append(lam[r] + mu * lam[N[i]] * u[a])
            row = mu * lam[N[i]] * (P[a] @ dS)
            row[r] += 1.0
            row[N[i]] += mu * u[a]
            J.append(row)
    return np.array(F), np.array(J)


def _newton(W, v_minus, e, mu, modes, start_n, start_t):
    """Stage 2 for fixed modes: damped Newton (backtracking on |F|) from the polyhedral answer;
    (normal, tangential), or None if a sliding contact loses its slip."""
    lam = np.concatenate([start_n, start_t[:, 0], start_t[:, 1]])
    current = _equations(W, v_minus, e, mu, modes, lam)
    for _ in range(100):
        if current is None:
            return None
        F, J = current
        try:
            step = np.linalg.solve(J, -F)
        except np.linalg.LinAlgError:
            step = np.linalg.lstsq(J, -F, rcond=None)[0]
        size = 1.0
        while size > 1e-6:  # backtrack until |F| decreases
            trial = _equations(W, v_minus, e, mu, modes, lam + size * step)
            if trial is not None and np.linalg.norm(trial[0]) < np.linalg.norm(F):
                break
            size *= 0.5
        else:
            break
        lam, current = lam + size * step, trial
        if np.max(np.abs(size * step)) <= 1e-15 * max(np.max(np.abs(lam)), np.finfo(float).tiny):
            break
    n = start_n.size
    return lam[:n], np.column_stack([lam[n : 2 * n], lam[2 * n :]])


def modes_of(normal, tangential, velocity, scale_v) -> tuple[ContactMode, ...]:
    """Each contact's mode from its impulses and its slip after the impact."""
    n = normal.size
    N, X, Z = _rows(n)
    scale_l = max(float(np.max(np.abs(normal), initial=0.0)), np.finfo(float).tiny)
    out = []
    for i in range(n):
        slip = np.hypot(velocity[X[i]], velocity[Z[i]])
        if normal[i] <= 1e-9 * scale_l:
            out.append(ContactMode.SEPARATING)
        elif slip <= LAW_TOL * scale_v:
            out.append(ContactMode.STICKING)
        else:
            out.append(ContactMode.SLIDING)
    return tuple(out)


def cone_impact(W: np.ndarray, v_minus: np.ndarray, restitution: float, mu: float) -> ConeImpact:
    """Normal and tangential impulses of the exact Newton-Coulomb law with a circular cone.

    Args:
        W: J M^-1 J^T with J's rows: the n normal rows, then the n x rows, then the n z rows.
        v_minus: those rows' velocities before the impact (3n).
        restitution: Newton's e in [0, 1].
        mu: Coulomb coefficient >= 0.

    Raises:
        NumericalError: stage 1 found no solution.
    """
    normal, tangential = polyhedral_impact(W, v_minus, restitution, mu)
    scale_v = max(float(np.max(np.abs(v_minus), initial=0.0)), np.finfo(float).tiny)

    def velocity(nrm, tan):
        return v_minus + W @ np.concatenate([nrm, tan[:, 0], tan[:, 1]])

    n = normal.size
    modes = list(modes_of(normal, tangential, velocity(normal, tangential), scale_v))
    for _ in range(ROUNDS):
        polished = _newton(W, v_minus, restitution, mu, modes, normal, tangential)
        if polished is None:  # a sliding guess lost its slip: it sticks on the circle
            v = velocity(normal, tangential)
            stuck = [i for i, m in enumerate(modes) if m is ContactMode.SLIDING]
            if not stuck:
                break
            i = min(stuck, key=lambda i: np.hypot(v[n + i], v[2 * n + i]))
            modes[i] = ContactMode.STICKING
            continue
        nrm, tan = polished
        if max(law_residuals(W, v_minus, restitution, mu, nrm, tan).values()) <= LAW_TOL:
            v = velocity(nrm, tan)
            return ConeImpact(nrm, tan, v, modes_of(nrm, tan, v, scale_v), True)
        changed = False
        v = velocity(nrm, tan)
        for i, m in enumerate(modes):
            outside = np.linalg.norm(tan[i]) > mu * nrm[i] * (1 + LAW_TOL)
            still = np.hypot(v[n + i], v[2 * n + i]) <= 1e3 * LAW_TOL * scale_v
            if m is ContactMode.STICKING and outside:
                modes[i], changed = ContactMode.SLIDING, True
            elif m is ContactMode.SLIDING and still:
                modes[i], changed = ContactMode.STICKING, True
            elif m is not ContactMode.SEPARATING and nrm[i] < 0:
                modes[i], changed = ContactMode.SEPARATING, True
        if not changed:
            break
    v = velocity(normal, tangential)
    return ConeImpact(normal, tangential, v, modes_of(normal, tangential, v, scale_v), False)


__all__ = ["POLYGON", "ConeImpact", "cone_impact", "law_residuals", "polygon_directions", "polyhedral_impact"]
