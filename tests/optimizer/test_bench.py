"""`footopt bench`: runs, prints the documented keys, and its batched path computes what the
single-call path computes (the timings themselves are not tested: benchmarks, not tests)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from impulse_core.evaluate import active_contacts, approach_velocity, evaluate
from impulse_core.impact.delassus import lean_impact_function, norms_gradient_function
from impulse_core.model.tree import Body, Tree, design_vector
from optimizer.analysis.bench import SCALING_SCENE, scaled_tree, speed_report
from optimizer.cli.main import main

pytestmark = pytest.mark.usefixtures("quick_timings")  # one call per timing: the times are not tested

#: The keys the issue asks for at the top level of ``footopt bench speed --json``.
SPEED_KEYS = ("us_per_design_batched", "pinocchio_us_per_call", "ratio", "gradient_ratio")


def test_bench_json_keys_and_agreement(leg_file, capsys, tmp_path) -> None:
    assert main(["bench", str(leg_file), "--batch", "8", "--json", "--cache-dir", str(tmp_path)]) == 0
    record = json.loads(capsys.readouterr().out.strip())
    for key in (
        *SPEED_KEYS,
        "n_instructions",
        "build_ms",
        "compile_s",
        "backend",
        "scaling",
        "us_per_design_batched_kernel",
        "us_per_design_batched_simd",
        "simd_lanes",
        "gradient_path",
    ):
        assert key in record
    assert record["batched_equals_single"] is True
    assert record["lean_equals_full"] is True
    assert record["gradient_equals_autodiff"] is True
    assert record["gradient_equals_full"] is True
    assert record["gradient_ratio_autodiff"] > 0
    assert record["gradient_ratio_all"] > 0 and record["gradient_ratio_all_c_loop"] > 0
    # leg.yaml (thigh, shank, foot) is no footopt design (no rod named heel..., toe...): every value
    assert record["n_gradient_values"] == record["n_values"]
    assert record["gradient_values"].startswith("every value: not a footopt design")
    evaluation = record[f"us_per_design_batched_{record['gradient_path']}"]
    assert math.isclose(record["gradient_ratio"], record["us_per_design_gradient"] / evaluation)
    assert math.isclose(record["gradient_ratio_all"], record["us_per_design_gradient_all"] / evaluation)
    assert record["scaling"] == []  # model files: no scaling series unless --sizes
    assert math.isclose(record["ratio"], record["us_per_design_batched"] / record["pinocchio_us_per_call"])
    assert record["gradient_ratio"] > 0


def test_bench_speed_mode_json_has_case3_keys_and_scaling(capsys) -> None:
    assert main(["bench", "speed", "--batch", "4", "--json", "--no-compile", "--sizes", "5,8"]) == 0
    record = json.loads(capsys.readouterr().out.strip())
    for key in SPEED_KEYS:
        assert key in record and record[key] is not None
    assert record["model"] == "paper_case3" and record["n_dof"] == 11 and record["n_contacts"] == 4
    assert record["backend"].startswith("CasADi virtual machine")
    assert [row["bodies"] for row in record["scaling"]] == [5, 8]
    for row in record["scaling"]:
        assert row["batched_equals_single"] and row["lean_equals_full"]
        assert row["instructions"] > 0 and row["us_per_design"] > 0


def test_benchmarked_function_is_what_evaluate_computes(leg_tree, leg_scene) -> None:
    """The function the benchmark times gives evaluate()'s impulses (no cheaper stand-in is timed)."""
    report = speed_report("leg", leg_tree, leg_scene, batch=4, gradient=False, pinocchio=False)
    assert report.batched_equals_single and report.lean_equals_full
    topology = leg_tree.topology(active_contacts(leg_tree, leg_scene))
    out = lean_impact_function(topology)(
        p=design_vector(leg_tree),
        v_minus=approach_velocity(topology, leg_scene.speed),
        restitution=leg_scene.restitution,
    )
    result = evaluate(leg_tree, leg_scene)
    np.testing.assert_allclose(np.array(out["external"]).ravel(), result.external[list(result.active)], rtol=1e-12)
    np.testing.assert_allclose(np.array(out["internal_magnitude"]).ravel(), result.internal_magnitude, rtol=1e-10)
    assert math.isclose(float(out["internal_norm"]), result.internal_norm, rel_tol=1e-10)


@pytest.mark.parametrize("n_bodies", [5, 12])
def test_norms_gradient_matches_finite_differences(n_bodies) -> None:
    tree = scaled_tree(n_bodies)
    topology = tree.topology(active_contacts(tree, SCALING_SCENE))
    grad = norms_gradient_function(topology)
    lean = lean_impact_function(topology)
    p = design_vector(tree)
    v = approach_velocity(topology, SCALING_SCENE.speed)
    e = SCALING_SCENE.restitution
    out = grad(p=p, v_minus=v, restitution=e)
    h = 1e-6
    for name in ("external_norm", "internal_norm"):
        g = np.array(out[f"d_{name}"]).ravel()
        fd = [
            (
                float(lean(p=p + h * dp, v_minus=v, restitution=e)[name])
                - float(lean(p=p - h * dp, v_minus=v, restitution=e)[name])
            )
            / (2 * h)
            for dp in np.eye(p.size)
        ]
        np.testing.assert_allclose(g, fd, rtol=1e-5, atol=1e-7)


def test_bench_takes_the_gradient_wrt_every_value_of_a_tree_not_of_a_foot_layout() -> None:
    """No leg above a foot (a lone rod): no searched values to restrict to, so the timed gradient
    is the all-values one (and equals it)."""
    tree = Tree((Body("rod", None, 0.5, 1.0, -0.8, contacts=(1.0,)),))
    report = speed_report("rod", tree, SCALING_SCENE, batch=4, pinocchio=False, threads=1, rounds=1)
    assert report.n_gradient_values == report.n_values == 7
    assert report.gradient_equals_full and report.gradient_equals_autodiff


def test_scaled_tree_grows_toes_and_segments() -> None:
    small, large = scaled_tree(5), scaled_tree(50)
    assert small.n_bodies == 5 and large.n_bodies == 50
    assert len(large.contacts) > len(small.contacts)


def test_bench_rejects_bad_batch(leg_file, capsys) -> None:
    assert main(["bench", str(leg_file), "--batch", "0"]) == 2
    err = capsys.readouterr().err
    assert "--batch" in err and "Traceback" not in err


def test_bench_rejects_bad_sizes(capsys) -> None:
    assert main(["bench", "speed", "--sizes", "2,x"]) == 2
    err = capsys.readouterr().err
    assert "--sizes" in err and "Traceback" not in err


def test_bench_plot_draws_the_report(tmp_path, capsys) -> None:
    """--plot writes a PNG of the paths and the scaling series; a bad suffix is a usage error."""
    path = tmp_path / "speed.png"
    args = ["bench", "speed", "--batch", "4", "--no-compile", "--sizes", "5,8", "--plot", str(path)]
    assert main(args) == 0
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert main(["bench", "speed", "--sizes", "none", "--plot", str(tmp_path / "speed.pdf")]) == 2
    err = capsys.readouterr().err
    assert "--plot" in err and "Traceback" not in err
