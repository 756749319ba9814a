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

With ``--inner``, the same study searched by the inner search (``search.method: inner``, IPOPT per
shape: its four shapes swept by the workers, :mod:`optimizer.search.landing_workers`), at
``--starts`` random starts and ``--front-points`` epsilon points per shape and a landing of
``--duration`` s, written into the run folder's parent as a study file of its own.

Run: python studies/whole_landing/study_workers.py [--trials 48] [--repeats 2]
     python studies/whole_landing/study_workers.py --inner [--starts 1 --front-points 1 --duration 0.05]
(writes study_workers.md, or study_workers_inner.md, next to this file)
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


def run(workers: int, trials: int, out: Path, study: Path = STUDY) -> tuple[float, float]:
    """One ``footopt optimize`` process with ``workers`` workers: (wall s, CPU s of it and its workers)."""
    env = {**os.environ, "FOOTOPT_WORKERS": str(workers), "PYTHONPATH": str(REPO)}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "optimizer", "optimize", str(study), "--trials", str(trials),
                    "--out", str(out), "--quiet"], cwd=REPO, env=env, check=True, capture_output=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=48)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--inner", action="store_true", help="the inner search's shapes on the workers")
    parser.add_argument("--starts", type=int, default=1, help="--inner: random starts per shape")
    parser.add_argument("--front-points", type=int, default=1, help="--inner: epsilon points per shape")
    parser.add_argument("--duration", type=float, default=0.05, help="--inner: the landing's duration (s)")
    args = parser.parse_args()
    n = cores()
    rows, ratios = [], []
    with tempfile.TemporaryDirectory() as tmp:
        study = inner_study(Path(tmp), args) if args.inner else STUDY
        for r in range(args.repeats):
            one, many = Path(tmp, f"one{r}"), Path(tmp, f"many{r}")
            wall1, cpu1 = run(1, args.trials, one, study)
            walln, cpun = run(n, args.trials, many, study)
            same = (one / "pareto.csv").read_bytes() == (many / "pareto.csv").read_bytes()
            rows.append(f"| {r + 1} | {wall1:.1f} | {cpu1:.1f} | {walln:.1f} | {cpun:.1f} | {wall1 / walln:.2f} | "
                        f"{'yes' if same else '**no**'} |")
            ratios.append(wall1 / walln)
            print(rows[-1], flush=True)
    what = (f"`configs/landing_study.yaml`, {args.trials} trials" if not args.inner else
            f"`configs/landing_study.yaml` searched by the inner search (4 shapes, {args.starts} start(s) and "
            f"{args.front_points} front point(s) per shape, a {args.duration:g} s landing)")
    command = (f"--trials {args.trials}" if not args.inner else
               f"--inner --starts {args.starts} --front-points {args.front_points} --duration {args.duration:g}")
    lines = [
        "# A whole-landing study on one core and on all of them" + (": the inner search" if args.inner else ""),
        "",
        f"`python studies/whole_landing/study_workers.py {command} --repeats {args.repeats}` "
        f"({time.strftime('%Y-%m-%d %H:%M', time.gmtime())} UTC; what is measured: the script's docstring). "
        f"{what}, {n} workers against 1.",
        "",
        f"| repeat | 1 worker: wall (s) | CPU (s) | {n} workers: wall (s) | CPU (s) | wall 1 / {n} | same front |",
        "|---|---|---|---|---|---|---|",
        *rows,
        "",
        f"Median wall-time ratio: **{statistics.median(ratios):.2f} x** faster on {n} workers.",
        "",
    ]
    out = HERE / ("study_workers_inner.md" if args.inner else "study_workers.md")
    out.write_text("\n".join(lines), encoding="utf-8")
    print("\n".join(lines))


def inner_study(folder: Path, args: argparse.Namespace) -> Path:
    """``landing_study.yaml`` searched by the inner search, written into ``folder``."""
    text = STUDY.read_text(encoding="utf-8")
    for old, new in (("duration: 0.15 ", f"duration: {args.duration} "),
                     ("  method: outer ", f"  inner: {{starts: {args.starts}, front_points: {args.front_points}}}\n"
                                          "  method: inner ")):
        assert old in text, old
        text = text.replace(old, new)
    path = folder / "landing_study_inner.yaml"
    path.write_text(text, encoding="utf-8")
    return path


if __name__ == "__main__":
    main()
