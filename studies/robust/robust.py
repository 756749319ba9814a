"""Nominal-optimal against robust-optimal feet, out of sample (issue #14).

Runs `nominal.yaml` (the feet scored on the one nominal landing) and `robust.yaml` (the same
feet scored over 32 landings: cvar:0.9 of external_norm, mean of internal_norm) unless their run
folders are there, picks each front's design with the least external_norm (its statistic), and
lands both on FRESH landings from the same distribution (another seed; 10,000 by default).
Writes `out_of_sample.csv` (every landing's objectives for both), `cdf.png`, `results.md`.

Usage: python studies/robust/robust.py [--landings N] [--rerun]
"""

from __future__ import annotations

import argparse
import csv
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from optimizer.config.study_config import StudyConfig, load_study
from optimizer.design_space import FootDesign, Objective, design_model
from optimizer.evaluation.robust import evaluate_over_landings
from optimizer.evaluation.statistics import Statistic, StatisticKind
from optimizer.results.runs import pareto_front, storage_url
from optimizer.search.outer import finished_trials, open_study, recorded_trials

HERE = Path(__file__).resolve().parent
OBJECTIVES = (Objective.EXTERNAL_NORM, Objective.INTERNAL_NORM)
STATISTICS = {"mean": Statistic(), "std": Statistic(StatisticKind.STD), "q90": Statistic(StatisticKind.QUANTILE, 0.9),
              "cvar90": Statistic(StatisticKind.CVAR, 0.9), "max": Statistic(StatisticKind.MAX)}
FRESH_SEED = 2026


def best_design(name: str, rerun: bool) -> tuple[StudyConfig, FootDesign, int]:
    """The study's front design with the least external_norm (statistic), running it if needed."""
    config = load_study(HERE / f"{name}.yaml")
    run_dir = HERE / f"run_{name}"
    study = open_study(config, storage_url(run_dir, config)) if run_dir.exists() else None
    inner_done = study is not None and config.search.method.value == "inner"
    if rerun or study is None or not inner_done and finished_trials(study) < config.search.trials:
        command = [sys.executable, "-m", "optimizer", "optimize", str(HERE / f"{name}.yaml"), "--out", str(run_dir)]
        subprocess.run(command + (["--force"] if rerun else []), check=True)
        study = open_study(config, storage_url(run_dir, config))
    front = pareto_front(config, list(recorded_trials(study)))
    best = min(front, key=lambda t: t.evaluation.objectives.value(Objective.EXTERNAL_NORM))
    return config, best.evaluation.design, best.number


def out_of_sample(config: StudyConfig, design: FootDesign, count: int) -> np.ndarray:
    """The design on ``count`` fresh landings of ``robust.yaml``'s distribution: landings x objectives."""
    landings = replace(config.landings, count=count, seed=FRESH_SEED)
    model = design_model(config.leg, design, config.scene, config.limits)
    robust = evaluate_over_landings(model, landings, config.statistic_of)
    rows = [[r.objectives.value(o) if r.objectives else np.nan for o in OBJECTIVES] for r in robust.rows]
    return np.array(rows)


def describe(design: FootDesign) -> str:
    toe, heel = design.toes[0], design.heel[0]
    angles = ", ".join(f"{s.joint_angle:.2f}" for s in toe)
    masses = ", ".join(f"{s.mass:.3f}" for s in toe)
    return (f"{design.shape.label}: heel {heel.mass:.3f} kg at {heel.joint_angle:.2f} rad; each toe's rods "
            f"{masses} kg at {angles} rad")


def write_landings(values: dict[str, np.ndarray], names: list[str], path: Path) -> None:
    """Every fresh landing's objectives, one row per (design, landing); designs as ``names``."""
    with path.open("w", newline="", encoding="utf-8") as f:
        writer = csv.writer(f, lineterminator="\n")
        writer.writerow(["design", "landing", *(o.value for o in OBJECTIVES)])
        for name, v in zip(names, values.values(), strict=True):
            writer.writerows([name, k, *map(repr, row)] for k, row in enumerate(v.tolist()))


def statistics_table(values: dict[str, np.ndarray]) -> list[str]:
    """A markdown table: each design's statistics of each objective over its landings."""
    lines = ["| design | objective | " + " | ".join(STATISTICS) + " | failed |", "|---" * (len(STATISTICS) + 3) + "|"]
    for label, v in values.items():
        for j, objective in enumerate(OBJECTIVES):
            ok = v[:, j][np.isfinite(v[:, j])]
            cells = " | ".join(f"{s.of(ok):.4f}" for s in STATISTICS.values())
            lines.append(f"| {label} | {objective.value} | {cells} | {v.shape[0] - ok.size} |")
    return lines


def plot_cdf(values: dict[str, np.ndarray], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for ax, (j, objective) in zip(axes, enumerate(OBJECTIVES), strict=True):
        for label, v in values.items():
            x = np.sort(v[:, j][np.isfinite(v[:, j])])
            ax.plot(x, np.arange(1, x.size + 1) / x.size, label=label)
        ax.set_xlabel(f"{objective.value} (N s)")
        ax.set_ylabel("fraction of landings at or below")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(f"{len(next(iter(values.values())))} fresh landings (seed {FRESH_SEED})")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--landings", type=int, default=10_000, help="fresh landings per design")
    parser.add_argument("--rerun", action="store_true", help="run both studies again from scratch")
    args = parser.parse_args()
    robust_config, robust_design, robust_trial = best_design("robust", args.rerun)
    _, nominal_design, nominal_trial = best_design("nominal", args.rerun)
    values = {
        f"nominal-optimal (trial {nominal_trial})": out_of_sample(robust_config, nominal_design, args.landings),
        f"robust-optimal (trial {robust_trial})": out_of_sample(robust_config, robust_design, args.landings),
    }
    write_landings(values, [label.split(" ")[0] for label in values], HERE / "out_of_sample.csv")
    plot_cdf(values, HERE / "cdf.png")
    lines = statistics_table(values)
    in_sample = []
    for label, design in (("nominal-optimal", nominal_design), ("robust-optimal", robust_design)):
        model = design_model(robust_config.leg, design, robust_config.scene, robust_config.limits)
        stats = evaluate_over_landings(model, robust_config.landings, robust_config.statistic_of).statistics
        in_sample.append(f"- {label} on the study's own {robust_config.landings.count} landings: cvar:0.9 of "
                         f"external_norm {stats.external_norm:.4f}, mean internal_norm {stats.internal_norm:.4f}")
    text = (
        "\n".join(lines) + "\n\n" + "\n".join(in_sample) + "\n\n"
        + f"- nominal-optimal: {describe(nominal_design)}\n- robust-optimal: {describe(robust_design)}\n"
    )
    (HERE / "results.md").write_text(text, encoding="utf-8")
    print(text)


if __name__ == "__main__":
    main()
