"""Numeric evaluation of one design: contact selection, the compiled model (cached per
topology), redundant contacts, and a typed result."""

from __future__ import annotations

import functools
from dataclasses import dataclass

import casadi as ca
import numpy as np

from impulse_core.errors import ModelError, NumericalError
from impulse_core.impact import geometry_function, impact_function, response_function
from impulse_core.kinematics import PLANAR, DofKind, Space, dof_layout
from impulse_core.nnls import least_distance
from impulse_core.tree import ContactSelection, Scene, Topology, Tree, design_vector

#: A relative Delassus pivot below this sends the evaluation to the rank check.
PIVOT_TOL = 1e-9
#: Singular values of the column-normalised contact Jacobian below this (relative) are zero.
RANK_TOL = 1e-9

MODEL_NAME = "newton-simultaneous (paper eq. 11)"


@dataclass(frozen=True)
class CompiledModel:
    """The CasADi functions of one topology (see :mod:`impulse_core.impact`)."""

    topology: Topology
    space: Space
    impact: ca.Function
    response: ca.Function


@functools.lru_cache(maxsize=256)
def compiled_model(topology: Topology, space: Space = PLANAR) -> CompiledModel:
    """Build (once per topology) the impact and response functions."""
    return CompiledModel(topology, space, impact_function(topology, space), response_function(topology, space))


@functools.lru_cache(maxsize=256)
def compiled_geometry(topology: Topology, space: Space = PLANAR) -> ca.Function:
    """Touchdown geometry of a topology (independent of which contacts are active)."""
    return geometry_function(topology.with_active(()), space)


@dataclass(frozen=True)
class Geometry:
    """World positions at touchdown (n x 2 in the plane; the ground is ``ground_height``)."""

    origins: np.ndarray
    tips: np.ndarray
    coms: np.ndarray
    contacts: np.ndarray
    ground_height: float


def touchdown_geometry(tree: Tree, space: Space = PLANAR) -> Geometry:
    """Where every body, centre of mass and contact point is at touchdown."""
    out = compiled_geometry(tree.topology(), space)(p=design_vector(tree))
    pts = {k: np.array(out[k]).T[:, :2] for k in ("origins", "tips", "coms", "contacts")}
    return Geometry(**pts, ground_height=float(pts["contacts"][:, 1].min()))


def active_contacts(tree: Tree, scene: Scene, geometry: Geometry | None = None) -> tuple[int, ...]:
    """Indices of the declared contacts that hit: all of them, or those within
    ``scene.contact_tolerance`` of the lowest one."""
    n = len(tree.contacts)
    if scene.selection is ContactSelection.ALL:
        return tuple(range(n))
    geometry = geometry or touchdown_geometry(tree)
    heights = geometry.contacts[:, 1]
    return tuple(int(i) for i in np.flatnonzero(heights <= heights.min() + scene.contact_tolerance))


def approach_velocity(topology: Topology, speed: float, space: Space = PLANAR) -> np.ndarray:
    """Generalized velocity of the whole tree translating straight down (-y) at ``speed``."""
    v = np.zeros(dof_layout(topology, space).nv)
    for k, (kind, axis) in enumerate(space.base_dofs):
        if kind is DofKind.TRANSLATION:
            v[k] = -speed * axis[1]
    return v


@dataclass(frozen=True)
class ImpactResult:
    """The outcome of one impact. Vectors are in the world frame; N s, m/s, J.

    Attributes:
        external: normal impulse at each declared contact (0 for contacts that do not hit).
        active: indices of the declared contacts that hit.
        internal: force impulse through each joint, parent onto child (n_joints x 3).
        internal_torque: torque impulse about each joint (n_joints x 3); its joint-axis part
            is zero at revolute joints.
        internal_magnitude: |internal| per joint (one per non-base body, file order).
        external_norm, internal_norm: Euclidean norms of ``external`` and ``internal_magnitude``.
        v_minus, v_plus: generalized velocities before and after (base vx, vy, omega, joints).
        energy_before, energy_after: kinetic energy.
        contact_velocity: normal velocity of each active contact after impact.
        split_unique: False when the active contacts are redundant (the Delassus matrix is
            singular): the post-impact velocity is unique, the split of the impulse is not, and
            ``external`` is the smallest-norm non-negative split that meets the restitution law.
        pulling: active contacts (declared indices) with a negative impulse: Newton's law asks
            them to pull on the ground.
        model: which impact model ran.
    """

    external: np.ndarray
    active: tuple[int, ...]
    internal: np.ndarray
    internal_torque: np.ndarray
    internal_magnitude: np.ndarray
    external_norm: float
    internal_norm: float
    v_minus: np.ndarray
    v_plus: np.ndarray
    energy_before: float
    energy_after: float
    contact_velocity: np.ndarray
    split_unique: bool
    pulling: tuple[int, ...]
    model: str

    @property
    def max_internal(self) -> float:
        """The largest joint impulse magnitude (0 for a single body)."""
        return float(self.internal_magnitude.max()) if self.internal_magnitude.size else 0.0


def evaluate(tree: Tree, scene: Scene, space: Space = PLANAR) -> ImpactResult:
    """External and internal impulses of ``tree`` landing as ``scene`` says.

    Raises:
        NumericalError: when float64 cannot resolve the impact (non-finite results).
        ModelError: for a scene the core does not model (friction) or an impulse split that
            no non-negative, restitution-meeting choice can make.
    """
    if scene.friction > 0:
        raise ModelError("scene.friction: the impulse core models frictionless contact only (friction: 0)")
    active = active_contacts(tree, scene)
    topology = tree.topology(active)
    model = compiled_model(topology, space)
    p = design_vector(tree)
    v_minus = approach_velocity(topology, scene.speed, space)
    out = model.impact(p=p, v_minus=v_minus, restitution=scene.restitution)
    lam = np.array(out["external"]).ravel()
    split_unique = True
    if np.min(np.array(out["delassus_pivots"])) < PIVOT_TOL or not np.all(np.isfinite(lam)):
        resp = model.response(p=p, v_minus=v_minus, external=np.zeros(len(active)))
        J = np.array(resp["contact_jacobian"])
        A = np.array(resp["delassus"])
        if not (np.all(np.isfinite(J)) and np.all(np.isfinite(A))):
            raise NumericalError("the Delassus matrix is not finite in float64 (values too extreme)")
        rhs = -(1 + scene.restitution) * (J @ v_minus)
        redundant = _redundant_split(J, A, rhs)
        if redundant is not None:
            lam, split_unique = redundant, False
            out = model.response(p=p, v_minus=v_minus, external=lam)
    if not all(np.all(np.isfinite(np.array(out[k]))) for k in ("v_plus", "internal", "energy_after")):
        raise NumericalError("the impact solve gave non-finite values in float64 (values too extreme)")
    n_declared = len(tree.contacts)
    external = np.zeros(n_declared)
    external[list(active)] = lam
    magnitude = np.array(out["internal_magnitude"]).ravel()
    return ImpactResult(
        external=external,
        active=active,
        internal=np.array(out["internal"]).T.reshape(-1, 3),
        internal_torque=np.array(out["internal_torque"]).T.reshape(-1, 3),
        internal_magnitude=magnitude,
        external_norm=float(np.linalg.norm(lam)),
        internal_norm=float(np.linalg.norm(magnitude)),
        v_minus=v_minus,
        v_plus=np.array(out["v_plus"]).ravel(),
        energy_before=float(out["energy_before"]),
        energy_after=float(out["energy_after"]),
        contact_velocity=np.array(out["contact_velocity"]).ravel(),
        split_unique=split_unique,
        pulling=tuple(active[i] for i in np.flatnonzero(lam < 0)),
        model=f"{MODEL_NAME}, {space.name}",
    )


def _redundant_split(J: np.ndarray, A: np.ndarray, rhs: np.ndarray) -> np.ndarray | None:
    """The smallest-norm non-negative impulse meeting A lambda = rhs when the contact normals
    are dependent (rank J < number of contacts); None when they are independent.

    Rank from the SVD of J with normalised columns (independent of masses). The smallest-norm
    solution lambda_0 lies in range(J); every solution is lambda_0 + N z with N spanning the
    left null space of J, and |lambda_0 + N z|^2 = |lambda_0|^2 + |z|^2, so the smallest
    non-negative one is a least-distance program: min |z| s.t. N z >= -lambda_0. If no
    non-negative split exists, the smallest-norm split (with pulling contacts) is returned.
    """
    scale = np.linalg.norm(J, axis=0)
    scale[scale == 0] = 1.0
    U, s, _ = np.linalg.svd(J / scale, full_matrices=True)
    rank = int(np.sum(s > RANK_TOL * s.max())) if s.size else 0
    if rank == J.shape[0]:
        return None
    Ur, N = U[:, :rank], U[:, rank:]
    lam0 = Ur @ np.linalg.solve(Ur.T @ A @ Ur, Ur.T @ rhs)
    if np.all(lam0 >= 0):
        return lam0
    z = least_distance(N, -lam0)
    return lam0 if z is None else np.maximum(lam0 + N @ z, 0.0)


__all__ = [
    "CompiledModel",
    "Geometry",
    "ImpactResult",
    "active_contacts",
    "approach_velocity",
    "compiled_model",
    "evaluate",
    "touchdown_geometry",
]
