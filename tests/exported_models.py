"""Exported URDF read back by Pinocchio, for the export tests (tests/optimizer/test_export.py) and
the run directory's tests (every Pareto design is exported). Needs ``pin`` (a test dependency)."""

from __future__ import annotations

import numpy as np
import pytest

from impulse_core.model.tree import JointKind, Scene, Tree
from impulse_core.timedomain.compliant import touchdown_configuration

pin = pytest.importorskip("pinocchio")


def pinocchio_landing(urdf: str, tree: Tree, scene: Scene, v_minus: np.ndarray, active: tuple[int, ...]):
    """pinocchio.impulseDynamics on the URDF loaded with a free-flyer at its neutral pose: the
    impulses at the active contacts, v_plus in footopt's coordinates (least squares: Pinocchio's
    has three more, out of the plane), the contact frames' positions, and Pinocchio's v_plus."""
    model = pin.buildModelFromXML(urdf, pin.JointModelFreeFlyer())
    data = model.createData()
    q = pin.neutral(model)
    names = [f"{tree.bodies[b].name}_contact{k}" for b, k in tree.contacts]
    frames = [model.getFrameId(n, pin.BODY) for n in names]
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    J = np.array([pin.getFrameJacobian(model, data, frames[c], pin.LOCAL_WORLD_ALIGNED)[1] for c in active])
    T = velocity_map(model, tree, scene)
    v_plus = pin.impulseDynamics(model, data, q, T @ v_minus, J.reshape(len(active), model.nv), scene.restitution, 0.0)
    at = {n: data.oMf[f].translation.copy() for n, f in zip(names, frames, strict=True)}
    return np.array(data.impulse_c), np.linalg.lstsq(T, np.array(v_plus), rcond=None)[0], at, v_plus


def velocity_map(model, tree: Tree, scene: Scene) -> np.ndarray:
    """T with v_pinocchio = T v_footopt. The free-flyer moves the root link, whose frame is the
    world frame at touchdown: its linear velocity is that of the point at the world origin,
    (vx, vy) + omega z x (0 - base origin)."""
    q = touchdown_configuration(tree, scene.terrain, scene.base_x, clearance=0.0)
    revolute = [b for b in tree.bodies[1:] if b.joint is JointKind.REVOLUTE]
    T = np.zeros((model.nv, 3 + len(revolute)))
    T[0, 0] = T[1, 1] = T[5, 2] = 1.0
    T[0, 2], T[1, 2] = q[1], -q[0]
    for k, b in enumerate(revolute):
        T[model.joints[model.getJointId(b.name)].idx_v, 3 + k] = 1.0
    return T
