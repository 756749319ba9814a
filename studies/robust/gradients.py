"""Robust design with the statistics' gradients: the inner search over landings against the
outer (TPE) search and the nominal optimum, out of sample (issue #14 item 2).

Runs `robust_inner.yaml` (IPOPT per shape, exact gradients of cvar:0.9 and the mean over 32
level landings), `robust_outer.yaml` (the same landings and statistics, TPE, 200 trials) and
`nominal.yaml` (the one nominal landing) unless their run folders are there, timing each run,
picks each front's design with the least external_norm statistic, and lands the three on FRESH
landings of `robust_inner.yaml`'s distribution (another seed; 10,000 by default).
Writes `gradients.csv` (every fresh landing), `cdf_gradients.png`, `gradients.md`.

Usage: python studies/robust/gradients.py [--landings N] [--rerun]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from robust import HERE, best_design, describe, out_of_sample, plot_cdf, statistics_table, write_landings

from optimizer.config.study_config import load_study
from optimizer.design_space import design_model
from optimizer.evaluation.robust import evaluate_over_landings

STUDIES = {"robust_inner": "robust-inner (IPOPT, gradients)", "robust_outer": "robust-outer (TPE, 200 trials)",
           "nominal": "nominal-optimal"}
TIMES = HERE / "gradients_times.json"


def timed_best(name: str, rerun: bool, times: dict[str, float]):
    """``best_design`` of a study, with the wall time of its run when it runs now."""
    fresh = rerun or not (HERE / f"run_{name}").exists()
    start = time.perf_counter()
    found = best_design(name, rerun)
    if fresh:
        times[name] = time.perf_counter() - start
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--landings", type=int, default=10_000, help="fresh landings per design")
    parser.add_argument("--rerun", action="store_true", help="run the studies again from scratch")
    args = parser.parse_args()
    times = json.loads(TIMES.read_text()) if TIMES.exists() else {}
    winners = {name: timed_best(name, args.rerun, times) for name in STUDIES}
    TIMES.write_text(json.dumps(times, indent=1) + "\n")
    config = load_study(HERE / "robust_inner.yaml")
    values = {f"{STUDIES[n]} (trial {t})": out_of_sample(config, d, args.landings) for n, (_, d, t) in winners.items()}
    write_landings(values, list(STUDIES), HERE / "gradients.csv")
    plot_cdf(values, HERE / "cdf_gradients.png")
    lines = statistics_table(values)
    notes = []
    for name, (_, design, _) in winners.items():
        model = design_model(config.leg, design, config.scene, config.limits)
        stats = evaluate_over_landings(model, config.landings, config.statistic_of).statistics
        run = f", run {times[name]:.0f} s" if name in times else ""
        notes.append(f"- {STUDIES[name]}{run}: on the study's own {config.landings.count} landings cvar:0.9 of "
                     f"external_norm {stats.external_norm:.4f}, mean internal_norm {stats.internal_norm:.4f}; "
                     f"{describe(design)}")
    text = "\n".join(lines) + "\n\n" + "\n".join(notes) + "\n"
    (HERE / "gradients.md").write_text(text, encoding="utf-8")
    print(text)


if __name__ == "__main__":
    main()
