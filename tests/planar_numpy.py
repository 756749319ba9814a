"""An independent numpy model of a planar tree of rods, for the tests.

Written from the conventions of ``impulse_core.model.tree`` only (no code shared with
``impulse_core.kinematics.spatial`` / ``dynamics``): every body is a rod along its own x axis, a child's
joint sits at ``at * parent.length`` on its parent and turns it by ``angle``; the base's origin is
the world origin. Generalized velocity: base (vx, vy of the base origin, omega), then one rate per
revolute joint in body order.

Planar cross products: for a rate w about z and a lever r = (rx, ry), w x r = w * (-ry, rx); for
r = (rx, ry) and f = (fx, fy), r x f = rx * fy - ry * fx (the z component).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from impulse_core.model.tree import JointKind, Tree

#: Ground normal in the plane (y up).
NORMAL = np.array([0.0, 1.0])


def perp(r: np.ndarray) -> np.ndarray:
    """z x r for planar r (rows allowed)."""
    r = np.asarray(r, dtype=float)
    return np.stack([-r[..., 1], r[..., 0]], axis=-1)


def cross2(r: np.ndarray, f: np.ndarray) -> float:
    """z component of r x f."""
    return float(r[0] * f[1] - r[1] * f[0])


@dataclass(frozen=True)
class Placement:
    """Where everything is at touchdown (world frame, metres, radians)."""

    theta: np.ndarray  # absolute angle of each body's x axis
    origin: np.ndarray  # n x 2 joint (origin) of each body
    com: np.ndarray  # n x 2
    tip: np.ndarray  # n x 2
    contacts: np.ndarray  # n_declared x 2
    contact_body: tuple[int, ...]
    body_dof: tuple[int | None, ...]  # DOF index of each body's revolute joint
    support: tuple[tuple[int, ...], ...]  # revolute DOFs (>= 3) that move each body
    nv: int


def place(tree: Tree, dtype=float) -> Placement:
    """Forward kinematics of ``tree`` at touchdown (``dtype=np.longdouble`` for a reference in
    extended precision: the design's float64 values are exact in it)."""
    n = tree.n_bodies
    theta = np.zeros(n, dtype=dtype)
    origin = np.zeros((n, 2), dtype=dtype)
    body_dof: list[int | None] = []
    support: list[tuple[int, ...]] = []
    nv = 3
    for i, b in enumerate(tree.bodies):
        if b.parent is None:
            theta[i] = dtype(b.angle)
            body_dof.append(None)
            support.append(())
            continue
        p = b.parent
        parent = tree.bodies[p]
        origin[i] = origin[p] + dtype(b.at) * dtype(parent.length) * np.array([np.cos(theta[p]), np.sin(theta[p])])
        theta[i] = theta[p] + dtype(b.angle)
        if b.joint is JointKind.REVOLUTE:
            body_dof.append(nv)
            support.append(support[p] + (nv,))
            nv += 1
        else:
            body_dof.append(None)
            support.append(support[p])
    axis = np.stack([np.cos(theta), np.sin(theta)], axis=1)
    lengths = np.array([b.length for b in tree.bodies], dtype=dtype)
    com = origin + (np.array([b.com for b in tree.bodies], dtype=dtype) * lengths)[:, None] * axis
    tip = origin + lengths[:, None] * axis
    contacts, contact_body = [], []
    for i, b in enumerate(tree.bodies):
        for c in b.contacts:
            contacts.append(origin[i] + dtype(c) * dtype(b.length) * axis[i])
            contact_body.append(i)
    return Placement(
        theta, origin, com, tip, np.array(contacts, dtype=dtype).reshape(-1, 2), tuple(contact_body), tuple(body_dof),
        tuple(support), nv,
    )


def point_jacobian(tree: Tree, pl: Placement, body: int, point: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(2 x nv) Jacobian of the velocity of a point fixed on ``body``, and the (nv,) row of the
    body's angular velocity."""
    Jv = np.zeros((2, pl.nv), dtype=pl.origin.dtype)
    Jw = np.zeros(pl.nv, dtype=pl.origin.dtype)
    Jv[:, 0] = [1.0, 0.0]
    Jv[:, 1] = [0.0, 1.0]
    Jv[:, 2] = perp(point - pl.origin[0])
    Jw[2] = 1.0
    owner = {pl.body_dof[i]: i for i in range(tree.n_bodies) if pl.body_dof[i] is not None}
    for k in pl.support[body]:
        Jv[:, k] = perp(point - pl.origin[owner[k]])
        Jw[k] = 1.0
    return Jv, Jw


def normal_jacobian(tree: Tree, pl: Placement, active: tuple[int, ...] | None = None) -> np.ndarray:
    """Rows n^T J_c of the active contacts (default: all declared)."""
    active = tuple(range(len(pl.contact_body))) if active is None else active
    rows = [NORMAL @ point_jacobian(tree, pl, pl.contact_body[c], pl.contacts[c])[0] for c in active]
    return np.array(rows, dtype=pl.origin.dtype).reshape(len(active), pl.nv)


def mass_matrix(tree: Tree, pl: Placement) -> np.ndarray:
    """M = sum_b m_b Jv_b^T Jv_b + I_b Jw_b^T Jw_b (centre-of-mass Jacobians)."""
    dtype = pl.origin.dtype.type
    M = np.zeros((pl.nv, pl.nv), dtype=dtype)
    for i, b in enumerate(tree.bodies):
        Jv, Jw = point_jacobian(tree, pl, i, pl.com[i])
        inertia = dtype(b.mass) * (dtype(b.gyration) * dtype(b.length)) ** 2
        M += dtype(b.mass) * Jv.T @ Jv + inertia * np.outer(Jw, Jw)
    return M


def solve(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """A X = B by Gaussian elimination with partial pivoting, in A's dtype (numpy's solvers are
    float64 only; this one also runs in long double for reference solutions)."""
    A = A.copy()
    X = B.copy().astype(A.dtype)
    vector = X.ndim == 1
    if vector:
        X = X[:, None]
    n = A.shape[0]
    for k in range(n):
        p = k + int(np.argmax(np.abs(A[k:, k])))
        A[[k, p]] = A[[p, k]]
        X[[k, p]] = X[[p, k]]
        for i in range(k + 1, n):
            f = A[i, k] / A[k, k]
            A[i, k:] -= f * A[k, k:]
            X[i] -= f * X[k]
    for i in reversed(range(n)):
        X[i] = (X[i] - A[i, i + 1 :] @ X[i + 1 :]) / A[i, i]
    return X[:, 0] if vector else X


def impulse_reference(tree: Tree, v_minus: np.ndarray, restitution: float, active=None, dtype=np.longdouble):
    """(v_plus, normal impulses) of Newton's law A lambda = -(1+e) J v-, computed in ``dtype``
    (default long double: a reference a few digits better than float64)."""
    pl = place(tree, dtype)
    J = normal_jacobian(tree, pl, active)
    M = mass_matrix(tree, pl)
    v = np.asarray(v_minus).astype(dtype)
    Minv_JT = solve(M, J.T.copy())
    A = J @ Minv_JT
    lam = solve(A, -(1 + dtype(restitution)) * (J @ v))
    return (v + Minv_JT @ lam).astype(float), lam.astype(float)


def descendants(tree: Tree, k: int) -> list[int]:
    """Body k and every body below it."""
    out = [k]
    for i in range(k + 1, tree.n_bodies):
        if tree.bodies[i].parent in out:
            out.append(i)
    return out


def momentum(tree: Tree, pl: Placement, v: np.ndarray, bodies, about: np.ndarray) -> tuple[np.ndarray, float]:
    """Linear momentum (2,) and angular momentum about the point ``about`` of a set of bodies."""
    P = np.zeros(2)
    L = 0.0
    for i in bodies:
        Jv, Jw = point_jacobian(tree, pl, i, pl.com[i])
        b = tree.bodies[i]
        vg = Jv @ v
        P += b.mass * vg
        L += cross2(pl.com[i] - about, b.mass * vg) + b.inertia * (Jw @ v)
    return P, L


def contact_wrench(pl: Placement, impulses: np.ndarray, active, bodies, about: np.ndarray) -> tuple[np.ndarray, float]:
    """Resultant (2,) and moment about ``about`` of the normal impulses of the active contacts
    that sit on ``bodies``."""
    F = np.zeros(2)
    Mz = 0.0
    for lam, c in zip(impulses, active):
        if pl.contact_body[c] in bodies:
            f = lam * NORMAL
            F += f
            Mz += cross2(pl.contacts[c] - about, f)
    return F, Mz


def kinetic_energy(tree: Tree, pl: Placement, v: np.ndarray) -> float:
    return 0.5 * float(v @ mass_matrix(tree, pl) @ v)


def displaced(tree: Tree, dq: np.ndarray) -> tuple[Tree, np.ndarray]:
    """The tree moved by a generalized displacement dq (base x, y, angle, then revolute joint
    angles in body order): the moved tree (the base still at the world origin) and the base
    translation to add to every position."""
    bodies = list(tree.bodies)
    bodies[0] = dataclasses.replace(bodies[0], angle=bodies[0].angle + dq[2])
    k = 3
    for i in range(1, len(bodies)):
        if bodies[i].joint is JointKind.REVOLUTE:
            bodies[i] = dataclasses.replace(bodies[i], angle=bodies[i].angle + dq[k])
            k += 1
    return Tree(tuple(bodies)), np.asarray(dq[:2], dtype=float)


def finite_difference_contact_jacobian(tree: Tree, h: float = 1e-6) -> np.ndarray:
    """2 x nv per contact, stacked (n_contacts x 2 x nv), by central differences of ``place``."""
    nv = place(tree).nv
    cols = []
    for k in range(nv):
        dq = np.zeros(nv)
        dq[k] = h
        tp, sp = displaced(tree, dq)
        tm, sm = displaced(tree, -dq)
        cols.append(((place(tp).contacts + sp) - (place(tm).contacts + sm)) / (2 * h))
    return np.stack(cols, axis=-1)


__all__ = [
    "NORMAL",
    "Placement",
    "contact_wrench",
    "descendants",
    "displaced",
    "finite_difference_contact_jacobian",
    "impulse_reference",
    "kinetic_energy",
    "mass_matrix",
    "momentum",
    "normal_jacobian",
    "place",
    "point_jacobian",
    "solve",
]
