"""Forward kinematics and Jacobians of a floating tree, in spatial (3D) form.

One kinematic core: every quantity is a 3-vector or 3x3 rotation in the world frame. The planar
model is the restriction ``PLANAR`` (base: translations along x and y, rotation about z; joints
about z); a 3D model is another :class:`Space`, not another copy of this code.

Frame names follow ``W_p_C`` (position of C in the world frame W) and ``W_R_B`` (rotation from
body B to W).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import casadi as ca

from impulse_core.model.tree import (
    BODY_VALUES,
    PLANAR_OFFSET_VALUES,
    SPATIAL_BODY_VALUES,
    TENSOR_VALUES,
    JointKind,
    Topology,
    Tree,
)


class DofKind(Enum):
    TRANSLATION = "translation"
    ROTATION = "rotation"


@dataclass(frozen=True)
class Space:
    """Which motions the model has: the floating base's DOFs and the revolute joints' axis.

    Attributes:
        base_dofs: the base's generalized velocities, as (kind, world axis); a rotation is about
            the base's origin.
        joint_axis: the axis of every revolute joint, in the child's frame, when all share it
            (the plane); None when each body carries its own ``rpy`` and ``axis`` (space).
        body_values: each body's entries in the design vector (``tree.design_vector``).
    """

    name: str
    base_dofs: tuple[tuple[DofKind, tuple[float, float, float]], ...]
    joint_axis: tuple[float, float, float] | None
    body_values: tuple[str, ...] = BODY_VALUES

    def __reduce_ex__(self, protocol):
        """The module's spaces pickle by name, so that ``space is SPATIAL`` (how the code asks)
        still holds in a forked worker that unpickles its study (:mod:`optimizer.workers`)."""
        for name in NAMED_SPACES:
            if globals().get(name) is self:
                return name
        return super().__reduce_ex__(protocol)


#: The planar restriction: x forward, y up, rotations about z.
PLANAR = Space(
    name="planar",
    base_dofs=(
        (DofKind.TRANSLATION, (1.0, 0.0, 0.0)),
        (DofKind.TRANSLATION, (0.0, 1.0, 0.0)),
        (DofKind.ROTATION, (0.0, 0.0, 1.0)),
    ),
    joint_axis=(0.0, 0.0, 1.0),
)

#: The plane with centres of mass off the rods (``com_offset`` [dy, 0]): PLANAR's motions, each
#: body's offset along its frame's y one more value (the spatial offset machinery, z fixed at 0).
#: :func:`values_space` picks it for a planar tree that needs it; rods keep PLANAR's functions.
PLANAR_OFFSET = Space(
    name="planar", base_dofs=PLANAR.base_dofs, joint_axis=PLANAR.joint_axis, body_values=PLANAR_OFFSET_VALUES
)


def values_space(tree: Tree, space: Space) -> Space:
    """The space whose values carry ``tree``: PLANAR_OFFSET for a planar tree with a centre of mass
    off a rod, else ``space``."""
    if space is PLANAR and any(b.com_offset[0] != 0.0 for b in tree.bodies):
        return PLANAR_OFFSET
    return space


#: Space (MODEL_FORMAT "Spatial models"): the base free in six directions (its origin's
#: velocity, then its angular velocity, world frame); each joint about its own axis.
SPATIAL = Space(
    name="spatial",
    base_dofs=tuple((DofKind.TRANSLATION, e) for e in ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)))
    + tuple((DofKind.ROTATION, e) for e in ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))),
    joint_axis=None,
    body_values=SPATIAL_BODY_VALUES,
)

#: The module's spaces, which pickle by name (:meth:`Space.__reduce_ex__`).
NAMED_SPACES = ("PLANAR", "PLANAR_OFFSET", "SPATIAL")

#: A spatial rod's inertia about its own axis is at least mass * (AXIAL_GYRATION_FLOOR *
#: length)^2 (MODEL_FORMAT: at radius 0 a straight chain has none, and the mass matrix would be
#: singular along a motion that moves no mass and no contact). The floor changes the impulses by
#: about floor^2 relative where that inertia matters (measured against Pinocchio without it on
#: spatial trees with mass ratios to 1e6: 3e-12 at 1e-7, 3e-10 at 1e-6); the mass matrix's pivot
#: along the null motion stays 1e-14 of the rod's, well above rounding.
AXIAL_GYRATION_FLOOR = 1e-7


def n_values(topology: Topology, space: Space = PLANAR) -> int:
    """Length of the design vector of ``topology`` in ``space``."""
    return len(space.body_values) * topology.n_bodies + sum(topology.n_contacts)


#: A body's general mass-property values (``com_offset`` and ``inertia_tensor``), all zero for a rod.
MASS_VALUES = ("com_y", "com_z") + TENSOR_VALUES


def mass_columns(topology: Topology, space: Space) -> tuple[int, ...]:
    """Where every body's ``MASS_VALUES`` sit in the design vector of ``space`` (none in PLANAR)."""
    n = len(space.body_values)
    at = [j for j, name in enumerate(space.body_values) if name in MASS_VALUES]
    return tuple(n * b + j for b in range(topology.n_bodies) for j in at)


def rods_only(tree: Tree, space: Space) -> bool:
    """Whether ``space`` carries mass-property values and every body of ``tree`` has them all
    zero: the rods variant of the hot path (``rods=True``, those values folded to 0) serves it."""
    return bool(mass_columns(tree.topology(), space)) and all(b.is_rod for b in tree.bodies)

#: A rod's own axis, in its frame.
E_X = ca.DM([1.0, 0.0, 0.0])

#: Ground normal (world frame): the ground is horizontal, y is up.
GROUND_NORMAL = ca.DM([0.0, 1.0, 0.0])


@dataclass(frozen=True)
class BodyValues:
    """The symbolic values of one body (see ``Space.body_values``) and its contact fractions;
    in the plane ``rpy``, ``axis``, ``radius``, ``com_offset`` and ``tensor`` are the constants of
    a planar body (a rod: no offset, no tensor added)."""

    length: ca.SX
    mass: ca.SX
    angle: ca.SX
    at: ca.SX
    com: ca.SX
    gyration: ca.SX
    contacts: tuple[ca.SX, ...]
    rpy: tuple[ca.SX | float, ...] = (0.0, 0.0, 0.0)
    axis: tuple[ca.SX | float, ...] = (0.0, 0.0, 1.0)
    radius: ca.SX | float = 0.0
    com_offset: tuple[ca.SX | float, ...] = (0.0, 0.0)
    tensor: tuple[ca.SX | float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)

    @property
    def is_rod(self) -> bool:
        """True when the offset and the added tensor are the constant zeros (the plane)."""
        return all(isinstance(x, float) and x == 0.0 for x in self.com_offset + self.tensor)

    @property
    def inertia(self) -> ca.SX:
        """Moment of inertia about the centre of mass, across the rod (kg m^2)."""
        return self.mass * (self.gyration * self.length) ** 2

    @property
    def axial_inertia(self) -> ca.SX | float:
        """Moment of inertia about the rod's own axis: m r^2 / 2, floored (``AXIAL_GYRATION_FLOOR``)
        in space; 0 in the plane, where no DOF turns a rod about its axis."""
        if isinstance(self.radius, float) and self.radius == 0.0:
            return 0.0
        return self.mass * (0.5 * self.radius**2 + (AXIAL_GYRATION_FLOOR * self.length) ** 2)


def unpack_values(topology: Topology, p: ca.SX, space: Space = PLANAR) -> tuple[BodyValues, ...]:
    """Split the flat design vector ``p`` (layout: ``tree.design_vector``) per body."""
    n = len(space.body_values)
    offset = n * topology.n_bodies
    out = []
    for i, nc in enumerate(topology.n_contacts):
        vals = {name: p[n * i + j] for j, name in enumerate(space.body_values)}
        contacts = tuple(p[offset + k] for k in range(nc))
        offset += nc
        spatial = {}
        if space.joint_axis is None:
            spatial = {
                "rpy": tuple(vals.pop(k) for k in ("roll", "pitch", "yaw")),
                "axis": tuple(vals.pop(k) for k in ("axis_x", "axis_y", "axis_z")),
                "radius": vals.pop("radius"),
            }
            if "com_y" in vals:
                spatial["com_offset"] = (vals.pop("com_y"), vals.pop("com_z"))
                spatial["tensor"] = tuple(vals.pop(k) for k in TENSOR_VALUES)
        elif "com_y" in vals:  # the plane with offsets: along y only
            spatial = {"com_offset": (vals.pop("com_y"), 0.0)}
        out.append(BodyValues(contacts=contacts, **vals, **spatial))
    return tuple(out)


@dataclass(frozen=True)
class DofLayout:
    """Where each generalized velocity sits.

    Attributes:
        nv: number of generalized velocities (base DOFs first, then one per revolute joint).
        body_dof: the DOF index of each body's joint (None for the base and for fixed joints).
        dof_parent: the expanded parent array (Featherstone, RBDA 6.5): the DOF each DOF
            moves with, -1 for the first; M[i, j] != 0 only if one is an ancestor of the other.
        body_support: for each body, the DOFs that move it (its ancestors' and its own).
    """

    nv: int
    body_dof: tuple[int | None, ...]
    dof_parent: tuple[int, ...]
    body_support: tuple[tuple[int, ...], ...]
    dof_body: tuple[int, ...]


def dof_layout(topology: Topology, space: Space = PLANAR) -> DofLayout:
    """Number the generalized velocities of a tree."""
    n_base = len(space.base_dofs)
    dof_parent = list(range(-1, n_base - 1))
    dof_body = [0] * n_base
    body_dof: list[int | None] = [None]
    last_dof = [n_base - 1]  # the last DOF that moves each body
    support: list[tuple[int, ...]] = [tuple(range(n_base))]
    for i in range(1, topology.n_bodies):
        parent = topology.parents[i]
        if topology.joints[i] is JointKind.REVOLUTE:
            k = len(dof_parent)
            dof_parent.append(last_dof[parent])
            dof_body.append(i)
            body_dof.append(k)
            last_dof.append(k)
            support.append(support[parent] + (k,))
        else:
            body_dof.append(None)
            last_dof.append(last_dof[parent])
            support.append(support[parent])
    return DofLayout(len(dof_parent), tuple(body_dof), tuple(dof_parent), tuple(support), tuple(dof_body))


def axis_rotation(axis: tuple[float, float, float], angle: ca.SX) -> ca.SX:
    """Rotation by ``angle`` about the unit ``axis`` (Rodrigues' formula in the form
    k k^T + c (I - k k^T) + s [k]x: about a coordinate axis the entries are bare constants, cos
    and sin, one sin and one cos per call)."""
    k = ca.DM(axis)
    kk = k @ k.T
    return kk + ca.cos(angle) * (ca.DM.eye(3) - kk) + ca.sin(angle) * ca.skew(k)


@dataclass(frozen=True)
class Kinematics:
    """World-frame placement of every body at touchdown.

    Attributes:
        W_R_B: rotation of each body frame.
        W_p_O: each body's origin (its joint).
        W_p_G: each body's centre of mass.
        W_p_T: each body's tip.
        W_p_C: every declared contact point, in declaration order.
        joint_axis: each body's joint axis in the world frame (None for the base).
    """

    W_R_B: tuple[ca.SX, ...]
    W_p_O: tuple[ca.SX, ...]
    W_p_G: tuple[ca.SX, ...]
    W_p_T: tuple[ca.SX, ...]
    W_p_C: tuple[ca.SX, ...]
    joint_axis: tuple[ca.SX | None, ...]


def rpy_rotation(rpy: tuple[ca.SX | float, ...]) -> ca.SX:
    """Rz(yaw) Ry(pitch) Rx(roll), as URDF's ``rpy``."""
    a, b, c = rpy
    return axis_rotation((0.0, 0.0, 1.0), c) @ axis_rotation((0.0, 1.0, 0.0), b) @ axis_rotation((1.0, 0.0, 0.0), a)


def unit_axis_rotation(axis: ca.SX, angle: ca.SX) -> ca.SX:
    """Rotation by ``angle`` about the unit vector ``axis`` (a symbolic 3-vector), Rodrigues."""
    kk = axis @ axis.T
    return kk + ca.cos(angle) * (ca.SX.eye(3) - kk) + ca.sin(angle) * ca.skew(axis)


def _spatial_kinematics(topology: Topology, values: tuple[BodyValues, ...]) -> Kinematics:
    """Place every body in space: body frame = parent frame at ``at`` x R(rpy) x R(axis, angle)
    (MODEL_FORMAT "Spatial models"); the base's origin is the world origin."""
    R: list[ca.SX] = []
    O: list[ca.SX] = []
    axes: list[ca.SX | None] = []
    for i, v in enumerate(values):
        k = ca.vertcat(*v.axis)
        k = k / ca.norm_2(k)
        parent = topology.parents[i]
        frame = rpy_rotation(v.rpy)
        if parent < 0:
            O.append(ca.SX.zeros(3, 1))
            axes.append(None)
        else:
            P = values[parent]
            O.append(O[parent] + R[parent] @ (v.at * P.length * E_X))
            frame = R[parent] @ frame
            axes.append(frame @ k)
        R.append(frame @ unit_axis_rotation(k, v.angle))
    return _placed(values, tuple(R), tuple(O), tuple(axes))


def _placed(values: tuple[BodyValues, ...], R: tuple, O: tuple, axes: tuple) -> Kinematics:
    """The kinematics given each body's rotation, joint origin and joint axis."""
    G = [O[i] + _offset(R[i] @ (v.com * v.length * E_X), R[i], v) for i, v in enumerate(values)]
    T = [O[i] + R[i] @ (v.length * E_X) for i, v in enumerate(values)]
    C = [O[i] + R[i] @ (c * v.length * E_X) for i, v in enumerate(values) for c in v.contacts]
    return Kinematics(R, O, tuple(G), tuple(T), tuple(C), axes)


def _offset(r: ca.SX, R: ca.SX, v: BodyValues) -> ca.SX:
    """The rod's centre of mass from its joint ``r`` (world frame) moved by the body's
    ``com_offset`` along its frame's y and z: a term added to the rod's own before the joint's
    position, so that a zero offset leaves every value unchanged, bit for bit (and CasADi still
    simplifies G - O to this vector, as for a rod)."""
    if v.is_rod:
        return r
    dy, dz = v.com_offset
    return r + (R[:, 1] * dy + R[:, 2] * dz)


def forward_kinematics(topology: Topology, values: tuple[BodyValues, ...], space: Space = PLANAR) -> Kinematics:
    """Place every body: a child's joint sits at ``at * length`` along its parent's x axis and
    turns by ``angle`` about ``space.joint_axis``; the base's origin is the world origin.

    In the plane every rotation of the tree (the base's and the joints') is about the same axis,
    so rotations commute and each body's rotation is one :func:`axis_rotation` of its absolute
    angle (the sum of the angles along its chain): trig once per absolute angle, no 3 x 3
    products. In space (``joint_axis`` None) each body carries its own ``rpy`` and ``axis``.
    """
    if space.joint_axis is None:
        return _spatial_kinematics(topology, values)
    R: list[ca.SX] = []
    O: list[ca.SX] = []
    theta: list[ca.SX] = []
    axes: list[ca.SX | None] = []
    for i, v in enumerate(values):
        parent = topology.parents[i]
        if parent < 0:
            theta.append(v.angle)
            O.append(ca.SX.zeros(3, 1))
            axes.append(None)
        else:
            P = values[parent]
            theta.append(theta[parent] + v.angle)
            O.append(O[parent] + R[parent] @ (v.at * P.length * E_X))
            axes.append(ca.SX(ca.DM(space.joint_axis)))  # the common axis is fixed in every frame
        R.append(axis_rotation(space.joint_axis, theta[i]))
    return _placed(values, tuple(R), tuple(O), tuple(axes))


def point_jacobian(
    kin: Kinematics, layout: DofLayout, body: int, W_p: ca.SX, space: Space = PLANAR
) -> tuple[ca.SX, ca.SX]:
    """Jacobians of the linear velocity of a point fixed on ``body`` and of the body's angular
    velocity, both in the world frame: (3 x nv, 3 x nv).

    Column of a revolute DOF with world axis a through o: (a x (p - o), a). Base translation e:
    (e, 0); base rotation e about the base origin: (e x (p - o_base), e).
    """
    Jv = ca.SX.zeros(3, layout.nv)
    Jw = ca.SX.zeros(3, layout.nv)
    n_base = len(space.base_dofs)
    for k in layout.body_support[body]:
        if k < n_base:
            kind, axis = space.base_dofs[k]
            e = ca.DM(axis)
            if kind is DofKind.TRANSLATION:
                Jv[:, k] = e
            else:
                Jv[:, k] = ca.cross(e, W_p - kin.W_p_O[0])
                Jw[:, k] = e
        else:
            j = layout.dof_body[k]
            a = kin.joint_axis[j]
            Jv[:, k] = ca.cross(a, W_p - kin.W_p_O[j])
            Jw[:, k] = a
    return Jv, Jw


def contact_bodies(topology: Topology) -> tuple[int, ...]:
    """The body of every declared contact, in declaration order."""
    return tuple(b for b, _ in topology.declared_contacts)
