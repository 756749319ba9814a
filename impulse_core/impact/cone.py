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
   a few rounds. If no round meets the law, the rounds start again from the answers of finer
   polygons (``FINER``: where the tangent rows are nearly dependent the 16-gon's active set can
   be wrong and the rounds cycle between wrong modes); if none meets it, the polyhedral answer is
   returned with ``exact`` False (the caller warns with the bound above).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from impulse_core.errors import NumericalError
from impulse_core.impact.coulomb import ContactMode, scaled_lemke, unloaded_without_friction

#: Sides of the polygon that stands for the cone in stage 1.
POLYGON = 16
#: Relative tolerance of the law's checks and of Newton's convergence.
LAW_TOL = 1e-9
#: Mode-correction rounds of stage 2.
ROUNDS = 6
#: Stage 1's answer meeting the circular cone's law to this (relative) is the answer: every
#: contact sticking inside the polygon (so inside the circle) or needing no friction.
EXACT_TOL = 1e-12
#: Finer polygons whose answers start stage 2 again where the rounds from the POLYGON-gon's
#: answer met no law: its active set can be wrong where the tangent rows are nearly dependent
#: (random landing 30891: the 16-gon slides the contact that sticks, and the rounds cycle between
#: two wrong mode sets; the 32-gon's modes are the law's).
FINER = (2 * POLYGON, 4 * POLYGON)


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


def _rows(n: int, m: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Indices of the normal, x and z rows of W (n normal rows, then m x rows, then m z rows;
    m = n by default: one tangent pair per contact)."""
    m = n if m is None else m
    return np.arange(n), n + np.arange(m), n + m + np.arange(m)


def _pairs(n: int, owner: np.ndarray) -> np.ndarray:
    """Per normal row, its tangent pair (index into ``owner``), or -1 (a frictionless row)."""
    pair = np.full(n, -1)
    pair[owner] = np.arange(len(owner))
    return pair


def polyhedral_impact(W: np.ndarray, v_minus: np.ndarray, restitution: float, mu: float, k: int = POLYGON):
    """Stage 1: (normal (n,), tangential (n, 2)) of the Stewart-Trinkle LCP with a k-gon cone."""
    n = W.shape[0] // 3
    return _polyhedral(W, v_minus, np.arange(n), np.full(n, float(restitution)), np.full(n, float(mu)), k)


def _polyhedral(W, u, owner, e, mu, k: int = POLYGON, kernel=None):
    """Stage 1 over n normal rows (restitution ``e`` each) of which those in ``owner`` carry a
    tangent pair (coefficient ``mu`` each): (normal (n,), tangential (m, 2))."""
    n, m = len(e), len(owner)
    N, X, Z = _rows(n, m)
    D = polygon_directions(k)
    G = np.zeros((2 * m, m * k))  # tangential impulse (x rows, z rows) = G beta
    for i in range(m):
        G[i, i * k : (i + 1) * k] = D[0]
        G[m + i, i * k : (i + 1) * k] = D[1]
    T = np.concatenate([X, Z])
    Wnn, Wnt, Wtn, Wtt = W[np.ix_(N, N)], W[np.ix_(N, T)], W[np.ix_(T, N)], W[np.ix_(T, T)]
    E = np.kron(np.eye(m), np.ones((1, k)))
    Mu = np.zeros((m, n))
    Mu[np.arange(m), owner] = mu
    M = np.block(
        [
            [Wnn, Wnt @ G, np.zeros((n, m))],
            [G.T @ Wtn, G.T @ Wtt @ G, E.T],
            [Mu, -E, np.zeros((m, m))],
        ]
    )
    q = np.concatenate([(1.0 + e) * u[N], G.T @ u[T], np.zeros(m)])
    s = 1.0 / np.sqrt(np.maximum(np.abs(np.diag(Wnn)), np.finfo(float).tiny))  # unit velocity diagonals
    z = scaled_lemke(M, q, np.concatenate([s, np.repeat(s[owner], k), 1.0 / s[owner]]), u, "the polyhedral Coulomb impact LCP",
                     kernel)
    t = G @ z[n : n + m * k]
    return z[:n], unloaded_without_friction(z[:n], np.column_stack([t[:m], t[m:]]), owner)


def law_residuals(
    W: np.ndarray, v_minus: np.ndarray, restitution: float, mu: float, normal: np.ndarray, tangential: np.ndarray
) -> dict[str, float]:
    """The worst violation of each part of the law, relative to the impact's scale (impulses to
    the largest normal impulse, velocities to the largest approach speed)."""
    n = normal.size
    return _residuals(W, v_minus, np.arange(n), np.full(n, float(restitution)), np.full(n, float(mu)), normal, tangential)


def _residuals(W, u, owner, e, mu, normal, tangential) -> dict[str, float]:
    """:func:`law_residuals` over rows with ``owner``, per-row ``e`` and per-pair ``mu``."""
    n, m = normal.size, len(owner)
    N, X, Z = _rows(n, m)
    v = u + W @ np.concatenate([normal, tangential[:, 0], tangential[:, 1]])
    slip = np.column_stack([v[X], v[Z]])
    gap = v[N] + e * u[N]
    scale_l = max(float(np.max(np.abs(normal), initial=0.0)), np.finfo(float).tiny)
    scale_v = max(float(np.max(np.abs(u), initial=0.0)), np.finfo(float).tiny)
    t_norm = np.linalg.norm(tangential, axis=1)
    s_norm = np.linalg.norm(slip, axis=1)
    sliding = s_norm > LAW_TOL * scale_v
    carried = normal[owner]
    opposing = tangential[sliding] + (mu * carried)[sliding, None] * slip[sliding] / s_norm[sliding, None]
    return {
        "normal >= 0": max(0.0, -float(np.min(normal, initial=0.0))) / scale_l,
        "restitution >= 0": max(0.0, -float(np.min(gap, initial=0.0))) / scale_v,
        "complementarity": float(np.max(np.abs(normal * gap), initial=0.0)) / (scale_l * scale_v),
        "cone": max(0.0, float(np.max(t_norm - mu * carried, initial=0.0))) / scale_l,
        "sliding opposes slip": float(np.max(np.abs(opposing), initial=0.0)) / scale_l,
    }


def _equations(W, u, owner, e, mu, modes, lam):
    """The exact law's equations F(lambda) = 0 for fixed modes and their Jacobian, or None
    where a sliding contact has no slip (its direction is undefined)."""
    n = len(modes)
    N, X, Z = _rows(n, len(owner))
    pair = _pairs(n, owner)
    v = u + W @ lam
    eye = np.eye(lam.size)
    F, J = [], []
    for i, mode in enumerate(modes):
        k = pair[i]
        if mode is ContactMode.SEPARATING:
            F += [lam[N[i]]] + ([lam[X[k]], lam[Z[k]]] if k >= 0 else [])
            J += [eye[N[i]]] + ([eye[X[k]], eye[Z[k]]] if k >= 0 else [])
            continue
        F.append(v[N[i]] + e[i] * u[N[i]])
        J.append(W[N[i]])
        if k < 0:
            continue
        if mode is ContactMode.STICKING:
            F += [v[X[k]], v[Z[k]]]
            J += [W[X[k]], W[Z[k]]]
            continue
        s = np.array([v[X[k]], v[Z[k]]])
        norm = np.linalg.norm(s)
        if norm == 0.0:
            return None
        d = s / norm
        P = (np.eye(2) - np.outer(d, d)) / norm  # d(s / |s|) / ds
        dS = np.vstack([W[X[k]], W[Z[k]]])
        for a, r in enumerate((X[k], Z[k])):
            F.append(lam[r] + mu[k] * lam[N[i]] * d[a])
            row = mu[k] * lam[N[i]] * (P[a] @ dS)
            row[r] += 1.0
            row[N[i]] += mu[k] * d[a]
            J.append(row)
    return np.array(F), np.array(J)


def _newton(W, u, owner, e, mu, modes, start_n, start_t):
    """Stage 2 for fixed modes: damped Newton (least-norm steps, backtracking on |F|) from the
    polyhedral answer; (normal, tangential), or None if a sliding contact loses its slip."""
    lam = np.concatenate([start_n, start_t[:, 0], start_t[:, 1]])
    current = _equations(W, u, owner, e, mu, modes, lam)
    for _ in range(100):
        if current is None:
            return None
        F, J = current
        # the least-norm step: redundant rows (more than the tree's directions) make J singular,
        # where a plain solve steps along rounding's null direction and the backtracking stalls
        step = np.linalg.lstsq(J, -F, rcond=1e-13)[0]
        size = 1.0
        while size > 1e-6:  # backtrack until |F| decreases
            trial = _equations(W, u, owner, e, mu, modes, lam + size * step)
            if trial is not None and np.linalg.norm(trial[0]) < np.linalg.norm(F):
                break
            size *= 0.5
        else:
            break
        lam, current = lam + size * step, trial
        if np.max(np.abs(size * step)) <= 1e-15 * max(np.max(np.abs(lam)), np.finfo(float).tiny):
            break
    n, m = start_n.size, len(owner)
    N, X, Z = _rows(n, m)
    pair = _pairs(n, owner)
    for i, mode in enumerate(modes):  # exactly 0, not a least-norm step's rounding
        if mode is ContactMode.SEPARATING:
            lam[N[i]] = 0.0
            if pair[i] >= 0:
                lam[[X[pair[i]], Z[pair[i]]]] = 0.0
    return lam[:n], np.column_stack([lam[n : n + m], lam[n + m :]])


def _slip(velocity: np.ndarray, n: int, m: int) -> np.ndarray:
    """Per tangent pair: the slip speed |(v_x, v_z)| in ``velocity`` (normal, x, z rows)."""
    return np.hypot(velocity[n : n + m], velocity[n + m : n + 2 * m])


def modes_of(normal, tangential, velocity, scale_v, owner=None) -> tuple[ContactMode, ...]:
    """Each normal row's mode from its impulses and its slip after the impact (a row without a
    tangent pair in ``owner``, default one per row, is sticking when loaded)."""
    n = normal.size
    owner = np.arange(n) if owner is None else owner
    pair = _pairs(n, owner)
    slip = _slip(velocity, n, len(owner))
    scale_l = max(float(np.max(np.abs(normal), initial=0.0)), np.finfo(float).tiny)
    out = []
    for i in range(n):
        if normal[i] <= 1e-9 * scale_l:
            out.append(ContactMode.SEPARATING)
        elif pair[i] < 0 or slip[pair[i]] <= LAW_TOL * scale_v:
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
    n = W.shape[0] // 3
    return cone_unilateral(W, v_minus, np.arange(n), np.full(n, float(restitution)), np.full(n, float(mu)))


def cone_unilateral(W: np.ndarray, u: np.ndarray, owner: np.ndarray, restitution: np.ndarray, mu: np.ndarray,
                    kernel=None) -> ConeImpact:
    """:func:`cone_impact` over n normal rows of which the rows ``owner`` carry a tangent pair:
    the circular-cone counterpart of :func:`impulse_core.impact.coulomb.solve_unilateral` (a joint
    stop is a normal row without a pair; each row has its own restitution, each pair its mu).

    Args:
        W: rows n normal, then m x rows, then m z rows (pair k belongs to normal row owner[k]).
        u: those rows' velocities before (at acceleration level: free accelerations).
        owner: (m,) normal row of each tangent pair.
        restitution: (n,) per normal row.
        mu: (m,) per pair.
        kernel: Lemke's method as C for the polygon's LCP (:func:`impulse_core.impact.coulomb.lemke`).

    Returns:
        ConeImpact with ``tangential`` (m, 2) and ``modes`` per normal row.
    """
    owner, e, mu = np.asarray(owner, dtype=int), np.asarray(restitution, dtype=float), np.asarray(mu, dtype=float)
    normal, tangential = _polyhedral(W, u, owner, e, mu, kernel=kernel)
    scale_v = max(float(np.max(np.abs(u), initial=0.0)), np.finfo(float).tiny)
    if max(_residuals(W, u, owner, e, mu, normal, tangential).values()) <= EXACT_TOL:
        v = u + W @ np.concatenate([normal, tangential[:, 0], tangential[:, 1]])  # stage 1 meets the law: its split
        return ConeImpact(normal, tangential, v, modes_of(normal, tangential, v, scale_v, owner), True)
    polished = _rounds(W, u, owner, e, mu, normal, tangential, scale_v)
    for k in FINER:  # the rounds cycled or stalled: their start from a finer polygon's answer
        if polished is not None:
            return polished
        try:
            start = _polyhedral(W, u, owner, e, mu, k, kernel=kernel)
        except NumericalError:
            break
        polished = _rounds(W, u, owner, e, mu, *start, scale_v)
    if polished is not None:
        return polished
    v = u + W @ np.concatenate([normal, tangential[:, 0], tangential[:, 1]])
    return ConeImpact(normal, tangential, v, modes_of(normal, tangential, v, scale_v, owner), False)


def _rounds(W, u, owner, e, mu, normal, tangential, scale_v) -> ConeImpact | None:
    """Stage 2 from a polyhedral answer (``normal``, ``tangential``): Newton's method on the exact
    equations of its modes, the modes corrected for up to :data:`ROUNDS` rounds; the exact answer,
    or None where no round met the law."""
    n, m = normal.size, len(owner)

    def velocity(nrm, tan):
        return u + W @ np.concatenate([nrm, tan[:, 0], tan[:, 1]])

    pair = _pairs(n, owner)
    modes = list(modes_of(normal, tangential, velocity(normal, tangential), scale_v, owner))
    for _ in range(ROUNDS):
        polished = _newton(W, u, owner, e, mu, modes, normal, tangential)
        if polished is None:  # a sliding guess lost its slip: it sticks on the circle
            slip = _slip(velocity(normal, tangential), n, m)
            stuck = [i for i, md in enumerate(modes) if md is ContactMode.SLIDING]
            if not stuck:
                break
            i = min(stuck, key=lambda i: slip[pair[i]])
            modes[i] = ContactMode.STICKING
            continue
        nrm, tan = polished
        if max(_residuals(W, u, owner, e, mu, nrm, tan).values()) <= LAW_TOL:
            v = velocity(nrm, tan)
            return ConeImpact(nrm, tan, v, modes_of(nrm, tan, v, scale_v, owner), True)
        changed = False
        slip = _slip(velocity(nrm, tan), n, m)
        for i, md in enumerate(modes):
            k = pair[i]
            outside = k >= 0 and np.linalg.norm(tan[k]) > mu[k] * nrm[i] * (1 + LAW_TOL)
            still = k >= 0 and slip[k] <= 1e3 * LAW_TOL * scale_v
            if md is ContactMode.STICKING and outside:
                modes[i], changed = ContactMode.SLIDING, True
            elif md is ContactMode.SLIDING and still:
                modes[i], changed = ContactMode.STICKING, True
            elif md is not ContactMode.SEPARATING and nrm[i] < 0:
                modes[i], changed = ContactMode.SEPARATING, True
        if not changed:
            break
    return None


__all__ = ["POLYGON", "ConeImpact", "cone_impact", "cone_unilateral", "law_residuals", "polygon_directions", "polyhedral_impact"]
