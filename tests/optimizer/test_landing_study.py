"""Whole-landing studies: objectives over every impact of the landing, joint laws and the foot's
reach in the design space, front files that ``footopt evaluate`` reproduces."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

from optimizer.cli.main import main
from optimizer.config.study_config import load_study
from optimizer.design_space import (
    FootLimits,
    FootShape,
    Leg,
    Objective,
    Objectives,
    assign_lengths,
    foot_geometry,
    design_from,
)
from optimizer.results.pareto import non_dominated
from optimizer.search.outer import FamilyLaw, design_from_record, design_record, with_joint_laws

REPO = Path(__file__).resolve().parents[2]

#: A landing study small enough for a test: 6 trials of a 0.02 s landing.
TINY_LANDING_YAML = """\
name: tiny_landing
seed: 2
scene: {speed: 2.0, restitution: 0.3, friction: 0.5, gravity: 9.81, duration: 0.02}
leg: {shank: {stiffness: 150.0, damping: 3.0, limits: [-2.0, 0.0]}}
design_space:
  toes: [1, 2]
  toe_segments: [1, 1]
  joint_laws:
    heel_root: {stiffness: [1.0, 20.0], damping: [0.05, 0.5], stop: [0.2, 0.6]}
    toe_root: {stiffness: [1.0, 20.0], damping: [0.05, 0.5], stop: [0.2, 0.6]}
constraints: {min_link_mass: 0.02}
objectives: [peak_external_norm, energy_absorbed]
search: {method: outer, trials: 6, startup_trials: 6, landing_tolerance: 1.0e-2}
"""


def test_energy_absorbed_is_maximised_and_the_rest_minimised():
    assert Objective.ENERGY_ABSORBED.sign == -1.0
    assert all(o.sign == 1.0 for o in Objective if o is not Objective.ENERGY_ABSORBED)
    a = Objectives(1, 1, 1, 1, 1, peak_external_norm=2.0, energy_absorbed=0.9)
    b = Objectives(1, 1, 1, 1, 1, peak_external_norm=2.0, energy_absorbed=0.5)
    objs = (Objective.PEAK_EXTERNAL_NORM, Objective.ENERGY_ABSORBED)
    scores = np.array([[o.score(x) for x in objs] for o in (a, b)])
    assert list(non_dominated(scores)) == [0]  # the one absorbing more dominates
    with pytest.raises(ValueError, match="settled_at: not evaluated"):
        a.value(Objective.SETTLED_AT)


def test_the_linear_program_meets_a_reach_target():
    """Given a reach, the toes' mean heel-to-toe distance equals it and the tips stay level."""
    leg, limits, shape = Leg(), FootLimits(), FootShape(2, 2)
    angles = ((-0.6,), (0.9, -0.2), (1.1, -0.4))
    masses = ((0.1,), (0.1, 0.1), (0.1, 0.1))
    for reach in (0.15, 0.25, 0.35):
        design = design_from(leg, angles, masses, limits, reach)
        geo = foot_geometry(leg, design)
        assert geo.reaches.mean() == pytest.approx(reach, abs=1e-9)
        assert np.ptp(geo.tips[:, 1]) <= 1e-9
    free = assign_lengths(leg, shape, angles, masses, limits)
    assert free is not None  # without a target the program picks the reach itself


def test_joint_laws_survive_the_trial_record():
    design = design_from(Leg(), ((-0.6,), (0.9,)), ((0.2,), (0.3,)), FootLimits())
    laws = {"heel_root": FamilyLaw(5.0, 0.2, 0.4), "heel_inner": FamilyLaw(), "toe_root": FamilyLaw(2.0, 0.1, None),
            "toe_inner": FamilyLaw()}
    sprung = with_joint_laws(design, laws)
    assert sprung.heel[0].joint_law().limits == pytest.approx((-1.0, -0.2))
    assert sprung.toes[0][0].joint_law().limits is None and sprung.toes[0][0].stiffness == 2.0
    assert design_from_record(json.loads(json.dumps(design_record(sprung)))) == sprung
    assert design_from_record(design_record(design)) == design


def test_the_shipped_landing_study_searches_joint_laws():
    config = load_study(REPO / "configs" / "landing_study.yaml")
    assert config.whole_landing and config.scene.duration and config.scene.gravity > 0
    assert not config.space.joint_laws.empty and config.leg.knee.stiffness > 0
    assert config.space.joint_laws.ranges(FootShape(2, 2))[1][1] == config.space.joint_laws.toe_inner


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("landing_study")
    study = folder / "tiny_landing.yaml"
    study.write_text(TINY_LANDING_YAML, encoding="utf-8")
    out = folder / "run"
    assert main(["optimize", str(study), "--out", str(out), "--quiet"]) == 0
    return out


def _trials(run: Path) -> list[tuple]:
    """Every trial of a run's study: number, state, values, parameters and records."""
    from optimizer.results.runs import storage_url
    from optimizer.search.outer import open_study

    config = load_study(run / "study.yaml")
    return [(t.number, t.state, t.values, t.params, t.user_attrs)
            for t in open_study(config, storage_url(run, config)).get_trials(deepcopy=False)]


def test_a_landing_study_lands_a_batch_in_worker_processes_as_in_one(tmp_path: Path, monkeypatch):
    """The batch's whole landings in two worker processes (a study on two cores) or in this one:
    the same trials, to the bit."""
    study = tmp_path / "tiny_landing.yaml"
    study.write_text(TINY_LANDING_YAML, encoding="utf-8")
    runs = {}
    for workers in ("2", "1"):
        monkeypatch.setenv("FOOTOPT_WORKERS", workers)
        runs[workers] = tmp_path / f"run{workers}"
        assert main(["optimize", str(study), "--out", str(runs[workers]), "--quiet"]) == 0
    assert _trials(runs["2"]) == _trials(runs["1"]) and len(_trials(runs["1"])) == 6
    assert (runs["2"] / "pareto.csv").read_bytes() == (runs["1"] / "pareto.csv").read_bytes()


def test_a_landing_study_writes_landing_objectives_and_joint_laws(tiny_run: Path):
    rows = list(csv.DictReader((tiny_run / "pareto.csv").open(encoding="utf-8")))
    assert rows
    for row in rows:
        for name in ("peak_external_norm", "peak_internal_norm", "settled_at", "energy_absorbed"):
            assert math.isfinite(float(row[name]))
        assert float(row["peak_external_norm"]) >= float(row["external_norm"]) - 1e-12
        assert 0.0 <= float(row["energy_absorbed"]) <= 1.0
        assert float(row["heel.stiffness"]) > 0 and float(row["heel.stop"]) > 0
    front = json.loads((tiny_run / "pareto.json").read_text(encoding="utf-8"))
    assert front["objectives"] == ["peak_external_norm", "energy_absorbed"]


def test_footopt_evaluate_reproduces_the_front(tiny_run: Path, capsys):
    """Each Pareto design's model file, landed by ``footopt evaluate --tolerance`` (the study's),
    gives the front's landing figures."""
    rows = list(csv.DictReader((tiny_run / "pareto.csv").open(encoding="utf-8")))
    for row in rows:
        capsys.readouterr()
        assert main(["evaluate", "--json", "--tolerance", "1e-2", str(tiny_run / row["model_file"])]) == 0
        out = json.loads(capsys.readouterr().out)
        assert out["model"] == "landing"
        assert out["landing"]["peak_external_norm"] == pytest.approx(float(row["peak_external_norm"]), rel=1e-12)
        assert out["landing"]["peak_internal_norm"] == pytest.approx(float(row["peak_internal_norm"]), rel=1e-12)
        assert out["landing"]["energy_absorbed"] == pytest.approx(float(row["energy_absorbed"]), rel=1e-12)


def test_a_design_whose_landing_breaks_its_momentum_balance_is_not_scored(monkeypatch, tmp_path):
    """A study's landing whose own momentum balance ends beyond the contract's 1e-4 (its totals
    miss impulse: random file 32843, 1e-2) gives the design no objectives, as a failed landing;
    the same landing within it is scored."""
    import dataclasses

    import optimizer.design_space as design_space
    import optimizer.evaluation.model_choice as model_choice
    from optimizer.design_space import design_model, evaluate_design_landing
    from optimizer.evaluation.robust import scenario_objectives

    study = tmp_path / "tiny_landing.yaml"
    study.write_text(TINY_LANDING_YAML, encoding="utf-8")
    config = load_study(study)
    design = design_from(config.leg, ((-0.6,), (0.9,)), ((0.2,), (0.3,)), config.limits)
    laws = {"heel_root": FamilyLaw(5.0, 0.2, 0.4), "heel_inner": FamilyLaw(), "toe_root": FamilyLaw(5.0, 0.2, 0.4),
            "toe_inner": FamilyLaw()}
    design = with_joint_laws(design, laws)

    def evaluated():
        return evaluate_design_landing(config.leg, design, config.scene, config.limits, 0.0, 1e-2)

    model = design_model(config.leg, design, config.scene, config.limits)
    assert evaluated().objectives is not None and scenario_objectives(model) is not None
    for module in (design_space, model_choice):  # a study's landing, and a robust study's scenario
        real = module.landing
        monkeypatch.setattr(module, "landing",
                            lambda *a, real=real, **k: dataclasses.replace(real(*a, **k), momentum_balance=1.2e-2))
    assert evaluated().objectives is None and scenario_objectives(model) is None


def test_a_failed_design_says_why(monkeypatch, tmp_path, capsys):
    """A design whose landing fails keeps why (a FAIL trial's ``failure``): the run's warning line
    names the trial and the landing's own message, and run.json lists every failed design."""
    import optimizer.design_space as design_space
    import optimizer.search.outer as outer
    from impulse_core.errors import NumericalError

    real = outer.evaluate_design_landing
    calls = []

    def every_third_fails(*args, **kwargs):
        calls.append(1)
        if len(calls) % 3 == 1:
            with monkeypatch.context() as m:
                m.setattr(design_space, "landing", lambda *a, **k: (_ for _ in ()).throw(
                    NumericalError("the landing chatters at t = 0.1 s (a planted failure)\nsecond line")))
                return real(*args, **kwargs)
        return real(*args, **kwargs)

    monkeypatch.setattr(outer, "evaluate_design_landing", every_third_fails)
    monkeypatch.setenv("FOOTOPT_WORKERS", "1")  # the plant counts calls: in one process
    study = tmp_path / "tiny_landing.yaml"
    study.write_text(TINY_LANDING_YAML, encoding="utf-8")
    out = tmp_path / "run"
    assert main(["optimize", str(study), "--out", str(out), "--quiet"]) == 0
    err = capsys.readouterr().err
    run = json.loads((out / "run.json").read_text(encoding="utf-8"))
    failed = run["failed_designs"]
    assert [f["trial"] for f in failed] == [0, 3]
    assert all(f["failure"] == "the landing chatters at t = 0.1 s (a planted failure)" for f in failed)
    assert "2 of 6 designs failed" in err and "trial 0: the landing chatters at t = 0.1 s" in err
    assert "second line" not in err


def test_an_unscored_landing_says_why(monkeypatch, tmp_path):
    """A landing that :func:`scored_landing` refuses names its momentum balance."""
    import dataclasses

    import optimizer.design_space as design_space
    from optimizer.design_space import evaluate_design_landing

    study = tmp_path / "tiny_landing.yaml"
    study.write_text(TINY_LANDING_YAML, encoding="utf-8")
    config = load_study(study)
    design = design_from(config.leg, ((-0.6,), (0.9,)), ((0.2,), (0.3,)), config.limits)
    real = design_space.landing
    monkeypatch.setattr(design_space, "landing",
                        lambda *a, **k: dataclasses.replace(real(*a, **k), momentum_balance=1.2e-2))
    found = evaluate_design_landing(config.leg, design, config.scene, config.limits, 0.0, 1e-2)
    assert found.objectives is None
    assert found.failure == "the landing's momentum balance 1.2e-02 is beyond 0.0001"


def test_a_ctrl_c_while_workers_land_a_batch_loses_no_trial(tmp_path: Path):
    """A real SIGINT to a whole-landing study whose batch two worker processes are landing: exit
    130 (the workers stopped, not awaited), the unfinished trials marked, and the printed resume
    finishes the study: every trial asked once."""
    import os
    import shlex
    import signal
    import subprocess
    import sys
    import time

    study = tmp_path / "tiny_landing.yaml"
    study.write_text(TINY_LANDING_YAML.replace("trials: 6, startup_trials: 6", "trials: 24, startup_trials: 6")
                     .replace("duration: 0.02", "duration: 0.05"), encoding="utf-8")
    env = {**os.environ, "PYTHONPATH": str(REPO), "FOOTOPT_WORKERS": "2"}
    out = tmp_path / "run"
    proc = subprocess.Popen([sys.executable, "-m", "optimizer", "optimize", str(study), "--out", str(out), "--quiet"],
                            cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 60
    while time.time() < deadline and not (out / "study.journal").exists():
        time.sleep(0.05)
    time.sleep(1.0)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert err.count("interrupted") == 1, err
    resume = shlex.split(err.split("Resume: ", 1)[1].splitlines()[0])
    assert resume[:2] == ["footopt", "optimize"]
    subprocess.run([sys.executable, "-m", "optimizer", *resume[1:], "--quiet"], cwd=REPO, env=env, check=True,
                   capture_output=True)
    trials = _trials(out)
    interrupted = [t for t in trials if t[1].name != "COMPLETE"]
    assert all(t[4].get("interrupted") for t in interrupted)  # none when it came between two batches
    finished = [t for t in trials if t[1].name == "COMPLETE"]
    assert len(finished) == 24 and len({tuple(sorted(t[3].items())) for t in finished}) == 24
