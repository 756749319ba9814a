"""A design scored over a distribution of landings: each scenario's objectives, and each
objective's statistic over the scenarios (:mod:`optimizer.evaluation.scenarios`,
:mod:`optimizer.evaluation.statistics`).

Each scenario is the design's model file with the scenario's overrides, evaluated by the model
``auto`` picks for it, as ``footopt evaluate`` does (a terrain step: the sequential model; a
scene with ``duration``: the whole landing; a spatial model in space). Frictionless planar first
impacts on flat ground are evaluated together, the rest one after another.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, fields
from functools import partial
from typing import Any

import numpy as np

from impulse_core.errors import ModelError, NumericalError
from impulse_core.timedomain.landing import LandingResult, LandingSettings
from optimizer.config.model_file import ModelFile
from optimizer.design_space import Objective, Objectives, objectives, scored_landing
from optimizer.evaluation.batched import FIRST_IMPACT, first_impact_values, first_impact_values_many
from optimizer.evaluation.model_choice import evaluate_landing
from optimizer.evaluation.scenarios import Landings, model_data, overrides, scenario_model
from optimizer.evaluation.statistics import Statistic
from optimizer.workers import cores, forked_pool, mapped


@dataclass(frozen=True)
class ScenarioRow:
    """One scenario of one design: its overrides and objectives (None: the evaluation failed)."""

    scenario: int
    overrides: dict[str, Any]
    objectives: Objectives | None


@dataclass(frozen=True)
class RobustEvaluation:
    """A design over the landings: every scenario, and each objective's statistic (None when a
    scenario failed: the design cannot be scored on all the landings)."""

    rows: tuple[ScenarioRow, ...]
    statistics: Objectives | None


def scenario_objectives(model: ModelFile, whole: LandingSettings | None = None) -> Objectives | None:
    """One model file's objectives by the model ``auto`` picks (None if the numerics fail, or the
    landing refuses a joint law too stiff to follow: a design's, as :func:`optimizer.design_space.
    evaluate_design_landing` records it); a whole landing with the settings ``whole`` (default
    ``footopt evaluate``'s)."""
    with np.errstate(all="ignore"):
        try:
            result = evaluate_landing(model.tree, model.scene, "auto", joints=model.joints, whole=whole, space=model.space)
        except (np.linalg.LinAlgError, NumericalError, ModelError):  # ModelError: a joint law too stiff to follow
            return None
    inner = getattr(result, "result", None)
    if isinstance(inner, LandingResult):
        return scored_landing(inner)
    found = objectives(result, model.space)
    return found if all(math.isfinite(v) for _, v in found.items()) else None


def scenario_table(
    model: ModelFile, names: tuple[str, ...], draws: np.ndarray, batched: np.ndarray | None = None,
    whole: LandingSettings | None = None, progress: Callable[[int, int], None] | None = None,
    pool: ProcessPoolExecutor | None = None,
) -> tuple[tuple[str, ...], np.ndarray]:
    """Every scenario's objectives: their names and one row per scenario (NaN: the evaluation
    failed). Batchable first impacts together (:func:`first_impact_values`, or ``batched`` when
    the caller evaluated them already), the rest one by one (whole landings with ``whole``), in
    ``pool``'s worker processes when given (:func:`optimizer.workers.mapped`: the same rows),
    ``progress`` told (done, of) after each of those."""
    table = first_impact_values(model, names, draws) if batched is None else batched.copy()
    todo = np.flatnonzero(np.isnan(table).any(axis=1))
    if todo.size == 0:
        return FIRST_IMPACT, table
    data = model_data(model)
    models = [scenario_model(data, overrides(model, names, draws[k])) for k in todo]
    found = dict(zip(map(int, todo), mapped(pool, partial(_objectives, whole), models, progress)))
    done = [o for o in found.values() if o is not None]
    keys = tuple(f.name for f in fields(Objectives) if done and getattr(done[0], f.name) is not None) or FIRST_IMPACT
    if keys != FIRST_IMPACT:
        table = np.full((len(draws), len(keys)), np.nan)
    for k, o in found.items():
        if o is not None:
            table[k] = [getattr(o, n) for n in keys]
    return keys, table


def _objectives(whole: LandingSettings | None, model: ModelFile) -> Objectives | None:
    """:func:`scenario_objectives` as a worker runs it (by its name, as this module has it then)."""
    return scenario_objectives(model, whole)


def statistics_of(keys: tuple[str, ...], table: np.ndarray, statistic: Callable[[Objective], Statistic]) -> Objectives | None:
    """Each objective's statistic over the table's rows (None if a row failed)."""
    if np.isnan(table).any() or len(table) == 0:
        return None
    return Objectives(**{n: statistic(Objective(n)).of(table[:, j]) for j, n in enumerate(keys)})


def statistics_over_landings(
    model: ModelFile, landings: Landings, statistic: Callable[[Objective], Statistic],
    whole: LandingSettings | None = None,
) -> Objectives | None:
    """``evaluate_over_landings(...).statistics`` without the rows (the searches' path)."""
    return statistics_of(*scenario_table(model, landings.names, landings.draw(), whole=whole), statistic)


def statistics_over_landings_many(
    models: list[ModelFile], landings: Landings, statistic: Callable[[Objective], Statistic],
    whole: LandingSettings | None = None, pool: ProcessPoolExecutor | None = None,
) -> list[Objectives | None]:
    """:func:`statistics_over_landings` of many designs: their batchable scenarios in one call
    per structure and contact set (:func:`first_impact_values_many`), the rest in ``pool``."""
    draws = landings.draw()
    batched = first_impact_values_many(models, landings.names, draws)
    return [statistics_of(*scenario_table(m, landings.names, draws, b, whole, pool=pool), statistic)
            for m, b in zip(models, batched, strict=True)]


def evaluate_over_landings(
    model: ModelFile, landings: Landings, statistic: Callable[[Objective], Statistic],
    whole: LandingSettings | None = None, progress: Callable[[int, int], None] | None = None,
) -> RobustEvaluation:
    """``model`` on every scenario of ``landings`` (:func:`scenario_table`, which tells
    ``progress``), each row with its overrides, and the statistics; whole landings with ``whole``
    (a study's: :func:`study_landing`), as many at once as there are cores (:func:`cores`)."""
    draws = landings.draw()
    workers = min(cores(), len(draws)) if model.scene.duration is not None else 1
    with forked_pool(workers) as pool:
        keys, table = scenario_table(model, landings.names, draws, whole=whole, progress=progress, pool=pool)
    rows = tuple(
        ScenarioRow(k, overrides(model, landings.names, values),
                    None if np.isnan(row).any() else Objectives(**dict(zip(keys, map(float, row), strict=True))))
        for k, (values, row) in enumerate(zip(draws, table, strict=True))
    )
    return RobustEvaluation(rows, statistics_of(keys, table, statistic))


__all__ = [
    "RobustEvaluation",
    "ScenarioRow",
    "evaluate_over_landings",
    "scenario_objectives",
    "scenario_table",
    "statistics_of",
    "statistics_over_landings",
    "statistics_over_landings_many",
]
