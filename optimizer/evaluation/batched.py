"""A design's frictionless first-impact landings evaluated together (issue #14's batching).

A scenario that lands on flat ground, without friction and without ``duration`` is one first
impact, and what changes between such scenarios is numeric: the base angle (``pitch``), the
approach (``speed``, ``velocity_x``, ``angular_velocity``) and ``restitution``. They are
evaluated as rows of one call of the topology's lean impact function
(:func:`impulse_core.impact.delassus.scenario_impact_function`: the hot path's algorithm plus the
motion after the impact), grouped by which contacts hit (the lowest within
``contact_tolerance``, from the touchdown geometry of every scenario at once). From
:data:`COMPILE_ROWS` rows on, the call runs as compiled C from the trusted cache, below on
CasADi's virtual machine (the same operations; the SIMD lanes' sine and cosine differ from
libm's in the last bits: 1e-13 relative, tested). The values equal
``footopt evaluate``'s (the full impact function) to rounding (1e-12 relative, tested). Where
Newton's answer is not the one ``auto`` would report (a contact pulls, so ``lcp`` runs; a singular
Delassus matrix, so the redundant-contact path runs), the scenario is left to the caller (a NaN
row).
"""

from __future__ import annotations

import functools
from pathlib import Path

import casadi as ca
import numpy as np

from impulse_core.compile.cache import default_root
from impulse_core.compile.codegen import batch_kernel, compile_function, simd_lanes
from impulse_core.evaluate import compiled_geometry
from impulse_core.impact.delassus import SCENARIO_IMPACT_OUTPUTS, scenario_impact_function
from impulse_core.impact.laws import PIVOT_TOL
from impulse_core.kinematics.spatial import PLANAR, Space, dof_layout, values_space
from impulse_core.model.tree import ContactSelection, Topology, design_vector
from optimizer.config.model_file import ModelFile
from optimizer.design_space import Objectives

#: Index of the base's angle in the design vector (``tree.BODY_VALUES``: length, mass, angle).
BASE_ANGLE = 2


def batchable(model: ModelFile, names: tuple[str, ...], values: np.ndarray) -> np.ndarray:
    """Which scenarios are frictionless planar first impacts on flat ground (module docstring;
    a spatial model's are evaluated one by one)."""
    s = model.scene
    if s.duration is not None or not s.ground_is_flat or "terrain_step" in names or model.space.joint_axis is None:
        return np.zeros(len(values), dtype=bool)
    friction = values[:, names.index("friction")] if "friction" in names else np.full(len(values), s.friction)
    return friction == 0.0


def scenario_inputs(model: ModelFile, names: tuple[str, ...], values: np.ndarray):
    """(P, V, E): design vectors, pre-impact velocities and restitutions, one row per scenario,
    as the scenario's file gives them (``scenarios.overrides``)."""
    s, n = model.scene, len(values)
    column = dict(zip(names, values.T, strict=True))
    P = np.tile(design_vector(model.tree, _space(model).body_values), (n, 1))
    if "pitch" in column:
        P[:, BASE_ANGLE] = model.tree.bodies[0].angle + column["pitch"]
    V = np.zeros((n, dof_layout(model.tree.topology()).nv))
    V[:, 0] = column.get("velocity_x", s.velocity_x)
    V[:, 1] = -column.get("speed", s.speed)
    V[:, 2] = column.get("angular_velocity", s.angular_velocity)
    E = np.broadcast_to(column.get("restitution", s.restitution), (n,)).astype(float)
    return P, V, E


def _space(model: ModelFile) -> Space:
    """The values' space of a planar model (PLANAR_OFFSET where a centre of mass is off its rod)."""
    return values_space(model.tree, PLANAR)


def active_sets(model: ModelFile, P: np.ndarray, pitched: bool = True) -> list[tuple[int, ...]]:
    """Each scenario's hitting contacts (``impulse_core.evaluate.active_contacts``, all rows at
    once; without ``pitched`` every row has the file's geometry, computed once)."""
    return [tuple(int(i) for i in np.flatnonzero(row)) for row in _hitting(model, P, pitched)]


def _hitting(model: ModelFile, P: np.ndarray, pitched: bool) -> np.ndarray:
    """Which declared contacts hit in each scenario (scenarios x declared, boolean)."""
    n_declared = len(model.tree.contacts)
    if model.scene.selection is ContactSelection.ALL:
        return np.ones((len(P), n_declared), dtype=bool)
    rows = P if pitched else P[:1]
    contacts = _rows(compiled_geometry(model.tree.topology(), _space(model)), rows)[3]  # 3 x declared, column-major
    heights = contacts.reshape(len(rows), n_declared, 3)[:, :, 1]
    hit = heights <= heights.min(axis=1, keepdims=True) + model.scene.contact_tolerance
    return hit if pitched else np.repeat(hit, len(P), axis=0)


@functools.lru_cache(maxsize=64)
def _mapped(f: ca.Function, n: int) -> ca.Function:
    return f.map(n)


#: The first impact's objectives, in the columns of :func:`first_impact_values`.
FIRST_IMPACT = ("external_norm", "internal_norm", "max_internal", "base_angular_velocity", "energy_after")
#: From this many rows of one contact set on, the impact runs as compiled C (cached on disk).
COMPILE_ROWS = 256


def first_impact_values(model: ModelFile, names: tuple[str, ...], values: np.ndarray) -> np.ndarray:
    """Each scenario's ``FIRST_IMPACT`` objectives (scenarios x 5), NaN rows where the caller
    must evaluate the scenario itself (not batchable, or not the Newton answer ``auto`` reports)."""
    return first_impact_values_many([model], names, values)[0]


def first_impact_values_many(models: list[ModelFile], names: tuple[str, ...], values: np.ndarray) -> list[np.ndarray]:
    """:func:`first_impact_values` of every model on the same scenarios: designs x scenarios in
    one call per structure and contact set (designs of one shape share it)."""
    tables = [np.full((len(values), len(FIRST_IMPACT)), np.nan) for _ in models]
    groups: dict[tuple[Topology, Space], list[tuple[int, np.ndarray, np.ndarray, np.ndarray, np.ndarray]]] = {}
    for i, model in enumerate(models):
        rows = np.flatnonzero(batchable(model, names, values))
        if rows.size == 0:
            continue
        P, V, E = scenario_inputs(model, names, values[rows])
        hit = _hitting(model, P, "pitch" in names)
        for members in _groups(hit):
            active = tuple(int(c) for c in np.flatnonzero(hit[members[0]]))
            key = (model.tree.topology(active), _space(model))
            groups.setdefault(key, []).append((i, rows[members], P[members], V[members], E[members]))
    for (topology, space), parts in groups.items():
        found = _newton_rows(topology, space, *(np.concatenate([part[k] for part in parts]) for k in (2, 3, 4)))
        start = 0
        for i, rows, P, _, _ in parts:
            tables[i][rows] = found[start : start + len(P)]
            start += len(P)
    return tables


def first_impacts(model: ModelFile, names: tuple[str, ...], values: np.ndarray) -> list[Objectives | None]:
    """:func:`first_impact_values` as one ``Objectives`` (or None) per scenario."""
    table = first_impact_values(model, names, values)
    return [None if np.isnan(row).any() else Objectives(**dict(zip(FIRST_IMPACT, map(float, row), strict=True)))
            for row in table]


def _groups(hit: np.ndarray) -> list[np.ndarray]:
    """The rows of each distinct contact set (rows of ``hit`` that are equal)."""
    if hit.shape[1] <= 62:  # one integer per set: far cheaper than comparing rows
        codes = hit @ (1 << np.arange(hit.shape[1], dtype=np.int64))
    else:
        codes = np.unique(hit, axis=0, return_inverse=True)[1].ravel()
    return [np.flatnonzero(codes == c) for c in np.unique(codes)]


def _newton_rows(topology: Topology, space: Space, P: np.ndarray, V: np.ndarray, E: np.ndarray) -> np.ndarray:
    """The objectives of every row (rows x 5); NaN where Newton's answer is not ``auto``'s."""
    f = _scenario_function(topology, space)
    out = dict(zip(SCENARIO_IMPACT_OUTPUTS, _rows(f, P, V, E[:, None]), strict=True))
    lam, magnitude = out["external"], out["internal_magnitude"]
    table = np.column_stack([
        out["external_norm"][:, 0],
        out["internal_norm"][:, 0],
        magnitude.max(axis=1) if magnitude.shape[1] else np.zeros(len(P)),
        np.abs(out["v_plus"][:, 2]),
        out["energy_after"][:, 0],
    ])
    finite = np.all([np.isfinite(o).all(axis=1) for o in out.values()], axis=0)
    pulls = lam.min(axis=1, initial=0.0) < 0
    singular = out["delassus_pivots"].min(axis=1, initial=1.0) < PIVOT_TOL
    table[~finite | pulls | singular] = np.nan
    return table


def _rows(f: ca.Function, *inputs: np.ndarray) -> list[np.ndarray]:
    """``f`` on every row of its inputs (one row per call, one array per output, rows out):
    compiled C from :data:`COMPILE_ROWS` rows on (or where no compiler runs, the VM), else the VM."""
    n = inputs[0].shape[0]
    run = _batch_kernel(f, default_root()) if n >= COMPILE_ROWS else None
    if run is not None:
        return run(*inputs)
    outs = _mapped(f, n)(*(x.T for x in inputs))
    return [np.array(o, dtype=float).T.reshape(n, -1) for o in outs]


@functools.lru_cache(maxsize=64)
def _scenario_function(topology: Topology, space: Space = PLANAR) -> ca.Function:
    return scenario_impact_function(topology, space)


@functools.lru_cache(maxsize=64)
def _batch_kernel(f: ca.Function, root: Path):
    """``f``'s compiled C loop, SIMD where the library has it (None where no compiler runs: a
    warning says so)."""
    compiled = compile_function(f, root, fallback=True)
    return batch_kernel(compiled, f, simd=simd_lanes(compiled, f) > 0)


__all__ = [
    "COMPILE_ROWS",
    "FIRST_IMPACT",
    "active_sets",
    "batchable",
    "first_impact_values",
    "first_impact_values_many",
    "first_impacts",
    "scenario_inputs",
]
