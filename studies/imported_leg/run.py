"""studies/imported_leg: a footopt foot on a real quadruped's imported leg, against the default leg.

1. ``footopt import`` of Unitree Go1's front left thigh and calf (example-robot-data's go1.urdf, a
   test extra), standing posture (thigh joint 0.9 rad, calf -1.8 rad), exact: centres of mass
   where they are, off the rods (``com_offset``; until the offsets reached studies the leg was
   imported with ``--com-on-rods``) and joint laws left out (the objectives are first-impact
   ones): ``go1_leg.yaml``. The thigh is the floating base, so its
   absolute angle comes from the same import rooted at the hip (the thigh joint on the chain).
2. ``footopt optimize`` of the same Go1-sized foot search (go1.yaml) on that leg and on footopt's
   default leg (default.yaml): the inner search, 6 foot shapes.
3. The two fronts: ``fronts.csv``, ``fronts.png`` and the numbers quoted in results.md.

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


def go1_urdf() -> Path:
    dist = md.distribution("example-robot-data")
    return next(Path(dist.locate_file(f)) for f in dist.files if str(f).endswith("go1_description/urdf/go1.urdf"))


def write_leg(out: Path) -> str:
    """The two-rod leg file; returns its summary."""
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
    for study, leg in (("go1.yaml", "go1"), ("default.yaml", "default")):
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

    fig, ax = plt.subplots(figsize=(6, 4.2))
    for (leg, rows), marker in zip(fronts.items(), "os", strict=True):
        x = [float(r["external_norm"]) for r in rows]
        y = [float(r["internal_norm"]) for r in rows]
        label = "Go1 front left leg (footopt import)" if leg == "go1" else "default leg (0.7 m, 1 kg rods)"
        shapes = ", ".join(sorted({r["shape"] for r in rows}))
        ax.plot(x, y, marker=marker, linestyle="-", label=f"{label}: {len(rows)} designs, shapes {shapes}")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("external_norm (N s)")
    ax.set_ylabel("internal_norm (N s)")
    ax.set_title("Pareto fronts (toes x rods): 0.1 kg foot, 1 m/s plastic landing", fontsize=10)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(HERE / "fronts.png", dpi=120)


if __name__ == "__main__":
    main()
