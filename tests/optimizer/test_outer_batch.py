"""The outer search in batches on the compiled values: the same objectives and constraint values
as evaluate_design (1e-10) for every design whose contacts all push, and a budget no shape can
meet ends in trials that say which constraint failed, not in an error."""

from __future__ import annotations

from pathlib import Path

import optuna
import pytest

from optimizer.config.study_config import load_study
from optimizer.design_space import Objective, evaluate_design
from optimizer.search.outer import evaluate_designs, open_study, recorded_trials, run_outer, suggest_design

optuna.logging.set_verbosity(optuna.logging.WARNING)


@pytest.mark.parametrize("symmetry", ["identical", "independent"])
def test_batched_values_are_evaluate_designs(tiny_outer_study: Path, write, symmetry: str):
    text = tiny_outer_study.read_text()
    text = text.replace("toes: [1, 2], toe_segments: [1, 1]", "toes: [1, 3], toe_segments: [1, 2]")
    config = load_study(write(text.replace("}", f", toe_symmetry: {symmetry}}}", 1), "outer.yaml"))
    study = open_study(config, optuna.storages.InMemoryStorage())
    designs = [suggest_design(study.ask(), config) for _ in range(40)]
    compared = 0
    for design, batched in zip(designs, evaluate_designs(config, designs), strict=True):
        single = evaluate_design(config.leg, design, config.scene, config.limits)
        assert batched.design == design
        if single.objectives is None or single.constraints.pulling > 0:
            continue  # a contact would pull: evaluate() lets it separate, Newton's law does not
        compared += 1
        for o in (o for o in Objective if not o.landing):
            assert batched.objectives.value(o) == pytest.approx(single.objectives.value(o), rel=1e-10, abs=1e-12)
        for (name, a), (_, b) in zip(batched.constraints.items(), single.constraints.items(), strict=True):
            assert a == pytest.approx(b, rel=1e-9, abs=1e-12), name
    assert compared >= 10


def test_a_budget_no_foot_meets_is_recorded_not_raised(tiny_outer_study: Path, write):
    text = tiny_outer_study.read_text().replace("min_link_mass: 0.02", "min_link_mass: 0.02, foot_mass: 0.05")
    config = load_study(write(text.replace("toe_segments: [1, 1]", "toe_segments: [1, 3]"), "heavy.yaml"))
    study = open_study(config, optuna.storages.InMemoryStorage())
    run_outer(study, config, 10)
    trials = study.get_trials()
    assert len(trials) == 10
    over = [t for t in recorded_trials(study) if t.evaluation.design.shape.n_links * 0.02 > 0.05]
    assert over and all(t.evaluation.constraints.foot_mass > 0 and not t.evaluation.feasible for t in over)
    assert all("constraints" in t.user_attrs for t in trials)
