"""The searches: the outer (Optuna) search is deterministic per seed and survives interruption
(an exception inside a trial, or the process killed) without losing a finished trial; the inner
(IPOPT) search records feasible designs only."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import optuna
import pytest
from optuna.trial import TrialState

import optimizer.search.outer as search
from optimizer.design_space import FootLimits, FootShape
from optimizer.search.compiled import NlpCache
from optimizer.search.inner import build_nlp, run_inner, shape_done_key
from optimizer.results.runs import storage_url
from optimizer.search.outer import finished_trials, masses_from_shares, open_study, recorded_trials, run_outer
from optimizer.config.study_config import load_study

REPO = Path(__file__).resolve().parents[2]

optuna.logging.set_verbosity(optuna.logging.WARNING)


def complete(study: optuna.Study) -> list[tuple[int, tuple, tuple]]:
    """(number, params, values) of every complete trial."""
    return [
        (t.number, tuple(sorted(t.params.items())), tuple(t.values))
        for t in study.get_trials(states=(TrialState.COMPLETE,))
    ]


def test_masses_from_shares_keep_budget_and_minimum():
    limits = FootLimits(foot_mass=0.5, min_link_mass=0.02)
    shape = FootShape(3, 2)
    shares = ((0.3,), (1.0, 0.0), (1.0, 0.0), (1.0, 0.0))
    masses = masses_from_shares(shape, shares, limits, 0.5)
    assert math.isclose(sum(sum(c) for c in masses), 0.5, rel_tol=1e-12)
    assert min(min(c) for c in masses) == pytest.approx(0.02)
    equal = masses_from_shares(shape, ((0.0,), (0.0, 0.0), (0.0, 0.0), (0.0, 0.0)), limits, 0.5)
    assert all(m == pytest.approx(0.5 / 7) for c in equal for m in c)


def test_outer_same_seed_same_trials(tiny_outer_study: Path):
    config = load_study(tiny_outer_study)
    runs = []
    for _ in range(2):
        study = open_study(config, optuna.storages.InMemoryStorage())
        run_outer(study, config, 10)
        runs.append(complete(study))
    assert runs[0] == runs[1] and len(runs[0]) == 10
    # every complete trial carries its design, objectives and constraint values
    study_trials = list(recorded_trials(study))
    assert len(study_trials) == 10 and all(t.method == "outer" for t in study_trials)


def test_outer_resumes_after_an_exception_inside_a_trial(tiny_outer_study: Path, monkeypatch):
    config = load_study(tiny_outer_study)
    reference = open_study(config, optuna.storages.InMemoryStorage())
    run_outer(reference, config, 10)

    storage = optuna.storages.InMemoryStorage()
    study = open_study(config, storage)
    real = search.evaluate_designs
    calls = {"n": 0}

    def failing(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 2:
            raise RuntimeError("injected in the second batch")
        return real(*args, **kwargs)

    monkeypatch.setattr(search, "evaluate_designs", failing)
    with pytest.raises(RuntimeError, match="injected"):
        run_outer(study, config, 10)
    before = complete(study)
    assert len(before) == search.OUTER_BATCH  # the first batch, told before the second was asked
    monkeypatch.setattr(search, "evaluate_designs", real)
    resumed = open_study(config, storage)
    run_outer(resumed, config, 10)
    after = complete(resumed)
    assert after[: len(before)] == before  # nothing finished was lost
    assert finished_trials(resumed) == 10
    # and the resumed study asked and got exactly what an uninterrupted one did
    assert [(p, v) for _, p, v in after] == [(p, v) for _, p, v in complete(reference)]


def test_outer_survives_a_killed_process(tiny_outer_study: Path, tmp_path: Path):
    """``footopt optimize`` killed with SIGKILL mid-run, then resumed: every trial finished
    before the kill is still there, the one it interrupted is marked, the target is reached."""
    out = tmp_path / "run"
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    cmd = [sys.executable, "-m", "optimizer", "optimize", str(tiny_outer_study), "--out", str(out), "--quiet"]
    proc = subprocess.Popen([*cmd, "--trials", "100000"], cwd=tmp_path, env=env)
    config = load_study(tiny_outer_study)
    try:
        deadline = time.monotonic() + 60
        seen = 0
        while time.monotonic() < deadline and seen < 8:
            time.sleep(0.3)
            if (out / "study.journal").exists():
                seen = len(open_study(config, storage_url(out, config)).get_trials(states=(TrialState.COMPLETE,)))
        assert seen >= 8, "the study did not get going"
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=30)
    killed = open_study(config, storage_url(out, config))
    before = complete(killed)
    target = len(before) + 3
    done = subprocess.run([*cmd, "--trials", str(target)], cwd=tmp_path, env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    resumed = open_study(config, storage_url(out, config))
    after = complete(resumed)
    assert after[: len(before)] == before
    assert finished_trials(resumed) == target
    assert not resumed.get_trials(states=(TrialState.RUNNING,))


def test_inner_records_feasible_designs_and_resumes(tiny_study: Path):
    config = load_study(tiny_study)
    study = open_study(config, optuna.storages.InMemoryStorage())
    assert run_inner(study, config) == len(config.space.shapes())
    trials = list(recorded_trials(study))
    assert trials and all(t.method == "inner" and t.evaluation.feasible for t in trials)
    assert all(study.user_attrs[shape_done_key(s)] for s in config.space.shapes())
    n = len(study.trials)
    assert run_inner(study, config) == 0 and len(study.trials) == n  # nothing left to do


def test_inner_nlp_is_built_once_per_kind_and_shared_by_toe_counts(tiny_study: Path):
    config = load_study(tiny_study)
    cache = NlpCache(config, [])
    two, three = build_nlp(config, FootShape(2, 1), cache), build_nlp(config, FootShape(3, 1), cache)
    assert two.compiled is three.compiled  # the toe count is a parameter
    assert two.compiled.n_rods == 2  # identical toes share their values: heel + one toe rod
    assert two.compiled.lbx.shape == two.compiled.ubx.shape == (two.compiled.n_x,)


@pytest.mark.parametrize("method", ["inner", "outer"])
def test_independent_toes_and_mass_budget_at_most(method: str, write):
    """Each toe its own values, a foot at most 0.5 kg: both searches give feasible designs."""
    from tests.optimizer.conftest import TINY_STUDY_YAML

    text = (
        TINY_STUDY_YAML.replace("toes: [1, 2]", "toes: [2, 2], toe_symmetry: independent")
        .replace("min_link_mass: 0.02", "min_link_mass: 0.02, foot_mass_mode: at_most")
        .replace("method: inner", f"method: {method}")
    )
    config = load_study(write(text, "independent.yaml"))
    study = open_study(config, optuna.storages.InMemoryStorage())
    if method == "inner":
        run_inner(study, config)
    else:
        run_outer(study, config, 12)
    trials = [t for t in recorded_trials(study) if t.evaluation.feasible]
    assert trials
    for t in trials:
        design = t.evaluation.design
        assert len(design.toes) == 2 and design.foot_mass <= 0.5 + 1e-12
    if method == "outer":
        assert {"toe1.joint_angle[0]", "toe2.joint_angle[0]", "foot_mass_fraction"} <= set(study.trials[0].params)


def test_nlp_libraries_come_from_the_trusted_cache_and_a_failed_build_is_said(tiny_study: Path, tmp_path, monkeypatch):
    """A kind's library is built once into a verified cache entry and loaded from it; a failing
    compiler gives a RuntimeWarning and the virtual machine, with the same NLP bounds."""
    import optimizer.search.compiled as compiled
    from impulse_core.compile.cache import lookup

    config = load_study(tiny_study)
    kind = compiled.foot_kind(config, FootShape(2, 1))
    built = compiled.NlpCache(config, [kind], directory=tmp_path / "good")[kind]
    key = compiled.nlp_key(config, kind, compiled.find_compiler())
    assert lookup(tmp_path / "good", kind.name, key) is not None
    assert compiled.NlpCache(config, [], directory=tmp_path / "good")[kind].n_x == built.n_x
    monkeypatch.setattr(compiled, "find_compiler", lambda: "false")
    with pytest.warns(RuntimeWarning, match="virtual machine"):
        on_vm = compiled.NlpCache(config, [kind], directory=tmp_path / "bad")[kind]
    np.testing.assert_array_equal(on_vm.lbx, built.lbx)
    assert not list((tmp_path / "bad").glob(f"{kind.name}_*"))  # nothing half-built was kept


def test_a_kind_with_few_solves_runs_on_the_virtual_machine_and_builds_nothing(tiny_study: Path, tmp_path, recwarn):
    """Below COMPILE_SOLVES planned solves an uncached kind is not compiled (silently); at it, it
    is; a cached library is used whatever the solves."""
    import optimizer.search.compiled as compiled
    from optimizer.search.inner import planned_solves

    config = load_study(tiny_study)
    kind = compiled.foot_kind(config, FootShape(2, 1))
    few = compiled.NlpCache(config, [kind], directory=tmp_path, solves={kind: compiled.COMPILE_SOLVES - 1})
    assert few.library(kind) is None and not list(tmp_path.glob(f"{kind.name}_*"))
    on_vm = few[kind]
    assert not recwarn.list  # no warning: the virtual machine is chosen, not fallen back to
    many = compiled.NlpCache(config, [kind], directory=tmp_path, solves={kind: compiled.COMPILE_SOLVES})
    assert many.library(kind) is not None
    np.testing.assert_array_equal(many[kind].lbx, on_vm.lbx)
    again = compiled.NlpCache(config, [kind], directory=tmp_path, solves={kind: 1})
    assert again.library(kind) == many.library(kind)
    # two anchors of `starts` random starts plus one from the other anchor, two solves per front point
    assert planned_solves(config) == 2 * (config.search.starts + 1) + 2 * config.search.front_points
