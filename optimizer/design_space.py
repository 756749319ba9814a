"""The parametric foot: a fixed leg, a heel chain and ``n`` toe chains, as frozen dataclasses,
mapped to the impulse core's ``Tree``; its geometry, constraints and objectives.

The leg is the paper's (:class:`Leg`): the thigh (floating base) and the shank hang from the hip
in a fixed touchdown posture; or any chain of rods read from a model file (:class:`LegChain`,
e.g. ``footopt import`` of a robot's leg, planar or spatial). At its ankle (the shank's tip, or
the chain's ankle on its last rod) hang, each by a passive revolute joint, a heel chain and ``n``
toe chains. Every chain is a serial chain of uniform rods; its last rod carries a
contact at its tip. All chain tips are meant to touch the ground at once.

Why lengths are not search variables. With uniform rods (centre of mass and joints at fixed
fractions, inertia m L^2 / 12), passive joints and a straight-down approach, scaling one rod's
length at fixed angles maps one solution of the impact equations to another (the rod's angular
velocity change scales by 1/s, its moment arms by s, its inertia by s^2): no impulse, energy or
base velocity depends on any rod length (``tests/optimizer/test_design_space.py`` checks it with
the core's exact derivatives). Lengths matter only through geometry: whether every tip lies on
the ground line, the foot's reach, the links' mass per length, clearance. Given the touchdown
angles, every one of those is *linear* in the lengths and the ankle height, so
:func:`assign_lengths` picks the lengths by a linear program: the foot that keeps every
geometric inequality furthest inside its bounds (relative margin, capped), with each tip exactly
on the ground line. The search then moves only the values that matter: joint angles and masses.
Over a whole landing (gravity, springs, later impacts) lengths do matter: a whole-landing search
also sets the toes' mean reach, which the linear program meets as one more equality.

Conventions: SI units, radians, planar, x forward, y up, angles counter-clockwise; a joint angle
is the child's angle relative to its parent (``MODEL_FORMAT.md``).

Splayed toes (a spatial foot, ``FootDesign.toe_yaws``): toe i is the same planar chain turned by
its yaw psi_i about the vertical (+y, right-handed) through the ankle: its rods stay in the
vertical plane through the ankle along (cos psi_i, 0, -sin psi_i), so a point of the chain at
(x, y) from the ankle in the plane lies at (x cos psi_i, y, -x sin psi_i). Heights are those of the
planar chain, so the same linear program levels the tips; a toe's reach is its forward (x)
distance, x cos psi_i. The heel stays in the sagittal plane (yaw 0). The model file says it by the
toe's root rod's ``rpy``: Rz(-phi_s) Ry(psi_i) Rz(phi_s), phi_s the shank's absolute angle.

A spatial leg (:class:`LegChain` in SPATIAL): the foot's chains hang in the world's vertical plane
through the ankle as above; phi_s is the angle of the last rod's direction projected on that plane
(x, y), and every chain root carries the ``rpy`` of W_R_L^T Ry(psi_i) Rz(phi_s) (W_R_L: the last
rod's frame in the world at touchdown), so that its joint angles count from phi_s as in the plane.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field, fields, replace
from enum import Enum
from itertools import accumulate
from pathlib import Path

import casadi as ca
import numpy as np

from impulse_core.evaluate import ImpactResult, approach_velocity, compiled_model, evaluate, touchdown_geometry
from impulse_core.errors import NumericalError
from impulse_core.kinematics.spatial import PLANAR, SPATIAL, Space, values_space
from impulse_core.model.support import support_margin as hull_margin
from impulse_core.model.joints import FREE, JointLaw
from impulse_core.model.rods import body_rotation, rotation_z
from impulse_core.timedomain.landing import AUTO_CODE, BALANCE_CHECK, LandingResult, LandingSettings, landing
from optimizer.config.model_file import ModelFile
from impulse_core.model.tree import (
    UNIFORM_COM,
    UNIFORM_GYRATION,
    Body,
    ContactSelection,
    Scene,
    Topology,
    Tree,
    design_vector,
)

#: A constraint value (see :class:`ConstraintValues`) up to this counts as met: room for float
#: rounding (sums of masses, the linear program's tolerance).
FEASIBILITY_TOL = 1e-9
#: The linear program keeps every geometric inequality at least this relative margin inside its
#: bound when it can (then picks the shortest foot): more would only make the foot odd.
MARGIN_CAP = 0.25
#: No rod is shorter than this (m): keeps the tree valid when the geometry is infeasible.
LENGTH_FLOOR = 1e-4
#: Names of the segments of a chain of 1, 2, 3, ... rods (proximal first).
SEGMENT_NAMES = {1: ("",), 2: ("proximal", "distal"), 3: ("proximal", "middle", "distal")}


def segment_suffixes(k: int) -> tuple[str, ...]:
    """Names of the rods of a chain of ``k`` rods, proximal first: ``SEGMENT_NAMES`` up to three,
    then ``proximal, middle1, ..., middle{k-2}, distal``."""
    if k in SEGMENT_NAMES:
        return SEGMENT_NAMES[k]
    return ("proximal", *(f"middle{j}" for j in range(1, k - 1)), "distal")


# --------------------------------------------------------------------------------------------
# Structure and values


@dataclass(frozen=True)
class Leg:
    """The fixed leg above the ankle, in its touchdown posture (the paper: 0.7 m, 1 kg rods).

    Attributes:
        thigh_length, thigh_mass: the thigh (floating base), m and kg.
        thigh_angle: absolute angle of the thigh's x axis, hip to knee (rad).
        shank_length, shank_mass: the shank, m and kg.
        knee_angle: the shank's joint angle relative to the thigh (rad).
        knee: the knee's spring, damper and stops (a whole landing; free by default).
        thigh_com, shank_com: centre of mass as a fraction of the length (default 0.5, uniform).
        thigh_gyration, shank_gyration: radius of gyration about it, as a fraction of the
            length (default a uniform rod's, 1/sqrt(12)); a leg read from a model file
            (``leg: {file: ...}``, e.g. ``footopt import``) carries its own.
        thigh_offset, shank_offset: the centre of mass's offset from the rod in the plane (m,
            the body's ``com_offset`` [dy, 0]; default 0: on the rod), as a leg file gives it.
    """

    thigh_length: float = 0.7
    thigh_mass: float = 1.0
    thigh_angle: float = -1.4
    shank_length: float = 0.7
    shank_mass: float = 1.0
    knee_angle: float = -0.3
    knee: JointLaw = FREE
    thigh_com: float = UNIFORM_COM
    thigh_gyration: float = UNIFORM_GYRATION
    shank_com: float = UNIFORM_COM
    shank_gyration: float = UNIFORM_GYRATION
    thigh_offset: float = 0.0
    shank_offset: float = 0.0

    @property
    def chain(self) -> LegChain:
        """The leg as a chain of two rods, ``thigh`` (the base) and ``shank``."""
        return LegChain(
            (Body("thigh", None, self.thigh_length, self.thigh_mass, self.thigh_angle, com=self.thigh_com,
                  gyration=self.thigh_gyration, com_offset=(self.thigh_offset, 0.0)),
             Body("shank", 0, self.shank_length, self.shank_mass, self.knee_angle, com=self.shank_com,
                  gyration=self.shank_gyration, com_offset=(self.shank_offset, 0.0))),
            (FREE, self.knee),
        )


@dataclass(frozen=True)
class LegChain:
    """A fixed leg of one or more rods in its touchdown posture, as a model file gives it
    (``leg: {file: F}``, e.g. ``footopt import`` of a robot's leg): the foot hangs at its ankle.

    Attributes:
        rods: the leg's bodies, base first, each the child of the one before (no contacts).
        joints: each rod's joint law (the base's: free); springs, dampers and stops act over a
            whole landing.
        space: PLANAR (every joint about z) or SPATIAL (each rod its ``rpy`` and ``axis``).
        ankle: where the foot hangs on the last rod, as a fraction of its length (the file's
            contact there, which ``footopt import`` puts at the ankle; 1.0: the tip).
        file: the model file it was read from (what a written study names; not compared).
    """

    rods: tuple[Body, ...]
    joints: tuple[JointLaw, ...]
    space: Space = PLANAR
    ankle: float = 1.0
    file: Path | None = field(default=None, compare=False, repr=False)

    @property
    def spatial(self) -> bool:
        return self.space is SPATIAL

    def rotations(self) -> tuple[np.ndarray, ...]:
        """Each rod's frame in the world at touchdown, W_R_k (3 x 3)."""
        out: list[np.ndarray] = []
        for b in self.rods:
            out.append(body_rotation(b) if not out else out[-1] @ body_rotation(b))
        return tuple(out)

    def directions(self) -> np.ndarray:
        """Each rod's unit direction in the world (rods x 3): in the plane (cos, sin, 0) of its
        absolute angle."""
        if not self.spatial:
            return np.array([[math.cos(phi), math.sin(phi), 0.0] for phi in accumulate(b.angle for b in self.rods)])
        return np.array([R[:, 0] for R in self.rotations()])

    @property
    def foot_angle(self) -> float:
        """phi_s: the absolute angle the foot's joint angles count from (rad): the last rod's
        (in space its direction projected on the vertical plane x, y)."""
        if not self.spatial:
            return list(accumulate(b.angle for b in self.rods))[-1]
        d = self.directions()[-1]
        return math.atan2(d[1], d[0])

    def points(self) -> np.ndarray:
        """The base's start and every joint of the leg, from the base down, relative to the
        ankle, in the world (rods x 3, m): the hip and the knee of a two-rod leg."""
        u = self.directions()
        p = [-(self.ankle * self.rods[-1].length) * u[-1]]
        for k in range(len(self.rods) - 2, -1, -1):  # back up the chain: the child's joint at ``at`` on rod k
            p.append(p[-1] - (self.rods[k + 1].at * self.rods[k].length) * u[k])
        return np.array(p[::-1])

    @property
    def ankle_rotation(self) -> np.ndarray:
        """W_R_L: the last rod's frame in the world at touchdown (3 x 3); in the plane Rz(phi_s)."""
        return self.rotations()[-1] if self.spatial else rotation_z(self.foot_angle)

    def root_rpy(self, yaw: float) -> tuple[float, float, float]:
        """The ``rpy`` of a foot chain's root (on the last rod) that turns the chain by ``yaw``
        about the vertical (module docstring, :func:`yaw_rpy`); the plane's foot at yaw 0 needs none."""
        if not self.spatial and yaw == 0.0:
            return (0.0, 0.0, 0.0)
        return tuple(float(v) for v in yaw_rpy(self, yaw))


def leg_chain(leg: Leg | LegChain) -> LegChain:
    """Any study leg as a chain (the two-rod :class:`Leg`'s thigh and shank)."""
    return leg if isinstance(leg, LegChain) else leg.chain


@dataclass(frozen=True, order=True)
class FootShape:
    """The discrete choices: how many toes, rods per toe and rods in the heel. Hashable: one
    shape is one topology, one compiled model, one NLP."""

    n_toes: int
    toe_segments: int
    heel_segments: int = 1

    def __post_init__(self) -> None:
        for name in ("n_toes", "toe_segments", "heel_segments"):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= 1):
                raise ValueError(f"FootShape.{name}: must be an integer >= 1, got {value!r}")

    @property
    def n_links(self) -> int:
        """Foot rods (heel and every toe)."""
        return self.heel_segments + self.n_toes * self.toe_segments

    @property
    def label(self) -> str:
        """``3x2`` (three toes of two rods), ``3x2+h2`` with a two-rod heel."""
        heel = "" if self.heel_segments == 1 else f"+h{self.heel_segments}"
        return f"{self.n_toes}x{self.toe_segments}{heel}"


@dataclass(frozen=True)
class Segment:
    """One foot rod: length (m), mass (kg) and touchdown joint angle relative to its parent (rad);
    for a whole landing, its joint's torsional spring (N m/rad, rest at the touchdown angle),
    damper (N m s/rad) and stops (``stop`` rad either side of the touchdown angle; None: none)."""

    length: float
    mass: float
    joint_angle: float
    stiffness: float = 0.0
    damping: float = 0.0
    stop: float | None = None

    def joint_law(self, stop_restitution: float = 0.0) -> JointLaw:
        """The joint's law for :mod:`impulse_core.timedomain.landing` (rest: the touchdown angle)."""
        limits = None if self.stop is None else (self.joint_angle - self.stop, self.joint_angle + self.stop)
        return JointLaw(self.stiffness, self.damping, None, limits, stop_restitution if limits else 0.0)


@dataclass(frozen=True)
class FootDesign:
    """One foot: the heel chain and the toe chains, proximal rod first in each.

    Attributes:
        heel: the heel chain (its root hangs from the ankle; it usually points back and down).
        toes: one chain per toe, all of the same number of rods.
    """

    heel: tuple[Segment, ...]
    toes: tuple[tuple[Segment, ...], ...]
    toe_yaws: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        if not self.heel or not self.toes or any(not toe for toe in self.toes):
            raise ValueError("FootDesign: the heel and every toe need at least one rod")
        if len({len(toe) for toe in self.toes}) != 1:
            raise ValueError("FootDesign: every toe has the same number of rods")
        if self.toe_yaws is not None and len(self.toe_yaws) != len(self.toes):
            raise ValueError("FootDesign: one yaw per toe")

    @property
    def spatial(self) -> bool:
        """True for a splayed (spatial) foot: its toes have yaws (module docstring)."""
        return self.toe_yaws is not None

    @property
    def space(self) -> Space:
        return SPATIAL if self.spatial else PLANAR

    @property
    def chain_yaws(self) -> tuple[float, ...]:
        """Yaw of every chain about the vertical (rad), heel (0) first."""
        return (0.0, *(self.toe_yaws or (0.0,) * len(self.toes)))

    @property
    def shape(self) -> FootShape:
        return FootShape(len(self.toes), len(self.toes[0]), len(self.heel))

    @property
    def chains(self) -> tuple[tuple[Segment, ...], ...]:
        """Heel first, then the toes."""
        return (self.heel, *self.toes)

    @property
    def segments(self) -> tuple[Segment, ...]:
        """Every foot rod, in tree order (heel, then toe 1, toe 2, ...)."""
        return tuple(s for chain in self.chains for s in chain)

    @property
    def foot_mass(self) -> float:
        return float(sum(s.mass for s in self.segments))


def chain_names(shape: FootShape) -> tuple[tuple[str, ...], ...]:
    """Body names per chain, heel first: ``heel``, ``toe1_proximal``, ``toe1_distal``, ..."""

    def names(prefix: str, k: int) -> tuple[str, ...]:
        return tuple(prefix if not s else f"{prefix}_{s}" for s in segment_suffixes(k))

    heel = names("heel", shape.heel_segments)
    return (heel, *(names(f"toe{i + 1}", shape.toe_segments) for i in range(shape.n_toes)))


def segment_names(shape: FootShape) -> tuple[str, ...]:
    """Body names of every foot rod, in tree order."""
    return tuple(n for chain in chain_names(shape) for n in chain)


def foot_tree(leg: Leg | LegChain, design: FootDesign) -> Tree:
    """The design as the impulse core's tree: the leg's rods (thigh, the base, and shank), then
    each chain (heel first), hanging from the ankle; one contact at each chain's tip. Every
    declared contact is one that must touch at touchdown (see :func:`intended_contacts`). A
    splayed toe's root, and every root on a spatial leg, carries the ``rpy`` of
    :meth:`LegChain.root_rpy` (evaluate such a tree with :func:`foot_space`)."""
    chain = leg_chain(leg)
    if chain.spatial and not design.spatial:
        raise ValueError("foot_tree: a spatial leg takes a spatial foot (toe_yaws)")
    bodies = list(chain.rods)
    ankle = len(bodies) - 1
    for names, rods, yaw in zip(chain_names(design.shape), design.chains, design.chain_yaws, strict=True):
        parent = ankle
        for k, (name, s) in enumerate(zip(names, rods, strict=True)):
            tip = (1.0,) if k == len(rods) - 1 else ()
            body = Body(name, parent, s.length, s.mass, s.joint_angle, contacts=tip)
            if k == 0:  # the chain's root, at the ankle
                body = replace(body, at=chain.ankle, rpy=chain.root_rpy(yaw))
            bodies.append(body)
            parent = len(bodies) - 1
    return Tree(tuple(bodies))


def foot_space(leg: Leg | LegChain, design: FootDesign) -> Space:
    """The space the design's tree moves in: SPATIAL for a splayed foot or a spatial leg."""
    return SPATIAL if design.spatial or leg_chain(leg).spatial else PLANAR


def search_columns(topology: Topology, space: Space, leg_rods: int = 2) -> tuple[int, ...] | None:
    """The entries of the design vector (``space.body_values`` per body, then the contact
    fractions) that a search changes in a tree of :func:`foot_tree`'s layout on a leg of
    ``leg_rods`` rods: every foot rod's (below the leg's last rod, the shank: body ``leg_rods - 1``)
    length, mass and joint angle (:func:`design_from`), and each toe root's (a child of the shank
    after the first, the heel) roll, pitch and yaw (its splay, :meth:`LegChain.root_rpy`; spatial
    only). The leg's values, the heel's rpy, positions on the parent, centres of mass, gyrations,
    axes, radii, mass properties and contact fractions are fixed. None when ``topology`` is not of
    that layout (the leg a chain from the base, every other body below its last rod)."""
    parents, shank = topology.parents, leg_rods - 1
    if (len(parents) <= leg_rods or parents[0] != -1 or any(parents[k] != k - 1 for k in range(1, leg_rods))
            or any(p < shank for p in parents[leg_rods:])):
        return None
    n, names = len(space.body_values), space.body_values
    rod = [names.index(k) for k in ("length", "mass", "angle")]
    splay = [names.index(k) for k in ("roll", "pitch", "yaw") if k in names]
    toe_roots = [b for b in range(leg_rods, len(parents)) if parents[b] == shank][1:]
    return tuple(n * b + j for b in range(leg_rods, len(parents)) for j in sorted(rod + (splay if b in toe_roots else [])))


#: Names only a foot's rods take (footopt's designs: ``heel``, ``heel_...``, ``toe<i>``,
#: ``toe<i>_...``; a leg file's rods may not: ``leg.file``).
FOOT_ROD_NAME = re.compile(r"(heel|toe\d+)(_.*)?")
#: A foot rod's name as :func:`leg_rod_count` reads it: any name starting ``heel`` or ``toe``
#: (footopt's own, :data:`FOOT_ROD_NAME`, and hand-written feet: the paper's ``toe``, ``toe_distal``).
FOOT_NAME_START = re.compile(r"heel|toe")


def leg_rod_count(tree: Tree) -> int | None:
    """The number of leg rods of a tree of :func:`foot_tree`'s layout (a footopt design's model
    file, whatever its leg; a hand-written foot named alike): the rods before its first foot rod
    (a name starting ``heel`` or ``toe``: :data:`FOOT_NAME_START`; footopt's leg files may not
    take footopt's own foot names, :data:`FOOT_ROD_NAME`). None when no rod is named so, the base
    is, or a rod after the first foot rod is not (no foot to go by: :func:`search_columns`)."""
    foot = [bool(FOOT_NAME_START.match(b.name)) for b in tree.bodies]
    first = foot.index(True) if True in foot else 0
    return first if first > 0 and all(foot[first:]) else None


def yaw_rpy(leg: LegChain, yaw: float | ca.SX) -> tuple:
    """The ``rpy`` (URDF: Rz(c) Ry(b) Rx(a)) of a foot chain's root on the leg's last rod that
    turns the chain by ``yaw`` about the world's vertical, its joint angles counted from the foot
    angle phi_s: R = W_R_L^T Ry(yaw) Rz(phi_s) (W_R_L: :attr:`LegChain.ankle_rotation`; in the
    plane Rz(-phi_s) Ry(yaw) Rz(phi_s)), read off in closed form. ``yaw`` a float gives floats; a
    CasADi symbol gives expressions (the inner search's spatial NLP)."""
    c, s = ca.cos(yaw), ca.sin(yaw)
    # Ry(yaw) = c (e_x e_x^T + e_z e_z^T) + s (e_x e_z^T - e_z e_x^T) + e_y e_y^T, so R = c P + s Q + U
    # with P, Q, U numeric: one expression for a float and for a symbol.
    P, Q, U = (leg.ankle_rotation.T @ M @ rotation_z(leg.foot_angle) for M in _RY_PARTS)
    r00, r10, r20, r21, r22 = (c * P[ij] + s * Q[ij] + U[ij] for ij in ((0, 0), (1, 0), (2, 0), (2, 1), (2, 2)))
    return (ca.atan2(r21, r22), ca.atan2(-r20, ca.sqrt(r00 * r00 + r10 * r10)), ca.atan2(r10, r00))


#: Ry(yaw)'s parts: its cos(yaw) part, its sin(yaw) part and its constant part.
_RY_PARTS = (np.diag([1.0, 0.0, 1.0]), np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [-1.0, 0.0, 0.0]]),
             np.diag([0.0, 1.0, 0.0]))


def foot_joint_laws(leg: Leg | LegChain, design: FootDesign, stop_restitution: float = 0.0) -> tuple[JointLaw, ...]:
    """The joint law of every body of :func:`foot_tree`: the leg's (the base: free; the knee...),
    then each foot rod's joint."""
    return (*leg_chain(leg).joints, *(s.joint_law(stop_restitution) for s in design.segments))


def intended_contacts(design: FootDesign) -> tuple[int, ...]:
    """Declared contacts of :func:`foot_tree` that must touch at once: every chain tip."""
    return tuple(range(len(design.chains)))


def absolute_angles(leg: Leg | LegChain, design: FootDesign) -> tuple[tuple[float, ...], ...]:
    """Absolute angle of every foot rod at touchdown, per chain, in the chain's plane (rad)."""
    out = []
    phi_s = leg_chain(leg).foot_angle
    for chain in design.chains:
        phi, angles = phi_s, []
        for s in chain:
            phi += s.joint_angle
            angles.append(phi)
        out.append(tuple(angles))
    return tuple(out)


class ToeSymmetry(Enum):
    """Whether the toes of a design share their values."""

    IDENTICAL = "identical"  # one set of rod values for every toe (the paper's case 3)
    INDEPENDENT = "independent"  # each toe its own lengths, masses and angles


#: The joint families: the heel's and the toes' joints at the ankle, and the joints inside a chain.
JOINT_FAMILIES = ("heel_root", "heel_inner", "toe_root", "toe_inner")


@dataclass(frozen=True)
class JointRanges:
    """Search ranges (inclusive) of one joint family's law; None: that part is absent (no
    spring, no damper, no stops). A range [x, x] fixes it."""

    stiffness: tuple[float, float] | None = None  # N m/rad
    damping: tuple[float, float] | None = None  # N m s/rad
    stop: tuple[float, float] | None = None  # rad either side of the touchdown angle

    @property
    def empty(self) -> bool:
        return self.stiffness is None and self.damping is None and self.stop is None


@dataclass(frozen=True)
class JointLawSpace:
    """The joint laws a whole-landing study searches, per family (``JOINT_FAMILIES``)."""

    heel_root: JointRanges = JointRanges()
    heel_inner: JointRanges = JointRanges()
    toe_root: JointRanges = JointRanges()
    toe_inner: JointRanges = JointRanges()
    stop_restitution: float = 0.0

    @property
    def empty(self) -> bool:
        return all(getattr(self, f).empty for f in JOINT_FAMILIES)

    def ranges(self, shape: FootShape) -> tuple[tuple[JointRanges, ...], ...]:
        """Ranges of every foot joint, per chain (heel first), as :meth:`FootLimits.joint_limits`."""
        heel = (self.heel_root,) + (self.heel_inner,) * (shape.heel_segments - 1)
        toe = (self.toe_root,) + (self.toe_inner,) * (shape.toe_segments - 1)
        return (heel, *(toe,) * shape.n_toes)


class SplayMode(Enum):
    """How a spatial design space turns its toes about the vertical."""

    SYMMETRIC = "symmetric"  # one splay s: toe i of n at yaw -s + 2 s i / (n - 1) (one toe: 0)
    PER_TOE = "per_toe"  # each toe its own yaw within the range


def symmetric_yaws(n_toes: int, splay: float) -> tuple[float, ...]:
    """Yaws of ``n_toes`` toes spread evenly from -splay (toe 1) to +splay (toe n); one toe: 0."""
    if n_toes == 1:
        return (0.0,)
    return tuple(-splay + 2.0 * splay * i / (n_toes - 1) for i in range(n_toes))


@dataclass(frozen=True)
class SplaySpace:
    """A spatial foot's splay: ``splay`` (rad) is the range of the symmetric splay s (0 <= lo)
    or, per toe, of each toe's yaw."""

    splay: tuple[float, float] = (0.0, 0.6)
    mode: SplayMode = SplayMode.SYMMETRIC


@dataclass(frozen=True)
class DesignSpace:
    """The discrete part of a study's design space (inclusive ranges), and the joint laws a
    whole-landing study searches.

    Attributes:
        toes: (min, max) toe count.
        toe_segments: (min, max) rods per toe.
        heel_segments: (min, max) rods in the heel chain.
        toe_symmetry: identical toes (fewer values; the planar model cannot tell identical toes
            in one plane from one heavier toe) or independent ones.
        joint_laws: the springs, dampers and stops searched per joint family.
        splay: a spatial foot's splay (None: the planar foot).
    """

    toes: tuple[int, int] = (1, 3)
    toe_segments: tuple[int, int] = (1, 2)
    heel_segments: tuple[int, int] = (1, 1)
    toe_symmetry: ToeSymmetry = ToeSymmetry.IDENTICAL
    joint_laws: JointLawSpace = JointLawSpace()
    splay: SplaySpace | None = None

    @property
    def spatial(self) -> bool:
        return self.splay is not None

    def shapes(self) -> tuple[FootShape, ...]:
        """Every foot shape of the space, fewest toes first."""
        return tuple(
            FootShape(n, k, h)
            for n in range(self.toes[0], self.toes[1] + 1)
            for k in range(self.toe_segments[0], self.toe_segments[1] + 1)
            for h in range(self.heel_segments[0], self.heel_segments[1] + 1)
        )


# --------------------------------------------------------------------------------------------
# Limits, objectives, constraint values


class MassMode(Enum):
    """How the foot mass budget binds."""

    EQUAL = "equal"  # the foot weighs exactly the budget (the paper keeps 0.5 kg)
    AT_MOST = "at_most"


@dataclass(frozen=True)
class FootLimits:
    """The design constraints (all SI).

    Attributes:
        foot_mass: the foot mass budget: heel and toe rods together (kg).
        mass_mode: equal to, or at most, the budget.
        min_link_mass: every foot rod weighs at least this (kg).
        mass_per_length: (min, max) of every foot rod's mass per length (kg/m).
        foot_length: (min, max) horizontal distance from the heel contact to each toe contact (m).
        min_clearance: every rod end that is not a contact (joints, ankle, knee, hip) stays at
            least this high above the ground at touchdown (m).
        heel_root, heel_inner, toe_root, toe_inner: joint angle limits (rad): the heel's and the
            toes' joints at the ankle (relative to the shank) and the joints inside a chain.
        contact_tolerance: every chain tip lies within this height of the ground at touchdown (m).
        support_margin: a spatial foot's centre of mass, projected on the ground, lies at least
            this far inside the convex hull of its contacts (m; None: not constrained).
    """

    foot_mass: float = 0.5
    mass_mode: MassMode = MassMode.EQUAL
    min_link_mass: float = 0.01
    mass_per_length: tuple[float, float] = (0.1, 5.0)
    foot_length: tuple[float, float] = (0.1, 0.4)
    min_clearance: float = 0.005
    heel_root: tuple[float, float] = (-1.2, -0.1)
    heel_inner: tuple[float, float] = (-0.8, 0.8)
    toe_root: tuple[float, float] = (0.3, 1.6)
    toe_inner: tuple[float, float] = (-1.0, 0.6)
    contact_tolerance: float = 1e-6
    support_margin: float | None = None

    def joint_limits(self, shape: FootShape) -> tuple[tuple[tuple[float, float], ...], ...]:
        """Angle limits of every foot joint, per chain (heel first)."""
        heel = (self.heel_root,) + (self.heel_inner,) * (shape.heel_segments - 1)
        toe = (self.toe_root,) + (self.toe_inner,) * (shape.toe_segments - 1)
        return (heel, *(toe,) * shape.n_toes)


class Objective(Enum):
    """What a study can optimise (see :class:`Objectives`): the first impact's figures, and the
    whole landing's (those need ``scene.duration``). ``energy_absorbed`` is maximised, every
    other one minimised."""

    EXTERNAL_NORM = "external_norm"
    INTERNAL_NORM = "internal_norm"
    MAX_INTERNAL = "max_internal"
    BASE_ANGULAR_VELOCITY = "base_angular_velocity"
    ENERGY_AFTER = "energy_after"
    PEAK_EXTERNAL_NORM = "peak_external_norm"
    PEAK_INTERNAL_NORM = "peak_internal_norm"
    PEAK_MAX_INTERNAL = "peak_max_internal"
    SETTLED_AT = "settled_at"
    ENERGY_ABSORBED = "energy_absorbed"

    @property
    def landing(self) -> bool:
        """True for the whole landing's objectives."""
        return self in LANDING_OBJECTIVES

    @property
    def sign(self) -> float:
        """+1 for a minimised objective, -1 for the maximised ``energy_absorbed``."""
        return -1.0 if self is Objective.ENERGY_ABSORBED else 1.0


LANDING_OBJECTIVES = frozenset(
    {Objective.PEAK_EXTERNAL_NORM, Objective.PEAK_INTERNAL_NORM, Objective.PEAK_MAX_INTERNAL,
     Objective.SETTLED_AT, Objective.ENERGY_ABSORBED}
)


@dataclass(frozen=True)
class Objectives:
    """The impact of one design, as a designer reads it; the whole landing's figures when it ran.

    Attributes:
        external_norm: Euclidean norm of the contact impulses (N s; the paper's).
        internal_norm: Euclidean norm of the joint impulse magnitudes (N s; the paper's).
        max_internal: the largest single joint impulse (N s).
        base_angular_velocity: |angular velocity| of the thigh just after the impact (rad/s).
        energy_after: kinetic energy just after the impact (J).
        peak_external_norm, peak_internal_norm, peak_max_internal: the largest external_norm,
            internal_norm and single joint impulse over the landing's impacts (N s).
        settled_at: when every velocity stays below 1e-3 (s); the duration when it never does.
        energy_absorbed: fraction of the energy brought in (touchdown kinetic energy and the
            work of gravity) that impacts, dampers and friction dissipated by the end.
    """

    external_norm: float
    internal_norm: float
    max_internal: float
    base_angular_velocity: float
    energy_after: float
    peak_external_norm: float | None = None
    peak_internal_norm: float | None = None
    peak_max_internal: float | None = None
    settled_at: float | None = None
    energy_absorbed: float | None = None

    def value(self, objective: Objective) -> float:
        x = getattr(self, objective.value)
        if x is None:
            raise ValueError(f"{objective.value}: not evaluated (a whole-landing objective needs scene.duration)")
        return float(x)

    def score(self, objective: Objective) -> float:
        """The value as minimised (maximised objectives negated)."""
        return objective.sign * self.value(objective)

    def items(self) -> tuple[tuple[str, float], ...]:
        """Every evaluated objective, as (name, value)."""
        return tuple((f.name, float(getattr(self, f.name))) for f in fields(self) if getattr(self, f.name) is not None)


@dataclass(frozen=True)
class ConstraintValues:
    """How far a design is from each constraint: <= 0 (up to ``FEASIBILITY_TOL``) is met.

    Attributes:
        foot_mass: |foot mass - budget| (equal) or foot mass - budget (at most), kg.
        min_link_mass: minimum link mass - lightest rod, kg.
        mass_per_length: largest excursion of a rod's mass per length outside its range, kg/m.
        foot_length: largest excursion of a heel-to-toe distance outside its range, m.
        joint_angles: largest excursion of a joint angle outside its limits, rad.
        touchdown: spread of the contact heights - contact tolerance, m.
        clearance: minimum clearance - lowest non-contact rod end above the ground, m.
        pulling: -(smallest contact impulse), N s: Newton's law must not make a contact pull.
        energy_gain: energy after - energy before the impact, J (Newton's law at simultaneous
            contacts can create energy; such a design is unphysical).
    """

    foot_mass: float
    min_link_mass: float
    mass_per_length: float
    foot_length: float
    joint_angles: float
    touchdown: float
    clearance: float
    pulling: float
    energy_gain: float

    def items(self) -> tuple[tuple[str, float], ...]:
        return tuple((f.name, float(getattr(self, f.name))) for f in fields(self))

    @property
    def feasible(self) -> bool:
        return all(v <= FEASIBILITY_TOL for _, v in self.items())

    def violations(self) -> tuple[tuple[str, float], ...]:
        """Each constraint's violation beyond the tolerance (0 when met): what a sampler sees."""
        return tuple((name, max(0.0, v - FEASIBILITY_TOL)) for name, v in self.items())


@dataclass(frozen=True)
class SupportConstraintValues(ConstraintValues):
    """The constraint values of a study that constrains the support polygon
    (``constraints.support_margin``): those of :class:`ConstraintValues`, and

    Attributes:
        support_margin: the bound - the support margin (:func:`foot_support_margin`), m.
    """

    support_margin: float = 0.0


def constraint_record(values: dict[str, float]) -> ConstraintValues:
    """Constraint values from their ``items()`` (a trial's record): with ``support_margin``, the
    support-constrained kind."""
    kind = SupportConstraintValues if "support_margin" in values else ConstraintValues
    return kind(**values)


#: The study-file field behind each constraint value (None: a law of physics, not a setting).
CONSTRAINT_FIELDS = {
    "foot_mass": "constraints.foot_mass",
    "min_link_mass": "constraints.min_link_mass",
    "mass_per_length": "constraints.mass_per_length",
    "foot_length": "constraints.foot_length",
    "joint_angles": "constraints.joint_angles",
    "touchdown": "constraints.contact_tolerance",
    "clearance": "constraints.min_clearance",
    "pulling": None,
    "energy_gain": None,
    "support_margin": "constraints.support_margin",
}


@dataclass(frozen=True)
class FootGeometry:
    """The touchdown geometry of a foot, relative to the ankle (m).

    Attributes:
        tips: (x, y) of each chain tip, heel first.
        joints: (x, y) of the joints inside the chains (not the ankle).
        leg_points: (x, y) of the leg's base start and joints (the hip and the knee; in space
            the points' x and height).
        tips_z: lateral position (z) of each chain tip (zeros for a planar foot).
    """

    tips: np.ndarray
    joints: np.ndarray
    leg_points: np.ndarray
    tips_z: np.ndarray | None = None

    @property
    def ground(self) -> float:
        return float(self.tips[:, 1].min())

    @property
    def reaches(self) -> np.ndarray:
        """Horizontal distance from the heel contact to each toe contact."""
        return self.tips[1:, 0] - self.tips[0, 0]

    @property
    def clearance(self) -> float:
        """Lowest non-contact rod end (chain joints, ankle, knee, hip) above the ground."""
        points = np.vstack([self.joints.reshape(-1, 2), self.leg_points, np.zeros((1, 2))])
        return float(points[:, 1].min() - self.ground)


def foot_geometry(leg: Leg | LegChain, design: FootDesign) -> FootGeometry:
    """Where the chain tips and joints are at touchdown, the ankle at the origin."""
    tips, joints, lateral = [], [], []
    for chain, angles, yaw in zip(design.chains, absolute_angles(leg, design), design.chain_yaws, strict=True):
        p = np.zeros(2)
        for k, (s, phi) in enumerate(zip(chain, angles, strict=True)):
            p = p + s.length * np.array([math.cos(phi), math.sin(phi)])
            turned = np.array([p[0] * math.cos(yaw), p[1]]) if design.spatial else p
            (tips if k == len(chain) - 1 else joints).append(turned)
        if design.spatial:  # the chain's plane turned by its yaw (module docstring)
            lateral.append(-p[0] * math.sin(yaw))
    tips_z = np.array(lateral) if design.spatial else None
    return FootGeometry(np.array(tips), np.array(joints).reshape(-1, 2), leg_chain(leg).points()[:, :2], tips_z)


def foot_support_margin(leg: Leg | LegChain, design: FootDesign) -> float:
    """The support margin of the design's model (m): the signed distance from the whole tree's
    centre of mass, projected on the ground (x, z), to the boundary of the convex hull of its
    contacts' projections, > 0 inside (:mod:`impulse_core.model.support`; as ``footopt evaluate``
    reports it for the model file)."""
    tree = foot_tree(leg, design)
    geometry = touchdown_geometry(tree, SPATIAL)
    masses = np.array([b.mass for b in tree.bodies])
    com = masses @ geometry.coms / masses.sum()
    return hull_margin(geometry.contacts[:, [0, 2]], com[[0, 2]])


def base_turn(v_plus: np.ndarray, planar: bool) -> float:
    """|angular velocity| of the base (the thigh) in a reported velocity: in the plane DOF 2 is its
    rate, in space DOFs 3-5 its angular velocity, whose norm is taken."""
    return abs(float(v_plus[2])) if planar else float(np.linalg.norm(v_plus[3:6]))


def objectives(result: ImpactResult, space: Space = PLANAR) -> Objectives:
    """The designer's objectives from the core's result (:func:`base_turn` after the impact)."""
    turn = base_turn(result.v_plus, space is PLANAR)
    return Objectives(
        external_norm=result.external_norm,
        internal_norm=result.internal_norm,
        max_internal=result.max_internal,
        base_angular_velocity=turn,
        energy_after=result.energy_after,
    )


def constraint_values(
    leg: Leg | LegChain, design: FootDesign, limits: FootLimits, result: ImpactResult | None = None
) -> ConstraintValues:
    """Every constraint's value for ``design``; the impact-dependent ones (pulling, energy
    gain) are 0 when ``result`` is None."""
    segs = design.segments
    masses = np.array([s.mass for s in segs])
    density = masses / np.array([s.length for s in segs])
    lo_rho, hi_rho = limits.mass_per_length
    geo = foot_geometry(leg, design)
    lo_f, hi_f = limits.foot_length
    excursions = []
    for chain, bounds in zip(design.chains, limits.joint_limits(design.shape), strict=True):
        for s, (lo, hi) in zip(chain, bounds, strict=True):
            excursions.append(max(lo - s.joint_angle, s.joint_angle - hi))
    mass_excess = design.foot_mass - limits.foot_mass
    heights = geo.tips[:, 1]
    values = ConstraintValues(
        foot_mass=abs(mass_excess) if limits.mass_mode is MassMode.EQUAL else mass_excess,
        min_link_mass=float(limits.min_link_mass - masses.min()),
        mass_per_length=float(max((density - hi_rho).max(), (lo_rho - density).max())),
        foot_length=float(max((lo_f - geo.reaches).max(), (geo.reaches - hi_f).max())),
        joint_angles=float(max(excursions)),
        touchdown=float(heights.max() - heights.min() - limits.contact_tolerance),
        clearance=float(limits.min_clearance - geo.clearance),
        pulling=0.0 if result is None else float(-result.external.min()),
        energy_gain=0.0 if result is None else float(result.energy_after - result.energy_before),
    )
    if limits.support_margin is None:
        return values
    return SupportConstraintValues(**dict(values.items()),
                                   support_margin=float(limits.support_margin - foot_support_margin(leg, design)))


# --------------------------------------------------------------------------------------------
# Lengths from angles and masses: a linear program


@dataclass(frozen=True)
class LengthAssignment:
    """Rod lengths chosen by :func:`assign_lengths`.

    Attributes:
        lengths: per chain, per rod (m).
        ankle_height: the ankle's height above the ground (m).
        margin: the smallest relative margin of the geometric inequalities (mass per length,
            foot length, clearance); < 0: the angles and masses admit no feasible lengths, and
            these lengths violate the worst inequality by that fraction of its bound.
    """

    lengths: tuple[tuple[float, ...], ...]
    ankle_height: float
    margin: float


def assign_lengths(
    leg: Leg | LegChain,
    shape: FootShape,
    joint_angles: tuple[tuple[float, ...], ...],
    masses: tuple[tuple[float, ...], ...],
    limits: FootLimits,
    reach: float | None = None,
    toe_yaws: tuple[float, ...] | None = None,
) -> LengthAssignment | None:
    """Rod lengths that put every chain tip on one ground line and keep the geometric limits
    (and, given ``reach``, make the toes' mean heel-to-toe distance equal to it: lengths matter
    over a whole landing, so a whole-landing search sets the foot's size). Splayed toes
    (``toe_yaws``) reach forward by cos(yaw) of their run in their plane.

    Given the angles, each tip's height below the ankle is sum_i L_i (-sin phi_i): linear in the
    lengths, as are the reaches, the clearances and the length bounds from mass per length. The
    linear program (HiGHS) finds lengths L and the ankle height h that maximise the smallest
    relative margin t of those inequalities (capped at ``MARGIN_CAP``, then the shortest foot):

        max t - eps * sum L   s.t.   sum_{i in chain} L_i (-sin phi_i) = h   for every chain,
                                     g_k(L, h) / b_k - 1 >= t  (lower bounds),  1 - g_k / b_k >= t
                                     (upper bounds),  L >= LENGTH_FLOOR,  t <= MARGIN_CAP.

    Each chain's last length is then recomputed from h so that the tips are level to rounding.

    Args:
        leg: the fixed leg (its posture sets the chains' absolute angles).
        shape: the foot's shape.
        joint_angles, masses: per chain (heel first), per rod.
        limits: the constraints.

    Returns:
        The lengths, or None when no lengths put every tip on one line (e.g. a chain that only
        rises cannot meet a chain that falls).
    """
    design0 = FootDesign(
        heel=tuple(Segment(1.0, m, a) for m, a in zip(masses[0], joint_angles[0], strict=True)),
        toes=tuple(
            tuple(Segment(1.0, m, a) for m, a in zip(ms, js, strict=True))
            for ms, js in zip(masses[1:], joint_angles[1:], strict=True)
        ),
    )
    if design0.shape != shape:
        raise ValueError(f"assign_lengths: angles and masses do not have the shape {shape}")
    lp = _LengthRows.of(absolute_angles(leg, design0), toe_yaws)
    lp.level_tips()
    lp.mass_per_length(np.array([m for c in masses for m in c]), limits.mass_per_length)
    lp.reaches(limits.foot_length, reach)
    lp.clearances(limits.min_clearance, foot_geometry(leg, design0).leg_points[:, 1])
    return lp.solve()


@dataclass
class _LengthRows:
    """The linear program of :func:`assign_lengths`, row by row: variables z = (L, h, t)."""

    drop: np.ndarray  # height lost per metre of each rod
    run: np.ndarray  # forward distance per metre of each rod
    sizes: list[int]
    a_eq: list[np.ndarray] = field(default_factory=list)
    b_eq: list[float] = field(default_factory=list)
    a_ub: list[np.ndarray] = field(default_factory=list)
    b_ub: list[float] = field(default_factory=list)

    @classmethod
    def of(cls, angles: tuple[tuple[float, ...], ...], toe_yaws: tuple[float, ...] | None = None) -> _LengthRows:
        phi = np.array([a for c in angles for a in c])
        run = np.cos(phi)
        if toe_yaws is not None:  # a splayed toe's forward run: its run in its plane x cos(yaw)
            yaws = (0.0, *toe_yaws)
            run = run * np.array([math.cos(yaws[i]) for i, c in enumerate(angles) for _ in c])
        return cls(-np.sin(phi), run, [len(c) for c in angles])

    @property
    def n(self) -> int:
        return len(self.drop)

    @property
    def starts(self) -> np.ndarray:
        return np.cumsum([0] + self.sizes[:-1])

    def row(self) -> np.ndarray:
        return np.zeros(self.n + 2)

    def at_least(self, row: np.ndarray, bound: float) -> None:  # row . z >= bound, with margin t
        r = -row / bound
        r[self.n + 1] = 1.0
        self.a_ub.append(r)
        self.b_ub.append(-1.0)

    def at_most(self, row: np.ndarray, bound: float) -> None:  # row . z <= bound, with margin t
        r = row / bound
        r[self.n + 1] = 1.0
        self.a_ub.append(r)
        self.b_ub.append(1.0)

    def level_tips(self) -> None:
        """Every chain's tip at the ankle height h below the ankle."""
        for c, k in zip(self.starts, self.sizes, strict=True):
            row = self.row()
            row[c : c + k] = self.drop[c : c + k]
            row[self.n] = -1.0
            self.a_eq.append(row)
            self.b_eq.append(0.0)

    def mass_per_length(self, masses: np.ndarray, bounds: tuple[float, float]) -> None:
        lo_rho, hi_rho = bounds
        for i in range(self.n):
            e = self.row()
            e[i] = 1.0
            self.at_least(e, masses[i] / hi_rho)  # m / L <= hi_rho
            self.at_most(e, masses[i] / lo_rho)  # m / L >= lo_rho

    def reaches(self, bounds: tuple[float, float], reach: float | None) -> None:
        """Each toe's heel-to-toe distance within ``bounds``; their mean = ``reach`` if given."""
        heel = self.row()
        heel[: self.sizes[0]] = self.run[: self.sizes[0]]
        mean_reach = self.row()
        for c, k in zip(self.starts[1:], self.sizes[1:], strict=True):
            toe_reach = -heel.copy()
            toe_reach[c : c + k] += self.run[c : c + k]
            self.at_least(toe_reach, bounds[0])
            self.at_most(toe_reach, bounds[1])
            mean_reach += toe_reach / (len(self.sizes) - 1)
        if reach is not None:
            self.a_eq.append(mean_reach)
            self.b_eq.append(reach)

    def clearances(self, min_clearance: float, leg_heights: np.ndarray) -> None:
        """Joints inside the chains, the ankle, the knee and the hip above the ground."""
        for c, k in zip(self.starts, self.sizes, strict=True):
            for j in range(k - 1):
                row = self.row()
                row[self.n] = 1.0
                row[c : c + j + 1] = -self.drop[c : c + j + 1]
                self.at_least(row, min_clearance)
        for y in (0.0, *leg_heights):  # height above ground = h + y (y: above the ankle)
            row = self.row()
            row[self.n] = 1.0
            self.a_ub.append(np.where(np.arange(self.n + 2) == self.n + 1, 1.0, -row / min_clearance))
            self.b_ub.append(-1.0 + y / min_clearance)

    def solve(self) -> LengthAssignment | None:
        """HiGHS on the rows; each chain's last rod then levels its tip to rounding."""
        n = self.n
        cost = self.row()
        cost[:n] = 1e-6
        cost[n + 1] = -1.0
        bounds = [(LENGTH_FLOOR, None)] * n + [(None, None), (None, MARGIN_CAP)]
        from scipy.optimize import linprog  # here: importing scipy.optimize costs ~0.2 s of CPU

        sol = linprog(
            cost,
            A_ub=np.array(self.a_ub),
            b_ub=np.array(self.b_ub),
            A_eq=np.array(self.a_eq),
            b_eq=np.array(self.b_eq),
            bounds=bounds,
            method="highs",
            options={"primal_feasibility_tolerance": 1e-10, "dual_feasibility_tolerance": 1e-10},
        )
        if sol.status != 0:
            return None
        h = float(sol.x[n])
        lengths = tuple(self.levelled(sol.x[c : c + k], c, h) for c, k in zip(self.starts, self.sizes, strict=True))
        return LengthAssignment(lengths, h, float(sol.x[n + 1]))

    def levelled(self, chain_lengths: np.ndarray, c: int, h: float) -> tuple[float, ...]:
        """A chain's lengths with the last rod taking up the LP's rounding (the tip exactly at h)."""
        chain = [float(x) for x in chain_lengths]
        k = len(chain)
        d_last = float(self.drop[c + k - 1])
        last = (h - float(np.dot(chain[:-1], self.drop[c : c + k - 1]))) / d_last if d_last > 1e-9 else 0.0
        if last > LENGTH_FLOOR and abs(last - chain[-1]) <= 1e-6 * max(1.0, chain[-1]):
            chain[-1] = last
        return tuple(chain)


def with_lengths(design_angles_masses: FootDesign, assignment: LengthAssignment) -> FootDesign:
    """``design_angles_masses`` with the lengths of ``assignment``."""
    chains = [
        tuple(replace(s, length=L) for s, L in zip(chain, lengths, strict=True))
        for chain, lengths in zip(design_angles_masses.chains, assignment.lengths, strict=True)
    ]
    return FootDesign(heel=chains[0], toes=tuple(chains[1:]), toe_yaws=design_angles_masses.toe_yaws)


def design_from(
    leg: Leg | LegChain,
    joint_angles: tuple[tuple[float, ...], ...],
    masses: tuple[tuple[float, ...], ...],
    limits: FootLimits,
    reach: float | None = None,
    toe_yaws: tuple[float, ...] | None = None,
) -> FootDesign:
    """The foot with these angles and masses (per chain, heel first), toe yaws (a splayed foot;
    None: planar) and lengths from :func:`assign_lengths` (with its ``reach``); when no lengths
    level the tips, every rod gets 0.1 m (the constraint values then say how far off the design is)."""
    shape = FootShape(len(joint_angles) - 1, len(joint_angles[1]), len(joint_angles[0]))
    unit = FootDesign(
        heel=tuple(Segment(0.1, m, a) for m, a in zip(masses[0], joint_angles[0], strict=True)),
        toes=tuple(
            tuple(Segment(0.1, m, a) for m, a in zip(ms, js, strict=True))
            for ms, js in zip(masses[1:], joint_angles[1:], strict=True)
        ),
        toe_yaws=toe_yaws,
    )
    assignment = assign_lengths(leg, shape, joint_angles, masses, limits, reach, toe_yaws)
    return unit if assignment is None else with_lengths(unit, assignment)


# --------------------------------------------------------------------------------------------
# Evaluation


@dataclass(frozen=True)
class DesignEvaluation:
    """A design with its impact, objectives and constraint values.

    Attributes:
        design: the foot.
        objectives: None when the impact solve failed numerically.
        constraints: the constraint values (impact-dependent ones 0 when it failed).
        failure: why there are no objectives, in one line ("" when there are).
    """

    design: FootDesign
    objectives: Objectives | None
    constraints: ConstraintValues
    failure: str = ""

    @property
    def feasible(self) -> bool:
        return self.objectives is not None and self.constraints.feasible


def evaluate_design(leg: Leg | LegChain, design: FootDesign, scene: Scene, limits: FootLimits) -> DesignEvaluation:
    """Impact, objectives and constraints of one design (by the rung ``auto`` picks: the exact
    Coulomb law when the scene has friction).

    Every chain tip is made to hit (``contacts: all``): whether they really touch at once is the
    ``touchdown`` constraint, measured on the geometry; the exported model files say
    ``contacts: lowest`` so that ``footopt evaluate`` checks it independently.
    """
    tree = foot_tree(leg, design)
    space = foot_space(leg, design)
    scene_all = Scene(
        speed=scene.speed,
        restitution=scene.restitution,
        friction=scene.friction,
        selection=ContactSelection.ALL,
        contact_tolerance=limits.contact_tolerance,
    )
    try:
        with np.errstate(all="ignore"):
            result = evaluate(tree, scene_all, space=space)
            newton = newton_impulses(tree, scene_all, space)
    except (ArithmeticError, np.linalg.LinAlgError, NumericalError) as error:
        return DesignEvaluation(design, None, constraint_values(leg, design, limits), failure_line(error))
    if not (np.all(np.isfinite(newton)) and np.isfinite(result.external_norm) and np.isfinite(result.internal_norm)):
        return DesignEvaluation(design, None, constraint_values(leg, design, limits), NOT_FINITE)
    values = constraint_values(leg, design, limits, result)
    # Newton's law (paper eq. 11) must not make a contact pull; the core would then switch to
    # the complementarity answer (the contact separates): a foot whose intended contact does not
    # take part is not the design asked for.
    values = replace(values, pulling=max(values.pulling, float(-newton.min())))
    return DesignEvaluation(design, objectives(result, space), values)


def newton_impulses(tree: Tree, scene: Scene, space: Space = PLANAR) -> np.ndarray:
    """The normal impulses of Newton's law at every declared contact (paper eq. 11), from the
    core's compiled model: negative where the law would make a contact pull."""
    topology, space = tree.topology(), values_space(tree, space)  # a leg's centres of mass off its rods too
    v_minus, p = approach_velocity(topology, scene.speed, space), design_vector(tree, space.body_values)
    out = compiled_model(topology, space).impact(p=p, v_minus=v_minus, restitution=scene.restitution)
    return np.array(out["external"]).ravel()


def landing_scene(scene: Scene, limits: FootLimits) -> Scene:
    """The scene of an exported model file: the ground at the lowest contact, contacts within
    the touchdown tolerance hit (so re-evaluating a file re-checks simultaneous touchdown)."""
    return replace(scene, selection=ContactSelection.LOWEST, contact_tolerance=limits.contact_tolerance)


def design_model(leg: Leg | LegChain, design: FootDesign, scene: Scene, limits: FootLimits, stop_restitution: float = 0.0) -> ModelFile:
    """The design's model file (its scene: :func:`landing_scene`; joint laws where any acts)."""
    joints = foot_joint_laws(leg, design, stop_restitution)
    laws = joints if any(not j.is_default for j in joints) else ()
    return ModelFile(foot_tree(leg, design), landing_scene(scene, limits), joints=laws, space=foot_space(leg, design))


#: A study's budget for one design's landing: a design that needs more impacts or finer steps
#: than this is numerically too stiff (e.g. a millimetre rod with a damper) and its trial fails.
#: Step code ``auto``: C where the compile cache holds the topology's (a long search builds it,
#: :mod:`optimizer.search.landing_code`), the same numbers as the virtual machine's.
STUDY_LANDING = LandingSettings(max_refinements=4, max_events=1000, step_code=AUTO_CODE)


def study_landing(tolerance: float) -> LandingSettings:
    """The landing settings of a study's evaluations: :data:`STUDY_LANDING` at the study's
    ``search.landing_tolerance``, the nominal scene's and every scenario's over ``landings``."""
    return replace(STUDY_LANDING, tolerance=tolerance)


def landing_objectives(result: LandingResult) -> Objectives:
    """The designer's objectives from a whole landing: its first event's (the base's turn as in
    :func:`objectives`), and its own."""
    first = result.events[0]
    turn = base_turn(first.v_plus, result.space == PLANAR.name)
    return Objectives(
        external_norm=first.external_norm,
        internal_norm=first.internal_norm,
        max_internal=float(first.internal_magnitude.max(initial=0.0)),
        base_angular_velocity=turn,
        energy_after=first.energy_after,
        peak_external_norm=result.peak_external_norm,
        peak_internal_norm=result.peak_internal_norm,
        peak_max_internal=result.peak_max_internal,
        settled_at=result.duration if result.settled_at is None else result.settled_at,
        energy_absorbed=result.energy_absorbed,
    )


#: Why a design has no objectives where a figure of its impact is not finite.
NOT_FINITE = "a figure of the impact is not finite"
#: The same of its whole landing.
LANDING_NOT_FINITE = "a figure of the landing is not finite"
#: Why a design failed where no reason was kept (trials recorded before reasons were).
FAILED = "failed numerically"


def failure_line(error: BaseException) -> str:
    """An error's first line, as a failed design's reason (:attr:`DesignEvaluation.failure`)."""
    text = str(error).strip()
    return (text.splitlines()[0] if text else type(error).__name__)[:300]


def unscored_why(result: LandingResult) -> str:
    """Why :func:`scored_landing` refuses ``result``: its momentum balance, or a figure not finite."""
    if result.momentum_balance > BALANCE_CHECK:
        return f"the landing's momentum balance {result.momentum_balance:.1e} is beyond {BALANCE_CHECK:g}"
    return LANDING_NOT_FINITE


def scored_landing(result: LandingResult) -> Objectives | None:
    """:func:`landing_objectives`, or None where a value is not finite or the landing's own
    momentum balance ends beyond the contract's (:data:`~impulse_core.timedomain.landing.BALANCE_CHECK`:
    its totals miss impulse)."""
    found = landing_objectives(result)
    finite = all(math.isfinite(v) for _, v in found.items())
    return found if finite and result.momentum_balance <= BALANCE_CHECK else None


def evaluate_design_landing(
    leg: Leg | LegChain, design: FootDesign, scene: Scene, limits: FootLimits, stop_restitution: float, tolerance: float
) -> DesignEvaluation:
    """The whole landing of one design (``scene.duration``), its objectives and constraints.

    The scene is that of the design's model file (:func:`landing_scene`), so that ``footopt
    evaluate --tolerance tolerance`` on it gives the same figures. A landing that fails
    numerically, or that :func:`scored_landing` refuses, gives no objectives. ``energy_gain`` is
    the largest gain of any impact.
    """
    tree = foot_tree(leg, design)
    laws = foot_joint_laws(leg, design, stop_restitution)
    geometric = constraint_values(leg, design, limits)
    try:
        with np.errstate(all="ignore"):
            result = landing(tree, landing_scene(scene, limits), laws, study_landing(tolerance), foot_space(leg, design))
    except (NumericalError, ArithmeticError, np.linalg.LinAlgError, ValueError) as error:
        return DesignEvaluation(design, None, geometric, failure_line(error))
    objectives = scored_landing(result)
    if objectives is None:
        return DesignEvaluation(design, None, geometric, unscored_why(result))
    gain = max(e.energy_after - e.energy_before for e in result.events)
    return DesignEvaluation(design, objectives, replace(geometric, energy_gain=float(gain)))


__all__ = [
    "FEASIBILITY_TOL",
    "FAILED",
    "LANDING_NOT_FINITE",
    "NOT_FINITE",
    "failure_line",
    "unscored_why",
    "ConstraintValues",
    "SupportConstraintValues",
    "constraint_record",
    "DesignEvaluation",
    "DesignSpace",
    "FootDesign",
    "FootGeometry",
    "FootLimits",
    "FootShape",
    "SplayMode",
    "SplaySpace",
    "JOINT_FAMILIES",
    "JointLawSpace",
    "JointRanges",
    "LANDING_OBJECTIVES",
    "Leg",
    "LegChain",
    "LengthAssignment",
    "MassMode",
    "Objective",
    "Objectives",
    "Segment",
    "ToeSymmetry",
    "absolute_angles",
    "assign_lengths",
    "chain_names",
    "constraint_values",
    "design_from",
    "design_model",
    "evaluate_design",
    "evaluate_design_landing",
    "landing_objectives",
    "scored_landing",
    "foot_geometry",
    "foot_joint_laws",
    "foot_space",
    "leg_chain",
    "foot_support_margin",
    "symmetric_yaws",
    "yaw_rpy",
    "foot_tree",
    "intended_contacts",
    "landing_scene",
    "newton_impulses",
    "base_turn",
    "objectives",
    "segment_names",
    "segment_suffixes",
    "with_lengths",
]
