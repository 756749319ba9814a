"""A robot description as links and joints, independent of its file format.

Every link has a frame; a joint places its child's frame in its parent's at the zero
configuration (``origin``, ``rotation``) and, when it moves, turns the child about ``axis`` (a unit
vector in the child's frame, through the child frame's origin). Mass properties are each link's
own: mass, centre of mass and inertia tensor about it, in the link's frame. A revolute joint's
laws (stops, damper, spring) are in the file's own joint coordinate (:class:`Dynamics`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from optimizer.errors import ConfigError

#: A movable joint footopt can carry (one rod turning on a passive revolute joint).
REVOLUTE = "revolute"
#: A welded joint: its child is merged into its parent.
FIXED = "fixed"


@dataclass(frozen=True)
class Link:
    """One rigid link: ``mass`` (kg), ``com`` (m, link frame), ``inertia`` (kg m^2, about the
    centre of mass, link frame axes)."""

    name: str
    mass: float
    com: np.ndarray
    inertia: np.ndarray


@dataclass(frozen=True)
class Dynamics:
    """A revolute joint's laws as the file states them, in its joint coordinate (rad): ``limits``
    (lower, upper; None: none), ``damping`` (N m s/rad), ``stiffness`` (N m/rad) of a spring about
    ``springref``; ``ref`` is the coordinate's value at the pose the links are placed in (MJCF
    ``ref``; URDF 0); ``unsupported``: (name, value) of the non-zero laws footopt has no key for
    (URDF friction, MJCF armature and frictionloss)."""

    limits: tuple[float, float] | None = None
    damping: float = 0.0
    stiffness: float = 0.0
    springref: float = 0.0
    ref: float = 0.0
    unsupported: tuple[tuple[str, float], ...] = ()


@dataclass(frozen=True)
class Joint:
    """The joint above ``child``: ``kind`` is ``revolute``, ``fixed`` or the format's name of a kind
    footopt does not carry (``prismatic``, ``ball``, ...)."""

    name: str
    kind: str
    parent: str
    child: str
    origin: np.ndarray
    rotation: np.ndarray
    axis: np.ndarray
    dynamics: Dynamics = field(default_factory=Dynamics)


@dataclass(frozen=True)
class Description:
    """A parsed description: links by name, each link's joint by child name, and named points
    (MJCF sites and geoms: ``(link, position in its frame)``)."""

    path: Path
    format: str  # "URDF" or "MJCF"
    links: dict[str, Link]
    joints: dict[str, Joint]
    points: dict[str, tuple[str, np.ndarray]] = field(default_factory=dict)

    def children(self, link: str) -> list[Joint]:
        """The joints whose parent is ``link``, in file order."""
        return [j for j in self.joints.values() if j.parent == link]

    def error(self, where: str, message: str) -> ConfigError:
        """A ConfigError about this description naming ``where`` (an option or a field)."""
        return ConfigError(f"{where}: {message}", self.path)


def unit(v: np.ndarray, where: str, source: Path) -> np.ndarray:
    """``v`` made unit length; ConfigError naming ``where`` if it is zero or not finite."""
    n = float(np.linalg.norm(v))
    if not np.all(np.isfinite(v)) or n < 1e-12:
        raise ConfigError(f"{where}: the joint axis must be a non-zero vector, got {list(map(float, v))}", source)
    return np.asarray(v, dtype=float) / n


def check_xml_safe(text: str, path: Path) -> None:
    """Refuse XML with a document type declaration: entity declarations are the only way an XML
    file acts beyond its own text (expansion bombs, external entities); robot descriptions do
    not need them."""
    if "<!DOCTYPE" in text or "<!ENTITY" in text:
        raise ConfigError("has a <!DOCTYPE> or <!ENTITY> declaration: footopt does not read XML with entities", path)


__all__ = ["FIXED", "REVOLUTE", "Description", "Dynamics", "Joint", "Link", "check_xml_safe", "unit"]
