"""The whole-landing inner search with and without the support margin's rows (issue #15), the
same random starts, interleaved in one run: per start, one anchor solve (peak_external_norm, IPOPT
cut to ``--iterations``) of each NLP, its realised design kept or not (the study's evaluation),
its support margin, wall time and landings (values and gradients). The NLPs: ``--forms`` of the
rows (``distance``, the default form, and ``quadratic``, the earlier one:
:func:`optimizer.search.compiled._support_rows`; ``rows``: the default form, under the name the
first run used) and ``no_rows``. Writes ``landing_margin.json`` (``--out``).

    python studies/splayed_toes/landing_margin.py [--starts 4] [--iterations 10] [--seed S] [--out F]
        [--forms rows,no_rows]
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

import optimizer.search.landing_inner as landing_inner
from optimizer.config.study_config import load_study
from optimizer.design_space import FootShape, foot_support_margin
from optimizer.search.landing_inner import LandingNlp, build_landing_nlp, realise_landing, solve_landing, start_landing

HERE = Path(__file__).parent


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--starts", type=int, default=4)
    parser.add_argument("--iterations", type=int, default=10)
    parser.add_argument("--seed", type=int, default=None, help="the starts' seed (default: the study's)")
    parser.add_argument("--out", default="landing_margin.json", help="file name, in this folder")
    parser.add_argument("--forms", default="rows,no_rows", help="the NLPs, comma-separated (module docstring)")
    args = parser.parse_args()
    config = load_study(HERE / "landing_margin.yaml")
    shape = FootShape(2, 1)

    def nlp_of(name: str) -> LandingNlp:
        if name == "no_rows":
            return build_landing_nlp(config, shape, margin_rows=False)
        return build_landing_nlp(config, shape, margin_form="distance" if name == "rows" else name)

    names = args.forms.split(",")
    nlps = {name: nlp_of(name) for name in names}
    seed = config.seed if args.seed is None else args.seed
    rng = np.random.default_rng(seed)
    starts = [x for x in (start_landing(nlps[names[0]], rng) for _ in range(args.starts)) if x is not None]
    landing_inner.LANDING_IPOPT["ipopt.max_iter"] = 0  # warm-up (the landing gradient's first build)
    solve_landing(nlps[names[-1]], (1.0, 1e-4), math.inf, starts[0])
    landing_inner.LANDING_IPOPT["ipopt.max_iter"] = args.iterations
    runs: dict[str, list] = {k: [] for k in nlps}
    for i, x0 in enumerate(starts):
        for name in names[i % len(names) :] + names[: i % len(names)]:  # rotate which goes first
            nlp = nlps[name]
            t, evaluations, gradients = time.perf_counter(), nlp.evaluations, nlp.gradients
            s = solve_landing(nlp, (1.0, 1e-4), math.inf, x0)
            ev = realise_landing(nlp, s.x) if math.isfinite(s.f) else None
            seconds = time.perf_counter() - t
            runs[name].append({
                "start": i, "status": s.status, "kept": ev is not None, "seconds": seconds,
                "landings": nlp.evaluations - evaluations, "gradients": nlp.gradients - gradients,
                "start_margin": foot_support_margin(config.leg, nlp.design(x0)),
                "margin": foot_support_margin(config.leg, nlp.design(s.x)),
                "rows_met": bool(np.all(nlp.geometric(s.x) >= nlp.lbg[1:] - 1e-9))
                            and bool(np.all(nlp.geometric(s.x) <= nlp.ubg[1:] + 1e-9)),
                "peak_external_norm": None if ev is None else ev.objectives.peak_external_norm,
            })
            print(name, runs[name][-1], flush=True)
    summary = {
        name: {"kept": sum(r["kept"] for r in rs), "solves": len(rs), "seconds": sum(r["seconds"] for r in rs),
               "landings": sum(r["landings"] for r in rs), "gradients": sum(r["gradients"] for r in rs)}
        for name, rs in runs.items()
    }
    summary["ratio"] = {
        "kept_fraction": {k: v["kept"] / v["solves"] for k, v in summary.items()},
        **{f"wall_time_{k}_over_{names[-1]}": summary[k]["seconds"] / summary[names[-1]]["seconds"]
           for k in names[:-1]},
    }
    out = {"bound": config.limits.support_margin, "iterations": args.iterations, "seed": seed, "summary": summary,
           "runs": runs}
    (HERE / args.out).write_text(json.dumps(out, indent=1) + "\n", encoding="utf-8")
    print(json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()
