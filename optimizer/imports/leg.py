"""The leg between two links of a description, as footopt rods (``footopt import``).

The chain: the links from ``root`` down to ``ankle``. Fixed joints are merged into their parent
(their links' mass properties added, about the merged centre of mass); each revolute joint on the
chain starts a rod; any other kind of joint on the chain is refused. Links hanging off the chain
by a fixed joint are merged too; those hanging by a moving joint (other legs, a foot beyond the
ankle) are left out, and the report names them. The root is the floating base.

Each rod runs from its joint (the base: from the root link's origin) to the next joint on the
chain; the last one to the ankle: the ankle link's origin, or the ``foot`` point when given (a
link welded to the ankle, or an MJCF site or geom on it). The contact is at its tip. The touchdown
posture is the pose the file places its links in (URDF: every joint at 0; MJCF: at ``ref``) or
``--angle``'s, with the root's frame as the world's; the joints' stops, dampers and springs come
along (:mod:`optimizer.imports.laws`).

What a rod carries (docs/MODEL_FORMAT.md, "Import"): mass exactly. Spatial: everything exactly:
the centre of mass as its projection on the rod (``com``) and the rest (``com_offset``), the link's
whole inertia tensor about it in the rod's axes (``inertia_tensor``); where the projection falls
behind a rod's start, the start slides along its joint's axis (the same line: the same motion; the
base's start moves back along its rod), and past its next joint, the rod reaches beyond it (the
child at ``at`` < 1, the contact at < 1). Planar: the same in the plane (``com``, ``com_offset``
[dy, 0], the inertia about the joint axis through the centre of mass; a centre of mass behind a
joint other than the base's is moved onto it, reported); ``com_on_rods`` (``--com-on-rods``) moves
each centre of mass to the nearest point of its rod instead, the inertia about the joint axis taken
about that point (parallel axes). The joints' axes and placement (on their axes) are exact.

Planar (every revolute axis of the chain parallel, the default then): the plane is normal to the
axes, which become footopt's z; offsets along the axis drop out (planar motion does not see them);
a joint whose axis points along -z has its angle counted the other way. Spatial: the description's
frame (x forward, y left, z up, as URDF and MJCF use) is turned onto footopt's (x forward, y up,
z lateral): x -> x, z -> y, y -> -z.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from impulse_core.kinematics.spatial import PLANAR, SPATIAL, Space
from impulse_core.model.tree import Body, JointKind, Scene, Tree, tensor_problem
from optimizer.config.model_file import ModelFile
from optimizer.errors import ConfigError
from optimizer.imports.description import FIXED, REVOLUTE, Description
from optimizer.imports.laws import footopt_angle, imported_laws, laws_summary
from impulse_core.model.rods import rpy_of

#: footopt's world from the description's (rows: footopt's x, y, z in the description's axes).
TO_FOOTOPT = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
#: Joint axes within this angle (rad) count as parallel (a planar chain).
PARALLEL = 1e-6
#: A rod shorter than this (m) has no direction.
SHORTEST = 1e-9
#: The placeholder landing of an imported leg (edit it): 1 m/s straight down, plastic, frictionless.
IMPORT_SCENE = Scene(speed=1.0, restitution=0.0, friction=0.0)


@dataclass(frozen=True)
class Segment:
    """One rod of the chain in the description's world frame at the zero configuration."""

    name: str  # the link that owns the rod's frame
    merged: tuple[str, ...]  # links welded into it (itself first)
    joint: str | None  # the revolute joint above it (None: the base)
    mass: float
    com: np.ndarray  # world
    inertia: np.ndarray  # about com, world axes
    start: np.ndarray  # world: the joint (base: the root link's origin)
    tip: np.ndarray  # world: the next joint, or the ankle
    axis: np.ndarray | None  # world, unit (None: the base)


@dataclass(frozen=True)
class Rod:
    """What one rod of the model file loses against its segment."""

    name: str
    merged: tuple[str, ...]
    com_offset: float  # m: distance of the centre of mass from the rod's axis (carried; --com-on-rods: dropped)
    com_clamped: bool  # planar: the centre of mass lay beyond an end of the rod (moved onto it)
    inertia_residual: float  # relative Frobenius norm of the inertia tensor's part not carried (spatial: 0)
    flipped: bool = False  # planar: the joint turns about -z (its angle counted the other way)
    slide: float = 0.0  # m the rod's start moved along its joint axis (the base: along its rod)
    carried: bool = False  # the centre of mass is carried (com_offset; spatial: and the whole tensor)


@dataclass(frozen=True)
class ImportedLeg:
    """A leg read from a description: the model file, per rod what it loses, what was left out."""

    model: ModelFile
    segments: tuple[Segment, ...]
    rods: tuple[Rod, ...]
    dropped: tuple[tuple[str, float], ...]  # (link hanging off the chain by a moving joint, its subtree's mass)
    source: Description
    root: str
    ankle: str
    foot: str | None
    reason: str  # why planar or spatial
    angles: tuple[tuple[str, float], ...] = ()  # the touchdown posture's joint angles (rad), as given
    joint_laws: bool = True  # the description's stops, dampers and springs imported (False: --no-joint-laws)
    warnings: tuple[str, ...] = ()  # one line each: what the model file cannot carry (laws left out)
    com_on_rods: bool = False  # planar: each centre of mass moved onto its rod (--com-on-rods)

    @property
    def space(self) -> Space:
        return self.model.space

    def summary(self) -> str:
        """What was imported and every approximation, one line each (the file's header too)."""
        d = self.source
        lines = [
            f"footopt import of {d.path.name} ({d.format}): the leg from '{self.root}' to '{self.ankle}'"
            + (f", foot point '{self.foot}'" if self.foot else "") + f": {len(self.rods)} rods, {self.space.name}"
            f" ({self.reason}).",
            "Touchdown posture: the description's pose as the file places it"
            + "".join(f", {n} = {v:.6g} rad" for n, v in self.angles) + "; the root link's frame as the world's;",
            "the scene (1 m/s straight down, restitution 0, frictionless) is a placeholder: edit it.",
            f"Contact: the tip of '{self.rods[-1].name}' (the ankle). Total mass {sum(s.mass for s in self.segments):.6g} kg.",
        ]
        for r, s in zip(self.rods, self.segments, strict=True):
            welded = f" (merged: {', '.join(r.merged[1:])})" if len(r.merged) > 1 else ""
            joint = "base" if s.joint is None else f"joint '{s.joint}'"
            if r.carried:
                lines.append(
                    f"  {r.name}: {joint}, {s.mass:.6g} kg{welded}; centre of mass "
                    + (f"{1000 * r.com_offset:.3g} mm off the rod's axis (com_offset)" if r.com_offset > 1e-12
                       else "on the rod's axis")
                    + (", inertia_tensor" if self.space is SPATIAL else "")
                    + ("; moved onto its joint (behind it: a planar rod starts at its joint)" if r.com_clamped else "")
                    + ("; its joint turns about -z (the description's angle is minus footopt's)" if r.flipped else "")
                    + (f"; its start {1000 * r.slide:.3g} mm "
                       + ("back along the rod" if s.joint is None else "along its joint axis")
                       + " (so the centre of mass projects onto the rod)" if r.slide > 0 else "")
                )
                continue
            lines.append(
                f"  {r.name}: {joint}, {s.mass:.6g} kg{welded}; "
                + (f"centre of mass {1000 * r.com_offset:.3g} mm off the rod's axis (moved onto it"
                   + (", past an end of the rod" if r.com_clamped else "") + ")"
                   if r.com_offset > 1e-12 else "centre of mass on the rod's axis")
                + ("; its joint turns about -z (the description's angle is minus footopt's)" if r.flipped else "")
            )
        if self.dropped:
            lines.append("Left out (hanging off the chain by a moving joint): "
                         + ", ".join(f"{n} ({m:.6g} kg with its subtree)" for n, m in self.dropped) + ".")
        if self.space is PLANAR and self.com_on_rods:
            lines.append("Exact: masses, joint placements and axes, the ankle; approximated as above (--com-on-rods): each")
            lines.append("rod carries its centre of mass on its axis and the inertia about the joint axis through it "
                         "(exact about that point).")
        elif self.space is PLANAR:
            lines.append("Exact: masses, centres of mass in the plane (com, com_offset), inertias about the joint axes,")
            lines.append("joint placements and axes, the ankle" + (" (except where said above)." if any(
                r.com_clamped for r in self.rods) else "."))
        else:
            lines.append("Exact: masses, centres of mass (com, com_offset), inertia tensors (inertia_tensor), joint axes")
            lines.append("and placements (a joint's point anywhere on its axis), the ankle.")
        names = [s.joint for s in self.segments[1:]]
        return "\n".join(lines + laws_summary(d.format, names, self.model.joints, self.joint_laws, self.warnings))


def import_leg(
    desc: Description,
    root: str,
    ankle: str,
    foot: str | None = None,
    space: str = "auto",
    angles: dict[str, float] | None = None,
    joint_laws: bool = True,
    com_on_rods: bool = False,
) -> ImportedLeg:
    """The leg from ``root`` to ``ankle`` of ``desc`` as a model file (see the module docstring),
    at the touchdown posture ``angles`` (joint name -> rad, as the description counts them;
    joints not named at the file's pose), with the joints' stops, dampers and springs unless
    ``joint_laws`` is False (:mod:`optimizer.imports.laws`).

    Raises:
        ConfigError: naming the option (``--root``, ``--ankle``, ``--foot``, ``--space``,
            ``--angle``) or the link or joint that cannot be imported.
    """
    for option, name in (("--root", root), ("--ankle", ankle)):
        if name not in desc.links:
            raise desc.error(option, f"no link named '{name}' in the file ({_some(desc.links)})")
    path = _path(desc, root, ankle)
    groups = _groups(desc, root, path)
    segments, dropped = _segments(desc, groups, path, ankle, foot)
    axes = [s.axis for s in segments if s.axis is not None]
    parallel = all(np.linalg.norm(np.cross(axes[0], a)) <= PARALLEL for a in axes)
    if space == "planar" and not parallel:
        raise desc.error("--space", "planar needs every revolute joint axis of the chain parallel; these are not")
    planar = space == "planar" or (space == "auto" and parallel)
    reason = ("every joint axis parallel" if parallel else "joint axes not parallel") if space == "auto" else "--space"
    tree, rods = _planar_tree(desc, segments, com_on_rods) if planar else _spatial_tree(desc, segments)
    posed = _posed(desc, tree, segments, rods, angles or {})
    laws, warnings = (), ()
    if joint_laws:
        chain = [desc.joints[s.name] for s in segments[1:]]
        laws, warnings = imported_laws(desc, chain, [r.flipped for r in rods], tree, angles or {})
    model = ModelFile(tree=posed, scene=IMPORT_SCENE, space=PLANAR if planar else SPATIAL, joints=laws)
    return ImportedLeg(model, tuple(segments), tuple(rods), tuple(dropped), desc, root, ankle, foot, reason,
                       tuple((angles or {}).items()), joint_laws, warnings, com_on_rods)


def _posed(desc: Description, tree: Tree, segments: list[Segment], rods: list[Rod], angles: dict[str, float]) -> Tree:
    """``tree`` with each named joint at its angle, as the description counts it (laws.footopt_angle)."""
    joints = {s.joint: k for k, s in enumerate(segments) if s.joint is not None}
    bodies = list(tree.bodies)
    for name, value in angles.items():
        if name not in joints:
            raise desc.error("--angle", f"no joint named '{name}' on the chain (joints: {', '.join(joints)})")
        k = joints[name]
        dynamics = desc.joints[segments[k].name].dynamics
        bodies[k] = replace(bodies[k], angle=footopt_angle(bodies[k].angle, rods[k].flipped, dynamics, value))
    return Tree(tuple(bodies))


def _some(names) -> str:
    names = list(names)
    return "links: " + ", ".join(names[:12]) + (f", ... ({len(names)} in all)" if len(names) > 12 else "")


def _path(desc: Description, root: str, ankle: str) -> list[str]:
    """The links from root to ankle, both included."""
    path = [ankle]
    while path[-1] != root:
        joint = desc.joints.get(path[-1])
        if joint is None:
            raise desc.error("--ankle", f"'{ankle}' does not hang below '{root}' (--root): the chain is not connected")
        path.append(joint.parent)
    return path[::-1]


def _groups(desc: Description, root: str, path: list[str]) -> list[list[str]]:
    """The chain's links grouped into rods: a revolute joint starts a new group."""
    groups = [[root]]
    for link in path[1:]:
        j = desc.joints[link]
        if j.kind == REVOLUTE:
            groups.append([link])
        elif j.kind == FIXED:
            groups[-1].append(link)
        else:
            raise desc.error(f"joint '{j.name}'", f"is {j.kind} (from '{j.parent}' to '{j.child}'): footopt imports "
                             "revolute and fixed joints only")
    if len(groups) < 2:
        raise desc.error("--ankle", f"no revolute joint between '{path[0]}' (--root) and '{path[-1]}': nothing turns")
    return groups


def _subtree_mass(desc: Description, link: str) -> float:
    return desc.links[link].mass + sum(_subtree_mass(desc, j.child) for j in desc.children(link))


def _segments(desc, groups, path, ankle, foot):
    """Each group's rigid body (its owner's frame, every link welded to it) as a Segment in the
    world frame, the links left out, and the rods' tips."""
    dropped: list[tuple[str, float]] = []
    world: dict[str, tuple[np.ndarray, np.ndarray]] = {}  # link -> (origin, rotation) in the world, zero configuration
    bodies = []
    for k, group in enumerate(groups):
        owner = group[0]
        top = owner
        if k == 0:
            world[owner] = (np.zeros(3), np.eye(3))
            while top in desc.joints and desc.joints[top].kind == FIXED:  # links the root is welded to
                j = desc.joints[top]
                p, R = world[top]
                world[j.parent] = (p - R @ j.rotation.T @ j.origin, R @ j.rotation.T)
                top = j.parent
        else:
            j = desc.joints[owner]
            p, R = world[j.parent]
            world[owner] = (p + R @ j.origin, R @ j.rotation)
        # every link welded to the owner, depth first; moving children off the chain are left out
        members, stack = [], [top]
        next_start = groups[k + 1][0] if k + 1 < len(groups) else None
        while stack:
            link = stack.pop()
            members.append(link)
            for j in desc.children(link):
                if j.child == next_start:
                    continue
                if j.kind == FIXED:
                    if j.child not in world:  # (the root and the links above it are placed already)
                        p, R = world[link]
                        world[j.child] = (p + R @ j.origin, R @ j.rotation)
                    stack.append(j.child)
                else:
                    dropped.append((j.child, _subtree_mass(desc, j.child)))
        members.remove(owner)
        bodies.append((owner, [owner, *members]))
    segments = []
    for k, (owner, members) in enumerate(bodies):
        mass = sum(desc.links[n].mass for n in members)
        if mass <= 0:
            raise desc.error(f"link '{owner}'", f"has no mass (with {', '.join(members[1:]) or 'nothing'} welded to "
                             "it): a footopt rod needs mass > 0")
        coms = [world[n][0] + world[n][1] @ desc.links[n].com for n in members]
        com = sum(desc.links[n].mass * c for n, c in zip(members, coms, strict=True)) / mass
        inertia = np.zeros((3, 3))
        for n, c in zip(members, coms, strict=True):
            R, link = world[n][1], desc.links[n]
            r = c - com
            inertia += R @ link.inertia @ R.T + link.mass * (r @ r * np.eye(3) - np.outer(r, r))
        if k + 1 < len(bodies):
            tip = world[bodies[k + 1][0]][0]
        else:
            tip = _ankle_point(desc, ankle, foot, members, world)
        start = world[owner][0]
        joint = None if k == 0 else desc.joints[owner]
        if k == 0 and np.linalg.norm(tip - start) < SHORTEST:
            start = com  # the root's origin is the first joint: the base rod starts at its centre of mass
        if np.linalg.norm(tip - start) < SHORTEST:
            where = "--ankle" if k + 1 == len(bodies) else f"link '{owner}'"
            hint = (" name the foot point with --foot (a link welded to it, or an MJCF site or geom)"
                    if k + 1 == len(bodies) else " the next joint sits at its own joint")
            raise desc.error(where, f"the rod of '{owner}' would have no length:{hint}")
        axis = None if joint is None else world[owner][1] @ joint.axis
        segments.append(Segment(owner, tuple(members), None if joint is None else joint.name, mass, com, inertia,
                                start, tip, axis))
    return segments, dropped


def _ankle_point(desc, ankle, foot, members, world) -> np.ndarray:
    """The last rod's tip: the foot point, else the ankle link's origin (world)."""
    if foot is None:
        return world[ankle][0]
    if foot in desc.links:
        if foot not in members:
            raise desc.error("--foot", f"'{foot}' is not welded to the ankle's rod ({', '.join(members)})")
        return world[foot][0]
    if foot in desc.points:
        link, p = desc.points[foot]
        if link not in members:
            raise desc.error("--foot", f"'{foot}' is on '{link}', not on the ankle's rod ({', '.join(members)})")
        return world[link][0] + world[link][1] @ p
    raise desc.error("--foot", f"no link, site or geom named '{foot}' in the file")


def _rod_points(segments: list[Segment]) -> tuple[list[np.ndarray], list[float]]:
    """Where each spatial rod starts so that its centre of mass projects onto it, and how far that
    moved it (m): a joint's point may slide along its axis (the same line, the same motion), the
    base's start anywhere (a translation of the whole leg). From the ankle up, a rod whose centre of
    mass projects behind its start has that start slid along the joint axis just past where the
    projection reaches it (the parent rod then ends there); the base's start moves back along its rod.
    A projection beyond the tip is kept by a rod longer than its joints' distance (see
    :func:`_spatial_tree`)."""
    starts = [s.start.copy() for s in segments]
    slides = [0.0] * len(segments)
    for k in reversed(range(len(segments))):
        s = segments[k]
        a, b = starts[k], starts[k + 1] if k + 1 < len(segments) else s.tip
        if float((s.com - a) @ (b - a)) >= 0.0:
            continue
        if k == 0:  # the base: its rod extended back to the centre of mass's projection
            x = (b - a) / np.linalg.norm(b - a)
            starts[0] = a + float((s.com - a) @ x) * x
        else:  # (c - a - t u).(b - a - t u) = t^2 - t u.((c - a) + (b - a)) + (c - a).(b - a), < 0 at t = 0
            u = s.axis
            p, q = float(u @ ((s.com - a) + (b - a))), float((s.com - a) @ (b - a))
            root = np.sqrt(0.25 * p * p - q)
            t = min(0.5 * p + root, 0.5 * p - root, key=abs)
            t += math.copysign(1e-3 * float(np.linalg.norm(b - a)), t)  # just past it: the projection on the rod
            starts[k] = a + t * u
        slides[k] = float(np.linalg.norm(starts[k] - s.start))
    return starts, slides


def _spatial_tree(desc: Description, segments: list[Segment]) -> tuple[Tree, list[Rod]]:
    """Each segment as a rod carrying its link's exact mass properties: ``com`` (the centre of
    mass's projection on the rod), ``com_offset`` (the rest, along the rod frame's y and z) and
    ``inertia_tensor`` (the link's, about its centre of mass, in the rod's axes)."""
    starts, slides = _rod_points(segments)
    segments[0] = replace(segments[0], start=starts[0])  # the base rod's start (the base origin)
    bodies, rods, frames, reach = [], [], [], []
    for k, s in enumerate(segments):
        a = starts[k]
        b = starts[k + 1] if k + 1 < len(segments) else s.tip
        span = float(np.linalg.norm(b - a))  # to the next joint (or the ankle)
        x = (b - a) / span
        along = float((s.com - a) @ x)
        length = max(span, along)  # a centre of mass beyond the next joint: the rod reaches past it
        reach.append(span / length)
        ref = s.axis if s.axis is not None else segments[1].axis
        z = ref - (ref @ x) * x
        if np.linalg.norm(z) < 1e-9:  # the axis along the rod: any frame across it
            e = np.eye(3)[int(np.argmin(np.abs(x)))]
            z = e - (e @ x) * x
        z /= np.linalg.norm(z)
        S_world = np.column_stack([x, np.cross(z, x), z])  # rod frame in the description's world
        S = TO_FOOTOPT @ S_world  # in footopt's world
        f = min(max(along / length, 0.0), 1.0)
        r = S_world.T @ (s.com - a - f * length * x)  # the centre of mass from its point on the rod, rod axes
        J = S_world.T @ s.inertia @ S_world  # about the centre of mass, rod axes
        J = 0.5 * (J + J.T)
        tensor = _clean(np.array([J[0, 0], J[1, 1], J[2, 2], J[0, 1], J[0, 2], J[1, 2]]), 1e-15 * float(np.trace(J)))
        if k == 0:
            rpy, axis, parent, at = rpy_of(S), (0.0, 0.0, 1.0), None, 1.0
        else:
            rpy, parent, at = rpy_of(frames[-1].T @ S), k - 1, reach[k - 1]
            axis = _clean(S_world.T @ s.axis)
        frames.append(S)
        problem = tensor_problem(tensor) if any(tensor) else None
        if problem is not None:
            raise desc.error(f"link '{s.name}'", f"its inertia (with {', '.join(s.merged[1:]) or 'nothing'} welded to "
                             f"it, rod axes) {problem}")
        bodies.append(Body(
            name=s.name, parent=parent, at=at, length=length, mass=s.mass, angle=0.0, com=f, gyration=0.0,
            contacts=(reach[k],) if k + 1 == len(segments) else (), rpy=_clean(np.array(rpy)), axis=axis,
            radius=0.0, com_offset=(float(r[1]), float(r[2])), tensor=tensor, joint=JointKind.REVOLUTE,
        ))
        rods.append(Rod(s.name, s.merged, float(np.hypot(r[1], r[2])), False, 0.0, slide=slides[k],
                        carried=True))
    return Tree(tuple(bodies)), rods


def _plane(segments: list[Segment]) -> tuple[np.ndarray, np.ndarray]:
    """footopt's (x, y) rows in the description's world, and the plane's normal (footopt's z):
    normal to the joint axes, y the description's up (+z) in the plane, x kept forward."""
    n = segments[1].axis
    up = np.array([0.0, 0.0, 1.0])
    y = up - (up @ n) * n
    if np.linalg.norm(y) < 1e-9:  # the joints turn about the vertical: the plane is horizontal
        y = np.array([0.0, 1.0, 0.0]) - n[1] * n
    y /= np.linalg.norm(y)
    if np.cross(y, n)[0] < 0:  # keep the description's forward (x) forward
        n = -n
    return np.vstack([np.cross(y, n), y]), n


def _planar_base(segments: list[Segment], plane: np.ndarray, on_rods: bool) -> float:
    """Where the base rod starts: at its centre of mass when the root's origin is the first joint;
    moved back along its rod when its centre of mass projects behind it (exact mode; the base's
    start is free). Updates ``segments[0]``; returns how far it moved back (m)."""
    s = segments[0]
    a, b = plane @ s.start, plane @ s.tip
    if np.linalg.norm(b - a) < SHORTEST:  # the root's origin sits on the first joint's axis
        segments[0] = replace(s, start=s.com)
        return 0.0
    u = (b - a) / np.linalg.norm(b - a)
    behind = float((plane @ s.com - a) @ u)
    if on_rods or behind >= 0.0:
        return 0.0
    segments[0] = replace(s, start=s.start + behind * (plane.T @ u))
    return -behind


def _planar_tree(desc: Description, segments: list[Segment], on_rods: bool = False) -> tuple[Tree, list[Rod]]:
    """Each segment as a planar rod: exact (``on_rods`` False) its centre of mass in the plane as
    ``com`` and ``com_offset`` [dy, 0] and its inertia about the joint axis through it; a centre of
    mass past the next joint lengthens the rod (the child at ``at`` < 1), behind the base's start
    moves that start back. ``on_rods``: each centre of mass moved onto its rod, the inertia about
    the joint axis through that point (parallel axes). Behind a joint (not the base's) a centre of
    mass is moved onto the joint either way (a planar rod cannot start elsewhere), reported."""
    plane, n = _plane(segments)
    slide = _planar_base(segments, plane, on_rods)
    bodies, rods, angles, reach = [], [], [], [1.0]
    for k, s in enumerate(segments):
        a, b = plane @ s.start, plane @ s.tip
        span = float(np.linalg.norm(b - a))
        if span < SHORTEST:
            raise desc.error(f"link '{s.name}'", "its rod lies along the joint axes (no length in their plane): "
                             "the chain is not planar; pass --space spatial")
        u = (b - a) / span
        theta = math.atan2(u[1], u[0])
        r = plane @ s.com - a
        along, dy = float(r @ u), float(r @ np.array([-u[1], u[0]]))
        length = span if on_rods else max(span, along)
        f = min(max(along / length, 0.0), 1.0)
        moved = r - f * length * u if on_rods else (f * length - along) * u  # what is not carried
        dy = 0.0 if on_rods or abs(dy) <= 1e-15 * length else dy
        inertia = float(n @ s.inertia @ n) + s.mass * float(moved @ moved)
        reach.append(span / length)
        flipped = s.axis is not None and float(s.axis @ n) < 0
        angle = theta if k == 0 else math.remainder(theta - angles[-1], 2 * math.pi)
        angles.append(theta)
        bodies.append(Body(
            name=s.name, parent=None if k == 0 else k - 1, at=reach[k], length=length, mass=s.mass, angle=angle,
            com=f, gyration=math.sqrt(inertia / s.mass) / length, com_offset=(dy, 0.0),
            contacts=(reach[-1],) if k + 1 == len(segments) else (),
        ))
        off = float(np.linalg.norm(moved)) if on_rods else abs(dy)
        rods.append(Rod(s.name, s.merged, off, abs(f * length - along) > 1e-12, 0.0, flipped,
                        slide=slide if k == 0 else 0.0, carried=not on_rods))
    return Tree(tuple(bodies)), rods


def _clean(v: np.ndarray, below: float = 1e-15) -> tuple[float, ...]:
    """Round-off below ``below`` written as 0 (readable files; far below any tolerance)."""
    return tuple(0.0 if abs(x) < below else float(x) for x in v)


__all__ = ["IMPORT_SCENE", "TO_FOOTOPT", "ImportedLeg", "Rod", "Segment", "import_leg"]
