"""`footopt evaluate` on a whole landing: the contract's JSON keys, the first event against the
first-impact model of the same file, --tolerance, bad options and the landing plot."""

from __future__ import annotations

import io
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from optimizer.cli.main import main

REPO = Path(__file__).resolve().parents[2]


def _landing_file(tmp_path: Path, friction: float, duration: float = 0.004) -> Path:
    text = (REPO / "configs" / "landing_case3.yaml").read_text()
    text = text.replace("  friction: 0.5 ", f"  friction: {friction} ").replace("  duration: 0.3 ", f"  duration: {duration} ")
    path = tmp_path / "landing.yaml"
    path.write_text(text)
    return path


def _json(capsys, *args: str) -> dict:
    assert main(["evaluate", "--json", *args]) == 0
    return json.loads(capsys.readouterr().out)


@pytest.mark.parametrize(("friction", "rung"), [(0.0, "lcp"), (0.5, "friction")])
def test_landing_json_keeps_the_contract(tmp_path, capsys, friction, rung):
    path = _landing_file(tmp_path, friction)
    d = _json(capsys, str(path))
    assert d["model"] == "landing" and d["warnings"] == []
    first = _json(capsys, "--model", rung, str(path))
    e0 = d["events"][0]
    assert e0["t"] == 0.0 and e0["kind"] == "touchdown"
    for key in ("external", "internal", "tangential"):
        scale = max(abs(x) for x in first[key]) or 1.0
        assert np.max(np.abs(np.subtract(e0[key], first[key]))) <= 1e-9 * scale, key
        assert d[key] == e0[key]  # the top-level keys are the first impact's
    landing = d["landing"]
    n_contacts, n_joints = len(d["contacts"]), len(d["joints"])
    assert len(landing["total_external"]) == n_contacts
    assert len(landing["final_angles"]) == n_joints + 1
    assert len(landing["final_velocity"]) == len(d["velocities"]) and len(landing["final_base"]) == 2
    assert landing["peak_external_norm"] == pytest.approx(max(np.linalg.norm(e["external"]) for e in d["events"]))
    assert landing["peak_internal_norm"] == pytest.approx(max(np.linalg.norm(e["internal"]) for e in d["events"]))
    assert all(len(e["external"]) == n_contacts and len(e["internal"]) == n_joints for e in d["events"])
    assert [e["t"] for e in d["events"]] == sorted(e["t"] for e in d["events"])
    assert d["error_estimate"] <= d["tolerance"] == 1e-3
    assert set(landing) == {"peak_external_norm", "peak_internal_norm", "peak_max_internal", "total_external",
                            "settled_at", "final_angles", "final_base", "final_velocity", "energy_absorbed",
                            "duration", "step"}  # MODEL_FORMAT's keys, no more
    assert d["integrator"] == "rk4"  # an extra beside error_estimate: these joint laws are not stiff


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_landing_shows_its_progress_on_a_terminal_only(tmp_path, capsys, monkeypatch):
    """On a terminal, stderr shows each run of the step halving (its step, t of the duration, the
    impacts) and clears it; elsewhere stderr stays empty; stdout's JSON is the same either way."""
    path = _landing_file(tmp_path, 0.5, duration=0.01)
    plain = _json(capsys, str(path))
    assert capsys.readouterr().err == ""
    terminal = _Terminal()
    monkeypatch.setattr(sys, "stderr", terminal)
    assert main(["evaluate", "--json", str(path)]) == 0
    assert json.loads(capsys.readouterr().out) == plain
    shown = terminal.getvalue()
    lines = [line for line in shown.split("\r") if line.strip()]
    assert lines and all(line.startswith("landing, run ") and " of 0.01 s, " in line and " impacts" in line
                         for line in lines)
    assert any(f"(step {plain['landing']['step']:.3g} s)" in line for line in lines)  # the last run's step
    assert shown.rstrip("\r").split("\r")[-1].strip() == ""  # the bar is gone


def test_whole_landings_over_landings_show_their_count_on_a_terminal_only(tmp_path, capsys, monkeypatch):
    """``evaluate --landings`` with whole landings (landed one by one): on a terminal stderr counts
    them (1/3 .. 3/3, the file named) and clears; elsewhere it stays empty; the JSON is the same
    either way, and every scenario was landed once."""
    from optimizer.evaluation import robust
    from tests.optimizer.test_landing_inner_robust import robust_yaml

    study = tmp_path / "robust.yaml"
    study.write_text(robust_yaml("{peak_external_norm: max, energy_absorbed: mean}", "outer"), encoding="utf-8")
    path = _landing_file(tmp_path, 0.3, duration=0.005)
    calls = []
    real = robust.scenario_objectives
    monkeypatch.setattr(robust, "scenario_objectives", lambda *a: calls.append(1) or real(*a))
    monkeypatch.setenv("FOOTOPT_WORKERS", "1")  # the spy counts calls in this process
    plain = _json(capsys, "--landings", str(study), str(path))
    assert capsys.readouterr().err == "" and len(calls) == 3 and plain["scenarios"] == 3
    terminal = _Terminal()
    monkeypatch.setattr(sys, "stderr", terminal)
    assert main(["evaluate", "--json", "--landings", str(study), str(path)]) == 0
    assert json.loads(capsys.readouterr().out) == plain
    lines = [line for line in terminal.getvalue().split("\r") if line.strip()]
    assert lines and all(line.startswith(f"{path}: landings") for line in lines)
    assert any("3/3" in line for line in lines) and any("1/3" in line for line in lines)
    assert terminal.getvalue().rstrip("\r").split("\r")[-1].strip() == ""  # the bar is gone


def test_tolerance_applies_to_the_landing_only(tmp_path, capsys):
    path = _landing_file(tmp_path, 0.0)
    assert main(["evaluate", "--model", "lcp", "--tolerance", "1e-4", str(path)]) == 2
    assert "--tolerance: applies to --model landing" in capsys.readouterr().err
    assert main(["evaluate", "--tolerance", "-1", str(path)]) == 2
    assert "--tolerance: must be a finite number > 0" in capsys.readouterr().err
    assert main(["evaluate", "--tolerance", "1e-300", str(path)]) == 2  # the fuzzer's: halved its steps for ever
    assert "--tolerance: a landing's must be >= 1e-12" in capsys.readouterr().err
    d = _json(capsys, "--tolerance", "1e-6", str(path))
    assert d["tolerance"] == 1e-6 and d["error_estimate"] <= 1e-6


def test_landing_plot_is_written(tmp_path, capsys):
    path = _landing_file(tmp_path, 0.5)
    out = tmp_path / "landing.png"
    assert main(["evaluate", "--plot", str(out), str(path)]) == 0
    assert out.stat().st_size > 10_000
    assert f"plot: {out}" in capsys.readouterr().out


def test_animate_writes_a_gif_of_the_landing(tmp_path, monkeypatch, capsys):
    """--animate: one frame per evenly spaced time (5 here), the leg moving between frames; a
    first-impact result or a wrong suffix is refused naming --animate, exit 2."""
    from PIL import Image, ImageChops

    import optimizer.report.landing_plot as landing_plot

    monkeypatch.setattr(landing_plot, "ANIMATION_FRAMES", 5)
    model = _landing_file(tmp_path, friction=0.3, duration=0.02)
    gif = tmp_path / "landing.gif"
    assert main(["evaluate", str(model), "--animate", str(gif)]) == 0
    assert f"animation: {gif}" in capsys.readouterr().out
    with Image.open(gif) as image:
        assert image.n_frames == 5
        first = image.convert("RGB")
        image.seek(image.n_frames - 1)
        width, height = image.size
        below_title = (0, height // 8, width, height)  # the title's time and impacts change anyway
        moved = ImageChops.difference(first.crop(below_title), image.convert("RGB").crop(below_title))
        # the leg moved: not only the GIF palette's dithering (differences of a few levels)
        assert moved.convert("L").point(lambda x: 255 if x > 60 else 0).getbbox() is not None
    assert main(["evaluate", str(model), "--animate", str(tmp_path / "x.mp4")]) == 2
    assert "--animate" in capsys.readouterr().err
    assert main(["evaluate", str(model), "--model", "lcp", "--animate", str(tmp_path / "y.gif")]) == 2
    assert "--animate: only a whole landing moves" in capsys.readouterr().err


def test_tolerance_refines_the_compliant_rung(capsys):
    """--model compliant --tolerance: adaptive steps, the estimate and the integrator in the JSON;
    --steps-per-period fixes them (no estimate, a warning saying so); both together are refused."""
    path = str(Path(__file__).resolve().parents[2] / "configs" / "uneven_terrain.yaml")
    got = _json(capsys, "--model", "compliant", "--tolerance", "1e-3", path)
    assert got["error_estimate"] <= 1e-3 and got["tolerance"] == 1e-3 and got["integrator"] == "dopri5"
    assert got["warnings"] == []
    fixed = _json(capsys, "--model", "compliant", "--steps-per-period", "240", path)
    assert fixed["error_estimate"] is None and any("fixed steps" in w for w in fixed["warnings"])
    assert fixed["integrator"] == "euler" and fixed["steps_per_period"] is None
    unmet = _json(capsys, "--model", "compliant", "--tolerance", "1e-15", path)  # below its rounding
    assert any("did not meet its tolerance" in w for w in unmet["warnings"])
    assert main(["evaluate", "--model", "compliant", "--tolerance", "1e-3", "--steps-per-period", "240", path]) == 2
    assert "--tolerance" in capsys.readouterr().err


def test_the_landing_plot_shades_each_moreau_jean_bridge():
    """A landing's stalled events crossed by Moreau-Jean steps (``LandingResult.bridges``) show as
    shaded spans over their times on the impulse plot, one legend entry for all."""
    from dataclasses import replace

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from impulse_core.timedomain.landing import LandingSettings, landing
    from optimizer.config.model_file import load_model_file
    from optimizer.report.landing_plot import _draw_impulses

    model = load_model_file(REPO / "configs" / "landing_case3.yaml")
    scene = replace(model.scene, duration=0.004)
    r = replace(landing(model.tree, scene, model.joints, LandingSettings()), bridges=((1e-3, 2e-4), (3e-3, 1e-4)))
    fig, ax = plt.subplots()
    _draw_impulses(ax, model.tree, r, "case 3")
    spans = [(p.get_x(), p.get_x() + p.get_width()) for p in ax.patches]
    plt.close(fig)
    assert spans == [pytest.approx((1.0, 1.2)), pytest.approx((3.0, 3.1))]
    assert [t.get_text() for t in ax.get_legend().get_texts()].count("Moreau-Jean bridge") == 1


def test_the_postures_drawn_spread_over_the_landing_time():
    """A Zeno cascade (one impact, then 440 within [9, 21] ms): the postures drawn are the events
    first at or after 12 evenly spaced times, not 12 evenly spaced indices (11 of them in the
    cascade's last milliseconds); no event is drawn twice and an empty landing draws none."""
    from optimizer.report.landing_plot import posture_events

    times = np.concatenate([[0.0], np.linspace(0.009, 0.021, 440)])
    picks = posture_events(times, 12)
    first_after = {int(np.argmax(times >= t)) for t in np.linspace(0.0, 0.021, 12)}
    assert list(picks) == sorted(first_after) and len(picks) == 9  # the targets 1.9-7.6 ms share the 9 ms event
    assert np.diff(times[picks])[2:].min() > 0.0018  # within the cascade ~1.9 ms apart (by index: 1.1 ms)
    assert posture_events(np.zeros(0), 12).size == 0
    assert list(posture_events(np.array([0.0, 0.0, 0.1]), 12)) == [0, 2]


def test_the_posture_labels_do_not_overlap():
    """Case 3's first 4 ms: the leg hardly moves between the impacts drawn, so their time labels
    would print over each other; each label drawn lies at least LABEL_SPACING of the drawing apart."""
    from dataclasses import replace

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from impulse_core.kinematics.spatial import PLANAR
    from impulse_core.timedomain.landing import LandingSettings, landing
    from optimizer.config.model_file import load_model_file
    from optimizer.report.landing_plot import LABEL_SPACING, _draw_postures

    model = load_model_file(REPO / "configs" / "landing_case3.yaml")
    scene = replace(model.scene, duration=0.004)
    r = landing(model.tree, scene, model.joints, LandingSettings())
    fig, ax = plt.subplots()
    _draw_postures(ax, model.tree, r, scene, PLANAR, (0, 1))
    at = np.array([t.xy for t in ax.texts])
    lines = np.vstack([np.column_stack(ln.get_data()) for ln in ax.get_lines()[:-1]])  # the ground last
    plt.close(fig)
    span = np.ptp(lines, axis=0).max()
    assert 1 <= len(at) < len(r.events) + 1
    assert all(np.max(np.abs(a - b)) > LABEL_SPACING * span for i, a in enumerate(at) for b in at[:i])
