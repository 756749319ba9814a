"""Spatial model files (MODEL_FORMAT "Spatial models") through the file format and the CLI."""

from __future__ import annotations

import contextlib
import dataclasses
import io
import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

from impulse_core.evaluate import evaluate
from impulse_core.kinematics.spatial import SPATIAL
from optimizer.config.model_file import format_model_file, load_model_file, parse_model
from optimizer.errors import ConfigError
from optimizer.config.model_file import load_yaml

REPO = Path(__file__).resolve().parents[2]
EXAMPLE = REPO / "configs" / "spatial_case3.yaml"
PLANAR_CASE = REPO / "configs" / "paper_case3.yaml"


def _footopt(*args: str) -> subprocess.CompletedProcess[str]:
    """``footopt ARGS`` from the repository, in this process (the command line's ``main``, which
    ``python -m optimizer`` runs, as test_reliability.py does): its exit status, stdout and stderr."""
    from optimizer.cli.main import main

    out, err, here = io.StringIO(), io.StringIO(), os.getcwd()
    os.chdir(REPO)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = main(list(args))
    finally:
        os.chdir(here)
    return subprocess.CompletedProcess(args, code, out.getvalue(), err.getvalue())


def _json(*args: str) -> dict:
    proc = _footopt("evaluate", "--json", *args)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def test_a_spatial_file_reads_with_its_fields_and_writes_back_equal() -> None:
    model = load_model_file(EXAMPLE)
    assert model.space is SPATIAL
    assert model.scene.velocity == (0.0, -3.43, 0.3) and model.scene.angular_velocity_3d == (0.5, 0.0, 0.0)
    toe1 = next(b for b in model.tree.bodies if b.name == "toe1_proximal")
    assert toe1.rpy == (-0.35, 0.0, 0.0) and toe1.radius == 0.01
    # a solid cylinder's inertia across the rod: m (3 r^2 + L^2) / 12
    assert toe1.inertia == pytest.approx(toe1.mass * (3 * 0.01**2 + toe1.length**2) / 12, rel=1e-14)
    again = parse_model(load_yaml(format_model_file(model)))
    assert again == model


@pytest.mark.parametrize("approach", ["", "  velocity: [0.4, -3.0]\n  angular_velocity: -1.5\n"])
def test_a_planar_file_marked_spatial_gives_the_same_answers(tmp_path: Path, approach: str) -> None:
    """With its planar approach too ([vx, vy] and a number about z, as MODEL_FORMAT's planar files)."""
    text = PLANAR_CASE.read_text(encoding="utf-8")
    if approach:
        text = text.replace("  speed: 3.43", approach.rstrip("\n"), 1)
        (tmp_path / "planar.yaml").write_text(text, encoding="utf-8")
    planar_file = tmp_path / "planar.yaml" if approach else PLANAR_CASE
    text = text.replace("model:\n", "model:\n  space: spatial\n", 1)
    spatial_file = tmp_path / "case3_spatial.yaml"
    spatial_file.write_text(text, encoding="utf-8")
    planar, spatial = _json(str(planar_file)), _json(str(spatial_file))
    for key in ("external", "internal"):
        assert np.allclose(spatial[key], planar[key], rtol=1e-10, atol=1e-12), key
    assert spatial["model"] == planar["model"]
    assert len(spatial["v_plus"]) == len(planar["v_plus"]) + 3


def test_evaluate_json_of_a_spatial_file_is_the_core_answer() -> None:
    record = _json(str(EXAMPLE))
    model = load_model_file(EXAMPLE)
    result = evaluate(model.tree, model.scene, space=SPATIAL)
    assert record["external"] == pytest.approx(list(result.external), rel=1e-12)
    assert record["internal"] == pytest.approx(list(result.internal_magnitude), rel=1e-12)
    assert record["velocities"][:6] == ["base vx", "base vy", "base vz", "base wx", "base wy", "base wz"]
    assert record["scene"]["velocity"] == [0.0, -3.43, 0.3]
    assert all(len(v) == 3 for v in record["internal_vector"])
    assert record["warnings"] == []


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        (lambda t: t.replace("      radius: 0.01\n", "      radius: -0.01\n", 1), "model.bodies[0].radius"),
        (lambda t: t.replace("  space: spatial\n", ""), "scene.velocity"),
        (lambda t: t.replace("  space: spatial\n", "  space: curved\n"), "model.space"),
        (lambda t: t.replace("[-0.35, 0.0, 0.0]", "[-0.35, 0.0]"), "model.bodies[3].rpy"),
        (lambda t: t.replace("  velocity: [0.0, -3.43, 0.3]", "  velocity: [0.0, -3.43, 0.3, 1.0]"), "scene.velocity"),
        (lambda t: t.replace("  angular_velocity: [0.5, 0.0, 0.0]", "  angular_velocity: [0.5, 0.0]"), "scene.angular_velocity"),
    ],
)
def test_bad_spatial_fields_exit_2_naming_the_field(tmp_path: Path, edit, field: str) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text(edit(EXAMPLE.read_text(encoding="utf-8")), encoding="utf-8")
    proc = _footopt("evaluate", str(bad))
    assert proc.returncode == 2
    assert field in proc.stderr and "Traceback" not in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1


def test_axis_zero_is_refused() -> None:
    text = EXAMPLE.read_text(encoding="utf-8").replace("      radius: 0.01\n", "      radius: 0.01\n      axis: [0, 0, 0]\n", 1)
    with pytest.raises(ConfigError, match=r"model.bodies\[0\].axis"):
        parse_model(load_yaml(text))


def test_the_landing_without_a_duration_is_refused_naming_the_field() -> None:
    proc = _footopt("evaluate", "--model", "landing", str(EXAMPLE))
    assert proc.returncode == 2 and "scene.duration" in proc.stderr


def test_a_spatial_file_with_a_duration_lands_whole(tmp_path: Path) -> None:
    """``auto`` and ``--model landing`` run the whole landing in space: final_base [x, y, z],
    final_angles = the base's turn (rotation vector) then the joints, tangential [t_x, t_z] per
    contact; the first event is the spatial first impact."""
    text = EXAMPLE.read_text().replace("  contacts: all\n", "  contacts: all\n  friction: 0.5\n  gravity: 9.81\n  duration: 0.004\n")
    text = text.replace("  friction: 0.0\n", "")
    path = tmp_path / "landing.yaml"
    path.write_text(text)
    auto, requested = _json(str(path)), _json("--model", "landing", str(path))
    assert auto["model"] == requested["model"] == "landing"
    model = load_model_file(path)
    landing = auto["landing"]
    assert len(landing["final_base"]) == 3
    assert len(landing["final_angles"]) == 3 + len(model.tree.bodies) - 1
    assert all(len(t) == 2 for t in auto["tangential"]) and all(len(t) == 2 for e in auto["events"] for t in e["tangential"])
    first = evaluate(model.tree, model.scene, space=SPATIAL)
    np.testing.assert_allclose(auto["events"][0]["external"], first.external, atol=1e-9 * max(first.external))
    np.testing.assert_allclose(auto["tangential"], first.tangential, atol=1e-9 * max(first.external))


def test_a_spatial_landing_is_drawn_and_animated_in_three_views(tmp_path: Path, monkeypatch, capsys) -> None:
    """--plot: the impulses over time above the side, front and top views; --animate: a GIF of
    the three views side by side, the leg moving between frames."""
    from PIL import Image, ImageChops

    import optimizer.report.landing_plot as landing_plot
    from optimizer.cli.main import main

    monkeypatch.setattr(landing_plot, "ANIMATION_FRAMES", 4)
    text = EXAMPLE.read_text().replace("  contacts: all\n", "  contacts: all\n  gravity: 9.81\n  duration: 0.01\n")
    path = tmp_path / "landing.yaml"
    path.write_text(text)
    png, gif = tmp_path / "landing.png", tmp_path / "landing.gif"
    assert main(["evaluate", str(path), "--plot", str(png), "--animate", str(gif)]) == 0
    out = capsys.readouterr().out
    assert f"plot: {png}" in out and f"animation: {gif}" in out
    with Image.open(png) as image:
        assert image.width > 1.4 * image.height  # three views under the time panel
    with Image.open(gif) as image:
        assert image.n_frames == 4 and image.width > 2.5 * image.height
        first = image.convert("RGB")
        image.seek(image.n_frames - 1)
        assert ImageChops.difference(first, image.convert("RGB")).getbbox() is not None


@pytest.mark.parametrize("spatial", [False, True])
def test_the_drawn_posture_puts_the_contacts_where_the_landing_has_them(spatial: bool) -> None:
    """``landing_plot.posture`` (the touchdown geometry at the run's joint angles, turned by the
    base's rotation vector and moved to its origin) puts each contact body's tip where the
    landing's own dynamics put the contact, along the whole trajectory (1e-12 m)."""
    from impulse_core.kinematics.spatial import PLANAR
    from impulse_core.timedomain.events.run import _Landing
    from impulse_core.timedomain.landing import LandingSettings
    from optimizer.report.landing_plot import posture

    path = EXAMPLE if spatial else REPO / "configs" / "landing_case3.yaml"
    model = load_model_file(path)
    space = SPATIAL if spatial else PLANAR
    scene = model.scene if model.scene.duration else dataclasses.replace(model.scene, duration=0.01, gravity=9.81)
    run = _Landing(model.tree, scene, model.joints, LandingSettings(), space)
    _, states = run.run(scene.duration / 40).trajectory
    tips_of = [b for b, _ in model.tree.contacts]
    assert all(model.tree.bodies[b].contacts[k] == 1.0 for b, k in model.tree.contacts)  # each at its rod's tip
    for q in states[:: max(1, len(states) // 8)]:
        _, tips = posture(model.tree, q, space)
        contacts = run.point(q, np.zeros(len(q))).contacts
        assert np.max(np.abs(tips[tips_of] - contacts)) <= 1e-12


def test_plot_of_a_spatial_file_draws_three_views(tmp_path: Path) -> None:
    out = tmp_path / "foot.png"
    proc = _footopt("evaluate", str(EXAMPLE), "--plot", str(out))
    assert proc.returncode == 0, proc.stderr
    from matplotlib.image import imread

    image = imread(out)
    assert image.shape[1] > 2 * image.shape[0]  # three views side by side


def test_landings_with_a_terrain_step_refuse_a_spatial_file_with_exit_2() -> None:
    """configs/robust_study.yaml steps the ground under the toes: a planar terrain."""
    proc = _footopt("evaluate", "--landings", str(REPO / "configs" / "robust_study.yaml"), str(EXAMPLE))
    assert proc.returncode == 2
    assert "landings.terrain_step: needs a planar model" in proc.stderr and "Traceback" not in proc.stderr


def test_spatial_friction_json_has_xz_tangential_impulses_and_modes(tmp_path: Path) -> None:
    text = EXAMPLE.read_text(encoding="utf-8").replace("friction: 0.0", "friction: 0.5")
    (tmp_path / "f.yaml").write_text(text, encoding="utf-8")
    record = _json(str(tmp_path / "f.yaml"))
    model = load_model_file(tmp_path / "f.yaml")
    result = evaluate(model.tree, model.scene, space=SPATIAL)
    assert record["model"] == "friction" and record["warnings"] == []
    assert np.allclose(record["tangential"], result.tangential, rtol=1e-12)
    assert all(len(t) == 2 for t in record["tangential"])
    assert record["modes"] == [m.value for m in result.modes]
    # the cone at each contact, from the printed numbers
    for lam, t in zip(record["external"], record["tangential"], strict=True):
        assert np.hypot(*t) <= 0.5 * lam * (1 + 1e-9)


def test_mjcf_export_refuses_a_rod_no_rigid_body_has_but_evaluate_takes_it(tmp_path: Path) -> None:
    text = EXAMPLE.read_text(encoding="utf-8").replace("      radius: 0.01\n", "      radius: 0.05\n      gyration: 0.01\n", 1)
    bad = tmp_path / "thin.yaml"
    bad.write_text(text, encoding="utf-8")
    proc = _footopt("export", str(bad), "-o", str(tmp_path / "thin.xml"))
    assert proc.returncode == 2 and "model.bodies[0].radius" in proc.stderr and "Traceback" not in proc.stderr
    assert not (tmp_path / "thin.xml").exists()
    assert _footopt("export", str(bad), "-o", str(tmp_path / "thin.urdf")).returncode == 0
    assert _json(str(bad))["external_norm"] > 0


def test_bench_times_a_spatial_file_beside_pinocchio(capsys, quick_timings) -> None:
    """footopt bench on a spatial model: the batched paths equal single calls and the full model,
    and Pinocchio (free-flyer) is timed beside them (in this process, one call per timing)."""
    from optimizer.cli.main import main

    assert main(["bench", str(EXAMPLE), "--json", "--batch", "64", "--no-compile"]) == 0  # the VM: no C compile here
    report = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert report["batched_equals_single"] and report["lean_equals_full"]
    assert report["n_dof"] == 6 + 8 and report["pinocchio_us_per_call"] > 0
    assert report["gradient_equals_autodiff"] and report["gradient_equals_full"]
    assert (report["n_gradient_values"], report["n_values"]) == (30, 193)  # foot rods' 7 x 3, toe roots' 3 x rpy


def test_support_margin_matches_pinocchio_and_qhull() -> None:
    """The JSON's support_margin: the centre of mass (Pinocchio's centerOfMass) inside the hull
    (scipy's Qhull) of the contact frames' ground projections, the smallest facet distance."""
    pin = pytest.importorskip("pinocchio")
    from scipy.spatial import ConvexHull

    from optimizer.validation.pinocchio_bridge import build_spatial

    model = load_model_file(EXAMPLE)
    pt = build_spatial(model.tree)
    data = pt.model.createData()
    com = pin.centerOfMass(pt.model, data, pt.q)
    pin.framesForwardKinematics(pt.model, data, pt.q)
    ground = np.array([data.oMf[f].translation[[0, 2]] for f in pt.contact_frames])
    hull = ConvexHull(ground)
    expected = float(np.min(-(hull.equations[:, :2] @ com[[0, 2]] + hull.equations[:, 2])))
    assert expected > 0
    assert _json(str(EXAMPLE))["support_margin"] == pytest.approx(expected, abs=1e-12)
