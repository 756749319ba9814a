"""The dynamics at (q, v): one CasADi call (:func:`landing_function`) read into a :class:`_Point`
(gaps, normals, Jacobians, mass matrix, forces), the contacts' tangents, the joint laws as arrays
(:class:`_Joints`) and their fastest rate, and the numeric checks every later module uses."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from impulse_core.kinematics.spatial import PLANAR, Space, dof_layout
from impulse_core.model.heightfield import Heightfield, is_twisted
from impulse_core.model.joints import FREE, JointLaw
from impulse_core.model.terrain import Terrain
from impulse_core.model.tree import Tree
from impulse_core.timedomain.compliant import DYNAMICS_INPUTS, Expressions, expressions, ground_expression


try:  # np.count_nonzero's C function (its wrapper calls it with the array alone: _any)
    from numpy._core.multiarray import count_nonzero as _count_nonzero
except ImportError:  # numpy < 2
    _count_nonzero = np.count_nonzero


LANDING_OUTPUTS = ("gap", "normal", "contact_jacobian", "contact_bias", "mass_matrix", "force", "kinetic_energy",
                   "subtree_momentum", "com_height", "contacts")


@functools.lru_cache(maxsize=64)
def landing_function(topology, terrain: Terrain | Heightfield, space: Space = PLANAR) -> ca.Function:
    """What the landing needs at (q, v, p, gravity), one call per evaluation: ``gap`` (n_c),
    ``normal`` (d x n_c, outward at the nearest ground point), ``contact_jacobian`` (d n_c x nv),
    ``contact_bias`` ((dJ/dt) v, d n_c), ``mass_matrix``, ``force`` (gravity - Coriolis),
    ``kinetic_energy``, ``subtree_momentum`` (d x bodies), ``com_height``, ``contacts`` (d x n_c);
    d = 2 in the plane (``terrain`` a profile), 3 in space (a heightfield; q and v as in
    :func:`impulse_core.timedomain.compliant._spatial_expressions`)."""
    x = expressions(topology, space)
    nc = x.contacts.shape[1]
    pairs = [ground_expression(terrain, x.contacts[:, c]) for c in range(nc)]
    outs = [
        ca.vertcat(*[g for g, _ in pairs]),
        ca.horzcat(*[n for _, n in pairs]),
        x.contact_jacobian,
        turning_ground_bias(x, [n for _, n in pairs]) if isinstance(terrain, Heightfield) and is_twisted(terrain)
        else x.contact_bias,
        x.mass_matrix,
        x.force,
        x.kinetic_energy,
        x.subtree_momentum,
        x.com_height,
        x.contacts,
    ]
    return ca.Function(
        "landing", [x.q, x.v, x.p, x.gravity], [ca.densify(o) for o in outs], list(DYNAMICS_INPUTS),
        list(LANDING_OUTPUTS)
    )


def turning_ground_bias(x: Expressions, normals: list[ca.SX]) -> ca.SX:
    """The contacts' bias (dJ/dt) v plus, along each normal n, n' . p' (p' the point's velocity,
    n' = dn/dq q' the turn of the ground's normal under it): so a normal row's bias n . (dJ/dt) v
    + n' . p' is the gap's second derivative at rest on a twisted heightfield patch (at zero gap
    and normal speed, g'' = n . p'' + n' . p'), and the tangent rows' are unchanged (t . n = 0).
    Without it a contact sliding across a twist at speed s had an unmodelled normal acceleration
    of order s^2 times the twist: the contact problem opened it while it sank, and random file
    30992 took 4,400 plastic touchdowns 1.9e-8 s apart."""
    d = x.dims
    parts = []
    for c, n in enumerate(normals):
        J = x.contact_jacobian[d * c : d * c + d, :]
        turn = ca.dot(ca.jtimes(n, x.q, x.v), J @ x.v)
        parts.append(x.contact_bias[d * c : d * c + d] + n * turn)
    return ca.vertcat(*parts)


@dataclass
class _Point:
    """Numeric dynamics at one (q, v), spring and damper torques included (d = 2 in the plane, 3
    in space; each contact has d - 1 tangents: +x's in the plane, the tangent plane's x and z in
    space, :func:`tangent_basis`)."""

    gap: np.ndarray
    normal: np.ndarray  # n_c x d
    tangent: np.ndarray  # n_c x (d - 1) x d
    Jn: np.ndarray  # n_c x nv
    Jt: np.ndarray  # n_c x (d - 1) x nv
    bn: np.ndarray  # (dJn/dt) v
    bt: np.ndarray  # n_c x (d - 1)
    M: np.ndarray
    f: np.ndarray
    kinetic: float
    momentum: np.ndarray  # d x bodies
    com_height: float
    contacts: np.ndarray  # n_c x d
    slip: np.ndarray  # n_c x (d - 1): the tangential velocities at this (q, v)
    slip_floor: float = 0.0  # below this slip speed a sliding contact keeps its mode's direction

    def vn(self, v: np.ndarray) -> np.ndarray:
        return self.Jn @ v

    def vt(self, v: np.ndarray) -> np.ndarray:
        """Tangential velocities (n_c x (d - 1)) of the generalized velocity v."""
        return self.Jt @ v


def momentum_terms(M, v, dims: int):  # type: ignore[no-untyped-def]
    """The linear momentum's terms at velocity ``v`` summed in absolute value, sum_k |P_ik v_k| for
    each of its ``dims`` components i (numpy or CasADi): the base's translations lead the
    velocities in every :class:`~impulse_core.kinematics.spatial.Space`, so the linear momentum is
    their generalized momentum P v, P the mass matrix ``M``'s first ``dims`` rows, and rounds at
    this scale (:meth:`_Landing.balance_rounding`)."""
    return abs(M[:dims, :]) @ abs(v)


def tangent_basis(normal: np.ndarray) -> np.ndarray:
    """Per contact (rows of ``normal``, n_c x d), its d - 1 unit tangents (n_c x (d - 1) x d): in
    the plane (n_y, -n_x) (+x on flat ground); in space t_x, x's projection on the tangent plane,
    and t_z = t_x x n (x and z on flat ground), so that a planar normal gives the planar tangent."""
    if normal.shape[1] == 2:
        tangent = np.empty((len(normal), 1, 2))
        tangent[:, 0, 0], tangent[:, 0, 1] = normal[:, 1], -normal[:, 0]
        return tangent
    t_x = np.array([1.0, 0.0, 0.0]) - normal[:, :1] * normal
    t_x /= np.sqrt(np.einsum("ij,ij->i", t_x, t_x))[:, None]
    (a, b, c), (x, y, z) = t_x.T, normal.T
    t_z = np.column_stack([b * z - c * y, c * x - a * z, a * y - b * x])  # t_x x n
    return np.stack([t_x, t_z], axis=1)


def _along(directions: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """sum_k directions[:, k] rows[:, k]: per contact, the component of ``rows`` (n_c x d x ...)
    along its direction (n_c x d)."""
    shape = (-1,) + (1,) * (rows.ndim - 2)
    out = directions[:, 0].reshape(shape) * rows[:, 0]
    for k in range(1, directions.shape[1]):  # in order, as numpy's sum over the axis adds
        out += directions[:, k].reshape(shape) * rows[:, k]
    return out


@dataclass(frozen=True)
class _Joints:
    """Joint laws as arrays over the generalized velocities (base entries inert)."""

    stiffness: np.ndarray
    damping: np.ndarray
    rest: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    restitution: np.ndarray
    dof_body: tuple[int, ...]

    def torque(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        return -self.stiffness * (q - self.rest) - self.damping * v

    def energy(self, q: np.ndarray) -> float:
        return float(0.5 * np.sum(self.stiffness * (q - self.rest) ** 2))

    @functools.cached_property
    def stopped(self) -> np.ndarray:
        """Per DOF: whether it has a stop."""
        return np.isfinite(self.lo) | np.isfinite(self.hi)


def joint_arrays(tree: Tree, laws: tuple[JointLaw, ...], q0: np.ndarray, space: Space = PLANAR) -> _Joints:
    """:class:`_Joints` of ``laws`` (one per body; () = all free), rest angles defaulting to the
    touchdown configuration ``q0``."""
    layout = dof_layout(tree.topology(), space)
    nv = layout.nv
    k, c, e = np.zeros(nv), np.zeros(nv), np.zeros(nv)
    rest, lo, hi = q0.copy(), np.full(nv, -np.inf), np.full(nv, np.inf)
    for b, law in enumerate(laws or (FREE,) * tree.n_bodies):
        j = layout.body_dof[b] if b > 0 else None
        if j is None:
            continue
        k[j], c[j], e[j] = law.stiffness, law.damping, law.stop_restitution
        if law.rest is not None:
            rest[j] = law.rest
        if law.limits is not None:
            lo[j], hi[j] = law.limits
    return _Joints(k, c, rest, lo, hi, e, layout.dof_body)


def joint_law_rate(M: np.ndarray, damping: np.ndarray, stiffness: np.ndarray) -> float:
    """The joint laws' fastest rate (1/s) at a mass matrix M: the largest eigenvalue of M^-1 D (a
    damper's decay rate) or square root of that of M^-1 K (a spring's angular frequency), D and K
    the diagonal damping and stiffness per DOF. Constraints only lower it (interlacing). Where a
    massless direction's eigenvalue rounds below 0 (rods of radius 0 turning about their own axes
    with nothing but the core's floor as inertia: random file 60603, where the Cholesky factor
    failed), M's factor is taken from its eigenvalues floored at eps x the largest."""
    try:
        L = np.linalg.cholesky(M)
    except np.linalg.LinAlgError:
        w, V = np.linalg.eigh(M)
        L = V * np.sqrt(np.maximum(w, np.finfo(float).eps * w[-1]))  # L L^T = M, floored
    rates = [0.0]
    for d, root in ((damping, False), (stiffness, True)):
        if (d > 0).any():
            Li = np.linalg.solve(L, np.diag(d))
            top = float(np.max(np.linalg.eigvalsh(np.linalg.solve(L, Li.T).T)))
            rates.append(math.sqrt(max(top, 0.0)) if root else top)
    return max(rates)


def _any(x: np.ndarray) -> bool:
    """Whether some entry of ``x`` is nonzero (True, or NaN): ``x.any()``, cheaper on a few entries
    (numpy's own ``count_nonzero`` without its Python wrapper, which only passes an array on)."""
    return _count_nonzero(x) != 0


def _finite(x: np.ndarray) -> bool:
    """``np.isfinite(x).all()``, without the method's wrapper (a few times a step)."""
    return _count_nonzero(np.isfinite(x)) == x.size


def _largest(x: np.ndarray) -> np.floating:
    """``np.max(x)``: the same reduction over every entry (NaN propagating), without its wrapper."""
    return np.maximum.reduce(x, axis=None)
