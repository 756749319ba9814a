"""The same tree, terrain and compliant contacts built in MuJoCo (an independent simulator), for
the agreement tests and the fidelity study. Needs ``mujoco`` (a test dependency), imported lazily.

Conventions. MuJoCo's world is ours: x forward, y up, rotations about z. The base body sits at the
world origin with slide-x, slide-y and hinge-z joints, so ``qvel`` of the base is our base
velocity (origin velocity in the world frame, angular velocity); each other body sits at
``at * parent length`` on its parent's x axis with a hinge about z (or welded at its angle for a
fixed joint), with the rod's mass, centre of mass and inertia set by ``<inertial>`` (geoms carry
no mass). Each contact point is the centre of a small massless sphere (radius ``radius``); the
terrain (a plane, or one box per segment) is lowered by that radius along its normal, so that
MuJoCo's contact distance is our signed gap. Contacts are frictionless (``condim=1``).

Contact softness. MuJoCo's contact is a soft constraint: with direct parameters
``solref = (-k, -b)`` and a constant impedance ``solimp = (d, d, ...)`` each contact's gap follows
g'' = -k g - b g' while it pushes (k in 1/s^2: mass-normalised), and the force is released, not
reversed, when that would pull. This is :attr:`ContactLaw.CONSTRAINT`. For the
:attr:`ContactLaw.PENALTY` law (force-level pads, k in N/m) each contact gets its own
``solref = (-k A_ii, -c_i A_ii)``, with A_ii the inverse effective mass at touchdown: the same
per-contact oscillator, exact for one contact in the stiff limit; with several contacts MuJoCo
still couples them through its constraint-space solve, so the two laws differ by that coupling.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from impulse_core.kinematics.spatial import dof_layout
from impulse_core.model import heightfield as hfield
from impulse_core.model.heightfield import Heightfield
from impulse_core.model.joints import JointLaw
from impulse_core.model.rods import centre_of_mass, children, contact_point, inertia_tensor, joint_origin
from impulse_core.model.terrain import Terrain
from impulse_core.model.tree import JointKind, Scene, Tree
from impulse_core.timedomain.compliant import (
    CompliantSettings,
    ContactLaw,
    damping_ratio_for_restitution,
    scene_ground,
    TOUCHDOWN_CLEARANCE,
    touchdown_configuration,
    touchdown_evaluator,
)

#: Radius of the contact spheres (m); the terrain is offset by it, so it does not enter the gap.
CONTACT_RADIUS = 1e-3
#: Half thickness of the terrain boxes (m).
BOX_HALF_THICKNESS = 0.5
#: How far the flat ends of a terrain extend beyond its first and last breakpoints (m).
FLAT_EXTENT = 20.0


def _f(x: float) -> str:
    return repr(float(x))


def _v(x: np.ndarray) -> str:
    return " ".join(_f(v) for v in x)


def contact_parameters(
    tree: Tree,
    scene: Scene,
    settings: CompliantSettings,
    terrain: Terrain | None = None,
    base_x: float | None = None,
    effective_mass: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's direct (stiffness 1/s^2, damping 1/s) per contact matching ``settings``.
    ``terrain`` and ``base_x`` override the scene's own.

    For the penalty law, ``effective_mass`` (kg per contact; e.g. ``CompliantResult.
    effective_mass``, each contact's at its own touchdown) turns N/m into 1/s^2; default: at the
    first touchdown.
    """
    zeta = (
        damping_ratio_for_restitution(scene.restitution) if settings.damping_ratio is None else settings.damping_ratio
    )
    n = len(tree.contacts)
    if settings.law is ContactLaw.CONSTRAINT:
        return np.full(n, settings.stiffness), np.full(n, 2.0 * zeta * math.sqrt(settings.stiffness))
    if effective_mass is None:  # the rung's own step function (centres of mass off the rods too)
        evaluate_step, q = touchdown_evaluator(tree, scene, 0.0, terrain, base_x)
        s = evaluate_step(q, np.zeros(len(q)))
        effective_mass = 1.0 / np.diag(s.Jn @ s.minv_jnt)
    a = 1.0 / np.asarray(effective_mass, dtype=float)
    c = 2.0 * zeta * np.sqrt(settings.stiffness / a)
    return settings.stiffness * a, c * a


def _terrain_geoms(terrain: Terrain, radius: float, contact_attrs: str) -> list[str]:
    if terrain.is_flat:
        y = terrain.y[0] - radius
        return [f'<geom name="ground" type="plane" size="0 0 1" pos="0 {_f(y)} 0" zaxis="0 1 0" {contact_attrs}/>']
    pts = list(terrain.points)
    pieces = [((pts[0][0] - FLAT_EXTENT, pts[0][1]), pts[0])]
    pieces += list(itertools.pairwise(pts))
    pieces += [(pts[-1], (pts[-1][0] + FLAT_EXTENT, pts[-1][1]))]
    geoms = []
    for i, ((x0, y0), (x1, y1)) in enumerate(pieces):
        dx, dy = x1 - x0, y1 - y0
        length = math.hypot(dx, dy)
        nx, ny = -dy / length, dx / length
        depth = BOX_HALF_THICKNESS + radius
        cx, cy = 0.5 * (x0 + x1) - nx * depth, 0.5 * (y0 + y1) - ny * depth
        geoms.append(
            f'<geom name="ground{i}" type="box" size="{_f(0.5 * length)} {_f(BOX_HALF_THICKNESS)} 1" '
            f'pos="{_f(cx)} {_f(cy)} 0" axisangle="0 0 1 {_f(math.atan2(dy, dx))}" {contact_attrs}/>'
        )
    return geoms


def build_mjcf(
    tree: Tree,
    terrain: Terrain,
    timestep: float,
    stiffness: np.ndarray,
    damping: np.ndarray,
    gravity: float = 0.0,
    impedance: float = 0.9999,
    radius: float = CONTACT_RADIUS,
    friction: float = 0.0,
) -> str:
    """The MJCF text of ``tree`` over ``terrain`` with per-contact direct contact parameters;
    with ``friction`` > 0, Coulomb friction on MuJoCo's elliptic cones (condim 3), else
    frictionless contacts (condim 1)."""
    solimp = f"{_f(impedance)} {_f(impedance)} 0.001 0.5 2"
    condim = f'condim="3" friction="{_f(friction)} 0 0"' if friction > 0 else 'condim="1"'
    ground = f'contype="0" conaffinity="1" {condim} solmix="0"'
    cone = "elliptic" if friction > 0 else "pyramidal"
    lines = [
        '<mujoco model="footopt">',
        '  <compiler angle="radian"/>',
        (
            f'  <option timestep="{_f(timestep)}" gravity="0 {_f(-gravity)} 0" integrator="Euler" solver="Newton" '
            f'tolerance="1e-14" iterations="200" ls_tolerance="1e-12" cone="{cone}" jacobian="dense"/>'
        ),
        "  <worldbody>",
        *[f"    {g}" for g in _terrain_geoms(terrain, radius, ground)],
    ]
    kids = children(tree)
    contact_index = {c: k for k, c in enumerate(tree.contacts)}

    def body(i: int, indent: str) -> list[str]:
        b = tree.bodies[i]
        if b.parent is None:
            head = f'{indent}<body name="{b.name}" pos="0 0 0">'
            joints = [
                f'{indent}  <joint name="base_x" type="slide" axis="1 0 0"/>',
                f'{indent}  <joint name="base_y" type="slide" axis="0 1 0"/>',
                f'{indent}  <joint name="base_rz" type="hinge" axis="0 0 1"/>',
            ]
        else:
            at = _v(joint_origin(tree, i))
            if b.joint is JointKind.REVOLUTE:
                head = f'{indent}<body name="{b.name}" pos="{at}">'
                joints = [f'{indent}  <joint name="{b.name}" type="hinge" axis="0 0 1"/>']
            else:
                head = f'{indent}<body name="{b.name}" pos="{at}" axisangle="0 0 1 {_f(b.angle)}">'
                joints = []
        out = [
            head,
            *joints,
            (
                f'{indent}  <inertial pos="{_v(centre_of_mass(b))}" mass="{_f(b.mass)}" '
                f'diaginertia="{_v(np.diag(inertia_tensor(b, floor=1e-12)))}"/>'
            ),
        ]
        for k in range(len(b.contacts)):
            j = contact_index[(i, k)]
            out.append(
                f'{indent}  <geom name="contact{j}" type="sphere" size="{_f(radius)}" pos="{_v(contact_point(b, k))}" '
                f'contype="1" conaffinity="0" {condim} solmix="1" mass="0" '
                f'solref="{_f(-stiffness[j])} {_f(-damping[j])}" solimp="{solimp}"/>'
            )
        for child in kids[i]:
            out += body(child, indent + "  ")
        out.append(f"{indent}</body>")
        return out

    lines += body(0, "    ")
    lines += ["  </worldbody>", "</mujoco>"]
    return "\n".join(lines)


def exported_for_drop(
    mjcf: str,
    tree: Tree,
    terrain: Terrain,
    timestep: float,
    stiffness: np.ndarray,
    damping: np.ndarray,
    settings: CompliantSettings,
    friction: float = 0.0,
) -> str:
    """An exported MJCF (``optimizer.results.export.to_mjcf``) made droppable: the bridge's
    integration options, its ground (flat only) and, at each contact site, the bridge's contact
    sphere ``contact<j>`` with the contact's direct solref; nothing else of the file changes."""
    import xml.etree.ElementTree as ET

    if not terrain.is_flat:
        raise ValueError("exported_for_drop: the exported MJCF is dropped on flat ground only")
    reference = ET.fromstring(build_mjcf(tree, terrain, timestep, stiffness, damping, settings.gravity,
                                         settings.impedance, friction=friction))
    root = ET.fromstring(mjcf)
    root.find("option").attrib.update(reference.find("option").attrib)
    world = root.find("worldbody")
    world.insert(0, reference.find("worldbody/geom[@name='ground']"))
    spheres = {g.get("name"): g for g in reference.iter("geom") if (g.get("name") or "").startswith("contact")}
    for j, (b, k) in enumerate(tree.contacts):
        site = root.find(f".//site[@name='{tree.bodies[b].name}_contact{k}']")
        body = next(e for e in root.iter("body") if site in list(e))
        body.append(spheres[f"contact{j}"])
    return ET.tostring(root, encoding="unicode")


@dataclass(frozen=True)
class MujocoDrop:
    """The same landing simulated by MuJoCo. World frame; N s, m/s, s. Contacts in declaration order.

    Attributes:
        external: time integral of each contact's normal force.
        external_vector: the same as planar vectors on the tree (n_c x 2).
        internal: joint force impulses (n_joints x 3, z = 0): MuJoCo's own joint reaction forces
            (``cfrc_int`` from ``mj_rnePostConstraint``: the force of the parent on each body)
            integrated over the steps in which a contact pushes (as the compliant rung).
        internal_magnitude: |internal| per joint.
        touchdown_time: start of the first step in which each contact had a constraint (NaN: never).
        v_plus: generalized velocity at the end, in our order (base vx, vy, omega, joints).
        loaded_at_end: a contact carries force in the final state (the impact was not over).
        timestep, n_steps: MuJoCo's integration.
        mjcf: the model text.
        touchdown_point: where each contact first touched (n_c x 3, world; the contact sphere's
            centre projected onto the ground along the contact normal; NaN: never touched).
        touchdown_normal: the ground's upward unit normal there (n_c x 3, world).
    """

    external: np.ndarray
    external_vector: np.ndarray
    internal: np.ndarray
    internal_magnitude: np.ndarray
    touchdown_time: np.ndarray
    v_plus: np.ndarray
    loaded_at_end: bool
    timestep: float
    n_steps: int
    mjcf: str
    touchdown_point: np.ndarray | None = None
    touchdown_normal: np.ndarray | None = None


def drop(
    tree: Tree,
    scene: Scene,
    settings: CompliantSettings,
    n_steps: int,
    timestep: float,
    terrain: Terrain | None = None,
    base_x: float | None = None,
    v_minus: np.ndarray | None = None,
    effective_mass: np.ndarray | None = None,
    exported: str | None = None,
) -> MujocoDrop:
    """Drop ``tree`` in MuJoCo from the touchdown configuration for ``n_steps`` steps of
    ``timestep``, integrating each contact's force (``mj_contactForce``). Pass the compliant
    rung's step and ``round(duration / timestep)`` steps, so that both integrate the same interval
    with the same semi-implicit Euler step; for a step-by-step match run the rung with
    ``flight_step=None`` (MuJoCo takes its contact step in free flight too).
    ``effective_mass``: see :func:`contact_parameters` (penalty law only). ``terrain`` and
    ``base_x`` override the scene's own. ``exported``: drop this MJCF text (``footopt export``'s,
    on the scene's flat ground) with the same contacts added (:func:`exported_for_drop`) instead
    of the bridge's own model (slides and a hinge for the base)."""
    import mujoco  # lazy: a test and study dependency only

    terrain, base_x = scene_ground(scene, terrain, base_x)

    stiffness, damping = contact_parameters(tree, scene, settings, terrain, base_x, effective_mass)
    layout = dof_layout(tree.topology())
    if v_minus is None:
        v0 = np.zeros(layout.nv)
        v0[1] = -scene.speed
    else:
        v0 = np.asarray(v_minus, dtype=float)
    joints = [tree.bodies[layout.dof_body[k]].name for k in range(3, layout.nv)]
    if exported is not None:  # the exported file: a freejoint at the touchdown pose (qpos0)
        text = exported_for_drop(exported, tree, terrain, timestep, stiffness, damping, settings, scene.friction)
        m = mujoco.MjModel.from_xml_string(text)
        d = mujoco.MjData(m)
        base = m.joint(tree.bodies[0].name).dofadr[0]  # world linear velocity, then body-frame angular
        d.qpos[m.joint(tree.bodies[0].name).qposadr[0] + 1] += TOUCHDOWN_CLEARANCE  # as the compliant rung
        vadr = np.array([base, base + 1, base + 5] + [m.joint(name).dofadr[0] for name in joints])
    else:
        text = build_mjcf(
            tree, terrain, timestep, stiffness, damping, settings.gravity, settings.impedance, friction=scene.friction
        )
        m = mujoco.MjModel.from_xml_string(text)
        d = mujoco.MjData(m)
        names = ["base_x", "base_y", "base_rz"] + joints  # our DOF k -> MuJoCo joint address
        d.qpos[[m.joint(name).qposadr[0] for name in names]] = touchdown_configuration(tree, terrain, base_x)
        vadr = np.array([m.joint(name).dofadr[0] for name in names])
    d.qvel[vadr] = v0
    geom_contact = {m.geom(f"contact{j}").id: j for j in range(len(tree.contacts))}
    body_ids = [m.body(b.name).id for b in tree.bodies]

    impulse, impulse_vec, joint_impulse, touchdown, loaded, point, normal = _integrate_drop(
        m, d, geom_contact, body_ids, n_steps, timestep, dims=2)
    joint = joint_impulse[1:]
    internal = np.column_stack([joint, np.zeros(len(joint))]) if len(joint) else np.zeros((0, 3))
    return MujocoDrop(
        external=impulse,
        external_vector=impulse_vec,
        internal=internal,
        internal_magnitude=np.linalg.norm(internal, axis=1),
        touchdown_time=touchdown,
        v_plus=np.array(d.qvel[vadr]),
        loaded_at_end=loaded,
        timestep=timestep,
        n_steps=n_steps,
        mjcf=text,
        touchdown_point=point,
        touchdown_normal=normal,
    )


def _integrate_drop(m, d, geom_contact: dict[int, int], body_ids: list[int], n_steps: int, timestep: float,
                    dims: int):  # type: ignore[no-untyped-def]
    """``n_steps`` of MuJoCo from ``d``, integrating each contact's normal impulse, its force
    vector (world axes, the first ``dims``), the joint reactions (``cfrc_int``, the force the parent
    exerts on each body) while a contact pushes, and each contact's first touch (time, the point
    under the sphere's centre on the ground, the ground's upward normal); then whether a contact
    still pushes at the end."""
    import mujoco

    nc = len(geom_contact)
    impulse, impulse_vec = np.zeros(nc), np.zeros((nc, dims))
    point, normal = np.full((nc, 3), np.nan), np.full((nc, 3), np.nan)
    joint_impulse = np.zeros((len(body_ids), dims))
    touchdown = np.full(nc, np.nan)
    f6 = np.zeros(6)
    for step in range(n_steps):
        mujoco.mj_forward(m, d)  # contacts, constraint forces and accelerations at this state
        mujoco.mj_rnePostConstraint(m, d)  # cfrc_int: MuJoCo's own joint reaction forces (RNE)
        F = np.zeros((nc, dims))
        for i in range(d.ncon):
            con = d.contact[i]
            if con.geom1 in geom_contact:
                j, sign = geom_contact[con.geom1], -1.0
            elif con.geom2 in geom_contact:
                j, sign = geom_contact[con.geom2], 1.0
            else:
                continue
            if math.isnan(touchdown[j]):
                touchdown[j] = step * timestep
                normal[j] = sign * np.array(con.frame[:3])  # geom1 -> geom2: up when the sphere is geom2
                point[j] = d.geom_xpos[con.geom1 if sign < 0 else con.geom2] - con.dist * normal[j]
            mujoco.mj_contactForce(m, d, i, f6)  # contact frame: normal, then the two tangents
            impulse[j] += timestep * f6[0]
            F[j] += sign * (f6[:3] @ np.array(con.frame).reshape(3, 3))[:dims]
        impulse_vec += timestep * F
        if np.any(F != 0.0):
            joint_impulse += timestep * np.array([d.cfrc_int[i, 3 : 3 + dims] for i in body_ids])
        mujoco.mj_Euler(m, d)  # semi-implicit Euler with these accelerations (= mj_step)
    mujoco.mj_forward(m, d)
    loaded = False
    for i in range(d.ncon):
        mujoco.mj_contactForce(m, d, i, f6)
        loaded = loaded or f6[0] > 0.0
    return impulse, impulse_vec, joint_impulse, touchdown, loaded, point, normal


def tangent_planes(mjcf: str, ground: Heightfield, points: np.ndarray, radius: float = CONTACT_RADIUS) -> str:
    """A droppable MJCF (:func:`exported_for_drop`) whose flat ground is replaced by one plane
    per contact: the heightfield's tangent plane at the ground point below the contact's
    touchdown position ``points`` (n_c x 3, world, m; normal as ``heightfield.normal``), lowered
    by ``radius`` along its normal, that contact's sphere colliding with its own plane only (an
    explicit ``<contact><pair>`` with the sphere's solref, solimp, condim and friction).

    Why planes and not a MuJoCo ``hfield``: MuJoCo splits each grid cell into two triangles, which
    differ from footopt's bilinear patch inside a twisted cell by up to |twist| / 4 (3.75 mm on
    configs/spatial_heightfield.yaml's rising cell), and collides spheres with the triangles'
    prisms. A first impact needs only the ground's height and normal at each touching contact,
    which the tangent plane carries exactly; a contact slides ~|v_t| x the impact window (about
    1 mm) over it, where the plane departs from the patch at second order (curvature x 1e-6 m^2).
    """
    import xml.etree.ElementTree as ET

    root = ET.fromstring(mjcf)
    world = root.find("worldbody")
    flat = world.find("geom[@name='ground']")
    world.remove(flat)
    P = np.atleast_2d(np.asarray(points, dtype=float))
    x, z = P[:, 0], P[:, 2]
    on_ground = np.column_stack([x, hfield.height(ground, x, z), z])
    n = hfield.normal(ground, x, z)
    pairs = ET.SubElement(root, "contact")
    for j in range(len(P)):
        sphere = root.find(f".//geom[@name='contact{j}']")
        sphere.set("contype", "0")  # only its pair collides
        ET.SubElement(world, "geom", name=f"ground{j}", type="plane", size="0 0 1",
                      pos=_v(on_ground[j] - radius * n[j]), zaxis=_v(n[j]), contype="0", conaffinity="0")
        mu = float((sphere.get("friction") or "0").split()[0]) if sphere.get("condim") == "3" else 0.0
        attrs = {k: sphere.get(k) for k in ("condim", "solref", "solimp")}
        if mu > 0:
            attrs["friction"] = f"{_f(mu)} {_f(mu)} 0 0 0"
        ET.SubElement(pairs, "pair", geom1=f"contact{j}", geom2=f"ground{j}", **attrs)
    return ET.tostring(root, encoding="unicode")


def drop_spatial(
    tree: Tree,
    scene: Scene,
    settings: CompliantSettings,
    n_steps: int,
    timestep: float,
    effective_mass: np.ndarray | None = None,
    joints: tuple[JointLaw, ...] = (),
) -> MujocoDrop:
    """A spatial model (``model.space: spatial``) dropped in MuJoCo, as :func:`drop` drops a planar
    one: ``footopt export``'s MJCF (a freejoint base, hinges about each rod's own axis) with the
    bridge's contact spheres and ground (:func:`exported_for_drop`; with ``scene.friction`` > 0
    Coulomb friction on elliptic cones, condim 3), the base origin at the scene's touchdown
    position (``base_x``, ``base_z``, lowered onto the ground), the scene's approach (``qvel``: the
    base origin's world velocity, the angular velocity in the base frame), ``n_steps``
    semi-implicit Euler steps of ``timestep``. On a ``scene.heightfield`` that is not flat each
    contact lands on the heightfield's tangent plane below its touchdown position
    (:func:`tangent_planes`, which says why). Impulse vectors and joint impulses are 3D (world
    frame); ``v_plus`` is in our order (base origin velocity, world angular velocity, joint
    rates). ``effective_mass``: the penalty law's (:func:`contact_parameters`; required for it:
    the planar default does not apply). ``joints``: joint laws the exported file carries (its
    stops tuned for ``timestep``).
    """
    import mujoco  # lazy: a test and study dependency only

    from impulse_core.evaluate import pre_impact_velocity, touchdown_geometry
    from impulse_core.kinematics.spatial import SPATIAL
    from impulse_core.model.rods import body_rotation
    from impulse_core.model.terrain import FLAT, flat
    from impulse_core.timedomain.compliant import landing_ground
    from optimizer.results.export import to_mjcf

    if settings.law is ContactLaw.PENALTY and effective_mass is None:
        raise ValueError("drop_spatial: the penalty law needs each contact's effective mass")
    ground, base_x, base_z = landing_ground(scene, None, None, SPATIAL)  # a heightfield in space
    q0 = touchdown_configuration(tree, ground, base_x, space=SPATIAL, base_z=base_z)  # clearance as the rung
    stiffness, damping = contact_parameters(tree, scene, settings, FLAT, 0.0, effective_mass)
    exported = to_mjcf(tree, scene, joints=joints, space=SPATIAL, stop_timestep=timestep, ground=False)
    text = exported_for_drop(exported, tree, flat(ground.level), timestep, stiffness, damping, settings,
                             scene.friction)  # the flat ground, replaced by tangent planes below if uneven
    if not ground.is_flat:
        text = tangent_planes(text, ground, touchdown_geometry(tree, SPATIAL).contacts + q0[:3])
    m = mujoco.MjModel.from_xml_string(text)
    d = mujoco.MjData(m)
    free = m.joint(tree.bodies[0].name)
    d.qpos[free.qposadr[0] : free.qposadr[0] + 3] = q0[:3]  # the touchdown orientation stays qpos0's
    layout = dof_layout(tree.topology(), SPATIAL)
    v0 = pre_impact_velocity(tree.topology(), scene, SPATIAL)
    R = body_rotation(tree.bodies[0])  # the base frame at touchdown, in the world
    base = free.dofadr[0]
    joints = [m.joint(tree.bodies[layout.dof_body[k]].name).dofadr[0] for k in range(6, layout.nv)]
    d.qvel[base : base + 3] = v0[:3]
    d.qvel[base + 3 : base + 6] = R.T @ v0[3:6]
    d.qvel[joints] = v0[6:]
    geom_contact = {m.geom(f"contact{j}").id: j for j in range(len(tree.contacts))}
    body_ids = [m.body(b.name).id for b in tree.bodies]
    impulse, impulse_vec, joint_impulse, touchdown, loaded, point, normal = _integrate_drop(
        m, d, geom_contact, body_ids, n_steps, timestep, dims=3)
    body_rot = np.array(d.xmat[m.body(tree.bodies[0].name).id]).reshape(3, 3)
    v_plus = np.concatenate([d.qvel[base : base + 3], body_rot @ d.qvel[base + 3 : base + 6], d.qvel[joints]])
    internal = joint_impulse[1:]
    return MujocoDrop(
        external=impulse,
        external_vector=impulse_vec,
        internal=internal,
        internal_magnitude=np.linalg.norm(internal, axis=1),
        touchdown_time=touchdown,
        v_plus=v_plus,
        loaded_at_end=loaded,
        timestep=timestep,
        n_steps=n_steps,
        mjcf=text,
        touchdown_point=point,
        touchdown_normal=normal,
    )


__all__ = ["CONTACT_RADIUS", "MujocoDrop", "build_mjcf", "contact_parameters", "drop", "drop_spatial", "tangent_planes"]
