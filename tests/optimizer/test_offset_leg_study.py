"""A study on a leg imported exactly (``footopt import`` without ``--com-on-rods``: Go1's thigh
and calf, their centres of mass 3.05 and 4.3 mm off the rods): the design space carries the
offsets into the thigh and shank it builds (the inner search's NLP and the outer search's batched
evaluator alike), each front design's model file re-evaluates (``footopt evaluate``) to the
impulses the study recorded; whole landings on such a leg (the outer search) too."""

from __future__ import annotations

import csv
import dataclasses
import json
from pathlib import Path

import pytest

from impulse_core.model.tree import Tree
from optimizer.cli.main import main
from optimizer.config.model_file import format_model_file, load_model_file
from optimizer.config.study_config import load_study
from optimizer.imports.leg import import_leg
from optimizer.imports.read import read_description
from tests.optimizer.conftest import drawings_unsaved
from tests.optimizer.imports.peers import robot_file

GO1 = "go1_description/urdf/go1.urdf"
ANGLES = {"FL_thigh_joint": 0.9, "FL_calf_joint": -1.8}
STUDY = """\
name: go1_exact
seed: 3
scene: {speed: 1.0, restitution: 0.0, friction: 0.0}
leg: {file: leg.yaml}
design_space: {toes: [1, 1], toe_segments: [2, 2], heel_segments: [1, 1], toe_symmetry: identical}
constraints: {foot_mass: 0.1, foot_mass_mode: equal, min_link_mass: 0.005, mass_per_length: [0.05, 2.0],
              foot_length: [0.03, 0.12], min_clearance: 0.002}
objectives: [external_norm, internal_norm]
search: {method: inner, trials: 12, startup_trials: 5, inner: {front_points: 3, starts: 2}}
"""


def go1_leg(folder: Path) -> Tree:
    """Go1's front left thigh and calf, exact (offsets kept), standing: the thigh's absolute angle
    from the same import rooted at the hip. Written to ``folder / leg.yaml``."""
    desc = read_description(robot_file(GO1))
    hip = import_leg(desc, "FL_hip", "FL_foot", angles=ANGLES, joint_laws=False).model.tree.bodies
    leg = import_leg(desc, "FL_thigh", "FL_foot", angles={"FL_calf_joint": ANGLES["FL_calf_joint"]}, joint_laws=False)
    thigh, calf = leg.model.tree.bodies
    tree = Tree((dataclasses.replace(thigh, angle=hip[0].angle + hip[1].angle), calf))
    (folder / "leg.yaml").write_text(format_model_file(dataclasses.replace(leg.model, tree=tree)))
    return tree


def _optimized_and_reevaluated(folder: Path, capsys) -> list[tuple[dict, dict, str]]:
    """``footopt optimize folder/s.yaml``, then ``footopt evaluate --json`` on its front's model
    files: (front row, evaluated record, model file) per design."""
    out = folder / "run"
    with drawings_unsaved():  # the callers read the front's model files, not its drawings
        assert main(["optimize", str(folder / "s.yaml"), "--out", str(out), "--quiet"]) == 0
    rows = list(csv.DictReader((out / "pareto.csv").open(encoding="utf-8")))
    assert rows
    capsys.readouterr()
    files = [str(out / r["model_file"]) for r in rows]
    assert main(["evaluate", "--json", *files]) == 0
    records = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    return list(zip(rows, records, files, strict=True))


@pytest.mark.parametrize("method", ["inner", "outer"])
def test_a_study_on_an_exact_import_reevaluates_to_its_impulses(tmp_path, capsys, method):
    leg = go1_leg(tmp_path)
    assert min(abs(b.com_offset[0]) for b in leg.bodies) > 3e-3
    (tmp_path / "s.yaml").write_text(STUDY.replace("method: inner", f"method: {method}"))
    assert load_study(tmp_path / "s.yaml").leg.shank_offset == leg.bodies[1].com_offset[0]
    for row, rec, path in _optimized_and_reevaluated(tmp_path, capsys):
        for key in ("external_norm", "internal_norm", "max_internal"):
            assert rec[key] == pytest.approx(float(row[key]), rel=1e-9, abs=1e-15), key
        thigh, shank = load_model_file(path).tree.bodies[:2]  # the leg's rods, offsets and all
        for built, source in ((thigh, leg.bodies[0]), (shank, leg.bodies[1])):
            assert dataclasses.replace(built, name=source.name, contacts=source.contacts) == source


def test_a_whole_landing_study_on_an_exact_import_reevaluates_to_its_landings(tmp_path, capsys):
    """The outer search scores whole landings of feet on the exact import (its offsets carried):
    each front design's model file lands again (``footopt evaluate --json``) to the peak and the
    energy the study recorded; the inner search, whose landing derivatives take rods, refuses."""
    leg = go1_leg(tmp_path)
    study = STUDY.replace("friction: 0.0}", "friction: 0.5, gravity: 9.81, duration: 0.03}")
    study = study.replace("[external_norm, internal_norm]", "[peak_external_norm, energy_absorbed]")
    study = study.replace("trials: 12, startup_trials: 5", "trials: 4, startup_trials: 4")
    (tmp_path / "s.yaml").write_text(study.replace("method: inner", "method: outer"))
    for row, rec, path in _optimized_and_reevaluated(tmp_path, capsys):
        assert rec["model"] == "landing"
        for key in ("peak_external_norm", "energy_absorbed"):
            assert rec["landing"][key] == pytest.approx(float(row[key]), rel=1e-9, abs=1e-15), key
        assert [b.com_offset for b in load_model_file(path).tree.bodies[:2]] == [b.com_offset for b in leg.bodies]


def test_batched_landings_carry_the_offsets():
    """A distribution of landings (``landings:``, batched first impacts) on paper case 3 with its
    thigh's and shank's centres of mass off the rods: each scenario as its own file gives (1e-12)."""
    from impulse_core.model.tree import ContactSelection
    from optimizer.evaluation.robust import evaluate_over_landings, scenario_objectives
    from optimizer.evaluation.scenarios import Distribution, DistributionKind, Landings, model_data, scenario_model
    from optimizer.evaluation.statistics import Statistic

    model = load_model_file(Path(__file__).resolve().parents[2] / "configs" / "paper_case3.yaml")
    bodies = list(model.tree.bodies)
    bodies[:2] = [dataclasses.replace(b, com_offset=(dy, 0.0)) for b, dy in zip(bodies[:2], (0.2, -0.15))]
    scene = dataclasses.replace(model.scene, selection=ContactSelection.LOWEST)
    model = dataclasses.replace(model, tree=Tree(tuple(bodies)), scene=scene)
    U = DistributionKind.UNIFORM
    landings = Landings(count=40, seed=5, distributions=(
        ("speed", Distribution(U, (2.0, 4.0))), ("pitch", Distribution(U, (-0.3, 0.3))),
        ("restitution", Distribution(U, (0.3, 0.9))),
    ))
    robust, data = evaluate_over_landings(model, landings, lambda o: Statistic()), model_data(model)
    for row in robust.rows:
        alone = scenario_objectives(scenario_model(data, row.overrides))
        for key, value in alone.items():
            assert getattr(row.objectives, key) == pytest.approx(value, rel=1e-12, abs=1e-15), (row.scenario, key)
