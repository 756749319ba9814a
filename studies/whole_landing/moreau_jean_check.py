"""footopt's whole landing against an independent peer of the same rigid law (issue #13's check).

The peer (:mod:`optimizer.validation.moreau_jean`): Moreau-Jean time stepping on Pinocchio's
dynamics, its contact law solved by nonsmooth Gauss-Seidel, first order in its step. MuJoCo, the
other peer, is a soft law: on the legs of ``settled_posture.py --tips`` with friction it settles up
to 8e-2 rad from footopt (``settled_posture_tips.md``), which says nothing about which is right.
This study lands the same legs with the rigid peer at two steps, h and h / 2: where its gap to
footopt halves with the step, the peer converges on footopt's answer.

- case 3 (``configs/landing_case3.yaml``, 0.3 s): the double Zeno cascade of 441 impacts;
- ``settled_posture.py --tips``'s random legs (a plank on sprung chains landing on their tips,
  friction 0, 0.5 or 1, restitution 0-0.3, 3 s).

footopt: ``landing()`` at its defaults (``--tolerance 1e-3``). Figures: the largest difference of
the final angles (rad), of each contact's total normal impulse (relative to the largest), and of
the final base origin (m); "order": log2 of the ratio of the angle gaps at h and h / 2 (1: first
order, the peer converging on footopt's answer; about 0: a gap the step does not close).

``--spatial``: the spatial legs with friction of ``settled_posture.py --spatial``
(``settled_posture_spatial.md``: 12 legs, friction 0.5 or 1, where footopt and MuJoCo reach
different rests, both passing footopt's statics), landed by the spatial peer; per leg the postures
frame-free (``posture_gaps``: the base's relative turn, its tilt, the largest joint gap) of the
peer against footopt and against MuJoCo (the bridge's contacts, as that table), and the peer's
final state in footopt's statics (``statics``).

Run: python studies/whole_landing/moreau_jean_check.py [--seeds 0 20] [--step 4e-5]
[--spatial [--spatial-seeds S ...]]
(writes moreau_jean[_spatial].md next to this file; each leg's row is kept in
moreau_jean[_spatial].jsonl as it ends, and a rerun skips the legs already there)
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(HERE))

from impulse_core.kinematics.spatial import SPATIAL, dof_layout  # noqa: E402
from impulse_core.timedomain.events.run import _Landing  # noqa: E402
from impulse_core.timedomain.landing import LandingSettings, landing  # noqa: E402
from optimizer.config.model_file import load_model_file  # noqa: E402
from optimizer.validation.moreau_jean import moreau_jean_landing  # noqa: E402
from settled_posture import StudyMujoco, posture_gaps, random_leg, random_spatial_leg, statics  # noqa: E402

#: the spatial legs with friction of settled_posture_spatial.md (the others: frictionless, or
#: footopt's landing over 60 s there)
SPATIAL_SEEDS = (1, 5, 6, 7, 10, 11, 12, 13, 15, 16, 18, 19)

CHECK = 2e-3  # issue #13: the settled posture of hidden legs against MuJoCo, rad


def compare(name: str, tree, laws, scene, step: float) -> dict:  # type: ignore[no-untyped-def]
    """One leg: footopt's landing and the peer's at ``step`` and ``step`` / 2, their differences."""
    t0 = time.process_time()
    ours = landing(tree, scene, laws, LandingSettings())
    row = {"name": name, "friction": scene.friction, "restitution": scene.restitution, "duration": scene.duration,
           "events": len(ours.events), "settled_at": ours.settled_at, "estimate": ours.error_estimate,
           "footopt_s": time.process_time() - t0, "gaps": []}
    for h in (step, step / 2):
        t0 = time.process_time()
        peer = moreau_jean_landing(tree, scene, laws, h)
        row["gaps"].append({
            "step": h, "seconds": time.process_time() - t0,
            "angles": float(np.max(np.abs(peer.final_angles - ours.final_angles))),
            "totals": float(np.max(np.abs(peer.total_external - ours.total_external)) / np.max(ours.total_external)),
            "base": float(np.max(np.abs(peer.final_base - ours.q_final[:2]))),
        })
    return row


def compare_spatial(seed: int, step: float) -> dict:
    """One spatial leg (:func:`random_spatial_leg`): footopt's landing, MuJoCo's and the peer's at
    ``step`` and ``step`` / 2; the postures' gaps (:func:`posture_gaps`: base turn, tilt, joints)."""
    from types import SimpleNamespace

    tree, laws, scene = random_spatial_leg(seed)
    t0 = time.process_time()
    ours = landing(tree, scene, laws, LandingSettings(), space=SPATIAL)
    row = {"name": f"leg {seed}", "friction": scene.friction, "restitution": scene.restitution,
           "events": len(ours.events), "settled_at": ours.settled_at, "estimate": ours.error_estimate,
           "footopt_s": time.process_time() - t0, "gaps": []}
    mujoco = StudyMujoco(SimpleNamespace(tree=tree, scene=scene, joints=laws), space=SPATIAL)
    theirs = mujoco.final_state()[0]
    row["mujoco_footopt"] = posture_gaps(ours.final_angles, theirs, SPATIAL)
    run = _Landing(tree, scene, laws, LandingSettings(), SPATIAL)
    revolute = [d is not None for d in dof_layout(tree.topology(), SPATIAL).body_dof[1:]]
    for h in (step, step / 2):
        t0 = time.process_time()
        peer = moreau_jean_landing(tree, scene, laws, h, space=SPATIAL)
        q = np.concatenate([peer.final_base, peer.final_angles[:3], peer.final_angles[3:][revolute]])
        row["gaps"].append({
            "step": h, "seconds": time.process_time() - t0,
            "footopt": posture_gaps(ours.final_angles, peer.final_angles, SPATIAL),
            "mujoco": posture_gaps(peer.final_angles, theirs, SPATIAL),
            "base": float(np.max(np.abs(peer.final_base - ours.final_base))),
            "totals": float(np.max(np.abs(peer.total_external - ours.total_external)) / np.max(ours.total_external)),
            "speed": float(np.max(np.abs(peer.final_velocity))),
            "statics": statics(run, q, scene.friction),
        })
    return row


def spatial_table(rows: list[dict], step: float, command: str) -> str:
    """``--spatial``'s table (the figures: the module docstring)."""
    lines = [
        "# Spatial legs with friction: footopt, MuJoCo and the Moreau-Jean peer of the rigid law",
        "",
        f"`{command}`; the legs: `settled_posture.py --spatial`'s with friction (its table: "
        "`settled_posture_spatial.md`), 3 s each. The peer (`optimizer/validation/moreau_jean.py`, spatial) at "
        f"h = {step:g} s and h / 2. Each gap: base turn / tilt / largest joint gap (rad, `posture_gaps`, "
        "frame-free); **worst**: the larger of the base turn and the joint gap. **statics**: the peer's final "
        "state at h / 2 in footopt's statics (`statics`, the residual over the weight, m; ~0: a rest). "
        "**speed**: the peer's largest generalized speed at 3 s. **s**: the peer's CPU seconds at h / 2.",
        "",
        "| leg | friction | restitution | events | settled at (s) | peer - footopt at h | peer - footopt at h / 2 "
        "| order | peer - MuJoCo at h / 2 | footopt - MuJoCo | base at h / 2 (m) | totals at h / 2 | statics "
        "| speed | s |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]

    def worst(g) -> float:  # type: ignore[no-untyped-def]
        return max(g[0], g[2])

    def cell(g) -> str:  # type: ignore[no-untyped-def]
        return f"{g[0]:.1e} / {g[1]:.1e} / {g[2]:.1e}"

    failed = [r for r in rows if "error" in r]
    rows = [r for r in rows if "error" not in r]
    for r in rows:
        a, b = r["gaps"]
        wa, wb = worst(a["footopt"]), worst(b["footopt"])
        order = math.log2(wa / wb) if wb > 0 else math.inf
        settled = "-" if r["settled_at"] is None else f"{r['settled_at']:.3f}"
        lines.append(f"| {r['name']} | {r['friction']:g} | {r['restitution']:.2f} | {r['events']} | {settled} | "
                     f"{cell(a['footopt'])} | {cell(b['footopt'])} | {order:.1f} | {cell(b['mujoco'])} | "
                     f"{cell(r['mujoco_footopt'])} | {b['base']:.1e} | {b['totals']:.1e} | {b['statics']:.0e} | "
                     f"{b['speed']:.0e} | {b['seconds']:.0f} |")
    fine = [worst(r["gaps"][1]["footopt"]) for r in rows]
    mj = [worst(r["gaps"][1]["mujoco"]) for r in rows]
    lines += ["", f"- The peer at h / 2 against footopt: worst {max(fine):.1e} rad; {sum(x <= CHECK for x in fine)} of "
              f"{len(rows)} legs within {CHECK:g} rad.",
              f"- The peer at h / 2 against MuJoCo: worst {max(mj):.1e} rad, best {min(mj):.1e}; "
              f"{sum(x <= CHECK for x in mj)} of {len(rows)} within {CHECK:g} rad."]
    lines += [f"- {r['name']}: the peer failed ({r['error']})." for r in failed]
    return "\n".join(lines) + "\n"


def legs(seeds: range):  # type: ignore[no-untyped-def]
    """Case 3, then the random legs of ``settled_posture.py --tips``."""
    m = load_model_file(ROOT / "configs" / "landing_case3.yaml")
    yield "case 3", m.tree, m.joints, m.scene
    for seed in seeds:
        tree, laws, scene = random_leg(seed, True)
        yield f"leg {seed}", tree, laws, scene


def table(rows: list[dict], step: float) -> str:
    lines = [
        "# footopt's whole landing against a Moreau-Jean peer of the same rigid law",
        "",
        "`python studies/whole_landing/moreau_jean_check.py`; the legs and the figures: the script's docstring. "
        f"The peer at h = {step:g} s and h / 2.",
        "",
        "| leg | friction | restitution | events | settled at (s) | angles at h (rad) | angles at h / 2 (rad) | order "
        "| totals at h / 2 | base at h / 2 (m) | peer s at h / 2 |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        a, b = r["gaps"]
        order = math.log2(a["angles"] / b["angles"]) if b["angles"] > 0 else math.inf
        settled = "-" if r["settled_at"] is None else f"{r['settled_at']:.3f}"
        lines.append(f"| {r['name']} | {r['friction']:g} | {r['restitution']:.2f} | {r['events']} | {settled} | "
                     f"{a['angles']:.1e} | {b['angles']:.1e} | {order:.1f} | {b['totals']:.1e} | {b['base']:.1e} | "
                     f"{b['seconds']:.0f} |")
    worst = max(r["gaps"][1]["angles"] for r in rows)
    within = sum(r["gaps"][1]["angles"] <= CHECK for r in rows)
    lines += ["", f"Worst angle gap at h / 2: {worst:.1e} rad; {within} of {len(rows)} legs within {CHECK:g} rad."]
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs=2, default=(0, 20), metavar=("LO", "HI"))
    parser.add_argument("--step", type=float, default=4e-5, help="the peer's coarser step h (s)")
    parser.add_argument("--spatial", action="store_true",
                        help="the spatial legs with friction (moreau_jean_spatial.md)")
    parser.add_argument("--spatial-seeds", type=int, nargs="+", default=SPATIAL_SEEDS, metavar="S")
    args = parser.parse_args()
    if args.spatial:
        return main_spatial(args)
    kept = HERE / "moreau_jean.jsonl"
    rows = [json.loads(line) for line in kept.read_text().splitlines()] if kept.exists() else []
    done = {r["name"] for r in rows}
    for name, tree, laws, scene in legs(range(*args.seeds)):
        if name in done:
            continue
        row = compare(name, tree, laws, scene, args.step)
        rows.append(row)
        with open(kept, "a") as out:
            out.write(json.dumps(row) + "\n")
        print(name, row["gaps"], flush=True)
        (HERE / "moreau_jean.md").write_text(table(rows, args.step))


def main_spatial(args: argparse.Namespace) -> None:
    """``--spatial``: each leg's row kept in moreau_jean_spatial.jsonl as it ends (a rerun skips them)."""
    command = "python studies/whole_landing/moreau_jean_check.py " + " ".join(sys.argv[1:])
    kept = HERE / "moreau_jean_spatial.jsonl"
    rows = [json.loads(line) for line in kept.read_text().splitlines()] if kept.exists() else []
    done = {r["name"] for r in rows}
    for seed in args.spatial_seeds:
        if f"leg {seed}" in done:
            continue
        try:
            row = compare_spatial(seed, args.step)
        except FloatingPointError as e:  # the peer's one-contact law found no answer: said in the table
            row = {"name": f"leg {seed}", "error": str(e)}
        rows.append(row)
        with open(kept, "a") as out:
            out.write(json.dumps(row) + "\n")
        print(row, flush=True)
        (HERE / "moreau_jean_spatial.md").write_text(spatial_table(rows, args.step, command))


if __name__ == "__main__":
    main()
