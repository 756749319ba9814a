"""The exact landing gradient's cost and accuracy (impulse_core.timedomain.landing_derivatives).

For each case: one landing evaluation as a study makes it (``landing()`` at the default tolerance,
its step halvings included), the gradient along the reported run's event sequence (``cold``: the
first design of its structure, building each mode's functions; ``warm``: a second design of the
same structure, as in a search), their ratio, and the gradient against central differences of
the numeric landing at the same step along three seeded directions (lengths, masses, angles and
joint-law values; the event sequence checked unchanged at both ends, and the slow slip's steps
split as in the nominal run, ``taped_run(halvings=)``). ``along 8``: the same
gradients carried along 8 seeded directions only (``landing_gradient(directions=...)``, forward
mode, as the whole-landing inner search uses it with its variables), cold (the symbolic
structures dropped first) and warm, and its largest difference from the full Jacobian times the
directions (relative to the largest entry). All figures come from one
run of this script on one machine, so only the ratios travel.

    .venv/bin/python studies/landing_gradient/bench.py            # writes results.md beside it
"""

from __future__ import annotations

import re
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from impulse_core.kinematics.spatial import PLANAR, SPATIAL  # noqa: E402
from impulse_core.timedomain import landing_derivatives  # noqa: E402
from impulse_core.timedomain.landing import LandingSettings, landing  # noqa: E402
from impulse_core.timedomain.landing_derivatives import (  # noqa: E402
    SCALARS,
    apply_theta,
    landing_gradient,
    sequence_signature,
    taped_run,
)
from optimizer.config.model_file import load_model_file  # noqa: E402
from tests.impulse_core.test_landing import _random_leg  # noqa: E402
from tests.impulse_core.test_landing_derivatives import _stop_leg  # noqa: E402
from tests.impulse_core.test_landing_derivatives_spatial import _splayed_stop_leg  # noqa: E402


def cases():
    m = load_model_file(ROOT / "configs/landing_case3.yaml")
    yield "landing_case3 (0.3 s, friction 0.5, springs, knee stops)", m.tree, m.joints, m.scene, PLANAR
    tree, laws, scene = _stop_leg()
    yield "knee stop leg (0.04 s, frictionless)", tree, laws, scene, PLANAR
    tree, laws, scene = _random_leg(0)
    yield "random leg 0 (0.05 s, friction 1)", tree, laws, scene, PLANAR
    tree, laws, scene, _ = _splayed_stop_leg()
    yield "splayed knee stop leg, space (0.02 s, friction 0.8, toe and heel yawed, oblique)", tree, laws, scene, SPATIAL


def vector(r) -> np.ndarray:
    return np.concatenate([[getattr(r, k) for k in SCALARS], r.total_external, r.final_angles])


def along_directions(g, J, tree, laws, tree2, laws2, scene, settings, h, space, searched) -> tuple[tuple, float]:
    """Cold and warm seconds of the gradient along 8 seeded directions over the searched values
    (no scene value moved), and its largest difference from ``J`` times them (relative)."""
    D = np.zeros((len(g.theta) + len(g.scene_theta), 8))
    D[: len(g.theta)] = np.random.default_rng(5).standard_normal((len(g.theta), 8)) * searched[:, None]
    landing_derivatives._SYMBOLIC.clear()
    times = []
    for t, l in ((tree, laws), (tree2, laws2)):
        t0 = time.perf_counter()
        along = landing_gradient(t, scene, l, settings, step=h, space=space, directions=D)
        times.append(time.perf_counter() - t0)
        if t is tree:
            Ja = np.vstack([along.jacobian[k] for k in SCALARS]
                           + [along.jacobian["total_external"], along.jacobian["final_angles"]])
    expected = J @ D[: len(g.theta)]
    return tuple(times), float(np.max(np.abs(Ja - expected)) / np.max(np.abs(expected)))


def main() -> None:
    lines = ["| case | events | steps | landing() s | taped run s | gradient cold s | gradient warm s | "
             "warm / landing() | cold / landing() | central FD (2 n runs) / landing() | rel. error vs FD, 3 directions | "
             "the same, masses and laws only, toes tied | along 8: cold s, warm s | along 8 warm / full warm | "
             "along 8 vs full x D |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, tree, laws, scene, space in cases():
        settings = LandingSettings()
        t0 = time.perf_counter()
        result = landing(tree, scene, laws, settings, space)
        t_landing = time.perf_counter() - t0
        h = result.step
        t0 = time.perf_counter()
        # the nominal run's slow-slip splits: the +-eps runs below follow them (a split is a threshold
        # decision, so the branch the derivatives hold is the nominal run's; taped_run's docstring)
        halvings = list(taped_run(tree, scene, laws, h, space=space)[2].slip_halvings)
        t_run = time.perf_counter() - t0
        t0 = time.perf_counter()
        g = landing_gradient(tree, scene, laws, settings, step=h, space=space)
        t_cold = time.perf_counter() - t0
        searched = np.array([n.endswith(("length", "mass", "angle", "roll", "pitch", "yaw", "stiffness", "damping"))
                             for n in g.names])
        # a second design of the same structure: masses and lengths 0.1 % larger
        theta2 = g.theta * (1 + 1e-3 * np.array([n.endswith(("length", "mass")) for n in g.names]))
        tree2, laws2 = apply_theta(tree, laws, theta2, space)
        t0 = time.perf_counter()
        landing_gradient(tree2, scene, laws2, settings, step=h, space=space)
        t_warm = time.perf_counter() - t0
        print(name, "landing()", t_landing, "run", t_run, "cold", t_cold, "warm", t_warm, flush=True)
        J = np.vstack([g.jacobian[k] for k in SCALARS] + [g.jacobian["total_external"], g.jacobian["final_angles"]])
        t_along, along_err = along_directions(g, J, tree, laws, tree2, laws2, scene, settings, h, space, searched)
        rng = np.random.default_rng(0)
        worst, kept = 0.0, []
        for _ in range(3):
            u = rng.standard_normal(len(g.theta)) * np.maximum(1.0, np.abs(g.theta)) * searched
            eps = 1e-6
            ends, same = [], True
            for sgn in (1, -1):
                t, l = apply_theta(tree, laws, g.theta + sgn * eps * u, space)
                r, tape, run = taped_run(t, scene, l, h, space=space, halvings=halvings)
                ends.append(vector(r))
                same = same and sequence_signature(tape, run) == g.sequence
            fd, exact = (ends[0] - ends[1]) / (2 * eps), J @ u
            err = float(np.max(np.abs(fd - exact) / np.maximum(np.abs(exact), 1e-9)))
            kept.append(f"{err:.0e}" + ("" if same else "*"))
            worst = max(worst, err) if same else worst
        # masses and law values only: no tip moves, so no tie of lowest contacts at touchdown
        # (landing_case3's soles all touch at once: its touchdown height has a kink in lengths and angles)
        # and tied across numbered toes (toe1_x, toe2_x, ... move alike: landing_case3's three identical toes
        # keep their symmetry; moving one alone changes how they touch and re-touch, a jump)
        still = np.array([n.endswith(("mass", "stiffness", "damping")) for n in g.names])
        groups = [re.sub(r"toe\d+", "toe", n) for n in g.names]
        draw = {k: rng.standard_normal() for k in sorted(set(groups))}
        u = np.array([draw[k] for k in groups]) * np.maximum(1.0, np.abs(g.theta)) * still
        ends, same = [], True
        for sgn in (1, -1):
            t, l = apply_theta(tree, laws, g.theta + sgn * 1e-6 * u, space)
            r, tape, run = taped_run(t, scene, l, h, space=space, halvings=halvings)
            ends.append(vector(r))
            same = same and sequence_signature(tape, run) == g.sequence
        fd, exact = (ends[0] - ends[1]) / 2e-6, J @ u
        still_err = f"{float(np.max(np.abs(fd - exact) / np.maximum(np.abs(exact), 1e-9))):.0e}" + ("" if same else "*")
        n = int(searched.sum())
        lines.append(
            f"| {name} | {len(g.result.events)} | {g.result.n_steps} | {t_landing:.2f} | {t_run:.2f} | {t_cold:.2f} | "
            f"{t_warm:.2f} | {t_warm / t_landing:.2f} | {t_cold / t_landing:.2f} | {2 * n * t_run / t_landing:.1f} "
            f"({n} values) | {', '.join(kept)} | {still_err} | {t_along[0]:.2f}, {t_along[1]:.2f} | "
            f"{t_along[1] / t_warm:.2f} | {along_err:.0e} |"
        )
        print(lines[-1], flush=True)
    text = "\n".join(lines)
    out = Path(__file__).parent / "results.md"
    out.write_text(
        "# The exact landing gradient: cost and accuracy\n\n"
        "`.venv/bin/python studies/landing_gradient/bench.py` (one run, one machine; ratios to that run's "
        "`landing()` at the default tolerance). `cold`: the first design of a structure (each mode's "
        "functions and their Jacobians built); `warm`: a second design of the same structure. The gradient "
        "is taken at the step `landing()` reports and costs a taped run at that step plus the sensitivity "
        "sweep; `landing_gradient(step=None)` adds one `landing()`. Errors: max over the outputs of "
        "|FD - exact| / |exact| along a seeded direction, central differences at eps = 1e-6 (relative); `*`: the "
        "event sequence at +- eps differs from the reported one (so the difference quotient straddles a change "
        "of sequence: where the objectives are continuous across it (micro-events at tolerance thresholds) the "
        "quotient still agrees; where they are not, it is no test of the derivative). The directions move lengths, "
        "masses, angles (rpy angles in space) and joint-law values; the last column masses and law values only, "
        "which move no tip, with "
        "every numbered toe's values moved alike. landing_case3's soles all touch at once (`contacts: all`, level "
        "tips), so its touchdown height, the lowest contact's, has a kink in the lengths and angles that a central "
        "difference straddles; and its three toes are identical, so moving one toe's values alone breaks their "
        "symmetry and changes how they touch and re-touch: a jump of the objectives, not a derivative. `along 8`: the "
        "gradient along 8 seeded directions over the searched values only (`landing_gradient(directions=...)`, "
        "forward mode: what the whole-landing inner search uses where its variables are at most a quarter of "
        "theta's and the scene's values), cold (the symbolic structures dropped first) and warm, its warm time "
        "over the full warm gradient's, and its largest difference from the full Jacobian times the directions "
        "(relative to the largest entry).\n\n" + kept_notes(out) + text + "\n"
    )


def kept_notes(path: Path) -> str:
    """The dated notes of ``path`` (its paragraphs starting "Run "), each followed by a blank line,
    so that a rerun replaces the table and keeps what was written about earlier runs."""
    if not path.exists():
        return ""
    return "".join(p + "\n\n" for p in path.read_text().split("\n\n") if p.startswith("Run "))


if __name__ == "__main__":
    main()
