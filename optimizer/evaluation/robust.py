"""A design scored over a distribution of landings: each scenario's objectives, and each
objective's statistic over the scenarios (:mod:`optimizer.evaluation.scenarios`,
:mod:`optimizer.evaluation.statistics`).

Each scenario is the design's model file with the scenario's overrides, evaluated by the model
``auto`` picks for it, as ``footopt evaluate`` does (a terrain step: the sequential model; a
scene with ``duration``: the whole landing). Frictionless first impacts on flat ground are
evaluated together, the rest one after another.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from impulse_core.errors import NumericalError
from impulse_core.timedomain.landing import LandingResult
from optimizer.config.model_file import ModelFile
from optimizer.design_space import Objective, Objectives, landing_objectives, objectives
from optimizer.evaluation.batched import first_impacts
from optimizer.evaluation.model_choice import evaluate_landing
from optimizer.evaluation.scenarios import Landings, model_data, overrides, scenario_model
from optimizer.evaluation.statistics import Statistic


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


def scenario_objectives(model: ModelFile) -> Objectives | None:
    """One model file's objectives by the model ``auto`` picks (None if the numerics fail)."""
    with np.errstate(all="ignore"):
        try:
            result = evaluate_landing(model.tree, model.scene, "auto", joints=model.joints)
        except (np.linalg.LinAlgError, NumericalError):
            return None
    inner = getattr(result, "result", None)
    found = landing_objectives(inner) if isinstance(inner, LandingResult) else objectives(result)
    return found if all(math.isfinite(v) for _, v in found.items()) else None


def statistics_of(rows: list[Objectives], statistic: Callable[[Objective], Statistic]) -> Objectives:
    """Each evaluated objective's statistic over the rows (``statistic`` picks it per objective)."""
    names = [f.name for f in fields(Objectives) if getattr(rows[0], f.name) is not None]
    return Objectives(**{n: statistic(Objective(n)).of(np.array([getattr(r, n) for r in rows])) for n in names})


def evaluate_over_landings(
    model: ModelFile, landings: Landings, statistic: Callable[[Objective], Statistic]
) -> RobustEvaluation:
    """``model`` on every scenario of ``landings``, and the statistics. Frictionless first impacts
    on flat ground are evaluated together (:mod:`optimizer.evaluation.batched`), the rest one by one."""
    rows, data, draws = [], model_data(model), landings.draw()
    fast = first_impacts(model, landings.names, draws)
    for k, values in enumerate(draws):
        changes = overrides(model, landings.names, values)
        found = fast[k] if fast[k] is not None else scenario_objectives(scenario_model(data, changes))
        rows.append(ScenarioRow(k, changes, found))
    scored = [r.objectives for r in rows if r.objectives is not None]
    stats = statistics_of(scored, statistic) if len(scored) == len(rows) and scored else None
    return RobustEvaluation(tuple(rows), stats)


__all__ = ["RobustEvaluation", "ScenarioRow", "evaluate_over_landings", "scenario_objectives", "statistics_of"]
