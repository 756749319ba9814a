"""``footopt import``: a real URDF to a model file that ``footopt evaluate`` runs as it is; bad
input is one line naming the option, link or joint, exit 2, never a traceback; OUT is never
replaced without --force."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from optimizer.cli.main import main
from optimizer.config.model_file import load_model_file
from tests.optimizer.imports.peers import robot_file
from tests.optimizer.imports.test_leg import SPATIAL_LEG, rod_urdf

SOLO = "solo_description/robots/solo12.urdf"


def test_import_writes_a_model_file_that_evaluate_runs(tmp_path: Path, capsys):
    out = tmp_path / "leg.yaml"
    assert main(["import", str(robot_file(SOLO)), "--root", "FL_UPPER_LEG", "--ankle", "FL_FOOT", "-o", str(out)]) == 0
    said = capsys.readouterr().out
    assert "2 rods, planar (every joint axis parallel)" in said and f"wrote {out}" in said
    text = out.read_text()
    assert text.startswith("# footopt import of solo12.urdf (URDF)")
    assert "centre of mass 0.0138 mm off the rod's axis" in text  # the approximation, in the file too
    model = load_model_file(out)
    assert [b.name for b in model.tree.bodies] == ["FL_UPPER_LEG", "FL_LOWER_LEG"]
    assert main(["evaluate", "--json", str(out)]) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["external"] == pytest.approx([sum(b.mass for b in model.tree.bodies)], rel=1e-6)  # a straight leg
    # never replaced without --force
    before = out.read_text()
    assert main(["import", str(robot_file(SOLO)), "--root", "base_link", "--ankle", "FL_FOOT", "-o", str(out)]) == 2
    assert "already exists" in capsys.readouterr().err and out.read_text() == before
    assert main(["import", str(robot_file(SOLO)), "--root", "base_link", "--ankle", "FL_FOOT", "-o", str(out), "--force"]) == 0
    assert "space: spatial" in out.read_text()
    assert main(["evaluate", str(out)]) == 0


def test_import_to_standard_output(capsys):
    assert main(["import", str(robot_file(SOLO)), "--root", "FL_UPPER_LEG", "--ankle", "FL_FOOT", "-o", "-"]) == 0
    assert capsys.readouterr().out.startswith("# footopt import of solo12.urdf")


@pytest.mark.parametrize(
    "args, where",
    [
        (["--root", "nope", "--ankle", "foot"], "--root: no link named 'nope'"),
        (["--root", "base", "--ankle", "nope"], "--ankle: no link named 'nope'"),
        (["--root", "shank", "--ankle", "hip"], "--ankle: 'hip' does not hang below 'shank'"),
        (["--root", "base", "--ankle", "foot", "--foot", "nope"], "--foot: no link, site or geom named 'nope'"),
        (["--root", "base", "--ankle", "foot", "--space", "planar"], "--space: planar needs"),
        (["--root", "base", "--ankle", "foot", "--angle", "knee"], "--angle: expected JOINT=RAD"),
        (["--root", "base", "--ankle", "foot", "--angle", "knee=inf"], "--angle: expected JOINT=RAD"),
        (["--root", "base", "--ankle", "foot", "--angle", "nope=0.2"], "--angle: no joint named 'nope'"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(tmp_path: Path, capsys, args, where):
    src = tmp_path / "rods.urdf"
    src.write_text(rod_urdf(SPATIAL_LEG))
    out = tmp_path / "leg.yaml"
    assert main(["import", str(src), *args, "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err and where in err, err
    assert not out.exists()


def test_bad_files_are_one_line_and_exit_2(tmp_path: Path, capsys):
    cases = {
        "missing.urdf": (None, "file not found"),
        "prismatic.urdf": (rod_urdf(SPATIAL_LEG).replace('type="continuous"', 'type="prismatic"'),
                           "joint 'thigh_joint': is prismatic"),
        "broken.urdf": ("<robot><link name='a'>", "not well-formed XML"),
        "other.xml": ("<sdf/>", "neither URDF"),
        "bad.xml": ('<mujoco><worldbody><body name="a"><joint type="hinge"/><geom size="-1"/></body></worldbody></mujoco>',
                    "MuJoCo cannot compile it"),
    }
    for name, (text, message) in cases.items():
        src = tmp_path / name
        if text is not None:
            src.write_text(text)
        assert main(["import", str(src), "--root", "base", "--ankle", "foot", "-o", str(tmp_path / "o.yaml")]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "Traceback" not in err and message in err, (name, err)
