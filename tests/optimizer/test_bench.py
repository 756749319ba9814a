"""`footopt bench`: runs, prints the documented keys, and its batched path computes what the
single-call path computes (the timings themselves are not tested: benchmarks, not tests)."""

from __future__ import annotations

import json
import math

import numpy as np

from impulse_core.evaluate import active_contacts, approach_velocity, compiled_model, evaluate
from impulse_core.tree import design_vector
from optimizer.bench import speed_report
from optimizer.cli import main


def test_bench_json_keys_and_agreement(leg_file, capsys, tmp_path) -> None:
    assert main(["bench", str(leg_file), "--batch", "8", "--json", "--cache-dir", str(tmp_path)]) == 0
    record = json.loads(capsys.readouterr().out.strip())
    for key in ("us_per_design_batched", "pinocchio_us_per_call", "ratio", "n_instructions", "build_ms"):
        assert key in record
    assert record["batched_equals_single"] is True
    assert math.isclose(record["ratio"], record["us_per_design_batched"] / record["pinocchio_us_per_call"])


def test_benchmarked_function_is_what_evaluate_computes(leg_tree, leg_scene) -> None:
    """The function the benchmark times gives evaluate()'s impulses (no cheaper stand-in is timed)."""
    report = speed_report("leg", leg_tree, leg_scene, batch=4)
    assert report.batched_equals_single
    topology = leg_tree.topology(active_contacts(leg_tree, leg_scene))
    out = compiled_model(topology).impact(
        design_vector(leg_tree), approach_velocity(topology, leg_scene.speed), leg_scene.restitution
    )
    result = evaluate(leg_tree, leg_scene)
    np.testing.assert_allclose(np.array(out[0]).ravel(), result.external[list(result.active)], rtol=1e-12)


def test_bench_rejects_bad_batch(leg_file, capsys) -> None:
    assert main(["bench", str(leg_file), "--batch", "0"]) == 2
    err = capsys.readouterr().err
    assert "--batch" in err and "Traceback" not in err
