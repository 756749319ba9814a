"""Floating kinematic trees of rods and the impact scene, as immutable dataclasses.

Structure (``Topology``: parents, joint kinds, contact counts, which contacts touch) is kept
apart from values (lengths, masses, angles, ...): one compiled CasADi function serves every
design of one topology, and the values enter it as the flat vector ``p``
(see :func:`design_vector`).

Conventions (``MODEL_FORMAT.md``): SI units, radians. Every body is a rod along its own x axis
from its joint (x = 0) to its tip (x = length). Planar: x forward, y up, angles counter-clockwise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

import numpy as np

from impulse_core.errors import ModelError
from impulse_core.model.heightfield import Heightfield
from impulse_core.model.terrain import FLAT, Terrain

#: Centre of mass of a uniform rod, as a fraction of its length.
UNIFORM_COM = 0.5
#: Radius of gyration of a uniform rod about its centre, as a fraction of its length (1/sqrt(12)).
UNIFORM_GYRATION = 1.0 / math.sqrt(12.0)

#: Values per body in the design vector, in this order.
BODY_VALUES = ("length", "mass", "angle", "at", "com", "gyration")
#: A spatial model's values per body: the planar ones, then the fixed rotation ``rpy`` (roll,
#: pitch, yaw: Rz(yaw) Ry(pitch) Rx(roll), as in URDF), the joint ``axis`` and the rod's ``radius``.
SPATIAL_BODY_VALUES = BODY_VALUES + ("roll", "pitch", "yaw", "axis_x", "axis_y", "axis_z", "radius")
#: A spatial body's general mass properties, appended after ``SPATIAL_BODY_VALUES``'s rod values:
#: the centre of mass's offset from the rod's axis along the body frame's y and z (m), and six
#: entries of an inertia tensor about the centre of mass, body axes (kg m^2), ADDED to the rod's
#: own (diag(m r^2 / 2, I, I)); all zero for a rod (MODEL_FORMAT "Spatial models": ``com_offset``,
#: ``inertia_tensor``).
TENSOR_VALUES = ("ixx", "iyy", "izz", "ixy", "ixz", "iyz")
SPATIAL_BODY_VALUES = SPATIAL_BODY_VALUES + ("com_y", "com_z") + TENSOR_VALUES
#: A planar model whose centres of mass lie off the rods (in the plane): the planar values, then
#: the offset along each body frame's y (``com_offset`` [dy, 0]; MODEL_FORMAT "Bodies").
PLANAR_OFFSET_VALUES = BODY_VALUES + ("com_y",)
#: Where each body value may lie: (lowest, whether the lowest itself is allowed, highest); every
#: value is also finite. :func:`validate_tree` enforces them one tree at a time, the batch
#: evaluator (``impulse_core.compile.batch``) on whole arrays of design vectors.
VALUE_BOUNDS = {
    "length": (0.0, False, math.inf),
    "mass": (0.0, False, math.inf),
    "angle": (-math.inf, False, math.inf),
    "at": (0.0, True, 1.0),
    "com": (0.0, True, 1.0),
    "gyration": (0.0, True, math.inf),
    "roll": (-math.inf, False, math.inf),
    "pitch": (-math.inf, False, math.inf),
    "yaw": (-math.inf, False, math.inf),
    "axis_x": (-math.inf, False, math.inf),
    "axis_y": (-math.inf, False, math.inf),
    "axis_z": (-math.inf, False, math.inf),
    "radius": (0.0, True, math.inf),
    "com_y": (-math.inf, False, math.inf),
    "com_z": (-math.inf, False, math.inf),
    "ixx": (0.0, True, math.inf),
    "iyy": (0.0, True, math.inf),
    "izz": (0.0, True, math.inf),
    "ixy": (-math.inf, False, math.inf),
    "ixz": (-math.inf, False, math.inf),
    "iyz": (-math.inf, False, math.inf),
}
#: A tensor is taken as physical (positive semidefinite, each principal moment at most the sum
#: of the other two) within this fraction of its trace (round-off of a tensor rotated or summed).
TENSOR_TOLERANCE = 1e-12
#: The same for every contact fraction.
CONTACT_BOUNDS = (0.0, True, 1.0)


class JointKind(Enum):
    """How a body hangs from its parent. Revolute joints are passive during the impact."""

    REVOLUTE = "revolute"
    FIXED = "fixed"


class ContactSelection(Enum):
    """Which declared contacts take part in the impact."""

    ALL = "all"  # every declared contact hits at the same instant (the paper's assumption)
    LOWEST = "lowest"  # ground at the lowest contact point; contacts within a tolerance hit


@dataclass(frozen=True)
class Body:
    """One rigid rod of the tree.

    Attributes:
        name: unique name.
        parent: index of the parent body in the tree, None for the floating base (body 0).
        length: rod length (m), > 0.
        mass: mass (kg), > 0.
        angle: base: absolute angle of its x axis; others: joint angle relative to the parent (rad).
        at: where the joint sits on the parent, as a fraction of the parent's length.
        joint: revolute (passive) or fixed (welded).
        contacts: contact points on this body, as fractions of its length.
        com: centre of mass along the rod, as a fraction of its length (0.5: uniform rod).
        gyration: radius of gyration about the centre of mass, as a fraction of the length;
            inertia about the centre of mass across the rod = mass * (gyration * length)**2.
        rpy: spatial models: the fixed rotation (roll, pitch, yaw) between the parent's frame
            at the joint and the joint (Rz(yaw) Ry(pitch) Rx(roll)); planar: zero.
        axis: spatial models: the joint's axis in the frame after ``rpy`` (any length but
            zero; made unit); planar: z.
        radius: spatial models: the rod's radius (a solid cylinder: m r^2 / 2 about its own
            axis); planar: 0.
        com_offset: the centre of mass's offset (m) from the rod's axis along the body frame's y
            and z (its position along the axis stays ``com`` x length); planar: [dy, 0].
        tensor: spatial models: (ixx, iyy, izz, ixy, ixz, iyz), an inertia tensor about the centre
            of mass in body axes (kg m^2) added to the rod's own diag(m r^2 / 2, I, I); a file's
            ``inertia_tensor`` is this with ``gyration`` and ``radius`` 0. Physical (see
            :func:`tensor_problem`). Planar: 0.
    """

    name: str
    parent: int | None
    length: float
    mass: float
    angle: float
    at: float = 1.0
    joint: JointKind = JointKind.REVOLUTE
    contacts: tuple[float, ...] = ()
    com: float = UNIFORM_COM
    gyration: float = UNIFORM_GYRATION
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    radius: float = 0.0
    com_offset: tuple[float, float] = (0.0, 0.0)
    tensor: tuple[float, float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)

    @property
    def inertia(self) -> float:
        """Moment of inertia about the centre of mass, across the rod (kg m^2)."""
        return self.mass * (self.gyration * self.length) ** 2

    @property
    def axial_inertia(self) -> float:
        """Moment of inertia about the rod's own axis (kg m^2): m r^2 / 2."""
        return 0.5 * self.mass * self.radius**2

    @property
    def is_planar(self) -> bool:
        """True when the body turns about z with no fixed rotation and no radius, its centre of
        mass in the plane (``com_offset`` [dy, 0]) and no tensor added."""
        return (
            self.rpy == (0.0, 0.0, 0.0)
            and self.axis == (0.0, 0.0, 1.0)
            and self.radius == 0.0
            and self.com_offset[1] == 0.0
            and not any(self.tensor)
        )

    @property
    def is_rod(self) -> bool:
        """True when the centre of mass is on the rod's axis and no tensor is added to the rod's."""
        return self.com_offset == (0.0, 0.0) and not any(self.tensor)

    roll = property(lambda self: self.rpy[0])
    pitch = property(lambda self: self.rpy[1])
    yaw = property(lambda self: self.rpy[2])
    axis_x = property(lambda self: self.axis[0])
    axis_y = property(lambda self: self.axis[1])
    axis_z = property(lambda self: self.axis[2])
    com_y = property(lambda self: self.com_offset[0])
    com_z = property(lambda self: self.com_offset[1])
    ixx = property(lambda self: self.tensor[0])
    iyy = property(lambda self: self.tensor[1])
    izz = property(lambda self: self.tensor[2])
    ixy = property(lambda self: self.tensor[3])
    ixz = property(lambda self: self.tensor[4])
    iyz = property(lambda self: self.tensor[5])


def tensor_matrix(t) -> np.ndarray:
    """The 3 x 3 symmetric matrix of (ixx, iyy, izz, ixy, ixz, iyz)."""
    ixx, iyy, izz, ixy, ixz, iyz = (float(x) for x in t)
    return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])


def tensor_problem(t) -> str | None:
    """Why (ixx, iyy, izz, ixy, ixz, iyz) is no rigid body's inertia about its centre of mass, or
    None: six finite numbers, positive semidefinite, and each principal moment at most the sum of
    the other two (within ``TENSOR_TOLERANCE`` x the trace)."""
    if len(t) != 6:
        return f"must be 6 numbers [ixx, iyy, izz, ixy, ixz, iyz] (kg m^2), got {len(t)}"
    if not all(math.isfinite(x) for x in t):
        return f"must be 6 finite numbers, got {list(t)}"
    moments = np.linalg.eigvalsh(tensor_matrix(t))
    tol = TENSOR_TOLERANCE * max(float(np.sum(np.abs(t[:3]))), 1e-300)
    if moments[0] < -tol:
        return (f"{list(t)} is not positive semidefinite (principal moments "
                f"{', '.join(f'{m:.6g}' for m in moments)} kg m^2)")
    if moments[2] > moments[0] + moments[1] + tol:
        return (f"{list(t)} is no rigid body's: its largest principal moment {moments[2]:.6g} exceeds the sum "
                f"of the other two ({moments[0]:.6g} + {moments[1]:.6g}; the triangle inequality)")
    return None


@dataclass(frozen=True)
class Tree:
    """A floating tree of rods, listed parents first; body 0 is the floating base."""

    bodies: tuple[Body, ...]

    def __post_init__(self) -> None:
        validate_tree(self)

    @property
    def n_bodies(self) -> int:
        return len(self.bodies)

    @property
    def contacts(self) -> tuple[tuple[int, int], ...]:
        """Declared contacts as (body index, index within the body), in declaration order."""
        return tuple((b, k) for b, body in enumerate(self.bodies) for k in range(len(body.contacts)))

    def topology(self, active: tuple[int, ...] | None = None) -> Topology:
        """The structure of this tree with the given active contacts (default: all)."""
        n_declared = len(self.contacts)
        return Topology(
            parents=tuple(-1 if b.parent is None else b.parent for b in self.bodies),
            joints=tuple(b.joint for b in self.bodies),
            n_contacts=tuple(len(b.contacts) for b in self.bodies),
            active=tuple(range(n_declared)) if active is None else tuple(active),
        )


@dataclass(frozen=True)
class Topology:
    """Hashable structure of a tree: keys one compiled impulse function.

    Attributes:
        parents: parent index per body (-1 for the base).
        joints: joint kind per body (the base's entry is ignored).
        n_contacts: number of declared contact points per body.
        active: indices (into the declared contact list) of the contacts that take part.
    """

    parents: tuple[int, ...]
    joints: tuple[JointKind, ...]
    n_contacts: tuple[int, ...]
    active: tuple[int, ...]

    @property
    def n_bodies(self) -> int:
        return len(self.parents)

    @property
    def declared_contacts(self) -> tuple[tuple[int, int], ...]:
        return tuple((b, k) for b, n in enumerate(self.n_contacts) for k in range(n))

    @property
    def active_contacts(self) -> tuple[tuple[int, int], ...]:
        declared = self.declared_contacts
        return tuple(declared[i] for i in self.active)

    @property
    def n_values(self) -> int:
        """Length of a planar design vector (spatial: ``kinematics.spatial.n_values``)."""
        return len(BODY_VALUES) * self.n_bodies + sum(self.n_contacts)

    def with_active(self, active: tuple[int, ...]) -> Topology:
        return Topology(self.parents, self.joints, self.n_contacts, tuple(active))


@dataclass(frozen=True)
class Scene:
    """The landing: the whole tree moves as one rigid body onto the ground (joints at rest
    relative to their parents): its base origin at (velocity_x, -speed), turning at
    angular_velocity about z (default: straight down).

    Attributes:
        speed: downward speed of the base origin (m/s), > 0.
        velocity_x: horizontal (+x) velocity of the base origin (m/s).
        angular_velocity: the base's (and every body's) angular velocity about z (rad/s).
        velocity_z, angular_velocity_x, angular_velocity_y: the rest of a spatial approach
            (lateral velocity; angular velocity about x and y), world frame; 0 in the plane.
        restitution: Newton's coefficient e in [0, 1].
        friction: Coulomb coefficient (0: frictionless; > 0: the FRICTION rung of contact_models).
        selection: which contacts hit (rigid rungs; the time-domain models let the geometry decide).
        contact_tolerance: with ``LOWEST``, contacts within this height (m) of the lowest hit.
        terrain: the ground profile (world frame; default flat at y = 0). The rigid rungs
            (``impulse_core.evaluate``) need it flat (``Terrain.is_flat``; the first instant on it:
            ``impulse_core.timedomain.first_instant``); the sequential and
            compliant models (``impulse_core.timedomain.sequential``, ``impulse_core.timedomain.compliant``) follow it.
        base_x: x (m) of the base origin at touchdown: the tree keeps its touchdown angles, sits
            with its base origin at ``base_x`` and is lowered straight down until the contact with
            the smallest vertical clearance touches the terrain. Irrelevant on flat ground.
        base_z: spatial: z (m) of the base origin at touchdown (as ``base_x``).
        heightfield: spatial: the ground y = h(x, z) (``impulse_core.model.heightfield``), or None
            (flat, as ``terrain`` says). The flat rungs need it flat (the first instant on it:
            ``impulse_core.timedomain.first_instant``); the time-domain models follow it.
        gravity: m/s^2 along -y (acts between impacts: the whole landing).
        duration: the whole landing's length (s) from the first touchdown, or None (first impact).
    """

    speed: float = 3.43
    restitution: float = 0.8
    friction: float = 0.0
    selection: ContactSelection = ContactSelection.LOWEST
    contact_tolerance: float = 1e-6
    terrain: Terrain = FLAT
    base_x: float = 0.0
    velocity_x: float = 0.0
    angular_velocity: float = 0.0
    velocity_z: float = 0.0
    angular_velocity_x: float = 0.0
    angular_velocity_y: float = 0.0
    gravity: float = 0.0
    duration: float | None = None
    base_z: float = 0.0
    heightfield: Heightfield | None = None

    def __post_init__(self) -> None:
        _require(math.isfinite(self.speed) and self.speed > 0, "scene.speed", f"must be > 0, got {self.speed}")
        _require(math.isfinite(self.velocity_x), "scene.velocity", f"must be finite, got {self.velocity_x}")
        for name in ("velocity_z", "angular_velocity_x", "angular_velocity_y"):
            value = getattr(self, name)
            _require(math.isfinite(value), f"scene.{name}", f"must be finite, got {value}")
        _require(
            math.isfinite(self.angular_velocity),
            "scene.angular_velocity",
            f"must be finite, got {self.angular_velocity}",
        )
        _require(
            math.isfinite(self.restitution) and 0.0 <= self.restitution <= 1.0,
            "scene.restitution",
            f"must be in [0, 1], got {self.restitution}",
        )
        _require(
            math.isfinite(self.friction) and self.friction >= 0.0,
            "scene.friction",
            f"must be >= 0, got {self.friction}",
        )
        _require(
            math.isfinite(self.contact_tolerance) and self.contact_tolerance >= 0.0,
            "scene.contact_tolerance",
            f"must be >= 0, got {self.contact_tolerance}",
        )
        _require(
            isinstance(self.terrain, Terrain),
            "scene.terrain",
            f"must be a Terrain (impulse_core.model.terrain), got {type(self.terrain).__name__}",
        )
        _require(
            isinstance(self.base_x, (int, float)) and not isinstance(self.base_x, bool) and math.isfinite(self.base_x),
            "scene.base_x",
            f"must be a finite number (m), got {self.base_x!r}",
        )
        _require(
            isinstance(self.base_z, (int, float)) and not isinstance(self.base_z, bool) and math.isfinite(self.base_z),
            "scene.base_z",
            f"must be a finite number (m), got {self.base_z!r}",
        )
        _require(
            self.heightfield is None or isinstance(self.heightfield, Heightfield),
            "scene.heightfield",
            f"must be a Heightfield (impulse_core.model.heightfield), got {type(self.heightfield).__name__}",
        )
        _require(
            math.isfinite(self.gravity) and self.gravity >= 0.0, "scene.gravity", f"must be >= 0, got {self.gravity}"
        )
        _require(
            self.duration is None or (math.isfinite(self.duration) and self.duration > 0.0),
            "scene.duration",
            f"must be > 0 (s), got {self.duration}",
        )

    @property
    def ground_is_flat(self) -> bool:
        """True when the ground (``terrain``, and ``heightfield`` where given) is horizontal."""
        return self.terrain.is_flat and (self.heightfield is None or self.heightfield.is_flat)

    @property
    def straight_down(self) -> bool:
        """True when the approach is a pure downward translation (the paper's landing)."""
        return self.velocity_x == 0.0 and self.angular_velocity == 0.0 and not self.out_of_plane

    @property
    def out_of_plane(self) -> bool:
        """True when the approach has a lateral velocity or turns about x or y (spatial only)."""
        return (self.velocity_z, self.angular_velocity_x, self.angular_velocity_y) != (0.0, 0.0, 0.0)

    @property
    def velocity(self) -> tuple[float, float, float]:
        """The base origin's velocity at touchdown (world frame, m/s)."""
        return (self.velocity_x, -self.speed, self.velocity_z)

    @property
    def angular_velocity_3d(self) -> tuple[float, float, float]:
        """The base's angular velocity at touchdown (world frame, rad/s)."""
        return (self.angular_velocity_x, self.angular_velocity_y, self.angular_velocity)


def _require(ok: bool, where: str, problem: str) -> None:
    if not ok:
        raise ModelError(f"{where}: {problem}")


def validate_tree(tree: Tree) -> None:
    """Raise ModelError naming the body field at fault (``model.bodies[i].field``)."""
    if not tree.bodies:
        raise ModelError("model.bodies: must list at least one body")
    names: set[str] = set()
    for i, b in enumerate(tree.bodies):
        where = f"model.bodies[{i}]"
        _require(bool(b.name), f"{where}.name", "must be a non-empty string")
        _require(b.name not in names, f"{where}.name", f"duplicate body name '{b.name}'")
        names.add(b.name)
        if i == 0:
            _require(b.parent is None, f"{where}.parent", "the first body is the floating base and has no parent")
        else:
            _require(b.parent is not None, f"{where}.parent", "missing (only the first body is the base)")
            assert b.parent is not None
            _require(
                0 <= b.parent < i,
                f"{where}.parent",
                "must name a body listed before this one (bodies are listed parents first)",
            )
        for field_name in ("length", "mass"):
            v = getattr(b, field_name)
            _require(math.isfinite(v) and v > 0, f"{where}.{field_name}", f"must be a finite number > 0, got {v}")
        for field_name in ("angle", "at", "com", "gyration"):
            v = getattr(b, field_name)
            _require(math.isfinite(v), f"{where}.{field_name}", f"must be a finite number, got {v}")
        _require(0.0 <= b.at <= 1.0, f"{where}.at", f"must be in [0, 1] (a point on the parent), got {b.at}")
        _require(0.0 <= b.com <= 1.0, f"{where}.com", f"must be in [0, 1] (a point on the rod), got {b.com}")
        _require(b.gyration >= 0.0, f"{where}.gyration", f"must be >= 0, got {b.gyration}")
        _require(
            len(b.rpy) == 3 and all(math.isfinite(x) for x in b.rpy), f"{where}.rpy", f"must be 3 finite numbers, got {b.rpy}"
        )
        _require(
            len(b.axis) == 3 and all(math.isfinite(x) for x in b.axis) and math.hypot(*b.axis) > 1e-12,
            f"{where}.axis",
            f"must be a non-zero finite 3-vector, got {b.axis}",
        )
        _require(math.isfinite(b.radius) and b.radius >= 0.0, f"{where}.radius", f"must be >= 0 (m), got {b.radius}")
        _require(
            len(b.com_offset) == 2 and all(math.isfinite(x) for x in b.com_offset),
            f"{where}.com_offset",
            f"must be 2 finite numbers [dy, dz] (m), got {b.com_offset}",
        )
        problem = tensor_problem(b.tensor) if len(b.tensor) != 6 or any(b.tensor) else None
        _require(problem is None, f"{where}.inertia_tensor", problem or "")
        for k, c in enumerate(b.contacts):
            _require(
                math.isfinite(c) and 0.0 <= c <= 1.0,
                f"{where}.contacts[{k}]",
                f"must be a fraction of the body's length in [0, 1], got {c}",
            )
    if not any(b.contacts for b in tree.bodies):
        raise ModelError("model.bodies: no body declares a contact point")


def design_vector(tree: Tree, body_values: tuple[str, ...] = BODY_VALUES) -> np.ndarray:
    """The values of a tree as the flat vector ``p`` the compiled functions take.

    Layout: for each body, ``body_values`` in order (``BODY_VALUES`` in the plane,
    ``PLANAR_OFFSET_VALUES`` in the plane with centres of mass off the rods, ``SPATIAL_BODY_VALUES``
    in space); then every declared contact fraction.

    Raises:
        ModelError: naming ``model.bodies[i].com_offset`` when a body's centre of mass is off its
            rod and the layout has no ``com_y`` (a computation that takes rods only).
    """
    if "com_y" not in body_values:
        for i, b in enumerate(tree.bodies):
            if b.com_offset != (0.0, 0.0):
                raise ModelError(f"model.bodies[{i}].com_offset: a centre of mass off the rod is read by the rigid "
                                 "impact models, the time-domain ones (sequential, compliant, landing) and spatial "
                                 "models; this computation takes planar rods only (a leg from footopt import: "
                                 "--com-on-rods)")
    per_body = [[getattr(b, name) for name in body_values] for b in tree.bodies]
    contacts = [c for b in tree.bodies for c in b.contacts]
    return np.array([v for row in per_body for v in row] + contacts, dtype=float)


def value_names(tree: Tree, body_values: tuple[str, ...] = BODY_VALUES) -> tuple[str, ...]:
    """Names of the entries of :func:`design_vector`, e.g. ``shank.length``, ``heel.contacts[0]``."""
    names = [f"{b.name}.{v}" for b in tree.bodies for v in body_values]
    names += [f"{b.name}.contacts[{k}]" for b in tree.bodies for k in range(len(b.contacts))]
    return tuple(names)


def with_values(tree: Tree, p: np.ndarray, body_values: tuple[str, ...] = BODY_VALUES) -> Tree:
    """A copy of ``tree`` with the values taken from the flat vector ``p`` (layout of
    :func:`design_vector` with the same ``body_values``)."""
    p = np.asarray(p, dtype=float).ravel()
    n = len(body_values)
    offset = n * tree.n_bodies
    bodies = []
    for i, b in enumerate(tree.bodies):
        vals = dict(zip(body_values, (float(x) for x in p[n * i : n * (i + 1)])))
        k = len(b.contacts)
        contacts = tuple(float(x) for x in p[offset : offset + k])
        offset += k
        spatial = {
            "rpy": tuple(vals.pop(name, old) for name, old in zip(("roll", "pitch", "yaw"), b.rpy)),
            "axis": tuple(vals.pop(name, old) for name, old in zip(("axis_x", "axis_y", "axis_z"), b.axis)),
            "radius": vals.pop("radius", b.radius),
            "com_offset": tuple(vals.pop(name, old) for name, old in zip(("com_y", "com_z"), b.com_offset)),
            "tensor": tuple(vals.pop(name, old) for name, old in zip(TENSOR_VALUES, b.tensor)),
        }
        bodies.append(Body(name=b.name, parent=b.parent, joint=b.joint, contacts=contacts, **vals, **spatial))
    return Tree(tuple(bodies))


__all__ = [
    "BODY_VALUES",
    "PLANAR_OFFSET_VALUES",
    "CONTACT_BOUNDS",
    "SPATIAL_BODY_VALUES",
    "TENSOR_VALUES",
    "VALUE_BOUNDS",
    "Body",
    "ContactSelection",
    "JointKind",
    "Scene",
    "Topology",
    "Tree",
    "design_vector",
    "tensor_matrix",
    "tensor_problem",
    "value_names",
    "with_values",
]
