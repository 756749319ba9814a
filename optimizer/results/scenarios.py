"""A robust study's per-scenario files: ``scenarios.csv`` (one row per front design and scenario)
and ``scenarios.png`` (each front design's distribution of each objective over the scenarios).

A row's ``overrides`` applied to the design's model file (``designs/<design>.yaml``) and
evaluated by ``footopt evaluate`` give that row's objectives exactly; the front files' objective
values are the study's statistics of these columns.
"""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

from optimizer.config.study_config import StudyConfig
from optimizer.design_space import FootDesign, Objective, design_model, study_landing
from optimizer.evaluation.robust import RobustEvaluation, evaluate_over_landings

SCENARIOS_FILE, SCENARIOS_PLOT = "scenarios.csv", "scenarios.png"


def front_scenarios(config: StudyConfig, designs: list[tuple[str, FootDesign]]) -> list[tuple[str, RobustEvaluation]]:
    """Each front design (id, design) over the study's landings."""
    assert config.landings is not None
    out = []
    for design_id, design in designs:
        model = design_model(config.leg, design, config.scene, config.limits, config.space.joint_laws.stop_restitution)
        out.append((design_id, evaluate_over_landings(model, config.landings, config.statistic_of,
                                                      study_landing(config.search.landing_tolerance))))
    return out


def scenarios_csv(columns: tuple[str, ...], evaluated: list[tuple[str, RobustEvaluation]]) -> str:
    """``scenarios.csv``: design, scenario, overrides (a JSON object), one column per objective
    (empty where the scenario failed)."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(["design", "scenario", "overrides", *columns])
    for design_id, robust in evaluated:
        for row in robust.rows:
            o = row.objectives
            values = ["" if o is None else repr(o.value(Objective(c))) for c in columns]
            writer.writerow([design_id, row.scenario, json.dumps(row.overrides, separators=(",", ":")), *values])
    return buffer.getvalue()


def plot_scenarios(path: Path, config: StudyConfig, evaluated: list[tuple[str, RobustEvaluation]]) -> Path:
    """One box plot per study objective: each front design's values over the scenarios."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    objectives = config.objectives
    fig, axes = plt.subplots(len(objectives), 1, figsize=(max(6.0, 0.5 * len(evaluated) + 3), 3.2 * len(objectives)),
                             squeeze=False)
    labels = [design_id.removeprefix("trial_") for design_id, _ in evaluated]
    for ax, objective in zip(axes[:, 0], objectives, strict=True):
        data = [[r.objectives.value(objective) for r in robust.rows if r.objectives is not None] for _, robust in evaluated]
        ax.boxplot(data, tick_labels=labels, whis=(0, 100))
        ax.set_ylabel(f"{objective.value}\n({config.statistic_of(objective).text} in the front)")
        ax.grid(True, axis="y", alpha=0.3)
    axes[-1, 0].set_xlabel("Pareto design (trial); boxes: quartiles, whiskers: min and max over the landings")
    axes[0, 0].set_title(f"study '{config.name}': {config.landings.count if config.landings else 0} landings per design")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def write_scenarios(run_dir: Path, config: StudyConfig, columns: tuple[str, ...],
                    designs: list[tuple[str, FootDesign]]) -> None:
    """Write ``scenarios.csv`` and ``scenarios.png`` for the front's designs."""
    evaluated = front_scenarios(config, designs)
    (run_dir / SCENARIOS_FILE).write_text(scenarios_csv(columns, evaluated), encoding="utf-8")
    if evaluated:
        plot_scenarios(run_dir / SCENARIOS_PLOT, config, evaluated)


__all__ = ["SCENARIOS_FILE", "SCENARIOS_PLOT", "front_scenarios", "plot_scenarios", "scenarios_csv", "write_scenarios"]
