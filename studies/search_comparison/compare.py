#!/usr/bin/env python3
"""Outer (Optuna) vs inner (IPOPT) search on the same study: front quality and wall time.

For each method the study runs from scratch in memory; the front is the feasible
non-dominated set in the study's first two objectives; its hypervolume is measured against one
reference point shared by all methods (1.1 x the worst front value of any method per
objective), so the numbers compare directly. Not a test: timings depend on the machine.

Usage (from the repository root):
    .venv/bin/python studies/search_comparison/compare.py [STUDY.yaml] [--trials 200 1000]
Writes comparison.json and comparison.png next to this script (for the default study).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import optuna

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from optimizer.search.inner import run_inner  # noqa: E402
from optimizer.results.pareto import hypervolume  # noqa: E402
from optimizer.results.runs import pareto_front, versions  # noqa: E402
from optimizer.search.outer import open_study, recorded_trials, run_outer  # noqa: E402
from optimizer.config.study_config import SamplerKind, SearchMethod, load_study  # noqa: E402

HERE = Path(__file__).resolve().parent


def run(config, label: str, trials: int | None) -> dict:
    study = open_study(config, optuna.storages.InMemoryStorage())
    started = time.perf_counter()
    if config.search.method is SearchMethod.INNER:
        run_inner(study, config)
    else:
        run_outer(study, config, trials)
    wall = time.perf_counter() - started
    recorded = list(recorded_trials(study))
    front = pareto_front(config, recorded)
    objs = config.objectives[:2]
    points = np.array([[t.evaluation.objectives.value(o) for o in objs] for t in front]).reshape(-1, len(objs))
    return {
        "method": label,
        "wall_time_s": round(wall, 2),
        "designs_evaluated": len(recorded),
        "feasible": sum(t.evaluation.feasible for t in recorded),
        "front": points.tolist(),
        "front_shapes": [t.evaluation.design.shape.label for t in front],
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("study", nargs="?", default=str(ROOT / "configs" / "quick_study.yaml"))
    parser.add_argument("--trials", type=int, nargs="+", default=[200, 1000])
    parser.add_argument("--out", default=str(HERE))
    args = parser.parse_args(argv)
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    base = load_study(args.study)
    results = [run(replace(base, search=replace(base.search, method=SearchMethod.INNER)), "inner (IPOPT)", None)]
    for sampler in (SamplerKind.TPE, SamplerKind.NSGA2):
        for n in args.trials:
            config = replace(base, search=replace(base.search, method=SearchMethod.OUTER, sampler=sampler))
            results.append(run(config, f"outer {sampler.value} {n}", n))
    every = np.vstack([np.array(r["front"]) for r in results if r["front"]])
    reference = every.max(axis=0) * 1.1
    for r in results:
        r["hypervolume"] = hypervolume(np.array(r["front"]).reshape(-1, len(reference)), reference) if r["front"] else 0.0
        r["best"] = np.array(r["front"]).min(axis=0).tolist() if r["front"] else None
    best_hv = max(r["hypervolume"] for r in results)
    print(f"study {base.name}: reference point {np.round(reference, 4).tolist()}")
    print(f"{'method':<18} {'time (s)':>9} {'designs':>8} {'front':>6} {'HV':>10} {'HV/best':>8}  best per objective")
    for r in results:
        print(
            f"{r['method']:<18} {r['wall_time_s']:>9.2f} {r['designs_evaluated']:>8} {len(r['front']):>6} "
            f"{r['hypervolume']:>10.5f} {r['hypervolume'] / best_hv:>8.3f}  {np.round(r['best'], 4).tolist() if r['best'] else '-'}"
        )
    out = Path(args.out)
    record = {
        "study": str(Path(args.study).resolve().relative_to(ROOT)) if Path(args.study).resolve().is_relative_to(ROOT) else args.study,
        "objectives": [o.value for o in base.objectives[:2]],
        "reference_point": reference.tolist(),
        "versions": versions(),
        "results": results,
    }
    (out / "comparison.json").write_text(json.dumps(record, indent=1) + "\n", encoding="utf-8")
    plot(out / "comparison.png", base, results)
    return 0


def plot(path: Path, config, results: list[dict]) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, 5.5))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    markers = "os^vD<>"
    for k, r in enumerate(results):
        if not r["front"]:
            continue
        f = np.array(sorted(r["front"]))
        ax.plot(f[:, 0], f[:, 1], marker=markers[k % len(markers)], lw=1, drawstyle="steps-post",
                label=f"{r['method']}: {r['wall_time_s']:.1f} s, HV {r['hypervolume']:.4f}")
    objs = config.objectives[:2]
    ax.set_xlabel(f"{objs[0].value} (N s)")
    ax.set_ylabel(f"{objs[1].value} (N s)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_title(f"study '{config.name}': fronts of the outer (Optuna) and inner (IPOPT) searches")
    ax.grid(True, alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    raise SystemExit(main())
