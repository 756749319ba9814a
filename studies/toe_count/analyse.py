#!/usr/bin/env python3
"""Read the toe-count study's run and answer its questions per foot shape: the best external
and internal norms, where the mass went (proximal or distal), and where more toes stop paying.

Usage (from the repository root), after the study ran:
    .venv/bin/footopt optimize studies/toe_count/study.yaml --out studies/toe_count/run
    .venv/bin/python studies/toe_count/analyse.py
Writes shapes.csv and toe_count.png next to this script.
"""

from __future__ import annotations

import csv
import sys
from collections import defaultdict
from pathlib import Path

import optuna

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from optimizer.results.runs import storage_url  # noqa: E402
from optimizer.search.outer import open_study, recorded_trials  # noqa: E402
from optimizer.config.study_config import load_study  # noqa: E402

HERE = Path(__file__).resolve().parent


def main() -> int:
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    run = HERE / "run"
    config = load_study(run / "study.yaml")
    study = open_study(config, storage_url(run, config))
    by_shape = defaultdict(list)
    for t in recorded_trials(study):
        if t.evaluation.feasible:
            by_shape[t.evaluation.design.shape].append(t.evaluation)
    rows = []
    for shape in sorted(by_shape):
        evs = by_shape[shape]
        best_ext = min(evs, key=lambda e: e.objectives.external_norm)
        best_int = min(evs, key=lambda e: e.objectives.internal_norm)
        d = best_ext.design
        toe = [s.mass for s in d.toes[0]]
        rows.append(
            {
                "shape": shape.label,
                "toes": shape.n_toes,
                "toe_segments": shape.toe_segments,
                "designs": len(evs),
                "best_external_norm": best_ext.objectives.external_norm,
                "best_internal_norm": best_int.objectives.internal_norm,
                "energy_after_at_best_external": best_ext.objectives.energy_after,
                "heel_mass": d.heel[0].mass,
                "toe_mass_each": sum(toe),
                "proximal_share_of_toe_mass": toe[0] / sum(toe),
                "distal_rod_mass": toe[-1],
                "heel_joint_angle": d.heel[0].joint_angle,
                "toe_root_joint_angle": d.toes[0][0].joint_angle,
            }
        )
    with (HERE / "shapes.csv").open("w", encoding="utf-8", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]), lineterminator="\n")
        writer.writeheader()
        for r in rows:
            writer.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})
    print(f"{'shape':>6} {'best ext':>9} {'best int':>9} {'heel kg':>8} {'toe kg':>7} {'proximal':>8} {'distal kg':>9}")
    for r in rows:
        print(
            f"{r['shape']:>6} {r['best_external_norm']:>9.4f} {r['best_internal_norm']:>9.4f} {r['heel_mass']:>8.3f} "
            f"{r['toe_mass_each']:>7.3f} {r['proximal_share_of_toe_mass']:>8.2f} {r['distal_rod_mass']:>9.3f}"
        )
    plot(HERE / "toe_count.png", rows)
    return 0


def plot(path: Path, rows: list[dict]) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11, 4.5))
    FigureCanvasAgg(fig)
    for k, (key, title) in enumerate(
        (("best_external_norm", "least external_norm per shape"), ("best_internal_norm", "least internal_norm per shape"))
    ):
        ax = fig.add_subplot(1, 2, k + 1)
        for segments in sorted({r["toe_segments"] for r in rows}):
            sel = [r for r in rows if r["toe_segments"] == segments]
            ax.plot([r["toes"] for r in sel], [r[key] for r in sel], marker="o", label=f"{segments} rod(s) per toe")
        ax.set_yscale("log")
        ax.set_xlabel("toe count (identical toes, 0.5 kg foot)")
        ax.set_ylabel(f"{key.removeprefix('best_')} (N s)")
        ax.set_title(title, fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("Toe count study (inner search, IPOPT per shape): one-rod toes gain from more toes, jointed toes do not")
    fig.tight_layout()
    fig.savefig(path, dpi=100)


if __name__ == "__main__":
    raise SystemExit(main())
