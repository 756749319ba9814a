"""Numeric evaluation of one design: contact selection, the compiled models (cached per
topology), the ladder of impact models with an automatic choice of rung, redundant contacts,
and a typed result.

The automatic choice is the cheapest rung that is exact for the scene
(:mod:`impulse_core.impact.laws`): FRICTION when ``scene.friction > 0``; otherwise NEWTON
(paper eq. 11) when every Newton impulse is >= 0 (it is then the complementarity answer), and
LCP when Newton's law would make a contact pull (the contact separates with zero impulse).
DECOUPLED (paper eq. 14) runs on request only. Frictionless scenes build no friction terms.

Every rung here assumes flat ground: the contacts that hit are found by height, and the impulses act
along +y. A scene whose ``terrain`` is not flat is refused (``ModelError`` naming
``scene.terrain``) rather than answered as if the ground were level; its first instant by the lcp
and friction laws (the contacts touching at t = 0 along their local normals) is
:func:`impulse_core.timedomain.first_instant.first_instant`, built on the whole landing's impact, and
its landing is the business of :func:`impulse_core.timedomain.sequential.sequential_impacts` (rigid
impacts in sequence, one per touchdown) or :func:`impulse_core.timedomain.compliant.simulate_impact`. A flat terrain at any height, and
any ``base_x``, change nothing here: heights are measured from the lowest contact. To measure the
flat-ground answer on purpose, evaluate ``dataclasses.replace(scene, terrain=FLAT)``. The same holds for a
spatial scene's ``heightfield`` (``scene.heightfield``): flat at any height is flat ground; otherwise refused.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import casadi as ca
import numpy as np

from impulse_core.errors import ModelError, NumericalError
from impulse_core.impact.coulomb import ContactMode, contact_modes, coulomb_impact
from impulse_core.impact.cone import POLYGON, cone_impact, modes_of
from impulse_core.impact.delassus import (
    friction_response_function,
    geometry_function,
    impact_function,
    metric_function,
    response_function,
)
from impulse_core.impact.laws import (
    PIVOT_TOL,
    ImpactModel,
    complementarity_impulse,
    coulomb_cone,
    coulomb_impulse,
    decoupled_impulse,
    least_norm_law_split,
    least_norm_split,
    redundant,
    row_space_split,
    share_among_twins,
    twin_groups,
)
from impulse_core.impact.mode_derivatives import mode_impulse_function, slip_signs
from impulse_core.impact.nnls import least_distance
from impulse_core.kinematics.spatial import PLANAR, DofKind, Space, dof_layout, values_space
from impulse_core.model.tree import ContactSelection, Scene, Topology, Tree, design_vector

#: A normal impulse below this fraction of the approach momentum counts as zero (separating).
ZERO_IMPULSE = 1e-12
#: The warning of a spatial friction impact whose exact circular-cone law was not met.
POLYHEDRAL_NOTE = (
    f"the exact circular-cone law was not met; the polyhedral answer ({POLYGON}-gon cone) is shown: its friction "
    f"may fall short of the cone's by up to {100 * (1 - np.cos(np.pi / POLYGON)):.1f}% and its slip direction "
    f"by up to {np.degrees(np.pi / POLYGON):.1f} degrees"
)


@dataclass(frozen=True)
class CompiledModel:
    """The CasADi functions of one topology (see :mod:`impulse_core.impact.delassus`)."""

    topology: Topology
    space: Space
    impact: ca.Function
    response: ca.Function


@functools.lru_cache(maxsize=256)
def compiled_model(topology: Topology, space: Space = PLANAR) -> CompiledModel:
    """Build (once per topology) the impact and response functions."""
    return CompiledModel(topology, space, impact_function(topology, space), response_function(topology, space))


@functools.lru_cache(maxsize=256)
def compiled_metric(topology: Topology, space: Space = PLANAR, tangent: bool = False) -> ca.Function:
    """Build (once per topology) the contact problem in the kinetic-energy metric
    (:func:`impulse_core.impact.delassus.metric_function`); tangent rows only with ``tangent``."""
    return metric_function(topology, space, tangent)


@functools.lru_cache(maxsize=256)
def compiled_friction(topology: Topology, space: Space = PLANAR) -> ca.Function:
    """Build (once per topology) the response to normal and tangential impulses; only scenes
    with friction (or an explicit FRICTION request) ever call this."""
    return friction_response_function(topology, space)


@functools.lru_cache(maxsize=256)
def compiled_geometry(topology: Topology, space: Space = PLANAR) -> ca.Function:
    """Touchdown geometry of a topology (independent of which contacts are active)."""
    return geometry_function(topology.with_active(()), space)


@dataclass(frozen=True)
class Geometry:
    """World positions at touchdown (n x 2 in the plane, n x 3 in space; the ground is
    ``ground_height``)."""

    origins: np.ndarray
    tips: np.ndarray
    coms: np.ndarray
    contacts: np.ndarray
    ground_height: float


def touchdown_geometry(tree: Tree, space: Space = PLANAR) -> Geometry:
    """Where every body, centre of mass and contact point is at touchdown."""
    space = values_space(tree, space)
    out = compiled_geometry(tree.topology(), space)(p=design_vector(tree, space.body_values))
    dims = 2 if space.joint_axis is not None else 3
    pts = {k: np.array(out[k]).T[:, :dims] for k in ("origins", "tips", "coms", "contacts")}
    return Geometry(**pts, ground_height=float(pts["contacts"][:, 1].min()))


def active_contacts(
    tree: Tree, scene: Scene, geometry: Geometry | None = None, space: Space = PLANAR
) -> tuple[int, ...]:
    """Indices of the declared contacts that hit: all of them, or those within
    ``scene.contact_tolerance`` of the lowest one."""
    n = len(tree.contacts)
    if scene.selection is ContactSelection.ALL:
        return tuple(range(n))
    geometry = geometry or touchdown_geometry(tree, space)
    heights = geometry.contacts[:, 1]
    return tuple(int(i) for i in np.flatnonzero(heights <= heights.min() + scene.contact_tolerance))


def approach_velocity(topology: Topology, speed: float, space: Space = PLANAR) -> np.ndarray:
    """Generalized velocity of the whole tree translating straight down (-y) at ``speed``."""
    v = np.zeros(dof_layout(topology, space).nv)
    for k, (kind, axis) in enumerate(space.base_dofs):
        if kind is DofKind.TRANSLATION:
            v[k] = -speed * axis[1]
    return v


def pre_impact_velocity(topology: Topology, scene: Scene, space: Space = PLANAR) -> np.ndarray:
    """Generalized velocity of the whole tree moving as one rigid body as ``scene`` says: base
    origin at ``scene.velocity``, every body turning at ``scene.angular_velocity_3d``, joints at
    rest (each base DOF takes the component along its axis)."""
    v = np.zeros(dof_layout(topology, space).nv)
    linear, angular = np.array(scene.velocity), np.array(scene.angular_velocity_3d)
    for k, (kind, axis) in enumerate(space.base_dofs):
        v[k] = np.dot(linear if kind is DofKind.TRANSLATION else angular, axis)
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
        split_unique: False when the active contacts are redundant (their Jacobian rows are
            dependent: the Delassus matrix is singular): the post-impact velocity is unique, the
            split of the impulse is not, and the smallest-norm admissible split is shown.
        pulling: active contacts (declared indices) with a negative impulse: the law that ran
            (NEWTON, DECOUPLED) asks them to pull on the ground.
        model: the rung of the impact-model ladder that ran.
        reason: why that rung ran (automatic choice or request), and what the reader must know.
        tangential: tangential (x) impulse at each declared contact (0 unless FRICTION ran).
        tangent_velocity: tangential velocity of each active contact after impact (FRICTION
            only; None for the frictionless rungs, which build no tangent terms).
        separating: active contacts that leave the ground with zero normal impulse.
        modes: each declared contact's mode with exact friction (FRICTION only, else None):
            separating (also a contact that does not hit), sticking or sliding.
        notes: warnings of the rung that ran (e.g. an approximation it fell back on).

    In space ``tangential`` and ``tangent_velocity`` have two columns (x, z) per contact.
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
    model: ImpactModel
    reason: str
    tangential: np.ndarray
    tangent_velocity: np.ndarray | None
    separating: tuple[int, ...]
    modes: tuple[ContactMode, ...] | None = None
    notes: tuple[str, ...] = ()

    @property
    def max_internal(self) -> float:
        """The largest joint impulse magnitude (0 for a single body)."""
        return float(self.internal_magnitude.max()) if self.internal_magnitude.size else 0.0


@dataclass(frozen=True)
class _Impact:
    """One impact to solve: the compiled structure and the numbers."""

    tree: Tree
    scene: Scene
    topology: Topology
    space: Space
    p: np.ndarray
    v_minus: np.ndarray


@dataclass(frozen=True)
class _Solution:
    """What a rung found: impulses at the active contacts and the response to them."""

    model: ImpactModel
    normal: np.ndarray
    tangential: np.ndarray | None
    split_unique: bool
    out: dict
    modes: tuple[ContactMode, ...] | None = None
    notes: tuple[str, ...] = ()


def evaluate(tree: Tree, scene: Scene, model: ImpactModel | None = None, space: Space = PLANAR) -> ImpactResult:
    """External and internal impulses of ``tree`` landing as ``scene`` says.

    Args:
        tree: the design.
        scene: the landing.
        model: the rung of the impact-model ladder to run (:class:`ImpactModel`); None (default)
            picks the cheapest rung that is exact for the scene (module docstring).
        space: the kinematic space (planar).

    Returns:
        The result, with the rung that ran in ``model`` and why in ``reason``.

    Raises:
        ModelError: the scene's terrain or heightfield is not flat (module docstring).
        NumericalError: when float64 cannot resolve the impact (non-finite results), or eq. 14
            is undefined (a zero row sum of the Delassus matrix).
    """
    if not scene.terrain.is_flat:
        raise ModelError(
            "scene.terrain: the rigid impact models (decoupled, newton, lcp, friction) assume flat ground and this "
            "terrain is not flat; its first instant by the lcp or friction law is "
            "impulse_core.timedomain.first_instant.first_instant, its landing the sequential rigid model (--model "
            "sequential, impulse_core.timedomain.sequential.sequential_impacts) or the compliant one (--model compliant)"
        )
    if scene.heightfield is not None and not scene.heightfield.is_flat:
        raise ModelError(
            "scene.heightfield: the rigid impact models (decoupled, newton, lcp, friction) assume flat ground and "
            "this heightfield is not flat; its first instant by the lcp or friction law is "
            "impulse_core.timedomain.first_instant.first_instant, its landing the sequential rigid model (--model "
            "sequential) or the compliant one (--model compliant)"
        )
    _check_space(tree, scene, model, space)
    space = values_space(tree, space)  # a planar tree with centres of mass off its rods: their offsets too
    active = active_contacts(tree, scene, space=space)
    topology = tree.topology(active)
    v_minus = pre_impact_velocity(topology, scene, space)
    impact = _Impact(tree, scene, topology, space, design_vector(tree, space.body_values), v_minus)
    if model is None:
        solution, reason = _automatic(impact)
    else:
        solution = _RUNGS[model](impact)
        reason = _requested_reason(impact, solution)
    return _result(impact, solution, reason)


def _check_space(tree: Tree, scene: Scene, model: ImpactModel | None, space: Space) -> None:
    """A planar evaluation of a body or an approach out of the plane, or the friction relaxation
    in space, is refused naming the field."""
    if space.joint_axis is not None:
        for i, b in enumerate(tree.bodies):
            if not b.is_planar:
                raise ModelError(f"model.bodies[{i}]: rpy, axis, radius, com_offset out of the plane (dz) and "
                                 "inertia_tensor need 'model.space: spatial'")
        if scene.out_of_plane:
            raise ModelError("scene.velocity: a lateral velocity or a turn about x or y needs 'model.space: spatial'")
        return
    if model is ImpactModel.FRICTION_RELAXED:
        raise ModelError("model: friction-relaxed is planar only; spatial models run the exact law (--model friction)")


def _automatic(c: _Impact) -> tuple[_Solution, str]:
    """The cheapest rung that is exact for the scene, and why it was chosen."""
    mu = c.scene.friction
    if mu > 0:
        how = (
            "by Lemke's method"
            if c.space.joint_axis is not None
            else "on the circular cone: a polyhedral LCP by Lemke's method, then Newton's method on the exact "
            "equations of its contact modes, checked at every contact"
        )
        return _friction(c), (
            f"automatic: scene.friction = {mu:g} > 0, so Coulomb friction acts at the contacts (exact law: "
            f"Newton restitution and Coulomb's law on the impulses, {how})"
        )
    newton = _newton(c)
    pulling = np.flatnonzero(newton.normal < 0)
    if pulling.size == 0:
        return newton, (
            "automatic: frictionless, and every Newton impulse is >= 0, so Newton's law (eq. 11) is "
            "the complementarity (LCP) answer"
        )
    names = _names(c, [c.topology.active[i] for i in pulling])
    return _lcp(c), (
        f"automatic: Newton's law (eq. 11) would make {names} pull on the ground (negative impulse); "
        f"the complementarity law (LCP) lets a contact separate with zero impulse instead"
    )


def _requested_reason(c: _Impact, s: _Solution) -> str:
    notes = ["requested"]
    mu = c.scene.friction
    frictional = s.model in (ImpactModel.FRICTION, ImpactModel.FRICTION_RELAXED)
    if frictional and mu == 0:
        notes.append("scene.friction = 0, so the friction rung gives the LCP answer")
    if not frictional and mu > 0:
        notes.append(f"scene.friction = {mu:g} is ignored by this frictionless rung")
    pulling = np.flatnonzero(s.normal < 0)
    if pulling.size:
        names = _names(c, [c.topology.active[i] for i in pulling])
        notes.append(f"it makes {names} pull on the ground; the complementarity law (LCP) would release them")
    return "; ".join(notes)


def _names(c: _Impact, declared: list[int]) -> str:
    contacts = c.tree.contacts
    names = [f"{c.tree.bodies[contacts[i][0]].name}[{contacts[i][1]}]" for i in declared]
    return ("contact " if len(names) == 1 else "contacts ") + ", ".join(names)


def _newton(c: _Impact) -> _Solution:
    """Paper eq. 11 by the compiled L^T D L solve; redundant contacts by the least-norm split."""
    model = compiled_model(c.topology, c.space)
    out = model.impact(p=c.p, v_minus=c.v_minus, restitution=c.scene.restitution)
    lam = np.array(out["external"]).ravel()
    split_unique = True
    if np.min(np.array(out["delassus_pivots"]), initial=1.0) < PIVOT_TOL or not np.all(np.isfinite(lam)):
        resp = model.response(p=c.p, v_minus=c.v_minus, external=np.zeros(len(c.topology.active)))
        J = np.array(resp["contact_jacobian"])
        A = np.array(resp["delassus"])
        if not (np.all(np.isfinite(J)) and np.all(np.isfinite(A))):
            raise NumericalError("the Delassus matrix is not finite in float64 (values too extreme)")
        rhs = -(1 + c.scene.restitution) * (J @ c.v_minus)
        split = _redundant_split(J, A, rhs)
        if split is not None:
            lam, split_unique = split, False
            out = model.response(p=c.p, v_minus=c.v_minus, external=lam)
    return _Solution(ImpactModel.NEWTON, lam, None, split_unique, out)


def _metric(c: _Impact, tangent: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """J, A, E, u- of :func:`impulse_core.impact.delassus.metric_function`, checked finite."""
    m = compiled_metric(c.topology, c.space, tangent)(p=c.p, v_minus=c.v_minus)
    J, A, E, u = (np.array(m[k]) for k in ("contact_jacobian", "delassus", "metric_factor", "u_minus"))
    if not all(np.all(np.isfinite(x)) for x in (J, A, E, u)):
        raise NumericalError("the Delassus matrix is not finite in float64 (values too extreme)")
    return J, A, E, u.ravel()


def _lcp(c: _Impact) -> _Solution:
    """The frictionless complementarity law by NNLS in the kinetic-energy metric."""
    J, A, E, u = _metric(c)
    lam = complementarity_impulse(E, -(1 + c.scene.restitution) * u)
    split_unique = not redundant(J, A)
    if not split_unique:
        lam = least_norm_split(J, lam)
    out = compiled_model(c.topology, c.space).response(p=c.p, v_minus=c.v_minus, external=lam)
    return _Solution(ImpactModel.LCP, lam, None, split_unique, out)


def _spatial_friction(c: _Impact) -> _Solution:
    """Exact Newton-Coulomb law on the circular cone (:func:`impulse_core.impact.cone.cone_impact`);
    tangential impulses (n, 2) along x and z."""
    n = len(c.topology.active)
    J, A, _, _ = _metric(c, tangent=True)
    law = cone_impact(A, J @ c.v_minus, c.scene.restitution, c.scene.friction)
    split_unique = not redundant(J, A)
    tangential = law.tangential if c.scene.friction > 0 else np.zeros((n, 2))
    u = J @ c.v_minus
    normal, tangential = _shared(J, A, u, c, split_unique, law.normal, tangential)
    out = compiled_friction(c.topology, c.space)(
        p=c.p, v_minus=c.v_minus, external=normal, tangential=tangential.T.ravel()
    )
    after = u + A @ np.concatenate([normal, tangential.T.ravel()])
    scale = max(float(np.max(np.abs(u), initial=0.0)), np.finfo(float).tiny)
    law_modes = law.modes if split_unique else modes_of(normal, None, after, scale)  # the split's
    modes = [ContactMode.SEPARATING] * len(c.tree.contacts)
    for k, i in enumerate(c.topology.active):
        modes[i] = law_modes[k]
    notes = () if law.exact else (POLYHEDRAL_NOTE,)
    return _Solution(ImpactModel.FRICTION, normal, tangential, split_unique, out, tuple(modes), notes)


def _friction(c: _Impact) -> _Solution:
    """Exact Newton-Coulomb impact law (:func:`impulse_core.impact.coulomb.coulomb_impact`)."""
    if c.space.joint_axis is None:
        return _spatial_friction(c)
    n = len(c.topology.active)
    J, A, _, _ = _metric(c, tangent=True)
    law = coulomb_impact(A, J @ c.v_minus, c.scene.restitution, c.scene.friction)
    split_unique = not redundant(J, A) if c.scene.friction > 0 else not redundant(J[:n], A[:n, :n])
    u = J @ c.v_minus
    normal, tangential = _shared(J, A, u, c, split_unique, law.normal, law.tangential)
    out = compiled_friction(c.topology, c.space)(
        p=c.p, v_minus=c.v_minus, external=normal, tangential=tangential
    )
    after = u + A @ np.concatenate([normal, tangential])
    scale = max(float(np.max(np.abs(u), initial=0.0)), np.finfo(float).tiny)
    law_modes = law.modes if split_unique else contact_modes(normal, after, scale)  # the split's
    modes = [ContactMode.SEPARATING] * len(c.tree.contacts)
    for k, i in enumerate(c.topology.active):
        modes[i] = law_modes[k]
    return _Solution(ImpactModel.FRICTION, normal, tangential, split_unique, out, tuple(modes))


def _shared(J: np.ndarray, A: np.ndarray, u: np.ndarray, c: _Impact, split_unique: bool, normal: np.ndarray,
            tangential: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where the split is not unique (rows of J: n normal rows, then each tangent's n rows; A =
    J M^-1 J^T, u = J v_minus), the smallest-norm split the law allows in the answer's modes
    (:func:`impulse_core.impact.laws.least_norm_law_split`, as the landing's impacts); where the
    law's answer does not meet its own modes to the law's tolerance, twin contacts' impulses
    shared equally (:func:`impulse_core.impact.laws.share_among_twins`)."""
    if split_unique:
        return normal, tangential
    n = len(normal)
    split = least_norm_law_split(J, A, u, np.arange(n), normal, tangential.reshape(n, -1), c.scene.restitution,
                                 c.scene.friction, POLYGON)
    if split is not None:
        return split[0], split[1].reshape(tangential.shape)
    rows = J.reshape(-1, n, J.shape[1]).transpose(1, 0, 2).reshape(n, -1)
    return share_among_twins(twin_groups(rows), normal, tangential)


def _friction_relaxed(c: _Impact) -> _Solution:
    """Moreau's impact law with Coulomb friction, convex relaxation, by NNLS on the cone's edges."""
    n = len(c.topology.active)
    mu = c.scene.friction
    J, A, E, u = _metric(c, tangent=True)
    lam_n, lam_t = coulomb_impulse(E[:, :n], E[:, n:], -(1 + c.scene.restitution) * u, mu)
    if mu == 0:  # the cone is the normal ray: only the normal rows can be redundant
        split_unique = not redundant(J[:n], A[:n, :n])
        if not split_unique:
            lam_n = least_norm_split(J[:n], lam_n)
    else:
        split_unique = not redundant(J, A)
        if not split_unique:
            lam = least_norm_split(J, np.concatenate([lam_n, lam_t]), coulomb_cone(mu, n))
            lam_n, lam_t = np.maximum(lam[:n], 0.0), lam[n:]
    out = compiled_friction(c.topology, c.space)(p=c.p, v_minus=c.v_minus, external=lam_n, tangential=lam_t)
    return _Solution(ImpactModel.FRICTION_RELAXED, lam_n, lam_t, split_unique, out)


def _decoupled(c: _Impact) -> _Solution:
    """The paper's decoupled approximation, eq. 14."""
    J, A, _, _ = _metric(c)
    lam = decoupled_impulse(A, -(1 + c.scene.restitution) * (J @ c.v_minus))
    if not np.all(np.isfinite(lam)):
        bad = [c.topology.active[i] for i in np.flatnonzero(~np.isfinite(lam))]
        raise NumericalError(f"paper eq. 14 is undefined: the Delassus row sum of {_names(c, bad)} is zero")
    out = compiled_model(c.topology, c.space).response(p=c.p, v_minus=c.v_minus, external=lam)
    return _Solution(ImpactModel.DECOUPLED, lam, None, not redundant(J, A), out)


_RUNGS: dict[ImpactModel, Callable[[_Impact], _Solution]] = {
    ImpactModel.DECOUPLED: _decoupled,
    ImpactModel.NEWTON: _newton,
    ImpactModel.LCP: _lcp,
    ImpactModel.FRICTION: _friction,
    ImpactModel.FRICTION_RELAXED: _friction_relaxed,
}


def _result(c: _Impact, s: _Solution, reason: str) -> ImpactResult:
    out = s.out
    keys = ("v_plus", "internal", "energy_after") + (("tangent_velocity",) if s.tangential is not None else ())
    if not all(np.all(np.isfinite(np.array(out[k]))) for k in keys):
        raise NumericalError("the impact solve gave non-finite values in float64 (values too extreme)")
    active = c.topology.active
    n_declared = len(c.tree.contacts)
    external = np.zeros(n_declared)
    external[list(active)] = s.normal
    tangential = np.zeros(n_declared if c.space.joint_axis is not None else (n_declared, 2))
    if s.tangential is not None:
        tangential[list(active)] = s.tangential
    magnitude = np.array(out["internal_magnitude"]).ravel()
    momentum = sum(b.mass for b in c.tree.bodies) * c.scene.speed
    return ImpactResult(
        external=external,
        active=active,
        internal=np.array(out["internal"]).T.reshape(-1, 3),
        internal_torque=np.array(out["internal_torque"]).T.reshape(-1, 3),
        internal_magnitude=magnitude,
        external_norm=float(np.linalg.norm(s.normal)),
        internal_norm=float(np.linalg.norm(magnitude)),
        v_minus=c.v_minus,
        v_plus=np.array(out["v_plus"]).ravel(),
        energy_before=float(out["energy_before"]),
        energy_after=float(out["energy_after"]),
        contact_velocity=np.array(out["contact_velocity"]).ravel(),
        split_unique=s.split_unique,
        pulling=tuple(active[i] for i in np.flatnonzero(s.normal < 0)),
        model=s.model,
        reason=reason,
        tangential=tangential,
        tangent_velocity=None if s.tangential is None else _per_contact(np.array(out["tangent_velocity"]), c.space),
        separating=tuple(active[i] for i in np.flatnonzero(np.abs(s.normal) <= ZERO_IMPULSE * momentum)),
        modes=s.modes,
        notes=s.notes,
    )


def _per_contact(rows: np.ndarray, space: Space) -> np.ndarray:
    """Tangent-row values per contact: (n,) in the plane, (n, 2) in space (x rows, then z rows)."""
    rows = rows.ravel()
    return rows if space.joint_axis is not None else rows.reshape(2, -1).T


def _redundant_split(J: np.ndarray, A: np.ndarray, rhs: np.ndarray) -> np.ndarray | None:
    """The smallest-norm non-negative impulse meeting A lambda = rhs when the contact normals
    are dependent (rank J < number of contacts); None when they are independent.

    Rank from the SVD of J with normalised columns (independent of masses). The smallest-norm
    solution lambda_0 lies in range(J); every solution is lambda_0 + N z with N spanning the
    left null space of J, and |lambda_0 + N z|^2 = |lambda_0|^2 + |z|^2, so the smallest
    non-negative one is a least-distance program: min |z| s.t. N z >= -lambda_0. If no
    non-negative split exists, the smallest-norm split (with pulling contacts) is returned.
    """
    Ur, N = row_space_split(J)
    if N.shape[1] == 0:
        return None
    lam0 = Ur @ np.linalg.solve(Ur.T @ A @ Ur, Ur.T @ rhs)
    if np.all(lam0 >= 0):
        return lam0
    z = least_distance(N, -lam0)
    return lam0 if z is None else np.maximum(lam0 + N @ z, 0.0)


__all__ = [
    "CompiledModel",
    "Geometry",
    "POLYHEDRAL_NOTE",
    "ZERO_IMPULSE",
    "ImpactModel",
    "ImpactResult",
    "active_contacts",
    "approach_velocity",
    "compiled_friction",
    "compiled_metric",
    "compiled_model",
    "evaluate",
    "friction_derivatives",
    "pre_impact_velocity",
    "touchdown_geometry",
]


def friction_derivatives(
    tree: Tree, scene: Scene, space: Space = PLANAR
) -> tuple[ImpactResult, np.ndarray, np.ndarray]:
    """The exact-friction impact of ``tree`` and the Jacobians of its normal and tangential
    impulses at the active contacts w.r.t. the design vector (:func:`impulse_core.model.tree.design_vector`),
    exact along the reported contact modes (:mod:`impulse_core.impact.mode_derivatives`).

    Returns:
        (result, d_normal, d_tangential), the Jacobians n_active x n_values.
    """
    result = evaluate(tree, scene, ImpactModel.FRICTION, space)
    space = values_space(tree, space)  # centres of mass off the rods: their layout
    topology = tree.topology(result.active)
    modes = tuple(result.modes[i] for i in result.active)
    f = mode_impulse_function(
        compiled_metric(topology, space, True), len(result.active), modes, slip_signs(result.tangent_velocity)
    )
    out = f(p=design_vector(tree, space.body_values), v_minus=result.v_minus, restitution=scene.restitution,
            mu=scene.friction)
    return result, np.array(out["d_normal"]), np.array(out["d_tangential"])
