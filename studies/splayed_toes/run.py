"""Splayed toes against planar toes (issue #15, item 5), on the same landings.

Part 1, optimised feet (``optimised``): two outer searches with the same leg, landing (straight
down, 3.43 m/s, e 0.8), mass budget (0.5 kg), shapes (a heel and 2-4 toes of 1-2 rods), seed and
trials (800): ``planar.yaml`` (toes in the plane) and ``splayed.yaml`` (the toes turned about the
vertical, spread symmetrically from -s to +s, s in [0, 0.8] rad, and the centre of mass at least
2 cm inside the contacts' hull: ``constraints.support_margin: 0.02``). Each front's best foot
(least internal_norm at the nominal landing) then meets the same 300 landings (seeded), evaluated
in space (``impulse_core.evaluate``, the exact circular-cone friction law, friction 0.5, the
contacts within 1e-6 m of the lowest hit): 100 pitched (pitch added to the thigh's angle, uniform
in +-0.15 rad), 100 rolled (the base tilted about x by a roll uniform in +-0.15 rad, a roll rate
about x uniform in +-1 rad/s and a lateral velocity uniform in +-0.3 m/s) and 100 both; speed
uniform in [3.0, 4.0] m/s. Writes ``run_planar/``, ``run_splayed/`` (the runs, with the splayed
front's ``top_views.png``), ``optimised.csv`` (every landing), ``optimised.png`` and
``top_views.png`` (the two best feet from above).

Part 2, a splay sweep of one fixed foot (``sweep``). The foot: the paper's case 3 leg in space (``configs/spatial_case3.yaml``: heel and three two-rod
toes, rods of 1 cm radius). Toes 1 and 3 are splayed about the shank's axis by -s and +s (toe 2
stays in the plane); s = 0 is the planar foot, whose three identical toes act as one. Each design
lands 200 times (seeded; the same landings for every design): pitch (added to the thigh's
angle) and roll (about x, the thigh's ``rpy``) uniform in +-0.15 rad, lateral velocity
uniform in +-0.5 m/s, roll rate uniform in +-1 rad/s, straight down at 3.43 m/s, restitution
0.8, friction 0.5 (the exact circular cone). The first impact of each landing: the contacts
within 1e-6 m of the lowest hit (a rolled landing meets the ground with one side first).
Scores: mean and worst (max) of external_norm and internal_norm over the landings; the best
splay minimises the mean internal_norm (the joints' load).

Run from the repository root: ``python studies/splayed_toes/run.py``; writes results.md (keeping
its section 3, by whole_landing.py),
splay.csv and splay.png here (and part 1's files).
"""

from __future__ import annotations

import csv
import dataclasses
import json
import time
from pathlib import Path

import numpy as np

from impulse_core.evaluate import evaluate, touchdown_geometry
from impulse_core.kinematics.spatial import SPATIAL
from impulse_core.model.support import support_margin
from impulse_core.model.tree import ContactSelection, Scene, Tree
from optimizer.cli.main import main as footopt
from optimizer.config.model_file import load_model_file
from optimizer.report.plot import plot_top_views

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
LANDINGS = 200
SPLAYS = np.round(np.linspace(0.0, 0.8, 17), 3)
SEED = 20261125
WHOLE = "## 3. Whole landings in space"  # results.md's section by whole_landing.py, kept by main


def splayed(tree: Tree, s: float) -> Tree:
    """The foot with toes 1 and 3 turned about the shank's axis by -s and +s."""
    roll = {"toe1_proximal": -s, "toe3_proximal": s}
    return Tree(tuple(dataclasses.replace(b, rpy=(roll.get(b.name, b.rpy[0]), 0.0, 0.0)) for b in tree.bodies))


def landings(scene, rng: np.random.Generator):
    """(pitch, roll, scene) per landing."""
    out = []
    for _ in range(LANDINGS):
        pitch, roll = rng.uniform(-0.15, 0.15, 2)
        s = dataclasses.replace(
            scene,
            speed=3.43,
            velocity_x=0.0,
            velocity_z=float(rng.uniform(-0.5, 0.5)),
            angular_velocity=0.0,
            angular_velocity_x=float(rng.uniform(-1.0, 1.0)),
            angular_velocity_y=0.0,
            friction=0.5,
            selection=ContactSelection.LOWEST,
        )
        out.append((float(pitch), float(roll), s))
    return out


def scores(tree: Tree, cases) -> dict[str, float]:
    ext, inner, exact, hit, shared = [], [], 0, [], 0
    for pitch, roll, scene in cases:
        base = tree.bodies[0]
        turned = dataclasses.replace(base, angle=base.angle + pitch, rpy=(roll, 0.0, 0.0))
        r = evaluate(Tree((turned,) + tree.bodies[1:]), scene, space=SPATIAL)
        ext.append(r.external_norm)
        inner.append(r.internal_norm)
        exact += not r.notes
        hit.append(len(r.active))
        shared += not r.split_unique
    return {
        "mean_external": float(np.mean(ext)),
        "max_external": float(np.max(ext)),
        "mean_internal": float(np.mean(inner)),
        "max_internal": float(np.max(inner)),
        "exact": exact,
        "mean_contacts_hit": float(np.mean(hit)),
        "non_unique": shared,
    }


def margin(tree: Tree) -> float:
    """The support margin at the nominal posture (m): the centre of mass inside the contacts' hull."""
    g = touchdown_geometry(tree, SPATIAL)
    masses = np.array([b.mass for b in tree.bodies])
    com = masses @ g.coms / masses.sum()
    return support_margin(g.contacts[:, [0, 2]], com[[0, 2]])


# --------------------------------------------------------------------------------------------
# Part 1: the best splayed foot against the best planar foot

GROUP_SIZE = 100
GROUPS = ("pitched", "rolled", "pitched and rolled")
OPT_SEED = 20261126


def opt_landings(rng: np.random.Generator) -> list[dict]:
    """The same landings for both feet: per group, pitch, roll, roll rate, lateral velocity, speed."""
    out = []
    for group in GROUPS:
        for _ in range(GROUP_SIZE):
            pitched, rolled = group != "rolled", group != "pitched"
            out.append({
                "group": group,
                "pitch": float(rng.uniform(-0.15, 0.15)) if pitched else 0.0,
                "roll": float(rng.uniform(-0.15, 0.15)) if rolled else 0.0,
                "roll_rate": float(rng.uniform(-1.0, 1.0)) if rolled else 0.0,
                "velocity_z": float(rng.uniform(-0.3, 0.3)) if rolled else 0.0,
                "speed": float(rng.uniform(3.0, 4.0)),
            })
    return out


def land(tree: Tree, case: dict):
    """One landing of ``tree`` (its base pitched and rolled), in space."""
    base = tree.bodies[0]
    turned = dataclasses.replace(base, angle=base.angle + case["pitch"], rpy=(case["roll"], 0.0, 0.0))
    scene = Scene(speed=case["speed"], restitution=0.8, friction=0.5, velocity_z=case["velocity_z"],
                  angular_velocity_x=case["roll_rate"], selection=ContactSelection.LOWEST)
    return evaluate(Tree((turned,) + tree.bodies[1:]), scene, space=SPATIAL)


def best_of(run: Path) -> tuple[dict, Tree]:
    """The front's design with the least internal_norm, and its model file's tree."""
    entries = json.loads((run / "pareto.json").read_text())["designs"]
    best = min(entries, key=lambda e: e["objectives"]["internal_norm"])
    return best, load_model_file(run / best["model_file"]).tree


def optimised() -> tuple[list[str], dict]:
    timing = {}
    feet = {}
    for name in ("planar", "splayed"):
        t0 = time.perf_counter()
        assert footopt(["optimize", str(HERE / f"{name}.yaml"), "--out", str(HERE / f"run_{name}"), "--quiet",
                        "--force"]) == 0
        timing[name] = time.perf_counter() - t0
        feet[name] = best_of(HERE / f"run_{name}")
    cases = opt_landings(np.random.default_rng(OPT_SEED))
    t0 = time.perf_counter()
    rows = []
    for k, case in enumerate(cases):
        row = {"landing": k, **case}
        for name, (_, tree) in feet.items():
            r = land(tree, case)
            row |= {f"{name}.external_norm": r.external_norm, f"{name}.internal_norm": r.internal_norm,
                    f"{name}.max_internal": r.max_internal, f"{name}.contacts_hit": len(r.active),
                    f"{name}.exact": int(not r.notes)}
        rows.append(row)
    timing["landings"] = time.perf_counter() - t0
    with (HERE / "optimised.csv").open("w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    margins = {name: margin(tree) for name, (_, tree) in feet.items()}
    plot_top_views([(f"best {name} foot (trial {best['trial']}, {best['shape']['toes']} toes)", tree)
                    for name, (best, tree) in feet.items()], HERE / "top_views.png")
    plot_optimised(rows)
    return optimised_text(feet, rows, margins, timing), timing


def optimised_text(feet: dict, rows: list[dict], margins: dict, timing: dict) -> list[str]:
    (bp, _), (bs, _) = feet["planar"], feet["splayed"]
    yaws = [v for k, v in sorted(bs["design"].items()) if k.endswith(".yaw")]
    lines = [
        "## 1. The best splayed foot against the best planar foot",
        "",
        f"Two outer searches of 800 trials each (`planar.yaml`: {timing['planar']:.0f} s, `splayed.yaml`: "
        f"{timing['splayed']:.0f} s), then 300 landings per foot ({timing['landings']:.0f} s). Best = least "
        "internal_norm on the front (nominal landing: straight down at 3.43 m/s).",
        "",
        "| foot | trial | shape | foot mass [kg] | toe yaws [rad] | support margin [mm] | nominal external_norm "
        "| nominal internal_norm |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, b in (("planar", bp), ("splayed", bs)):
        ys = [v for k, v in sorted(b["design"].items()) if k.endswith(".yaw")] or [0.0] * b["shape"]["toes"]
        lines.append(f"| {name} | {b['trial']} | {b['shape']['toes']}x{b['shape']['toe_segments']} | "
                     f"{b['design']['foot_mass']:.3f} | {', '.join(f'{y:+.3f}' for y in ys)} | "
                     f"{round(1e3 * margins[name], 1) + 0.0:+.1f} | {b['objectives']['external_norm']:.4f} | "
                     f"{b['objectives']['internal_norm']:.4f} |")
    lines += [
        "",
        f"Nominal splayed / planar: external_norm {bs['objectives']['external_norm'] / bp['objectives']['external_norm']:.3f}, "
        f"internal_norm {bs['objectives']['internal_norm'] / bp['objectives']['internal_norm']:.3f}.",
        "",
        "On the same landings (friction 0.5; mean and worst over each group of 100; ratio = splayed / planar):",
        "",
        "| landings | figure | planar mean | splayed mean | ratio of means | planar worst | splayed worst "
        "| ratio of worsts |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for group in (*GROUPS, "all"):
        sel = [r for r in rows if group == "all" or r["group"] == group]
        for fig in ("external_norm", "internal_norm", "max_internal"):
            p = np.array([r[f"planar.{fig}"] for r in sel])
            s = np.array([r[f"splayed.{fig}"] for r in sel])
            lines.append(f"| {group} ({len(sel)}) | {fig} | {p.mean():.4f} | {s.mean():.4f} | {s.mean() / p.mean():.3f} "
                         f"| {p.max():.4f} | {s.max():.4f} | {s.max() / p.max():.3f} |")
    hit = {n: np.mean([r[f"{n}.contacts_hit"] for r in rows]) for n in ("planar", "splayed")}
    exact = {n: sum(r[f"{n}.exact"] for r in rows) for n in ("planar", "splayed")}
    lines += [
        "",
        f"Contacts hit per landing (mean): planar {hit['planar']:.2f}, splayed {hit['splayed']:.2f}. The exact "
        f"circular-cone law was met on {exact['planar']} (planar) and {exact['splayed']} (splayed) of {len(rows)} "
        "landings (the rest: the polyhedral answer, with its warning).",
        f"The splayed foot's yaws: {', '.join(f'{y:+.3f}' for y in yaws)} rad.",
        "",
        "![the best feet from above](top_views.png)",
        "",
        "![per-landing impulses, splayed against planar](optimised.png)",
        "",
        "What this says, and what it does not. Both searches end at the same shape (a heel and two two-rod",
        "toes) and nearly the same figures on the nominal landing: standing (the support margin) cost the splayed",
        "foot about 1 % there, and about 2 % on the pitched landings, where both feet meet the ground alike. On",
        "rolled landings the splayed foot's first impact is lower, because it meets one toe (or the heel) first:",
        "the planar foot's two toes lie on one line, so a roll does not separate them and both hit together.",
        "As in part 2, only the first impact is scored: the splayed foot's other toe lands later and that impact",
        "is not in these figures (section 3 lands the feet whole, in space), so the rolled ratios overstate",
        "the gain by an amount not measured here. Both feet weigh the budget (0.5 kg);",
        "one seed, one budget of trials, one set of landing ranges.",
        "",
    ]
    return lines


def plot_optimised(rows: list[dict]) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 4.5))
    FigureCanvasAgg(fig)
    for k, key in enumerate(("external_norm", "internal_norm")):
        ax = fig.add_subplot(1, 2, k + 1)
        for group, marker in zip(GROUPS, "os^", strict=True):
            sel = [r for r in rows if r["group"] == group]
            ax.plot([r[f"planar.{key}"] for r in sel], [r[f"splayed.{key}"] for r in sel], marker, ms=4, alpha=0.6,
                    label=group)
        hi = max(max(r[f"planar.{key}"], r[f"splayed.{key}"]) for r in rows)
        ax.plot([0, hi], [0, hi], color="grey", lw=1)
        ax.set_xlabel(f"planar foot: {key} [N s]")
        ax.set_ylabel(f"splayed foot: {key} [N s]")
        ax.set_title(f"{key}, one point per landing (below the line: splayed lower)", fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(HERE / "optimised.png", dpi=120)


# --------------------------------------------------------------------------------------------
# Part 2: a splay sweep of one fixed foot


def main() -> None:
    part1, _ = optimised()
    part2 = sweep()
    text = "\n".join([
        "# Splayed toes against planar toes (issue #15)",
        "",
        f"Produced by `python studies/splayed_toes/run.py` ({time.strftime('%Y-%m-%d', time.gmtime())}). "
        "What is compared: run.py's docstring.",
        "",
        *part1,
        *part2,
    ])
    old = (HERE / "results.md").read_text(encoding="utf-8") if (HERE / "results.md").exists() else ""
    kept = old[old.index(WHOLE):] if WHOLE in old else ""  # whole_landing.py's section
    (HERE / "results.md").write_text(text + ("\n" + kept if kept else ""), encoding="utf-8")
    print(text)


def sweep() -> list[str]:
    model = load_model_file(REPO / "configs" / "spatial_case3.yaml")
    plain = Tree(tuple(dataclasses.replace(b, rpy=(0.0, 0.0, 0.0)) for b in model.tree.bodies))
    cases = landings(model.scene, np.random.default_rng(SEED))
    t0 = time.perf_counter()
    rows = [
        {"splay": float(s), **scores(splayed(plain, float(s)), cases), "support_margin": margin(splayed(plain, float(s)))}
        for s in SPLAYS
    ]
    seconds = time.perf_counter() - t0
    with (HERE / "splay.csv").open("w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    planar = rows[0]
    best = min(rows, key=lambda r: r["mean_internal"])
    plot(rows, best)
    table = ["| foot | splay [rad] | mean external_norm | worst external_norm | mean internal_norm | worst internal_norm "
             "| contacts hit (mean) | landings with a non-unique split | support margin [mm] |",
             "|---|---|---|---|---|---|---|---|---|"]
    for name, r in (("planar (toes in the plane)", planar), ("best splayed", best)):
        table.append(f"| {name} | {r['splay']:.2f} | {r['mean_external']:.4f} | {r['max_external']:.4f} | "
                     f"{r['mean_internal']:.4f} | {r['max_internal']:.4f} | {r['mean_contacts_hit']:.2f} | "
                     f"{r['non_unique']} | {round(1e3 * r['support_margin'], 1) + 0.0:+.1f} |")
    ratio = {k: best[k] / planar[k] for k in ("mean_external", "max_external", "mean_internal", "max_internal")}
    return [
        "## 2. One foot, splay swept",
        "",
        f"{len(SPLAYS)} splays x {LANDINGS} landings in {seconds:.0f} s.",
        "",
        *table,
        "",
        "Best splayed / planar: " + ", ".join(f"{k} {v:.3f}" for k, v in ratio.items()) + ".",
        f"The exact circular-cone law was met in {min(r['exact'] for r in rows)} to {max(r['exact'] for r in rows)} "
        f"of the {LANDINGS} landings per design (the rest: the polyhedral answer, with its warning).",
        "",
        "![scores against the splay](splay.png)",
        "",
        "What this says, and what it does not. The whole gain comes between splay 0 and the first step",
        f"({rows[1]['splay']:.2f} rad) and is then flat: at splay 0 the three toe tips coincide, so a landing that",
        f"meets the toes first meets all three at once ({planar['non_unique']} of {LANDINGS} landings: a redundant contact",
        "set, its split shown as the smallest-norm one), while any splay separates them and a rolled landing meets",
        "one toe first. The first impact then takes one toe's impulse, and the other toes' later impacts are",
        "not scored. So on first impacts a splayed foot looks better on average and no better in the worst",
        "landing (the heel-first ones); whether splay spreads the whole landing's impulses needs the whole",
        "landing in space (section 3). What splay does give is a foot that stands: the",
        f"support margin (the centre of mass inside the contacts' hull) is {round(1e3 * planar['support_margin'], 1) + 0.0:+.1f} mm for the",
        f"planar foot (its contacts on one line) and {1e3 * best['support_margin']:+.1f} mm at the best splay.",
        "Every splay's scores are in `splay.csv`; one",
        "leg geometry (only the splay varies); the landings' ranges are a choice.",
        "",
    ]


def plot(rows, best) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 4))
    FigureCanvasAgg(fig)
    s = [r["splay"] for r in rows]
    for k, (key, title) in enumerate((("external", "external_norm [N s]"), ("internal", "internal_norm [N s]"))):
        ax = fig.add_subplot(1, 2, k + 1)
        ax.plot(s, [r[f"mean_{key}"] for r in rows], "o-", label="mean over the landings")
        ax.plot(s, [r[f"max_{key}"] for r in rows], "s--", label="worst landing")
        ax.axvline(best["splay"], color="grey", lw=1)
        ax.set_xlabel("splay of toes 1 and 3 [rad] (0: planar)")
        ax.set_title(title)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(HERE / "splay.png", dpi=120)


if __name__ == "__main__":
    main()
