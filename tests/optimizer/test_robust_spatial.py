"""Landings in space (``landings:`` with a spatial design space, ``footopt evaluate --landings`` on
spatial model files): the overrides of the spatial parameters (roll, roll rate, lateral velocity),
a study's scenario rows reproduced by ``footopt evaluate`` on the overridden files, a planar
foot read as spatial scored as in the plane (the batched planar path against the spatial one, one
scenario at a time), and the parameters each kind of model refuses."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from impulse_core.model.tree import Scene
from optimizer.cli.main import main
from optimizer.config.model_file import load_model_file, parse_model
from optimizer.config.study_config import load_study
from optimizer.design_space import FootLimits, Leg, Objective, design_from, design_model, symmetric_yaws
from optimizer.errors import ConfigError
from optimizer.evaluation.robust import evaluate_over_landings
from optimizer.evaluation.scenarios import Distribution, DistributionKind, Landings, apply_overrides, model_data, overrides
from optimizer.evaluation.statistics import Statistic

STUDY = """\
name: robust_splay
seed: 2
design_space: {toes: [2, 3], toe_segments: [1, 2], space: spatial, splay: [0.2, 0.6]}
constraints: {support_margin: 0.005}
objectives: [external_norm, internal_norm]
search: {method: outer, trials: 4, startup_trials: 4}
landings:
  count: 5
  seed: 4
  speed: {uniform: [2.5, 4.0]}
  pitch: {uniform: [-0.1, 0.1]}
  roll: {uniform: [-0.15, 0.15]}
  roll_rate: {uniform: [-1.0, 1.0]}
  velocity_z: {uniform: [-0.3, 0.3]}
  restitution: {uniform: [0.5, 0.9]}
statistic: {external_norm: max}
"""


def _splayed_model():
    leg, limits = Leg(), FootLimits()
    angles = ((-0.6,), (1.0, 0.2), (1.0, 0.2), (1.0, 0.2))
    masses = ((0.1,), (0.08, 0.053), (0.08, 0.053), (0.08, 0.054))
    design = design_from(leg, angles, masses, limits, toe_yaws=symmetric_yaws(3, 0.4))
    return design_model(leg, design, Scene(speed=3.0, restitution=0.7), limits)


def test_spatial_overrides_follow_the_contract():
    """Roll adds to the base's rpy roll, pitch to its angle; the approach is written whole as
    3-vectors (world frame), keeping what the scenario does not change."""
    model = _splayed_model()
    names = ("speed", "pitch", "roll", "roll_rate", "velocity_z")
    out = overrides(model, names, np.array([2.0, 0.05, -0.1, 0.7, 0.2]))
    base = model.tree.bodies[0]
    assert out["model.bodies.0.angle"] == base.angle + 0.05
    assert out["model.bodies.0.rpy"] == [base.rpy[0] - 0.1, base.rpy[1], base.rpy[2]]
    assert out["scene.velocity"] == [0.0, -2.0, 0.2]
    assert out["scene.angular_velocity"] == [0.7, 0.0, 0.0]
    turned = parse_model(apply_overrides(model_data(model), out))
    assert turned.scene.velocity == (0.0, -2.0, 0.2) and turned.tree.bodies[0].rpy[0] == pytest.approx(-0.1)
    assert overrides(model, ("velocity_x",), np.array([0.3])) == {"scene.velocity": [0.3, -3.0, 0.0]}


def test_each_kind_of_model_refuses_the_other_kinds_parameters():
    spatial = _splayed_model()
    with pytest.raises(ConfigError, match=r"^landings\.terrain_step: needs a planar model"):
        overrides(spatial, ("terrain_step",), np.array([0.01]))
    planar = load_model_file(Path(__file__).resolve().parents[2] / "configs" / "paper_case3.yaml")
    with pytest.raises(ConfigError, match=r"^landings\.roll: needs a spatial model"):
        overrides(planar, ("roll",), np.array([0.1]))


def test_a_planar_foot_read_as_spatial_scores_as_in_the_plane(tmp_path):
    """Paper case 3 over pitched, tilted-approach, spinning landings with varied restitution: the
    planar file (its scenarios batched in one compiled call) and the same file with
    ``space: spatial`` (each scenario by the spatial first-impact rung) give the same statistics."""
    path = Path(__file__).resolve().parents[2] / "configs" / "paper_case3.yaml"
    text = path.read_text(encoding="utf-8")
    assert "space:" not in text
    (tmp_path / "spatial.yaml").write_text(text.replace("model:\n", "model:\n  space: spatial\n", 1), encoding="utf-8")
    U = DistributionKind.UNIFORM
    landings = Landings(count=12, seed=3, distributions=(
        ("speed", Distribution(U, (2.0, 4.0))), ("velocity_x", Distribution(U, (-0.3, 0.3))),
        ("pitch", Distribution(U, (-0.1, 0.1))), ("angular_velocity", Distribution(U, (-1.0, 1.0))),
        ("restitution", Distribution(U, (0.4, 0.9))),
    ))
    planar = evaluate_over_landings(load_model_file(path), landings, lambda o: Statistic())
    spatial = evaluate_over_landings(load_model_file(tmp_path / "spatial.yaml"), landings, lambda o: Statistic())
    assert planar.statistics is not None and spatial.statistics is not None
    for (key, a), (_, b) in zip(planar.statistics.items(), spatial.statistics.items(), strict=True):
        assert b == pytest.approx(a, rel=1e-9, abs=1e-12), key


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("robust_splay")
    (folder / "study.yaml").write_text(STUDY, encoding="utf-8")
    assert main(["optimize", str(folder / "study.yaml"), "--out", str(folder / "run"), "--quiet"]) == 0
    return folder / "run"


def test_spatial_scenario_rows_are_reproduced_by_footopt_evaluate(run: Path, tmp_path, capsys):
    """A row's overrides applied to the design's spatial model file give its objectives back
    through ``footopt evaluate`` (1e-12); the front's values are the rows' statistics; rolled
    landings change which contacts hit (not every row alike); ``footopt evaluate --landings``
    gives the front's values."""
    rows = list(csv.DictReader((run / "scenarios.csv").open(encoding="utf-8")))
    front = {r["model_file"]: r for r in csv.DictReader((run / "pareto.csv").open(encoding="utf-8"))}
    assert len(rows) == 5 * len(front) > 0
    for row in rows[:5]:
        model = run / "designs" / f"{row['design']}.yaml"
        changes = json.loads(row["overrides"])
        assert {"model.bodies.0.rpy", "scene.velocity", "scene.angular_velocity"} <= changes.keys()
        data = apply_overrides(yaml.safe_load(model.read_text(encoding="utf-8")), changes)
        path = tmp_path / f"{row['design']}_{row['scenario']}.yaml"
        path.write_text(yaml.safe_dump(data), encoding="utf-8")
        capsys.readouterr()
        assert main(["evaluate", "--json", str(path)]) == 0
        got = json.loads(capsys.readouterr().out)
        assert len(got["v_minus"]) > 9  # spatial: six base rates, then the joints
        for key in ("external_norm", "internal_norm"):
            assert got[key] == pytest.approx(float(row[key]), rel=1e-12, abs=1e-15), key
    assert len({r["external_norm"] for r in rows[:5]}) > 1
    config = load_study(run / "study.yaml")
    for model_file, point in front.items():
        mine = [r for r in rows if f"designs/{r['design']}.yaml" == model_file]
        for objective in (Objective.EXTERNAL_NORM, Objective.INTERNAL_NORM):
            values = np.array([float(r[objective.value]) for r in mine])
            assert float(point[objective.value]) == pytest.approx(config.statistic_of(objective).of(values), rel=1e-9)
    point = next(iter(front.values()))
    capsys.readouterr()
    assert main(["evaluate", "--json", "--landings", str(run / "study.yaml"), str(run / point["model_file"])]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["statistics"]["external_norm"] == pytest.approx(float(point["external_norm"]), rel=1e-12)


def test_evaluate_landings_names_a_spatial_parameter_on_a_planar_file(tmp_path, capsys):
    (tmp_path / "study.yaml").write_text(STUDY, encoding="utf-8")
    planar = Path(__file__).resolve().parents[2] / "configs" / "paper_case3.yaml"
    assert main(["evaluate", "--landings", str(tmp_path / "study.yaml"), str(planar)]) == 2
    err = capsys.readouterr().err
    assert "landings.roll: needs a spatial model" in err and len(err.strip().splitlines()) == 1
