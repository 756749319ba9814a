"""MJCF as a :class:`~optimizer.imports.description.Description`, compiled by MuJoCo itself
(``mujoco.MjModel.from_xml_path``: defaults, classes, includes and the inertia rules exactly as
MuJoCo simulates the file), then read from the compiled model. Needs the ``mujoco`` package
(``pip install 'footopt[mjcf]'``), imported only here.

MuJoCo places a hinge anywhere in its body (``jnt_pos``): each link's frame here is its body frame
moved to that point, so that the joint turns the link about its frame's origin as in URDF. A body
without joints is welded to its parent (fixed); one hinge is revolute; a free joint on the root
is the root's own and ignored; anything else (slide, ball, several joints) keeps MuJoCo's name.
Sites and geoms are named points on their body. A hinge's laws are MuJoCo's compiled ones (so
``<compiler angle>``, ``limited``/autolimits and default classes resolve as MuJoCo resolves them):
``jnt_range`` where ``jnt_limited``, ``dof_damping``, ``jnt_stiffness`` about ``qpos_spring``
(springref), all in qpos, whose value at the file's pose is ``qpos0`` (``ref``); ``dof_armature``
and ``dof_frictionloss`` are kept as laws footopt cannot carry.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from optimizer.errors import ConfigError
from optimizer.imports.description import FIXED, REVOLUTE, Description, Dynamics, Joint, Link, unit


def _rotation(quat: np.ndarray) -> np.ndarray:
    w, x, y, z = quat / np.linalg.norm(quat)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def _dynamics(m, j: int) -> Dynamics:
    """Hinge ``j``'s compiled laws (qpos units: rad)."""
    q, v = int(m.jnt_qposadr[j]), int(m.jnt_dofadr[j])
    limits = (float(m.jnt_range[j][0]), float(m.jnt_range[j][1])) if m.jnt_limited[j] else None
    other = (("armature", float(m.dof_armature[v])), ("frictionloss", float(m.dof_frictionloss[v])))
    return Dynamics(limits=limits, damping=float(m.dof_damping[v]), stiffness=float(m.jnt_stiffness[j]),
                    springref=float(m.qpos_spring[q]), ref=float(m.qpos0[q]),
                    unsupported=tuple((name, x) for name, x in other if x != 0.0))


def read_mjcf(path: Path) -> Description:
    """The links and joints of an MJCF file, as MuJoCo compiles it."""
    try:
        import mujoco
    except ImportError:
        raise ConfigError("reading MJCF needs the mujoco package: pip install 'footopt[mjcf]' (or mujoco)", path) from None
    try:
        m = mujoco.MjModel.from_xml_path(str(path))
    except ValueError as e:  # MuJoCo's compiler errors
        raise ConfigError(f"MuJoCo cannot compile it: {' '.join(str(e).split())}", path) from None
    body_name = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b) or f"body{b}" for b in range(m.nbody)]
    kinds = {int(mujoco.mjtJoint.mjJNT_FREE): "free", int(mujoco.mjtJoint.mjJNT_BALL): "ball",
             int(mujoco.mjtJoint.mjJNT_SLIDE): "slide", int(mujoco.mjtJoint.mjJNT_HINGE): REVOLUTE}
    anchor = np.zeros((m.nbody, 3))
    kind = [FIXED] * m.nbody
    axis = [np.array([1.0, 0.0, 0.0])] * m.nbody
    joint_name = list(body_name)
    dynamics = [Dynamics()] * m.nbody
    for b in range(1, m.nbody):
        n, adr = int(m.body_jntnum[b]), int(m.body_jntadr[b])
        if n == 1:
            kind[b] = kinds.get(int(m.jnt_type[adr]), "unknown")
            joint_name[b] = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, adr) or f"{body_name[b]} joint"
            if kind[b] == REVOLUTE:
                anchor[b] = m.jnt_pos[adr]
                axis[b] = unit(np.array(m.jnt_axis[adr], dtype=float), f"joint '{joint_name[b]}'.axis", path)
                dynamics[b] = _dynamics(m, adr)
        elif n > 1:
            kind[b] = f"{n} joints"
            joint_name[b] = f"{body_name[b]}'s {n} joints"
    links: dict[str, Link] = {}
    joints: dict[str, Joint] = {}
    for b in range(m.nbody):
        _check_finite(m, b, body_name[b], path)
        Ri = _rotation(np.array(m.body_iquat[b], dtype=float))
        inertia = Ri @ np.diag(np.array(m.body_inertia[b], dtype=float)) @ Ri.T
        links[body_name[b]] = Link(body_name[b], float(m.body_mass[b]), np.array(m.body_ipos[b]) - anchor[b], inertia)
        if b == 0:
            continue
        p = int(m.body_parentid[b])
        R = _rotation(np.array(m.body_quat[b], dtype=float))
        origin = np.array(m.body_pos[b], dtype=float) + R @ anchor[b] - anchor[p]
        joints[body_name[b]] = Joint(joint_name[b], kind[b], body_name[p], body_name[b], origin, R, axis[b],
                                     dynamics[b])
    points: dict[str, tuple[str, np.ndarray]] = {}
    for obj, count, body_of, pos in ((mujoco.mjtObj.mjOBJ_GEOM, m.ngeom, m.geom_bodyid, m.geom_pos),
                                     (mujoco.mjtObj.mjOBJ_SITE, m.nsite, m.site_bodyid, m.site_pos)):
        for k in range(count):
            name = mujoco.mj_id2name(m, obj, k)
            if name:
                b = int(body_of[k])
                points[name] = (body_name[b], np.array(pos[k], dtype=float) - anchor[b])
    return Description(path, "MJCF", links, joints, points)


def _check_finite(m: Any, b: int, name: str, path: Path) -> None:
    """ConfigError naming body ``name`` where MuJoCo compiled a mass, inertia, pose or inertial
    frame of it that is not finite (MuJoCo accepts ``mass="nan"``)."""
    for field, label in (("body_mass", "mass"), ("body_inertia", "inertia"), ("body_ipos", "inertial pos"),
                         ("body_iquat", "inertial quat"), ("body_pos", "pos"), ("body_quat", "quat")):
        if not np.all(np.isfinite(np.asarray(getattr(m, field)[b], dtype=float))):
            raise ConfigError(f"body '{name}': its {label} is not finite (compiled as "
                              f"{np.asarray(getattr(m, field)[b]).tolist()})", path)


__all__ = ["read_mjcf"]
