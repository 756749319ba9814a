"""A model as URDF or MJCF, for simulators and robot tools (``footopt export``; every Pareto design).

Pure functions: a tree and its scene in, XML text out, built with ``xml.etree.ElementTree`` (names
are escaped, never pasted into text); the callers write the files. What the files hold
(``docs/MODEL_FORMAT.md``, "Export"):

- one link (URDF) or body (MJCF) per rod, named as the rod, with the rod's mass, centre of mass and
  inertia tensor about it (``impulse_core.model.rods``). URDF holds the tensor footopt's dynamics
  use (:func:`dynamics_inertia`: a rod without radius has m (1e-7 L)^2 about its own axis, the
  kinematic core's floor), so Pinocchio's impulses are footopt's; MJCF raises every principal
  moment to :data:`INERTIA_FLOOR` (MuJoCo refuses smaller ones);
- one joint per other rod, named as the rod: revolute about z (URDF ``continuous``, or
  ``revolute`` with its stops as limits) or fixed; each joint's origin holds the rod's touchdown
  angle, so that the zero configuration is the touchdown posture; a joint law (stops, spring,
  damper) is carried over where the format has it, relative to that zero: URDF ``<limit>`` and
  ``<dynamics damping>`` (URDF has no springs: the file says so), MJCF ``range``, ``stiffness``,
  ``springref`` and ``damping``; a stop's restitution has no URDF counterpart (the file says so),
  and in MJCF each stop is a stiff limit (``solreflimit``, ``solimplimit``: :func:`stop_parameters`)
  rebounding with the stop's restitution;
- a floating base whose zero pose is the touchdown pose (base origin above ``scene.base_x``,
  lowered until its first contact touches the scene's ground): MJCF, a ``freejoint`` on the base
  body placed there; URDF, the root link (to be loaded with a free-flyer), whose frame is then the
  world frame at touchdown, the base rod's frame sitting in it at the touchdown pose;
- one frame per contact, ``<rod>_contact<k>``: a massless link on a fixed joint (URDF), a site
  (MJCF);
- footopt's axes: x forward, y up, z lateral; MJCF's gravity along -y;
- a spatial scene's ``scene.heightfield`` (the base pose is then the touchdown on it): MJCF, an
  ``<hfield>`` asset and geom (:func:`mjcf_ground`) on a regular grid (:func:`regular_heightfield`:
  an uneven grid on a common step, or refused naming ``scene.heightfield.x``/``.z``; a flat skirt
  beyond it as far as the robot reaches, :func:`ground_cover`), the geom
  turned so that MuJoCo's elevation axis is footopt's y; the comment states the float32 rounding of
  the heights and the largest distance between MuJoCo's two triangles per cell and footopt's
  bilinear patch (:attr:`RegularHeightfield.triangulation_error`); URDF has no terrain (the comment
  says so).
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from enum import Enum

from dataclasses import dataclass, replace

import numpy as np

from impulse_core.kinematics.spatial import AXIAL_GYRATION_FLOOR, PLANAR, Space
from impulse_core.model.rods import (
    body_rotation,
    centre_of_mass,
    children,
    contact_point,
    depth_first,
    inertia_tensor,
    joint_origin,
    rpy_of,
    unit_axis,
)
from impulse_core.model import heightfield as hfield
from impulse_core.model.heightfield import Heightfield
from impulse_core.model.joints import FREE, JointLaw
from impulse_core.model.tree import Body, JointKind, Scene, Tree, tensor_problem
from impulse_core.timedomain.compliant import damping_ratio_for_restitution, scene_ground, touchdown_configuration
from optimizer.errors import ConfigError

#: Each principal moment of inertia is written as at least this (kg m^2).
INERTIA_FLOOR = 1e-9
#: Gravity written into MJCF (m/s^2, along -y): MuJoCo's default magnitude.
GRAVITY = 9.81
#: Radius of the rods' visual cylinders and capsules (m): drawing only, no mass, no collision.
VISUAL_RADIUS = 0.005
#: MuJoCo's default time step (s), which the exported MJCF keeps: its stops are tuned for it.
STOP_TIMESTEP = 0.002
#: The MuJoCo steps (s) the stops can be tuned for: at 1e300 s their solreflimit was -0.0, at
#: 1e-300 s -inf (not a number MuJoCo reads).
STOP_TIMESTEP_RANGE = (1.0e-8, 1.0)
#: Time steps per period of a stop's spring (MuJoCo's semi-implicit Euler step): the stop's
#: rebound ratio is within 0.035 of its restitution at this step, whatever the phase of the step
#: at which it closes, converging as the step shrinks (tests/optimizer/test_export.py).
STOP_STEPS_PER_PERIOD = 40
#: A stop's constant impedance (MuJoCo's ``solimplimit = (d, d, ...)``), as the drop's contacts.
STOP_IMPEDANCE = 0.9999
#: URDF's effort and velocity limits of a joint with stops (the model has no motors: unbounded).
UNBOUNDED = 1e9
#: Characters XML 1.0 cannot hold (control characters other than tab and line breaks, and non-characters).
_NOT_XML = re.compile("[^\t\n\r\x20-\ud7ff\ue000-\ufffd\U00010000-\U0010ffff]")


class ExportFormat(Enum):
    """A robot description format footopt writes."""

    URDF = "urdf"
    MJCF = "mjcf"

    @property
    def suffix(self) -> str:
        """The file suffix footopt gives it."""
        return ".urdf" if self is ExportFormat.URDF else ".xml"


def contact_frame_name(body: Body, k: int) -> str:
    """The name of contact ``k`` of ``body`` (its index in the body's ``contacts``)."""
    return f"{body.name}_contact{k}"


def check_inertias(tree: Tree) -> None:
    """Raise ConfigError naming ``model.bodies[i].radius`` where a rod's m r^2 / 2 about its axis
    exceeds twice its inertia across: no rigid body has such principal moments (their triangle
    inequality), and MuJoCo refuses them. The model file allows them (the impulses are defined)."""
    for i, b in enumerate(tree.bodies):
        if not b.is_rod:  # a general body: its whole tensor (the rod's and the added one)
            I = inertia_tensor(b)
            problem = tensor_problem((I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]))
            if problem is not None:
                raise ConfigError(f"model.bodies[{i}].inertia_tensor: with the rod's own, {problem}: MuJoCo refuses it")
            continue
        if b.axial_inertia > 2.0 * b.inertia * (1 + 1e-12):
            raise ConfigError(
                f"model.bodies[{i}].radius: {b.radius} m gives m r^2/2 = {b.axial_inertia:.6g} kg m^2 about the rod's "
                f"axis, more than twice its inertia across ({b.inertia:.6g}): MuJoCo refuses such a body (the "
                "triangle inequality of principal moments); lower the radius or raise inertia/gyration"
            )


def check_names(tree: Tree) -> None:
    """Raise ConfigError naming ``model.bodies[i].name`` when a rod's name cannot be exported: a
    character XML cannot hold, or the name of another rod's contact frame."""
    frames = {contact_frame_name(b, k): b.name for b in tree.bodies for k in range(len(b.contacts))}
    for i, b in enumerate(tree.bodies):
        bad = _NOT_XML.search(b.name)
        if bad:
            raise ConfigError(f"model.bodies[{i}].name: character {ord(bad.group()):#x} cannot be written in XML")
        if b.name in frames:
            raise ConfigError(
                f"model.bodies[{i}].name: '{b.name}' is also the name of a contact frame of '{frames[b.name]}' "
                "in URDF and MJCF; rename one of the two rods"
            )


#: A frame: its origin and its rotation (3 x 3), in the frame that holds it.
Frame = tuple[np.ndarray, np.ndarray]


def base_pose(tree: Tree, scene: Scene, space: Space = PLANAR) -> Frame:
    """The base rod's frame at touchdown in the world: origin (m) and rotation. Planar: above
    ``scene.base_x``, lowered until the first contact touches the scene's ground; spatial on a
    ``scene.heightfield``: above (``base_x``, ``base_z``), lowered until the first contact touches
    the heightfield (footopt's bilinear ground); spatial otherwise (flat ground): above the world
    origin, its lowest contact on y = 0."""
    if space is PLANAR:
        q = touchdown_configuration(tree, *scene_ground(scene), clearance=0.0)
        return np.array([q[0], q[1], 0.0]), body_rotation(replace(tree.bodies[0], angle=float(q[2])))
    from impulse_core.evaluate import touchdown_geometry

    if scene.heightfield is not None:
        q = touchdown_configuration(tree, scene.heightfield, scene.base_x, clearance=0.0, space=space,
                                    base_z=scene.base_z)
        return np.array(q[:3], dtype=float), body_rotation(tree.bodies[0])
    return np.array([0.0, -touchdown_geometry(tree, space).ground_height, 0.0]), body_rotation(tree.bodies[0])


def export_text(
    tree: Tree,
    scene: Scene,
    fmt: ExportFormat,
    name: str = "footopt",
    joints: tuple[JointLaw, ...] = (),
    space: Space = PLANAR,
    stop_timestep: float = STOP_TIMESTEP,
) -> str:
    """The description of ``tree`` (and its joint laws) at its touchdown in ``scene``, in ``fmt``
    (MJCF: the stops tuned for MuJoCo steps of ``stop_timestep`` s)."""
    if fmt is ExportFormat.URDF:
        return to_urdf(tree, scene, name, joints, space)
    return to_mjcf(tree, scene, name, joints=joints, space=space, stop_timestep=stop_timestep)


def _law(joints: tuple[JointLaw, ...], i: int) -> JointLaw:
    return joints[i] if joints else FREE


def _relative(law: JointLaw, angle: float) -> tuple[tuple[float, float] | None, float]:
    """The law's stops and spring rest relative to the touchdown angle (the exported zero)."""
    limits = None if law.limits is None else (law.limits[0] - angle, law.limits[1] - angle)
    return limits, 0.0 if law.rest is None else law.rest - angle


# --------------------------------------------------------------------------------------------
# URDF


def to_urdf(
    tree: Tree, scene: Scene, name: str = "footopt", joints: tuple[JointLaw, ...] = (), space: Space = PLANAR
) -> str:
    """The URDF of ``tree``: load it with a free-flyer root joint (Pinocchio:
    ``pin.buildModelFromXML(text, pin.JointModelFreeFlyer())``); ``pin.neutral(model)`` is then
    the touchdown pose, and the free-flyer's velocity that of the world frame's origin."""
    check_names(tree)
    robot = ET.Element("robot", name=_xml_safe(name))
    robot.append(ET.Comment(_note(tree, scene, ExportFormat.URDF, joints, space)))
    # each rod's frame in its link's frame: the base rod's in the root link (the world at touchdown)
    identity: Frame = (np.zeros(3), np.eye(3))
    frames = [base_pose(tree, scene, space) if b.parent is None else identity for b in tree.bodies]
    for i in depth_first(tree):
        b = tree.bodies[i]
        robot.append(_urdf_link(b, frames[i]))
        if b.parent is not None:
            law = _law(joints, i)
            kind = "fixed" if b.joint is not JointKind.REVOLUTE else "continuous" if law.limits is None else "revolute"
            placed = _placed(frames[b.parent], joint_origin(tree, i), body_rotation(b))
            joint = _urdf_joint(b.name, kind, tree.bodies[b.parent].name, b.name, placed, _axis_text(b))
            _urdf_law(joint, law, b.angle)
            robot.append(joint)
        for k in range(len(b.contacts)):
            frame = contact_frame_name(b, k)
            robot.append(ET.Element("link", name=frame))
            placed = _placed(frames[i], contact_point(b, k), np.eye(3))
            robot.append(_urdf_joint(frame, "fixed", b.name, frame, placed))
    return _text(robot, declaration=True)


def _placed(frame: Frame, point: np.ndarray, turn: np.ndarray) -> Frame:
    """A point and a rotation ``turn`` given in a rod's frame, in its link's frame, where the rod's
    frame sits at ``frame``."""
    origin, R = frame
    return origin + R @ point, R @ turn


def quaternion_of(R: np.ndarray) -> tuple[float, float, float, float]:
    """MJCF's (w, x, y, z) of a rotation (Shepperd's method: the largest component first)."""
    t = np.trace(R)
    cases = [t, R[0, 0], R[1, 1], R[2, 2]]
    k = int(np.argmax(cases))
    if k == 0:
        w = 0.5 * math.sqrt(1 + t)
        q = (w, (R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w), (R[1, 0] - R[0, 1]) / (4 * w))
    elif k == 1:
        x = 0.5 * math.sqrt(1 + 2 * R[0, 0] - t)
        q = ((R[2, 1] - R[1, 2]) / (4 * x), x, (R[0, 1] + R[1, 0]) / (4 * x), (R[0, 2] + R[2, 0]) / (4 * x))
    elif k == 2:
        y = 0.5 * math.sqrt(1 + 2 * R[1, 1] - t)
        q = ((R[0, 2] - R[2, 0]) / (4 * y), (R[0, 1] + R[1, 0]) / (4 * y), y, (R[1, 2] + R[2, 1]) / (4 * y))
    else:
        z = 0.5 * math.sqrt(1 + 2 * R[2, 2] - t)
        q = ((R[1, 0] - R[0, 1]) / (4 * z), (R[0, 2] + R[2, 0]) / (4 * z), (R[1, 2] + R[2, 1]) / (4 * z), z)
    return q if q[0] >= 0 else tuple(-c for c in q)  # type: ignore[return-value]


#: A cylinder's axis (its z) turned onto a rod's x axis.
_CYLINDER_ON_X = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])


def dynamics_inertia(b: Body) -> np.ndarray:
    """The inertia tensor about the centre of mass (rod frame) that footopt's dynamics use: the
    model's, plus the kinematic core's axial floor m (AXIAL_GYRATION_FLOOR L)^2 about the rod's
    own axis (positive, and so small that it moves no impulse: docs/MODEL_FORMAT.md)."""
    return inertia_tensor(b) + np.diag([b.mass * (AXIAL_GYRATION_FLOOR * b.length) ** 2, 0.0, 0.0])


_URDF_INERTIA_NOTE = (
    "Inertia: as the model, about each rod's centre of mass, as footopt's dynamics use it: a rod without",
    f"radius has m ({AXIAL_GYRATION_FLOOR:g} L)^2 about its own axis (x), footopt's own floor, so the impulses are footopt's.",
)


def _mjcf_inertia_note(planar: bool) -> tuple[str, ...]:
    """What the MJCF's inertia floor changes (MuJoCo refuses principal moments below 1e-15)."""
    return (
        "Inertia: as the model, about each rod's centre of mass; a slender rod has none about its own axis (x),",
        f"written here as {INERTIA_FLOOR:g} kg m^2 because MuJoCo needs positive inertia; "
        + ("planar motion never turns a rod about" if planar else "a rod with a radius has m r^2 / 2. Where the"),
        "its own axis, so the impulses do not change." if planar
        else "floor stands in for a rod without radius, a motion turning the rod about its axis feels it: the impulses",
        *(() if planar else ("can differ from footopt's by about 1e-9 kg m^2 / (the smallest inertia the impact "
                             "sees), relative; the URDF holds footopt's own values.",)),
    )


def _urdf_link(b: Body, frame: Frame) -> ET.Element:
    """A rod's link: inertial and a visual cylinder, the rod's frame at ``frame`` in the link."""
    link = ET.Element("link", name=b.name)
    inertial = ET.SubElement(link, "inertial")
    com, R = _placed(frame, centre_of_mass(b), np.eye(3))
    ET.SubElement(inertial, "origin", xyz=_xyz(com), rpy=_xyz(rpy_of(R)))
    ET.SubElement(inertial, "mass", value=_f(b.mass))
    tensor = dynamics_inertia(b)  # about the centre of mass, in the rod's frame (the origin's)
    axes = {"ixx": (0, 0), "ixy": (0, 1), "ixz": (0, 2), "iyy": (1, 1), "iyz": (1, 2), "izz": (2, 2)}
    ET.SubElement(inertial, "inertia", {key: _f(tensor[r, c]) for key, (r, c) in axes.items()})
    visual = ET.SubElement(link, "visual")
    middle, R = _placed(frame, np.array([0.5 * b.length, 0.0, 0.0]), _CYLINDER_ON_X)
    ET.SubElement(visual, "origin", xyz=_xyz(middle), rpy=_xyz(rpy_of(R)))
    geometry = ET.SubElement(visual, "geometry")
    ET.SubElement(geometry, "cylinder", radius=_f(max(b.radius, VISUAL_RADIUS)), length=_f(b.length))
    return link


def _axis_text(b: Body) -> str:
    """A joint's axis in its frame: ``0 0 1`` in the plane, the unit ``axis`` in space."""
    return "0 0 1" if b.axis == (0.0, 0.0, 1.0) else _xyz(unit_axis(b))


def _urdf_joint(name: str, kind: str, parent: str, child: str, frame: Frame, axis: str = "0 0 1") -> ET.Element:
    joint = ET.Element("joint", name=name, type=kind)
    ET.SubElement(joint, "parent", link=parent)
    ET.SubElement(joint, "child", link=child)
    ET.SubElement(joint, "origin", xyz=_xyz(frame[0]), rpy=_xyz(rpy_of(frame[1])))
    if kind != "fixed":
        ET.SubElement(joint, "axis", xyz=axis)
    return joint


def _urdf_law(joint: ET.Element, law: JointLaw, angle: float) -> None:
    """Stops as ``<limit>`` (effort and velocity unbounded: the model has no motors), the damper as
    ``<dynamics>``."""
    limits, _ = _relative(law, angle)
    if limits is not None:
        ET.SubElement(joint, "limit", lower=_f(limits[0]), upper=_f(limits[1]), effort=_f(UNBOUNDED),
                      velocity=_f(UNBOUNDED))
    if law.damping:
        ET.SubElement(joint, "dynamics", damping=_f(law.damping), friction="0.0")


# --------------------------------------------------------------------------------------------
# MJCF


def to_mjcf(
    tree: Tree,
    scene: Scene,
    name: str = "footopt",
    gravity: float = GRAVITY,
    joints: tuple[JointLaw, ...] = (),
    space: Space = PLANAR,
    stop_timestep: float = STOP_TIMESTEP,
    ground: bool = True,
) -> str:
    """The MJCF of ``tree``: ``qpos0`` is the touchdown pose; gravity ``gravity`` (m/s^2) along -y;
    the stops tuned for MuJoCo steps of ``stop_timestep`` (s; :func:`stop_parameters`). A spatial
    scene's ``scene.heightfield`` is written as the ground (:func:`mjcf_ground`) unless ``ground``
    is False (``footopt drop`` adds its own)."""
    check_names(tree)
    check_inertias(tree)
    hf = scene.heightfield if ground and space is not PLANAR else None
    regular = None if hf is None or hf.is_flat else regular_heightfield(hf, ground_cover(tree, scene, space))
    root = ET.Element("mujoco", model=_xml_safe(name))
    root.append(ET.Comment(_note(tree, scene, ExportFormat.MJCF, joints, space, stop_timestep, ground)))
    ET.SubElement(root, "compiler", angle="radian")
    ET.SubElement(root, "option", gravity=_xyz((0.0, -gravity, 0.0)))
    world = ET.SubElement(root, "worldbody")
    if hf is not None:
        mjcf_ground(root, world, hf, regular)
    _mjcf_body(world, tree, 0, base_pose(tree, scene, space), children(tree), joints, stop_timestep)
    return _text(root, declaration=False)


def _mjcf_body(
    parent: ET.Element, tree: Tree, i: int, frame: Frame, kids: tuple[tuple[int, ...], ...],
    joints: tuple[JointLaw, ...] = (), stop_timestep: float = STOP_TIMESTEP,
) -> None:
    """Body ``i`` (and its subtree) inside ``parent``, its frame at ``frame`` in the parent's."""
    b = tree.bodies[i]
    body = ET.SubElement(parent, "body", name=b.name, pos=_xyz(frame[0]), quat=_xyz(quaternion_of(frame[1])))
    if b.parent is None:
        ET.SubElement(body, "freejoint", name=b.name)
    elif b.joint is JointKind.REVOLUTE:
        law = _mjcf_law(_law(joints, i), b.angle, stop_timestep)
        ET.SubElement(body, "joint", name=b.name, type="hinge", axis=_axis_text(b), **law)
    tensor = inertia_tensor(b, INERTIA_FLOOR)
    if b.is_rod:  # principal axes = body axes
        inertia = {"diaginertia": _xyz(np.diag(tensor))}
    else:  # a general body: the full tensor about its centre of mass, body axes
        tensor = _inside_triangle(tensor)
        inertia = {"fullinertia": _xyz(tensor[r, c] for r, c in ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)))}
    ET.SubElement(body, "inertial", pos=_xyz(centre_of_mass(b)), mass=_f(b.mass), **inertia)
    rod = {"type": "capsule", "fromto": _xyz((0, 0, 0, b.length, 0, 0)), "size": _f(max(b.radius, VISUAL_RADIUS))}
    ET.SubElement(body, "geom", rod, contype="0", conaffinity="0", group="1", mass="0")  # drawing only
    for k in range(len(b.contacts)):
        ET.SubElement(body, "site", name=contact_frame_name(b, k), pos=_xyz(contact_point(b, k)))
    for child in kids[i]:
        placed = (joint_origin(tree, child), body_rotation(tree.bodies[child]))
        _mjcf_body(body, tree, child, placed, kids, joints, stop_timestep)


#: A general body's principal moments are written at least this fraction of their sum inside
#: the triangle inequality (MuJoCo checks A + B >= C on its own eigenvalues, without slack).
TRIANGLE_MARGIN = 1e-12


def _inside_triangle(I: np.ndarray) -> np.ndarray:
    """``I`` with its two smaller principal moments raised, where needed, so that their sum
    exceeds the largest by ``TRIANGLE_MARGIN`` of the trace: a tensor on the boundary (a thin
    plate, a rod) then passes MuJoCo's check despite rounding; it changes by at most that fraction."""
    moments, axes = np.linalg.eigh(I)
    slack = moments[0] + moments[1] - moments[2]
    margin = TRIANGLE_MARGIN * float(moments.sum())
    if slack >= margin:
        return I
    moments[:2] += 0.5 * (margin - slack)
    out = axes @ np.diag(moments) @ axes.T
    return 0.5 * (out + out.T)


def stop_parameters(restitution: float, timestep: float = STOP_TIMESTEP) -> tuple[float, float]:
    """MuJoCo's direct limit parameters ``(k, b)`` of a stop (``solreflimit = (-k, -b)``, 1/s^2
    and 1/s), for a constant impedance :data:`STOP_IMPEDANCE`: the joint angle's overshoot past
    the stop follows x'' = -k x - b x' while the stop pushes (released, not reversed), whatever
    the inertia behind it. k: :data:`STOP_STEPS_PER_PERIOD` steps of ``timestep`` per period;
    b: the damping ratio at which that clipped spring-damper rebounds with ``restitution``
    (:func:`damping_ratio_for_restitution`), at most the one with b * timestep = 1 (a
    semi-implicit step removes a step's velocity in one step and no more: more damping rebounds
    in one step). e = 0 takes that most damped one, which rebounds with about 0.021."""
    omega = 2.0 * math.pi / (STOP_STEPS_PER_PERIOD * timestep)
    most = 1.0 / (2.0 * omega * timestep)
    zeta = most if restitution <= 0.0 else min(damping_ratio_for_restitution(restitution), most)
    return omega * omega, 2.0 * zeta * omega


def _mjcf_law(law: JointLaw, angle: float, stop_timestep: float = STOP_TIMESTEP) -> dict[str, str]:
    """A hinge's attributes for a joint law: ``range`` (limited) with the stops' stiff limit
    (:func:`stop_parameters` at ``stop_timestep``), ``stiffness`` about ``springref``, ``damping``."""
    limits, rest = _relative(law, angle)
    out: dict[str, str] = {}
    if limits is not None:
        k, b = stop_parameters(law.stop_restitution, stop_timestep)
        d = _f(STOP_IMPEDANCE)
        out = {"limited": "true", "range": _xyz(limits), "solreflimit": _xyz((-k, -b)),
               "solimplimit": f"{d} {d} 0.001 0.5 2"}
    if law.stiffness:
        out |= {"stiffness": _f(law.stiffness), "springref": _f(rest)}
    if law.damping:
        out["damping"] = _f(law.damping)
    return out


# --------------------------------------------------------------------------------------------
# The ground: scene.heightfield as a MuJoCo hfield

#: The MJCF names of the ground's hfield asset and geom.
HFIELD_NAME = "heightfield"
#: Most cells per axis of the regular grid an uneven ``scene.heightfield`` is written on.
HFIELD_MAX_CELLS = 1000
#: Most cells of the flat skirt beyond the grid on each side of an axis.
HFIELD_SKIRT_MAX_CELLS = 200
#: An uneven grid's points must lie within this fraction of the common step of a regular node
#: (a regular grid written to rounded decimals: 0.266667, 0.266666); MuJoCo's nodes are then up
#: to this fraction of a step from the model's points, which the file states (``node_shift``).
HFIELD_GRID_TOLERANCE = 1e-5
#: Least depth (m) of the hfield's solid base below its lowest point (MuJoCo's ``base_z``; at
#: least the heights' range too).
HFIELD_BASE = 0.1
#: The hfield's local axes (columns) in footopt's world: its x along x, its y (MuJoCo's rows)
#: along -z, its z (the elevation) along y, up.
HFIELD_AXES = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
#: MuJoCo stores an hfield's normalised heights as float32: each within 2^-24 of the range.
HFIELD_ROUNDING = 2.0**-24


@dataclass(frozen=True)
class RegularHeightfield:
    """footopt's ground on a regular grid (MuJoCo's hfield): nodes ``x`` and ``z`` (m, evenly
    spaced; every point of the model's grid is one of them) and ``heights[i, j]``, footopt's
    bilinear ground at (x[i], z[j]) (m)."""

    x: np.ndarray
    z: np.ndarray
    heights: np.ndarray

    @property
    def triangulation_error(self) -> float:
        """The largest distance (m, vertical) between footopt's bilinear ground and MuJoCo's two
        triangles per cell: |twist| / 4 of the cell with the largest twist, at its centre
        (h00 - h10 - h01 + h11 the twist; either diagonal: the patch less the triangles is
        +-twist u v or +-twist v (1 - u), at most 1/4 of it)."""
        H = self.heights
        return float(np.max(np.abs(H[:-1, :-1] - H[1:, :-1] - H[:-1, 1:] + H[1:, 1:]))) / 4.0

    @property
    def node_shift(self) -> float:
        """The largest distance (m) between a node here (a model point) and MuJoCo's evenly spaced
        node in its place: 0 on an exactly regular grid, within :data:`HFIELD_GRID_TOLERANCE` of a
        step where the model's points were rounded."""
        return max(float(np.max(np.abs(a - np.linspace(a[0], a[-1], len(a))))) for a in (self.x, self.z))


def _regular_axis(grid: tuple[float, ...], where: str, cover: tuple[float, float]) -> np.ndarray:
    """Evenly spaced nodes through every point of ``grid`` (from its first to its last point, the
    fewest cells whose step divides every spacing), then a skirt of whole steps out to ``cover``
    (lo, hi) where it lies beyond the grid, at most :data:`HFIELD_SKIRT_MAX_CELLS` a side; a
    one-point grid (ground constant along it): it and one node either side, reaching ``cover``.
    ConfigError naming ``where`` when no step divides the spacings within :data:`HFIELD_MAX_CELLS`
    cells."""
    g = np.asarray(grid, dtype=float)
    if len(g) == 1:
        reach = max(g[0] - cover[0], cover[1] - g[0], 1e-3)
        return g[0] + np.array([-reach, 0.0, reach])
    span = g[-1] - g[0]
    for cells in range(len(g) - 1, HFIELD_MAX_CELLS + 1):
        t = (g - g[0]) / span * cells
        k = np.rint(t).astype(int)
        if np.all(np.abs(t - k) <= HFIELD_GRID_TOLERANCE):
            step = span / cells
            nodes = g[0] + np.arange(cells + 1) * step
            nodes[k] = g  # the model's points exactly
            below, above = (min(max(0, math.ceil(d / step - 1e-9)), HFIELD_SKIRT_MAX_CELLS)
                            for d in (g[0] - cover[0], cover[1] - g[-1]))
            skirt = step * np.arange(1, max(below, above) + 1)
            return np.concatenate([g[0] - skirt[:below][::-1], nodes, g[-1] + skirt[:above]])
    raise ConfigError(
        f"{where}: its spacings {_xyz(np.diff(g))} m are no whole multiples of one step within {HFIELD_MAX_CELLS} "
        "cells; MuJoCo's hfield is a regular grid: give spacings that share a step (e.g. 0.1, 0.2, 0.3)"
    )


def regular_heightfield(
    hf: Heightfield, cover: tuple[tuple[float, float], tuple[float, float]] | None = None
) -> RegularHeightfield:
    """``hf`` on a regular grid (MuJoCo's hfield): the model's grid where evenly spaced, else the
    coarsest regular grid through all its points, with a flat skirt out to ``cover`` ((x lo, x
    hi), (z lo, z hi); default the grid itself, an axis of one point spanning the other's extent)
    (:func:`_regular_axis`); footopt's heights at every node: the model's own at its points, along
    every cell of the model the same bilinear patch, in the skirt footopt's flat extension (its
    cells untwisted: MuJoCo's triangles are that ground exactly)."""
    if cover is None:
        half = 0.5 * max(hf.x[-1] - hf.x[0], hf.z[-1] - hf.z[0], 1.0)
        cover = ((hf.x[0] - half, hf.x[-1] + half) if len(hf.x) == 1 else (hf.x[0], hf.x[-1]),
                 (hf.z[0] - half, hf.z[-1] + half) if len(hf.z) == 1 else (hf.z[0], hf.z[-1]))
    x = _regular_axis(hf.x, "scene.heightfield.x", cover[0])
    z = _regular_axis(hf.z, "scene.heightfield.z", cover[1])
    return RegularHeightfield(x, z, hfield.height(hf, x[:, None], z[None, :]))


def ground_cover(tree: Tree, scene: Scene, space: Space) -> tuple[tuple[float, float], tuple[float, float]]:
    """Where the exported hfield reaches ((x lo, x hi), (z lo, z hi), m): the heightfield's grid and
    the contacts at touchdown, and beyond them the rods' total length (as far as the robot reaches)."""
    from impulse_core.evaluate import touchdown_geometry

    hf = scene.heightfield
    origin, _ = base_pose(tree, scene, space)
    P = touchdown_geometry(tree, space).contacts + origin
    reach = float(sum(b.length for b in tree.bodies))
    return ((min(hf.x[0], P[:, 0].min()) - reach, max(hf.x[-1], P[:, 0].max()) + reach),
            (min(hf.z[0], P[:, 2].min()) - reach, max(hf.z[-1], P[:, 2].max()) + reach))


def mjcf_ground(
    root: ET.Element, world: ET.Element, hf: Heightfield, regular: RegularHeightfield | None = None
) -> None:
    """The heightfield ``hf`` as the ground of an MJCF (``root``, its ``world`` body): a flat one as
    a plane at its height; any other as an ``<hfield>`` asset and geom named
    :data:`HFIELD_NAME` on :func:`regular_heightfield`'s grid: heights normalised to [0, 1]
    (MuJoCo's own normalisation then leaves them) times ``elevation`` = their range, above the
    geom at the lowest height; the geom turned by :data:`HFIELD_AXES` (MuJoCo's elevation along
    footopt's y; its rows, along -z, listed from the first z up: MuJoCo's first row is its +y
    edge)."""
    R = quaternion_of(HFIELD_AXES)
    if hf.is_flat:
        ET.SubElement(world, "geom", name=HFIELD_NAME, type="plane", size="0 0 1", pos=_xyz((0.0, hf.level, 0.0)),
                      quat=_xyz(R))
        return
    g = regular_heightfield(hf) if regular is None else regular
    lo, hi = float(g.heights.min()), float(g.heights.max())
    unit = (g.heights - lo) / (hi - lo)
    size = (0.5 * (g.x[-1] - g.x[0]), 0.5 * (g.z[-1] - g.z[0]), hi - lo, max(HFIELD_BASE, hi - lo))
    asset = ET.Element("asset")
    root.insert(list(root).index(world), asset)
    ET.SubElement(asset, "hfield", name=HFIELD_NAME, nrow=str(len(g.z)), ncol=str(len(g.x)), size=_xyz(size),
                  elevation=_xyz(unit.T.ravel()))
    centre = (0.5 * (g.x[0] + g.x[-1]), lo, 0.5 * (g.z[0] + g.z[-1]))
    ET.SubElement(world, "geom", name=HFIELD_NAME, type="hfield", hfield=HFIELD_NAME, pos=_xyz(centre), quat=_xyz(R))


# --------------------------------------------------------------------------------------------
# Text


def _note(
    tree: Tree, scene: Scene, fmt: ExportFormat, joints: tuple[JointLaw, ...] = (), space: Space = PLANAR,
    stop_timestep: float = STOP_TIMESTEP, ground: bool = True,
) -> str:
    """The comment at the top of a file: what it holds and where it departs from the model."""
    origin, R = base_pose(tree, scene, space)
    mjcf = fmt is ExportFormat.MJCF
    thin = sum(b.inertia < INERTIA_FLOOR for b in tree.bodies if b.is_rod) if mjcf else 0
    general = [b.name for b in tree.bodies if not b.is_rod] if mjcf else []
    planar = space is PLANAR
    lines = [
        f"footopt export: {tree.n_bodies} rods of a {space.name} model (docs/MODEL_FORMAT.md, Export).",
        "Axes as footopt's: x forward, y up, z lateral; "
        + ("planar joints turn about z. SI units." if planar else "each joint turns about its own axis. SI units."),
        "The zero configuration is the touchdown posture: each joint's origin holds its touchdown angle;",
        f"the base origin is at ({_f(origin[0])}, {_f(origin[1])}, {_f(origin[2])}) m, the base turned by "
        + (f"{_f(math.atan2(R[1, 0], R[0, 0]))} rad about z." if planar else f"rpy {_xyz(rpy_of(R))} rad."),
        *(_mjcf_inertia_note(planar) if mjcf else _URDF_INERTIA_NOTE),
    ]
    if thin:
        lines.append(f"{thin} rod(s) have less than {INERTIA_FLOOR:g} kg m^2 across the rod too: raised to it.")
    if general:
        lines.append(f"{', '.join(general)}: centre of mass off the rod's axis (com_offset) or a full inertia tensor")
        lines.append("(inertia_tensor): written whole ("
                     + ("<inertia> ixx..iyz" if fmt is ExportFormat.URDF else "fullinertia")
                     + f"), any principal moment below {INERTIA_FLOOR:g} kg m^2 raised to it.")
    if fmt is ExportFormat.URDF:
        lines += [
            "Load with a free-flyer root joint (Pinocchio: buildModelFromXML(text, JointModelFreeFlyer())):",
            "the root link's frame is the world frame at touchdown, and neutral(model) the touchdown pose.",
            "Revolute joints without stops are 'continuous'; stops are 'revolute' limits (effort and velocity",
            f"unbounded: {_f(UNBOUNDED)}), dampers <dynamics damping>, relative to the touchdown angle.",
        ]
    sprung = [tree.bodies[i].name for i, law in enumerate(joints) if law.stiffness]
    if sprung and fmt is ExportFormat.URDF:
        lines.append(f"URDF has no joint springs: the torsional springs of {', '.join(sprung)} are not written.")
    elif sprung:
        lines.append("Joint springs: stiffness about springref (the rest angle less the touchdown angle).")
    stopped = [tree.bodies[i].name for i, law in enumerate(joints) if law.limits is not None]
    bouncy = [tree.bodies[i].name for i, law in enumerate(joints) if law.limits is not None and law.stop_restitution]
    if bouncy and fmt is ExportFormat.URDF:
        lines.append(f"The stops' restitution of {', '.join(bouncy)} has no counterpart in the format: not written.")
    elif stopped and fmt is ExportFormat.MJCF:
        k, _ = stop_parameters(0.0, stop_timestep)
        lines += [
            f"Stops ({', '.join(stopped)}): stiff limits rebounding with the stop's restitution: direct",
            "solreflimit (-k, -b): the overshoot x follows x'' = -k x - b x' while the stop pushes (any inertia),",
            f"k = {_f(k)} 1/s^2 ({STOP_STEPS_PER_PERIOD} steps of {_f(stop_timestep)} s per period), b for the restitution",
            f"(at most 1/timestep: restitution 0 rebounds with about 0.02); solimplimit d = {_f(STOP_IMPEDANCE)}.",
            f"Stable and accurate at timestep {_f(stop_timestep)} s or shorter (rebound within 0.035 of the restitution",
            "at it, closer as the step shrinks); a longer step needs a softer k (docs/MODEL_FORMAT.md, Export).",
        ]
    if scene.heightfield is not None and not planar:
        cover = None if fmt is ExportFormat.URDF or not ground else ground_cover(tree, scene, space)
        lines += _ground_note(scene.heightfield, fmt, ground, cover)
    return "\n" + "\n".join(lines) + "\n"


def _ground_note(
    hf: Heightfield, fmt: ExportFormat, ground: bool = True,
    cover: tuple[tuple[float, float], tuple[float, float]] | None = None,
) -> list[str]:
    """What the file says about the scene's heightfield (the base pose is the touchdown on it)."""
    shape = (f"{len(hf.x)} x {len(hf.z)} points, x in [{_f(hf.x[0])}, {_f(hf.x[-1])}], "
             f"z in [{_f(hf.z[0])}, {_f(hf.z[-1])}] m")
    if fmt is ExportFormat.URDF:
        return [f"URDF has no terrain: scene.heightfield ({shape}) is not written;",
                "the pose above is the touchdown on it."]
    if not ground:
        return [f"scene.heightfield ({shape}): not written here; the pose above is the touchdown on it."]
    if hf.is_flat:
        return [f"Ground: scene.heightfield is flat ({shape}): a plane '{HFIELD_NAME}' at y = {_f(hf.level)} m."]
    g = regular_heightfield(hf, cover)
    lo, hi = float(g.heights.min()), float(g.heights.max())
    inner = regular_heightfield(hf)
    uneven = any(len(a) > 1 and len(b) != len(a) for a, b in ((hf.x, inner.x), (hf.z, inner.z)))
    grid = (f"the model's uneven grid on a common step ({len(inner.x)} x {len(inner.z)} nodes: each model point "
            "a node, each node on footopt's bilinear ground)" if uneven else "on the model's own regular grid")
    return [
        f"Ground: scene.heightfield ({shape}) as the MuJoCo hfield '{HFIELD_NAME}',",
        f"{grid}; heights normalised to [0, 1] x elevation {_f(hi - lo)} m above y = {_f(lo)} m.",
        "The geom's quat turns MuJoCo's z (the elevation) onto footopt's y (up); its rows run along -z.",
        f"MuJoCo keeps the heights as float32 (within {_f((hi - lo) * HFIELD_ROUNDING)} m at the nodes) and splits "
        "each",
        f"cell into two triangles: they leave footopt's bilinear patch by up to {_f(g.triangulation_error)} m",
        "(|twist| / 4, at the centre of the most twisted cell)."
        + (f" MuJoCo's evenly spaced nodes sit up to {_f(g.node_shift)} m from the model's rounded points."
           if g.node_shift > 0 else ""),
        "Beyond the grid a flat skirt (footopt's flat",
        "extension, the edge's heights: exact in triangles) out to the rods' total length beyond the grid and the",
        f"contacts (at most {HFIELD_SKIRT_MAX_CELLS} cells a side): {len(g.x)} x {len(g.z)} nodes, x in "
        f"[{_f(g.x[0])}, {_f(g.x[-1])}], z in [{_f(g.z[0])}, {_f(g.z[-1])}] m; beyond that MuJoCo has no ground.",
    ]


def _text(root: ET.Element, declaration: bool) -> str:
    ET.indent(root, space="  ")
    head = '<?xml version="1.0" encoding="utf-8"?>\n' if declaration else ""
    return head + ET.tostring(root, encoding="unicode") + "\n"


def _xml_safe(text: str) -> str:
    return _NOT_XML.sub("_", text)


def _f(x: float) -> str:
    return repr(float(x))


def _xyz(values) -> str:
    return " ".join(_f(v) for v in values)


__all__ = [
    "GRAVITY",
    "HFIELD_NAME",
    "HFIELD_SKIRT_MAX_CELLS",
    "INERTIA_FLOOR",
    "RegularHeightfield",
    "dynamics_inertia",
    "ExportFormat",
    "base_pose",
    "check_inertias",
    "check_names",
    "contact_frame_name",
    "export_text",
    "ground_cover",
    "mjcf_ground",
    "quaternion_of",
    "regular_heightfield",
    "stop_parameters",
    "rpy_of",
    "to_mjcf",
    "to_urdf",
]
