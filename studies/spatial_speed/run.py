"""Speed of the spatial core (issue #15): case 3 with three splayed two-rod toes, batched, beside
one Pinocchio ``impulseDynamics`` call per design and beside the planar case 3, in one run.

Run from the repository root: ``python studies/spatial_speed/run.py`` (writes results.md here).
Interleaved rounds, best of 5; each batched figure is per design over 2000 designs (the design
vector jittered by 1 %). The Pinocchio call gets its contact Jacobian precomputed (its cost is
not counted), so the ratio favours Pinocchio.
"""

from __future__ import annotations

import dataclasses
import platform
import tempfile
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

from impulse_core.compile.batch import batch_evaluator
from impulse_core.evaluate import evaluate
from impulse_core.kinematics.spatial import PLANAR, SPATIAL
from impulse_core.model.tree import design_vector
from optimizer.config.model_file import load_model_file
from optimizer.validation.pinocchio_bridge import build, build_spatial

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
N = 2000
ROUNDS = 5


def fractions(topology, space) -> np.ndarray:
    """Indices of the design vector's fractions (at, com, contacts), which stay <= 1."""
    n = len(space.body_values)
    per_body = [b * n + space.body_values.index(k) for b in range(topology.n_bodies) for k in ("at", "com")]
    return np.array(per_body + list(range(n * topology.n_bodies, n * topology.n_bodies + sum(topology.n_contacts))))


def case(file: str, space, builder):
    """(batched evaluator, with gradients, design rows, Pinocchio call) for one model file."""
    m = load_model_file(REPO / "configs" / file)
    scene = dataclasses.replace(m.scene, velocity_x=0.0, velocity_z=0.0, angular_velocity=0.0, angular_velocity_x=0.0)
    r = evaluate(m.tree, scene, space=space)
    topology = m.tree.topology(r.active)
    cache = tempfile.mkdtemp()
    plain = batch_evaluator(topology, cache, space=space)
    grad = batch_evaluator(topology, cache, space=space, gradient=True)
    rng = np.random.default_rng(0)
    p = design_vector(m.tree, space.body_values)
    P = p * (1 + 0.01 * rng.uniform(-1, 1, (N, p.size)))
    P = np.minimum(P, np.where(np.isin(np.arange(p.size), fractions(topology, space)), 1.0, np.inf))
    first = plain(p[None, :], scene.speed, scene.restitution).external[0]
    assert np.allclose(first, r.external[list(r.active)], rtol=1e-10), "batched != evaluate"
    pt = builder(m.tree)
    data = pt.model.createData()
    J = pt.normal_jacobian(r.active)
    v = pt.to_pin_velocity(r.v_minus)

    def pinocchio() -> None:
        for _ in range(N):
            pin.impulseDynamics(pt.model, data, pt.q, v, J, scene.restitution, 0.0)

    return (
        lambda: plain(P, scene.speed, scene.restitution),
        lambda: grad(P, scene.speed, scene.restitution),
        pinocchio,
    )


def best(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return (time.perf_counter() - t0) / N


def main() -> None:
    cases = {"spatial": case("spatial_case3.yaml", SPATIAL, build_spatial), "planar": case("paper_case3.yaml", PLANAR, build)}
    times = {(k, j): float("inf") for k in cases for j in range(3)}
    for _ in range(ROUNDS):
        for k, fns in cases.items():
            for j, fn in enumerate(fns):
                times[k, j] = min(times[k, j], best(fn))
    rows = []
    for k in cases:
        ev, gr, pn = (times[k, j] * 1e6 for j in range(3))
        rows.append(f"| {k} case 3 | {ev:.3f} | {gr:.3f} | {pn:.2f} | {ev / pn:.3f} | {gr / ev:.2f} |")
    s, p = times["spatial", 0], times["planar", 0]
    text = "\n".join(
        [
            "# Spatial core speed (issue #15)",
            "",
            f"Produced by `python studies/spatial_speed/run.py` on {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, "
            f"{platform.machine()}, Pinocchio {pin.__version__}; one run, interleaved, best of {ROUNDS} rounds of {N} designs.",
            "",
            "| model | batched evaluation [us/design] | with both gradients [us/design] | Pinocchio impulseDynamics [us/call] "
            "| evaluation / Pinocchio | gradients / evaluation |",
            "|---|---|---|---|---|---|",
            *rows,
            "",
            f"Spatial / planar batched evaluation: {s / p:.2f}. Targets (issue #15): evaluation <= 0.1 x Pinocchio; "
            "gradients <= 3 x an evaluation.",
            "",
        ]
    )
    (HERE / "results.md").write_text(text, encoding="utf-8")
    print(text)


if __name__ == "__main__":
    main()
