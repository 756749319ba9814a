"""What an accuracy costs: footopt's compliant rung, adaptive and with fixed steps, and MuJoCo on the
same soft contacts (issue #12: "the compliant rung at --tolerance 1e-4 on the uneven-terrain example:
at most 0.1 x the time that fixed steps need for the same error").

Scene: ``configs/uneven_terrain.yaml`` (case 2's foot, toe on a ramp, heel 5.4 ms later),
frictionless, gravity off, under two laws: the CLI's default (penalty, 1e6 N/m) and MuJoCo's
soft-constraint law at 1e8 1/s^2 (direct solref, the damping for e = 0.8, impedance 0.9999), which
MuJoCo runs too. Each model's error is measured against its own converged answer: footopt's is the
adaptive integration at a local tolerance of 1e-9 (the fixed steps converge to it at first order:
tests/impulse_core/test_compliant_adaptive.py), MuJoCo's its run at 1024 x 120 steps per period;
the error is MODEL_FORMAT's relative difference of the external, then of the joint impulses, the
larger. Rows per tolerance:

* adaptive: ``--tolerance`` now (``simulate_to_tolerance``: Dormand-Prince 5(4) between located
  contact switches, two runs at local tolerances 4 apart; its cost includes both);
* fixed, same error: footopt's fixed semi-implicit Euler steps at the fewest steps per period (on a
  grid of ratio 2^(1/4) from 120) whose error is at most the adaptive answer's: the target's
  comparison. Chosen with the converged answer in hand (an oracle a user does not have);
* fixed, tolerance: the same, the fewest steps whose error meets the tolerance (also an oracle);
* doubling: ``--tolerance`` before (fixed steps doubled from 120 until two runs differ by less;
  its cost includes the coarser runs);
* MuJoCo (constraint law only): fixed steps doubled from 120 until its error meets the tolerance
  (an oracle, as before).

Cost: the best wall time of 3 or more runs (up to 20, until 0.5 s are spent), all in one process,
one after another. Run: python
studies/fidelity/tolerance_cost.py (writes tolerance_cost.md next to this file; a few minutes).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from impulse_core.evaluate import pre_impact_velocity
from impulse_core.timedomain.adaptive import simulate_adaptive
from impulse_core.timedomain.compliant import (
    DOUBLING,
    CompliantResult,
    CompliantSettings,
    ContactLaw,
    compliant_difference,
    simulate_impact,
    simulate_to_tolerance,
)
from optimizer.config.model_file import load_model_file
from optimizer.validation.mujoco_bridge import drop

HERE = Path(__file__).resolve().parent
SCENE_FILE = HERE.parents[1] / "configs" / "uneven_terrain.yaml"
LAWS = {
    "penalty 1e6 N/m (CLI default)": CompliantSettings(),
    "constraint 1e8 1/s^2 (MuJoCo's)": CompliantSettings(law=ContactLaw.CONSTRAINT, stiffness=1e8),
}
TOLERANCES = (1e-3, 1e-4, 1e-5)
CONVERGED = 1e-9  # footopt's converged answer: adaptive at this local tolerance
FINE = 1024  # MuJoCo's converged answer: 1024 x the default steps per period
GRID = 2.0**0.25  # the fixed steps' search grid


def best_time(run: Callable[[], object]) -> tuple[float, object]:
    """The best wall time of at least 3 runs, more (up to 20) until 0.5 s have passed: short runs
    on a shared machine need more tries to find their unloaded time."""
    best, out, spent, tries = float("inf"), None, 0.0, 0
    while tries < 3 or spent < 0.5 and tries < 20:
        start = time.perf_counter()
        out = run()
        elapsed = time.perf_counter() - start
        best, spent, tries = min(best, elapsed), spent + elapsed, tries + 1
    return best, out


def fixed(tree, scene, settings: CompliantSettings, n: float) -> CompliantResult:
    return simulate_impact(tree, scene, dataclasses.replace(settings, steps_per_period=n))


def fewest_fixed_steps(tree, scene, settings, converged, target: float) -> float:
    """The fewest steps per period on the grid whose error is at most ``target`` (first order:
    start from the prediction of 120 steps' error, then walk the grid)."""
    n0 = settings.steps_per_period
    predicted = n0 * compliant_difference(fixed(tree, scene, settings, n0), converged) / target
    k = max(0, int(np.floor(np.log(predicted / n0) / np.log(GRID))) - 1)
    while compliant_difference(fixed(tree, scene, settings, n0 * GRID**k), converged) > target:
        k += 1
    while k > 0 and compliant_difference(fixed(tree, scene, settings, n0 * GRID ** (k - 1)), converged) <= target:
        k -= 1
    return n0 * GRID**k


def mujoco_at(tree, scene, settings, n_per_period: float) -> Callable[[], object]:
    """MuJoCo over the compliant rung's impact window at ``n_per_period`` steps per period."""
    settings = dataclasses.replace(settings, steps_per_period=n_per_period, flight_step=None)
    soft = simulate_impact(tree, scene, settings)
    steps = int(round(soft.duration / soft.timestep))
    v = pre_impact_velocity(tree.topology(), scene)
    return lambda: drop(tree, scene, settings, steps, soft.timestep, v_minus=v)


def mujoco_row(tree, scene, settings, tol: float, reference) -> tuple:
    n = settings.steps_per_period
    while True:
        mj = mujoco_at(tree, scene, settings, n)()
        err = compliant_difference(mj, reference)
        if err <= tol or n >= FINE * settings.steps_per_period / 4:
            break
        n *= 2
    seconds, _ = best_time(mujoco_at(tree, scene, settings, n))
    return "MuJoCo, fixed steps meeting the tolerance", n, err, None, seconds


def rows_at(tree, scene, settings, tol: float, converged, mj_reference) -> list[tuple]:
    """(method, steps per period, error, estimate, seconds) of each row at ``tol``."""
    seconds, ours = best_time(lambda: simulate_to_tolerance(tree, scene, settings, tol))
    rows = [("adaptive (--tolerance)", ours.steps_per_period, compliant_difference(ours, converged),
             ours.error_estimate, seconds)]
    for name, target in (("fixed steps, same error", rows[0][2]), ("fixed steps meeting the tolerance", tol)):
        n = fewest_fixed_steps(tree, scene, settings, converged, target)
        seconds, r = best_time(lambda: fixed(tree, scene, settings, n))
        rows.append((name, n, compliant_difference(r, converged), None, seconds))
    seconds, r = best_time(lambda: simulate_to_tolerance(tree, scene, settings, tol, max_doublings=9, method=DOUBLING))
    rows.append(("doubling (--tolerance before)", r.steps_per_period, compliant_difference(r, converged),
                 r.error_estimate, seconds))
    if mj_reference is not None:
        rows.append(mujoco_row(tree, scene, settings, tol, mj_reference))
    return rows


def table(results: dict) -> list[str]:
    lines = [
        "| law | tolerance | method | steps per period | error | estimate | seconds | / fixed, same error | / MuJoCo |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for (law, tol), rows in results.items():
        same, mujoco = rows[1][4], (rows[4][4] if len(rows) > 4 else None)
        for name, n, err, estimate, seconds in rows:
            est = "-" if estimate is None else f"{estimate:.1e}"
            vs_mj = "-" if mujoco is None else f"{seconds / mujoco:.3f}"
            lines.append(f"| {law} | {tol:g} | {name} | {n:.4g} | {err:.1e} | {est} | {seconds:.4f} | "
                         f"{seconds / same:.3f} | {vs_mj} |")
    return lines


def reading(results: dict) -> list[str]:
    """The verdict on the target and what the table shows, from its numbers."""
    at = {law: rows for (law, tol), rows in results.items() if tol == 1e-4}
    same = [rows[0][4] / rows[1][4] for rows in at.values()]
    meeting = [rows[0][4] / rows[2][4] for rows in at.values()]
    mujoco = [rows[0][4] / rows[4][4] for rows in at.values() if len(rows) > 4]
    ratio = [rows[0][3] / rows[0][2] for rows in results.values()]
    steps = [rows[1][1] / rows[2][1] for rows in results.values()]
    verdict = "met" if max(same) <= 0.1 else "not met"
    above = "above" if min(ratio) >= 1.0 else "NOT always above"
    return [
        f"**Target (issue #12) {verdict}**: at --tolerance 1e-4 the adaptive rung takes "
        + " and ".join(f"{x:.3f}" for x in same)
        + " x the time of fixed steps at the same error (penalty, constraint law; target 0.1 x), same run.",
        "Against fixed steps that merely meet the tolerance (a less accurate answer, their step chosen with the",
        "converged answer in hand) it takes " + " and ".join(f"{x:.2f}" for x in meeting) + " x, and against",
        "MuJoCo's fixed steps meeting the tolerance " + " ".join(f"{x:.2f}" for x in mujoco) + " x.",
        "",
        "Reading: the adaptive rung is fifth order between the located contact switches, so its cost hardly",
        "grows with the accuracy (mostly the events: each touchdown and release located by a few trial",
        "steps), while fixed steps are first order (10 x the steps per 10 x the accuracy). Its answer is",
        "several times more accurate than the tolerance asks (the two runs' difference, its estimate,",
        f"must fall below it), so fixed steps at the same error need {min(steps):.0f} to {max(steps):.0f} x the steps "
        f"that meet the tolerance. The estimate is {above} the error in the adaptive rows, by "
        + f"{min(ratio):.1f} to {max(ratio):.1f} x. Timings are wall times on a machine shared with other",
        "jobs: the ratios within a row's tolerance are the comparison, the absolute seconds are not.",
    ]


def main() -> None:
    model = load_model_file(SCENE_FILE)
    tree, scene = model.tree, dataclasses.replace(model.scene, friction=0.0)
    results = {}
    for law, settings in LAWS.items():
        converged = simulate_adaptive(tree, scene, settings, CONVERGED)
        mj_reference = None
        if settings.law is ContactLaw.CONSTRAINT:
            mj_reference = mujoco_at(tree, scene, settings, FINE * settings.steps_per_period)()
        for tol in TOLERANCES:
            results[law, tol] = rows_at(tree, scene, settings, tol, converged, mj_reference)
            print(law, tol, results[law, tol], flush=True)
    lines = [
        "# The cost of an accuracy: footopt's compliant rung, adaptive and fixed, and MuJoCo",
        "",
        "`python studies/fidelity/tolerance_cost.py`; what is measured: the script's docstring. Errors are each",
        "model's own discretisation error (footopt against its adaptive answer at a local tolerance of 1e-9,",
        "MuJoCo against itself at 1024 x 120 steps per period). For the adaptive rows, steps per period is",
        "the contact period over the mean step while a contact touches.",
        "",
        *table(results),
        "",
        *reading(results),
    ]
    text = "\n".join(lines + [""])
    (HERE / "tolerance_cost.md").write_text(text, encoding="utf-8")
    print(text)


if __name__ == "__main__":
    main()
