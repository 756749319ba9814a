"""The robust evaluation's table and statistics (``optimizer.evaluation.robust``) on hand-made
tables: a design with a failed scenario is not scored (None, not NaN statistics), and every row
the batched path left incomplete is evaluated one by one, the complete ones not again."""

from __future__ import annotations

import numpy as np
import pytest

from optimizer.design_space import Objective, Objectives
from optimizer.evaluation import robust
from optimizer.evaluation.batched import FIRST_IMPACT
from optimizer.evaluation.statistics import Statistic, StatisticKind


def _mean(_: Objective) -> Statistic:
    return Statistic(StatisticKind.MEAN)


def test_a_failed_scenario_leaves_the_design_unscored() -> None:
    rng = np.random.default_rng(3)
    table = rng.uniform(1.0, 2.0, size=(6, len(FIRST_IMPACT)))
    scored = robust.statistics_of(FIRST_IMPACT, table, _mean)
    assert scored is not None
    for j, name in enumerate(FIRST_IMPACT):
        assert getattr(scored, name) == pytest.approx(float(np.mean(table[:, j])), rel=1e-15)
    table[4, 2] = np.nan
    assert robust.statistics_of(FIRST_IMPACT, table, _mean) is None
    assert robust.statistics_of(FIRST_IMPACT, table[:0], _mean) is None


def test_every_incomplete_batched_row_is_evaluated_one_by_one(monkeypatch: pytest.MonkeyPatch) -> None:
    draws = np.arange(5.0)[:, None]
    batched = np.tile(np.arange(1.0, 1.0 + len(FIRST_IMPACT)), (5, 1))
    batched[1, :] = np.nan  # not batchable at all
    batched[3, 0] = np.nan  # one figure missing
    evaluated = []

    def objectives(model, whole):  # type: ignore[no-untyped-def]
        evaluated.append(model["k"])
        return Objectives(*(100.0 + model["k"] for _ in FIRST_IMPACT))

    monkeypatch.setattr(robust, "model_data", lambda model: None)
    monkeypatch.setattr(robust, "overrides", lambda model, names, values: {"k": float(values[0])})
    monkeypatch.setattr(robust, "scenario_model", lambda data, changes: changes)
    monkeypatch.setattr(robust, "scenario_objectives", objectives)
    keys, table = robust.scenario_table(None, ("x",), draws, batched)
    assert keys == FIRST_IMPACT and sorted(evaluated) == [1.0, 3.0]
    assert np.all(table[[1, 3]] == np.array([[101.0], [103.0]]))
    assert np.array_equal(table[[0, 2, 4]], batched[[0, 2, 4]])


@pytest.mark.parametrize("bad", [np.inf, np.nan])
def test_a_scenario_with_a_non_finite_objective_failed(monkeypatch: pytest.MonkeyPatch, bad: float) -> None:
    """One non-finite figure (a diverged evaluation) fails the whole scenario (None), as a
    numerical error does; all finite, the objectives are returned."""
    from types import SimpleNamespace

    from impulse_core.errors import NumericalError

    model = SimpleNamespace(tree=None, scene=None, joints=(), space=None)
    figures = [1.0, 2.0, 3.0, 4.0, 5.0]
    monkeypatch.setattr(robust, "evaluate_landing", lambda *args, **kwargs: SimpleNamespace())
    monkeypatch.setattr(robust, "objectives", lambda result, space: Objectives(*figures))
    assert robust.scenario_objectives(model) == Objectives(*figures)
    figures[3] = bad
    assert robust.scenario_objectives(model) is None

    def diverged(*args, **kwargs):  # type: ignore[no-untyped-def]
        raise NumericalError("diverged")

    monkeypatch.setattr(robust, "evaluate_landing", diverged)
    assert robust.scenario_objectives(model) is None
