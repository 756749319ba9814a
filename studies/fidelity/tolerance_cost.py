"""What an accuracy costs: footopt's compliant rung and MuJoCo on the same soft contacts (issue #12, item 8).

Scene: ``configs/uneven_terrain.yaml`` (case 2's foot, toe on a ramp, heel 5.4 ms later), both
models with MuJoCo's soft-constraint law at stiffness 1e8 1/s^2 (direct solref, the damping for
e = 0.8, impedance 0.9999), frictionless, gravity off. Each model's error is measured against
its own converged answer (the same model at 1024 x the compliant rung's default steps per
contact period): the relative difference of the external impulses, then of the joint impulses
(MODEL_FORMAT's "relative"), the larger. The compliant rung runs ``--tolerance`` (it doubles its
steps until two runs differ by less: ``simulate_to_tolerance``); MuJoCo runs at fixed steps,
doubled from the compliant rung's default until it meets the tolerance against its converged
answer. Cost: the best of 3 wall times of the run that met the tolerance (the compliant rung's
includes its coarser runs, which is what ``--tolerance`` costs). One run, one process.

Run: python studies/fidelity/tolerance_cost.py (writes tolerance_cost.md next to this file)
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np

from impulse_core.evaluate import pre_impact_velocity
from impulse_core.timedomain.compliant import (
    CompliantSettings,
    ContactLaw,
    simulate_impact,
    simulate_to_tolerance,
)
from optimizer.config.model_file import load_model_file
from optimizer.validation.mujoco_bridge import drop

HERE = Path(__file__).resolve().parent
SCENE_FILE = HERE.parents[1] / "configs" / "uneven_terrain.yaml"
SETTINGS = CompliantSettings(law=ContactLaw.CONSTRAINT, stiffness=1e8)
TOLERANCES = (1e-3, 1e-4, 1e-5)
FINE = 1024  # the converged answers: 1024 x the default steps per period


def relative(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / np.abs(b).max())


def error(ext, internal, ref_ext, ref_int) -> float:
    return max(relative(ext, ref_ext), relative(internal, ref_int))


def best_time(run) -> tuple[float, object]:
    best, out = float("inf"), None
    for _ in range(3):
        start = time.perf_counter()
        out = run()
        best = min(best, time.perf_counter() - start)
    return best, out


def mujoco_at(tree, scene, n_per_period: float):
    """MuJoCo over the compliant rung's impact window at ``n_per_period`` steps per period."""
    settings = dataclasses.replace(SETTINGS, steps_per_period=n_per_period, flight_step=None)
    soft = simulate_impact(tree, scene, settings)
    steps = int(round(soft.duration / soft.timestep))
    v = pre_impact_velocity(tree.topology(), scene)
    return lambda: drop(tree, scene, settings, steps, soft.timestep, v_minus=v)


def main() -> None:
    model = load_model_file(SCENE_FILE)
    tree, scene = model.tree, dataclasses.replace(model.scene, friction=0.0)
    n0 = SETTINGS.steps_per_period
    fine = simulate_impact(tree, scene, dataclasses.replace(SETTINGS, steps_per_period=FINE * n0))
    mj_fine = mujoco_at(tree, scene, FINE * n0)()
    rows = []
    for tol in TOLERANCES:
        seconds, r = best_time(lambda: simulate_to_tolerance(tree, scene, SETTINGS, tol, max_doublings=9))
        err = error(r.external, r.internal_magnitude, fine.external, fine.internal_magnitude)
        rows.append((tol, "footopt compliant (--tolerance)", r.steps_per_period, err, r.error_estimate, seconds))
        n = n0
        while True:
            mj = mujoco_at(tree, scene, n)()
            err = error(mj.external, mj.internal_magnitude, mj_fine.external, mj_fine.internal_magnitude)
            if err <= tol or n >= FINE * n0 / 4:
                break
            n *= 2
        seconds, mj = best_time(mujoco_at(tree, scene, n))
        rows.append((tol, "MuJoCo (fixed steps)", n, err, None, seconds))
    lines = [
        "# The cost of an accuracy: footopt's compliant rung and MuJoCo",
        "",
        "`python studies/fidelity/tolerance_cost.py`; what is measured: the script's docstring. Both errors are",
        "each model's own discretisation error (against itself at 1024 x the default steps per period).",
        "",
        "| tolerance | model | steps per period | error | estimate | seconds | cost / MuJoCo's |",
        "|---|---|---|---|---|---|---|",
    ]
    for k in range(0, len(rows), 2):
        ours, theirs = rows[k], rows[k + 1]
        for tol, name, n, err, estimate, seconds in (ours, theirs):
            est = "-" if estimate is None else f"{estimate:.1e}"
            lines.append(f"| {tol:g} | {name} | {n:g} | {err:.1e} | {est} | {seconds:.3f} | {seconds / theirs[5]:.2f} |")
    text = "\n".join(lines + [""])
    (HERE / "tolerance_cost.md").write_text(text, encoding="utf-8")
    print(text)


if __name__ == "__main__":
    main()
