"""``footopt optimize`` and ``footopt pareto`` end to end: the run directory's files, exported
designs that meet the constraints and re-evaluate (through ``footopt evaluate --json``) to their
objectives, a mutually non-dominated front, and run directories that are never clobbered."""

from __future__ import annotations

import csv
import itertools
import json
from pathlib import Path

import numpy as np
import pytest

from optimizer.cli.main import main
from optimizer.config.model_file import load_model_file
from optimizer.config.study_config import load_study
from optimizer.design_space import FEASIBILITY_TOL, ConstraintValues
from optimizer.results.pareto import dominates
from tests.optimizer.conftest import TINY_OUTER_YAML, TINY_STUDY_YAML

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
CONSTRAINTS = [f"constraint.{name}" for name in ConstraintValues.__dataclass_fields__]


@pytest.fixture(scope="module", params=["inner", "outer"])
def run(request, tmp_path_factory) -> Path:
    """A finished run of the tiny study (inner, then outer search)."""
    root = tmp_path_factory.mktemp(f"run_{request.param}")
    study = root / "tiny.yaml"
    study.write_text(TINY_STUDY_YAML if request.param == "inner" else TINY_OUTER_YAML, encoding="utf-8")
    out = root / "out"
    assert main(["optimize", str(study), "--out", str(out), "--quiet"]) == 0
    return out


def rows(run: Path) -> list[dict[str, str]]:
    with (run / "pareto.csv").open(encoding="utf-8") as f:
        return list(csv.DictReader(f))


def test_run_directory_files(run: Path):
    for name in ("pareto.csv", "pareto.json", "front.png", "study.yaml", "run.json", "study.journal"):
        assert (run / name).is_file(), name
    assert (run / "front.png").read_bytes()[:8] == PNG_MAGIC
    record = json.loads((run / "run.json").read_text())
    assert record["seed"] == 3 and record["study"] == "tiny"
    assert {"optuna", "casadi", "numpy", "python"} <= set(record["versions"])
    assert load_study(run / "study.yaml").name == "tiny"
    table = rows(run)
    assert table, "an empty front"
    assert {"external_norm", "internal_norm", "model_file", *CONSTRAINTS} <= set(table[0])
    entries = json.loads((run / "pareto.json").read_text())["designs"]
    assert [e["model_file"] for e in entries] == [r["model_file"] for r in table]


def test_every_exported_design_meets_the_constraints(run: Path):
    config = load_study(run / "study.yaml")
    for row in rows(run):
        assert all(float(row[c]) <= FEASIBILITY_TOL for c in CONSTRAINTS), row
        # and independently, from the model file itself
        tree = load_model_file(run / row["model_file"]).tree
        rods = tree.bodies[2:]
        masses = np.array([b.mass for b in rods])
        density = masses / np.array([b.length for b in rods])
        lim = config.limits
        assert abs(masses.sum() - lim.foot_mass) < 1e-9
        assert masses.min() >= lim.min_link_mass - 1e-12
        assert np.all(density >= lim.mass_per_length[0] - 1e-9) and np.all(density <= lim.mass_per_length[1] + 1e-9)
        assert tree.bodies[0].length == config.leg.thigh_length and tree.bodies[1].mass == config.leg.shank_mass


def test_front_is_mutually_non_dominated(run: Path):
    config = load_study(run / "study.yaml")
    names = [o.value for o in config.objectives]
    values = np.array([[float(r[n]) for n in names] for r in rows(run)])
    for a, b in itertools.permutations(values, 2):
        assert not dominates(a, b)


def test_exported_model_files_reevaluate_to_their_objectives(run: Path, capsys):
    table = rows(run)
    files = [str(run / r["model_file"]) for r in table]
    capsys.readouterr()
    assert main(["evaluate", "--json", *files]) == 0
    records = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert len(records) == len(table)
    for row, rec in zip(table, records, strict=True):
        for key in ("external_norm", "internal_norm"):
            assert rec[key] == pytest.approx(float(row[key]), rel=1e-9, abs=1e-12), key
        assert len(rec["external"]) == int(row["toes"]) + 1  # every contact hit (contacts: lowest)
        assert min(rec["external"]) > 0


def test_every_design_is_exported_and_pinocchio_gives_its_impulses(run: Path):
    """Beside each design's model file, its URDF and MJCF: the URDF in Pinocchio lands with the
    front's external impulse norm (1e-8), the MJCF loads in MuJoCo with the design's mass."""
    mujoco = pytest.importorskip("mujoco")
    from impulse_core.evaluate import evaluate
    from tests.exported_models import pinocchio_landing

    for row in rows(run):
        yaml = run / row["model_file"]
        model = load_model_file(yaml)
        res = evaluate(model.tree, model.scene)
        urdf = yaml.with_suffix(".urdf").read_text()
        lam, *_ = pinocchio_landing(urdf, model.tree, model.scene, res.v_minus, res.active)
        assert np.linalg.norm(lam) == pytest.approx(float(row["external_norm"]), rel=1e-8)
        mj = mujoco.MjModel.from_xml_string(yaml.with_suffix(".xml").read_text())
        assert mj.body_mass.sum() == pytest.approx(sum(b.mass for b in model.tree.bodies), rel=1e-12)
    assert sorted(p.suffix for p in (run / "designs").iterdir()) == sorted([".png", ".urdf", ".xml", ".yaml"] * len(rows(run)))


def test_pareto_command_prints_and_reexports(run: Path, capsys):
    before = (run / "pareto.csv").read_text()
    (run / "pareto.csv").unlink()
    capsys.readouterr()
    assert main(["pareto", str(run)]) == 0
    out = capsys.readouterr().out
    assert "Pareto designs" in out and "designs/trial_" in out
    assert (run / "pareto.csv").read_text() == before


def test_bad_study_yaml_exit_2_one_line_with_path(tmp_path: Path, capsys):
    study = tmp_path / "bad.yaml"
    study.write_text(TINY_STUDY_YAML.replace("trials: 12", "trials: ten"), encoding="utf-8")
    assert main(["optimize", str(study), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert f"{study}: search.trials: must be an integer >= 1, got 'ten'" in err
    assert not (tmp_path / "out").exists()


def test_run_directory_is_never_clobbered(tmp_path: Path, capsys, unsaved_drawings):
    study = tmp_path / "tiny.yaml"
    study.write_text(TINY_STUDY_YAML, encoding="utf-8")
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine", encoding="utf-8")
    assert main(["optimize", str(study), "--out", str(out), "--quiet"]) == 2
    assert "not empty and not a footopt run" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]
    # --force writes the run beside the user's file, which stays
    assert main(["optimize", str(study), "--out", str(out), "--quiet", "--force"]) == 0
    assert (out / "notes.txt").read_text() == "mine" and (out / "pareto.csv").exists()
    # the same study again: resumes (nothing left to do for the inner search), same front
    front = (out / "pareto.csv").read_text()
    assert main(["optimize", str(study), "--out", str(out), "--quiet"]) == 0
    assert (out / "pareto.csv").read_text() == front
    # another study in the same directory: refused
    other = tmp_path / "other.yaml"
    other.write_text(TINY_STUDY_YAML.replace("seed: 3", "seed: 4"), encoding="utf-8")
    assert main(["optimize", str(other), "--out", str(out), "--quiet"]) == 2
    assert ": holds a run of a different study (seed differs)" in capsys.readouterr().err


def test_outer_same_seed_same_front(tmp_path: Path):
    study = tmp_path / "tiny.yaml"
    study.write_text(TINY_OUTER_YAML, encoding="utf-8")
    fronts = []
    for k in range(2):
        out = tmp_path / f"out{k}"
        assert main(["optimize", str(study), "--out", str(out), "--quiet", "--trials", "8"]) == 0
        fronts.append((out / "pareto.csv").read_text())
    assert fronts[0] == fronts[1]


def test_sqlite_storage_url(tmp_path: Path):
    study = tmp_path / "tiny.yaml"
    study.write_text(TINY_OUTER_YAML, encoding="utf-8")
    url = f"sqlite:///{tmp_path / 'studies.db'}"
    out = tmp_path / "out"
    assert main(["optimize", str(study), "--out", str(out), "--quiet", "--trials", "4", "--storage", url]) == 0
    assert (tmp_path / "studies.db").exists() and not (out / "study.journal").exists()
    assert load_study(out / "study.yaml").storage == url
    assert main(["optimize", str(study), "--out", str(out), "--quiet", "--trials", "6", "--storage", url]) == 0
    assert json.loads((out / "run.json").read_text())["finished_trials"] == 6


def test_an_outer_study_with_friction_optimises_the_exact_coulomb_law(tmp_path: Path, capsys):
    """scene.friction > 0: each design's impact by the exact friction rung; the front's model
    files re-evaluate (footopt evaluate, auto = friction) to its objectives."""
    from tests.optimizer.conftest import TINY_OUTER_YAML

    study = tmp_path / "friction.yaml"
    study.write_text(TINY_OUTER_YAML.replace("trials: 12", "trials: 8") + "scene: {friction: 0.6}\n", encoding="utf-8")
    out = tmp_path / "run"
    assert main(["optimize", str(study), "--out", str(out), "--quiet"]) == 0
    rows = list(csv.DictReader((out / "pareto.csv").open(encoding="utf-8")))
    assert rows
    for row in rows:
        capsys.readouterr()
        assert main(["evaluate", "--json", str(out / row["model_file"])]) == 0
        got = json.loads(capsys.readouterr().out)
        assert got["model"] == "friction"
        assert got["external_norm"] == pytest.approx(float(row["external_norm"]), rel=1e-9)
        assert got["internal_norm"] == pytest.approx(float(row["internal_norm"]), rel=1e-9)
