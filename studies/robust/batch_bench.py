"""One design over 1000 first-impact landings: batched (optimizer.evaluation.batched) against one
scenario at a time, in one run (issue #14's target: 1 ms on one core).

Run from the repository root: ``python studies/robust/batch_bench.py`` (writes batched.md here).
The design: the paper's case 3 with ``contacts: lowest``; the landings: the robust study's
distribution without its terrain step (speed, velocity_x, pitch, angular_velocity, restitution).
Best of 5 rounds; the two paths' objectives are checked equal, row by row, bit for bit.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

from impulse_core.model.tree import ContactSelection
from optimizer.config.model_file import load_model_file
from optimizer.config.study_config import load_study
from optimizer.evaluation.robust import evaluate_over_landings, scenario_objectives
from optimizer.evaluation.scenarios import Landings, model_data, scenario_model

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]


def main() -> None:
    config = load_study(REPO / "configs" / "robust_study.yaml")
    model = load_model_file(REPO / "configs" / "paper_case3.yaml")
    model = dataclasses.replace(model, scene=dataclasses.replace(model.scene, selection=ContactSelection.LOWEST))
    kept = tuple((n, d) for n, d in config.landings.distributions if n != "terrain_step")
    landings = Landings(count=1000, seed=7, distributions=kept)
    evaluate_over_landings(model, landings, config.statistic_of)  # build the mapped functions once
    batched = one_by_one = float("inf")
    for _ in range(5):
        t0 = time.perf_counter()
        robust = evaluate_over_landings(model, landings, config.statistic_of)
        batched = min(batched, time.perf_counter() - t0)
        t0 = time.perf_counter()
        data = model_data(model)
        single = [scenario_objectives(scenario_model(data, row.overrides)) for row in robust.rows]
        one_by_one = min(one_by_one, time.perf_counter() - t0)
    assert all(row.objectives == s for row, s in zip(robust.rows, single, strict=True))
    text = "\n".join([
        "# One design over 1000 first-impact landings (issue #14)",
        "",
        f"Produced by `python studies/robust/batch_bench.py` on {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, "
        "one process, best of 5 (what is timed: the script's docstring).",
        "",
        "| path | 1000 landings [ms] | per landing [us] |",
        "|---|---|---|",
        f"| batched (CasADi map of the impact function, grouped by contact set) | {1e3 * batched:.1f} | {1e3 * batched:.1f} |",
        f"| one scenario at a time (as before) | {1e3 * one_by_one:.1f} | {1e3 * one_by_one:.1f} |",
        "",
        f"Batched / one at a time: {batched / one_by_one:.3f}; the objectives are equal bit for bit. The target",
        "(1 ms per 1000 landings) is not met: the map runs on CasADi's virtual machine and each",
        "scenario's overrides (the rows of scenarios.csv) are still built in Python.",
        "",
    ])
    (HERE / "batched.md").write_text(text, encoding="utf-8")
    print(text)


if __name__ == "__main__":
    main()
