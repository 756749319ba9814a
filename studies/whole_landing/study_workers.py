"""A whole-landing study on one core and on all of them: what the batch's worker processes buy.

``footopt optimize configs/landing_study.yaml --trials N`` runs as its own process into a fresh
folder, with ``FOOTOPT_WORKERS=1`` (every landing in that process) and with the machine's cores
(:func:`optimizer.workers.cores`: each batch's designs landed by forked workers), interleaved,
``--repeats`` times. Reported per run: the wall time and the CPU time of the process and its
workers (user + system, ``RUSAGE_CHILDREN`` around it), and whether its ``pareto.csv`` and trials
are those of the one-process run (they must be, bit for bit). The ratio to read is the wall
time's, one-process over workers, in the same repeat; the CPU times say what the workers cost in
all. The C of the study's landings is not built (fewer than ``COMPILE_LANDINGS`` landings per
shape below about 100 trials), so both land on CasADi's virtual machine or on what the compile
cache already holds.

Run: python studies/whole_landing/study_workers.py [--trials 48] [--repeats 2]
(writes study_workers.md next to this file)
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from optimizer.workers import cores

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
STUDY = REPO / "configs" / "landing_study.yaml"


def run(workers: int, trials: int, out: Path) -> tuple[float, float]:
    """One ``footopt optimize`` process with ``workers`` workers: (wall s, CPU s of it and its workers)."""
    env = {**os.environ, "FOOTOPT_WORKERS": str(workers), "PYTHONPATH": str(REPO)}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "optimizer", "optimize", str(STUDY), "--trials", str(trials),
                    "--out", str(out), "--quiet"], cwd=REPO, env=env, check=True, capture_output=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=48)
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args()
    n = cores()
    rows, ratios = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.repeats):
            one, many = Path(tmp, f"one{r}"), Path(tmp, f"many{r}")
            wall1, cpu1 = run(1, args.trials, one)
            walln, cpun = run(n, args.trials, many)
            same = (one / "pareto.csv").read_bytes() == (many / "pareto.csv").read_bytes()
            rows.append(f"| {r + 1} | {wall1:.1f} | {cpu1:.1f} | {walln:.1f} | {cpun:.1f} | {wall1 / walln:.2f} | "
                        f"{'yes' if same else '**no**'} |")
            ratios.append(wall1 / walln)
            print(rows[-1], flush=True)
    lines = [
        "# A whole-landing study on one core and on all of them",
        "",
        f"`python studies/whole_landing/study_workers.py --trials {args.trials} --repeats {args.repeats}` "
        f"({time.strftime('%Y-%m-%d %H:%M', time.gmtime())} UTC; what is measured: the script's docstring). "
        f"`configs/landing_study.yaml`, {args.trials} trials, {n} workers against 1.",
        "",
        f"| repeat | 1 worker: wall (s) | CPU (s) | {n} workers: wall (s) | CPU (s) | wall 1 / {n} | same front |",
        "|---|---|---|---|---|---|---|",
        *rows,
        "",
        f"Median wall-time ratio: **{statistics.median(ratios):.2f} x** faster on {n} workers.",
        "",
    ]
    (HERE / "study_workers.md").write_text("\n".join(lines), encoding="utf-8")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
