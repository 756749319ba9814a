"""The ladder of rigid impact models (coarse to fine) and their numeric solvers.

Notation: n active contacts; J the normal Jacobian (n x nv); A = J M^-1 J^T the Delassus matrix;
w = J v- the normal approach velocities; b = -(1 + e) w. With M = L^T D L and u = D^1/2 L v the
kinetic energy is |u|^2 / 2 and an impulse lambda changes u by E lambda, E = D^-1/2 L^-T J^T,
so A = E^T E and b = E^T f with f = -(1 + e) u- (``impact.metric_function`` builds E and u-).

Rungs:

- ``DECOUPLED``, paper eq. 14: lambda_i = b_i / sum_j A_ij, each contact's row of eq. 11 divided
  by its row sum (ERRATA.md). Equals eq. 11 only when all impulses are equal; no sign guarantee.
- ``NEWTON``, paper eq. 11: A lambda = b, Newton's restitution at every contact at once. A
  contact may pull (lambda_i < 0).
- ``LCP``, frictionless complementarity with Newton restitution (Moreau's impact law without
  friction): lambda >= 0, A lambda - b >= 0 (that is v+_n + e v-_n >= 0), complementary. With A
  symmetric positive semi-definite these are the KKT conditions of
  min 1/2 |E lambda - f|^2 s.t. lambda >= 0, solved exactly by NNLS (Lawson-Hanson). Equals
  NEWTON whenever every Newton impulse is >= 0. For an approach with w <= 0 (every contact
  closing, as in a landing) the energy change is (1 - e)/2 lambda^T w <= 0: no energy gain.
- ``FRICTION``, exact Coulomb friction: Newton's restitution and Coulomb's law on the impulses,
  an LCP solved by Lemke's method (:mod:`impulse_core.impact.coulomb`). What ``auto`` runs when
  the scene has friction.
- ``FRICTION_RELAXED`` (on request only), Coulomb friction by Moreau's impact law (Moreau 1988, Newton restitution on
  Moreau's weighted velocity v+ + e v-) in its convex relaxation (Anitescu 2006, the cone
  complementarity problem): the maximal-dissipation program
      min over lambda = (lambda_n, lambda_t) in the Coulomb cone |lambda_t| <= mu lambda_n of
      1/2 |v+ + e v-|_M^2,  v+ = v- + M^-1 (J_n^T lambda_n + J_t^T lambda_t).
  In the plane the cone is spanned by its two edges (1, mu) and (1, -mu): with lambda_n = x+ + x-,
  lambda_t = mu (x+ - x-), the cone is x >= 0 and the program is again an NNLS. Its KKT
  conditions: tangentially, Coulomb's law on the weighted velocity (sticking inside the cone,
  sliding against the tangential velocity on its edge); normally, v+_n + e v-_n >= mu |v+_t + e v-_t|
  at every contact (the dual cone), with equality where it carries impulse. At e = 0 the program is
  "minimise the post-impact kinetic energy over the cone" (maximal dissipation, Drumwright & Shell
  2010), and v+_n >= 0 follows from the KKT conditions.

Known limits of the FRICTION_RELAXED rung (why it is not the default):

- Convex relaxation, not Coulomb's complementarity law: the normal condition is the dual cone,
  y_n >= mu |y_t| (y = J (v+ + e v-)), not y_n >= 0. A sliding contact leaves with a normal
  velocity mu |y_t| above the restitution value while still carrying impulse (the "hopping" of
  convex relaxations, Anitescu 2006), and a contact that would separate while sliding is held
  by friction until y_n >= mu |y_t|: at large mu it grips tangentially with a normal impulse near
  0. Sticking contacts are exact. At mu = 0 the program is the LCP rung's; as mu grows, every
  contact that carries impulse sticks (v+_t = 0, v+_n = -e v-_n).
- Restitution: Newton's kinematic coefficient applied to Moreau's weighted velocity, the same e
  for the normal and the tangential part. For a straight-down landing (v-_t = 0) the answer is
  (1 + e) times the perfectly plastic (e = 0) one, i.e. Poisson's hypothesis; Stronge's
  energetic coefficient and the time-resolved slip reversal of a real impact are not modelled.
  The alternative "minimise the kinetic energy of v+ subject to the cone and v+_n >= -e v-_n"
  (the KE-min law) was not taken: for e > 0 its stationarity gives v+_t = (J_t M^-1 J_n^T) nu at
  a sticking contact (nu the restitution multiplier), so it slides even with unbounded friction.
  It has the opposite strength: no hop at sliding contacts.
- Measured against the exact (non-convex) Coulomb-Newton law, whose contact modes the study
  enumerates (studies/fidelity/rigid_rungs.md): exact where contacts stick; on random scenes
  the post-impact velocity is off by about 1 % (median, energy norm), but on the paper's case 3
  with mu = 0.3, where every contact slides, the contact impulses are 18 % off (the KE-min law:
  exact there).
- Energy: for a landing (every contact closing, v-_t = 0) the kinetic energy falls by
  (1 - e^2) times the plastic loss: never a gain, conserved at e = 1.
- Impulse-level Coulomb law: the friction bound holds for the impulses integrated over the
  impact, not for the force at every instant.
- Numerics: the cone's edge coordinates lose about log10(mu) digits of the tangential impulse
  of a sticking contact (lambda_t = mu (x+ - x-)); fine to mu ~ 1e4.

Redundant contacts (rank J < rows) leave the split of the impulse open under every rung; the
smallest-norm admissible split is returned (:func:`least_norm_split`).
"""

from __future__ import annotations

import math

from dataclasses import dataclass
from enum import Enum

import numpy as np

from impulse_core.impact.nnls import least_distance, nnls

#: Singular values of the column-normalised contact Jacobian below this (relative) are zero.
RANK_TOL = 1e-9
#: A relative Delassus pivot below this sends an evaluation to the rank check (the SVD of J).
PIVOT_TOL = 1e-9


class ImpactModel(Enum):
    """The rigid impact models, from the coarsest to the finest."""

    DECOUPLED = "decoupled"
    NEWTON = "newton"
    LCP = "lcp"
    FRICTION = "friction"
    FRICTION_RELAXED = "friction-relaxed"

    @property
    def description(self) -> str:
        """One line naming the law (and the paper's equation) the rung implements."""
        return _DESCRIPTIONS[self]


_DESCRIPTIONS = {
    ImpactModel.DECOUPLED: "decoupled approximation (paper eq. 14)",
    ImpactModel.NEWTON: "newton-simultaneous (paper eq. 11)",
    ImpactModel.LCP: "complementarity, frictionless (LCP: impulses >= 0, Newton restitution)",
    ImpactModel.FRICTION: "Coulomb friction, exact (Newton restitution, Coulomb's law on the impulses: LCP, Lemke)",
    ImpactModel.FRICTION_RELAXED: "Coulomb friction, convex relaxation (Moreau's impact law, maximal dissipation)",
}


def decoupled_impulse(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Paper eq. 14: lambda_i = b_i / sum_j A_ij (N s), b = -(1 + e) J v-.

    Returns non-finite entries where a row sum of A is zero (the caller checks).
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.asarray(b, dtype=float) / np.asarray(A, dtype=float).sum(axis=1)


def complementarity_impulse(E: np.ndarray, f: np.ndarray) -> np.ndarray:
    """The frictionless impact LCP: lambda >= 0, E^T (E lambda - f) >= 0, complementary (N s).

    With E the metric factor of the normal rows and f = -(1 + e) u-, that is lambda >= 0,
    A lambda - b >= 0, lambda^T (A lambda - b) = 0: the KKT conditions of
    min 1/2 |E lambda - f|^2 s.t. lambda >= 0, solved by NNLS. For a singular A one minimiser
    is returned (the post-impact velocity is unique; see :func:`least_norm_split`).
    """
    return _scaled_nnls(E, f)


def coulomb_impulse(E_n: np.ndarray, E_t: np.ndarray, f: np.ndarray, mu: float) -> tuple[np.ndarray, np.ndarray]:
    """Normal and tangential impulses of the FRICTION_RELAXED rung (module docstring): the maximal-
    dissipation program min 1/2 |E_n l_n + E_t l_t - f|^2 over |l_t| <= mu l_n, in the cone's
    edge coordinates (l_n = x+ + x-, l_t = mu (x+ - x-), x >= 0) as an NNLS.

    Args:
        E_n, E_t: metric factors of the normal and the tangential rows (nv x n each).
        f: -(1 + e) u-, Moreau's weighted velocity target in the metric coordinates.
        mu: Coulomb coefficient, >= 0 (0 gives the LCP answer with zero tangential impulse).
    """
    n = E_n.shape[1]
    x = _scaled_nnls(np.hstack([E_n + mu * E_t, E_n - mu * E_t]), f)
    x_plus, x_minus = x[:n], x[n:]
    return x_plus + x_minus, mu * (x_plus - x_minus)


def coulomb_cone(mu: float, n: int) -> np.ndarray:
    """Rows P with P @ concat(l_n, l_t) >= 0 the planar Coulomb cone at n contacts:
    mu l_n + l_t >= 0 and mu l_n - l_t >= 0 (2n x 2n)."""
    eye = np.eye(n)
    return np.block([[mu * eye, eye], [mu * eye, -eye]])


def redundant(J: np.ndarray, A: np.ndarray | None = None) -> bool:
    """True when the rows of J are dependent (rank from the SVD of J with unit columns, so the
    answer does not depend on the units of the DOFs).

    With the Delassus matrix A = J M^-1 J^T, a Cholesky factor of A scaled to unit diagonal whose
    pivots all exceed ``PIVOT_TOL`` settles "independent" without the SVD (the fast path).
    """
    if A is not None and A.size:
        d = np.sqrt(np.diag(A))
        if np.all(d > 0):
            try:
                L = np.linalg.cholesky(A / d[:, None] / d[None, :])
            except np.linalg.LinAlgError:
                pass
            else:
                if np.min(np.diag(L)) ** 2 >= PIVOT_TOL:
                    return False
    if _surely_independent(J):
        return False
    return _rank(J) < J.shape[0]


#: :func:`_surely_independent`'s margin: a lower bound of the smallest eigenvalue of the unit-column
#: Gram matrix at least this times its trace (singular values at least 1e-4 of the largest, five
#: orders above RANK_TOL: what rounding does to the bound or to the SVD cannot reach the rank test).
SURE_GAP = 1e-8


def _surely_independent(J: np.ndarray) -> bool:
    """Whether J's rows (r <= columns) are certainly independent by :func:`_rank`'s test, from a
    bound that needs no SVD: with B = U U^T (U: J with unit columns), lambda_min(B) >= det B /
    (trace B / (r - 1))^(r - 1) (the other eigenvalues' product is at most that, their sum being
    below the trace) and lambda_max(B) <= trace B. False where the bound does not settle it (the
    SVD then answers), so :func:`redundant` answers as the SVD alone would, cheaper."""
    r, c = J.shape
    if not 0 < r <= c:
        return False
    squares = np.einsum("ij,ij->j", J, J)
    B = (J / np.where(squares > 0, squares, 1.0)) @ J.T
    trace = float(B.trace())
    if not 0.0 < trace < math.inf:
        return False
    if r == 1:
        return True
    bound = float(np.linalg.det(B)) / (trace / (r - 1)) ** (r - 1)
    return bound >= SURE_GAP * trace


def twin_groups(rows: np.ndarray, tol: float = 1e-12) -> list[np.ndarray]:
    """Groups (two or more, by index) of contacts whose rows are identical (``rows``: one row per
    contact, its normal and tangent Jacobian rows end to end; within ``tol`` of the largest
    entry): contacts at one point of one motion, as identical toes' tips or a rod's tip on the
    next rod's root. Their impulses act alike, so only their sum is defined."""
    scale = tol * max(float(np.max(np.abs(rows), initial=0.0)), 1e-300)
    groups, seen = [], np.zeros(len(rows), bool)
    for i in range(len(rows)):
        if seen[i]:
            continue
        same = np.flatnonzero(np.max(np.abs(rows - rows[i]), axis=1) <= scale)
        seen[same] = True
        if len(same) > 1:
            groups.append(same)
    return groups


def share_among_twins(groups: list[np.ndarray], *impulses: np.ndarray) -> tuple[np.ndarray, ...]:
    """Each array of per-contact impulses (first axis: contacts) with every twin group's entries
    replaced by their mean: the smallest-norm split of the same effect (the twins' rows are one
    row), inside each contact's cone when the members were (the cones are one convex cone)."""
    out = tuple(np.array(x, dtype=float, copy=True) for x in impulses)
    for g in groups:
        for x in out:
            x[g] = np.mean(x[g], axis=0)
    return out


def least_norm_split(J: np.ndarray, lam: np.ndarray, P: np.ndarray | None = None) -> np.ndarray:
    """The smallest-norm impulse with the same effect as ``lam`` (J^T lambda = J^T lam, hence the
    same post-impact velocity) that stays admissible (P lambda >= 0; default lambda >= 0).

    Every such lambda is lam_0 + N z with lam_0 the projection of ``lam`` on the range of J and
    N an orthonormal basis of J's left null space; |lambda|^2 = |lam_0|^2 + |z|^2, so this is the
    least-distance program min |z| s.t. P N z >= -P lam_0 (Lawson-Hanson LDP). ``lam`` itself is
    admissible, so the program is feasible; ``lam`` is returned if rounding says otherwise.
    """
    lam = np.asarray(lam, dtype=float)
    N = _left_null_space(J)
    if N.shape[1] == 0:
        return lam
    lam0 = lam - N @ (N.T @ lam)
    if P is None:
        z = least_distance(N, -lam0)
        return lam if z is None else np.maximum(lam0 + N @ z, 0.0)
    z = least_distance(P @ N, -(P @ lam0))
    return lam if z is None else lam0 + N @ z


#: Entries of a split this small against its largest normal impulse are rounding: 0.
ROUNDING = 1e-13


#: How far (relative to the largest speed before) an answer's velocities after may be from its
#: modes' own for :func:`least_norm_law_split` to take the modes: a wrong mode is off by O(1), a
#: solver's answer by its tolerance times W's spread (fe12600: law residual 3e-10, velocities 2e-9).
MODES_TOL = 1e-6


def least_norm_law_split(
    J: np.ndarray, W: np.ndarray, u: np.ndarray, owner: np.ndarray, normal: np.ndarray, tangential: np.ndarray,
    restitution: float | np.ndarray, mu: float, sides: int, tol: float = 1e-9,
) -> tuple[np.ndarray, np.ndarray] | None:
    """The smallest-norm split of an impact's impulses that obeys the law in the answer's modes:
    no impulse on a normal row that separates (its velocity after plus e times before above
    ``tol`` of the largest speed before), a sliding pair's impulse mu lambda_n against its slip,
    a sticking pair's inside the cone (two tangents: the circle; one, the plane: the interval).
    Its velocities after are the modes' own (restitution and sticking rows met exactly, not to the
    answer's tolerance), and the split is unique (a strictly convex norm over a convex set), so two
    solvers of one impact, or one solver on rows that differ by rounding, report the same split.

    Args:
        J: the rows: n normal rows (contacts, joint stops), then each tangent's m pair rows; W =
            J M^-1 J^T; u = J v before the impact.
        owner: (m,) each pair's normal row; normal (n,), tangential (m, tangents): the law's answer.
        restitution: Newton's e, per normal row or one for all.
        sides: the inscribed polygon whose split starts the circle's (:func:`_in_cones`).

    Returns:
        (normal, tangential), or None where the answer does not obey the law in its own modes to
        ``tol`` (its own split then stands).
    """
    n, (m, tangents) = len(normal), tangential.shape
    after = u + W @ np.concatenate([normal, tangential.T.ravel()])
    scale = max(float(np.max(np.abs(u), initial=0.0)), np.finfo(float).tiny)
    target = np.concatenate([-restitution * u[:n], np.zeros(m * tangents)])
    gap_rate, slip = (after[:n] - target[:n]) / scale, after[n:].reshape(tangents, m).T / scale
    speed = np.linalg.norm(slip, axis=1)
    free = gap_rate <= tol
    sliding = (speed > tol) & free[owner]
    sticking = ~sliding & free[owner]
    size = max(float(np.max(np.abs(normal), initial=0.0)), np.finfo(float).tiny)
    if np.any(np.abs(normal[~free]) > tol * size) or np.any(np.abs(tangential[~free[owner]]) > tol * size):
        return None  # a separating row with an impulse beyond rounding: not the law's answer
    direction = np.where(sliding[:, None], slip / np.maximum(speed, 1e-300)[:, None], 0.0)
    B = _mode_basis(owner, free, sticking, mu * direction)
    stick = np.flatnonzero(sticking)
    equations = np.concatenate([np.flatnonzero(free), n + (np.arange(tangents)[:, None] * m + stick).ravel()])
    lam0 = np.linalg.lstsq(W[equations] @ B, target[equations] - u[equations], rcond=None)[0]
    _, N = row_space_split(B.T @ J)
    lam0 -= N @ (N.T @ lam0)
    answer = np.concatenate([normal[free], tangential[stick].T.ravel()])
    if np.max(np.abs(W @ (B @ lam0) + u - after), initial=0.0) > MODES_TOL * scale:
        return None  # the answer's velocities are not its modes' (not the law's answer)
    cones = _Cones(int(free.sum()), np.searchsorted(np.flatnonzero(free), owner[stick]), mu, tangents)
    if min(cones.margins(answer), default=0.0) < -tol * size:
        return None
    split = _in_cones(lam0, N, cones, answer, sides, size)
    if split is None:
        return None
    out_n, out_t = np.zeros_like(normal, dtype=float), np.zeros_like(tangential, dtype=float)
    out_n[free] = np.maximum(split[: cones.n], 0.0)  # a normal's rounding below 0
    out_t[stick] = split[cones.n :].reshape(tangents, len(stick)).T
    out_t[sliding] = -mu * out_n[owner[sliding], None] * direction[sliding]
    out_n[np.abs(out_n) <= ROUNDING * size] = 0.0  # what rounding left where the split is 0
    out_t[np.abs(out_t) <= ROUNDING * size] = 0.0
    return out_n, out_t


def _mode_basis(owner: np.ndarray, free: np.ndarray, sticking: np.ndarray, slide: np.ndarray) -> np.ndarray:
    """B with lambda = B lambda_mode: the impulses on every row (n normal, then tangent-major
    pair rows) from the mode's unknowns (the free normal rows' impulses, then the sticking pairs'
    tangential ones, tangent-major); a sliding pair's impulse is -``slide`` (mu times its slip
    direction, per pair) times its normal's."""
    n, (m, tangents) = len(free), slide.shape
    stick = np.flatnonzero(sticking)
    B = np.zeros((n + m * tangents, int(free.sum()) + len(stick) * tangents))
    column = np.cumsum(free) - 1
    B[np.flatnonzero(free), column[free]] = 1.0
    slid = np.flatnonzero(np.any(slide != 0, axis=1) & free[owner])
    for a in range(tangents):
        rows = n + a * m
        B[rows + slid, column[owner[slid]]] = -slide[slid, a]
        B[rows + stick, int(free.sum()) + a * len(stick) + np.arange(len(stick))] = 1.0
    return B


@dataclass(frozen=True)
class _Cones:
    """The law's convex set over a mode's unknowns [lambda_n (n), lambda_t (tangent-major, one
    pair per ``owner`` entry)]: lambda_n >= 0 and |lambda_t| <= mu lambda_n of each pair's normal."""

    n: int
    owner: np.ndarray
    mu: float
    tangents: int

    def pair(self, k: int) -> tuple[int, np.ndarray]:
        """Pair k's normal index and tangent indices in the unknowns."""
        return int(self.owner[k]), self.n + np.arange(self.tangents) * len(self.owner) + k

    def margins(self, lam: np.ndarray) -> np.ndarray:
        """Every constraint's slack: the normals, then mu lambda_n - |lambda_t| per pair."""
        cone = [self.mu * lam[i] - np.linalg.norm(lam[t]) for i, t in map(self.pair, range(len(self.owner)))]
        return np.concatenate([lam[: self.n], cone])

    def polygon(self, sides: int) -> np.ndarray:
        """Rows P >= 0 of the pairs' inscribed ``sides``-gon (one tangent: the interval itself)."""
        if self.tangents == 1:
            edges, reach = np.array([[1.0], [-1.0]]), 1.0
        else:
            angles = (2 * np.arange(sides) + 1) * np.pi / sides
            edges, reach = np.column_stack([np.cos(angles), np.sin(angles)]), float(np.cos(np.pi / sides))
        P = np.zeros((self.n + len(self.owner) * len(edges), self.n + len(self.owner) * self.tangents))
        P[: self.n, : self.n] = np.eye(self.n)
        for k in range(len(self.owner)):
            i, t = self.pair(k)
            r = self.n + k * len(edges)
            P[r : r + len(edges), i] = self.mu * reach * (1 + 1e-12)
            P[r : r + len(edges), t] = -edges
        return P



def _in_cones(lam0: np.ndarray, N: np.ndarray, cones: _Cones, answer: np.ndarray, sides: int,
              size: float) -> np.ndarray | None:
    """argmin |lambda| over lambda = lam0 + N z in ``cones`` (lam0 orthogonal to N's columns, so
    this is min |z|): the least-distance program on the inscribed polygon (exact with one
    tangent), then with two tangents the circle's by :func:`_on_circles` from the polygon's answer
    (from the ``answer``'s where the polygon holds none of the family)."""
    if N.shape[1] == 0:
        return lam0
    P = cones.polygon(sides)
    z = least_distance(P @ N, -(P @ lam0))
    if z is None:  # the family meets the law's set only between the polygon and the circle
        z = N.T @ answer
        active = np.flatnonzero(cones.margins(lam0 + N @ z) <= 1e-9 * size)
    else:
        tight = np.flatnonzero(P @ (lam0 + N @ z) <= 1e-9 * size)
        per = (len(P) - cones.n) // max(len(cones.owner), 1)
        active = np.unique(np.where(tight < cones.n, tight, cones.n + (tight - cones.n) // max(per, 1)))
    if cones.tangents == 1:
        return lam0 + N @ z
    return _on_circles(lam0, N, cones, z, set(active.tolist()), size)


def _on_circles(lam0: np.ndarray, N: np.ndarray, cones: _Cones, z: np.ndarray, active: set[int],
                size: float) -> np.ndarray | None:
    """min |z| s.t. ``cones.margins``(lam0 + N z) >= 0 on the circular cones (a convex program in
    the few directions of N): Newton's method on the KKT equations of the ``active`` constraints
    (:func:`_kkt_newton`), the active set changed one constraint at a time (a negative multiplier
    leaves, the most violated constraint joins) until both hold. None where it does not settle
    or an active cone is at its apex (no circle to be on)."""
    for _ in range(2 * (cones.n + len(cones.owner)) + 2):
        solved = _kkt_newton(lam0, N, cones, z, sorted(active), size)
        if solved is None:
            return None
        z, multipliers = solved
        margins = cones.margins(lam0 + N @ z)
        if multipliers.size and multipliers.min() < -1e-12 * max(1.0, float(np.max(np.abs(multipliers)))):
            active.discard(sorted(active)[int(np.argmin(multipliers))])
        elif margins.min() < -1e-13 * size:
            active.add(int(np.argmin(margins)))
        else:
            return lam0 + N @ z
    return None


def _kkt_newton(lam0: np.ndarray, N: np.ndarray, cones: _Cones, z: np.ndarray, active: list[int],
                size: float) -> tuple[np.ndarray, np.ndarray] | None:
    """z and multipliers with z = sum mu_a grad g_a(z) and g_a(z) = 0 for the active constraints
    (a normal: linear; a pair's mu lambda_n - |lambda_t|: concave), by Newton's method on those
    equations (least-squares steps: the active gradients may be dependent). None if it fails."""
    k = N.shape[1]

    def parts(z):  # the active constraints' gradients, values and curvatures (-Hessians) at z
        lam = lam0 + N @ z
        grads, values, curvature = [], [], []
        for c in active:
            if c < cones.n:
                grads.append(N[c])
                values.append(lam[c])
                curvature.append(np.zeros((k, k)))
                continue
            i, t = cones.pair(c - cones.n)
            norm = float(np.linalg.norm(lam[t]))
            if norm <= 1e-12 * size:
                return None  # the cone's apex: no circle
            d, T = lam[t] / norm, N[t]
            grads.append(cones.mu * N[i] - d @ T)
            values.append(cones.mu * lam[i] - norm)
            curvature.append((T.T @ (np.eye(len(t)) - np.outer(d, d)) @ T) / norm)
        return np.array(grads).reshape(len(active), k), np.array(values), curvature

    got = parts(z)
    if got is None:
        return None
    mult = np.linalg.lstsq(got[0].T, z, rcond=None)[0] if active else np.zeros(0)
    for _ in range(50):
        G, g, curvature = got
        F = np.concatenate([z - G.T @ mult, g])
        if np.max(np.abs(F), initial=0.0) <= 1e-15 * size:
            break
        H = np.eye(k) + sum(m * C for m, C in zip(mult, curvature))
        K = np.block([[H, -G.T], [G, np.zeros((len(active), len(active)))]])
        step = np.linalg.lstsq(K, -F, rcond=None)[0]
        z, mult = z + step[:k], mult + step[k:]
        got = parts(z)
        if got is None:
            return None
        if np.max(np.abs(step[:k]), initial=0.0) <= 1e-16 * size:
            break
    if np.max(np.abs(np.concatenate([z - got[0].T @ mult, got[1]])), initial=0.0) > 1e-12 * size:
        return None
    return z, mult


def row_space_split(J: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal bases (Ur, N) of the range of J's rows and of its left null space, the rank
    from the SVD of J with unit columns (so it does not depend on the units of the DOFs)."""
    U, s, _ = np.linalg.svd(_unit_columns(J), full_matrices=True)
    rank = _rank_of(s)
    return U[:, :rank], U[:, rank:]


def _unit_columns(J: np.ndarray) -> np.ndarray:
    scale = np.linalg.norm(J, axis=0)
    scale[scale == 0] = 1.0
    return J / scale


def _rank_of(s: np.ndarray) -> int:
    """The rank from singular values ``s``: those above RANK_TOL of the largest."""
    return int(np.sum(s > RANK_TOL * s.max())) if s.size else 0


def _rank(J: np.ndarray) -> int:
    """:func:`row_space_split`'s rank without the bases (the singular values alone: cheaper)."""
    return _rank_of(np.linalg.svd(_unit_columns(J), compute_uv=False))


def _left_null_space(J: np.ndarray) -> np.ndarray:
    return row_space_split(J)[1]


def _scaled_nnls(E: np.ndarray, f: np.ndarray) -> np.ndarray:
    """NNLS on unit columns and a unit right-hand side: the solver's tolerances are then free of
    the units (masses, speeds) of the problem. Block principal pivoting first (fast, a few
    least-squares solves), Lawson-Hanson when it does not settle."""
    E = np.asarray(E, dtype=float)
    f = np.asarray(f, dtype=float)
    col = np.linalg.norm(E, axis=0)
    scale = float(np.max(np.abs(f))) if f.size else 0.0
    x = np.zeros(E.shape[1])
    keep = col > 0
    if scale == 0.0 or not keep.any():
        return x
    Es, fs = E[:, keep] / col[keep], f / scale
    xs = _block_pivoting(Es, fs)
    x[keep] = (nnls(Es, fs) if xs is None else xs) / col[keep] * scale
    return x


#: Block pivoting steps before falling back to Lawson-Hanson.
BLOCK_PIVOTING_STEPS = 6


def _block_pivoting(E: np.ndarray, f: np.ndarray) -> np.ndarray | None:
    """min |E x - f| s.t. x >= 0 (unit columns, |f|_inf = 1) by block principal pivoting
    (Judice & Pires 1994; Kim & Park 2011 for NNLS) from the unconstrained solution: every
    infeasible index changes sides at once. Returns None unless the KKT conditions hold
    (x >= 0, g = E^T (E x - f) >= 0 where x = 0, g = 0 where x > 0) within rounding; the caller
    then runs Lawson-Hanson, which always terminates."""
    n = E.shape[1]
    tol = 1e3 * np.finfo(float).eps * max(E.shape)
    passive = np.ones(n, dtype=bool)
    for _ in range(BLOCK_PIVOTING_STEPS):
        x = np.zeros(n)
        if passive.any():
            x[passive] = np.linalg.lstsq(E[:, passive], f, rcond=None)[0]
        g = E.T @ (E @ x - f)
        infeasible = (passive & (x < 0)) | (~passive & (g < -tol))
        if not infeasible.any():
            return x
        passive ^= infeasible
    return None


__all__ = [
    "ImpactModel",
    "complementarity_impulse",
    "coulomb_cone",
    "coulomb_impulse",
    "decoupled_impulse",
    "least_norm_law_split",
    "least_norm_split",
    "redundant",
    "row_space_split",
    "share_among_twins",
    "twin_groups",
]
