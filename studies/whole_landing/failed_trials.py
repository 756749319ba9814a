"""Re-land the designs whose landings failed numerically in a whole-landing run (issue #13's
study saw 28 % of its trials fail).

The first call reads the failed trials' parameters from the run's Optuna storage and keeps them in
`failed_trials.json` (so they survive a rerun of the study, which replaces `run/`; `--kept FILE`
names another file); every call re-lands each of those designs as the study does (its scene and
joint laws, its budget `STUDY_LANDING` at its tolerance) and prints how many land now, and why
the others fail.

Kept here: `failed_trials.json`, the 34 of the first run (commit d4abda4, before the implicit
integrator and the identical-toes fixes), and `failed_trials_rerun.json`, the 10 of the rerun.

Usage: python studies/whole_landing/failed_trials.py [--run DIR] [--kept FILE] [--only N ...]
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import optuna

from impulse_core.errors import NumericalError
from impulse_core.timedomain.landing import landing
from optimizer.config.study_config import load_study
from optimizer.design_space import STUDY_LANDING, foot_joint_laws, foot_tree, landing_scene
from optimizer.results.runs import storage_url
from optimizer.search.outer import open_study, suggest_design

HERE = Path(__file__).resolve().parent
KEPT = HERE / "failed_trials.json"


def failed_params(run_dir: Path) -> list[dict]:
    config = load_study(HERE / "study.yaml")
    study = open_study(config, storage_url(run_dir, config))
    out = []
    for t in study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.FAIL,)):
        if t.user_attrs.get("interrupted"):
            continue
        out.append({"trial": t.number, "params": dict(t.params)})
    return out


def land(config, params: dict) -> tuple[str, float, int]:
    """(outcome, seconds, impacts): 'landed' or the failure's message."""
    design = suggest_design(optuna.trial.FixedTrial(params), config)
    tree = foot_tree(config.leg, design)
    laws = foot_joint_laws(config.leg, design, config.space.joint_laws.stop_restitution)
    scene = landing_scene(config.scene, config.limits)
    t0 = time.perf_counter()
    try:
        with np.errstate(all="ignore"):
            r = landing(tree, scene, laws, replace(STUDY_LANDING, tolerance=config.search.landing_tolerance))
    except (NumericalError, ArithmeticError, np.linalg.LinAlgError, ValueError) as exc:
        return f"{type(exc).__name__}: {exc}", time.perf_counter() - t0, -1
    return "landed", time.perf_counter() - t0, len(r.events)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run", type=Path, default=HERE / "run")
    parser.add_argument("--kept", type=Path, default=KEPT)
    parser.add_argument("--only", type=int, nargs="*")
    args = parser.parse_args()
    if not args.kept.exists():
        args.kept.write_text(json.dumps(failed_params(args.run), indent=1) + "\n", encoding="utf-8")
    kept = json.loads(args.kept.read_text(encoding="utf-8"))
    config = load_study(HERE / "study.yaml")
    landed = 0
    for item in kept:
        if args.only and item["trial"] not in args.only:
            continue
        outcome, seconds, impacts = land(config, item["params"])
        landed += outcome == "landed"
        print(f"trial {item['trial']:4d}: {outcome} ({seconds:.1f} s, {impacts} impacts)", flush=True)
    n = len(args.only) if args.only else len(kept)
    print(f"{landed} of {n} previously failed designs land now")


if __name__ == "__main__":
    main()
