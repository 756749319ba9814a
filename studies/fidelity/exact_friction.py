"""Exact Coulomb friction against its convex relaxation on the paper's case 3 (issue #12).

For friction 0.1, 0.3, 1 and 2: the heel's and a toe's normal and tangential impulses, the
heel's separation speed after the impact (Newton's restitution says e v = 2.744 m/s), each
contact's mode, and the cost of one evaluate() call of each rung beside the frictionless one, in
the same run. Writes exact_friction.csv and exact_friction.md next to this file.

Run: python studies/fidelity/exact_friction.py
"""

from __future__ import annotations

import csv
import dataclasses
import time
from pathlib import Path

from impulse_core.evaluate import evaluate
from impulse_core.impact.laws import ImpactModel
from optimizer.config.model_file import load_model_file

HERE = Path(__file__).resolve().parent
CASE3 = HERE.parents[1] / "configs" / "paper_case3.yaml"


def cost_us(tree, scene, model: ImpactModel, repeats: int = 200) -> float:
    """Best-of-5 mean time of one evaluate() call (microseconds)."""
    best = float("inf")
    for _ in range(5):
        start = time.perf_counter()
        for _ in range(repeats):
            evaluate(tree, scene, model)
        best = min(best, (time.perf_counter() - start) / repeats * 1e6)
    return best


def main() -> None:
    model = load_model_file(CASE3)
    tree = model.tree
    frictionless_us = cost_us(tree, model.scene, ImpactModel.LCP)
    rows = []
    for mu in (0.1, 0.3, 1.0, 2.0):
        scene = dataclasses.replace(model.scene, friction=mu)
        for rung in (ImpactModel.FRICTION, ImpactModel.FRICTION_RELAXED):
            r = evaluate(tree, scene, rung)
            rows.append(
                {
                    "friction": mu,
                    "rung": rung.value,
                    "heel_normal": round(float(r.external[0]), 4),
                    "heel_tangential": round(float(r.tangential[0]), 4),
                    "toe_normal": round(float(r.external[1]), 4),
                    "heel_leaves_at": round(float(r.contact_velocity[0]), 3),
                    "modes": " ".join(m.value for m in r.modes) if r.modes else "-",
                    "cost_vs_frictionless": round(cost_us(tree, scene, rung) / frictionless_us, 2),
                }
            )
    with (HERE / "exact_friction.csv").open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    lines = [
        "# Exact Coulomb friction vs the convex relaxation, paper case 3",
        "",
        f"`python studies/fidelity/exact_friction.py`; cost = one `evaluate()` call of the rung divided by one of "
        f"the frictionless LCP rung in the same run ({frictionless_us:.0f} us per call here).",
        "",
        "| " + " | ".join(rows[0]) + " |",
        "|" + "---|" * len(rows[0]),
        *("| " + " | ".join(str(v) for v in r.values()) + " |" for r in rows),
        "",
    ]
    (HERE / "exact_friction.md").write_text("\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
