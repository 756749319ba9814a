"""Spatial landings on each step code (``LandingSettings.step_code``: numpy, vm, c) in one process:
the three runs of each landing interleaved (the order reversed every other round), the best of N
rounds; the build (graph, or C from the compile cache) timed apart. Results: results.md.

Usage: PYTHONPATH=. python studies/spatial_speed/landing_step_codes.py [ROUNDS]
"""

from __future__ import annotations

import sys
import time
from dataclasses import replace
import numpy as np
from impulse_core.kinematics.spatial import SPATIAL
from impulse_core.timedomain.events.run import _Landing
from impulse_core.timedomain.landing import LandingSettings, landing_difference
from optimizer.config.model_file import load_model_file
from tests.impulse_core.test_landing_spatial import _splayed_leg

CODES = ("numpy", "vm", "c")


def case3(duration, friction=None):
    m = load_model_file("configs/spatial_case3.yaml")
    scene = replace(m.scene, duration=duration)
    if friction is not None:
        scene = replace(scene, friction=friction, gravity=9.81)
    return m.tree, m.joints, scene

def main(rounds: int) -> None:
    """Time each case's landing on the three step codes, ``rounds`` interleaved rounds each."""
    cases = {
        "spatial case 3, 0.1 s (file: e 0.8, mu 0, g 0)": case3(0.1),
        "spatial case 3, 0.05 s, mu 0.5, g 9.81": case3(0.05, 0.5),
        "splayed random leg 1 (mu 1.0, 0.05 s)": _splayed_leg(1, 1.0),
    }
    for name, (tree, laws, scene) in cases.items():
        report(name, tree, laws, scene, rounds)


def report(name, tree, laws, scene, rounds: int) -> None:
    """One case: build its landing on each step code, run them interleaved, print the best times."""
    runs, build = {}, {}
    for code in CODES:
        t = time.perf_counter()
        runs[code] = _Landing(tree, scene, laws, LandingSettings(step_code=code, integrator="rk4"), SPATIAL)
        build[code] = time.perf_counter() - t
    h = runs["numpy"].first_step()
    best, results = {c: np.inf for c in CODES}, {}
    for k in range(rounds):
        order = CODES if k % 2 == 0 else CODES[::-1]
        for code in order:
            t = time.perf_counter()
            results[code] = runs[code].run(h)
            best[code] = min(best[code], time.perf_counter() - t)
    ref = results["numpy"]
    print(f"## {name}: h = {h:.3g} s, {ref.n_steps} steps, {len(ref.events)} events")
    for code in CODES:
        r = results[code]
        same = (r.n_steps, len(r.events)) == (ref.n_steps, len(ref.events))
        print(f"  {code:5s} build {build[code]:6.2f} s  run best {best[code]:7.3f} s  "
              f"numpy/this {best['numpy'] / best[code]:5.2f}  same decisions {same}  "
              f"landing_difference {landing_difference(r, ref):.1e}")
    sys.stdout.flush()


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 3)
