#!/usr/bin/env python3
"""Which values the landing impulse norms depend on: exact derivatives (CasADi AD through the
impulse core) at two feet of ``study.yaml``, a finite check of the length result, and the
budget-neutral mass derivatives (where to move mass).

Designs:
  A. the paper's case-3 masses (heel 0.1 kg; three toes of 0.0889 + 0.0444 kg) at plausible
     angles (heel joint -0.9 rad, toe root 1.2 rad, toe middle joint 0.25 rad);
  B. the inner search's foot of least external_norm for the study (three toes of two rods).

Writes sensitivity.csv, sensitivity.json and sensitivity.png next to this script.
Usage (from the repository root): .venv/bin/python studies/sensitivity/sensitivity.py
"""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import numpy as np
import optuna

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from optimizer.design_space import FootDesign, Segment, design_from, evaluate_design  # noqa: E402
from optimizer.search.inner import run_inner  # noqa: E402
from optimizer.search.outer import open_study, recorded_trials  # noqa: E402
from optimizer.analysis.sensitivity import QUANTITIES, sensitivities  # noqa: E402
from optimizer.config.study_config import load_study  # noqa: E402

HERE = Path(__file__).resolve().parent
#: A value's "step" for the change columns: 10 % of a length, mass or fraction; 0.1 rad of an angle.
REL_STEP, ANGLE_STEP = 0.1, 0.1


def design_a(config) -> FootDesign:
    angles = ((-0.9,), *[(1.2, 0.25)] * 3)
    masses = ((0.1,), *[(0.2667 / 3, 0.1333 / 3)] * 3)
    return design_from(config.leg, angles, masses, config.limits)


def design_b(config) -> FootDesign:
    study = open_study(config, optuna.storages.InMemoryStorage())
    run_inner(study, config)
    feasible = [t.evaluation for t in recorded_trials(study) if t.evaluation.feasible]
    return min(feasible, key=lambda e: e.objectives.external_norm).design


def kind(name: str) -> str:
    field = name.split(".", 1)[1]
    return "contact" if field.startswith("contacts") else field


def step(name: str, value: float) -> float:
    return ANGLE_STEP if kind(name) == "angle" else REL_STEP * abs(value)


def length_scaling_check(config, design: FootDesign, rng: np.random.Generator) -> float:
    """Largest relative change of any objective when every foot rod is scaled by a random
    factor in [0.25, 4] at fixed angles and masses."""
    base = evaluate_design(config.leg, design, config.scene, config.limits).objectives
    chains = [tuple(Segment(s.length * rng.uniform(0.25, 4.0), s.mass, s.joint_angle) for s in c) for c in design.chains]
    scaled = FootDesign(heel=chains[0], toes=tuple(chains[1:]))
    other = evaluate_design(config.leg, scaled, config.scene, config.limits).objectives
    return max(abs(getattr(other, k) - getattr(base, k)) / abs(getattr(base, k)) for k in vars(base))


def main() -> int:
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    config = load_study(HERE / "study.yaml")
    designs = {"A (paper case-3 masses)": design_a(config), "B (least external_norm)": design_b(config)}
    rng = np.random.default_rng(config.seed)
    record: dict = {"study": "studies/sensitivity/study.yaml", "designs": {}}
    rows = []
    for label, design in designs.items():
        ev = evaluate_design(config.leg, design, config.scene, config.limits)
        assert ev.feasible, label
        s = sensitivities(config.leg, design, config.scene)
        check = length_scaling_check(config, design, rng)
        masses = {r: m for r, m in zip(s.foot_rods, (seg.mass for seg in design.segments), strict=True)}
        record["designs"][label] = {
            "objectives": vars(ev.objectives),
            "foot_rod_masses": masses,
            "length_scaling_max_relative_change": check,
            "budget_neutral_mass_derivative": {
                q: dict(zip(s.foot_rods, (float(x) for x in s.budget_neutral_mass[i]), strict=True))
                for i, q in enumerate(QUANTITIES)
            },
        }
        for j, name in enumerate(s.names):
            h = step(name, s.values[j])
            row = {"design": label, "value": name, "kind": kind(name), "at": float(s.values[j])}
            for i, q in enumerate(QUANTITIES):
                row[f"d_{q}"] = float(s.derivatives[i, j])
                row[f"change_{q}"] = float(s.derivatives[i, j] * h)
            rows.append(row)
    with (HERE / "sensitivity.csv").open("w", encoding="utf-8", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]), lineterminator="\n")
        writer.writeheader()
        for r in rows:
            writer.writerow({k: (f"{v:.6e}" if isinstance(v, float) else v) for k, v in r.items()})
    # Summary: the largest |change| per kind of value, per design and norm.
    summary: dict = {}
    for label in designs:
        summary[label] = {}
        for q in ("external_norm", "internal_norm"):
            by_kind: dict[str, float] = {}
            for r in rows:
                if r["design"] == label:
                    by_kind[r["kind"]] = max(by_kind.get(r["kind"], 0.0), abs(r[f"change_{q}"]))
            summary[label][q] = by_kind
    record["largest_change_by_kind"] = summary
    record["steps"] = {"lengths_masses_fractions": f"{REL_STEP:.0%} of the value", "angles": f"{ANGLE_STEP} rad"}
    (HERE / "sensitivity.json").write_text(json.dumps(record, indent=1) + "\n", encoding="utf-8")
    plot(HERE / "sensitivity.png", rows, list(designs))
    for label in designs:
        print(label)
        for q in ("external_norm", "internal_norm"):
            parts = ", ".join(f"{k} {v:.2e}" for k, v in sorted(summary[label][q].items(), key=lambda kv: -kv[1]))
            print(f"  largest |change of {q}| by kind (N s): {parts}")
        d = record["designs"][label]
        print(f"  length scaling check: max relative change {d['length_scaling_max_relative_change']:.1e}")
        bn = d["budget_neutral_mass_derivative"]["external_norm"]
        print("  d external_norm / d mass, budget-neutral (N s/kg):", {k: round(v, 3) for k, v in bn.items()})
    return 0


def plot(path: Path, rows: list[dict], labels: list[str]) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(12, 9))
    FigureCanvasAgg(fig)
    floor = 1e-19
    colours = {"length": "#c0392b", "mass": "#2e86c1", "angle": "#28b463", "com": "#aaaaaa", "gyration": "#888888",
               "at": "#cccccc", "contact": "#666666"}
    for k, label in enumerate(labels):
        ax = fig.add_subplot(1, len(labels), k + 1)
        sel = [r for r in rows if r["design"] == label and r["kind"] in ("length", "mass", "angle")]
        names = [r["value"] for r in sel]
        y = np.arange(len(sel))
        ext = np.maximum([abs(r["change_external_norm"]) for r in sel], floor)
        inn = np.maximum([abs(r["change_internal_norm"]) for r in sel], floor)
        ax.barh(y - 0.2, ext, height=0.4, color=[colours[r["kind"]] for r in sel], label="external_norm")
        ax.barh(y + 0.2, inn, height=0.4, color=[colours[r["kind"]] for r in sel], alpha=0.45, label="internal_norm")
        ax.set_xscale("log")
        ax.set_xlim(floor, 1.0)
        ax.set_yticks(y)
        ax.set_yticklabels(names, fontsize=7)
        ax.invert_yaxis()
        ax.axvline(1e-12, color="black", lw=0.8, ls="--")
        ax.text(1.3e-12, len(sel) - 0.5, "rounding", fontsize=7)
        ax.set_xlabel("|change of norm| (N s) for +10 % length/mass or +0.1 rad angle\n(solid: external, pale: internal)",
                      fontsize=8)
        ax.set_title(label, fontsize=10)
        ax.grid(True, axis="x", alpha=0.3)
    fig.suptitle("Exact sensitivities of the impulse norms: lengths (red) are zero, masses (blue) and angles (green) are not")
    fig.tight_layout()
    fig.savefig(path, dpi=100)


if __name__ == "__main__":
    raise SystemExit(main())
