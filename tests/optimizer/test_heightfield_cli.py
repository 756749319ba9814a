"""``scene.heightfield`` in model files and ``footopt evaluate`` on spatial files with uneven
ground: parsing errors (one line naming the field), the round trip, the automatic choice of the
sequential rung (and why), the compliant rung on request, and its JSON."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from impulse_core.kinematics.spatial import SPATIAL
from impulse_core.model.heightfield import Heightfield
from impulse_core.timedomain.compliant import CompliantSettings, simulate_to_tolerance
from impulse_core.timedomain.sequential import sequential_impacts
from optimizer.cli.main import main
from optimizer.config.model_file import format_model_file, load_model_file, load_yaml, parse_model
from optimizer.errors import ConfigError

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "configs" / "spatial_heightfield.yaml"
SPATIAL_CASE = ROOT / "configs" / "spatial_case3.yaml"
UNEVEN_FILE = ROOT / "configs" / "uneven_terrain.yaml"
FIELD_TEXT = """  heightfield:   # ground height y at (x_i, z_j), m; heights[i] is the row at x[i], along z
    x: [-0.2, 0.4, 0.8]
    z: [-0.3, 0.0, 0.3]
    heights: [[0.0, 0.0, 0.0],
              [0.0, 0.0, 0.0],
              [0.01, 0.025, 0.04]]
"""


def _record(capsys) -> dict:
    (line,) = capsys.readouterr().out.splitlines()
    return json.loads(line)


def _scene_with(field: str) -> dict:
    data = load_yaml(EXAMPLE.read_text(encoding="utf-8"))
    data["scene"]["heightfield"] = load_yaml(field)
    return data


def test_the_example_reads_and_writes_back_equal():
    assert FIELD_TEXT in EXAMPLE.read_text(encoding="utf-8")
    model = load_model_file(EXAMPLE)
    hf = model.scene.heightfield
    assert hf == Heightfield((-0.2, 0.4, 0.8), (-0.3, 0.0, 0.3), ((0.0,) * 3, (0.0,) * 3, (0.01, 0.025, 0.04)))
    assert model.scene.base_z == 0.0
    assert parse_model(load_yaml(format_model_file(model))) == model
    moved = dataclasses.replace(model, scene=dataclasses.replace(model.scene, base_z=0.05, base_x=-0.02))
    assert parse_model(load_yaml(format_model_file(moved))) == moved


@pytest.mark.parametrize(
    "field, message",
    [
        ("{x: [0.0, 1.0], z: [0.0, 1.0, 2.0], heights: [[0, 0, 0]]}",
         "scene.heightfield.heights: expected 2 rows of 3 values"),
        ("{x: [0.0, 1.0], z: [0.0], heights: [[0], [0, 1]]}", "scene.heightfield.heights: expected 2 rows of 1 values"),
        ("{x: [0.0, 0.0], z: [0.0], heights: [[0], [0]]}", "scene.heightfield.x[1]: the grid must increase strictly"),
        ("{x: [0.0], z: [1.0, -1.0], heights: [[0, 0]]}", "scene.heightfield.z[1]: the grid must increase strictly"),
        ("{x: [0.0], z: [0.0], heights: [[.nan]]}", "scene.heightfield.heights[0][0]: must be a finite number"),
        ("{x: [0.0], z: [0.0], heights: [['a']]}", "scene.heightfield.heights[0][0]: must be a number"),
        ("{x: [0.0], heights: [[0]]}", "scene.heightfield.z: missing (required)"),
        ("{x: [], z: [0.0], heights: []}", "scene.heightfield.x: must be a non-empty list"),
        ("{x: [0.0], z: [0.0], heights: [[0]], y: 1}", "scene.heightfield.y: unknown key"),
        ("[[0.0, 0.0]]", "scene.heightfield: must be a mapping"),
    ],
)
def test_bad_heightfields_are_refused_naming_the_field(field, message):
    with pytest.raises(ConfigError) as info:
        parse_model(_scene_with(field))
    text = str(info.value)
    assert message in text and "\n" not in text, text


def test_heightfield_and_base_z_need_a_spatial_file_and_exclude_a_terrain():
    data = load_yaml(UNEVEN_FILE.read_text(encoding="utf-8"))
    data["scene"]["heightfield"] = {"x": [0.0], "z": [0.0], "heights": [[0.0]]}
    with pytest.raises(ConfigError, match=r"scene\.heightfield: needs 'model\.space: spatial'"):
        parse_model(data)
    data["scene"].pop("heightfield")
    data["scene"]["base_z"] = 0.1
    with pytest.raises(ConfigError, match=r"scene\.base_z: needs 'model\.space: spatial'"):
        parse_model(data)
    data["scene"].pop("base_z")
    data["model"]["space"] = "spatial"
    data["scene"]["heightfield"] = {"x": [0.0], "z": [0.0], "heights": [[0.0]]}
    with pytest.raises(ConfigError, match=r"scene\.terrain: give scene\.heightfield or scene\.terrain, not both"):
        parse_model(data)


def test_bad_heightfield_exits_2_with_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text(EXAMPLE.read_text(encoding="utf-8").replace("[0.01, 0.025, 0.04]", "[0.01, 0.025]"), encoding="utf-8")
    assert main(["evaluate", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "scene.heightfield.heights: expected 3 rows of 3 values" in err, err


def test_auto_runs_the_sequential_rung_on_a_heightfield_and_says_why(capsys):
    assert main(["evaluate", str(EXAMPLE), "--json"]) == 0
    record = _record(capsys)
    assert record["model"] == record["impact_model"] == "sequential"
    assert record["impact_reason"].startswith("automatic: scene.heightfield is not flat")
    model = load_model_file(EXAMPLE)
    direct = sequential_impacts(model.tree, model.scene, space=SPATIAL)
    assert record["external"] == direct.external.tolist()
    assert record["internal"] == direct.internal_magnitude.tolist()
    assert record["touchdown_order"][0] == "toe2_distal[0]" and record["touchdown_order"][-1] == "heel[0]"
    assert record["scene"]["heightfield"]["heights"][2] == [0.01, 0.025, 0.04]
    assert all(len(v) == 3 for v in record["internal_vector"])
    assert len(record["v_plus"]) == len(record["velocities"]) == 6 + 8
    assert record["warnings"] == []


def test_the_compliant_rung_on_request_meets_its_tolerance(capsys):
    assert main(["evaluate", str(EXAMPLE), "--json", "--model", "compliant", "--tolerance", "1e-3"]) == 0
    record = _record(capsys)
    assert record["model"] == "compliant" and record["impact_reason"].startswith("requested")
    assert record["error_estimate"] <= record["tolerance"] == 1e-3
    model = load_model_file(EXAMPLE)
    direct = simulate_to_tolerance(model.tree, model.scene, CompliantSettings(), 1e-3, space=SPATIAL)
    np.testing.assert_allclose(record["external"], direct.external, rtol=1e-12)
    rigid = sequential_impacts(model.tree, model.scene, space=SPATIAL)
    # the penalty pads at 1e6 N/m against the stiff limit: a few percent on this landing
    assert np.max(np.abs(direct.external - rigid.external)) / np.max(rigid.external) < 0.05


def test_newton_and_decoupled_refuse_a_heightfield_that_is_not_flat(capsys):
    for rung in ("newton", "decoupled"):
        assert main(["evaluate", str(EXAMPLE), "--model", rung]) == 2
        err = capsys.readouterr().err
        assert f"scene.heightfield: --model {rung} assumes flat ground" in err and err.count("\n") == 1, err


def test_lcp_and_friction_on_a_heightfield_are_the_landing_s_first_event(tmp_path, capsys):
    """The first instant on the example's heightfield (with friction, so the heel slides on its
    slope) through the JSON: the spatial landing's first event of the same file (1e-9)."""
    from impulse_core.timedomain.landing import LandingSettings, landing

    text = EXAMPLE.read_text(encoding="utf-8").replace("  friction: 0.0\n", "  friction: 0.3\n", 1)
    path = tmp_path / "rough.yaml"
    path.write_text(text, encoding="utf-8")
    model = load_model_file(path)
    for rung, mu in (("friction", 0.3), ("lcp", 0.0)):
        assert main(["evaluate", str(path), "--json", "--model", rung]) == 0
        record = json.loads(capsys.readouterr().out)
        scene = dataclasses.replace(model.scene, friction=mu, duration=1e-3)
        event = landing(model.tree, scene, (), LandingSettings(tolerance=1.0, max_refinements=1), SPATIAL).events[0]
        scale = float(np.max(event.external))
        np.testing.assert_allclose(record["external"], event.external, atol=1e-9 * scale)
        np.testing.assert_allclose(record["tangential"], event.tangential, atol=1e-9 * scale)
        np.testing.assert_allclose(record["internal"], event.internal_magnitude, atol=1e-9 * scale)
        assert record["model"] == rung and sum(record["active"]) >= 1
        assert bool(np.any(np.array(record["tangential"]) != 0)) is (rung == "friction")


def test_a_flat_heightfield_keeps_the_rigid_rungs(tmp_path, capsys):
    text = SPATIAL_CASE.read_text(encoding="utf-8").replace(
        "  contacts: all\n", "  contacts: all\n  heightfield: {x: [0, 1], z: [0, 1], heights: [[0.2, 0.2], [0.2, 0.2]]}\n", 1
    )
    flat = tmp_path / "flat.yaml"
    flat.write_text(text, encoding="utf-8")
    assert main(["evaluate", str(flat), "--json"]) == 0
    on_field = _record(capsys)
    assert main(["evaluate", str(SPATIAL_CASE), "--json"]) == 0
    plain = _record(capsys)
    assert on_field["model"] == plain["model"] == "newton"
    assert on_field["external"] == plain["external"]


def test_a_planar_terrain_that_is_not_flat_is_refused_in_space(tmp_path, capsys):
    text = UNEVEN_FILE.read_text(encoding="utf-8").replace("model:\n", "model:\n  space: spatial\n", 1)
    f = tmp_path / "uneven_spatial.yaml"
    f.write_text(text, encoding="utf-8")
    assert main(["evaluate", str(f)]) == 2
    err = capsys.readouterr().err
    assert "scene.terrain: a ground profile y(x) is planar" in err and "scene.heightfield" in err


@pytest.mark.parametrize("rung", ["compliant", "sequential"])
def test_a_planar_file_read_as_spatial_gives_the_planar_time_domain_answer(tmp_path, capsys, rung):
    planar = ROOT / "configs" / "paper_case2.yaml"
    spatial = tmp_path / "case2_spatial.yaml"
    spatial.write_text(planar.read_text(encoding="utf-8").replace("model:\n", "model:\n  space: spatial\n", 1),
                       encoding="utf-8")
    records = []
    for f in (planar, spatial):
        assert main(["evaluate", str(f), "--json", "--model", rung]) == 0
        records.append(_record(capsys))
    a, b = records
    assert b["model"] == a["model"] == rung
    for key in ("external", "internal"):
        np.testing.assert_allclose(b[key], a[key], rtol=1e-10, atol=1e-12 * max(a[key]))
    if rung == "compliant":
        assert b["error_estimate"] == pytest.approx(a["error_estimate"], rel=1e-6)
    assert b["touchdown_order"] == a["touchdown_order"]


def test_the_plot_stands_the_foot_on_the_heightfield(tmp_path, capsys):
    """--plot on a heightfield: the drawn tree stands where the scene lands it (its lowest
    contact the touchdown clearance above the ground, the base at base_x, base_z) and the impulse
    arrows point along the ground's normal at each contact."""
    from impulse_core.evaluate import touchdown_geometry
    from impulse_core.model import heightfield
    from impulse_core.timedomain.compliant import TOUCHDOWN_CLEARANCE
    from optimizer.report.plot import _placed_on

    model = load_model_file(EXAMPLE)
    hf = model.scene.heightfield
    assert not hf.is_flat
    placed, normals = _placed_on(model.tree, touchdown_geometry(model.tree, SPATIAL), model.scene)
    clearance = heightfield.vertical_clearance(hf, placed.contacts)
    assert float(np.min(clearance)) == pytest.approx(TOUCHDOWN_CLEARANCE, abs=1e-12)
    assert placed.origins[0, [0, 2]] == pytest.approx([model.scene.base_x, model.scene.base_z], abs=1e-12)
    assert np.allclose(normals, heightfield.normal(hf, placed.contacts[:, 0], placed.contacts[:, 2]))
    assert np.max(np.abs(normals[:, [0, 2]])) > 1e-3  # tilted somewhere: the arrows are not all vertical
    assert main(["evaluate", str(EXAMPLE), "--plot", str(tmp_path / "hf.png")]) == 0
    assert (tmp_path / "hf.png").stat().st_size > 10_000


def test_a_contact_turned_into_the_heightfield_rests_instead_of_chattering(capsys):
    """tests/impulse_core/data/chatter_heightfield.yaml (restitution 0, a rod's tip that the tree
    keeps turning into the ground) failed with exit 1 after 1000 impacts ("the contacts chatter");
    the sequential rung now rests the tip: exit 0, one touchdown, the tip's impulse over its rest
    (more than twice its touchdown's), and a warning that the run reached its time limit with
    the tip still resting."""
    data = Path(__file__).resolve().parents[1] / "impulse_core" / "data" / "chatter_heightfield.yaml"
    assert main(["evaluate", str(data), "--json"]) == 0
    r = _record(capsys)
    assert r["model"] == "sequential" and r["touchdown_order"] == ["b2[0]"]
    assert r["external"][4] > 4.0 and sum(r["external"][:4]) == 0.0
    assert any("time limit (0.1 s)" in w and "resting" in w for w in r["warnings"])
