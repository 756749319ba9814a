"""``footopt evaluate`` on uneven terrain: ``scene.terrain`` and ``scene.base_x`` from the model
file, the sequential model by default there, the compliant rung on request, the rigid rungs
refusing, and the report and JSON of the time-domain models."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from impulse_core.timedomain.compliant import CompliantSettings, ContactLaw, simulate_impact
from impulse_core.errors import ModelError
from impulse_core.evaluate import evaluate
from impulse_core.timedomain.sequential import sequential_impacts
from impulse_core.model.terrain import FLAT, Terrain
from optimizer.cli.main import main
from optimizer.config.model_file import load_model_file
from tests.optimizer.conftest import LEG_YAML

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"

ROOT = Path(__file__).resolve().parents[2]
UNEVEN_FILE = ROOT / "configs" / "uneven_terrain.yaml"
CONTRACT_KEYS = {"external", "internal", "external_norm", "internal_norm"}
TIME_DOMAIN_KEYS = {
    "impact_model",
    "impact_reason",
    "touchdown_time",
    "touchdown_order",
    "energy_before",
    "energy_after",
    "energy_gained",
}
#: Fast compliant settings for tests (30 steps per contact period).
FAST = ["--steps-per-period", "30"]


def _record(capsys) -> dict:
    (line,) = capsys.readouterr().out.splitlines()
    return json.loads(line)


def _one_error_line(err: str, where: str | Path, start: str) -> None:
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert err.startswith(f"footopt: error: {where}: {start}"), err


def test_uneven_terrain_runs_the_sequential_model_by_default(capsys) -> None:
    assert main(["evaluate", str(UNEVEN_FILE), "--json"]) == 0
    record = _record(capsys)
    assert CONTRACT_KEYS | TIME_DOMAIN_KEYS <= set(record)
    assert record["impact_model"] == "sequential"
    assert record["impact_reason"].startswith("automatic: scene.terrain is not flat")
    model = load_model_file(UNEVEN_FILE)
    direct = sequential_impacts(model.tree, model.scene)
    assert record["external"] == direct.external.tolist()
    assert record["internal"] == direct.internal_magnitude.tolist()
    assert record["external_norm"] == direct.external_norm and record["internal_norm"] == direct.internal_norm
    assert record["touchdown_time"] == direct.touchdown_time.tolist()
    assert record["touchdown_order"] == ["toe_distal[0]", "heel[0]"]
    assert record["touchdown_time"][1] == 0.0 and 5e-3 < record["touchdown_time"][0] < 6e-3
    assert record["energy_before"] == direct.energy_before and record["energy_after"] == direct.energy_after
    assert record["energy_gained"] is False
    assert record["scene"]["terrain"] == [[-1.0, 0.0], [0.45, 0.0], [0.75, 0.04]] and record["scene"]["base_x"] == 0.0
    assert len(record["internal"]) == model.tree.n_bodies - 1 and len(record["external"]) == 2


def test_compliant_on_request(capsys) -> None:
    args = ["evaluate", str(UNEVEN_FILE), "--json", "--model", "compliant", "--stiffness", "1e6", *FAST]
    assert main(args) == 0
    record = _record(capsys)
    assert CONTRACT_KEYS | TIME_DOMAIN_KEYS | {"status", "recontacting", "stiffness", "timestep"} <= set(record)
    assert record["impact_model"] == "compliant" and record["impact_reason"].startswith("requested")
    assert record["status"] == "separated" and record["stiffness"] == 1e6 and record["law"] == "penalty"
    model = load_model_file(UNEVEN_FILE)
    direct = simulate_impact(model.tree, model.scene, CompliantSettings(stiffness=1e6, steps_per_period=30))
    assert record["external"] == direct.external.tolist()
    assert record["internal"] == direct.internal_magnitude.tolist()
    assert record["timestep"] == direct.timestep
    assert record["touchdown_order"] == ["toe_distal[0]", "heel[0]"]
    sequential = sequential_impacts(model.tree, model.scene)
    np.testing.assert_allclose(record["external"], sequential.external, rtol=0.05)


def test_compliant_constraint_law_and_gravity(capsys) -> None:
    args = ["evaluate", str(UNEVEN_FILE), "--json", "--model", "compliant", "--law", "constraint"]
    assert main([*args, "--stiffness", "1e8", "--gravity", "9.81", *FAST]) == 0
    record = _record(capsys)
    assert (
        record["law"] == "constraint"
        and "1/s^2" in record["impact_reason"]
        and "gravity 9.81" in record["impact_reason"]
    )


def test_the_text_report_of_a_time_domain_model(capsys) -> None:
    assert main(["evaluate", str(UNEVEN_FILE)]) == 0
    out = capsys.readouterr().out
    assert "model:   sequential:" in out and "why:     automatic: scene.terrain is not flat" in out
    assert "ground:  terrain [[-1, 0], [0.45, 0], [0.75, 0.04]] (m), base origin at x = 0 m" in out
    assert "contacts: the geometry decides (touchdowns below)" in out
    for section in ("External impulses", "Internal impulses", "external_norm", "Velocities", "kinetic energy [J]"):
        assert section in out  # the rigid report's layout
    table = out[out.index("Touchdowns") :].splitlines()[1:4]
    assert table[0].split() == ["contact", "touchdown", "[ms]", "order"]
    assert table[1].split()[::2] == ["heel[0]", "2"] and 5.0 < float(table[1].split()[1]) < 6.0
    assert table[2].split() == ["toe_distal[0]", "0.000", "1"]
    assert main(["evaluate", str(UNEVEN_FILE), "--model", "compliant", *FAST]) == 0
    assert "integration: separated after" in capsys.readouterr().out


@pytest.mark.parametrize("rung", ["decoupled", "newton", "friction-relaxed"])
def test_flat_ground_rungs_refuse_uneven_terrain(rung: str, capsys) -> None:
    assert main(["evaluate", str(UNEVEN_FILE), "--model", rung]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    _one_error_line(err, UNEVEN_FILE, f"scene.terrain: --model {rung} assumes flat ground")
    assert "--model lcp or friction" in err and "sequential" in err


@pytest.mark.parametrize("friction", [0.0, 0.4])
def test_lcp_and_friction_give_the_landing_s_first_event(write, friction: float, capsys) -> None:
    """On the uneven terrain, ``--model lcp`` and ``--model friction`` are the first instant: the
    whole landing's first event of the same file (``--model landing``), through the JSON (1e-9)."""
    text = UNEVEN_FILE.read_text().replace("friction: 0.0", f"friction: {friction}\n  duration: 0.002\n  gravity: 9.81")
    path = write(text)
    assert main(["evaluate", str(path), "--json", "--model", "landing", "--tolerance", "1"]) == 0
    first = _record(capsys)["events"][0]
    assert first["t"] == 0.0
    for rung in ("lcp", "friction"):
        assert main(["evaluate", str(path), "--json", "--model", rung]) == 0
        record = _record(capsys)
        assert record["model"] == rung and "first instant on uneven ground" in record["impact_reason"]
        assert CONTRACT_KEYS | {"tangential", "modes", "warnings"} <= set(record)
        event = first if rung == "friction" or friction == 0 else None
        if event is None:  # lcp on a rough file: the frictionless landing's first event
            main(["evaluate", str(write(text.replace(f"friction: {friction}", "friction: 0.0"), "smooth.yaml")), "--json",
                  "--model", "landing", "--tolerance", "1"])
            event = _record(capsys)["events"][0]
        scale = max(event["external"])
        for key in ("external", "tangential", "internal"):
            np.testing.assert_allclose(record[key], event[key], atol=1e-9 * scale, err_msg=key)
        assert record["active"] == [False, True]  # the toe on the ramp
        modes = record["modes"]
        assert modes is None if rung == "lcp" else modes[0] == "separating" and modes[1] in ("sticking", "sliding")


def test_evaluate_refuses_uneven_terrain_but_not_flat_terrain_at_any_height() -> None:
    model = load_model_file(UNEVEN_FILE)
    with pytest.raises(ModelError, match=r"^scene\.terrain: .*sequential"):
        evaluate(model.tree, model.scene)
    level = evaluate(model.tree, dataclasses.replace(model.scene, terrain=FLAT))
    raised = evaluate(model.tree, dataclasses.replace(model.scene, terrain=Terrain((0.0, 1.0), (0.3, 0.3)), base_x=2.0))
    np.testing.assert_array_equal(level.external, raised.external)


def test_flat_ground_sequential_equals_newton(capsys) -> None:
    """On flat ground with level soles the sequential model is eq. 11 (one impact)."""
    case2 = ROOT / "configs" / "paper_case2.yaml"
    assert main(["evaluate", str(case2), "--json", "--model", "sequential"]) == 0
    seq = _record(capsys)
    assert main(["evaluate", str(case2), "--json"]) == 0
    rigid = _record(capsys)
    assert rigid["impact_model"] == "newton" and "scene.contacts: all is not used" in seq["impact_reason"]
    np.testing.assert_allclose(seq["external"], rigid["external"], rtol=1e-9)
    np.testing.assert_allclose(seq["internal"], rigid["internal"], rtol=1e-8)
    assert seq["touchdown_time"] == [0.0] * len(seq["external"])


@pytest.mark.parametrize(
    ("line", "start"),
    [
        ("  terrain: [[0, 0], [1, 0.1], [1, 0.2]]", "scene.terrain[2]: x must increase strictly"),
        ("  terrain: [[0, 0], [0.5, high]]", "scene.terrain[1][1]: must be a number"),
        ("  terrain: [[0, 0], [0.5]]", "scene.terrain[1]: must be a pair [x, y]"),
        ("  terrain: [0, 0]", "scene.terrain[0]: must be a pair [x, y]"),
        ("  terrain: 0.1", "scene.terrain: must be a non-empty list"),
        ("  base_x: [0]", "scene.base_x: must be a number"),
    ],
)
def test_bad_terrain_exits_2_with_its_yaml_path(write, line: str, start: str, capsys) -> None:
    path = write(LEG_YAML.replace("  contacts: all\n", line + "\n"))
    assert main(["evaluate", str(path)]) == 2
    _one_error_line(capsys.readouterr().err, path, start)


@pytest.mark.parametrize(
    ("args", "where", "start"),
    [
        (["--model", "newton", "--stiffness", "1e6"], "--stiffness", "applies to --model compliant only"),
        (["--law", "constraint"], "--law", "applies to --model compliant only"),
        (["--model", "sequential", "--steps-per-period", "30"], "--steps-per-period", "applies to --model compliant"),
        (["--model", "lcp", "--gravity", "9.81"], "--gravity", "applies to --model sequential or compliant only"),
        (["--model", "compliant", "--stiffness", "-1"], "--stiffness", "must be in [1, 1e+16]"),
        (["--model", "compliant", "--stiffness", "1e300"], "--stiffness", "must be in [1, 1e+16]"),  # ran for ever
        (["--model", "compliant", "--steps-per-period", "2"], "--steps-per-period", "must be in [4, 100000]"),
        (["--model", "compliant", "--steps-per-period", "1e300"], "--steps-per-period", "must be in [4, 100000]"),
        (["--model", "sequential", "--gravity", "-9.81"], "--gravity", "must be a finite number >= 0"),
    ],
)
def test_bad_time_domain_options_exit_2(leg_file: Path, args: list[str], where: str, start: str, capsys) -> None:
    assert main(["evaluate", str(leg_file), *args]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    _one_error_line(err, where, start)


def test_plot_draws_the_terrain(tmp_path: Path, capsys) -> None:
    path = tmp_path / "uneven.png"
    assert main(["evaluate", str(UNEVEN_FILE), "--plot", str(path)]) == 0
    assert path.read_bytes()[:8] == PNG_MAGIC
    assert capsys.readouterr().err == ""


def test_a_written_file_keeps_its_terrain(tmp_path: Path, capsys) -> None:
    from optimizer.config.model_file import dump_model_file

    model = load_model_file(UNEVEN_FILE)
    moved = dataclasses.replace(model, scene=dataclasses.replace(model.scene, base_x=0.005))
    path = dump_model_file(moved, tmp_path / "moved.yaml")
    assert load_model_file(path) == moved
    assert main(["evaluate", str(path), "--json"]) == 0
    record = _record(capsys)
    assert record["scene"]["base_x"] == 0.005 and record["impact_model"] == "sequential"
    assert not math.isclose(record["touchdown_time"][0], sequential_impacts(model.tree, model.scene).touchdown_time[0])


def test_the_text_report_of_the_first_instant_names_the_ground_s_tangent(write, capsys) -> None:
    path = write(UNEVEN_FILE.read_text().replace("friction: 0.0", "friction: 0.3"))
    assert main(["evaluate", str(path), "--model", "friction"]) == 0
    out = capsys.readouterr().out
    assert "why:     requested; first instant on uneven ground" in out
    assert "External impulses (normal and tangential along the ground's tangent, on the contacts)" in out


def test_friction_on_uneven_terrain_runs_the_sequential_model_with_friction(write, capsys) -> None:
    text = UNEVEN_FILE.read_text().replace("friction: 0.0", "friction: 0.3")
    path = write(text)
    assert main(["evaluate", str(path), "--json"]) == 0
    record = _record(capsys)
    model = load_model_file(path)
    direct = sequential_impacts(model.tree, model.scene)
    assert record["model"] == "sequential" and record["impact_reason"].startswith("automatic: scene.terrain")
    assert record["external"] == direct.external.tolist() and record["tangential"] == direct.tangential.tolist()
    assert record["modes"] == [m.value for m in direct.modes] and "Coulomb" in record["model_description"]
    assert main(["evaluate", str(UNEVEN_FILE), "--json"]) == 0
    plain = _record(capsys)
    assert plain["tangential"] == [0.0, 0.0] and plain["modes"] is None


def test_bad_friction_on_uneven_terrain_exits_2_naming_it(write, capsys) -> None:
    path = write(UNEVEN_FILE.read_text().replace("friction: 0.0", "friction: -0.3"))
    for rung in ("friction", "auto"):
        assert main(["evaluate", str(path), "--model", rung]) == 2
        _one_error_line(capsys.readouterr().err, path, "scene.friction")


def test_contact_law_choices_match_the_library() -> None:
    from optimizer.cli.main import build_parser

    args = build_parser().parse_args(["evaluate", "x.yaml", "--law", "penalty"])
    assert ContactLaw(args.law) is ContactLaw.PENALTY and args.steps_per_period is None


def test_the_compliant_rung_meets_its_default_tolerance(capsys) -> None:
    """Without --steps-per-period the compliant rung refines its steps to the default 1e-3 and
    reports its estimate; with fixed steps the warnings say the error is not estimated."""
    assert main(["evaluate", "--json", "--model", "compliant", str(ROOT / "configs" / "uneven_terrain.yaml")]) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["model"] == "compliant"
    assert record["tolerance"] == 1e-3 and record["error_estimate"] <= 1e-3
    assert not any("not estimated" in w for w in record["warnings"])


def test_an_impulsive_jam_is_a_touchdown_marked_jam_in_the_json(capsys) -> None:
    """Random file 40029 slides into Painleve's paradox and jams (``_Landing.jam``): its event is a
    ``touchdown`` (the contract's kind for an impact at the contacts) with ``"jam": true``, a key
    no other event has."""
    path = ROOT / "tests" / "impulse_core" / "data" / "jam_40029.yaml"
    assert main(["evaluate", str(path), "--json", "--tolerance", "1"]) == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    jams = [e for e in out["events"] if "jam" in e]
    assert len(jams) == 1 and jams[0]["jam"] is True and jams[0]["kind"] == "touchdown"
    assert jams[0]["external"][0] > 0 and abs(jams[0]["tangential"][0]) <= 0.3 * jams[0]["external"][0] * (1 + 1e-9)
