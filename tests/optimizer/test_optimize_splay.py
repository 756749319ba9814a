"""A spatial (splayed-toe) study end to end through ``footopt optimize``: spatial model files
that ``footopt evaluate --json`` re-evaluates to the front's numbers and support margins at or
above the bound, the three-view drawings and the run folder's top views; the top-view plot."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from optimizer.cli.main import main
from optimizer.config.model_file import load_model_file
from optimizer.design_space import FEASIBILITY_TOL, FootLimits, Leg, design_from, foot_tree, symmetric_yaws
from optimizer.errors import ConfigError
from optimizer.report.plot import plot_top_views

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
BOUND = 0.01
STUDY = f"""\
name: tiny_splay
seed: 3
design_space: {{toes: [2, 3], toe_segments: [1, 2], space: spatial, splay: [0.0, 0.8], splay_mode: symmetric}}
constraints: {{support_margin: {BOUND}}}
objectives: [external_norm, internal_norm]
search: {{method: outer, trials: 24, startup_trials: 8}}
"""


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("splay_run")
    (root / "study.yaml").write_text(STUDY, encoding="utf-8")
    out = root / "out"
    assert main(["optimize", str(root / "study.yaml"), "--out", str(out), "--quiet"]) == 0
    return out


def test_run_folder_has_spatial_designs_and_top_views(run: Path):
    assert (run / "top_views.png").read_bytes()[:8] == PNG_MAGIC
    with (run / "pareto.csv").open(encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    assert rows
    for row in rows:
        assert float(row["constraint.support_margin"]) <= FEASIBILITY_TOL
        assert float(row["support_margin"]) >= BOUND - FEASIBILITY_TOL
        n = int(row["toes"])
        s = -float(row["toe1.yaw"])
        assert np.allclose([float(row[f"toe{i + 1}.yaw"]) for i in range(n)], symmetric_yaws(n, s), atol=1e-12)
        model = load_model_file(run / row["model_file"])
        assert model.space.joint_axis is None  # spatial
        assert (run / row["model_file"]).with_suffix(".png").read_bytes()[:8] == PNG_MAGIC


def test_model_files_reevaluate_to_the_front(run: Path, capsys):
    entries = json.loads((run / "pareto.json").read_text())["designs"]
    files = [str(run / e["model_file"]) for e in entries]
    capsys.readouterr()
    assert main(["evaluate", "--json", *files]) == 0
    records = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    for entry, record in zip(entries, records, strict=True):
        assert record["external_norm"] == pytest.approx(entry["objectives"]["external_norm"], rel=1e-9)
        assert record["internal_norm"] == pytest.approx(entry["objectives"]["internal_norm"], rel=1e-9)
        assert record["support_margin"] >= BOUND - 1e-9
        assert record["support_margin"] == pytest.approx(entry["design"]["support_margin"], abs=1e-12)


def test_top_view_plot_is_written(tmp_path: Path):
    leg, limits = Leg(), FootLimits()
    angles = ((-0.6,), (1.0, 0.2), (1.0, 0.2), (1.0, 0.2))
    masses = ((0.1,), (0.08, 0.053), (0.08, 0.053), (0.08, 0.054))
    feet = [(f"splay {s}", foot_tree(leg, design_from(leg, angles, masses, limits, toe_yaws=symmetric_yaws(3, s))))
            for s in (0.0, 0.3, 0.6)]
    path = plot_top_views(feet, tmp_path / "top.png")
    assert path.read_bytes()[:8] == PNG_MAGIC and path.stat().st_size > 10_000
    svg = plot_top_views(feet[:1], tmp_path / "top.svg")
    assert svg.read_text(encoding="utf-8").lstrip().startswith("<?xml")
    with pytest.raises(ConfigError):
        plot_top_views(feet, tmp_path / "top.bmp")


LANDING_STUDY = """\
name: tiny_splay_landing
seed: 4
scene: {speed: 2.0, restitution: 0.3, friction: 0.5, gravity: 9.81, duration: 0.01}
design_space:
  toes: [2, 3]
  toe_segments: [1, 2]
  space: spatial
  splay: [0.1, 0.6]
  joint_laws:
    heel_root: {stiffness: [5.0, 20.0], damping: [0.05, 0.5], stop: [0.2, 0.6]}
    toe_root: {stiffness: [5.0, 20.0], damping: [0.05, 0.5], stop: [0.2, 0.6]}
    toe_inner: {stiffness: [2.0, 10.0], damping: [0.02, 0.2]}
constraints: {support_margin: 0.005}
objectives: [peak_external_norm, energy_absorbed]
search: {method: outer, trials: 2, startup_trials: 2}
"""


def test_a_whole_landing_study_of_splayed_feet_reevaluates_to_its_landings(tmp_path: Path, capsys, unsaved_drawings):
    """Splayed feet scored on their whole landings in space (the outer search): each front
    design's spatial model file lands again (``footopt evaluate --json``) to the recorded peak and
    energy absorbed, its joints sprung as the trial asked, its toes splayed (the inner search over
    whole landings in space: ``tests/optimizer/test_landing_inner_spatial.py``)."""
    (tmp_path / "study.yaml").write_text(LANDING_STUDY, encoding="utf-8")
    out = tmp_path / "out"
    assert main(["optimize", str(tmp_path / "study.yaml"), "--out", str(out), "--quiet"]) == 0
    entries = json.loads((out / "pareto.json").read_text())["designs"]
    assert entries
    files = [str(out / e["model_file"]) for e in entries]
    capsys.readouterr()
    assert main(["evaluate", "--json", *files]) == 0
    records = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    for entry, record, path in zip(entries, records, files, strict=True):
        assert record["model"] == "landing" and len(record["landing"]["final_base"]) == 3
        for key in ("peak_external_norm", "energy_absorbed"):
            assert record["landing"][key] == pytest.approx(entry["objectives"][key], rel=1e-9), key
        model = load_model_file(path)
        assert model.space.joint_axis is None and any(b.rpy != (0.0, 0.0, 0.0) for b in model.tree.bodies)
        assert sum(1 for j in model.joints if j.stiffness > 0) == len(model.tree.bodies) - 2  # every foot joint
