"""Study files: what to optimise, validated once into frozen dataclasses.

A study file is YAML 1.2 (read by :func:`optimizer.config.model_file.load_yaml`, so ``1e-6`` is a
number). Every bad value becomes a :class:`~optimizer.errors.ConfigError` whose one-line message
starts with its YAML path (``search.trials: must be an integer >= 1, got 'ten'``). The schema,
with defaults, is ``configs/quick_study.yaml``; :func:`format_study` writes a resolved study
(every default filled in) that loads back to an equal :class:`StudyConfig`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from enum import Enum
from pathlib import Path
from typing import Any

from impulse_core.model.joints import FREE
from impulse_core.model.tree import Scene
from impulse_core.timedomain.events.settings import MIN_TOLERANCE
from optimizer.config.model_file import joint_law, load_yaml, read_text
from optimizer.config.redact import redact_url
from optimizer.config.yaml_fields import MAX_ANGLE
from optimizer.config.yaml_fields import angle as _angle
from optimizer.config.yaml_fields import describe as _describe
from optimizer.config.yaml_fields import mapping as _checked_mapping
from optimizer.config.yaml_fields import number as _number
from optimizer.config.yaml_fields import positive as _positive
from optimizer.config.yaml_fields import required as _required
from optimizer.config.yaml_fields import string as _string
from optimizer.design_space import (
    FOOT_ROD_NAME,
    JOINT_FAMILIES,
    DesignSpace,
    FootLimits,
    JointLawSpace,
    JointRanges,
    Leg,
    LegChain,
    MassMode,
    Objective,
    SplayMode,
    SplaySpace,
    ToeSymmetry,
    leg_chain,
)
from optimizer.errors import ConfigError
from optimizer.evaluation.scenarios import (
    PARAMETERS,
    PLANAR_PARAMETERS,
    SPATIAL_PARAMETERS,
    Distribution,
    DistributionKind,
    Landings,
)
from optimizer.evaluation.statistics import Statistic, StatisticKind, parse_statistic


class SearchMethod(Enum):
    """How a study searches."""

    OUTER = "outer"  # Optuna over shapes and values together (global, derivative-free)
    INNER = "inner"  # per shape: IPOPT with exact derivatives, an epsilon-constraint sweep


class SamplerKind(Enum):
    """The outer search's Optuna sampler."""

    TPE = "tpe"
    NSGA2 = "nsga2"


@dataclass(frozen=True)
class SearchSettings:
    """How to search.

    Attributes:
        method: outer (Optuna) or inner (IPOPT per shape).
        sampler: the outer search's sampler.
        trials: outer: completed trials to reach (a resumed study runs the rest).
        startup_trials: TPE: random trials before the model-based ones.
        population: NSGA-II: population size.
        front_points: inner: epsilon-constraint points per shape (besides the two anchors).
        starts: inner: random starts per shape.
        landing_tolerance: the whole landing's accuracy (``footopt evaluate --tolerance``).
    """

    method: SearchMethod = SearchMethod.INNER
    sampler: SamplerKind = SamplerKind.TPE
    trials: int = 200
    startup_trials: int = 20
    population: int = 24
    front_points: int = 8
    starts: int = 4
    landing_tolerance: float = 1e-3


@dataclass(frozen=True)
class StudyConfig:
    """One study: the landing, the leg, the design space, the constraints, the objectives and
    how to search.

    Attributes:
        name: the study's name (the Optuna study name).
        seed: seeds every random choice of the search.
        storage: an Optuna storage URL, or None for a journal file in the run directory.
        scene: the landing (straight down; friction, gravity and a duration for whole-landing
            objectives).
        leg: the fixed leg and its posture: thigh and shank, or a chain of rods from a model file.
        space: toe count, rods per toe and per heel, toe symmetry.
        limits: the constraints.
        objectives: what to minimise (at least one; the first two span the plotted front).
        search: how to search.
        source: the file it was read from (not part of equality).
        landings: a distribution of landings every design is scored over (None: the scene only).
        statistic: per objective, its statistic over the landings (absent: the mean).
    """

    name: str
    seed: int
    storage: str | None
    scene: Scene
    leg: Leg | LegChain
    space: DesignSpace
    limits: FootLimits
    objectives: tuple[Objective, ...]
    search: SearchSettings
    source: Path | None = field(default=None, compare=False)
    landings: Landings | None = None
    statistic: tuple[tuple[Objective, Statistic], ...] = ()

    def statistic_of(self, objective: Objective) -> Statistic:
        """The statistic the study reports for ``objective`` over its landings (default mean)."""
        return dict(self.statistic).get(objective, Statistic())

    @property
    def whole_landing(self) -> bool:
        """True when an objective scores the whole landing (every design then lands in full)."""
        return any(o.landing for o in self.objectives)


TOP_KEYS = ("name", "seed", "storage", "scene", "leg", "design_space", "constraints", "objectives", "search", "notes",
            "landings", "statistic")
LANDINGS_KEYS = ("count", "seed", *PARAMETERS)
SCENE_KEYS = ("speed", "restitution", "friction", "gravity", "duration")
LEG_KEYS = ("thigh", "shank", "file")
ROD_KEYS = ("length", "mass", "angle", "com", "gyration", "com_offset")
KNEE_KEYS = ("stiffness", "damping", "limits", "stop_restitution")
SPACE_KEYS = ("toes", "toe_segments", "heel_segments", "toe_symmetry", "joint_laws", "space", "splay", "splay_mode")
#: ``design_space.space``: the planar foot, or a spatial one with splayed toes.
SPACES = ("planar", "spatial")
JOINT_SPACE_KEYS = (*JOINT_FAMILIES, "stop_restitution")
FAMILY_KEYS = ("stiffness", "damping", "stop")
CONSTRAINT_KEYS = (
    "foot_mass",
    "foot_mass_mode",
    "min_link_mass",
    "mass_per_length",
    "foot_length",
    "min_clearance",
    "joint_angles",
    "contact_tolerance",
    "support_margin",
)
ANGLE_KEYS = ("heel_root", "heel_inner", "toe_root", "toe_inner")
SEARCH_KEYS = ("method", "sampler", "trials", "startup_trials", "population", "inner", "landing_tolerance")
INNER_KEYS = ("front_points", "starts")
#: Most toes and most rods per chain a study may ask for (documented in configs/quick_study.yaml):
#: beyond them a study is refused at once rather than enumerating shapes for ever.
MAX_TOES = 32
MAX_SEGMENTS = 16
#: The seed of a study file without ``seed`` (configs/quick_study.yaml shows every default).
DEFAULT_SEED = 1


# --------------------------------------------------------------------------------------------
# Reading


def load_study(path: str | Path) -> StudyConfig:
    """Read and validate a study file.

    Raises:
        ConfigError: the file is missing, not YAML, or a value is wrong (message: YAML path
            first; ``source``: the file).
    """
    path = Path(path)
    text = read_text(path, "study file")
    try:
        return parse_study(load_yaml(text, path), path)
    except ConfigError as e:
        e.source = e.source or path
        raise


def parse_study(data: Any, path: str | Path | None = None) -> StudyConfig:
    """Validate loaded study data (a mapping as in ``configs/quick_study.yaml``).

    Args:
        data: the loaded YAML document.
        path: the file it came from; its stem is the default study name.
    """
    source = None if path is None else Path(path)
    if data is None:
        raise ConfigError("empty file: expected a study (see configs/quick_study.yaml)", source)
    top = _mapping(data, "", TOP_KEYS, what="the top level")
    default_name = source.stem if source is not None else "study"
    name = _string(top.get("name", default_name), "name")
    seed = _integer(top.get("seed", DEFAULT_SEED), "seed", minimum=0)
    storage = top.get("storage")
    if storage is not None:
        storage = resolve_storage(_string(storage, "storage"), None if source is None else source.parent)
    objectives = _objectives(_required(top, "objectives", ""))
    space = _space(top.get("design_space", {}))
    limits = _limits(top.get("constraints", {}))
    fewest = space.heel_segments[0] + space.toes[0] * space.toe_segments[0]
    if fewest * limits.min_link_mass > limits.foot_mass:
        raise ConfigError(
            f"constraints.min_link_mass: {fewest} foot rods of {limits.min_link_mass!r} kg exceed the foot mass "
            f"{limits.foot_mass!r} kg even for the smallest foot of the design space"
        )
    config = StudyConfig(
        name=name,
        seed=seed,
        storage=storage,
        scene=_scene(top.get("scene", {})),
        leg=_leg(top.get("leg", {}), None if source is None else source.parent),
        space=space,
        limits=limits,
        objectives=objectives,
        search=_search(top.get("search", {})),
        source=source,
        landings=None if top.get("landings") is None else _landings(top["landings"]),
        statistic=_statistic(top.get("statistic", {})),
    )
    _check_leg(config)
    _check_whole_landing(config)
    _check_spatial(config)
    if config.landings is not None:
        _check_landings(config, config.landings)
    return config


def _check_leg(config: StudyConfig) -> None:
    """A spatial leg needs a spatial design space (the plane's foot cannot hang from it); either
    search takes it."""
    leg = config.leg
    if isinstance(leg, LegChain) and leg.spatial and not config.space.spatial:
        raise ConfigError(f"leg.file: {leg.file} is a spatial leg: it needs design_space.space: spatial (either "
                          "search); a planar design space takes a planar leg (footopt import --space planar, when the "
                          "leg's joint axes are parallel)")


def _check_spatial(config: StudyConfig) -> None:
    """What a spatial design space (splayed toes) needs, and what only it takes."""
    if not config.space.spatial:
        if config.limits.support_margin is not None:
            raise ConfigError("constraints.support_margin: needs design_space.space: spatial (a planar foot's "
                              "contacts lie on one line: its margin is at most 0)")
        return


def _check_landings(config: StudyConfig, landings: Landings) -> None:
    """What the landings need of the rest of the study."""
    if config.search.method is SearchMethod.INNER:
        _check_inner_landings(config, landings)
    for name in landings.names:
        if name in SPATIAL_PARAMETERS and not config.space.spatial:
            raise ConfigError(f"landings.{name}: needs design_space.space: spatial (a planar foot neither rolls nor "
                              "moves sideways)")
        if name in PLANAR_PARAMETERS and config.space.spatial:
            raise ConfigError(f"landings.{name}: a step is a planar terrain: a spatial design space lands on flat ground")


#: What the inner search's landings may vary: the approach and the restitution of one level
#: first impact (a pitch, a roll, a step or friction changes which contacts hit, or the law).
INNER_PARAMETERS = ("speed", "velocity_x", "angular_velocity", "restitution")
#: ... and over a spatial design space, the rest of the approach: a lateral velocity and a roll
#: rate change the impact's right-hand side only, not which contacts hit.
INNER_SPATIAL_PARAMETERS = (*INNER_PARAMETERS, "velocity_z", "roll_rate")
#: What the inner search over whole landings may vary: the scene's constants (each landing is
#: differentiated along its own event sequence); not a pitch (the tree) nor a step (placed by the
#: design's contacts).
INNER_LANDING_PARAMETERS = (*INNER_PARAMETERS, "friction")
#: ... and over a spatial design space, the rest of the spatial approach too (not a roll: the tree).
INNER_SPATIAL_LANDING_PARAMETERS = (*INNER_SPATIAL_PARAMETERS, "friction")


def _check_inner_landings(config: StudyConfig, landings: Landings) -> None:
    """The inner search takes landings whose statistics its NLP can differentiate exactly: of
    level first impacts, or of whole landings (:func:`check_inner_whole_landings`)."""
    if config.whole_landing:
        check_inner_whole_landings(config, landings)
        return
    _varied_only(landings, INNER_SPATIAL_PARAMETERS if config.space.spatial else INNER_PARAMETERS,
                 "the inner search", "a level first impact")
    for objective in config.objectives[:2]:
        stat = _inner_statistic(config, objective)
        if stat.kind is StatisticKind.STD and objective in (Objective.MAX_INTERNAL, Objective.BASE_ANGULAR_VELOCITY):
            raise ConfigError(f"statistic.{objective.value}: the inner search cannot take the std of a maximum "
                              "(its epigraph would not be tight); use mean, max or cvar:q, or search.method: outer")


def _varied_only(landings: Landings, allowed: tuple[str, ...], search: str, why: str) -> None:
    """Refuse, naming the field, a landing parameter ``search`` does not vary (``why``: what it varies)."""
    for name in landings.names:
        if name not in allowed:
            raise ConfigError(f"landings.{name}: {search} varies {', '.join(allowed)} only ({why}); "
                              "search.method: outer takes every parameter")


def _inner_statistic(config: StudyConfig, objective: Objective) -> Statistic:
    """The statistic of ``objective``, refused for the inner search if a quantile."""
    stat = config.statistic_of(objective)
    if stat.kind is StatisticKind.QUANTILE:
        raise ConfigError(f"statistic.{objective.value}: the inner search takes mean, std, max or cvar:q "
                          "(a quantile is neither smooth nor convex); use cvar:q or search.method: outer")
    return stat


def check_inner_whole_landings(config: StudyConfig, landings: Landings) -> None:
    """Whole landings over landings in the inner search: the scene's constants (in the plane, or
    in space with its lateral velocity and roll rate), and statistics its NLP writes smoothly or
    by an epigraph (one of a minimised objective)."""
    _varied_only(landings, INNER_SPATIAL_LANDING_PARAMETERS if config.space.spatial else INNER_LANDING_PARAMETERS,
                 "the inner search over whole landings", "the scene's constants")
    for objective in config.objectives[:2]:
        stat = _inner_statistic(config, objective)
        if objective.sign < 0 and stat.kind in (StatisticKind.MAX, StatisticKind.CVAR):
            raise ConfigError(f"statistic.{objective.value}: the inner search cannot maximise a {stat.kind.value} "
                              "(its epigraph would not be tight); use mean or std, or search.method: outer")


def _landings(data: Any) -> Landings:
    m = _mapping(data, "landings", LANDINGS_KEYS)
    count = _integer(m.get("count", 64), "landings.count", minimum=1)
    if count > 100_000:
        raise ConfigError(f"landings.count: at most 100000 scenarios, got {count}")
    seed = _integer(m.get("seed", 0), "landings.seed", minimum=0)
    given = tuple((name, _distribution(m[name], f"landings.{name}")) for name in PARAMETERS if name in m)
    landings = Landings(count, seed, given)
    _check_draws(landings)
    return landings


def _distribution(value: Any, where: str) -> Distribution:
    """``{uniform: [lo, hi]}``, ``{normal: [mean, sd]}`` or a non-empty list of values."""
    if isinstance(value, list):
        if not value:
            raise ConfigError(f"{where}: an empty list of values")
        return Distribution(DistributionKind.VALUES, tuple(_number(x, f"{where}[{i}]") for i, x in enumerate(value)))
    m = _mapping(value, where, ("uniform", "normal"))
    if len(m) != 1:
        raise ConfigError(f"{where}: must be {{uniform: [lo, hi]}}, {{normal: [mean, sd]}} or a list of values")
    (kind, pair), = m.items()
    a, b = (_number(x, f"{where}.{kind}[{i}]") for i, x in enumerate(_pair(pair, f"{where}.{kind}", "numbers")))
    if kind == "uniform" and a > b:
        raise ConfigError(f"{where}.uniform: lo {a!r} is above hi {b!r}")
    if kind == "normal" and b < 0:
        raise ConfigError(f"{where}.normal[1]: the standard deviation must be >= 0, got {b!r}")
    return Distribution(DistributionKind(kind), (a, b))


def _check_draws(landings: Landings) -> None:
    """Every drawn landing must be a valid scene: speed > 0, restitution in [0, 1], friction >= 0,
    a pitch within +-MAX_ANGLE (a model file's angles)."""
    draws = landings.draw()
    bounds = {"speed": (0.0, math.inf, False), "restitution": (0.0, 1.0, True), "friction": (0.0, math.inf, True),
              "pitch": (-MAX_ANGLE, MAX_ANGLE, True)}
    for j, name in enumerate(landings.names):
        if name not in bounds:
            continue
        lo, hi, closed = bounds[name]
        x = draws[:, j]
        bad = x[(x < lo) | (x > hi) | ((x == lo) & (not closed))]
        if bad.size:
            raise ConfigError(f"landings.{name}: draws {float(bad[0])!r}, outside its range; narrow the distribution")


def _statistic(data: Any) -> tuple[tuple[Objective, Statistic], ...]:
    m = _mapping(data, "statistic", tuple(o.value for o in Objective))
    return tuple((Objective(k), parse_statistic(v, f"statistic.{k}")) for k, v in m.items())


def _check_whole_landing(config: StudyConfig) -> None:
    """What only a whole landing uses needs a landing objective, and the reverse."""
    landing = [o.value for o in config.objectives if o.landing]
    if landing and config.scene.duration is None:
        raise ConfigError(f"scene.duration: missing: the objective {landing[0]} scores the whole landing (s)")
    if landing and config.search.method is SearchMethod.INNER:
        primary = config.objectives[:2]
        if Objective.SETTLED_AT in primary:
            raise ConfigError("search.method: the objective settled_at has no derivative (a threshold crossing): "
                              "the inner search cannot optimise it; search.method: outer can")
        first = [o.value for o in primary if not o.landing]
        if first:
            raise ConfigError(f"objectives: the inner search over a whole landing optimises landing objectives only, "
                              f"got {first[0]}; search.method: outer mixes them")
    if landing:
        return
    if config.scene.friction != 0.0 and config.search.method is SearchMethod.INNER:
        raise ConfigError(
            f"scene.friction: the inner search optimises frictionless landings only (0), got "
            f"{config.scene.friction!r}; search.method: outer takes friction (the exact Coulomb law per design)"
        )
    leg_laws = any(not law.is_default for law in leg_chain(config.leg).joints)
    if not config.space.joint_laws.empty or leg_laws:
        where = ("design_space.joint_laws" if not config.space.joint_laws.empty
                 else "leg.file" if isinstance(config.leg, LegChain) else "leg.shank")
        hint = "" if where == "design_space.joint_laws" else " (a leg file from footopt import: --no-joint-laws leaves them out)"
        raise ConfigError(f"{where}: springs, dampers and stops act only over a whole landing: add a landing "
                          "objective (peak_external_norm, peak_internal_norm, peak_max_internal, settled_at, "
                          f"energy_absorbed){hint}")


def resolve_storage(url: str, folder: Path | None) -> str:
    """``url`` with a relative SQLite path (``sqlite:///x.db``) made absolute against ``folder``
    (the study file's), so a study finds its storage from any working directory."""
    prefix = "sqlite:///"
    if folder is None or not url.startswith(prefix) or url == prefix + ":memory:":
        return url
    path = Path(url[len(prefix) :])
    return url if path.is_absolute() else prefix + str((folder / path).resolve())


def _scene(data: Any) -> Scene:
    m = _mapping(data, "scene", SCENE_KEYS)
    default = Scene()
    speed = _number(m.get("speed", default.speed), "scene.speed")
    if speed <= 0:
        raise ConfigError(f"scene.speed: must be > 0 (m/s, straight down), got {speed!r}")
    e = _number(m.get("restitution", default.restitution), "scene.restitution")
    if not 0.0 <= e <= 1.0:
        raise ConfigError(f"scene.restitution: must be in [0, 1], got {e!r}")
    friction = _number(m.get("friction", 0.0), "scene.friction")
    if friction < 0:
        raise ConfigError(f"scene.friction: must be >= 0, got {friction!r}")
    gravity = _number(m.get("gravity", 0.0), "scene.gravity")
    if gravity < 0:
        raise ConfigError(f"scene.gravity: must be >= 0 (m/s^2, along -y), got {gravity!r}")
    duration = None if m.get("duration") is None else _positive(m["duration"], "scene.duration")
    return Scene(speed=speed, restitution=e, friction=friction, gravity=gravity, duration=duration)


def _leg(data: Any, folder: Path | None = None) -> Leg | LegChain:
    m = _mapping(data, "leg", LEG_KEYS)
    if "file" in m:
        if len(m) > 1:
            raise ConfigError(f"leg.file: give the leg as a file or as thigh and shank, not both (also: "
                              f"{', '.join(k for k in m if k != 'file')})")
        return _leg_file(m["file"], folder)
    d = Leg()
    values = {}
    for rod, angle_name in (("thigh", "thigh_angle"), ("shank", "knee_angle")):
        where = f"leg.{rod}"
        r = _mapping(m.get(rod, {}), where, ROD_KEYS if rod == "thigh" else ROD_KEYS + KNEE_KEYS)
        for key in ("length", "mass"):
            x = _number(r.get(key, getattr(d, f"{rod}_{key}")), f"{where}.{key}")
            if x <= 0:
                raise ConfigError(f"{where}.{key}: must be > 0, got {x!r}")
            values[f"{rod}_{key}"] = x
        values[angle_name] = _angle(r.get("angle", getattr(d, angle_name)), f"{where}.angle")
        com = _number(r.get("com", d.thigh_com), f"{where}.com")
        if not 0.0 <= com <= 1.0:
            raise ConfigError(f"{where}.com: must be in [0, 1] (a fraction of the length), got {com!r}")
        gyration = _number(r.get("gyration", d.thigh_gyration), f"{where}.gyration")
        if gyration < 0:
            raise ConfigError(f"{where}.gyration: must be >= 0 (a fraction of the length), got {gyration!r}")
        values[f"{rod}_com"], values[f"{rod}_gyration"] = com, gyration
        values[f"{rod}_offset"] = _planar_offset(r.get("com_offset", [0.0, 0.0]), f"{where}.com_offset")
        if any(k in r for k in KNEE_KEYS):
            values["knee"] = joint_law({**r, "angle": values[angle_name]}, where)
    return Leg(**values)


def _planar_offset(value: Any, where: str) -> float:
    """A rod's ``com_offset`` in the plane, [dy, 0] (m): its dy."""
    if not isinstance(value, list) or len(value) != 2 or value[1] != 0:
        raise ConfigError(f"{where}: must be [dy, 0] (m: the centre of mass off the rod, in the plane), "
                          f"got {_describe(value)}")
    return _number(value[0], f"{where}[0]")


def _leg_file(value: Any, folder: Path | None) -> Leg | LegChain:
    """``leg: {file: F}``: a model file's chain of rods (``footopt import`` from the hip, or the
    thigh, to the ankle), planar or spatial: the base first, each rod the child of the one before;
    the foot hangs at the last rod's contact (the ankle, where import puts it) or, without one, at
    its tip. The joints' laws come along. Its scene and other contacts are not used. Two planar
    rods joined at the thigh's tip, the ankle at the shank's tip, are the study's thigh and shank
    (:class:`Leg`, as ``leg: {thigh, shank}`` writes them)."""
    from optimizer.config.model_file import load_model_file
    from impulse_core.kinematics.spatial import PLANAR
    from impulse_core.model.tree import JointKind

    path = Path(_string(value, "leg.file"))
    if folder is not None and not path.is_absolute():
        path = folder / path
    try:
        model = load_model_file(path)
    except ConfigError as e:
        raise ConfigError(f"leg.file: {path}: {e}") from None
    bodies = model.tree.bodies
    for k, b in enumerate(bodies[1:], start=1):
        if b.parent != k - 1:
            raise ConfigError(f"leg.file: {path}: rod '{b.name}' hangs from '{bodies[b.parent].name}', not from "
                              f"'{bodies[k - 1].name}': a leg is a chain, each rod the child of the one before")
    for b in bodies:
        if FOOT_ROD_NAME.fullmatch(b.name):
            raise ConfigError(f"leg.file: {path}: rod '{b.name}' takes a foot rod's name (heel..., toe<i>...): "
                              "rename it")
    last = bodies[-1]
    if len(last.contacts) > 1:
        raise ConfigError(f"leg.file: {path}: its last rod '{last.name}' has {len(last.contacts)} contacts: the foot "
                          "hangs at one ankle (one contact on the last rod, or none: its tip)")
    ankle = last.contacts[0] if last.contacts else 1.0
    joints = model.joints or tuple(FREE for _ in bodies)
    if (model.space is PLANAR and len(bodies) == 2 and bodies[1].joint is JointKind.REVOLUTE
            and bodies[1].at == 1.0 and ankle == 1.0):
        thigh, shank = bodies
        return Leg(thigh_length=thigh.length, thigh_mass=thigh.mass, thigh_angle=thigh.angle,
                   shank_length=shank.length, shank_mass=shank.mass, knee_angle=shank.angle, knee=joints[1],
                   thigh_com=thigh.com, thigh_gyration=thigh.gyration, shank_com=shank.com,
                   shank_gyration=shank.gyration, thigh_offset=thigh.com_offset[0], shank_offset=shank.com_offset[0])
    rods = tuple(replace(b, contacts=()) for b in bodies)
    return LegChain(rods, joints, model.space, ankle, path.resolve())


def _space(data: Any) -> DesignSpace:
    m = _mapping(data, "design_space", SPACE_KEYS)
    d = DesignSpace()
    toes = _int_range(m.get("toes", list(d.toes)), "design_space.toes", 1, MAX_TOES)
    toe_segments = _int_range(m.get("toe_segments", list(d.toe_segments)), "design_space.toe_segments", 1, MAX_SEGMENTS)
    heel = _int_range(m.get("heel_segments", list(d.heel_segments)), "design_space.heel_segments", 1, MAX_SEGMENTS)
    symmetry = _choice(m.get("toe_symmetry", d.toe_symmetry.value), "design_space.toe_symmetry", ToeSymmetry)
    laws = _joint_law_space(m.get("joint_laws", {}))
    return DesignSpace(toes=toes, toe_segments=toe_segments, heel_segments=heel, toe_symmetry=symmetry, joint_laws=laws,
                       splay=_splay(m))


def _splay(m: dict[str, Any]) -> SplaySpace | None:
    """``design_space.space`` and, for a spatial foot, ``splay`` and ``splay_mode``."""
    w = "design_space"
    space = m.get("space", "planar")
    if space not in SPACES:
        raise ConfigError(f"{w}.space: must be one of {', '.join(SPACES)}, got {_describe(space)}")
    if space == "planar":
        for key in ("splay", "splay_mode"):
            if key in m:
                raise ConfigError(f"{w}.{key}: needs design_space.space: spatial (a planar foot has no splay)")
        return None
    d = SplaySpace()
    mode = _choice(m.get("splay_mode", d.mode.value), f"{w}.splay_mode", SplayMode)
    lo, hi = (_number(x, f"{w}.splay[{k}]") for k, x in enumerate(_pair(m.get("splay", list(d.splay)), f"{w}.splay", "numbers")))
    if mode is SplayMode.SYMMETRIC and lo < 0:
        raise ConfigError(f"{w}.splay[0]: the symmetric splay is >= 0 (rad; toes spread from -splay to +splay), got {lo!r}")
    if lo > hi:
        raise ConfigError(f"{w}.splay: min {lo!r} is above max {hi!r}")
    if max(abs(lo), abs(hi)) >= math.pi / 2:
        raise ConfigError(f"{w}.splay: a toe's yaw must stay within (-pi/2, pi/2) rad (it would point backwards), "
                          f"got [{lo!r}, {hi!r}]")
    return SplaySpace((lo, hi), mode)


def _joint_law_space(data: Any) -> JointLawSpace:
    w = "design_space.joint_laws"
    m = _mapping(data, w, JOINT_SPACE_KEYS)
    families = {}
    for name in JOINT_FAMILIES:
        f = _mapping(m.get(name, {}), f"{w}.{name}", FAMILY_KEYS)
        families[name] = JointRanges(**{k: _law_range(f[k], f"{w}.{name}.{k}") for k in FAMILY_KEYS if k in f})
    e = _number(m.get("stop_restitution", 0.0), f"{w}.stop_restitution")
    if not 0.0 <= e <= 1.0:
        raise ConfigError(f"{w}.stop_restitution: must be in [0, 1], got {e!r}")
    return JointLawSpace(**families, stop_restitution=e)


def _law_range(value: Any, where: str) -> tuple[float, float]:
    """[lo, hi] with 0 <= lo <= hi (lo = hi fixes the value); a stop's travel must be > 0."""
    lo, hi = (_number(x, f"{where}[{k}]") for k, x in enumerate(_pair(value, where, "numbers")))
    if lo < 0 or (where.endswith(".stop") and lo <= 0):
        raise ConfigError(f"{where}[0]: must be {'> 0 (rad)' if where.endswith('.stop') else '>= 0'}, got {lo!r}")
    if lo > hi:
        raise ConfigError(f"{where}: min {lo!r} is above max {hi!r}")
    return lo, hi


def _limits(data: Any) -> FootLimits:
    m = _mapping(data, "constraints", CONSTRAINT_KEYS)
    d = FootLimits()
    w = "constraints"
    foot_mass = _positive(m.get("foot_mass", d.foot_mass), f"{w}.foot_mass")
    mode = _choice(m.get("foot_mass_mode", d.mass_mode.value), f"{w}.foot_mass_mode", MassMode)
    min_link = _positive(m.get("min_link_mass", d.min_link_mass), f"{w}.min_link_mass")
    rho = _float_range(m.get("mass_per_length", list(d.mass_per_length)), f"{w}.mass_per_length", positive=True)
    length = _float_range(m.get("foot_length", list(d.foot_length)), f"{w}.foot_length", positive=True)
    clearance = _positive(m.get("min_clearance", d.min_clearance), f"{w}.min_clearance")
    tol = _number(m.get("contact_tolerance", d.contact_tolerance), f"{w}.contact_tolerance")
    if tol < 0:
        raise ConfigError(f"{w}.contact_tolerance: must be >= 0 (m), got {tol!r}")
    margin = None if m.get("support_margin") is None else _number(m["support_margin"], f"{w}.support_margin")
    a = _mapping(m.get("joint_angles", {}), f"{w}.joint_angles", ANGLE_KEYS)
    angles = {k: _float_range(a.get(k, list(getattr(d, k))), f"{w}.joint_angles.{k}") for k in ANGLE_KEYS}
    return FootLimits(
        foot_mass=foot_mass,
        mass_mode=mode,
        min_link_mass=min_link,
        mass_per_length=rho,
        foot_length=length,
        min_clearance=clearance,
        contact_tolerance=tol,
        support_margin=margin,
        **angles,
    )


def _objectives(data: Any) -> tuple[Objective, ...]:
    if isinstance(data, str):
        data = [data]
    if not isinstance(data, list) or not data:
        raise ConfigError(f"objectives: must be a non-empty list of {_allowed(Objective)}, got {_describe(data)}")
    out = tuple(_choice(x, f"objectives[{i}]", Objective) for i, x in enumerate(data))
    for i, o in enumerate(out):
        if o in out[:i]:
            raise ConfigError(f"objectives[{i}]: '{o.value}' is listed twice")
    return out


def _search(data: Any) -> SearchSettings:
    m = _mapping(data, "search", SEARCH_KEYS)
    d = SearchSettings()
    inner = _mapping(m.get("inner", {}), "search.inner", INNER_KEYS)
    return SearchSettings(
        method=_choice(m.get("method", d.method.value), "search.method", SearchMethod),
        sampler=_choice(m.get("sampler", d.sampler.value), "search.sampler", SamplerKind),
        trials=_integer(m.get("trials", d.trials), "search.trials", minimum=1),
        startup_trials=_integer(m.get("startup_trials", d.startup_trials), "search.startup_trials", minimum=1),
        population=_integer(m.get("population", d.population), "search.population", minimum=2),
        front_points=_integer(inner.get("front_points", d.front_points), "search.inner.front_points", minimum=0),
        starts=_integer(inner.get("starts", d.starts), "search.inner.starts", minimum=1),
        landing_tolerance=_landing_tolerance(m.get("landing_tolerance", d.landing_tolerance)),
    )


def _landing_tolerance(value: Any) -> float:
    """``search.landing_tolerance``: a finite number >= MIN_TOLERANCE (finer never ends)."""
    x = _number(value, "search.landing_tolerance")
    if x < MIN_TOLERANCE:
        raise ConfigError(f"search.landing_tolerance: must be >= {MIN_TOLERANCE:g} (relative), got {x!r}")
    return x


# --------------------------------------------------------------------------------------------
# Writing


def format_study(config: StudyConfig, header_comment: str | None = None) -> str:
    """The resolved study as YAML: every value explicit; ``load_study`` reads it back equal."""
    s, leg, sp, lim, se = config.scene, config.leg, config.space, config.limits, config.search
    f = _float_text
    lines = [f"# {line}".rstrip() for line in header_comment.splitlines()] if header_comment else []
    lines += [
        f"name: {_string_text(config.name)}",
        f"seed: {config.seed}",
        f"storage: {'null' if config.storage is None else _string_text(redact_url(config.storage))}",
        "scene:",
        f"  speed: {f(s.speed)}",
        f"  restitution: {f(s.restitution)}",
        f"  friction: {f(s.friction)}",
        f"  gravity: {f(s.gravity)}",
        f"  duration: {'null' if s.duration is None else f(s.duration)}",
        "leg:",
        *_leg_lines(leg),
        "design_space:",
        f"  toes: [{sp.toes[0]}, {sp.toes[1]}]",
        f"  toe_segments: [{sp.toe_segments[0]}, {sp.toe_segments[1]}]",
        f"  heel_segments: [{sp.heel_segments[0]}, {sp.heel_segments[1]}]",
        f"  toe_symmetry: {sp.toe_symmetry.value}",
        *_joint_law_space_lines(sp.joint_laws),
        *_splay_lines(sp.splay),
        "constraints:",
        f"  foot_mass: {f(lim.foot_mass)}",
        f"  foot_mass_mode: {lim.mass_mode.value}",
        f"  min_link_mass: {f(lim.min_link_mass)}",
        f"  mass_per_length: [{f(lim.mass_per_length[0])}, {f(lim.mass_per_length[1])}]",
        f"  foot_length: [{f(lim.foot_length[0])}, {f(lim.foot_length[1])}]",
        f"  min_clearance: {f(lim.min_clearance)}",
        "  joint_angles:",
        *(f"    {k}: [{f(getattr(lim, k)[0])}, {f(getattr(lim, k)[1])}]" for k in ANGLE_KEYS),
        f"  contact_tolerance: {f(lim.contact_tolerance)}",
        *([] if lim.support_margin is None else [f"  support_margin: {f(lim.support_margin)}"]),
        f"objectives: [{', '.join(o.value for o in config.objectives)}]",
        "search:",
        f"  method: {se.method.value}",
        f"  sampler: {se.sampler.value}",
        f"  trials: {se.trials}",
        f"  startup_trials: {se.startup_trials}",
        f"  population: {se.population}",
        "  inner:",
        f"    front_points: {se.front_points}",
        f"    starts: {se.starts}",
        f"  landing_tolerance: {f(se.landing_tolerance)}",
        *_landings_lines(config),
    ]
    return "\n".join(lines) + "\n"


def _landings_lines(config: StudyConfig) -> list[str]:
    """``landings:`` and ``statistic:`` (nothing when the study has none)."""
    lines = []
    if config.landings is not None:
        lines += ["landings:", f"  count: {config.landings.count}", f"  seed: {config.landings.seed}"]
        for name, d in config.landings.distributions:
            values = ", ".join(_float_text(v) for v in d.values)
            text = f"[{values}]" if d.kind is DistributionKind.VALUES else f"{{{d.kind.value}: [{values}]}}"
            lines.append(f"  {name}: {text}")
    if config.statistic:
        lines.append("statistic:")
        lines += [f"  {o.value}: {_string_text(st.text)}" for o, st in config.statistic]
    return lines


def _leg_lines(leg: Leg | LegChain) -> list[str]:
    """``leg:``'s lines: the thigh and shank inline, or a chain's model file (its absolute path)."""
    if isinstance(leg, LegChain):
        if leg.file is None:
            raise ValueError("format_study: a leg chain without its model file cannot be written")
        return [f"  file: {_string_text(str(leg.file))}"]
    f = _float_text
    return [
        f"  thigh: {{length: {f(leg.thigh_length)}, mass: {f(leg.thigh_mass)}, angle: {f(leg.thigh_angle)}"
        f"{_mass_text(leg, 'thigh')}}}",
        f"  shank: {{length: {f(leg.shank_length)}, mass: {f(leg.shank_mass)}, angle: {f(leg.knee_angle)}"
        f"{_mass_text(leg, 'shank')}{_knee_text(leg)}}}",
    ]


def _mass_text(leg: Leg, rod: str) -> str:
    """A rod's ``com``, ``gyration`` and ``com_offset`` inside its flow mapping (empty when a
    uniform rod's)."""
    d, parts = Leg(), []
    for key in ("com", "gyration"):
        value = getattr(leg, f"{rod}_{key}")
        if value != getattr(d, f"{rod}_{key}"):
            parts.append(f", {key}: {_float_text(value)}")
    if getattr(leg, f"{rod}_offset") != 0.0:
        parts.append(f", com_offset: [{_float_text(getattr(leg, f'{rod}_offset'))}, 0]")
    return "".join(parts)


def _splay_lines(splay: SplaySpace | None) -> list[str]:
    """``design_space.space`` and its splay (nothing for the planar foot)."""
    if splay is None:
        return []
    lo, hi = (_float_text(x) for x in splay.splay)
    return ["  space: spatial", f"  splay: [{lo}, {hi}]", f"  splay_mode: {splay.mode.value}"]


def _knee_text(leg: Leg) -> str:
    """The knee law's keys inside the shank's flow mapping (empty when free)."""
    k, f = leg.knee, _float_text
    parts = [f"{key}: {f(getattr(k, key))}" for key in ("stiffness", "damping", "stop_restitution") if getattr(k, key)]
    if k.limits is not None:
        parts.append(f"limits: [{f(k.limits[0])}, {f(k.limits[1])}]")
    return "".join(f", {p}" for p in parts)


def _joint_law_space_lines(space: JointLawSpace) -> list[str]:
    """``design_space.joint_laws`` (nothing when no family has a law)."""
    if space.empty:
        return []
    lines = ["  joint_laws:"]
    for name in JOINT_FAMILIES:
        r = getattr(space, name)
        parts = [f"{k}: [{_float_text(v[0])}, {_float_text(v[1])}]" for k in FAMILY_KEYS if (v := getattr(r, k)) is not None]
        if parts:
            lines.append(f"    {name}: {{{', '.join(parts)}}}")
    lines.append(f"    stop_restitution: {_float_text(space.stop_restitution)}")
    return lines


def _float_text(x: float) -> str:
    text = repr(float(x))
    mantissa, e, exponent = text.partition("e")
    return f"{mantissa}.0e{exponent}" if e and "." not in mantissa else text


def _string_text(s: str) -> str:
    import json

    return json.dumps(s)  # a JSON string is a valid double-quoted YAML scalar


# --------------------------------------------------------------------------------------------
# Field helpers: each raises ConfigError naming the YAML path


def _allowed(enum: type[Enum]) -> str:
    return ", ".join(e.value for e in enum)


def _mapping(value: Any, where: str, allowed: tuple[str, ...], what: str | None = None) -> dict[str, Any]:
    """A mapping with only ``allowed`` keys; an absent section (null) is empty."""
    return {} if value is None else _checked_mapping(value, where, allowed, what)






def _integer(value: Any, where: str, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise ConfigError(f"{where}: must be an integer >= {minimum}, got {_describe(value)}")
    return int(value)


def _pair(value: Any, where: str, what: str) -> tuple[Any, Any]:
    if not isinstance(value, list) or len(value) != 2:
        raise ConfigError(f"{where}: must be a list [min, max] of {what}, got {_describe(value)}")
    return value[0], value[1]


def _int_range(value: Any, where: str, minimum: int, maximum: int | None) -> tuple[int, int]:
    lo, hi = _pair(value, where, "integers")
    lo = _integer(lo, f"{where}[0]", minimum)
    hi = _integer(hi, f"{where}[1]", minimum)
    if maximum is not None and hi > maximum:
        raise ConfigError(f"{where}[1]: must be at most {maximum}, got {hi}")
    if lo > hi:
        raise ConfigError(f"{where}: min {lo} is above max {hi}")
    return lo, hi


def _float_range(value: Any, where: str, positive: bool = False) -> tuple[float, float]:
    lo, hi = _pair(value, where, "numbers")
    lo = _positive(lo, f"{where}[0]") if positive else _number(lo, f"{where}[0]")
    hi = _positive(hi, f"{where}[1]") if positive else _number(hi, f"{where}[1]")
    if lo >= hi:
        raise ConfigError(f"{where}: min {lo!r} must be below max {hi!r}")
    return lo, hi


def _choice(value: Any, where: str, enum: type[Enum]) -> Any:
    for e in enum:
        if value == e.value:
            return e
    raise ConfigError(f"{where}: must be one of {_allowed(enum)}, got {_describe(value)}")


__all__ = [
    "SamplerKind",
    "SearchMethod",
    "SearchSettings",
    "StudyConfig",
    "format_study",
    "load_study",
    "check_inner_whole_landings",
    "parse_study",
]
