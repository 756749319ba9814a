"""Each rod's placement on its parent, centre of mass, inertia tensor and contact points, as numpy.

These are the body-frame rules of ``MODEL_FORMAT.md`` for every description built from a tree
outside the core: the URDF and MJCF exports (``optimizer.results.export``) and the Pinocchio and
MuJoCo bridges (``optimizer.validation``). The kinematic core (``impulse_core.kinematics.spatial``)
builds the same placements symbolically.

Body frame: origin at the rod's joint, x along the rod (tip at x = length), z the planar joint
axis. Every vector below is in the frame named in its docstring (m, kg, kg m^2).
"""

from __future__ import annotations

import math

import numpy as np

from impulse_core.model.tree import Body, Tree, tensor_matrix


def children(tree: Tree) -> tuple[tuple[int, ...], ...]:
    """The children of every body, in file order."""
    out: list[list[int]] = [[] for _ in tree.bodies]
    for i, b in enumerate(tree.bodies):
        if b.parent is not None:
            out[b.parent].append(i)
    return tuple(tuple(c) for c in out)


def depth_first(tree: Tree) -> tuple[int, ...]:
    """The bodies in depth-first order from the base, children in file order: each subtree is
    contiguous (what Pinocchio needs of its joints, and the nesting of MJCF bodies)."""
    kids = children(tree)
    order: list[int] = []
    stack = [0]
    while stack:
        i = stack.pop()
        order.append(i)
        stack.extend(reversed(kids[i]))
    return tuple(order)


def joint_origin(tree: Tree, i: int) -> np.ndarray:
    """Where body ``i``'s joint sits on its parent, in the parent's frame: ``at`` x its length
    along the parent's x axis. The child frame is there, turned by the body's ``angle`` about z."""
    b = tree.bodies[i]
    if b.parent is None:
        raise ValueError(f"{b.name} is the floating base: it has no parent")
    return np.array([b.at * tree.bodies[b.parent].length, 0.0, 0.0])


def rotation_z(angle: float) -> np.ndarray:
    """The rotation by ``angle`` (rad) about z: the parent-from-child rotation of a planar joint."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rotation_rpy(rpy: tuple[float, float, float]) -> np.ndarray:
    """Rz(yaw) Ry(pitch) Rx(roll), as URDF's ``rpy``."""
    a, b, c = rpy
    ca_, sa, cb, sb, cc, sc = math.cos(a), math.sin(a), math.cos(b), math.sin(b), math.cos(c), math.sin(c)
    Rx = np.array([[1.0, 0.0, 0.0], [0.0, ca_, -sa], [0.0, sa, ca_]])
    Ry = np.array([[cb, 0.0, sb], [0.0, 1.0, 0.0], [-sb, 0.0, cb]])
    Rz = np.array([[cc, -sc, 0.0], [sc, cc, 0.0], [0.0, 0.0, 1.0]])
    return Rz @ Ry @ Rx


def rpy_of(R: np.ndarray) -> tuple[float, float, float]:
    """URDF's (roll, pitch, yaw) of a rotation: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    pitch = math.atan2(-R[2, 0], math.hypot(R[0, 0], R[1, 0]))
    if math.hypot(R[0, 0], R[1, 0]) < 1e-12:  # gimbal lock: yaw 0, roll takes the rest
        return math.atan2(-R[1, 2], R[1, 1]), pitch, 0.0
    return math.atan2(R[2, 1], R[2, 2]), pitch, math.atan2(R[1, 0], R[0, 0])


def unit_axis(body: Body) -> np.ndarray:
    """The body's joint axis made unit length (the frame after ``rpy``)."""
    k = np.array(body.axis, dtype=float)
    return k / np.linalg.norm(k)


def rotation_axis(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation by ``angle`` about the unit vector ``axis`` (Rodrigues)."""
    K = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * (K @ K)


def body_rotation(body: Body) -> np.ndarray:
    """The body frame in its parent's frame at the joint (the base: in the world), at touchdown:
    R(rpy) R(axis, angle); in the plane the rotation by ``angle`` about z."""
    return rotation_rpy(body.rpy) @ rotation_axis(unit_axis(body), body.angle)


def centre_of_mass(body: Body) -> np.ndarray:
    """The centre of mass in the body frame: ``com`` x length along x, ``com_offset`` along y, z."""
    return np.array([body.com * body.length, body.com_offset[0], body.com_offset[1]])


def contact_point(body: Body, k: int) -> np.ndarray:
    """Contact ``k`` of the body (index in its ``contacts``), in the body frame."""
    return np.array([body.contacts[k] * body.length, 0.0, 0.0])


def inertia_tensor(body: Body, floor: float = 0.0) -> np.ndarray:
    """The inertia tensor about the centre of mass, in the body frame (kg m^2): ``axial_inertia``
    (m r^2 / 2; 0 for a slender planar rod) about its own axis (x) and ``body.inertia`` across it
    (y and z), plus the body's added ``tensor`` (spatial). ``floor`` raises each principal moment
    to at least that value (for formats and engines that need it positive; a rod's diagonal entry
    by entry, a general tensor in its principal axes)."""
    across = body.inertia
    if body.is_rod:
        return np.diag([max(body.axial_inertia, floor), max(across, floor), max(across, floor)])
    I = np.diag([body.axial_inertia, across, across]) + tensor_matrix(body.tensor)
    if floor > 0.0:
        moments, axes = np.linalg.eigh(I)
        if moments.min() < floor:
            I = axes @ np.diag(np.maximum(moments, floor)) @ axes.T
            I = 0.5 * (I + I.T)
    return I


__all__ = [
    "body_rotation",
    "rotation_axis",
    "rotation_rpy",
    "rpy_of",
    "unit_axis",
    "centre_of_mass", "children", "contact_point", "depth_first", "inertia_tensor", "joint_origin", "rotation_z"]
