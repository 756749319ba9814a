"""Mass matrix of a floating tree and its sparse L^T D L factorization; the tree-structured
algorithms of the hot path: joint motion subspaces, spatial inertias, the composite-rigid-body
mass matrix (RBDA alg. 6.2) and the articulated-body impulse response (RBDA alg. 7.3).

The factorization follows Featherstone (Rigid Body Dynamics Algorithms, 2008, sec. 6.5,
algorithm LTDL): with the expanded parent array, M = L^T D L has no fill-in beyond the
tree's sparsity, is free of square roots, and M^-1 is never formed.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from impulse_core.kinematics.spatial import PLANAR, BodyValues, DofKind, DofLayout, Kinematics, Space, point_jacobian


@dataclass(frozen=True)
class BodyJacobians:
    """Centre-of-mass velocity Jacobian ``Jv`` and angular velocity Jacobian ``Jw`` of each body
    (world frame, 3 x nv each), and each body's inertia about its centre of mass in the world
    frame ``W_I_G`` (3 x 3)."""

    Jv: tuple[ca.SX, ...]
    Jw: tuple[ca.SX, ...]
    W_I_G: tuple[ca.SX, ...]


def body_jacobians(
    kin: Kinematics, layout: DofLayout, values: tuple[BodyValues, ...], space: Space = PLANAR
) -> BodyJacobians:
    """Jacobians of every body's centre of mass, and its world-frame inertia.

    A rod's inertia about its centre of mass in its own frame is diag(I_axial, I, I) with
    I = mass * (gyration * length)^2 and I_axial = ``BodyValues.axial_inertia`` (0 in the plane).
    """
    Jv, Jw, inertia = [], [], []
    for b, v in enumerate(values):
        jv, jw = point_jacobian(kin, layout, b, kin.W_p_G[b], space)
        Jv.append(jv)
        Jw.append(jw)
        B_I = ca.diag(ca.vertcat(v.axial_inertia, v.inertia, v.inertia))
        inertia.append(_with_tensor(kin.W_R_B[b] @ B_I @ kin.W_R_B[b].T, kin.W_R_B[b], v))
    return BodyJacobians(tuple(Jv), tuple(Jw), tuple(inertia))


def mass_matrix(jac: BodyJacobians, values: tuple[BodyValues, ...]) -> ca.SX:
    """Joint-space mass matrix M = sum_b m_b Jv_b^T Jv_b + Jw_b^T I_b Jw_b (nv x nv)."""
    M = 0
    for b, v in enumerate(values):
        M = M + v.mass * (jac.Jv[b].T @ jac.Jv[b]) + jac.Jw[b].T @ jac.W_I_G[b] @ jac.Jw[b]
    return M


@dataclass(frozen=True)
class LTDL:
    """M = L^T D L with L unit lower triangular, stored sparsely: ``L[(k, i)]`` for each
    ancestor i of k; ``D`` the diagonal; ``parent`` the expanded parent array; ``D_inv`` the
    reciprocals of ``D`` where the factor divides once per pivot (:func:`ltdl`), else None."""

    L: dict[tuple[int, int], ca.SX]
    D: tuple[ca.SX, ...]
    parent: tuple[int, ...]
    D_inv: tuple[ca.SX, ...] | None = None

    def ancestors(self, k: int):
        i = self.parent[k]
        while i >= 0:
            yield i
            i = self.parent[i]


def reciprocal(x: ca.SX) -> ca.SX:
    """1 / x bit for bit (2 / (x + x): both scalings by 2 exact), as a node CasADi keeps in a
    product (it rewrites y * (1 / x) as y / x)."""
    return 2 / (x + x)


def ltdl(M: ca.SX, parent: tuple[int, ...], reciprocals: bool = False) -> LTDL:
    """Factor a symmetric positive definite M whose sparsity follows ``parent`` (RBDA alg. 6.3).

    A dense matrix is the special case ``parent = (-1, 0, 1, ..., n-2)``. With ``reciprocals``,
    one division per pivot: the multipliers and :func:`solve_d` multiply by its reciprocal.
    """
    n = M.shape[0]
    H: dict[tuple[int, int], ca.SX] = {}

    def anc(k: int):
        i = parent[k]
        while i >= 0:
            yield i
            i = parent[i]

    for k in range(n):
        H[(k, k)] = M[k, k]
        for i in anc(k):
            H[(k, i)] = M[k, i]
    inv: dict[int, ca.SX] = {}
    for k in reversed(range(n)):
        if reciprocals:
            inv[k] = reciprocal(H[(k, k)])
        for i in anc(k):
            a = H[(k, i)] * inv[k] if reciprocals else H[(k, i)] / H[(k, k)]
            H[(i, i)] = H[(i, i)] - a * H[(k, i)]
            for j in anc(i):
                H[(i, j)] = H[(i, j)] - a * H[(k, j)]
            H[(k, i)] = a
    D = tuple(H[(k, k)] for k in range(n))
    L = {(k, i): H[(k, i)] for k in range(n) for i in anc(k)}
    return LTDL(L, D, tuple(parent), tuple(inv[k] for k in range(n)) if reciprocals else None)


def dense_parent(n: int) -> tuple[int, ...]:
    """Parent array of a dense n x n matrix."""
    return tuple(range(-1, n - 1))


def solve_lt(f: LTDL, Y: ca.SX) -> ca.SX:
    """Z = L^-T Y (columns of Y independently)."""
    Z = [Y[k, :] for k in range(Y.shape[0])]
    for k in reversed(range(len(Z))):
        for i in f.ancestors(k):
            Z[i] = Z[i] - f.L[(k, i)] * Z[k]
    return ca.vertcat(*Z)


def solve_l(f: LTDL, W: ca.SX) -> ca.SX:
    """X = L^-1 W."""
    X = [W[k, :] for k in range(W.shape[0])]
    for k in range(len(X)):
        for i in f.ancestors(k):
            X[k] = X[k] - f.L[(k, i)] * X[i]
    return ca.vertcat(*X)


def solve_d(f: LTDL, W: ca.SX) -> ca.SX:
    """D^-1 W."""
    if f.D_inv is not None:
        return ca.vertcat(*[W[k, :] * f.D_inv[k] for k in range(W.shape[0])])
    return ca.vertcat(*[W[k, :] / f.D[k] for k in range(W.shape[0])])


def solve(f: LTDL, Y: ca.SX) -> ca.SX:
    """M^-1 Y by two sparse triangular solves and a diagonal one."""
    return solve_l(f, solve_d(f, solve_lt(f, Y)))


def relative_pivots(f: LTDL, M: ca.SX) -> ca.SX:
    """D_k / M_kk for each k: all in (0, 1] for a positive definite M; near 0 where M loses rank."""
    return ca.vertcat(*[f.D[k] / M[k, k] for k in range(len(f.D))])


# --- Tree-structured algorithms -------------------------------------------------------------
#
# World-frame coordinates with a moving reference point (RBDA sec. 2.8): each body's velocity is
# (omega, v_O), its angular velocity and the velocity of its own joint origin O; each subtree's
# inertia is taken about the joint origin of its root. Only differences of nearby points (rod
# vectors) enter, never lever arms from the world origin, so a 0.1 mm rod beside a 10 m one keeps
# its digits (tests/impulse_core/test_extremes.py).


@dataclass(frozen=True)
class JointMotion:
    """Motion subspace of one DOF, world frame: unit rate moves the body with angular velocity
    ``omega`` and the point ``origin`` with velocity ``v`` (base translation e: (0, e);
    rotation about the axis a through o: omega = a, v = 0, origin = o)."""

    omega: ca.SX
    v: ca.SX
    origin: ca.SX

    def velocity_at(self, W_p: ca.SX) -> ca.SX:
        """Velocity of the point ``W_p`` (world frame) moving with this DOF at unit rate."""
        return self.v + ca.cross(self.omega, W_p - self.origin)


def joint_motions(kin: Kinematics, layout: DofLayout, space: Space = PLANAR) -> tuple[JointMotion, ...]:
    """The motion subspace of every DOF (base DOFs first, then the revolute joints)."""
    n_base = len(space.base_dofs)
    zero = ca.SX.zeros(3, 1)
    out = []
    for k in range(layout.nv):
        if k < n_base:
            kind, axis = space.base_dofs[k]
            e = ca.SX(ca.DM(axis))
            translation = kind is DofKind.TRANSLATION
            out.append(JointMotion(zero if translation else e, e if translation else zero, kin.W_p_O[0]))
        else:
            j = layout.dof_body[k]
            out.append(JointMotion(kin.joint_axis[j], zero, kin.W_p_O[j]))
    return tuple(out)


def body_velocities(
    parents: tuple[int, ...], kin: Kinematics, layout: DofLayout, motions: tuple[JointMotion, ...], x: ca.SX
) -> tuple[tuple[ca.SX, ...], tuple[ca.SX, ...]]:
    """Angular velocity and velocity of the joint origin O_b of every body (world frame) under
    the generalized velocity ``x``: one forward pass (RBDA alg. 7.3, first loop), the base's
    from its DOFs, each child's from its parent's plus its own joint (which turns about O_b)."""
    omega: list[ca.SX] = []
    vel: list[ca.SX] = []
    for b, parent in enumerate(parents):
        O_b = kin.W_p_O[b]
        if parent < 0:
            w, v = ca.SX.zeros(3, 1), ca.SX.zeros(3, 1)
            for k in layout.body_support[0]:
                w = w + motions[k].omega * x[k]
                v = v + motions[k].velocity_at(O_b) * x[k]
        else:
            w, v = omega[parent], vel[parent] + ca.cross(omega[parent], O_b - kin.W_p_O[parent])
            k = layout.body_dof[b]
            if k is not None:
                w = w + motions[k].omega * x[k]
        omega.append(w)
        vel.append(v)
    return tuple(omega), tuple(vel)


@dataclass(frozen=True)
class SpatialInertia:
    """A rigid body's (or a subtree's) inertia about a reference point P, world frame.

    Attributes:
        mass: total mass (kg).
        h: first moment of mass about P, mass * (centre of mass - P) (kg m, 3-vector).
        I_P: rotational inertia about P (kg m^2, 3 x 3).
    """

    mass: ca.SX
    h: ca.SX
    I_P: ca.SX

    def shifted(self, d: ca.SX) -> SpatialInertia:
        """The same inertia about P - d (parallel-axis theorem with r -> r + d); each symmetric
        pair of I_Q formed once (the same values: a sum's and a product's operands swapped)."""
        E = ca.DM.eye(3)
        h = self.h + self.mass * d
        dh = d @ self.h.T
        I_Q = self.I_P + (2 * (d.T @ self.h) + self.mass * (d.T @ d)) * E - (dh + dh.T + self.mass * (d @ d.T))
        return SpatialInertia(self.mass, h, _symmetric(I_Q))

    def __add__(self, other: SpatialInertia) -> SpatialInertia:
        return SpatialInertia(self.mass + other.mass, self.h + other.h, self.I_P + other.I_P)

    def momentum(self, omega: ca.SX, v_P: ca.SX) -> tuple[ca.SX, ca.SX]:
        """Momentum (L_P, p) when moving with angular velocity omega and the point P with v_P:
        p = m v_P + omega x h, L_P = I_P omega + h x v_P (RBDA eq. 2.63)."""
        return self.I_P @ omega + ca.cross(self.h, v_P), self.mass * v_P + ca.cross(omega, self.h)


def com_velocities(kin: Kinematics, omega: tuple[ca.SX, ...], vel: tuple[ca.SX, ...]) -> tuple[ca.SX, ...]:
    """Velocity of every body's centre of mass, from the body velocities (:func:`body_velocities`)."""
    return tuple(vel[b] + ca.cross(omega[b], kin.W_p_G[b] - kin.W_p_O[b]) for b in range(len(omega)))


def kinetic_bilinear(
    kin: Kinematics,
    values: tuple[BodyValues, ...],
    x: tuple[tuple[ca.SX, ...], tuple[ca.SX, ...]],
    y: tuple[tuple[ca.SX, ...], tuple[ca.SX, ...]],
) -> ca.SX:
    """x^T M y from the body velocities (omega, vel) of x and of y (:func:`body_velocities`): the
    sum over bodies of m v_G(x) . v_G(y) + omega_x^T I_G omega_y, with the rod's
    I_G = I (E - r r^T) + I_axial r r^T (r its axis, ``W_R_B[:, 0]``) plus R T R^T (its added
    tensor) applied as dot products. Equal to the sum of twist(x) . momentum(y) about each joint
    origin (parallel-axis theorem) without forming a world-frame inertia: a cheaper graph to
    differentiate w.r.t. the design."""
    (ox, vx), (oy, vy) = x, y
    gx, gy = com_velocities(kin, ox, vx), com_velocities(kin, oy, vy)
    total = ca.SX(0)
    for b, v in enumerate(values):
        R = kin.W_R_B[b]
        r = R[:, 0]
        total = total + v.mass * (gx[b].T @ gy[b]) + v.inertia * (ox[b].T @ oy[b])
        total = total - (v.inertia - v.axial_inertia) * (ox[b].T @ r) * (oy[b].T @ r)
        if not v.is_rod:
            total = total + (R.T @ ox[b]).T @ added_tensor(ca.SX.eye(3), v) @ (R.T @ oy[b])
    return total


def added_tensor(R: ca.SX, v: BodyValues) -> ca.SX:
    """A body's added inertia tensor (``BodyValues.tensor``, body axes) in the world frame,
    R T R^T: each of its six distinct entries formed once."""
    ixx, iyy, izz, ixy, ixz, iyz = v.tensor
    T = ca.SX(3, 3)
    T[0, 0], T[1, 1], T[2, 2] = ixx, iyy, izz
    T[0, 1] = T[1, 0] = ixy
    T[0, 2] = T[2, 0] = ixz
    T[1, 2] = T[2, 1] = iyz
    A = R @ T
    out = ca.SX(3, 3)
    for i in range(3):
        for j in range(i, 3):
            out[i, j] = A[i, 0] * R[j, 0] + A[i, 1] * R[j, 1] + A[i, 2] * R[j, 2]
            out[j, i] = out[i, j]
    return out


def _with_tensor(W_I_G: ca.SX, R: ca.SX, v: BodyValues) -> ca.SX:
    """The rod's world-frame inertia plus the body's added tensor (a term added after the rod's
    own, so a zero tensor leaves the rod's value unchanged); the rod's alone in the plane."""
    return W_I_G if v.is_rod else W_I_G + added_tensor(R, v)


def body_inertias(kin: Kinematics, values: tuple[BodyValues, ...]) -> tuple[SpatialInertia, ...]:
    """Each rod's inertia about its own joint origin. In its own frame a rod's inertia about its
    centre of mass is diag(I_axial, I, I), I = mass * (gyration * length)^2, plus the body's
    added tensor (space: ``BodyValues.tensor``)."""
    out = []
    for b, v in enumerate(values):
        R = kin.W_R_B[b]
        W_I_G = v.inertia * (R[:, 1] @ R[:, 1].T + R[:, 2] @ R[:, 2].T) + v.axial_inertia * (R[:, 0] @ R[:, 0].T)
        W_I_G = _with_tensor(W_I_G, R, v)
        about_G = SpatialInertia(v.mass, ca.SX.zeros(3, 1), W_I_G)
        out.append(about_G.shifted(kin.W_p_G[b] - kin.W_p_O[b]))
    return tuple(out)


def lean_body_inertias(kin: Kinematics, values: tuple[BodyValues, ...]) -> tuple[SpatialInertia, ...]:
    """:func:`body_inertias` to rounding, in fewer operations: with r the rod's axis (``W_R_B[:, 0]``),
    s = com * length and o the centre of mass's offset off the rod (G - O = s r + o), the
    parallel-axis theorem with |r| = 1 gives
    I_O = (I + m s^2) E + (I_axial - I - m s^2) r r^T + m ((2 s r.o + o.o) E - s (r o^T + o r^T) - o o^T)
    + R T R^T: for a rod (o and T folded to 0) two scalars times E and r r^T, each symmetric entry
    formed once, and no other column of the rod's rotation. Rounds otherwise than
    :func:`body_inertias` (whose rod part is I (R_1 R_1^T + R_2 R_2^T) + I_axial r r^T shifted by
    d d^T): the hot path's (:func:`impulse_core.impact.delassus.lean_impact_function`); the full
    model keeps :func:`body_inertias`."""
    out = []
    for v, R in zip(values, kin.W_R_B):
        r = R[:, 0]
        s = v.com * v.length
        o = com_offset(R, v)
        m_s2 = v.mass * s**2
        alpha, beta = v.inertia + m_s2, v.axial_inertia - v.inertia - m_s2
        c = v.mass * (2 * s * (r.T @ o) + o.T @ o)
        I_O = ca.SX(3, 3)
        for i in range(3):
            for j in range(i, 3):
                offset = v.mass * (s * (r[i] * o[j] + o[i] * r[j]) + o[i] * o[j])
                I_O[i, j] = beta * (r[i] * r[j]) - offset + (alpha + c if i == j else 0)
                I_O[j, i] = I_O[i, j]
        out.append(SpatialInertia(v.mass, v.mass * (r * s + o), _with_tensor(I_O, R, v)))
    return tuple(out)


def com_offset(R: ca.SX, v: BodyValues) -> ca.SX:
    """The centre of mass's offset off the rod, world frame: ``com_offset`` along the body frame's
    y and z (zero for a rod)."""
    if v.is_rod:
        return ca.SX.zeros(3, 1)
    dy, dz = v.com_offset
    return R[:, 1] * dy + R[:, 2] * dz


def composite_inertias(
    parents: tuple[int, ...], kin: Kinematics, inertias: tuple[SpatialInertia, ...]
) -> tuple[SpatialInertia, ...]:
    """Inertia of every body's subtree about the body's joint origin: one backward pass
    (RBDA alg. 6.2, first loop), shifting each child's composite to its parent's origin."""
    Ic = list(inertias)
    for b in reversed(range(1, len(Ic))):
        parent = parents[b]
        Ic[parent] = Ic[parent] + Ic[b].shifted(kin.W_p_O[b] - kin.W_p_O[parent])
    return tuple(Ic)


def composite_mass_matrix(
    parents: tuple[int, ...],
    kin: Kinematics,
    layout: DofLayout,
    values: tuple[BodyValues, ...],
    space: Space = PLANAR,
    inertias: tuple[SpatialInertia, ...] | None = None,
) -> ca.SX:
    """Joint-space mass matrix by the composite-rigid-body algorithm (RBDA alg. 6.2): for DOF j
    of body b, F_j = Ic_b S_j (momentum of b's subtree moving with DOF j, about O_b), and
    M_ij = S_i^T F_j for i = j and every ancestor DOF i. Equals :func:`mass_matrix`; only the
    entries the tree's sparsity allows are formed (the rest are structural zeros). ``inertias``:
    the bodies' (default :func:`body_inertias`)."""
    S = joint_motions(kin, layout, space)
    Ic = composite_inertias(parents, kin, body_inertias(kin, values) if inertias is None else inertias)
    M = ca.SX(layout.nv, layout.nv)
    for j in range(layout.nv):
        b = layout.dof_body[j]
        O_b = kin.W_p_O[b]
        L, p = Ic[b].momentum(S[j].omega, S[j].velocity_at(O_b))
        i = j
        while i >= 0:
            M[i, j] = S[i].omega.T @ L + S[i].velocity_at(O_b).T @ p
            M[j, i] = M[i, j]
            i = layout.dof_parent[i]
    return M


# --- Articulated-body algorithm for impulses (RBDA sec. 7.3) ----------------------------------
#
# Spatial vectors are 6-vectors in world coordinates about a reference point: a motion is
# (omega; v_P), a force (n_P; f). Body b's quantities are about its joint origin O_b.


def spatial_matrix(I: SpatialInertia) -> ca.SX:
    """The 6 x 6 matrix of a rigid-body inertia: (L_P; p) = [[I_P, [h]x], [[h]x^T, m E]] (omega; v_P)."""
    H = ca.skew(I.h)
    return ca.blockcat([[I.I_P, H], [H.T, I.mass * ca.DM.eye(3)]])


def motion_shift(r: ca.SX) -> ca.SX:
    """6 x 6 transform of a motion from reference point P to P + r: v_(P+r) = v_P + omega x r."""
    return ca.blockcat([[ca.DM.eye(3), ca.DM.zeros(3, 3)], [-ca.skew(r), ca.DM.eye(3)]])


def force_shift(r: ca.SX) -> ca.SX:
    """6 x 6 transform of a force from reference point P to P + r: n_(P+r) = n_P - r x f."""
    return ca.blockcat([[ca.DM.eye(3), -ca.skew(r)], [ca.DM.zeros(3, 3), ca.DM.eye(3)]])


def _symmetric(M: ca.SX) -> ca.SX:
    """M with its lower triangle copied from the upper one (one expression per pair)."""
    out = ca.SX(M.shape[0], M.shape[1])
    for i in range(M.shape[0]):
        for j in range(i, M.shape[1]):
            out[i, j] = M[i, j]
            out[j, i] = M[i, j]
    return out


@dataclass(frozen=True)
class ArticulatedBodies:
    """Articulated-body inertias of a tree (RBDA alg. 7.3, pass 2, without the bias terms).

    Attributes:
        S: each body's motion subspace at O_b (6 x DOFs of its joint: 3 for the base, 1 for a
            revolute joint, 0 for a fixed one).
        dofs: each body's DOF indices.
        U: IA_b S_b per body; D: the factor of S_b^T U_b (an LTDL, or None without DOFs).
        r_parent: O_parent - O_b per body (zero for the base).
        parents: the parent of each body (-1 for the base).
    """

    S: tuple[ca.SX, ...]
    dofs: tuple[tuple[int, ...], ...]
    U: tuple[ca.SX, ...]
    D: tuple[LTDL | None, ...]
    r_parent: tuple[ca.SX, ...]
    parents: tuple[int, ...]


def articulated_bodies(
    parents: tuple[int, ...],
    kin: Kinematics,
    layout: DofLayout,
    inertias: tuple[SpatialInertia, ...],
    space: Space = PLANAR,
) -> ArticulatedBodies:
    """Articulated-body inertias, leaves to root (RBDA alg. 7.3, second loop): IA_b = I_b + sum
    over children of X* (IA_c - U_c D_c^-1 U_c^T) X, each child's term shifted to O_b."""
    motions = joint_motions(kin, layout, space)
    n = len(parents)
    n_base = len(space.base_dofs)
    dofs = [
        tuple(range(n_base)) if b == 0 else (() if layout.body_dof[b] is None else (layout.body_dof[b],))
        for b in range(n)
    ]
    S = []
    for b in range(n):
        cols = [ca.vertcat(motions[k].omega, motions[k].velocity_at(kin.W_p_O[b])) for k in dofs[b]]
        S.append(ca.horzcat(*cols) if cols else ca.SX(6, 0))
    IA = [spatial_matrix(I) for I in inertias]
    U: list[ca.SX] = [ca.SX(6, 0)] * n
    D: list[LTDL | None] = [None] * n
    r_parent = [ca.SX.zeros(3, 1)] + [kin.W_p_O[parents[b]] - kin.W_p_O[b] for b in range(1, n)]
    for b in reversed(range(n)):
        Ia = IA[b]
        if S[b].shape[1]:
            U[b] = IA[b] @ S[b]
            D[b] = ltdl(_symmetric(S[b].T @ U[b]), dense_parent(S[b].shape[1]))
            if b > 0:
                Ia = _symmetric(IA[b] - U[b] @ solve(D[b], U[b].T))
        if b > 0:
            r = r_parent[b]
            IA[parents[b]] = IA[parents[b]] + _symmetric(force_shift(r) @ Ia @ motion_shift(-r))
    return ArticulatedBodies(tuple(S), tuple(dofs), tuple(U), tuple(D), tuple(r_parent), tuple(parents))


def impulse_response(
    art: ArticulatedBodies, forces: dict[int, ca.SX], joint_impulses: ca.SX | None = None
) -> tuple[tuple[ca.SX, ...], dict[int, ca.SX]]:
    """Velocity change of every body under external impulses (RBDA alg. 7.3 with zero velocity:
    Delta v = M^-1 (J^T lambda + tau) in O(n)).

    Args:
        art: the tree's articulated-body inertias.
        forces: external impulse on body b as a spatial force (moment about O_b; force), 6 x 1.
        joint_impulses: generalized impulse tau on every DOF (nv x 1), or None for zero.

    Returns:
        (each body's change of spatial velocity (omega; v at O_b), each body's DOF rate changes).
    """
    n = len(art.parents)
    zero6 = ca.SX.zeros(6, 1)
    pA = [-forces.get(b, zero6) for b in range(n)]
    u: list[ca.SX | None] = [None] * n
    for b in reversed(range(n)):
        if art.S[b].shape[1]:
            u[b] = -(art.S[b].T @ pA[b])
            if joint_impulses is not None:
                u[b] = u[b] + ca.vertcat(*[joint_impulses[k] for k in art.dofs[b]])
        if b > 0:
            pa = pA[b]
            if art.S[b].shape[1]:
                pa = pa + art.U[b] @ solve(art.D[b], u[b])
            pA[art.parents[b]] = pA[art.parents[b]] + force_shift(art.r_parent[b]) @ pa
    a: list[ca.SX] = []
    rates: dict[int, ca.SX] = {}
    for b in range(n):
        a_b = zero6 if b == 0 else motion_shift(-art.r_parent[b]) @ a[art.parents[b]]
        if art.S[b].shape[1]:
            qdd = solve(art.D[b], u[b] - art.U[b].T @ a_b)
            a_b = a_b + art.S[b] @ qdd
            for i, k in enumerate(art.dofs[b]):
                rates[k] = qdd[i]
        a.append(a_b)
    return tuple(a), rates
