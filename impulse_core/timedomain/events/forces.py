"""A mode's forces and accelerations from its rows (:mod:`.rows`): the constrained solve, the
least-norm split of redundant rows, the contact forces per contact (corners included), and the
contact impulses as generalized and world vectors."""

from __future__ import annotations

import numpy as np

from impulse_core.impact.cone import cone_unilateral
from impulse_core.impact.coulomb import UnilateralSolution, solve_unilateral
from impulse_core.impact.nnls import least_distance
from impulse_core.timedomain.events.point import _Point, tangent_basis
from impulse_core.timedomain.events.rows import _Rows


def _solve_rows(
    W: np.ndarray, u: np.ndarray, rows: _Rows, restitution: np.ndarray, kernel=None
) -> tuple[UnilateralSolution, np.ndarray, bool]:
    """The unilateral law over the rows (Newton's restitution per normal row, Coulomb friction
    per sticking contact; at the acceleration level with ``restitution`` 0): in the plane the
    LCP by Lemke's method (:func:`impulse_core.impact.coulomb.solve_unilateral`); in space the
    circular cone (:func:`impulse_core.impact.cone.cone_unilateral`: the Stewart-Trinkle 16-gon
    LCP, then Newton's method on the exact law). Returns the solution (tangential impulses and
    tangent-row velocities in :class:`_Rows`' order, ``slip`` the slip speed per sticking contact),
    the tangent rows' velocities after, per sticking contact (m x (d - 1)), and whether the exact
    law was met (False: the cone's polyhedral answer). ``kernel``: Lemke's method as C (the same
    numbers; :func:`impulse_core.impact.lemke_c.compiled_lemke`), or None."""
    m, tangents = len(rows.owner), rows.direction.shape[1]
    if tangents == 1 or not m:
        sol = solve_unilateral(W, u, rows.owner, restitution, rows.mu, kernel)
        return sol, sol.velocity[rows.n :].reshape(tangents, m).T, True
    law = cone_unilateral(W, u, rows.owner, restitution, rows.mu, kernel)
    after = law.velocity[rows.n :].reshape(tangents, m).T
    slip = np.linalg.norm(after, axis=1)
    return UnilateralSolution(law.normal, law.tangential.T.ravel(), law.velocity, slip), after, law.exact


def _accelerations(pt: _Point, rows: _Rows) -> tuple[np.ndarray, np.ndarray]:
    """Accelerations and row forces of the mode: M a = f + F^T lambda, G a + b = 0."""
    X = np.linalg.solve(pt.M, np.column_stack([pt.f, rows.F.T]))
    a0, minv_ft = X[:, 0], X[:, 1:]
    if not rows.G.shape[0]:
        return a0, np.zeros(0)
    W = rows.G @ minv_ft
    rhs = -(rows.G @ a0 + rows.b)
    if rows.redundant:  # the least-norm split (np.linalg.solve would return any one, rounding's), pushing
        return _least_norm(W, rhs, a0, minv_ft, rows.n)
    try:
        lam = np.linalg.solve(W, rhs)
    except np.linalg.LinAlgError:  # redundant rows (e.g. two sticking contacts on one rod)
        lam = np.linalg.lstsq(W, rhs, rcond=None)[0]
    return a0 + minv_ft @ lam, lam


#: Rows whose matrix G M^-1 F^T has a singular value below this times its largest are redundant.
REDUNDANT = 1e-10


def _least_norm(W: np.ndarray, rhs: np.ndarray, a0: np.ndarray, minv_ft: np.ndarray, pushing: int = 0
                ) -> tuple[np.ndarray, np.ndarray]:
    """(a0 + M^-1 F^T lambda, lambda) with W lambda = rhs for redundant rows W: the least-norm
    lambda, or where that pulls on one of the first ``pushing`` rows (the normal rows: contacts'
    and stops' forces, which Signorini's law keeps >= 0) the least-norm one of the splits that
    push on all of them (:func:`_pushing_split`), where one exists."""
    lam = np.linalg.lstsq(W, rhs, rcond=REDUNDANT)[0]
    if pushing and np.min(lam[:pushing]) < 0.0:
        lam = _pushing_split(W, lam, pushing)
    return a0 + minv_ft @ lam, lam


def _pushing_split(W: np.ndarray, lam: np.ndarray, pushing: int) -> np.ndarray:
    """The least-norm lambda + N z (N an orthonormal basis of W's null space, as
    :data:`REDUNDANT` ranks it; ``lam`` the least-norm solution, orthogonal to it) whose first
    ``pushing`` entries are >= 0: the least-distance problem min |z| subject to N_p z >= -lam_p
    (:func:`impulse_core.impact.nnls.least_distance`); ``lam`` where none exists (then no split of
    these rows pushes everywhere, and the force witness opens the pulling row). The rows' total
    force differs between splits where friction slides (F is not G): any of these meets the
    contact laws, and the least-norm one pulled while Lemke's answer of the same rows, which
    chose the mode, pushed (random file 30804: a hinged rod's tip at -2e-9 N, its force witness
    at every 4.5e-10 s)."""
    _, s, Vt = np.linalg.svd(W)
    N = Vt[int(np.count_nonzero(s > REDUNDANT * s[0])) :].T
    if not N.shape[1]:
        return lam
    z = least_distance(N[:pushing], -lam[:pushing])
    return lam if z is None else lam + N @ z


def _constrained_solve(W: np.ndarray, rows: _Rows, rhs: np.ndarray, row_rhs: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray]:
    """(x, nu) with W x = rhs + F^T nu and G x = row_rhs (the rows of a mode; W symmetric positive
    definite): the mode's accelerations with W for the mass matrix."""
    X = np.linalg.solve(W, np.column_stack([rhs, rows.F.T]))
    x0, winv_ft = X[:, 0], X[:, 1:]
    if not rows.G.shape[0]:
        return x0, np.zeros(0)
    S = rows.G @ winv_ft
    r = row_rhs - rows.G @ x0
    if rows.redundant:
        return _least_norm(S, r, x0, winv_ft)
    try:
        nu = np.linalg.solve(S, r)
    except np.linalg.LinAlgError:  # redundant rows
        nu = np.linalg.lstsq(S, r, rcond=None)[0]
    return x0 + winv_ft @ nu, nu


def _contact_forces(rows: _Rows, lam: np.ndarray, mu: float, nc: int) -> tuple[np.ndarray, np.ndarray]:
    """Normal (n_c) and tangential (n_c x (d - 1)) force (or impulse) per contact from the rows'
    multipliers; a sliding contact's tangential force is -mu u lambda_n (u its slip direction)."""
    tangents = rows.direction.shape[1]
    fn, ft = np.zeros(nc), np.zeros((nc, tangents))
    on = rows.contact >= 0
    c = rows.contact[on]
    fn[c] = lam[: rows.n][on]
    ft[c] = -mu * rows.direction[c] * fn[c][:, None]
    ft[rows.contact[rows.owner]] = lam[rows.n :].reshape(tangents, len(rows.owner)).T
    if rows.cornered is not None:  # a corner's two rows: their forces' sum, along the point's normal and tangent
        k = rows.cornered
        corner, force = rows.contact[: rows.n][k], lam[: rows.n][k]
        fn[corner] = 0.0
        ft[corner] = 0.0
        np.add.at(fn, corner, force * rows.turn[k, 0])
        np.add.at(ft[:, 0], corner, force * rows.turn[k, 1])
    return fn, ft


def _corner_side(rows: _Rows) -> np.ndarray:
    """Per normal row: 0 for a corner's left segment's row (and any other row), 1 for its right's."""
    side = np.zeros(rows.n, int)
    k = np.flatnonzero(rows.cornered)
    side[k] = (k - k[0]) % 2  # the corners' rows are consecutive, left then right (:func:`_with_corners`)
    return side


def _corner_row_forces(rows: _Rows, lam: np.ndarray, nc: int) -> np.ndarray:
    """Per contact, its corner's left and right rows' forces (n_c x 2; NaN where it has none)."""
    out = np.full((nc, 2), np.nan)
    k = np.flatnonzero(rows.cornered)
    out[rows.contact[k], _corner_side(rows)[k]] = lam[k]
    return out


def _corner_forces(rows: _Rows, lam: np.ndarray, nc: int) -> np.ndarray:
    """Per contact, the smaller of its two corner rows' forces (inf where it has none)."""
    out = np.full(nc, np.inf)
    if rows.cornered is not None:
        k = rows.cornered
        np.minimum.at(out, rows.contact[: rows.n][k], lam[: rows.n][k])
    return out


def contact_impulses(pt: _Point, normal: np.ndarray, tangential: np.ndarray) -> np.ndarray:
    """The ground's impulse vector on each contact (d x n_c, world frame) from its normal (n_c) and
    tangential (n_c x (d - 1)) impulse along the contact's normal and tangents at ``pt``."""
    return contact_vectors(pt.normal, pt.tangent, normal, tangential)


def contact_vectors(normal: np.ndarray, tangent: np.ndarray, fn: np.ndarray, ft: np.ndarray) -> np.ndarray:
    """Each contact's impulse vector (d x n_c, world): ``fn`` (n_c) along its ``normal`` (n_c x d),
    ``ft`` (n_c x (d - 1)) along its tangents (``tangent``: n_c x (d - 1) x d, :func:`tangent_basis`)."""
    return normal.T * fn + sum(tangent[:, a].T * ft[:, a] for a in range(tangent.shape[1]))


def _stacked(fn: np.ndarray, ft: np.ndarray) -> np.ndarray:
    """[normal per contact, first tangent per contact, (space) second tangent per contact]."""
    return np.concatenate([fn, ft.T.ravel()])


def _unstacked(stacked: np.ndarray, nc: int, tangents: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_stacked`'s inverse: (normal per contact, n_c x ``tangents`` tangential), as views."""
    return stacked[:nc], stacked[nc:].reshape(tangents, nc).T


def impulse_vector(normal: np.ndarray, fn: np.ndarray, ft: np.ndarray, tangent: np.ndarray | None = None
                   ) -> np.ndarray:
    """The sum over contacts of the ground's impulse vectors (:func:`contact_vectors`; ``tangent``
    default :func:`tangent_basis`, ``ft`` n_c x (d - 1), or n_c in the plane)."""
    tangent = tangent_basis(normal) if tangent is None else tangent
    return contact_vectors(normal, tangent, fn, np.reshape(ft, (len(fn), -1))).sum(axis=1)
