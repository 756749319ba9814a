"""Distributions of landings (a study's ``landings:`` block) and a design evaluated over them.

A study draws its scenarios once from its seed (common random numbers: every design meets the
same landings). A scenario is a set of *overrides* of the design's model file: dotted
``MODEL_FORMAT.md`` paths and their values (``scene.velocity``, ``model.bodies.0.angle``, ...).
Applying them to the model file's data and evaluating the result as ``footopt evaluate`` does is,
by construction, how a scenario is scored, so that a row of ``scenarios.csv`` is reproduced by
``footopt evaluate`` on the overridden file exactly.

Parameters (each optional): ``speed`` (m/s, downward), ``velocity_x`` (m/s), ``pitch`` (rad, added
to the base's angle), ``angular_velocity`` (rad/s, about z), ``restitution``, ``friction``,
``terrain_step`` (m: the ground is raised by this much in front of the midpoint between the
rearmost and the foremost contact at touchdown, a 2 mm ramp; under a footopt foot: under the toes,
not the heel; planar models only). Spatial models only: ``roll`` (rad, added to the base's rpy
roll, its turn about x before its angle about z), ``roll_rate`` (rad/s, the angular velocity about
x) and ``velocity_z`` (m/s, lateral).
"""

from __future__ import annotations

import copy
import functools
from dataclasses import dataclass
from enum import Enum
from typing import Any

import numpy as np

from impulse_core.evaluate import touchdown_geometry
from optimizer.config.model_file import ModelFile, format_model_file, load_yaml, parse_model
from optimizer.errors import ConfigError

#: The landing parameters, in the order they are drawn.
PARAMETERS = ("speed", "velocity_x", "pitch", "angular_velocity", "restitution", "friction", "terrain_step",
              "roll", "roll_rate", "velocity_z")
#: The parameters only a spatial model has, and those only a planar one has.
SPATIAL_PARAMETERS = ("roll", "roll_rate", "velocity_z")
PLANAR_PARAMETERS = ("terrain_step",)
#: Width of a terrain step's ramp (m).
STEP_RAMP = 2e-3


class DistributionKind(Enum):
    UNIFORM = "uniform"  # values: (lo, hi)
    NORMAL = "normal"  # values: (mean, sd)
    VALUES = "values"  # each scenario picks one of the values, equally likely


@dataclass(frozen=True)
class Distribution:
    kind: DistributionKind
    values: tuple[float, ...]

    def draw(self, rng: np.random.Generator, n: int) -> np.ndarray:
        if self.kind is DistributionKind.UNIFORM:
            return rng.uniform(self.values[0], self.values[1], n)
        if self.kind is DistributionKind.NORMAL:
            return rng.normal(self.values[0], self.values[1], n)
        return rng.choice(np.array(self.values), n)


@dataclass(frozen=True)
class Landings:
    """A study's landings: ``count`` scenarios drawn from ``seed``, one distribution per varied
    parameter (name, distribution), in ``PARAMETERS`` order."""

    count: int = 64
    seed: int = 0
    distributions: tuple[tuple[str, Distribution], ...] = ()

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(name for name, _ in self.distributions)

    def draw(self) -> np.ndarray:
        """The scenarios' values: ``count`` x one column per distribution (the same every call;
        drawn once per process, read-only)."""
        return _drawn(self)


@functools.lru_cache(maxsize=16)
def _drawn(landings: Landings) -> np.ndarray:
    rng = np.random.default_rng(landings.seed)
    columns = [d.draw(rng, landings.count) for _, d in landings.distributions]
    out = np.column_stack(columns) if columns else np.zeros((landings.count, 0))
    out.setflags(write=False)
    return out


def overrides(model: ModelFile, names: tuple[str, ...], values: np.ndarray) -> dict[str, Any]:
    """The dotted-path overrides of one scenario on ``model`` (module docstring).

    Raises:
        ConfigError: a spatial parameter on a planar model, or a planar one on a spatial model.
    """
    given = {n: float(v) for n, v in zip(names, values, strict=True)}
    spatial = model.space.joint_axis is None
    wrong = [n for n in given if n in (PLANAR_PARAMETERS if spatial else SPATIAL_PARAMETERS)]
    if wrong:
        need = "a planar model (a step is a planar terrain)" if spatial else "a spatial model (model.space: spatial)"
        raise ConfigError(f"landings.{wrong[0]}: needs {need}", model.path)
    out = _spatial_approach(model, given) if spatial else _planar_approach(model, given)
    if "pitch" in given:
        out["model.bodies.0.angle"] = model.tree.bodies[0].angle + given["pitch"]
    if "roll" in given:
        a, b, c = model.tree.bodies[0].rpy
        out["model.bodies.0.rpy"] = [a + given["roll"], b, c]
    for name in ("restitution", "friction"):
        if name in given:
            out[f"scene.{name}"] = given[name]
    if "terrain_step" in given:
        x = touchdown_geometry(model.tree).contacts[:, 0] + model.scene.base_x
        middle = 0.5 * (float(x.min()) + float(x.max()))
        out["scene.terrain"] = [[middle - STEP_RAMP / 2, 0.0], [middle + STEP_RAMP / 2, given["terrain_step"]]]
    return out


def _planar_approach(model: ModelFile, given: dict[str, float]) -> dict[str, Any]:
    """``scene.speed`` or ``scene.velocity`` [vx, vy], and ``scene.angular_velocity``."""
    s, out = model.scene, {}
    speed = given.get("speed", s.speed)
    if "velocity_x" in given or ("speed" in given and s.velocity_x != 0.0):
        out["scene.velocity"] = [given.get("velocity_x", s.velocity_x), -speed]
    elif "speed" in given:
        out["scene.speed"] = speed
    if "angular_velocity" in given:
        out["scene.angular_velocity"] = given["angular_velocity"]
    return out


def _spatial_approach(model: ModelFile, given: dict[str, float]) -> dict[str, Any]:
    """``scene.velocity`` [vx, vy, vz] and ``scene.angular_velocity`` [wx, wy, wz] (world frame),
    each written whole where a scenario changes a component."""
    s, out = model.scene, {}
    if given.keys() & {"speed", "velocity_x", "velocity_z"}:
        out["scene.velocity"] = [given.get("velocity_x", s.velocity_x), -given.get("speed", s.speed),
                                 given.get("velocity_z", s.velocity_z)]
    if given.keys() & {"roll_rate", "angular_velocity"}:
        out["scene.angular_velocity"] = [given.get("roll_rate", s.angular_velocity_x), s.angular_velocity_y,
                                         given.get("angular_velocity", s.angular_velocity)]
    return out


def apply_overrides(data: dict[str, Any], changes: dict[str, Any]) -> dict[str, Any]:
    """A copy of model-file data with each dotted path set (list indices as numbers); setting
    ``scene.velocity`` drops ``scene.speed`` and the reverse (``MODEL_FORMAT.md``)."""
    out = copy.deepcopy(data)
    for path, value in changes.items():
        keys = [int(k) if k.isdigit() else k for k in path.split(".")]
        node = out
        for k in keys[:-1]:
            node = node[k]
        node[keys[-1]] = copy.deepcopy(value)
        if path in ("scene.velocity", "scene.speed"):
            out["scene"].pop("speed" if path == "scene.velocity" else "velocity", None)
    return out


def model_data(model: ModelFile) -> dict[str, Any]:
    """``model``'s file as data (what :func:`scenario_model` overrides; read once per design)."""
    return load_yaml(format_model_file(model))


def scenario_model(data: dict[str, Any], changes: dict[str, Any]) -> ModelFile:
    """The model of file data ``data`` (:func:`model_data`) with ``changes`` applied, as an outside
    check would apply them to the file."""
    return parse_model(apply_overrides(data, changes))


__all__ = [
    "PARAMETERS",
    "PLANAR_PARAMETERS",
    "SPATIAL_PARAMETERS",
    "Distribution",
    "DistributionKind",
    "Landings",
    "apply_overrides",
    "model_data",
    "overrides",
    "scenario_model",
]
