"""The impact law over a mode's rows (:func:`rigid_impact`: Newton's restitution with exact
Coulomb friction, the circular cone in space) and the modes an impact leaves (:func:`impact_modes`);
:meth:`.impacts._Impacts.impact` applies it at each touchdown and stop."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from impulse_core.impact.cone import POLYGON, modes_of
from impulse_core.impact.coulomb import ContactMode, UnilateralSolution, contact_modes
from impulse_core.impact.laws import least_norm_law_split, least_norm_split, redundant, share_among_twins, twin_groups
from impulse_core.timedomain.events.point import _Point
from impulse_core.timedomain.events.rows import _Rows
from impulse_core.timedomain.events.forces import _contact_forces, _solve_rows


@dataclass(frozen=True)
class RigidImpact:
    """One rigid impact over constraint rows (:func:`rigid_impact`).

    Attributes:
        solution: the law's row impulses and row velocities after (:func:`_solve_rows`; where the
            frictionless split is not unique, the least-norm normal split).
        v_plus: the generalized velocity after.
        normal, tangential: each contact's normal (n_c) and tangential (n_c x (d - 1)) impulse
            (0 where not in the rows; twin contacts share alike where the split is not unique).
        split_unique: the rows are independent (the split of the impulse is unique).
        exact: the exact law was met (False: the circular cone's polyhedral answer).
    """

    solution: UnilateralSolution
    v_plus: np.ndarray
    normal: np.ndarray
    tangential: np.ndarray
    split_unique: bool
    exact: bool


def rigid_impact(pt: _Point, v: np.ndarray, rows: _Rows, restitution: np.ndarray, mu: float, kernel=None
                 ) -> RigidImpact:
    """Newton's restitution (``restitution`` per normal row) with exact Coulomb friction (``mu``;
    0: the frictionless LCP) over ``rows`` at ``pt``, from the velocity ``v`` (:func:`_solve_rows`):
    the law of every impact of the landing and of the first instant on uneven ground. Redundant
    rows: without friction the lcp rung's smallest-norm split, with friction twins share alike.
    ``kernel``: as :func:`_solve_rows`'."""
    u = rows.G @ v
    minv_gt = np.linalg.solve(pt.M, rows.G.T)
    W = rows.G @ minv_gt
    sol, _, exact = _solve_rows(W, u, rows, restitution, kernel)
    split_unique = not redundant(rows.G)
    if not split_unique and mu == 0:  # the lcp rung's split (G has no tangent rows without friction)
        sol = replace(sol, normal=least_norm_split(rows.G, sol.normal))
    law_split = None if split_unique or mu == 0 else _law_split(rows, W, u, sol, restitution, mu)
    sol = sol if law_split is None else law_split
    lam = np.concatenate([sol.normal, sol.tangential])
    fn, ft = _contact_forces(rows, lam, mu, len(pt.gap))
    if not split_unique and mu > 0 and law_split is None:  # twins share alike, as in the friction rung
        c = rows.contact[rows.contact >= 0]
        groups = twin_groups(np.hstack([pt.Jn[c], pt.Jt[c].reshape(len(c), -1)]))
        fn[c], ft[c] = share_among_twins(groups, fn[c], ft[c])
    return RigidImpact(sol, v + minv_gt @ lam, fn, ft, split_unique, exact)


def _law_split(rows: _Rows, W: np.ndarray, u: np.ndarray, sol: UnilateralSolution, restitution: np.ndarray,
               mu: float) -> UnilateralSolution | None:
    """The friction rung's split of a redundant impact (:func:`least_norm_law_split`), or None
    where the law's answer does not meet its own modes to the law's tolerance."""
    t = sol.tangential.reshape(rows.direction.shape[1], len(rows.owner)).T
    split = least_norm_law_split(rows.G, W, u, rows.owner, sol.normal, t, restitution, mu, POLYGON)
    return None if split is None else replace(sol, normal=split[0], tangential=split[1].T.ravel())


def impact_modes(pt: _Point, v: np.ndarray, v_plus: np.ndarray, contacts: np.ndarray, normal: np.ndarray
                 ) -> tuple[ContactMode, ...]:
    """Each of ``contacts``' mode in an impact at ``pt`` from v to ``v_plus`` with normal impulses
    ``normal`` (per contact of ``contacts``), by the friction rung's thresholds (the scale: the
    largest normal or tangential contact speed before; :func:`contact_modes`, :func:`modes_of`)."""
    Jt = pt.Jt[contacts].transpose(1, 0, 2).reshape(-1, pt.Jt.shape[2])  # the first tangents, then the second
    J = np.vstack([pt.Jn[contacts], Jt])
    scale = max(float(np.max(np.abs(J @ v), initial=0.0)), np.finfo(float).tiny)
    after = J @ v_plus
    if pt.Jt.shape[1] == 1:
        return contact_modes(normal, after, scale)
    return modes_of(normal, None, after, scale)
