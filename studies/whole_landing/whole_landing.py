"""Does scoring the whole landing change which foot is best? (issue #13)

Runs the whole-landing study `study.yaml` (unless `run/` already holds it), then reads every
evaluated design from its storage. Each trial landed in full, so each carries both scores: the
first impact's (`external_norm`, what footopt scored before) and the landing's
(`peak_external_norm`, the largest external impulse norm of any impact until the end). Writes
`trials.csv`, `scores.png` (one score against the other), `first_impact_best.png` and
`landing_best.png` (the two winners' landings) and `results.md`.

Usage: python studies/whole_landing/whole_landing.py [--rerun]
"""

from __future__ import annotations

import argparse
import csv
import subprocess
import sys
from pathlib import Path

import numpy as np
from scipy.stats import spearmanr

from impulse_core.timedomain.landing import LandingSettings, landing
from optimizer.config.study_config import StudyConfig, load_study
from optimizer.design_space import DesignEvaluation, foot_geometry, foot_joint_laws, foot_tree, landing_scene
from optimizer.report.landing_plot import plot_landing
from optimizer.results.runs import storage_url
from optimizer.search.outer import finished_trials, open_study, recorded_trials

HERE = Path(__file__).resolve().parent
SCORES = ("external_norm", "peak_external_norm", "peak_internal_norm", "energy_absorbed", "settled_at")


def run_study(config: StudyConfig, run_dir: Path, rerun: bool) -> None:
    """The study's trials in ``run_dir`` (resumed or run by the CLI, with its progress bar)."""
    study = open_study(config, storage_url(run_dir, config)) if run_dir.exists() else None
    if not rerun and study is not None and finished_trials(study) >= config.search.trials:
        return
    command = [sys.executable, "-m", "optimizer", "optimize", str(HERE / "study.yaml"), "--out", str(run_dir)]
    subprocess.run(command + (["--force"] if rerun else []), check=True)


def describe(config: StudyConfig, number: int, ev: DesignEvaluation) -> dict[str, object]:
    """One trial as a row: its scores, shape, reach and joint laws."""
    o, d = ev.objectives, ev.design
    assert o is not None
    root = d.toes[0][0]
    return {
        "trial": number,
        "shape": d.shape.label,
        **{name: getattr(o, name) for name in SCORES},
        "reach": float(foot_geometry(config.leg, d).reaches.mean()),
        "toe_root.stiffness": root.stiffness,
        "toe_root.damping": root.damping,
        "toe_root.stop": root.stop,
        "heel.stiffness": d.heel[0].stiffness,
        "heel.stop": d.heel[0].stop,
    }


def draw(config: StudyConfig, ev: DesignEvaluation, path: Path, title: str) -> None:
    """The design's landing, impulses over time and the leg at each impact."""
    tree = foot_tree(config.leg, ev.design)
    scene = landing_scene(config.scene, config.limits)
    laws = foot_joint_laws(config.leg, ev.design, config.space.joint_laws.stop_restitution)
    result = landing(tree, scene, laws, LandingSettings(tolerance=config.search.landing_tolerance))
    plot_landing(tree, result, path, title, scene)


def plot_scores(rows: list[dict[str, object]], picks: dict[str, dict[str, object]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    x = [float(r["external_norm"]) for r in rows]
    y = [float(r["peak_external_norm"]) for r in rows]
    ax.scatter(x, y, s=12, color="#888888", label="feasible designs (each landed in full)")
    lim = [min(x + y), max(x + y)]
    ax.plot(lim, lim, color="black", lw=0.7, label="peak = first impact")
    for (label, row), color in zip(picks.items(), ("tab:red", "tab:blue"), strict=True):
        ax.scatter([row["external_norm"]], [row["peak_external_norm"]], s=70, color=color, edgecolor="black",
                   label=f"{label} (trial {row['trial']})", zorder=3)
    ax.set_xscale("log")
    ax.set_yscale("log")
    from matplotlib.ticker import NullFormatter

    for axis in (ax.xaxis, ax.yaxis):
        axis.set_minor_formatter(NullFormatter())
    ax.set_xlabel("first impact: external_norm (N s)")
    ax.set_ylabel("whole landing: peak_external_norm (N s)")
    ax.set_title("The first instant vs the whole landing")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_csv(rows: list[dict[str, object]], path: Path) -> None:
    with path.open("w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]), lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)


def table(picks: dict[str, dict[str, object]]) -> str:
    keys = ["trial", "shape", *SCORES, "reach", "toe_root.stiffness", "toe_root.damping", "toe_root.stop"]
    lines = ["| | " + " | ".join(keys) + " |", "|---" * (len(keys) + 1) + "|"]
    for label, row in picks.items():
        cells = [f"{row[k]:.4g}" if isinstance(row[k], float) else str(row[k]) for k in keys]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rerun", action="store_true", help="run the study again from scratch")
    args = parser.parse_args()
    config = load_study(HERE / "study.yaml")
    run_dir = HERE / "run"
    run_study(config, run_dir, args.rerun)
    study = open_study(config, storage_url(run_dir, config))
    trials = list(recorded_trials(study))
    feasible = [t for t in trials if t.evaluation.feasible]
    rows = [describe(config, t.number, t.evaluation) for t in feasible]
    write_csv(rows, HERE / "trials.csv")
    first = min(rows, key=lambda r: float(r["external_norm"]))
    best = min(rows, key=lambda r: float(r["peak_external_norm"]))
    picks = {"best first impact": first, "best whole landing": best}
    plot_scores(rows, picks, HERE / "scores.png")
    by_number = {t.number: t.evaluation for t in feasible}
    draw(config, by_number[int(first["trial"])], HERE / "first_impact_best.png", "best by the first impact")
    draw(config, by_number[int(best["trial"])], HERE / "landing_best.png", "best by the whole landing")
    ext = np.array([float(r["external_norm"]) for r in rows])
    peak = np.array([float(r["peak_external_norm"]) for r in rows])
    rho = spearmanr(ext, peak).statistic
    later = int(np.sum(peak > ext * (1 + 1e-9)))
    from optuna.trial import TrialState

    failed = len(study.get_trials(deepcopy=False, states=(TrialState.FAIL,)))
    summary = (
        f"{len(trials) + failed} designs tried: {len(trials)} landed, {len(feasible)} of them feasible; "
        f"{failed} landings failed numerically (trials FAIL).\n"
        f"Spearman rank correlation of external_norm and peak_external_norm over the feasible designs: {rho:.3f}.\n"
        f"Designs whose largest impact comes after touchdown: {later} of {len(rows)}.\n"
        f"The first-impact winner's peak over the landing: {float(first['peak_external_norm']) / float(best['peak_external_norm']):.2f} x the landing winner's.\n\n"
        + table(picks)
        + "\n"
    )
    (HERE / "results.md").write_text(summary, encoding="utf-8")
    print(summary)


if __name__ == "__main__":
    main()
