"""Whole landings in space of the best planar and the best splayed foot (issue #15 item 5's open question).

run.py's part 1 scores the two feet on first impacts only. Here the same seeded landings
(run.py's ``opt_landings``: the first ``PER_GROUP`` of each group, pitched, rolled and both) are
followed as whole landings in space (``impulse_core.timedomain.landing``, the planar foot read as
spatial), restitution 0.8, friction 0.5, gravity 9.81, for ``DURATION`` s from the first touchdown.

The designs have no joint laws, and with free joints the foot collapses (the toes spin up to
~200 rad/s within 0.05 s and a heel impact gains energy): both feet get the same laws, ``LAWS``:
the knee of studies/whole_landing (150 N m/rad, 3 N m s/rad, stops [-2, 0] rad), and at the foot
the middles of that study's search ranges (ankle joints 20 N m/rad, 0.5 N m s/rad, stops 0.45 rad
either side of the touchdown angle; joints inside a toe 10 N m/rad, 0.25 N m s/rad, no stops).

Speed: ``LandingSettings(tolerance=TOLERANCE, bounce_steps=BOUNCE_STEPS)``; bounce_steps makes a
rebound shorter than a quarter step plastic (the light heel's chatter: fewer, not the contract's,
events; the first event and the peaks are unchanged to ~1e-4 on the landings tried).

Writes whole_landing.csv, whole_landing.png and section 3 of results.md (replacing it if there).
Run from the repository root: ``python studies/splayed_toes/whole_landing.py``.
"""

from __future__ import annotations

import csv
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

from impulse_core.kinematics.spatial import SPATIAL
from impulse_core.model.joints import FREE, JointLaw
from impulse_core.model.tree import Body, ContactSelection, Scene, Tree
from impulse_core.timedomain.landing import LandingResult, LandingSettings, landing

sys.path.insert(0, str(Path(__file__).resolve().parent))
from run import GROUPS, GROUP_SIZE, HERE, OPT_SEED, best_of, land, opt_landings  # noqa: E402

PER_GROUP = 6
DURATION = 0.03  # s: toes land by ~0.013 s, the heel's stop by ~0.018 s (measured on landings 0 and 150)
TOLERANCE = 1e-2
BOUNCE_STEPS = 0.25
FIGURES = ("peak_external_norm", "peak_internal_norm", "peak_max_internal")
SECTION = "## 3. Whole landings in space"


def law(body: Body) -> JointLaw:
    """The joint law both feet get (module docstring), by the body's role."""
    if body.parent is None:
        return FREE
    if body.name == "shank":
        return JointLaw(150.0, 3.0, None, (-2.0, 0.0))
    if body.name.endswith("_distal"):
        return JointLaw(10.0, 0.25)
    return JointLaw(20.0, 0.5, None, (body.angle - 0.45, body.angle + 0.45))


def whole(tree: Tree, case: dict) -> LandingResult:
    """``case``'s landing of ``tree`` as run.py's ``land`` draws it, followed for DURATION s."""
    base = tree.bodies[0]
    turned = Tree((dataclasses.replace(base, angle=base.angle + case["pitch"], rpy=(case["roll"], 0.0, 0.0)),)
                  + tree.bodies[1:])
    scene = Scene(speed=case["speed"], restitution=0.8, friction=0.5, velocity_z=case["velocity_z"],
                  angular_velocity_x=case["roll_rate"], selection=ContactSelection.LOWEST, gravity=9.81,
                  duration=DURATION)
    settings = LandingSettings(tolerance=TOLERANCE, bounce_steps=BOUNCE_STEPS)
    return landing(turned, scene, tuple(law(b) for b in tree.bodies), settings, space=SPATIAL)


def chosen() -> list[tuple[int, dict]]:
    """(run.py's landing number, landing): the first PER_GROUP of each group."""
    cases = opt_landings(np.random.default_rng(OPT_SEED))
    return [(g * GROUP_SIZE + k, cases[g * GROUP_SIZE + k]) for g in range(len(GROUPS)) for k in range(PER_GROUP)]


def run() -> tuple[list[dict], float]:
    feet = {name: best_of(HERE / f"run_{name}")[1] for name in ("planar", "splayed")}
    rows, t0 = [], time.perf_counter()
    for number, case in chosen():
        row = {"landing": number, **case}
        for name, tree in feet.items():
            r = whole(tree, case)
            first = land(tree, case)
            row |= {
                f"{name}.peak_external_norm": r.peak_external_norm,
                f"{name}.peak_internal_norm": r.peak_internal_norm,
                f"{name}.peak_max_internal": r.peak_max_internal,
                f"{name}.impacts": len(r.events),
                f"{name}.peak_at": max(r.events, key=lambda e: e.external_norm).time,
                f"{name}.peak_kind": max(r.events, key=lambda e: e.external_norm).kind,
                f"{name}.energy_absorbed": r.energy_absorbed,
                f"{name}.momentum_balance": r.momentum_balance,
                f"{name}.first_external_norm": r.external_norm,
                f"{name}.first_impact_external_norm": first.external_norm,
                f"{name}.first_difference": abs(r.external_norm - first.external_norm),
                f"{name}.error_estimate": r.error_estimate,
                f"{name}.energy_gained": int(r.energy_gained),
            }
        rows.append(row)
        print(f"landing {number} ({case['group']}): planar {row['planar.peak_external_norm']:.4f}, "
              f"splayed {row['splayed.peak_external_norm']:.4f} ({time.perf_counter() - t0:.0f} s)", flush=True)
    return rows, time.perf_counter() - t0


def plot(rows: list[dict]) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(12, 4.2))
    FigureCanvasAgg(fig)
    for k, key in enumerate(FIGURES):
        ax = fig.add_subplot(1, 3, k + 1)
        data, labels = [], []
        for group in GROUPS:
            for name in ("planar", "splayed"):
                data.append([r[f"{name}.{key}"] for r in rows if r["group"] == group])
                labels.append(f"{group}\n{name}")
        ax.boxplot(data, showmeans=True)
        ax.set_xticks(range(1, len(labels) + 1), labels, fontsize=6)
        ax.set_title(f"{key} [N s]", fontsize=9)
        ax.set_yscale("log")
        ax.grid(alpha=0.3)
    fig.suptitle(f"whole landings in space ({DURATION} s), {PER_GROUP} per group: planar against splayed", fontsize=10)
    fig.tight_layout()
    fig.savefig(HERE / "whole_landing.png", dpi=120)


def section(rows: list[dict], seconds: float) -> list[str]:
    n = len(rows)
    lines = [
        SECTION,
        "",
        f"Produced by `python studies/splayed_toes/whole_landing.py` ({time.strftime('%Y-%m-%d', time.gmtime())}; "
        "what and how: its docstring). "
        f"{n} landings ({PER_GROUP} per group: run.py's landings {', '.join(str(r['landing']) for r in rows)}) "
        f"x 2 feet, {DURATION} s each, in {seconds:.0f} s. Both feet carry the same joint laws (the designs have "
        "none; with free joints the foot collapses): knee 150 N m/rad, 3 N m s/rad, stops [-2, 0] rad; ankle "
        "joints 20 N m/rad, 0.5 N m s/rad, stops 0.45 rad either side; joints inside a toe 10 N m/rad, "
        "0.25 N m s/rad. Restitution 0.8, friction 0.5, gravity 9.81.",
        "",
        "| landings | figure | planar mean | splayed mean | ratio of means | planar worst | splayed worst "
        "| ratio of worsts |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for group in (*GROUPS, "all"):
        sel = [r for r in rows if group == "all" or r["group"] == group]
        for fig in (*FIGURES, "first_external_norm", "impacts", "energy_absorbed"):
            p = np.array([r[f"planar.{fig}"] for r in sel], dtype=float)
            s = np.array([r[f"splayed.{fig}"] for r in sel], dtype=float)
            lines.append(f"| {group} ({len(sel)}) | {fig} | {p.mean():.4f} | {s.mean():.4f} | {s.mean() / p.mean():.3f} "
                         f"| {p.max():.4f} | {s.max():.4f} | {s.max() / p.max():.3f} |")
    worst = {k: max(r[f"{f}.{k}"] for r in rows for f in ("planar", "splayed"))
             for k in ("momentum_balance", "first_difference", "error_estimate")}
    kinds = {f: sorted({r[f"{f}.peak_kind"] for r in rows}) for f in ("planar", "splayed")}
    at = {f: [r[f"{f}.peak_at"] for r in rows] for f in ("planar", "splayed")}
    gained = sum(r[f"{f}.energy_gained"] for r in rows for f in ("planar", "splayed"))
    lines += [
        "",
        f"Law checks: momentum balance at most {worst['momentum_balance']:.1e} (asked: below 1e-4); the first "
        f"event's external_norm against run.py's first impact (`land`) differs by at most "
        f"{worst['first_difference']:.1e} (asked: 1e-9); no impact gained energy in {2 * n - gained} of {2 * n} "
        f"landings. Step-halving error estimate at most {worst['error_estimate']:.1e} (tolerance {TOLERANCE}).",
        f"The largest external impulse of a landing is a `{'`/`'.join(kinds['planar'])}` event (planar) and "
        f"`{'`/`'.join(kinds['splayed'])}` (splayed), at {min(min(v) for v in at.values()) * 1e3:.1f} to "
        f"{max(max(v) for v in at.values()) * 1e3:.1f} ms.",
        "",
        "![whole landings: peak impulses per group and foot](whole_landing.png)",
        "",
    ]
    return lines


def write_results(lines: list[str]) -> None:
    path = HERE / "results.md"
    text = path.read_text(encoding="utf-8")
    head = text.split(SECTION)[0].rstrip("\n")
    path.write_text(head + "\n\n" + "\n".join(lines), encoding="utf-8")


def main() -> None:
    rows, seconds = run()
    with (HERE / "whole_landing.csv").open("w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    plot(rows)
    lines = section(rows, seconds)
    write_results(lines)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
