"""A design's frictionless first-impact landings evaluated together (issue #14's batching).

A scenario that lands on flat ground, without friction and without ``duration`` is one first
impact, and what changes between such scenarios is numeric: the base angle (``pitch``), the
approach (``speed``, ``velocity_x``, ``angular_velocity``) and ``restitution``. They are
evaluated as columns of one call of the topology's impact function (CasADi's ``map``), grouped
by which contacts hit (the lowest within ``contact_tolerance``, from the touchdown geometry of
every scenario at once). The values are the ones ``footopt evaluate`` computes for the
scenario's file, operation for operation: the same compiled function on the same inputs.
Where that function's answer is not the one ``auto`` would report (a contact pulls, so ``lcp``
runs; a singular Delassus matrix, so the redundant-contact path runs), the scenario is left to
the caller (None in the mask).
"""

from __future__ import annotations

import functools

import casadi as ca
import numpy as np

from impulse_core.evaluate import compiled_geometry, compiled_model
from impulse_core.impact.laws import PIVOT_TOL
from impulse_core.kinematics.spatial import dof_layout
from impulse_core.model.tree import ContactSelection, Topology, design_vector
from optimizer.config.model_file import ModelFile
from optimizer.design_space import Objectives

#: Index of the base's angle in the design vector (``tree.BODY_VALUES``: length, mass, angle).
BASE_ANGLE = 2


def batchable(model: ModelFile, names: tuple[str, ...], values: np.ndarray) -> np.ndarray:
    """Which scenarios are frictionless first impacts on flat ground (module docstring)."""
    s = model.scene
    if s.duration is not None or not s.terrain.is_flat or "terrain_step" in names:
        return np.zeros(len(values), dtype=bool)
    friction = values[:, names.index("friction")] if "friction" in names else np.full(len(values), s.friction)
    return friction == 0.0


def scenario_inputs(model: ModelFile, names: tuple[str, ...], values: np.ndarray):
    """(P, V, E): design vectors, pre-impact velocities and restitutions, one row per scenario,
    as the scenario's file gives them (``scenarios.overrides``)."""
    s, n = model.scene, len(values)
    column = dict(zip(names, values.T, strict=True))
    P = np.tile(design_vector(model.tree), (n, 1))
    if "pitch" in column:
        P[:, BASE_ANGLE] = model.tree.bodies[0].angle + column["pitch"]
    V = np.zeros((n, dof_layout(model.tree.topology()).nv))
    V[:, 0] = column.get("velocity_x", s.velocity_x)
    V[:, 1] = -column.get("speed", s.speed)
    V[:, 2] = column.get("angular_velocity", s.angular_velocity)
    E = np.broadcast_to(column.get("restitution", s.restitution), (n,)).astype(float)
    return P, V, E


def active_sets(model: ModelFile, P: np.ndarray) -> list[tuple[int, ...]]:
    """Each scenario's hitting contacts (``impulse_core.evaluate.active_contacts``, all rows at once)."""
    n_declared = len(model.tree.contacts)
    if model.scene.selection is ContactSelection.ALL:
        return [tuple(range(n_declared))] * len(P)
    geometry = _mapped(compiled_geometry(model.tree.topology()), len(P))
    heights = np.array(geometry(P.T)[3])[1].reshape(len(P), n_declared)  # contacts: 3 x (declared x rows)
    low = heights.min(axis=1, keepdims=True) + model.scene.contact_tolerance
    return [tuple(int(i) for i in np.flatnonzero(row <= lim)) for row, lim in zip(heights, low[:, 0], strict=True)]


@functools.lru_cache(maxsize=64)
def _mapped(f: ca.Function, n: int) -> ca.Function:
    return f.map(n)


def first_impacts(model: ModelFile, names: tuple[str, ...], values: np.ndarray) -> list[Objectives | None]:
    """Each batchable scenario's objectives (``batchable``), None where the caller must evaluate
    the scenario itself (not batchable, or not the Newton answer ``auto`` reports)."""
    out: list[Objectives | None] = [None] * len(values)
    rows = np.flatnonzero(batchable(model, names, values))
    if rows.size == 0:
        return out
    P, V, E = scenario_inputs(model, names, values[rows])
    groups: dict[tuple[int, ...], list[int]] = {}
    for k, active in enumerate(active_sets(model, P)):
        groups.setdefault(active, []).append(k)
    for active, members in groups.items():
        found = _newton_rows(model.tree.topology(active), P[members], V[members], E[members])
        for k, objectives in zip(members, found, strict=True):
            out[int(rows[k])] = objectives
    return out


def _newton_rows(topology: Topology, P: np.ndarray, V: np.ndarray, E: np.ndarray) -> list[Objectives | None]:
    """The impact function on every row; Objectives where its Newton answer is ``auto``'s."""
    impact = compiled_model(topology).impact
    res = dict(zip(impact.name_out(), _mapped(impact, len(P))(P.T, V.T, E[None, :]), strict=True))
    arrays = {k: np.array(v) for k, v in res.items()}
    out: list[Objectives | None] = []
    for j in range(len(P)):
        lam, pivots, v_plus = arrays["external"][:, j], arrays["delassus_pivots"][:, j], arrays["v_plus"][:, j]
        magnitude, energy = arrays["internal_magnitude"][:, j], arrays["energy_after"][:, j]
        finite = all(np.isfinite(x).all() for x in (lam, v_plus, magnitude, energy))
        if not finite or lam.min(initial=0.0) < 0 or pivots.min(initial=1.0) < PIVOT_TOL:
            out.append(None)
            continue
        out.append(  # as impulse_core.evaluate's result and design_space.objectives compute them
            Objectives(
                external_norm=float(np.linalg.norm(lam)),
                internal_norm=float(np.linalg.norm(magnitude)),
                max_internal=float(magnitude.max()) if magnitude.size else 0.0,
                base_angular_velocity=abs(float(v_plus[2])),
                energy_after=float(energy[0]),
            )
        )
    return out


__all__ = ["active_sets", "batchable", "first_impacts", "scenario_inputs"]
