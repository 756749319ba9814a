"""Exact Coulomb friction at impact: Newton's restitution and Coulomb's law at the impulse level,
as a linear complementarity problem solved by Lemke's method.

The law at each contact i (n the ground normal, t the tangent along +x, v- and v+ the contact
velocity before and after the impact, e the restitution, mu the friction coefficient):

    0 <= lambda_n  _|_  v+_n + e v-_n >= 0          (Newton's restitution, unilateral)
    |lambda_t| <= mu lambda_n                        (the friction cone)
    v+_t != 0  =>  lambda_t = -mu lambda_n sign(v+_t) (sliding opposes the post-impact slip)

In the plane this is exactly an LCP (Stewart & Trinkle 1996, with restitution as in Anitescu &
Potra 1997): split lambda_t = lambda_t+ - lambda_t- and add beta (the slip speed |v+_t| where a
contact slides):

    0 <= lambda_t+ _|_ beta + v+_t >= 0
    0 <= lambda_t- _|_ beta - v+_t >= 0
    0 <= beta      _|_ mu lambda_n - lambda_t+ - lambda_t- >= 0

With W = J M^-1 J^T (normal rows, then tangent rows) the post-impact contact velocities are
v+ = v- + W lambda, so z = (lambda_n, lambda_t+, lambda_t-, beta) solves the LCP (M_lcp, q)
of :func:`coulomb_lcp`. That matrix is copositive-plus, so Lemke's method finds a solution
(Stewart & Trinkle 1996). It is the law, not a relaxation: unlike Anitescu's convex program
(``friction-relaxed``) a sliding contact leaves the ground at its restitution speed.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import numpy as np

from impulse_core.errors import NumericalError

#: Relative tolerance of Lemke's ratio test and of the mode classification.
LEMKE_TOL = 1e-12
#: Covering vectors tried after the first when a pivoting path ends on a ray (degenerate ties).
RETRIES = 8


class ContactMode(Enum):
    """What a contact does in the impact."""

    SEPARATING = "separating"
    STICKING = "sticking"
    SLIDING = "sliding"


@dataclass(frozen=True)
class CoulombImpact:
    """The impulses of one impact with exact Coulomb friction (N s) and each contact's mode.

    Attributes:
        normal: normal impulse per contact.
        tangential: tangential impulse per contact, along the tangent rows of J (+x).
        modes: per contact.
        velocity: contact velocities after the impact, normal rows then tangent rows (m/s).
    """

    normal: np.ndarray
    tangential: np.ndarray
    modes: tuple[ContactMode, ...]
    velocity: np.ndarray


def lemke(
    M: np.ndarray, q: np.ndarray, cover: np.ndarray | None = None, max_pivots: int | None = None, kernel=None
) -> np.ndarray | None:
    """A solution z of the LCP  z >= 0, w = M z + q >= 0, z^T w = 0  by Lemke's complementary
    pivoting with the covering vector ``cover`` (> 0; default (1, ..., 1)); None when it ends on a
    secondary ray (no solution found) or runs out of pivots.

    Ties in the ratio test go to the artificial variable first (it ends the path), then to the
    lowest row, which is enough for the small, nondegenerate problems of an impact. ``kernel``:
    the same method as C (:func:`impulse_core.impact.lemke_c.compiled_lemke`: the same z to the
    bit, ~30 x faster on an impact's LCP), or None (this Python code).
    """
    M, q = np.asarray(M, dtype=float), np.asarray(q, dtype=float)
    n = q.size
    if kernel is not None and n:  # the same code as C (its checks too)
        return kernel(M, q, cover, max_pivots or 50 * n + 50, LEMKE_TOL)
    if not (np.all(np.isfinite(M)) and np.all(np.isfinite(q))):
        return None  # no pivoting on NaN (a diverged state upstream)
    if n == 0 or np.all(q >= 0):
        return np.zeros(n)
    cover = np.ones(n) if cover is None else np.asarray(cover, dtype=float)
    tableau = np.hstack([np.eye(n), -M, -cover[:, None], q[:, None]])
    basis = list(range(n))  # w_i basic; z_j is column n + j, the artificial z0 column 2n
    scale = max(1.0, float(np.max(np.abs(tableau[:, :-1]))))
    tol = LEMKE_TOL * scale
    first = int(np.argmin(q / cover))
    _pivot(tableau, basis, first, 2 * n)
    entering = n + first  # the complement of the w that left
    for _ in range(max_pivots or 50 * n + 50):
        # the ratio test on a few rows: Python floats cost less than numpy's calls here
        column, rhs = tableau[:, entering].tolist(), tableau[:, -1].tolist()
        ratios = [(rhs[r] / column[r], r) for r in range(n) if column[r] > tol]
        if not ratios:
            return None  # a secondary ray
        least = min(ratio for ratio, _ in ratios)
        ties = [r for ratio, r in ratios if ratio <= least + tol * (1.0 + abs(least))]
        row = next((r for r in ties if basis[r] == 2 * n), ties[0])
        leaving = basis[row]
        _pivot(tableau, basis, row, entering)
        if leaving == 2 * n:
            z = np.zeros(n)
            for r, var in enumerate(basis):
                if n <= var < 2 * n:
                    z[var - n] = tableau[r, -1]
            return np.maximum(z, 0.0)
        entering = leaving + n if leaving < n else leaving - n
    return None


def _pivot(tableau: np.ndarray, basis: list[int], row: int, column: int) -> None:
    """Gauss-Jordan pivot of ``tableau`` on (row, column); ``column`` enters the basis. The
    other rows are updated in one operation on the whole tableau (the pivot row's factor 0, so it
    is unchanged there and then replaced): the same arithmetic as row by row."""
    pivot_row = tableau[row] / tableau[row, column]
    factors = tableau[:, column].copy()
    factors[row] = 0.0
    tableau -= np.multiply.outer(factors, pivot_row)
    tableau[row] = pivot_row
    basis[row] = column


def coulomb_lcp(W: np.ndarray, v_minus: np.ndarray, restitution: float, mu: float) -> tuple[np.ndarray, np.ndarray]:
    """The LCP (M, q) of the impact law (module docstring) at n contacts.

    Args:
        W: J M^-1 J^T with J's normal rows first, then its tangent rows (2n x 2n).
        v_minus: contact velocities before the impact, normal then tangent (2n).
        restitution: Newton's e in [0, 1].
        mu: Coulomb coefficient >= 0.
    """
    n = W.shape[0] // 2
    return unilateral_lcp(W, v_minus, np.arange(n), np.full(n, float(restitution)), np.full(n, float(mu)))


def unilateral_lcp(
    W: np.ndarray, u: np.ndarray, owner: np.ndarray, restitution: np.ndarray, mu: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The LCP (M, q) of n unilateral rows of which m have a friction (tangent) row.

    The law of the module docstring, row by row: normal row i has its own restitution e_i; tangent
    row k belongs to normal row ``owner[k]`` with coefficient ``mu[k]``; normal rows without a
    tangent row are frictionless (a joint stop, a contact that slides with a given direction).

    Args:
        W: (n + m) square, velocity of each row per unit impulse of each row (normal rows first).
            Not necessarily symmetric: a sliding contact's impulse direction is n - mu s t.
        u: the rows' velocities before (n + m); at acceleration level, their free accelerations.
        owner: (m,) normal row of each tangent row.
        restitution: (n,) per normal row.
        mu: (m,) per tangent row.
    """
    n, m = len(restitution), len(owner)
    Wnn, Wnt, Wtn, Wtt = W[:n, :n], W[:n, n:], W[n:, :n], W[n:, n:]
    M = np.zeros((n + 3 * m, n + 3 * m))
    t, s, b = slice(n, n + m), slice(n + m, n + 2 * m), slice(n + 2 * m, n + 3 * m)  # lambda_t+, lambda_t-, beta
    M[:n, :n], M[:n, t], M[:n, s] = Wnn, Wnt, -Wnt
    M[t, :n], M[t, t], M[t, s] = Wtn, Wtt, -Wtt
    M[s, :n], M[s, t], M[s, s] = -Wtn, -Wtt, Wtt
    M[t, b] = M[s, b] = np.eye(m)
    M[n + 2 * m + np.arange(m), owner] = mu
    M[b, t] = M[b, s] = -np.eye(m)
    un, ut = u[:n], u[n:]
    q = np.concatenate([(1.0 + np.asarray(restitution)) * un, ut, -ut, np.zeros(m)])
    return M, q


@dataclass(frozen=True)
class UnilateralSolution:
    """Impulses (or forces) of :func:`solve_unilateral`: per normal row, per tangent row, the
    rows' velocities after (or accelerations), and the slip (beta) per tangent row."""

    normal: np.ndarray
    tangential: np.ndarray
    velocity: np.ndarray
    slip: np.ndarray


def scaled_lemke(M: np.ndarray, q: np.ndarray, d: np.ndarray, u: np.ndarray, what: str, kernel=None) -> np.ndarray:
    """Lemke's method (:func:`lemke`, on ``kernel``) on the LCP (M, q) scaled by the diagonal ``d``
    (z = D z', w' = D w) and by the largest approach speed in ``u``; other covering vectors on a
    degenerate path.

    Raises:
        NumericalError: no solution (a secondary ray, or too many pivots), naming ``what``.
    """
    speed = max(float(np.max(np.abs(u), initial=0.0)), np.finfo(float).tiny)
    Ms, qs = d[:, None] * M * d[None, :], d * q / speed
    z = lemke(Ms, qs, kernel=kernel)
    rng = None if z is not None else np.random.default_rng(0)
    for _ in range(RETRIES):  # a degenerate path (extreme conditioning): other covering vectors
        if z is not None:
            break
        z = lemke(Ms, qs, cover=rng.uniform(0.5, 2.0, qs.size), kernel=kernel)
    if z is None:
        raise NumericalError(f"Lemke's method found no solution of {what} (a secondary ray)")
    return d * z * speed


def solve_unilateral(
    W: np.ndarray, u: np.ndarray, owner: np.ndarray, restitution: np.ndarray, mu: np.ndarray, kernel=None
) -> UnilateralSolution:
    """Solve :func:`unilateral_lcp` by Lemke's method, scaled and with retries (``kernel``: as
    :func:`lemke`'s; with it the LCP, its scaling and the first path are built as C too).

    Raises:
        NumericalError: Lemke's method found no solution (a ray, or too many pivots).
    """
    n, m = len(restitution), len(owner)
    # the compiled LCP, scaling and first Lemke path (the same numbers); else, or on a ray, Python's
    z = None if kernel is None or not n + m else kernel.unilateral(W, u, owner, restitution, mu, LEMKE_TOL)
    if z is not None:
        return _solution(z, W, u, owner)
    M, q = unilateral_lcp(W, u, owner, restitution, mu)
    # Diagonal scaling z = D z', w' = D w with D = (s, s, s, 1/s), s_i = 1/sqrt(W_nn,ii): the velocity
    # blocks get a unit diagonal and the cone and slip blocks stay mu and 1, whatever the units.
    s = 1.0 / np.sqrt(np.maximum(np.abs(np.diag(W)[:n]), np.finfo(float).tiny))
    st = s[owner]
    z = scaled_lemke(M, q, np.concatenate([s, st, st, 1.0 / st]), u, "the unilateral LCP", kernel)
    return _solution(z, W, u, owner)


def _solution(z: np.ndarray, W: np.ndarray, u: np.ndarray, owner: np.ndarray) -> UnilateralSolution:
    """The impulses and velocities of the unilateral LCP's answer ``z``."""
    n, m = len(u) - len(owner), len(owner)
    normal = z[:n]
    tangential = unloaded_without_friction(normal, z[n : n + m] - z[n + m : n + 2 * m], owner)
    velocity = u + W @ np.concatenate([normal, tangential])
    return UnilateralSolution(normal, tangential, velocity, z[n + 2 * m :])


def unloaded_without_friction(normal: np.ndarray, tangential: np.ndarray, owner: np.ndarray) -> np.ndarray:
    """``tangential`` (per friction row, along its first axis) with the rows of contacts that carry
    no normal impulse zeroed: Coulomb's law, |t| <= mu n, leaves them none, where Lemke's basic
    friction variables keep rounding's 1e-17 (random file 32064: a first impact with no normal
    impulse had 1.6e-17 N s of friction, which the first-impact rung, solving nothing, did not)."""
    loaded = normal[owner] > 0
    if loaded.all():
        return tangential
    return np.where(loaded.reshape(-1, *[1] * (tangential.ndim - 1)), tangential, 0.0)


def coulomb_impact(W: np.ndarray, v_minus: np.ndarray, restitution: float, mu: float) -> CoulombImpact:
    """Normal and tangential impulses of the exact Newton-Coulomb impact law, with the modes.

    Args:
        W, v_minus, restitution, mu: as in :func:`coulomb_lcp`.

    Raises:
        NumericalError: Lemke's method found no solution (a ray, or too many pivots).
    """
    n = W.shape[0] // 2
    try:
        sol = solve_unilateral(W, v_minus, np.arange(n), np.full(n, float(restitution)), np.full(n, float(mu)))
    except NumericalError:
        raise NumericalError("Lemke's method found no solution of the Coulomb impact LCP (a secondary ray)") from None
    normal, tangential = sol.normal, sol.tangential
    if mu == 0:
        tangential = np.zeros(n)  # not rounding's 1e-16: no friction, no tangential impulse
    velocity = v_minus + W @ np.concatenate([normal, tangential])
    speed = max(float(np.max(np.abs(v_minus))), np.finfo(float).tiny)
    return CoulombImpact(normal, tangential, contact_modes(normal, velocity, speed), velocity)


def contact_modes(normal: np.ndarray, velocity: np.ndarray, speed: float) -> tuple[ContactMode, ...]:
    """Each contact's mode: separating without normal impulse, sticking with no slip after the
    impact, sliding otherwise (``speed`` sets the scale of "no slip")."""
    n = normal.size
    impulse_tol = LEMKE_TOL * 1e3 * max(float(np.max(np.abs(normal), initial=0.0)), np.finfo(float).tiny)
    slip_tol = 1e-9 * speed
    return tuple(
        ContactMode.SEPARATING
        if normal[i] <= impulse_tol
        else ContactMode.STICKING
        if abs(velocity[n + i]) <= slip_tol
        else ContactMode.SLIDING
        for i in range(n)
    )


__all__ = [
    "LEMKE_TOL",
    "ContactMode",
    "CoulombImpact",
    "UnilateralSolution",
    "contact_modes",
    "coulomb_impact",
    "coulomb_lcp",
    "lemke",
    "scaled_lemke",
    "solve_unilateral",
    "unloaded_without_friction",
    "unilateral_lcp",
]
