"""Model files (``MODEL_FORMAT.md``): read, validate and write one tree and its landing scene.

A model file is YAML (JSON is valid YAML) read with the YAML 1.2 core schema, so ``1e-6`` is a
number. It is parsed once into frozen dataclasses (:class:`ModelFile`, the core's ``Tree`` and
``Scene``, :class:`Reference`); every bad input becomes a :class:`ConfigError` whose one-line
message starts with the YAML path of the field at fault.

Extensions to the contract (a file without them means what the contract says):
    - body ``com``: centre of mass as a fraction of the length (default 0.5);
    - body ``inertia``: moment of inertia about the centre of mass, z axis (kg m^2; default
      that of a uniform rod, mass * length^2 / 12), or ``gyration``: the radius of gyration
      about the centre of mass as a fraction of the length (the core's parameter; written by
      :func:`dump_model_file` when no float ``inertia`` reproduces it exactly);
    - scene ``contact_tolerance`` (m, default 1e-6) and ``contacts: lowest`` (the default, named);
    - scene ``terrain``: the ground profile y(x), world frame, m, as ``[[x0, y0], [x1, y1], ...]``
      with x strictly increasing, linear between the points, flat beyond the ends; one point is
      flat ground at y0 (default: flat at y = 0). newton and decoupled need it flat, lcp and friction
      give the first instant on it; the sequential and compliant models follow it;
    - scene ``base_x``: x (m) of the base origin at touchdown (default 0): the model keeps its
      touchdown angles, sits with its base origin at ``base_x`` and is lowered straight down until
      the contact with the smallest vertical clearance touches the terrain;
    - top-level ``reference`` (a paper's printed values, shown beside ours) and ``notes``.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from impulse_core.errors import ModelError
from impulse_core.kinematics.spatial import PLANAR, SPATIAL, Space
from impulse_core.model.joints import FREE, JointLaw
from impulse_core.model.heightfield import Heightfield
from impulse_core.model.terrain import FLAT, Terrain
from impulse_core.model.tree import (
    UNIFORM_COM,
    UNIFORM_GYRATION,
    Body,
    ContactSelection,
    JointKind,
    Scene,
    Tree,
    tensor_problem,
)
from optimizer.config.yaml_fields import angle as _angle
from optimizer.config.yaml_fields import describe as _describe
from optimizer.config.yaml_fields import join as _join
from optimizer.config.yaml_fields import mapping as _mapping
from optimizer.config.yaml_fields import number as _number
from optimizer.config.yaml_fields import positive as _positive
from optimizer.config.yaml_fields import required as _required
from optimizer.config.yaml_fields import string as _string
from optimizer.errors import ConfigError

TOP_KEYS = ("scene", "model", "reference", "notes")
SCENE_KEYS = (
    "speed",
    "velocity",
    "angular_velocity",
    "restitution",
    "friction",
    "contacts",
    "contact_tolerance",
    "terrain",
    "base_x",
    "base_z",
    "heightfield",
    "gravity",
    "duration",
)
MODEL_KEYS = ("bodies", "space")
BODY_KEYS = ("name", "parent", "at", "length", "mass", "angle", "joint", "contacts", "com", "inertia", "gyration")
#: A spatial model's body keys (MODEL_FORMAT "Spatial models").
SPATIAL_BODY_KEYS = ("rpy", "axis", "radius", "com_offset", "inertia_tensor")
#: ``model.space``.
SPACES = {"planar": PLANAR, "spatial": SPATIAL}
#: A revolute joint's spring, damper and stops (``impulse_core.model.joints.JointLaw``).
JOINT_LAW_KEYS = ("stiffness", "damping", "rest", "limits", "stop_restitution")
REFERENCE_KEYS = ("source", "external", "internal", "external_norm", "internal_norm", "note")

_DEFAULT_TOLERANCE = Scene().contact_tolerance


# --------------------------------------------------------------------------------------------
# YAML 1.2 core schema on PyYAML


class Yaml12Loader(yaml.SafeLoader):
    """PyYAML's safe loader with the YAML 1.2 core schema's implicit types.

    PyYAML implements YAML 1.1: ``1e-6`` (no dot) is a string there, ``010`` is octal, ``yes``
    and ``off`` are booleans, ``2021-05-01`` is a date. Here plain scalars resolve as YAML 1.2
    reads them: null (``~``, ``null``, empty), booleans (``true``/``false``), integers (decimal,
    ``0o`` octal, ``0x`` hex) and floats (``1e-6``, ``2E3``, ``.5``, ``-1.5e+3``, ``.inf``,
    ``.nan``); everything else is a string.
    """

    yaml_implicit_resolvers: dict[Any, list[tuple[str, re.Pattern[str]]]] = {}


Yaml12Loader.add_implicit_resolver(
    "tag:yaml.org,2002:null", re.compile(r"^(?:~|null|Null|NULL|)$"), ["~", "n", "N", ""]
)
Yaml12Loader.add_implicit_resolver(
    "tag:yaml.org,2002:bool", re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$"), list("tTfF")
)
# Integers before floats: a plain "3" is an int (then read as 3.0 where a number is expected).
Yaml12Loader.add_implicit_resolver(
    "tag:yaml.org,2002:int", re.compile(r"^(?:[-+]?[0-9]+|0o[0-7]+|0x[0-9a-fA-F]+)$"), list("-+0123456789")
)
Yaml12Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(
        r"^(?:[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?"
        r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$"
    ),
    list("-+.0123456789"),
)
Yaml12Loader.add_implicit_resolver("tag:yaml.org,2002:merge", re.compile(r"^(?:<<)$"), ["<"])


def _construct_int(loader: yaml.SafeLoader, node: yaml.ScalarNode) -> int:
    text = str(loader.construct_scalar(node))
    if text.startswith("0o"):
        return int(text[2:], 8)
    if text.startswith("0x"):
        return int(text[2:], 16)
    return int(text)  # decimal, leading zeros allowed ("010" is ten in YAML 1.2)


Yaml12Loader.add_constructor("tag:yaml.org,2002:int", _construct_int)


def load_yaml(text: str, source: str | Path | None = None) -> Any:
    """Parse YAML text with the YAML 1.2 core schema (see :class:`Yaml12Loader`).

    Args:
        text: the document.
        source: the file it came from, recorded on errors.

    Returns:
        The plain data (dicts, lists, str, int, float, bool, None); None for an empty document.

    Raises:
        ConfigError: a syntax error (with line and column), several documents, or a key
            repeated in one mapping (named by its YAML path).
    """
    loader = Yaml12Loader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        _check_duplicate_keys(node, "", set())
        return loader.construct_document(node)
    except ConfigError:
        raise
    except yaml.MarkedYAMLError as e:
        raise ConfigError(_yaml_error_message(e), source) from None
    except (yaml.YAMLError, ValueError) as e:
        raise ConfigError(f"YAML error: {e}", source) from None
    except RecursionError:
        raise ConfigError("YAML: nested too deeply", source) from None
    finally:
        loader.dispose()


def _yaml_error_message(e: yaml.MarkedYAMLError) -> str:
    if isinstance(e, yaml.composer.ComposerError) and e.context and "single document" in e.context:
        return f"YAML: a second document starts{_mark(e.problem_mark)}; a model file holds one"
    context = f" ({e.context}{_mark(e.context_mark)})" if e.context else ""
    return f"YAML syntax error{_mark(e.problem_mark)}: {e.problem or 'invalid YAML'}{context}"


def _mark(mark: yaml.Mark | None) -> str:
    return "" if mark is None else f" at line {mark.line + 1}, column {mark.column + 1}"


def _check_duplicate_keys(node: yaml.Node, path: str, seen: set[int]) -> None:
    """Reject a key given twice in one mapping (PyYAML would keep the last one silently)."""
    if id(node) in seen:  # an alias: already checked (and anchors may be recursive)
        return
    seen.add(id(node))
    if isinstance(node, yaml.MappingNode):
        keys: dict[str, str] = {}
        for key_node, value_node in node.value:
            if isinstance(key_node, yaml.ScalarNode) and key_node.tag != "tag:yaml.org,2002:merge":
                key = key_node.value
                mark = key_node.start_mark
                at = f"line {mark.line + 1}, column {mark.column + 1}"
                if key in keys:
                    raise ConfigError(f"{_join(path, key)}: duplicate key (at {keys[key]} and {at})")
                keys[key] = at
                _check_duplicate_keys(value_node, _join(path, key), seen)
            else:
                _check_duplicate_keys(value_node, path, seen)
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            _check_duplicate_keys(item, f"{path}[{i}]", seen)


# --------------------------------------------------------------------------------------------
# Parsed file


@dataclass(frozen=True)
class Reference:
    """Published values to print beside ours (e.g. the paper's table); None where unknown.

    Attributes:
        source: where the values come from.
        external: normal impulse per declared contact, declaration order (N s).
        internal: joint impulse magnitude per non-base body, file order (N s).
        external_norm, internal_norm: norms of those (N s).
        note: free text.
    """

    source: str | None = None
    external: tuple[float | None, ...] | None = None
    internal: tuple[float | None, ...] | None = None
    external_norm: float | None = None
    internal_norm: float | None = None
    note: str | None = None


@dataclass(frozen=True)
class ModelFile:
    """One model file: the tree, its landing scene, and optional reference values and notes.

    Attributes:
        tree: the floating tree of rods.
        scene: the landing.
        joints: each body's joint law (spring, damper, stops; the base's entry is free), or ()
            when no joint has one.
        reference: published values for comparison, or None.
        notes: free text (the top-level ``notes``), ignored by the evaluation.
        path: the file it was read from (not part of equality).
        space: ``model.space`` (PLANAR or SPATIAL).
    """

    tree: Tree
    scene: Scene
    reference: Reference | None = None
    notes: str | None = None
    path: Path | None = field(default=None, compare=False)
    joints: tuple[JointLaw, ...] = ()
    space: Space = PLANAR

    def __post_init__(self) -> None:
        if self.joints and len(self.joints) != self.tree.n_bodies:
            raise ConfigError(f"joints: {len(self.joints)} joint laws for {self.tree.n_bodies} bodies")
        ref = self.reference
        if ref is None:
            return
        n_contacts = len(self.tree.contacts)
        if ref.external is not None and len(ref.external) != n_contacts:
            raise ConfigError(
                f"reference.external: has {len(ref.external)} entries, the model declares {n_contacts} "
                "contacts (one per contact, in declaration order; null where unknown)"
            )
        n_joints = self.tree.n_bodies - 1
        if ref.internal is not None and len(ref.internal) != n_joints:
            raise ConfigError(
                f"reference.internal: has {len(ref.internal)} entries, the model has {n_joints} joints "
                "(one per non-base body, in file order; null where unknown)"
            )


def load_model_file(path: str | Path) -> ModelFile:
    """Read and validate a model file.

    Raises:
        ConfigError: the file is missing or unreadable, is not YAML, or a field is wrong; the
            message names the field (``model.bodies[2].mass: ...``), ``source`` the file.
    """
    path = Path(path)
    text = read_text(path, "model file")
    try:
        return parse_model(load_yaml(text, path), path)
    except ConfigError as e:
        e.source = e.source or path
        raise


def read_text(path: Path, what: str) -> str:
    """The UTF-8 text of a config file, or ConfigError saying why it cannot be read."""
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError("file not found", path) from None
    except IsADirectoryError:
        raise ConfigError(f"is a directory, not a {what}", path) from None
    except UnicodeDecodeError as e:
        raise ConfigError(f"not a UTF-8 text file (byte {e.start})", path) from None
    except OSError as e:
        raise ConfigError(f"cannot read the file: {e.strerror or e}", path) from None


def parse_model(data: Any, path: str | Path | None = None) -> ModelFile:
    """Validate already-loaded model data (a mapping as in ``MODEL_FORMAT.md``).

    Args:
        data: the loaded YAML/JSON document.
        path: the file it came from, kept on the result and on errors.

    Raises:
        ConfigError: naming the first bad field.
    """
    source = None if path is None else Path(path)
    try:
        if data is None:
            raise ConfigError("empty file: expected a mapping with 'scene' and 'model'")
        top = _mapping(data, "", TOP_KEYS, what="the top level")
        space = parse_space(_required(top, "model", ""))
        scene = parse_scene(_required(top, "scene", ""), spatial=space is SPATIAL)
        tree = parse_tree(top["model"])
        joints = parse_joint_laws(top["model"], tree)
        reference = parse_reference(top["reference"]) if top.get("reference") is not None else None
        notes = _optional_string(top, "notes", "")
        return ModelFile(
            tree=tree, scene=scene, reference=reference, notes=notes, path=source, joints=joints, space=space
        )
    except ModelError as e:  # the dataclasses' own checks, already named by field
        raise ConfigError(str(e), source) from None
    except ConfigError as e:
        e.source = e.source or source
        raise


def parse_space(data: Any, where: str = "model") -> Space:
    """``model.space``: planar (default) or spatial."""
    m = _mapping(data, where, MODEL_KEYS)
    raw = m.get("space", "planar")
    if raw not in SPACES:
        raise ConfigError(f"{where}.space: must be one of {', '.join(SPACES)}, got {_describe(raw)}")
    return SPACES[raw]


def _vector(value: Any, where: str, names: str, spatial: bool = True, unit: str = " (m/s)") -> tuple[float, ...]:
    """A list of numbers named ``names`` (e.g. "vx, vy"); ``spatial`` False adds the hint that
    a 3-vector needs a spatial model."""
    n = names.count(",") + 1
    if not isinstance(value, list) or len(value) != n:
        hint = "" if spatial else " (a 3-vector needs 'model.space: spatial')"
        raise ConfigError(f"{where}: must be [{names}]{unit}{hint}, got {_describe(value)}")
    return tuple(_number(x, f"{where}[{i}]") for i, x in enumerate(value))


def _approach(m: dict[str, Any], where: str, spatial: bool = False) -> tuple[float, float, float]:
    """(velocity_x, speed, velocity_z) from ``speed: s`` (straight down) or ``velocity: [vx, vy]``
    (spatial: ``[vx, vy, vz]``, or a planar file's ``[vx, vy]``), vy < 0."""
    if "velocity" in m and "speed" in m:
        raise ConfigError(f"{where}.velocity: give speed (straight down) or velocity, not both")
    if "velocity" not in m:
        speed = _number(_required(m, "speed", where), f"{where}.speed")
        if speed <= 0:
            raise ConfigError(f"{where}.speed: must be > 0 (m/s, straight down), got {speed!r}")
        return 0.0, speed, 0.0
    raw = m["velocity"]
    names = "vx, vy, vz" if spatial and not (isinstance(raw, list) and len(raw) == 2) else "vx, vy"
    v = _vector(raw, f"{where}.velocity", names, spatial) + (0.0,)  # a planar [vx, vy] is also spatial
    if v[1] >= 0:
        raise ConfigError(f"{where}.velocity[1]: must be < 0 (the model comes down onto the ground), got {v[1]!r}")
    return v[0], -v[1], v[2]


def _angular_velocity(m: dict[str, Any], where: str, spatial: bool) -> tuple[float, float, float]:
    """(wx, wy, wz): one number about z in the plane; in space ``[wx, wy, wz]`` or that number."""
    raw = m.get("angular_velocity", 0.0)
    if spatial and isinstance(raw, list):  # a planar file's number (about z) stays valid in space
        return _vector(raw, where, "wx, wy, wz", unit=" (rad/s)")  # type: ignore[return-value]
    if isinstance(raw, list):
        raise ConfigError(f"{where}: a planar model turns about z only: one number (rad/s); [wx, wy, wz] needs 'model.space: spatial'")
    return 0.0, 0.0, _number(raw, where)


def parse_scene(data: Any, where: str = "scene", spatial: bool = False) -> Scene:
    """Validate the ``scene`` block into a core ``Scene`` (``spatial``: 3-vector velocities)."""
    m = _mapping(data, where, SCENE_KEYS)
    velocity_x, speed, velocity_z = _approach(m, where, spatial)
    wx, wy, angular_velocity = _angular_velocity(m, f"{where}.angular_velocity", spatial)
    restitution = _number(_required(m, "restitution", where), f"{where}.restitution")
    if not 0.0 <= restitution <= 1.0:
        raise ConfigError(f"{where}.restitution: must be in [0, 1], got {restitution!r}")
    friction = _number(m.get("friction", 0.0), f"{where}.friction")
    if friction < 0:
        raise ConfigError(f"{where}.friction: must be >= 0, got {friction!r}")
    tolerance = _number(m.get("contact_tolerance", _DEFAULT_TOLERANCE), f"{where}.contact_tolerance")
    if tolerance < 0:
        raise ConfigError(f"{where}.contact_tolerance: must be >= 0 (m), got {tolerance!r}")
    selection = _choice(m.get("contacts", ContactSelection.LOWEST.value), f"{where}.contacts", ContactSelection, "mode")
    terrain = parse_terrain(m["terrain"], f"{where}.terrain") if "terrain" in m else FLAT
    base_x = parse_base_x(m["base_x"], f"{where}.base_x") if "base_x" in m else 0.0
    for key in ("heightfield", "base_z"):
        if key in m and not spatial:
            raise ConfigError(f"{where}.{key}: needs 'model.space: spatial' (a planar ground is scene.terrain)")
    heightfield = parse_heightfield(m["heightfield"], f"{where}.heightfield") if "heightfield" in m else None
    if heightfield is not None and "terrain" in m:
        raise ConfigError(f"{where}.terrain: give scene.heightfield or scene.terrain, not both (in space: the heightfield)")
    base_z = _number(m["base_z"], f"{where}.base_z") if "base_z" in m else 0.0
    gravity = _number(m.get("gravity", 0.0), f"{where}.gravity")
    if gravity < 0:
        raise ConfigError(f"{where}.gravity: must be >= 0 (m/s^2 along -y, e.g. 9.81), got {gravity!r}")
    duration = _positive(m["duration"], f"{where}.duration") if m.get("duration") is not None else None
    return Scene(
        speed=speed,
        velocity_x=velocity_x,
        angular_velocity=angular_velocity,
        velocity_z=velocity_z,
        angular_velocity_x=wx,
        angular_velocity_y=wy,
        restitution=restitution,
        friction=friction,
        selection=selection,
        contact_tolerance=tolerance,
        terrain=terrain,
        base_x=base_x,
        base_z=base_z,
        heightfield=heightfield,
        gravity=gravity,
        duration=duration,
    )


def parse_joint_laws(data: dict[str, Any], tree: Tree, where: str = "model") -> tuple[JointLaw, ...]:
    """Each body's spring, damper and stops (``JOINT_LAW_KEYS``), or () when no body has any.

    Raises:
        ConfigError: naming the field: a bad value, or a joint law on the base or a fixed joint.
    """
    laws = []
    for i, b in enumerate(data["bodies"]):
        at = f"{where}.bodies[{i}]"
        given = [k for k in JOINT_LAW_KEYS if k in b]
        if given and (i == 0 or tree.bodies[i].joint is not JointKind.REVOLUTE):
            what = "the floating base has no joint" if i == 0 else "a fixed joint does not move"
            raise ConfigError(f"{at}.{given[0]}: applies to revolute joints only ({what})")
        laws.append(joint_law(b, at) if given else FREE)
    return tuple(laws) if any(law != FREE for law in laws) else ()


def joint_law(b: dict[str, Any], where: str) -> JointLaw:
    """A revolute joint's law from a body's (or a study's leg rod's) keys, validated; ``b``'s
    ``angle`` is the touchdown angle the stops must admit.

    Raises:
        ConfigError: naming the field.
    """
    limits = None
    if "limits" in b:
        raw = b["limits"]
        if not (isinstance(raw, list) and len(raw) == 2):
            raise ConfigError(f"{where}.limits: must be [lo, hi] (rad), got {_describe(raw)}")
        lo, hi = (_number(x, f"{where}.limits[{k}]") for k, x in enumerate(raw))
        limits = (lo, hi)
    law = JointLaw(
        stiffness=_number(b.get("stiffness", 0.0), f"{where}.stiffness"),
        damping=_number(b.get("damping", 0.0), f"{where}.damping"),
        rest=None if b.get("rest") is None else _angle(b["rest"], f"{where}.rest"),
        limits=limits,
        stop_restitution=_number(b.get("stop_restitution", 0.0), f"{where}.stop_restitution"),
    )
    try:
        law.validate(where)
    except ModelError as e:
        raise ConfigError(str(e)) from None
    if limits is not None and not limits[0] <= float(b["angle"]) <= limits[1]:
        raise ConfigError(f"{where}.limits: the touchdown angle {b['angle']!r} lies outside [{limits[0]!r}, {limits[1]!r}]")
    return law


def parse_terrain(value: Any, where: str = "scene.terrain") -> Terrain:
    """Validate ``scene.terrain``: a non-empty list of ``[x, y]`` pairs of finite numbers (m) with
    x strictly increasing.

    Raises:
        ConfigError: naming the entry at fault (``scene.terrain[2]: ...``).
    """
    if not isinstance(value, list) or not value:
        raise ConfigError(f"{where}: must be a non-empty list of [x, y] points (m), got {_describe(value)}")
    points = []
    for i, p in enumerate(value):
        if not (isinstance(p, list) and len(p) == 2):
            raise ConfigError(f"{where}[{i}]: must be a pair [x, y] (m), got {_describe(p)}")
        points.append(tuple(_number(c, f"{where}[{i}][{k}]") for k, c in enumerate(p)))
    try:
        return Terrain.from_points(points)
    except ModelError as e:  # x not increasing: Terrain names it scene.terrain[i]
        raise ConfigError(str(e).replace("scene.terrain", where, 1)) from None


def parse_heightfield(value: Any, where: str = "scene.heightfield") -> Heightfield:
    """Validate ``scene.heightfield``: ``{x: [...], z: [...], heights: [[...], ...]}``, x and z
    strictly increasing, ``heights`` len(x) rows of len(z) finite numbers (m).

    Raises:
        ConfigError: one line naming the field at fault (``scene.heightfield.heights: expected 3
            rows of 4 values ...``).
    """
    m = _mapping(value, where, ("x", "z", "heights"))
    grid = {}
    for key in ("x", "z"):
        raw = _required(m, key, where)
        if not isinstance(raw, list) or not raw:
            raise ConfigError(f"{where}.{key}: must be a non-empty list of numbers (m), got {_describe(raw)}")
        grid[key] = tuple(_number(v, f"{where}.{key}[{i}]") for i, v in enumerate(raw))
    rows = _required(m, "heights", where)
    nx, nz = len(grid["x"]), len(grid["z"])
    if not isinstance(rows, list) or len(rows) != nx or any(not isinstance(r, list) or len(r) != nz for r in rows):
        raise ConfigError(
            f"{where}.heights: expected {nx} rows of {nz} values (row i: the heights at x[i] along z), got "
            + (_describe(rows) if not isinstance(rows, list) else
               f"{len(rows)} rows of " + "/".join(str(len(r)) if isinstance(r, list) else _describe(r) for r in rows)
               + " values")
        )
    heights = tuple(
        tuple(_number(v, f"{where}.heights[{i}][{j}]") for j, v in enumerate(r)) for i, r in enumerate(rows)
    )
    try:
        return Heightfield(grid["x"], grid["z"], heights)
    except ModelError as e:  # a grid not increasing: named scene.heightfield.x[i]
        raise ConfigError(str(e).replace("scene.heightfield", where, 1)) from None


def parse_base_x(value: Any, where: str = "scene.base_x") -> float:
    """Validate ``scene.base_x``: a finite number (m)."""
    return _number(value, where)


def parse_tree(data: Any, where: str = "model") -> Tree:
    """Validate the ``model`` block (a list of bodies, parents first) into a core ``Tree``."""
    m = _mapping(data, where, MODEL_KEYS)
    raw = _required(m, "bodies", where)
    path = f"{where}.bodies"
    if not isinstance(raw, list):
        raise ConfigError(f"{path}: must be a list of bodies, got {_describe(raw)}")
    if not raw:
        raise ConfigError(f"{path}: must list at least one body")
    spatial = parse_space(data, where) is SPATIAL
    keys = BODY_KEYS + JOINT_LAW_KEYS + SPATIAL_BODY_KEYS
    entries = [_mapping(b, f"{path}[{i}]", keys) for i, b in enumerate(raw)]
    for i, b in enumerate(entries):
        for key in SPATIAL_BODY_KEYS:
            if key in b and not spatial and key != "com_offset":
                raise ConfigError(f"{path}[{i}].{key}: needs 'model.space: spatial' (a planar body turns about z)")

    index: dict[str, int] = {}
    for i, b in enumerate(entries):
        name = _string(_required(b, "name", f"{path}[{i}]"), f"{path}[{i}].name")
        if name in index:
            raise ConfigError(f"{path}[{i}].name: duplicate body name '{name}' (also {path}[{index[name]}])")
        index[name] = i
    names = list(index)

    bodies = [_parse_body(b, i, names, entries, path, spatial) for i, b in enumerate(entries)]
    if not any(b.contacts for b in bodies):
        raise ConfigError(f"{path}: no body declares a contact point (add e.g. 'contacts: [1.0]' to a body)")
    return Tree(tuple(bodies))


def _parse_body(
    b: dict[str, Any], i: int, names: list[str], entries: list[dict[str, Any]], path: str, spatial: bool = False
) -> Body:
    where = f"{path}[{i}]"
    parent = _parse_parent(b, i, names, entries, where)
    length = _positive(_required(b, "length", where), f"{where}.length")
    mass = _positive(_required(b, "mass", where), f"{where}.mass")
    angle = _angle(_required(b, "angle", where), f"{where}.angle")
    at = _fraction(b.get("at", 1.0), f"{where}.at", "a fraction of the parent's length")
    joint = _choice(b.get("joint", JointKind.REVOLUTE.value), f"{where}.joint", JointKind, "joint kind")
    com = _fraction(b.get("com", UNIFORM_COM), f"{where}.com", "a fraction of the body's length")
    raw_contacts = b.get("contacts", [])
    if not isinstance(raw_contacts, list):
        raise ConfigError(
            f"{where}.contacts: must be a list of fractions of the body's length, e.g. [1.0], "
            f"got {_describe(raw_contacts)}"
        )
    contacts = []
    for k, c in enumerate(raw_contacts):
        x = _number(c, f"{where}.contacts[{k}]")
        if not 0.0 <= x <= 1.0:
            raise ConfigError(
                f"{where}.contacts[{k}]: {x!r} is off its body: a contact is a fraction of the body's length in [0, 1]"
            )
        contacts.append(x)
    if "inertia" in b and "gyration" in b:
        raise ConfigError(f"{where}.gyration: give 'inertia' or 'gyration', not both")
    rpy, axis, radius = _spatial_fields(b, where) if spatial else ((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 0.0)
    com_offset, tensor = _mass_fields(b, where) if spatial else (_planar_offset(b, where), None)
    if tensor is not None:
        return Body(
            name=names[i], parent=parent, length=length, mass=mass, angle=angle, at=at, joint=joint,
            contacts=tuple(contacts), com=com, gyration=0.0, rpy=rpy, axis=axis, radius=0.0,
            com_offset=com_offset, tensor=tensor,
        )
    # a solid cylinder's m (3 r^2 + L^2) / 12 across the rod (a uniform rod's m L^2 / 12 at r = 0)
    gyration = math.sqrt(UNIFORM_GYRATION**2 + 0.25 * (radius / length) ** 2) if radius else UNIFORM_GYRATION
    if "inertia" in b:
        inertia = _number(b["inertia"], f"{where}.inertia")
        if inertia < 0:
            raise ConfigError(f"{where}.inertia: must be >= 0 (kg m^2, about the centre of mass), got {inertia!r}")
        gyration = math.sqrt(inertia / mass) / length
    elif "gyration" in b:
        gyration = _number(b["gyration"], f"{where}.gyration")
        if gyration < 0:
            raise ConfigError(f"{where}.gyration: must be >= 0 (a fraction of the length), got {gyration!r}")
    return Body(
        name=names[i],
        parent=parent,
        length=length,
        mass=mass,
        angle=angle,
        at=at,
        joint=joint,
        contacts=tuple(contacts),
        com=com,
        gyration=gyration,
        rpy=rpy,
        axis=axis,
        radius=radius,
        com_offset=com_offset,
    )


def _mass_fields(b: dict[str, Any], where: str) -> tuple[tuple[float, float], tuple[float, ...] | None]:
    """A spatial body's ``com_offset`` ([dy, dz], m, default 0) and ``inertia_tensor`` ([ixx, iyy,
    izz, ixy, ixz, iyz], kg m^2 about the centre of mass, body axes; physical), or None without
    one. The tensor is the body's whole inertia: ``inertia``, ``gyration`` and ``radius`` are
    refused beside it."""
    com_offset = _vector(b.get("com_offset", [0.0, 0.0]), f"{where}.com_offset", "dy, dz", unit=" (m)")
    if "inertia_tensor" not in b:
        return com_offset, None
    for key in ("inertia", "gyration", "radius"):
        if key in b:
            raise ConfigError(f"{where}.inertia_tensor: is the whole inertia about the centre of mass; "
                              f"give 'inertia_tensor' or '{key}', not both")
    raw = b["inertia_tensor"]
    if not isinstance(raw, list) or len(raw) != 6:
        raise ConfigError(f"{where}.inertia_tensor: must be [ixx, iyy, izz, ixy, ixz, iyz] (kg m^2, about the "
                          f"centre of mass, body axes), got {_describe(raw)}")
    tensor = tuple(_number(x, f"{where}.inertia_tensor[{k}]") for k, x in enumerate(raw))
    problem = tensor_problem(tensor)
    if problem is not None:
        raise ConfigError(f"{where}.inertia_tensor: {problem}")
    return com_offset, tensor


def _planar_offset(b: dict[str, Any], where: str) -> tuple[float, float]:
    """A planar body's ``com_offset`` [dy, 0] (m, default 0): its centre of mass lies in the plane."""
    dy, dz = _vector(b.get("com_offset", [0.0, 0.0]), f"{where}.com_offset", "dy, dz", unit=" (m)")
    if dz != 0.0:
        raise ConfigError(f"{where}.com_offset: a planar body's centre of mass lies in the plane: dz must be 0, "
                          f"got {dz!r} (out of the plane: 'model.space: spatial')")
    return dy, 0.0


def _spatial_fields(b: dict[str, Any], where: str) -> tuple[tuple[float, ...], tuple[float, ...], float]:
    """A spatial body's ``rpy`` (default 0), ``axis`` (default z, non-zero) and ``radius`` (>= 0)."""
    rpy = _vector(b.get("rpy", [0.0, 0.0, 0.0]), f"{where}.rpy", "a, b, c", unit=" (rad)")
    axis = _vector(b.get("axis", [0.0, 0.0, 1.0]), f"{where}.axis", "x, y, z", unit="")
    if math.hypot(*axis) <= 1e-12:
        raise ConfigError(f"{where}.axis: must be a non-zero vector (the joint's axis), got {list(axis)}")
    radius = _number(b.get("radius", 0.0), f"{where}.radius")
    if radius < 0:
        raise ConfigError(f"{where}.radius: must be >= 0 (m), got {radius!r}")
    return rpy, axis, radius


def _parse_parent(b: dict[str, Any], i: int, names: list[str], entries: list[dict[str, Any]], where: str) -> int | None:
    """Resolve a body's ``parent`` name to the index of a body listed before it."""
    raw = b.get("parent")
    if i == 0:
        if raw is not None:
            raise ConfigError(f"{where}.parent: the first body is the floating base and has no parent")
        return None
    if raw is None:
        raise ConfigError(
            f"{where}.parent: missing (only the first body is the floating base; name this body's parent)"
        )
    parent = _string(raw, f"{where}.parent")
    if parent not in names:
        raise ConfigError(f"{where}.parent: unknown body '{parent}' (bodies: {', '.join(names)})")
    j = names.index(parent)
    if j < i:
        return j
    cycle = _parent_cycle(i, names, entries)
    if cycle is not None:
        raise ConfigError(f"{where}.parent: the parents form a cycle: {' -> '.join(cycle)}")
    raise ConfigError(f"{where}.parent: '{parent}' is listed after '{names[i]}'; list parents first")


def _parent_cycle(i: int, names: list[str], entries: list[dict[str, Any]]) -> list[str] | None:
    """The names along the parent chain from body ``i`` back to itself, or None if it ends."""
    chain = [names[i]]
    current = i
    for _ in range(len(names)):
        parent = entries[current].get("parent")
        if not isinstance(parent, str) or parent not in names:
            return None
        current = names.index(parent)
        chain.append(parent)
        if current == i:
            return chain
    return None


def parse_reference(data: Any, where: str = "reference") -> Reference:
    """Validate a ``reference`` block (lengths are checked against the tree by ``ModelFile``)."""
    m = _mapping(data, where, REFERENCE_KEYS)
    return Reference(
        source=_optional_string(m, "source", where),
        external=_optional_values(m, "external", where),
        internal=_optional_values(m, "internal", where),
        external_norm=_optional_number(m, "external_norm", where),
        internal_norm=_optional_number(m, "internal_norm", where),
        note=_optional_string(m, "note", where),
    )


# --------------------------------------------------------------------------------------------
# Field helpers: each raises ConfigError naming the YAML path






def _fraction(value: Any, where: str, what: str) -> float:
    x = _number(value, where)
    if not 0.0 <= x <= 1.0:
        raise ConfigError(f"{where}: must be in [0, 1] ({what}), got {x!r}")
    return x


def _choice(value: Any, where: str, enum: Any, what: str) -> Any:
    allowed = [e.value for e in enum]
    for e in enum:
        if value == e.value:
            return e
    raise ConfigError(f"{where}: unknown {what} {_describe(value)} (allowed: {', '.join(allowed)})")


def _optional_string(m: dict[str, Any], key: str, where: str) -> str | None:
    value = m.get(key)
    if value is None:
        return None
    if not isinstance(value, str):
        raise ConfigError(f"{_join(where, key)}: must be a string, got {_describe(value)}")
    return value


def _optional_number(m: dict[str, Any], key: str, where: str) -> float | None:
    value = m.get(key)
    return None if value is None else _number(value, _join(where, key))


def _optional_values(m: dict[str, Any], key: str, where: str) -> tuple[float | None, ...] | None:
    value = m.get(key)
    if value is None:
        return None
    path = _join(where, key)
    if not isinstance(value, list):
        raise ConfigError(f"{path}: must be a list of numbers (null where unknown), got {_describe(value)}")
    return tuple(None if v is None else _number(v, f"{path}[{k}]") for k, v in enumerate(value))


# --------------------------------------------------------------------------------------------
# Writing

_PLAIN = re.compile(r"[A-Za-z_][A-Za-z0-9_\-]*")
# Plain words that some YAML reader (1.1 or 1.2) would not read as a string.
_RESERVED = frozenset({"true", "false", "yes", "no", "on", "off", "y", "n", "null"})
# Characters written as they are inside a double-quoted scalar (YAML's printable set, less line breaks).
_PRINTABLE = re.compile("[\x20-\x7e\xa0-\u2027\u202a-\ud7ff\ue000-\ufffd\U00010000-\U0010ffff]")


def format_model_file(model: ModelFile, header_comment: str | None = None) -> str:
    """The text of a model file for ``model``: loading it gives back equal dataclasses.

    Floats are written at repr precision with a dot in the mantissa (``1.0e-06``), so that YAML
    1.1 readers read them as numbers too. Defaults are left out (``at: 1.0``, ``joint:
    revolute``, ``com: 0.5``, a uniform rod's inertia, flat ground at y = 0, ``base_x: 0``); the
    rest of the scene is written in full.
    """
    lines = [f"# {line}".rstrip() for line in header_comment.splitlines()] if header_comment else []
    s = model.scene
    spatial = model.space is SPATIAL
    velocity = s.velocity if spatial else s.velocity[:2]
    lines += [
        "scene:",
        f"  speed: {_float_text(s.speed)}  # m/s, straight down"
        if s.velocity_x == 0.0 and s.velocity_z == 0.0
        else f"  velocity: {_list_text(velocity)}  # m/s, base origin",
        f"  restitution: {_float_text(s.restitution)}",
        f"  friction: {_float_text(s.friction)}",
        f"  contacts: {s.selection.value}",
    ]
    if spatial and s.angular_velocity_3d != (0.0, 0.0, 0.0):
        lines.append(f"  angular_velocity: {_list_text(s.angular_velocity_3d)}  # rad/s, world frame")
    elif s.angular_velocity != 0.0:
        lines.append(f"  angular_velocity: {_float_text(s.angular_velocity)}  # rad/s, about z")
    if s.contact_tolerance != _DEFAULT_TOLERANCE:
        lines.append(f"  contact_tolerance: {_float_text(s.contact_tolerance)}  # m")
    if s.terrain != FLAT:
        points = ", ".join(f"[{_float_text(x)}, {_float_text(y)}]" for x, y in s.terrain.points)
        lines.append(f"  terrain: [{points}]  # ground profile y(x), world frame, m")
    if s.base_x != 0.0:
        lines.append(f"  base_x: {_float_text(s.base_x)}  # m, base origin at touchdown")
    if s.base_z != 0.0:
        lines.append(f"  base_z: {_float_text(s.base_z)}  # m, base origin at touchdown")
    if s.heightfield is not None:
        hf = s.heightfield
        rows = ", ".join(_list_text(row) for row in hf.heights)
        lines.append(
            f"  heightfield: {{x: {_list_text(hf.x)}, z: {_list_text(hf.z)}, heights: [{rows}]}}  # ground y(x, z), m"
        )
    if s.gravity != 0.0:
        lines.append(f"  gravity: {_float_text(s.gravity)}  # m/s^2 along -y")
    if s.duration is not None:
        lines.append(f"  duration: {_float_text(s.duration)}  # s: the whole landing")
    lines += ["model:"] + (["  space: spatial"] if spatial else []) + ["  bodies:"]
    tree = model.tree
    for b in tree.bodies:
        lines.append(f"    - name: {_string_text(b.name)}")
        if b.parent is not None:
            lines.append(f"      parent: {_string_text(tree.bodies[b.parent].name)}")
        if b.at != 1.0:
            lines.append(f"      at: {_float_text(b.at)}")
        lines += [
            f"      length: {_float_text(b.length)}",
            f"      mass: {_float_text(b.mass)}",
            f"      angle: {_float_text(b.angle)}",
        ]
        if b.joint is not JointKind.REVOLUTE:
            lines.append(f"      joint: {b.joint.value}")
        if b.rpy != (0.0, 0.0, 0.0):
            lines.append(f"      rpy: {_list_text(b.rpy)}  # rad: Rz(c) Ry(b) Rx(a)")
        if b.axis != (0.0, 0.0, 1.0):
            lines.append(f"      axis: {_list_text(b.axis)}")
        tensor = _tensor_text(b)
        if b.radius != 0.0 and tensor is None:
            lines.append(f"      radius: {_float_text(b.radius)}  # m")
        if b.com != UNIFORM_COM:
            lines.append(f"      com: {_float_text(b.com)}")
        if b.com_offset != (0.0, 0.0):
            lines.append(f"      com_offset: {_list_text(b.com_offset)}  # m, along the body's y and z")
        if tensor is not None:
            lines.append(f"      inertia_tensor: {tensor}  # kg m^2 about the centre of mass: ixx, iyy, izz, ixy, ixz, iyz")
        elif b.gyration != UNIFORM_GYRATION:
            inertia = _exact_inertia(b)
            if inertia is not None:
                lines.append(f"      inertia: {_float_text(inertia)}  # kg m^2, about the centre of mass")
            else:
                lines.append(f"      gyration: {_float_text(b.gyration)}  # radius of gyration / length")
        if b.contacts:
            lines.append(f"      contacts: [{', '.join(_float_text(c) for c in b.contacts)}]")
        if model.joints:
            lines += _joint_law_lines(model.joints[tree.bodies.index(b)])
    ref = model.reference
    if ref is not None:
        lines.append("reference:" if any(getattr(ref, key) is not None for key in REFERENCE_KEYS) else "reference: {}")
        for key in REFERENCE_KEYS:
            value = getattr(ref, key)
            if value is None:
                continue
            if isinstance(value, str):
                text = _string_text(value)
            elif isinstance(value, tuple):
                text = f"[{', '.join('null' if v is None else _float_text(v) for v in value)}]"
            else:
                text = _float_text(value)
            lines.append(f"  {key}: {text}")
    if model.notes is not None:
        lines.append(f"notes: {_string_text(model.notes)}")
    return "\n".join(lines) + "\n"


def _joint_law_lines(law: JointLaw) -> list[str]:
    """The non-default fields of a joint law, as body lines of a model file."""
    lines = []
    for key in ("stiffness", "damping", "rest", "stop_restitution"):
        value, default = getattr(law, key), getattr(FREE, key)
        if value != default:
            lines.append(f"      {key}: {_float_text(value)}")
    if law.limits is not None:
        lines.append(f"      limits: [{_float_text(law.limits[0])}, {_float_text(law.limits[1])}]  # rad")
    return lines


def dump_model_file(
    model: ModelFile | Tree,
    path: str | Path,
    scene: Scene | None = None,
    reference: Reference | None = None,
    *,
    header_comment: str | None = None,
    overwrite: bool = False,
) -> Path:
    """Write a model file.

    Args:
        model: a ``ModelFile``, or a ``Tree`` (then ``scene`` is required and ``reference``
            optional).
        path: where to write.
        scene, reference: with a ``Tree``.
        header_comment: text written first as YAML comments (one ``#`` per line).
        overwrite: replace an existing file (default: refuse).

    Returns:
        The path written.

    Raises:
        ConfigError: the file exists and ``overwrite`` is False, or it cannot be written.
    """
    if isinstance(model, Tree):
        if scene is None:
            raise TypeError("dump_model_file(tree, path, scene): a Tree needs its Scene")
        model = ModelFile(tree=model, scene=scene, reference=reference)
    elif scene is not None or reference is not None:
        raise TypeError("dump_model_file: scene and reference go with a Tree, not a ModelFile")
    path = Path(path)
    text = format_model_file(model, header_comment)
    try:
        with path.open("w" if overwrite else "x", encoding="utf-8") as f:
            f.write(text)
    except FileExistsError:
        raise ConfigError(f"{path}: already exists; not overwriting it (pass overwrite=True)", path) from None
    except OSError as e:
        raise ConfigError(f"{path}: cannot write: {e.strerror or e}", path) from None
    return path


def _float_text(x: float) -> str:
    x = float(x)
    if math.isnan(x):
        return ".nan"
    if math.isinf(x):
        return ".inf" if x > 0 else "-.inf"
    text = repr(x)
    mantissa, e, exponent = text.partition("e")
    if e and "." not in mantissa:
        text = f"{mantissa}.0e{exponent}"
    return text


def _list_text(xs: tuple[float, ...]) -> str:
    return "[" + ", ".join(_float_text(x) for x in xs) + "]"


def _string_text(s: str) -> str:
    """A YAML scalar that reads back as ``s``: plain when that is safe, else double-quoted."""
    if _PLAIN.fullmatch(s) and s.lower() not in _RESERVED:
        return s
    return '"' + "".join(_escape(ch) for ch in s) + '"'


def _escape(ch: str) -> str:
    if ch in '"\\':
        return "\\" + ch
    if _PRINTABLE.fullmatch(ch):
        return ch
    code = ord(ch)  # control characters, YAML 1.1 line breaks (NEL, LS, PS), non-characters
    return f"\\x{code:02x}" if code <= 0xFF else f"\\u{code:04x}" if code <= 0xFFFF else f"\\U{code:08x}"


def _tensor_text(b: Body) -> str | None:
    """A body's ``inertia_tensor`` as written, or None for a rod (no added tensor): the added
    tensor itself when the rod carries none (``gyration`` and ``radius`` 0, as a file's tensor
    loads), else the rod's and the added one summed (a tree built in code)."""
    if not any(b.tensor):
        return None
    t = b.tensor
    if b.gyration != 0.0 or b.radius != 0.0:
        t = tuple(x + y for x, y in zip(t, (b.axial_inertia, b.inertia, b.inertia, 0.0, 0.0, 0.0)))
    return _list_text(t)


def _exact_inertia(b: Body) -> float | None:
    """A float inertia that loads back to exactly ``b.gyration``, or None if none is near."""
    inertia = b.inertia
    candidates = [inertia]
    lo = hi = inertia
    for _ in range(8):
        lo, hi = math.nextafter(lo, 0.0), math.nextafter(hi, math.inf)
        candidates += [lo, hi]
    for c in candidates:
        if math.sqrt(c / b.mass) / b.length == b.gyration:
            return c
    return None


__all__ = [
    "ModelFile",
    "Reference",
    "Yaml12Loader",
    "dump_model_file",
    "format_model_file",
    "load_model_file",
    "load_yaml",
    "parse_base_x",
    "parse_model",
    "parse_reference",
    "parse_scene",
    "parse_terrain",
    "parse_tree",
]
