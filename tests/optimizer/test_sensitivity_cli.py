"""`footopt evaluate --sensitivity`: a whole landing's exact derivatives from the command line.

configs/landing_case3.yaml over 4 ms (two impacts: the touchdown, a re-touchdown of the toes) at
--tolerance 1e-10, whose reported step (1e-5 s) is half the default tolerance's:
- the JSON's derivatives are landing_gradient's at the reported step and settings, bit for bit;
- the derivatives w.r.t. the speed and the heel's mass (a value that moves no contact: the
  touchdown height's kink at the four level contacts is not straddled) agree with central
  differences of `footopt evaluate --json` runs at the same step and event sequence;
- the text tables list x, df/dx and the effect (x / f df/dx, or per degree of an angle), sorted by |effect|;
- a refused derivative (a plank resting on both ends with friction: redundant rows) is a warning
  beside the landing (exit 0); a first-impact file or model is
  an error naming --sensitivity (exit 2); without the flag the JSON has no "sensitivity" key.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from impulse_core.timedomain.landing import LandingSettings, landing
from impulse_core.timedomain.landing_derivatives import SCALARS, landing_gradient
from optimizer.cli.main import main
from optimizer.config.model_file import load_model_file
from optimizer.report.landing_sensitivity import format_sensitivity

REPO = Path(__file__).resolve().parents[2]
TOLERANCE = "1e-10"
#: Central differences' step, relative to the value.
EPS = 1e-6


def _landing_file(path: Path, speed: float = 3.43, heel_mass: float = 0.1) -> Path:
    text = (REPO / "configs" / "landing_case3.yaml").read_text()
    text = text.replace("  duration: 0.3 ", "  duration: 0.004 ").replace("  speed: 3.43 ", f"  speed: {speed!r} ")
    text, n = re.subn(r"(- name: heel .*\n(?:      .*\n)*?      mass: )0\.1\n", rf"\g<1>{heel_mass!r}\n", text)
    assert n == 1
    path.write_text(text)
    return path


def _json(capsys, *args: str) -> dict:
    assert main(["evaluate", "--json", "--tolerance", TOLERANCE, *args]) == 0
    return json.loads(capsys.readouterr().out)


@pytest.fixture(scope="module")
def case(tmp_path_factory) -> tuple[Path, dict]:
    """The landing file and its --json --sensitivity record."""
    path = _landing_file(tmp_path_factory.mktemp("sensitivity") / "landing.yaml")
    out = io.StringIO()
    with contextlib.redirect_stdout(out):  # module scope: no capsys
        assert main(["evaluate", "--json", "--sensitivity", "--tolerance", TOLERANCE, str(path)]) == 0
    return path, json.loads(out.getvalue())


def test_the_json_derivatives_are_landing_gradients_at_the_reported_step(case):
    path, d = case
    s = d["sensitivity"]
    assert d["landing"]["step"] == s["step"] == 1e-5 and s["events"] == len(d["events"]) == 2
    assert s["along"] == "event sequence" and d["warnings"] == []
    model = load_model_file(path)
    settings = LandingSettings(tolerance=float(TOLERANCE))
    r = landing(model.tree, model.scene, model.joints, settings)  # its runs' momentum-balance share
    g = landing_gradient(model.tree, model.scene, model.joints, settings, step=1e-5, share=r.share)
    assert s["design"] == list(g.names) and s["scene"] == list(g.scene_names)
    assert list(s["values"].values()) == [*g.theta, *g.scene_theta]
    for k in g.jacobian:
        exact = np.concatenate([g.jacobian[k], g.scene_jacobian[k]], axis=-1)
        got = np.array(list(s["derivatives"][k].values())).T
        assert np.array_equal(got, exact), k
        assert s["objectives"][k] == pytest.approx(d["landing"][k] if k in d["landing"] else g.values[k], rel=1e-12)
    for k in SCALARS:
        f = g.values[k]
        for name, x in s["values"].items():
            e = s["elasticities"][k][name]
            assert e == (None if x == 0 or f == 0 else x / f * s["derivatives"][k][name]), (k, name)
    assert "shank.rest" in s["unset"] and "heel.limits[0]" in s["unset"] and "shank.limits[0]" not in s["unset"]
    assert len(s["lowest_contacts"]) == 4  # contacts: all, level tips: the touchdown height's kink
    # a peak two events tie for is noted: the derivatives are a subgradient
    assert s["ties"] == {}
    tied = "\n".join(format_sensitivity(model, replace(g, ties={**g.ties, "peak_internal_norm": (0, 1)})))
    assert tied.count("note: 2 events tie for the peak") == 1 and "Clarke subdifferential" in tied
    assert tied.index("note: 2 events tie") > tied.index("peak_internal_norm = ") > tied.index("peak_external_norm = ")


@pytest.mark.parametrize("value", ["speed", "heel.mass"])
def test_derivatives_agree_with_central_differences_of_the_cli(case, tmp_path, capsys, value):
    path, d = case
    s = d["sensitivity"]
    x = s["values"][value]
    ends = []
    for sign in (1, -1):
        moved = {"speed": "speed", "heel.mass": "heel_mass"}[value]
        other = _landing_file(tmp_path / f"moved{sign}.yaml", **{moved: x * (1 + sign * EPS)})
        e = _json(capsys, str(other))
        assert e["landing"]["step"] == s["step"]
        assert [(ev["kind"], len(ev["external"])) for ev in e["events"]] == [(ev["kind"], len(ev["external"]))
                                                                                  for ev in d["events"]]
        ends.append(e["landing"])
    for k in (*SCALARS, "total_external", "final_angles"):
        fd = (np.array(ends[0][k]) - np.array(ends[1][k])) / (2 * EPS * x)
        exact = np.array(s["derivatives"][k][value])
        assert np.all(np.abs(fd - exact) <= 1e-4 * np.maximum(np.abs(exact), 1e-4)), (k, fd, exact)  # measured 2e-6
    assert abs(s["derivatives"]["peak_external_norm"][value]) > 1e-2


def _tables(text: str) -> dict[str, list[tuple[str, float, float, str]]]:
    """Per objective, the rows (name, x, df/dx, effect) of the text report's tables."""
    out: dict[str, list] = {}
    current = None
    for line in text.splitlines():
        head = re.match(r"^(\w+) = ", line)
        if head and head.group(1) in SCALARS:
            current = out.setdefault(head.group(1), [])
        elif current is not None and line.startswith("  ") and not line.strip().startswith(("value", "...", "note")):
            name, x, *_, dfdx, e = line.split()
            current.append((name, float(x), float(dfdx), e))
        elif not line.startswith("  "):
            current = None
    return out


def test_the_text_tables_are_sorted_by_effect(case, capsys):
    path, d = case
    assert main(["evaluate", "--sensitivity", "--tolerance", TOLERANCE, str(path)]) == 0
    text = capsys.readouterr().out
    assert "along its event sequence" in text and "4-11 landings" in text
    assert "peak_external_norm = " in text and " N s" in text and "df/dx [N s per unit of x]" in text
    tables = _tables(text)
    assert set(tables) == set(SCALARS)
    for k, rows in tables.items():
        assert len(rows) == 12
        e = [abs(float(r[3])) for r in rows if r[3] != "-"]
        assert e == sorted(e, reverse=True) and len(e) >= 10
        f = d["sensitivity"]["objectives"][k]
        for name, x, dfdx, el in rows:
            assert name not in d["sensitivity"]["unset"]
            if el != "-":  # printed to 4 decimals, x and df/dx to 6 and 4 significant digits
                per = 100 * math.pi / 180 / f * dfdx if name.endswith(".angle") else x / f * dfdx  # % per degree
                assert float(el) == pytest.approx(per, rel=1e-3, abs=1e-4), (k, name)
    assert "speed" in [r[0] for r in tables["peak_external_norm"]]
    assert re.search(r"\.\.\. \d+ more values \(\d+ with derivative 0\)", text)
    assert "note: 4 contacts are lowest at touchdown" in text


#: A plank landing plastically on both ends with friction: it sticks on four rows over three DOFs,
#: so the force split is not unique and landing_gradient refuses the derivatives.
PLANK = """scene: {speed: 0.5, restitution: 0.0, friction: 1.0, gravity: 9.81, duration: 0.002}
model:
  bodies:
    - {name: plank, length: 0.6, mass: 3.0, angle: 0.0, contacts: [0.0, 1.0]}
"""


def test_refused_derivatives_are_a_warning_beside_the_landing(tmp_path, capsys):
    path = tmp_path / "plank.yaml"
    path.write_text(PLANK)
    d = _json(capsys, "--sensitivity", str(path))
    assert d["sensitivity"] is None and d["model"] == "landing" and d["events"]
    assert d["warnings"][-1] == ("no sensitivity: the landing's derivatives are refused (redundant constraint rows in a "
                                 "landing mode: the force split is not unique, so it has no derivative)")
    assert main(["evaluate", "--tolerance", TOLERANCE, "--sensitivity", str(path)]) == 0
    out = capsys.readouterr().out
    assert "Whole landing over 2 ms" in out and "Sensitivity:" not in out
    assert out.rstrip().splitlines()[-1].startswith("warning: no sensitivity: the landing's derivatives are refused")


def test_a_first_impact_is_an_error_naming_the_flag(case, capsys):
    path, _ = case
    first = str(REPO / "configs" / "paper_case3.yaml")
    assert main(["evaluate", "--sensitivity", first]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err.count("\n") == 1
    assert captured.err.startswith(f"footopt: error: {first}: --sensitivity: ") and "scene.duration" in captured.err
    assert main(["evaluate", "--sensitivity", "--model", "friction", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("footopt: error: --sensitivity: needs the whole landing") and err.count("\n") == 1
    study = str(REPO / "configs" / "robust_study.yaml")
    assert main(["evaluate", "--sensitivity", "--landings", study, str(path)]) == 2
    assert capsys.readouterr().err.startswith("footopt: error: --sensitivity: not with --landings")


def test_without_the_flag_the_json_has_no_sensitivity(case, capsys):
    path, _ = case
    assert "sensitivity" not in _json(capsys, str(path))
