"""studies/imported_leg: a footopt foot on a real quadruped's imported leg, against the default leg.

1. ``footopt import`` of Unitree Go1's front left thigh and calf (example-robot-data's go1.urdf, a
   test extra), standing posture (thigh joint 0.9 rad, calf -1.8 rad), exact: centres of mass
   where they are, off the rods (``com_offset``; until the offsets reached studies the leg was
   imported with ``--com-on-rods``) and joint laws left out (the objectives are first-impact
   ones): ``go1_leg.yaml``. The thigh is the floating base, so its
   absolute angle comes from the same import rooted at the hip (the thigh joint on the chain).
2. ``footopt optimize`` of the same Go1-sized foot search (go1.yaml) on that leg and on footopt's
   default leg (default.yaml): the inner search, 6 foot shapes.
3. The same leg from the hip (three rods: hip, thigh, calf; planar: ``go1_hip_leg.yaml``) under the
   same search (go1_hip.yaml), and from the trunk (four rods, spatial: ``go1_trunk_leg.yaml``) under
   a spatial design space (splayed toes, the outer search: go1_trunk.yaml), beside the two-rod leg
   read as spatial in that space (go1_splay.yaml).
4. The fronts: ``fronts.csv``, ``fronts.png`` and the numbers quoted in results.md.

Run from anywhere: ``.venv/bin/python studies/imported_leg/run.py`` (about 30 s on one core).
"""

from __future__ import annotations

import csv
import importlib.metadata as md
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

HERE = Path(__file__).resolve().parent
ANGLES = {"FL_thigh_joint": 0.9, "FL_calf_joint": -1.8}
#: (study file, leg label): the planar search's three legs, then the spatial search's two.
STUDIES = (("go1.yaml", "go1"), ("default.yaml", "default"), ("go1_hip.yaml", "go1_hip"),
           ("go1_splay.yaml", "go1_splay"), ("go1_trunk.yaml", "go1_trunk"))
LABELS = {"go1": "Go1 thigh and calf (2 rods)", "default": "default leg (0.7 m, 1 kg rods)",
          "go1_hip": "Go1 hip, thigh, calf (3 rods)", "go1_splay": "Go1 thigh and calf, splayed toes",
          "go1_trunk": "Go1 trunk to calf (4 rods, spatial), splayed toes"}


def go1_urdf() -> Path:
    dist = md.distribution("example-robot-data")
    return next(Path(dist.locate_file(f)) for f in dist.files if str(f).endswith("go1_description/urdf/go1.urdf"))


def write_leg(out: Path) -> str:
    """The two-rod leg file; returns its summary (the chains from the hip and the trunk beside it)."""
    from impulse_core.model.tree import Tree
    from optimizer.config.model_file import format_model_file
    from optimizer.imports.leg import import_leg
    from optimizer.imports.read import read_description

    desc = read_description(go1_urdf())
    hip = import_leg(desc, "FL_hip", "FL_foot", angles=ANGLES, joint_laws=False)
    thigh_angle = hip.model.tree.bodies[0].angle + hip.model.tree.bodies[1].angle  # absolute, hip to knee
    leg = import_leg(desc, "FL_thigh", "FL_foot", angles={"FL_calf_joint": ANGLES["FL_calf_joint"]},
                     joint_laws=False)
    bodies = leg.model.tree.bodies
    model = replace(leg.model, tree=Tree((replace(bodies[0], angle=thigh_angle), *bodies[1:])))
    note = (f"{leg.summary()}\nstudies/imported_leg/run.py: the thigh's absolute angle set to {thigh_angle:.6g} rad "
            f"(thigh joint {ANGLES['FL_thigh_joint']} rad, from the import rooted at FL_hip).")
    out.write_text(format_model_file(model, header_comment=note))
    for root, name, angles in (("FL_hip", "go1_hip_leg.yaml", ANGLES),
                               ("trunk", "go1_trunk_leg.yaml", {"FL_hip_joint": 0.0, **ANGLES})):
        chain = import_leg(desc, root, "FL_foot", angles=angles, joint_laws=False)
        (out.parent / name).write_text(format_model_file(chain.model, header_comment=chain.summary()))
    return note


def optimize(study: str) -> tuple[Path, float]:
    run = HERE / "runs" / Path(study).stem
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "optimizer.cli.main", "optimize", str(HERE / study), "--out", str(run),
                    "--force", "--quiet"], check=True)
    return run, time.perf_counter() - start


def front(run: Path) -> list[dict[str, str]]:
    with open(run / "pareto.csv", newline="") as f:
        return sorted(csv.DictReader(f), key=lambda r: float(r["external_norm"]))


def main() -> None:
    print(write_leg(HERE / "go1_leg.yaml"))
    fronts = {}
    for study, leg in STUDIES:
        run, seconds = optimize(study)
        fronts[leg] = front(run)
        print(f"{leg}: {len(fronts[leg])} Pareto designs in {seconds:.1f} s")
    keys = ("trial", "shape", "external_norm", "internal_norm", "max_internal")
    with open(HERE / "fronts.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(("leg",) + keys)
        for leg, rows in fronts.items():
            for r in rows:
                w.writerow((leg,) + tuple(r[k] for k in keys))
                print(leg, *(r[k] for k in keys))
    plot(fronts)


def plot(fronts: dict[str, list[dict[str, str]]]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(12, 4.6))
    for (leg, rows), marker in zip(fronts.items(), "os^Dv", strict=True):
        ax = axes[1 if leg in ("go1_splay", "go1_trunk") else 0]
        x = [float(r["external_norm"]) for r in rows]
        y = [float(r["internal_norm"]) for r in rows]
        shapes = ", ".join(sorted({r["shape"] for r in rows}))
        ax.plot(x, y, marker=marker, linestyle="-", label=f"{LABELS[leg]}: {len(rows)} designs, shapes {shapes}")
    for ax, title in zip(axes, ("planar feet, inner search", "splayed (spatial) feet, outer search"), strict=True):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("external_norm (N s)")
        ax.set_ylabel("internal_norm (N s)")
        ax.set_title(f"{title}: 0.1 kg foot, 1 m/s plastic landing", fontsize=10)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(HERE / "fronts.png", dpi=120)


if __name__ == "__main__":
    main()
