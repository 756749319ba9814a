"""``footopt``: every bad input is one line on stderr with exit status 2; reports, JSON Lines
and plots for good files."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import optimizer.cli.main
from impulse_core.errors import NumericalError
from impulse_core.evaluate import evaluate
from impulse_core.model.tree import Scene, Tree
from optimizer.cli.main import main
from optimizer.config.model_file import load_model_file
from tests.optimizer.conftest import LEG_YAML, PLANK_YAML, PULLING_YAML

REPO = Path(__file__).resolve().parents[2]
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"

SCENE = "scene: {speed: 1, restitution: 0.5}\n"


def bad(id: str, edit: tuple[str, str] | list[tuple[str, str]] | str, start: str, *words: str) -> object:
    """A bad file: ``edit`` is a replacement (or several) in ``LEG_YAML`` or a whole text; the
    error line must name ``start`` right after the file and contain ``words``."""
    return pytest.param(edit, start, words, id=id)


BAD_FILES = [
    bad("syntax", ("  restitution: 0.5", "  restitution: [0.5"), "YAML syntax error at line", "column"),
    bad("two documents", "scene: {}\n---\nmodel: {}\n", "YAML: a second document starts at line 2", "holds one"),
    bad("empty", "", "empty file"),
    bad("top level list", "- 1\n- 2\n", "the top level: must be a mapping", "scene", "model", "got a list"),
    bad("scene missing", "model: {bodies: [{name: a, length: 1, mass: 1, angle: 0}]}\n", "scene: missing"),
    bad(
        "scene not a mapping",
        "scene: 3\nmodel: {bodies: [{name: a, length: 1, mass: 1, angle: 0}]}\n",
        "scene: must be",
    ),
    bad("model missing", SCENE, "model: missing"),
    bad("bodies missing", SCENE + "model: {}\n", "model.bodies: missing"),
    bad("bodies empty", SCENE + "model: {bodies: []}\n", "model.bodies: must list at least one body"),
    bad("bodies not a list", SCENE + "model: {bodies: 3}\n", "model.bodies: must be a list"),
    bad("body not a mapping", SCENE + "model: {bodies: [1]}\n", "model.bodies[0]: must be a mapping"),
    bad("speed missing", ("  speed: 2.0\n", ""), "scene.speed: missing"),
    bad("speed null", ("speed: 2.0", "speed: ~"), "scene.speed: required, got null"),
    bad("speed string", ("speed: 2.0", "speed: fast"), "scene.speed: must be a number, got 'fast'"),
    bad("speed bool", ("speed: 2.0", "speed: true"), "scene.speed: must be a number, got true (a boolean)"),
    bad("speed negative", ("speed: 2.0", "speed: -2.0"), "scene.speed: must be > 0", "-2.0"),
    bad("speed zero", ("speed: 2.0", "speed: 0"), "scene.speed: must be > 0"),
    bad("speed inf", ("speed: 2.0", "speed: .inf"), "scene.speed: must be a finite number, got inf"),
    bad("restitution nan", ("restitution: 0.5", "restitution: .nan"), "scene.restitution: must be a finite number"),
    bad(
        "restitution above 1", ("restitution: 0.5", "restitution: 1.5"), "scene.restitution: must be in [0, 1], got 1.5"
    ),
    bad("restitution below 0", ("restitution: 0.5", "restitution: -1e-3"), "scene.restitution: must be in [0, 1]"),
    bad("friction negative", ("restitution: 0.5", "restitution: 0.5\n  friction: -1"), "scene.friction: must be >= 0"),
    bad("contacts mode", ("contacts: all", "contacts: some"), "scene.contacts: unknown mode 'some'", "all, lowest"),
    bad(
        "scene key typo",
        ("restitution:", "restitusion:"),
        "scene.restitusion: unknown key",
        "did you mean 'restitution'",
        "allowed:",
    ),
    bad(
        "top key typo",
        ("model:", "modle:"),
        "modle: unknown key",
        "did you mean 'model'",
        "allowed: scene, model, reference, notes",
    ),
    bad(
        "body key typo",
        ("length: 0.25", "lenght: 0.25"),
        "model.bodies[2].lenght: unknown key",
        "did you mean 'length'",
        "allowed:",
    ),
    bad("mass negative", ("mass: 0.3", "mass: -1"), "model.bodies[2].mass: must be a finite number > 0, got -1.0"),
    bad("mass string", ("mass: 0.3", "mass: 1kg"), "model.bodies[2].mass: must be a number, got '1kg'"),
    bad("mass bool", ("mass: 0.3", "mass: false"), "model.bodies[2].mass: must be a number, got false"),
    bad("mass duplicated", ("mass: 0.3", "mass: 0.3\n      mass: 0.4"), "model.bodies[2].mass: duplicate key", "line"),
    bad(
        "length zero",
        ("length: 0.5\n      mass: 1.0", "length: 0\n      mass: 1.0"),
        "model.bodies[1].length: must be a finite number > 0, got 0.0",
    ),
    bad("length inf", ("length: 0.25", "length: -.inf"), "model.bodies[2].length: must be a finite number, got -inf"),
    bad("angle missing", ("      angle: 1.2\n", ""), "model.bodies[2].angle: missing"),
    bad("name missing", ("- name: foot\n      parent", "- parent"), "model.bodies[2].name: missing"),
    bad("name not a string", ("name: foot", "name: 3"), "model.bodies[2].name: must be a non-empty string, got 3"),
    bad("duplicate name", ("name: foot", "name: shank"), "model.bodies[2].name: duplicate body name 'shank'", "[1]"),
    bad(
        "unknown parent",
        ("parent: shank", "parent: shin"),
        "model.bodies[2].parent: unknown body 'shin'",
        "thigh, shank",
    ),
    bad("parent not a string", ("parent: shank", "parent: 1"), "model.bodies[2].parent: must be a non-empty string"),
    bad(
        "parent listed later",
        [("parent: thigh", "parent: foot"), ("parent: shank", "parent: thigh")],
        "model.bodies[1].parent: 'foot' is listed after 'shank'; list parents first",
    ),
    bad(
        "parent cycle", ("parent: thigh", "parent: foot"), "model.bodies[1].parent:", "cycle", "shank -> foot -> shank"
    ),
    bad("self parent", ("parent: shank", "parent: foot"), "model.bodies[2].parent:", "cycle", "foot -> foot"),
    bad(
        "base with parent", ("- name: thigh", "- name: thigh\n      parent: foot"), "model.bodies[0].parent: the first"
    ),
    bad("parent missing", ("      parent: thigh\n", ""), "model.bodies[1].parent: missing"),
    bad("no contact", ("      contacts: [0.0, 1.0]\n", ""), "model.bodies: no body declares a contact point"),
    bad("contact off body", ("[0.0, 1.0]", "[0.0, 1.5]"), "model.bodies[2].contacts[1]: 1.5 is off its body"),
    bad("contact negative", ("[0.0, 1.0]", "[-0.1, 1.0]"), "model.bodies[2].contacts[0]: -0.1 is off its body"),
    bad("contact string", ("[0.0, 1.0]", "[0.0, tip]"), "model.bodies[2].contacts[1]: must be a number, got 'tip'"),
    bad("contacts not a list", ("contacts: [0.0, 1.0]", "contacts: 1.0"), "model.bodies[2].contacts: must be a list"),
    bad(
        "joint kind",
        ("angle: 1.2", "angle: 1.2\n      joint: prismatic"),
        "model.bodies[2].joint: unknown joint kind 'prismatic'",
        "revolute, fixed",
    ),
    bad("at off parent", ("angle: 1.2", "angle: 1.2\n      at: 1.5"), "model.bodies[2].at: must be in [0, 1]"),
    bad("com off body", ("angle: 1.2", "angle: 1.2\n      com: 2"), "model.bodies[2].com: must be in [0, 1]"),
    bad(
        "inertia negative", ("angle: 1.2", "angle: 1.2\n      inertia: -1e-3"), "model.bodies[2].inertia: must be >= 0"
    ),
    bad(
        "inertia and gyration",
        ("angle: 1.2", "angle: 1.2\n      inertia: 1e-3\n      gyration: 0.2"),
        "model.bodies[2].gyration: give 'inertia' or 'gyration', not both",
    ),
    bad(
        "reference length",
        ("model:", "reference: {external: [1.0]}\nmodel:"),
        "reference.external: has 1 entries, the model declares 2 contacts",
    ),
    bad(
        "reference internal length",
        ("model:", "reference: {internal: [1, 2, 3]}\nmodel:"),
        "reference.internal: has 3 entries, the model has 2 joints",
    ),
    bad(
        "reference value",
        ("model:", "reference: {external: [big, 1]}\nmodel:"),
        "reference.external[0]: must be a number, got 'big'",
    ),
    bad(
        "reference key",
        ("model:", "reference: {externals: [1, 1]}\nmodel:"),
        "reference.externals: unknown key",
        "did you mean 'external'",
    ),
    bad("notes not text", ("model:", "notes: [1]\nmodel:"), "notes: must be a string, got a list"),
]


def _text(edit: tuple[str, str] | list[tuple[str, str]] | str) -> str:
    if isinstance(edit, str):
        return edit
    text = LEG_YAML
    for old, new in [edit] if isinstance(edit, tuple) else edit:
        assert old in text, f"the case does not apply: {old!r}"
        text = text.replace(old, new, 1)
    return text


def _assert_one_error_line(err: str, file: Path | str, start: str, words: tuple[str, ...] = ()) -> None:
    assert err.count("\n") == 1 and err.endswith("\n"), err
    assert "Traceback" not in err
    assert err.startswith(f"footopt: error: {file}: {start}"), err
    for w in words:
        assert w in err, err


@pytest.mark.parametrize(("edit", "start", "words"), BAD_FILES)
def test_bad_file_is_one_error_line(write, capsys, edit, start: str, words: tuple[str, ...]) -> None:
    path = write(_text(edit))
    assert main(["evaluate", str(path)]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    _assert_one_error_line(err, path, start, words)


def test_bad_file_as_json_is_one_error_line(write, capsys) -> None:
    path = write(LEG_YAML.replace("mass: 0.3", "mass: -1"))
    assert main(["evaluate", "--json", str(path)]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    _assert_one_error_line(err, path, "model.bodies[2].mass: must be a finite number > 0, got -1.0")


def test_missing_file(tmp_path: Path, capsys) -> None:
    path = tmp_path / "nope.yaml"
    assert main(["evaluate", str(path)]) == 2
    _assert_one_error_line(capsys.readouterr().err, path, "file not found")


def test_directory(tmp_path: Path, capsys) -> None:
    assert main(["evaluate", str(tmp_path)]) == 2
    _assert_one_error_line(capsys.readouterr().err, tmp_path, "is a directory")


def test_not_text(tmp_path: Path, capsys) -> None:
    path = tmp_path / "binary.yaml"
    path.write_bytes(b"scene: \xff\xfe\x00\n")
    assert main(["evaluate", str(path)]) == 2
    _assert_one_error_line(capsys.readouterr().err, path, "not a UTF-8 text file")


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() == 0, reason="root reads any file")
def test_unreadable(leg_file: Path, capsys) -> None:
    leg_file.chmod(0)
    try:
        assert main(["evaluate", str(leg_file)]) == 2
    finally:
        leg_file.chmod(0o644)
    _assert_one_error_line(capsys.readouterr().err, leg_file, "cannot read the file")


@pytest.mark.parametrize(
    ("argv", "names"),
    [([], "COMMAND"), (["evaluate"], "FILE"), (["bogus"], "'bogus'"), (["evaluate", "--nope", "x.yaml"], "--nope"),
     (["evaluate", "--tolerance", "abc", "x.yaml"], "--tolerance: invalid float value: 'abc'"),
     (["drop", "--stiffness", "1e", "x.yaml"], "--stiffness"),
     (["export", "x.yaml", "--stop-timestep"], "--stop-timestep"),
     (["optimize", "--workers", "two"], "--workers: invalid int value")],
    ids=["none", "no file", "command", "option", "float", "drop float", "no value", "int"],
)
def test_usage_errors_exit_2_on_one_line(argv: list[str], names: str, capsys) -> None:
    """A usage error is one line naming the option (argparse's usage block is not printed), with
    where to read the command's options; exit status 2."""
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1, err
    assert err.startswith("footopt") and ": error: " in err and names in err and "--help'" in err


def test_a_usage_error_redacts_a_password(capsys) -> None:
    assert main(["optimize", "x.yaml", "postgresql://user:hunter2@db.example/footopt"]) == 2
    err = capsys.readouterr().err
    assert "hunter2" not in err and "unrecognized arguments" in err and len(err.splitlines()) == 1


def test_help_exits_0(capsys) -> None:
    assert main(["--help"]) == 0
    assert "evaluate" in capsys.readouterr().out
    assert main(["evaluate", "--help"]) == 0
    assert "--json" in capsys.readouterr().out


def test_keyboard_interrupt_exits_130(leg_file: Path, monkeypatch, capsys) -> None:
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(optimizer.cli.main, "evaluate_landing", interrupted)
    assert main(["evaluate", str(leg_file)]) == 130
    assert "Traceback" not in capsys.readouterr().err


# --------------------------------------------------------------------------------------------
# Through a real process


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")]))}
    return subprocess.run(
        [sys.executable, "-m", "optimizer.cli.main", *args], capture_output=True, text=True, env=env, timeout=120
    )


@pytest.mark.parametrize(
    ("edit", "start"),
    [
        ([("mass: 0.3", "mass: -1")], "model.bodies[2].mass: must be a finite number > 0, got -1.0"),
        *(pytest.param(*case, marks=pytest.mark.slow) for case in [  # each message in-process: BAD_FILES
            ([("  restitution: 0.5", "  restitution: [0.5")], "YAML syntax error at line"),
            ([("length: 0.25", "lenght: 0.25")], "model.bodies[2].lenght: unknown key"),
            ([("parent: thigh", "parent: foot")], "model.bodies[1].parent: the parents form a cycle"),
            ([("restitution: 0.5", "restitution: 0.5\n  friction: -0.3")], "scene.friction: must be >= 0"),
        ]),
    ],
    ids=["mass", "syntax", "typo", "cycle", "friction"],
)
def test_bad_file_in_a_process(write, edit, start: str) -> None:
    path = write(_text(edit))
    proc = _run("evaluate", str(path))
    assert proc.returncode == 2
    assert proc.stdout == ""
    _assert_one_error_line(proc.stderr, path, start)


def test_missing_file_in_a_process(tmp_path: Path) -> None:
    proc = _run("evaluate", "--json", str(tmp_path / "nope.yaml"))
    assert proc.returncode == 2
    _assert_one_error_line(proc.stderr, tmp_path / "nope.yaml", "file not found")


def test_usage_error_in_a_process() -> None:
    proc = _run("evaluate")
    assert proc.returncode == 2
    assert proc.stderr.startswith("footopt evaluate: error: ") and len(proc.stderr.splitlines()) == 1


def test_json_in_a_process(leg_file: Path, foot_file: Path) -> None:
    proc = _run("evaluate", "--json", str(leg_file), str(foot_file))
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    assert [json.loads(line)["file"] for line in proc.stdout.splitlines()] == [str(leg_file), str(foot_file)]


# --------------------------------------------------------------------------------------------
# JSON Lines


def _json_lines(out: str) -> list[dict]:
    def no_constants(name: str) -> None:
        raise AssertionError(f"{name} in the JSON output")

    return [json.loads(line, parse_constant=no_constants) for line in out.splitlines()]


CONTRACT_KEYS = {"external", "internal", "external_norm", "internal_norm", "model", "warnings"}
EXTRA_KEYS = {
    "file", "model_description", "scene", "contacts", "active", "joints", "joint_kinds", "internal_vector", "internal_torque",
    "max_internal", "max_internal_joint", "velocities", "v_minus", "v_plus", "energy_before", "energy_after",
    "energy_gained", "split_unique", "pulling", "reference", "impact_model", "impact_reason", "tangential",
    "separating", "modes",
}  # fmt: skip


def test_json_matches_the_core(leg_file: Path, leg_tree: Tree, leg_scene: Scene, capsys) -> None:
    assert main(["evaluate", "--json", str(leg_file)]) == 0
    out, err = capsys.readouterr()
    assert err == ""
    (record,) = _json_lines(out)
    assert set(record) == CONTRACT_KEYS | EXTRA_KEYS
    expected = evaluate(leg_tree, leg_scene)  # the tree built by hand, not parsed
    assert record["external"] == expected.external.tolist()
    assert record["internal"] == expected.internal_magnitude.tolist()
    assert record["internal_vector"] == expected.internal[:, :2].tolist()
    assert record["internal_torque"] == expected.internal_torque[:, 2].tolist()
    assert record["external_norm"] == expected.external_norm
    assert record["internal_norm"] == expected.internal_norm
    assert record["v_plus"] == expected.v_plus.tolist()
    assert record["energy_after"] == expected.energy_after
    assert record["contacts"] == ["foot[0]", "foot[1]"]
    assert record["active"] == [True, True]
    assert record["joints"] == ["shank", "foot"]
    assert record["velocities"] == ["base vx", "base vy", "base omega", "shank rate", "foot rate"]
    assert record["split_unique"] is True and record["pulling"] == []
    assert record["reference"] is None
    assert record["impact_model"] == expected.model.value == "newton"
    assert record["impact_reason"] == expected.reason and record["impact_reason"].startswith("automatic")
    assert record["model"] == "newton" and record["model_description"] == expected.model.description
    assert record["warnings"] == []  # always a list (MODEL_FORMAT.md)
    assert record["tangential"] == [0.0, 0.0] and record["separating"] == []


def test_json_lengths_and_norms(foot_file: Path, capsys) -> None:
    assert main(["evaluate", "--json", str(foot_file)]) == 0
    (record,) = _json_lines(capsys.readouterr().out)
    model = load_model_file(foot_file)
    assert len(record["external"]) == len(record["contacts"]) == len(record["active"]) == len(model.tree.contacts) == 2
    assert len(record["internal"]) == len(record["joints"]) == len(record["internal_vector"]) == 3
    assert math.isclose(record["external_norm"], float(np.linalg.norm(record["external"])), rel_tol=1e-12)
    assert math.isclose(record["internal_norm"], float(np.linalg.norm(record["internal"])), rel_tol=1e-12)
    assert math.isclose(record["max_internal"], max(record["internal"]))
    assert record["internal"][record["joints"].index(record["max_internal_joint"])] == record["max_internal"]
    # only the lowest contact hits: the heel's impulse is 0.0
    assert record["active"] == [False, True]
    assert record["external"][0] == 0.0 and record["external"][1] > 0
    assert record["reference"]["external"] == [None, 0.9]
    for value in record["external"] + record["internal"] + record["v_plus"]:
        assert type(value) is float


def test_json_lines_in_order_and_a_bad_file_among_them(write, leg_file: Path, foot_file: Path, capsys) -> None:
    bad = write(LEG_YAML.replace("mass: 0.3", "mass: -1"), "bad.yaml")
    assert main(["evaluate", "--json", str(foot_file), str(bad), str(leg_file)]) == 2
    out, err = capsys.readouterr()
    assert [r["file"] for r in _json_lines(out)] == [str(foot_file), str(leg_file)]
    _assert_one_error_line(err, bad, "model.bodies[2].mass")


def test_json_redundant_and_pulling(write, capsys) -> None:
    """By default a contact that Newton's law would make pull separates (LCP rung); with
    ``--model newton`` the pulling Newton answer is shown and flagged."""
    plank, pulling = write(PLANK_YAML, "plank.yaml"), write(PULLING_YAML, "pulling.yaml")
    assert main(["evaluate", "--json", str(plank), str(pulling)]) == 0
    r_plank, r_pulling = _json_lines(capsys.readouterr().out)
    assert r_plank["split_unique"] is False and r_plank["impact_model"] == "newton"
    assert r_plank["internal"] == [] and r_plank["internal_norm"] == 0.0 and r_plank["max_internal_joint"] is None
    assert r_pulling["impact_model"] == "lcp" and "toe[1] pull" in r_pulling["impact_reason"]
    assert r_pulling["pulling"] == [] and min(r_pulling["external"]) >= 0.0
    # the LCP's one solution (checked by enumerating the 8 active sets): toe[0] alone takes the impulse
    assert r_pulling["separating"] == ["heel[0]", "toe[1]"] and r_pulling["external"][1] > 0.0
    assert main(["evaluate", "--json", "--model", "newton", str(pulling)]) == 0
    (r_newton,) = _json_lines(capsys.readouterr().out)
    assert r_newton["impact_model"] == "newton" and r_newton["impact_reason"].startswith("requested")
    assert r_newton["pulling"] == [
        name for name, x in zip(r_newton["contacts"], r_newton["external"], strict=True) if x < 0
    ]
    assert r_newton["pulling"] == ["toe[1]"]


# --------------------------------------------------------------------------------------------
# Text report


def test_text_report(foot_file: Path, capsys) -> None:
    assert main(["evaluate", str(foot_file)]) == 0
    out, err = capsys.readouterr()
    assert err == ""
    model = load_model_file(foot_file)
    result = evaluate(model.tree, model.scene)
    assert out.startswith(f"== {foot_file} ==\n")
    assert f"model:   newton: {result.model.description}" in out
    assert f"why:     {result.reason}" in out
    for words in (
        "speed 3.43 m/s", "e = 0.8", "contacts: lowest", "impulse [N s]", "reference [N s]", "a made-up table",
        "heel[0]", "toe[0]", "revolute", "external_norm", "internal_norm", "base omega [rad/s]", "toe rate [rad/s]",
        "kinetic energy [J]", "largest joint impulse",
    ):  # fmt: skip
        assert words in out, words
    toe_line = next(line for line in out.splitlines() if line.startswith("toe[0]"))
    assert toe_line.split()[1:4] == ["yes", f"{result.external[1]:.4f}", "0.9000"]
    assert "warning" not in out


def test_text_report_warnings(write, capsys) -> None:
    plank, pulling = write(PLANK_YAML, "plank.yaml"), write(PULLING_YAML, "pulling.yaml")
    assert main(["evaluate", str(plank), str(pulling)]) == 0
    out = capsys.readouterr().out
    assert "warning: contacts plank[0], plank[1], plank[2] are redundant" in out
    assert "the split of the impulse is not" in out
    assert "why:     automatic: Newton's law (eq. 11) would make contact toe[1] pull on the ground" in out
    assert "warning: contacts heel[0], toe[1] separate from the ground with zero impulse" in out
    assert out.index("plank.yaml") < out.index("pulling.yaml")
    assert main(["evaluate", "--model", "newton", str(pulling)]) == 0
    out = capsys.readouterr().out
    assert "warning: Newton's law makes contacts toe[1] pull on the ground (negative impulse)" in out


# --------------------------------------------------------------------------------------------
# Plots


def test_plot_png(leg_file: Path, tmp_path: Path, capsys) -> None:
    path = tmp_path / "leg.png"
    assert main(["evaluate", str(leg_file), "--plot", str(path)]) == 0
    assert path.read_bytes()[:8] == PNG_MAGIC
    assert capsys.readouterr().err == ""


def test_plot_several_files_svg(leg_file: Path, foot_file: Path, tmp_path: Path, capsys) -> None:
    path = tmp_path / "out" / "legs.svg"
    path.parent.mkdir()
    assert main(["evaluate", "--json", str(leg_file), str(foot_file), "--plot", str(path)]) == 0
    assert sorted(p.name for p in path.parent.iterdir()) == ["legs_foot.svg", "legs_leg.svg"]
    assert "<svg" in (path.parent / "legs_leg.svg").read_text()
    assert len(_json_lines(capsys.readouterr().out)) == 2  # the plot does not spoil the JSON Lines


def test_plot_overwrites(leg_file: Path, tmp_path: Path) -> None:
    path = tmp_path / "leg.png"
    path.write_text("old")
    assert main(["evaluate", str(leg_file), "--plot", str(path)]) == 0
    assert path.read_bytes()[:8] == PNG_MAGIC


def test_plot_bad_suffix(leg_file: Path, tmp_path: Path, capsys) -> None:
    assert main(["evaluate", str(leg_file), "--plot", str(tmp_path / "leg.jpg")]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    _assert_one_error_line(err, "--plot", f"{tmp_path / 'leg.jpg'}: must end in .png or .svg")


def test_plot_unwritable(leg_file: Path, tmp_path: Path, capsys) -> None:
    path = tmp_path / "missing_dir" / "leg.png"
    assert main(["evaluate", "--json", str(leg_file), "--plot", str(path)]) == 2
    _assert_one_error_line(capsys.readouterr().err, leg_file, f"{path}: cannot write the plot")


def test_importing_the_cli_does_not_import_matplotlib() -> None:
    code = "import sys, optimizer.cli.main; assert 'matplotlib' not in sys.modules, 'matplotlib imported'"
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    subprocess.run([sys.executable, "-c", code], check=True, env=env, timeout=120)


def test_numerical_failure_is_one_line_and_status_1(write, leg_file: Path, capsys) -> None:
    extreme = write(LEG_YAML.replace("mass: 0.3", "mass: 1e300"), "extreme.yaml")
    assert main(["evaluate", "--json", str(extreme), str(leg_file)]) == 1
    out, err = capsys.readouterr()
    assert [r["file"] for r in _json_lines(out)] == [str(leg_file)]
    _assert_one_error_line(err, extreme, "numerical failure")


def test_a_failing_solve_is_a_numerical_failure(leg_file: Path, monkeypatch, capsys) -> None:
    def singular(*args, **kwargs):
        raise np.linalg.LinAlgError("SVD did not converge")

    monkeypatch.setattr(optimizer.cli.main, "evaluate_landing", singular)
    assert main(["evaluate", str(leg_file)]) == 1
    _assert_one_error_line(capsys.readouterr().err, leg_file, "numerical failure")


def test_json_warnings_are_the_reports_warnings(capsys) -> None:
    """An approximation on request warns, and the JSON's ``warnings`` list holds exactly the
    warnings the text report prints."""
    case = str(REPO / "configs" / "paper_case3.yaml")
    assert main(["evaluate", "--model", "decoupled", case]) == 0
    printed = [line.removeprefix("warning: ") for line in capsys.readouterr().out.splitlines() if line.startswith("warning: ")]
    assert main(["evaluate", "--json", "--model", "decoupled", case]) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["model"] == "decoupled" and record["warnings"] == printed
    assert any("no error bound" in w for w in printed)


def test_a_numerical_failure_names_its_cause(leg_file: Path, monkeypatch, capsys) -> None:
    """The solver's own one-line reason reaches the user (it was replaced by a generic line)."""
    def turned(*args, **kwargs):
        raise NumericalError("the base turned 289 degrees from its touchdown orientation by t = 0.0167 s\nmore")

    monkeypatch.setattr(optimizer.cli.main, "evaluate_landing", turned)
    assert main(["evaluate", str(leg_file)]) == 1
    _assert_one_error_line(capsys.readouterr().err, leg_file, "numerical failure: the base turned 289 degrees")
