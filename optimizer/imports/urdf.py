"""URDF as a :class:`~optimizer.imports.description.Description`, read with ``xml.etree`` (no
entities, nothing executed; mesh files are not opened).

URDF: a link's ``<inertial>`` holds its mass, the centre of mass (``origin xyz``) and the inertia
tensor about it in the frame turned by ``origin rpy``; a joint's ``<origin>`` places the child
frame in the parent's and ``<axis>`` (default 1 0 0) is in the child frame. ``revolute`` and
``continuous`` joints are revolute here; ``fixed`` is fixed; others keep their URDF kind. A
``revolute`` joint's ``<limit lower upper>`` (default 0, as URDF) are its stops; ``<dynamics
damping>`` its damper, ``friction`` is kept as a law footopt cannot carry. URDF has no springs.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from impulse_core.model.rods import rotation_rpy
from optimizer.errors import ConfigError
from optimizer.imports.description import FIXED, REVOLUTE, Description, Dynamics, Joint, Link, check_xml_safe, unit

_KINDS = {"revolute": REVOLUTE, "continuous": REVOLUTE, "fixed": FIXED}


def read_urdf(path: Path, text: str) -> Description:
    """The links and joints of a URDF file's text."""
    check_xml_safe(text, path)
    try:
        robot = ET.fromstring(text)
    except ET.ParseError as e:
        raise ConfigError(f"not well-formed XML: {e}", path) from None
    if robot.tag != "robot":
        raise ConfigError(f"the root element is <{robot.tag}>, not URDF's <robot>", path)
    links: dict[str, Link] = {}
    for k, el in enumerate(robot.findall("link")):
        name = _name(el, f"link[{k}]", path)
        if name in links:
            raise ConfigError(f"link '{name}': defined twice", path)
        links[name] = _link(el, name, path)
    joints: dict[str, Joint] = {}
    for k, el in enumerate(robot.findall("joint")):
        name = _name(el, f"joint[{k}]", path)
        where = f"joint '{name}'"
        parent, child = (_child_attr(el, tag, "link", where, path) for tag in ("parent", "child"))
        for link in (parent, child):
            if link not in links:
                raise ConfigError(f"{where}: names the link '{link}', which the file does not define", path)
        if child in joints:
            raise ConfigError(f"{where}: the link '{child}' already has a parent joint ('{joints[child].name}')", path)
        kind = el.get("type", "")
        xyz, rpy = _origin(el.find("origin"), where, path)
        axis_el = el.find("axis")
        axis = _floats(axis_el.get("xyz", "1 0 0") if axis_el is not None else "1 0 0", 3, f"{where}.axis", path)
        kind = _KINDS.get(kind, kind or "(no type)")
        axis = unit(axis, f"{where}.axis", path) if kind == REVOLUTE else np.array([1.0, 0.0, 0.0])
        dynamics = _dynamics(el, where, path) if kind == REVOLUTE else Dynamics()
        joints[child] = Joint(name, kind, parent, child, xyz, rotation_rpy(tuple(rpy)), axis, dynamics)
    _check_tree(joints, path)
    return Description(path, "URDF", links, joints)


def _check_tree(joints: dict[str, Joint], path: Path) -> None:
    """ConfigError naming a joint whose chain of parents comes back to its own child: a URDF is a tree."""
    for child, joint in joints.items():
        chain, link = [child], joint.parent
        while link in joints and len(chain) <= len(joints):
            chain.append(link)
            if link == child:
                raise ConfigError(f"joint '{joint.name}': closes a loop ({' <- '.join(chain)}): a URDF is a tree", path)
            link = joints[link].parent


def _dynamics(el: ET.Element, where: str, path: Path) -> Dynamics:
    """A revolute or continuous joint's stops (``revolute`` only), damper and friction."""
    limits = None
    limit = el.find("limit")
    if el.get("type") == "revolute" and limit is not None:
        lo, hi = (float(_floats(limit.get(k, "0"), 1, f"{where}.limit.{k}", path)[0]) for k in ("lower", "upper"))
        limits = (lo, hi)
    dyn = el.find("dynamics")
    damping, friction = (0.0 if dyn is None else float(_floats(dyn.get(k, "0"), 1, f"{where}.dynamics.{k}", path)[0])
                         for k in ("damping", "friction"))
    return Dynamics(limits=limits, damping=damping, unsupported=(("friction", friction),) if friction else ())


def _link(el: ET.Element, name: str, path: Path) -> Link:
    inertial = el.find("inertial")
    if inertial is None:
        return Link(name, 0.0, np.zeros(3), np.zeros((3, 3)))
    where = f"link '{name}'.inertial"
    xyz, rpy = _origin(inertial.find("origin"), where, path)
    mass_el = inertial.find("mass")
    mass = 0.0 if mass_el is None else float(_floats(mass_el.get("value", ""), 1, f"{where}.mass", path)[0])
    if mass < 0:
        raise ConfigError(f"{where}.mass: must be >= 0 (kg), got {mass!r}", path)
    I = np.zeros((3, 3))
    inertia_el = inertial.find("inertia")
    if inertia_el is not None:
        keys = {"ixx": (0, 0), "iyy": (1, 1), "izz": (2, 2), "ixy": (0, 1), "ixz": (0, 2), "iyz": (1, 2)}
        for key, (r, c) in keys.items():
            I[r, c] = I[c, r] = _floats(inertia_el.get(key, "0"), 1, f"{where}.inertia.{key}", path)[0]
    R = rotation_rpy(tuple(rpy))
    return Link(name, mass, xyz, R @ I @ R.T)


def _origin(el: ET.Element | None, where: str, path: Path) -> tuple[np.ndarray, np.ndarray]:
    if el is None:
        return np.zeros(3), np.zeros(3)
    return (_floats(el.get("xyz", "0 0 0"), 3, f"{where}.origin.xyz", path),
            _floats(el.get("rpy", "0 0 0"), 3, f"{where}.origin.rpy", path))


def _floats(text: str, n: int, where: str, path: Path) -> np.ndarray:
    try:
        values = np.array([float(x) for x in text.split()])
    except ValueError:
        values = np.array([])
    if values.size != n or not np.all(np.isfinite(values)):
        raise ConfigError(f"{where}: expected {n} finite number(s), got '{text}'", path)
    return values


def _name(el: ET.Element, where: str, path: Path) -> str:
    name = el.get("name")
    if not name:
        raise ConfigError(f"{where}: has no name", path)
    return name


def _child_attr(el: ET.Element, tag: str, attr: str, where: str, path: Path) -> str:
    sub = el.find(tag)
    value = None if sub is None else sub.get(attr)
    if not value:
        raise ConfigError(f"{where}: has no <{tag} {attr}=...>", path)
    return value


__all__ = ["read_urdf"]
