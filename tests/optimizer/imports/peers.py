"""Independent references for imported legs: the source description loaded by Pinocchio's own
URDF parser (its own fixed-joint merging), the chain rebuilt from it on a floating base, and the
footopt side read back through the model file. Test peers only (pin, example-robot-data)."""

from __future__ import annotations

import importlib.metadata as md
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from impulse_core.evaluate import evaluate
from impulse_core.kinematics.spatial import PLANAR
from impulse_core.model.rods import body_rotation, unit_axis
from impulse_core.model.tree import Scene, Tree
from optimizer.imports.leg import TO_FOOTOPT, ImportedLeg
from optimizer.validation.pinocchio_bridge import build, build_spatial, crba_mass_matrix


def robot_file(relative: str) -> Path:
    """A file of the example-robot-data wheel (``robots/...``), or skip when it is not installed."""
    try:
        dist = md.distribution("example-robot-data")
    except md.PackageNotFoundError:
        pytest.skip("example-robot-data is not installed (pip install -e '.[test]')")
    for f in dist.files or ():
        if str(f).endswith(relative):
            return Path(dist.locate_file(f))
    pytest.fail(f"example-robot-data has no {relative}")


def package_file(distribution: str, relative: str) -> Path:
    """A file shipped by an installed distribution, or skip when it is not installed."""
    try:
        dist = md.distribution(distribution)
    except md.PackageNotFoundError:
        pytest.skip(f"{distribution} is not installed (pip install -e '.[test]')")
    for f in dist.files or ():
        if str(f).endswith(relative):
            return Path(dist.locate_file(f))
    pytest.fail(f"{distribution} has no {relative}")


@dataclass
class Reference:
    """The chain rebuilt in Pinocchio from the source's own parse, in the root link's frame."""

    model: pin.Model
    q: np.ndarray
    ankle_frame: int
    chain: list[str]  # the chain's joint names, root to ankle
    base_rotation: np.ndarray  # the base joint's frame in the world (planar: its z is the plane's normal)
    full: pin.Model

    def ankle(self) -> np.ndarray:
        data = self.model.createData()
        pin.framesForwardKinematics(self.model, data, self.q)
        return data.oMf[self.ankle_frame].translation.copy()

    def joints(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """(anchor, unit axis) of each chain joint in the world at q."""
        data = self.model.createData()
        pin.forwardKinematics(self.model, data, self.q)
        out = []
        for name in self.chain:
            j = self.model.getJointId(name)
            M = data.oMi[j]
            axis = self.model.joints[j].shortname()[-1].lower()
            local = {"x": np.array([1.0, 0, 0]), "y": np.array([0, 1.0, 0]), "z": np.array([0, 0, 1.0])}.get(axis)
            if local is None:
                local = np.array(self.model.joints[j].extract().axis)
            out.append((M.translation.copy(), M.rotation @ local))
        return out

    def joint_mass_matrix(self) -> np.ndarray:
        """The chain joints' block of the mass matrix (independent of the base's coordinates)."""
        M = crba_mass_matrix(self.model, self.model.createData(), self.q)
        nb = self.model.joints[1].nv
        return M[nb:, nb:]

    def impulse(self, speed: float = 1.0) -> float:
        """pinocchio.impulseDynamics: the normal impulse at the ankle when the whole chain moves
        straight down (-z, the description's up is +z) at ``speed``, restitution 0."""
        data = self.model.createData()
        pin.computeJointJacobians(self.model, data, self.q)
        pin.updateFramePlacements(self.model, data)
        J = pin.getFrameJacobian(self.model, data, self.ankle_frame, pin.LOCAL_WORLD_ALIGNED)[2:3]
        v = np.zeros(self.model.nv)
        nb = self.model.joints[1].nv
        down = self.base_rotation.T @ np.array([0.0, 0.0, -speed])  # in the base joint's frame
        if nb == 3:
            v[:2] = down[:2]
        else:
            v[:3] = down
        pin.impulseDynamics(self.model, data, self.q, v, J, 0.0, 0.0)
        return float(np.array(data.impulse_c)[0])


def reference(urdf: Path, root: str, ankle: str, planar_basis: np.ndarray | None = None) -> Reference:
    """The chain root -> ankle of ``urdf`` as Pinocchio parses it (fixed joints merged by
    Pinocchio), on a free-flyer (or, given the plane's basis rows x, y, z, a planar joint)."""
    full = pin.buildModelFromUrdf(str(urdf), pin.JointModelFreeFlyer())
    data = full.createData()
    pin.framesForwardKinematics(full, data, pin.neutral(full))
    fr, fa = full.getFrameId(root), full.getFrameId(ankle)
    jr, ja = full.frames[fr].parentJoint, full.frames[fa].parentJoint
    chain = []
    j = ja
    while j != jr:
        chain.append(j)
        j = full.parents[j]
        assert j != 0 or jr == 0, "not connected"
    chain.reverse()
    X_r = full.frames[fr].placement  # the root link in its joint's frame
    R = np.eye(3) if planar_basis is None else planar_basis.T
    B = pin.SE3(R, np.zeros(3)).inverse() * X_r.inverse()  # from joint jr's frame to the base joint's
    ref = pin.Model()
    base = ref.addJoint(0, pin.JointModelFreeFlyer() if planar_basis is None else pin.JointModelPlanar(),
                        pin.SE3(R, np.zeros(3)), "base")
    ref.appendBodyToJoint(base, B.act(full.inertias[jr]), pin.SE3.Identity())
    parent, placement = base, None
    for j in chain:
        placement = full.jointPlacements[j] if parent != base else B * full.jointPlacements[j]
        parent = ref.addJoint(parent, full.joints[j], placement, full.names[j])
        ref.appendBodyToJoint(parent, full.inertias[j], pin.SE3.Identity())
    frame = ref.addFrame(pin.Frame("ankle", parent, 0, full.frames[fa].placement, pin.FrameType.OP_FRAME), False)
    q = pin.neutral(ref)
    return Reference(ref, q, frame, [full.names[j] for j in chain], R, full)


def footopt_impulse(leg: ImportedLeg, speed: float = 1.0) -> float:
    """footopt's answer on the imported model file: the ankle's normal impulse."""
    m = leg.model
    return float(evaluate(m.tree, Scene(speed=speed, restitution=0.0), space=m.space).external[0])


def footopt_joint_mass_matrix(leg: ImportedLeg) -> np.ndarray:
    """The joints' block of the imported tree's mass matrix (footopt's coordinates: the planar
    joints' angles as footopt counts them)."""
    t = build(leg.model.tree) if leg.space is PLANAR else build_spatial(leg.model.tree)
    M = t.mass_matrix_ours()
    nb = 3 if leg.space is PLANAR else 6
    return M[nb:, nb:]


def spatial_world(leg: ImportedLeg, tree: Tree | None = None):
    """A spatial leg's joint positions and axes and its contact (the ankle) in the description's
    world (the root link's frame), from the model file's rods alone (footopt's frame rules,
    rods.py); ``tree``: the leg's tree posed otherwise."""
    tree = tree or leg.model.tree
    R = [None] * tree.n_bodies
    p = [None] * tree.n_bodies
    out = []
    for i, b in enumerate(tree.bodies):
        if b.parent is None:
            R[i], p[i] = body_rotation(b), TO_FOOTOPT @ leg.segments[0].start
        else:
            q = tree.bodies[b.parent]
            p[i] = p[b.parent] + R[b.parent] @ np.array([b.at * q.length, 0.0, 0.0])
            R[i] = R[b.parent] @ body_rotation(b)
            out.append((TO_FOOTOPT.T @ p[i], TO_FOOTOPT.T @ R[i] @ unit_axis(b)))
    last = tree.bodies[-1]
    ankle = TO_FOOTOPT.T @ (p[-1] + R[-1] @ np.array([last.contacts[0] * last.length, 0.0, 0.0]))
    return out, ankle


def planar_ankle(leg: ImportedLeg, tree: Tree | None = None) -> np.ndarray:
    """A planar leg's contact (the ankle) in footopt's plane (x, y), from the model file's rods
    alone, the base rod starting where the import placed it (``TO_FOOTOPT[:2]`` of the description's
    world: the plane of legs turning about the description's y)."""
    tree = tree or leg.model.tree
    tip, phi = TO_FOOTOPT[:2] @ leg.segments[0].start, 0.0
    for b in tree.bodies:
        phi += b.angle
        reach = b.contacts[0] if b.contacts else 1.0
        tip = tip + reach * b.length * np.array([np.cos(phi), np.sin(phi)])
    return tip


def footopt_ankle(leg: ImportedLeg, tree: Tree | None = None) -> np.ndarray:
    """The ankle from the rods: spatial, in the description's world; planar, in footopt's plane."""
    return planar_ankle(leg, tree) if leg.space is PLANAR else spatial_world(leg, tree)[1]
