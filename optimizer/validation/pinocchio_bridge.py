"""The same tree built in Pinocchio (an independent rigid-body implementation), for the agreement
tests and as the benchmark's peer. Needs `pin` (a test dependency)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from impulse_core.model.rods import (
    body_rotation,
    centre_of_mass,
    contact_point,
    depth_first,
    inertia_tensor,
    joint_origin,
    rotation_axis,
    rotation_rpy,
    rotation_z,
    unit_axis,
)
from impulse_core.model.tree import JointKind, Tree


@dataclass(frozen=True)
class PinocchioTree:
    model: pin.Model
    q: np.ndarray
    contact_frames: tuple[int, ...]
    T: np.ndarray  # v_ours = T v_pinocchio

    def to_pin_velocity(self, v: np.ndarray) -> np.ndarray:
        return np.linalg.solve(self.T, v)

    def from_pin_velocity(self, v: np.ndarray) -> np.ndarray:
        return self.T @ v

    def normal_jacobian(self, active: tuple[int, ...]) -> np.ndarray:
        data = self.model.createData()
        pin.computeJointJacobians(self.model, data, self.q)
        pin.updateFramePlacements(self.model, data)
        rows = []
        for c in active:
            J = pin.getFrameJacobian(self.model, data, self.contact_frames[c], pin.LOCAL_WORLD_ALIGNED)
            rows.append(J[1])
        return np.array(rows).reshape(len(active), self.model.nv)

    def mass_matrix(self) -> np.ndarray:
        return crba_mass_matrix(self.model, self.model.createData(), self.q)

    def mass_matrix_ours(self) -> np.ndarray:
        """Pinocchio's mass matrix in our coordinates: M_ours = T^-T M_pin T^-1."""
        Ti = np.linalg.inv(self.T)
        return Ti.T @ self.mass_matrix() @ Ti

    def impulse(self, v_minus: np.ndarray, restitution: float, active: tuple[int, ...]):
        """(v_plus in our convention, normal impulses) from pinocchio.impulseDynamics."""
        data = self.model.createData()
        J = self.normal_jacobian(active)
        v_pin = pin.impulseDynamics(self.model, data, self.q, self.to_pin_velocity(v_minus), J, restitution, 0.0)
        return self.from_pin_velocity(np.array(v_pin)), np.array(data.impulse_c).copy()


def crba_mass_matrix(model: pin.Model, data: pin.Data, q: np.ndarray) -> np.ndarray:
    """The mass matrix at q by ``pinocchio.crba`` (which fills its upper triangle only), symmetric."""
    M = pin.crba(model, data, q)
    return np.triu(M) + np.triu(M, 1).T


def _bodies(tree: Tree, base_joint: pin.JointModel) -> tuple[pin.Model, list[int], dict[int, float], tuple[int, ...]]:
    """The rods as Pinocchio bodies on ``base_joint``: each revolute joint about its axis (RZ in
    the plane), placed at ``at`` on its parent and turned by its ``rpy``; fixed joints welded.
    Returns the model, each body's joint, each revolute body's touchdown angle, the contact frames."""
    model = pin.Model()
    n = tree.n_bodies
    joint_of: list[int] = [0] * n
    placement_in_joint: list[pin.SE3] = [pin.SE3.Identity()] * n
    q_of: dict[int, float] = {}
    for i in depth_first(tree):
        b = tree.bodies[i]
        if b.parent is None:
            joint_of[i] = model.addJoint(0, base_joint, pin.SE3.Identity(), "base")
        else:
            offset = placement_in_joint[b.parent] * pin.SE3(rotation_rpy(b.rpy), joint_origin(tree, i))
            if b.joint is JointKind.REVOLUTE:
                joint = pin.JointModelRZ() if b.axis == (0.0, 0.0, 1.0) else pin.JointModelRevoluteUnaligned(*unit_axis(b))
                joint_of[i] = model.addJoint(joint_of[b.parent], joint, offset, b.name)
                q_of[i] = b.angle
            else:
                joint_of[i] = joint_of[b.parent]
                turn = rotation_z(b.angle) if b.axis == (0.0, 0.0, 1.0) else rotation_axis(unit_axis(b), b.angle)
                placement_in_joint[i] = offset * pin.SE3(turn, np.zeros(3))
        inertia = pin.Inertia(b.mass, centre_of_mass(b), inertia_tensor(b))
        model.appendBodyToJoint(joint_of[i], inertia, placement_in_joint[i])
    frames = []
    for i, b in enumerate(tree.bodies):
        for k in range(len(b.contacts)):
            placement = placement_in_joint[i] * pin.SE3(np.eye(3), contact_point(b, k))
            frame = pin.Frame(f"{b.name}_c{k}", joint_of[i], 0, placement, pin.FrameType.OP_FRAME)
            frames.append(model.addFrame(frame, False))
    return model, joint_of, q_of, tuple(frames)


def _tree(tree: Tree, model, joint_of, q_of, frames, q_base: np.ndarray, T_base: np.ndarray) -> PinocchioTree:
    """The PinocchioTree: the base's configuration ``q_base`` and velocity map ``T_base`` (ours =
    T Pinocchio's), then one DOF per revolute body in file order."""
    n_base = T_base.shape[0]
    q = np.zeros(model.nq)
    q[: q_base.size] = q_base
    T = np.eye(model.nv)
    T[:n_base, :n_base] = T_base
    P = np.zeros((model.nv, model.nv))
    P[:n_base, :n_base] = np.eye(n_base)
    revolute = [i for i in range(1, tree.n_bodies) if tree.bodies[i].joint is JointKind.REVOLUTE]
    for k, i in enumerate(revolute):
        jm = model.joints[joint_of[i]]
        q[jm.idx_q] = q_of[i]
        P[n_base + k, jm.idx_v] = 1.0
    return PinocchioTree(model, q, frames, P @ T)


def build(tree: Tree) -> PinocchioTree:
    """Rods as Pinocchio bodies: a planar base joint, revolute-z joints, fixed joints welded."""
    model, joint_of, q_of, frames = _bodies(tree, pin.JointModelPlanar())
    angle = tree.bodies[0].angle
    q_base = np.array([0.0, 0.0, np.cos(angle), np.sin(angle)])
    return _tree(tree, model, joint_of, q_of, frames, q_base, velocity_map(angle, 3))


def velocity_map(base_angle: float, nv: int) -> np.ndarray:
    """T with v_ours = T v_pinocchio (the base's linear velocity rotated to the world frame)."""
    T = np.eye(nv)
    c, s = np.cos(base_angle), np.sin(base_angle)
    T[:2, :2] = [[c, -s], [s, c]]
    return T


def build_spatial(tree: Tree) -> PinocchioTree:
    """A spatial tree (MODEL_FORMAT "Spatial models") in Pinocchio: a free-flyer base, each
    revolute joint a ``JointModelRevoluteUnaligned`` about its axis. Our base velocity is the base
    origin's velocity and the angular velocity in the world frame, Pinocchio's in the base frame."""
    model, joint_of, q_of, frames = _bodies(tree, pin.JointModelFreeFlyer())
    R0 = body_rotation(tree.bodies[0])
    q_base = np.concatenate([np.zeros(3), pin.Quaternion(R0).coeffs()])  # x, y, z, w
    return _tree(tree, model, joint_of, q_of, frames, q_base, spatial_velocity_map(R0, 6))


def spatial_velocity_map(R: np.ndarray, nv: int) -> np.ndarray:
    """T with v_ours = T v_pinocchio for a free-flyer base turned by R (world from base):
    blockdiag(R, R, I), the base origin's velocity and the angular velocity to the world frame."""
    T = np.eye(nv)
    T[:3, :3] = T[3:6, 3:6] = R
    return T


def joint_force_impulses(tree: PinocchioTree, v_minus: np.ndarray, v_plus: np.ndarray, active: tuple[int, ...],
                         impulses: np.ndarray) -> dict[str, float]:
    """|force part| of the impulse each Pinocchio joint transmits (its subtree's momentum change
    minus the contact impulses on it, by ``pinocchio.rnea`` with a = v+ - v-, v = 0, no gravity),
    by joint (= body) name. Contact impulses are along world +y."""
    model = tree.model
    data = model.createData()
    pin.framesForwardKinematics(model, data, tree.q)
    fext = [pin.Force.Zero() for _ in range(model.njoints)]
    for c, lam in zip(active, impulses):
        frame = model.frames[tree.contact_frames[c]]
        oMj = data.oMi[frame.parentJoint]
        f_local = oMj.rotation.T @ np.array([0.0, lam, 0.0])
        p_local = frame.placement.translation
        fext[frame.parentJoint] += pin.Force(f_local, np.cross(p_local, f_local))
    gravity = model.gravity.linear.copy()
    model.gravity.linear[:] = 0.0
    dv = tree.to_pin_velocity(v_plus - v_minus)
    pin.rnea(model, data, tree.q, np.zeros(model.nv), dv, fext)
    model.gravity.linear[:] = gravity
    return {model.names[j]: float(np.linalg.norm(data.f[j].linear)) for j in range(2, model.njoints)}
