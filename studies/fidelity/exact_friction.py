"""Exact Coulomb friction against its convex relaxation and MuJoCo on the paper's case 3 (issue #12).

For friction 0.1, 0.3, 1 and 2: the heel's and a toe's normal and tangential impulses, the
heel's separation speed after the impact (Newton's restitution says e v = 2.744 m/s), each
contact's mode, and the cost of one evaluate() call of each rung beside the frictionless one, in
the same run. MuJoCo: the same leg dropped with Coulomb friction on elliptic cones (condim 3)
and its soft contacts at the settings of ``footopt drop`` (direct solref, stiffness 1e8 1/s^2,
damping for e = 0.8, the compliant rung's step), the contact forces integrated over the drop;
its cost is one drop's, beside the same frictionless evaluate() call. Writes exact_friction.csv
and exact_friction.md next to this file.

Run: python studies/fidelity/exact_friction.py
"""

from __future__ import annotations

import csv
import dataclasses
import time
from pathlib import Path

from impulse_core.evaluate import evaluate, pre_impact_velocity
from impulse_core.impact.laws import ImpactModel
from impulse_core.timedomain.compliant import CompliantSettings, ContactLaw, simulate_impact
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


#: MuJoCo's contact stiffness (1/s^2), as ``footopt drop``'s default.
STIFFNESS = 1e8


def mujoco_row(tree, scene) -> dict:
    """The MuJoCo columns of one friction coefficient (best-of-3 time of one drop)."""
    from optimizer.validation.mujoco_bridge import drop

    settings = CompliantSettings(law=ContactLaw.CONSTRAINT, stiffness=STIFFNESS)
    soft = simulate_impact(tree, dataclasses.replace(scene, friction=0.0), settings)
    steps = 3 * int(round(soft.duration / soft.timestep))  # sliding contacts stay a little longer
    v = pre_impact_velocity(tree.topology(), scene)
    best = float("inf")
    for _ in range(3):
        start = time.perf_counter()
        mj = drop(tree, scene, settings, steps, soft.timestep, v_minus=v)
        best = min(best, time.perf_counter() - start)
    assert not mj.loaded_at_end, "the drop ended with a loaded contact: lengthen it"
    return {
        "heel_normal": round(float(mj.external[0]), 4),
        "heel_tangential": round(float(mj.external_vector[0, 0]), 4),
        "toe_normal": round(float(mj.external[1]), 4),
        "heel_leaves_at": "-",
        "modes": "-",
        "seconds": best,
    }


def _agreement(rows: list[dict]) -> list[str]:
    """One table row per friction: MuJoCo's heel impulses relative to the two rigid rungs'."""
    out = []
    for mu in sorted({r["friction"] for r in rows}):
        by = {r["rung"]: r for r in rows if r["friction"] == mu}
        mj = by["MuJoCo (elliptic)"]
        cells = []
        for rung in ("friction", "friction-relaxed"):
            for key in ("heel_normal", "heel_tangential"):
                cells.append(f"{100 * (mj[key] - by[rung][key]) / by[rung][key]:+.1f}%")
        out.append(f"| {mu} | " + " | ".join(cells) + " |")
    return out


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
        mj = mujoco_row(tree, scene)
        seconds = mj.pop("seconds")
        rows.append({"friction": mu, "rung": "MuJoCo (elliptic)", **mj,
                     "cost_vs_frictionless": round(seconds * 1e6 / frictionless_us, 1)})
    with (HERE / "exact_friction.csv").open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    lines = [
        "# Exact Coulomb friction vs the convex relaxation, paper case 3",
        "",
        f"`python studies/fidelity/exact_friction.py`; cost = one `evaluate()` call of the rung divided by one of "
        f"the frictionless LCP rung in the same run ({frictionless_us:.0f} us per call here); MuJoCo's, one drop's "
        f"(elliptic cones, direct solref at {STIFFNESS:g} 1/s^2, the damping for e = 0.8, the compliant rung's step).",
        "",
        "| " + " | ".join(rows[0]) + " |",
        "|" + "---|" * len(rows[0]),
        *("| " + " | ".join(str(v) for v in r.values()) + " |" for r in rows),
        "",
        "MuJoCo's heel impulses against the exact law's and the relaxation's (relative differences):",
        "",
        "| friction | MuJoCo vs exact: heel normal | heel tangential | MuJoCo vs relaxed: heel normal | heel tangential |",
        "|---|---|---|---|---|",
        *_agreement(rows),
        "",
    ]
    (HERE / "exact_friction.md").write_text("\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
