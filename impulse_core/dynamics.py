"""Mass matrix of a floating tree and its sparse L^T D L factorization.

The factorization follows Featherstone (Rigid Body Dynamics Algorithms, 2008, sec. 6.5,
algorithm LTDL): with the expanded parent array, M = L^T D L has no fill-in beyond the
tree's sparsity, is free of square roots, and M^-1 is never formed.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from impulse_core.kinematics import BodyValues, DofLayout, Kinematics, Space, PLANAR, point_jacobian


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

    A rod's inertia about its centre of mass in its own frame is diag(0, I, I) with
    I = mass * (gyration * length)^2 (slender rod: none about its own axis).
    """
    Jv, Jw, inertia = [], [], []
    for b, v in enumerate(values):
        jv, jw = point_jacobian(kin, layout, b, kin.W_p_G[b], space)
        Jv.append(jv)
        Jw.append(jw)
        B_I = ca.diag(ca.vertcat(0, v.inertia, v.inertia))
        inertia.append(kin.W_R_B[b] @ B_I @ kin.W_R_B[b].T)
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
    ancestor i of k; ``D`` the diagonal; ``parent`` the expanded parent array."""

    L: dict[tuple[int, int], ca.SX]
    D: tuple[ca.SX, ...]
    parent: tuple[int, ...]

    def ancestors(self, k: int):
        i = self.parent[k]
        while i >= 0:
            yield i
            i = self.parent[i]


def ltdl(M: ca.SX, parent: tuple[int, ...]) -> LTDL:
    """Factor a symmetric positive definite M whose sparsity follows ``parent`` (RBDA alg. 6.3).

    A dense matrix is the special case ``parent = (-1, 0, 1, ..., n-2)``.
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
    for k in reversed(range(n)):
        for i in anc(k):
            a = H[(k, i)] / H[(k, k)]
            H[(i, i)] = H[(i, i)] - a * H[(k, i)]
            for j in anc(i):
                H[(i, j)] = H[(i, j)] - a * H[(k, j)]
            H[(k, i)] = a
    D = tuple(H[(k, k)] for k in range(n))
    L = {(k, i): H[(k, i)] for k in range(n) for i in anc(k)}
    return LTDL(L, D, tuple(parent))


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
    return ca.vertcat(*[W[k, :] / f.D[k] for k in range(W.shape[0])])


def solve(f: LTDL, Y: ca.SX) -> ca.SX:
    """M^-1 Y by two sparse triangular solves and a diagonal one."""
    return solve_l(f, solve_d(f, solve_lt(f, Y)))


def relative_pivots(f: LTDL, M: ca.SX) -> ca.SX:
    """D_k / M_kk for each k: all in (0, 1] for a positive definite M; near 0 where M loses rank."""
    return ca.vertcat(*[f.D[k] / M[k, k] for k in range(len(f.D))])
