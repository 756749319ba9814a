"""The inner search (IPOPT) against the outer search (TPE) on the same whole-landing study over 3
landings, in one run: each search's wall time and best statistics (``footopt optimize`` on
robust_inner.yaml, then robust_outer.yaml, in STUDY_DIR: this folder, or the spatial one,
studies/splayed_toes/robust_landing). IPOPT is cut to MAX_ITER iterations per solve (its
realised designs are recorded whatever its status). Prints a JSON record.

    PYTHONPATH=. python studies/whole_landing/robust/compare.py OUT_DIR [STUDY_DIR [MAX_ITER]]
    PYTHONPATH=. python studies/whole_landing/robust/compare.py OUT_DIR studies/splayed_toes/robust_landing 10
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import optimizer.search.landing_inner as landing_inner
from optimizer.cli.main import main
from optimizer.config.study_config import load_study
from optimizer.results.runs import storage_url
from optimizer.search.outer import open_study, recorded_trials

HERE = Path(__file__).parent
#: IPOPT's iterations per solve (LANDING_IPOPT's 60 take ~30 min on this study on a shared core;
#: the spatial study's 3 landings and gradients per iterate ~10-20 s: 10 there).
MAX_ITER = 15


def run(name: str, out: Path, folder: Path = HERE) -> dict:
    study = folder / f"{name}.yaml"
    t0 = time.perf_counter()
    assert main(["optimize", str(study), "--out", str(out / name), "--quiet"]) == 0
    wall = time.perf_counter() - t0
    config = load_study(study)
    evs = [t.evaluation for t in recorded_trials(open_study(config, storage_url(out / name, config)))]
    feasible = [e for e in evs if e.feasible]
    return {
        "wall_s": wall,
        "designs": len(evs),
        "feasible": len(feasible),
        "best_max_peak_external_norm": min(e.objectives.peak_external_norm for e in feasible),
        "best_mean_energy_absorbed": max(e.objectives.energy_absorbed for e in feasible),
    }


if __name__ == "__main__":
    out = Path(sys.argv[1])
    folder = Path(sys.argv[2]) if len(sys.argv) > 2 else HERE
    landing_inner.LANDING_IPOPT["ipopt.max_iter"] = int(sys.argv[3]) if len(sys.argv) > 3 else MAX_ITER
    found = {name: run(name, out, folder) for name in ("robust_inner", "robust_outer")}
    i, o = found["robust_inner"], found["robust_outer"]
    found["ratios_inner_over_outer"] = {k: i[k] / o[k] for k in ("wall_s", "best_max_peak_external_norm",
                                                                 "best_mean_energy_absorbed")}
    print(json.dumps(found, indent=1))
