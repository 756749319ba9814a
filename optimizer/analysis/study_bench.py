"""``footopt bench study``: the toe-count study timed at HEAD and at an older commit side by side,
the hypervolume of both fronts, and the batched API's cost per design against its bare loop.

Each version runs as its own process (``footopt optimize`` of the same study file into a fresh
folder), interleaved, ``repeats`` times: the old one from a temporary git worktree of its commit
(same interpreter and packages, ``PYTHONPATH`` at the worktree), HEAD cold (an empty cache of
compiled NLPs) and warm (the cache the cold run filled); each run's wall time and CPU time
(user + system of all its processes: HEAD runs forked workers) are reported. The hypervolume is measured in
(external_norm, internal_norm) against one reference point for both fronts: 1.1 x the worst
value of each objective over the union of the two fronts (stated in the report).
"""

from __future__ import annotations

import csv
import math
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from impulse_core.compile.cache import default_root

REPO = Path(__file__).resolve().parents[2]
#: The study and the commit the targets of issue 10 are measured against.
DEFAULT_STUDY = REPO / "studies" / "toe_count" / "study.yaml"
DEFAULT_OLD = "087e17f"
#: Designs per call when timing the batched API.
BATCH_DESIGNS = 10_000


def hypervolume_2d(points: np.ndarray, reference: np.ndarray) -> float:
    """Area dominated by ``points`` (n x 2, both minimised) and bounded by ``reference``."""
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    p = p[np.all(p < reference, axis=1)]
    area, best_y = 0.0, float(reference[1])
    for x, y in p[np.lexsort((p[:, 1], p[:, 0]))]:
        if y < best_y:
            area += (reference[0] - x) * (best_y - y)
            best_y = y
    return area


def read_front(run_dir: Path) -> np.ndarray:
    """(external_norm, internal_norm) of every design in a run's ``pareto.csv``."""
    with (run_dir / "pareto.csv").open(newline="") as f:
        rows = list(csv.DictReader(f))
    return np.array([[float(r["external_norm"]), float(r["internal_norm"])] for r in rows]).reshape(-1, 2)


def timed_run(command: list[str], env: dict[str, str], cwd: Path) -> tuple[float, float]:
    """Wall time and CPU time (user + system, the run's processes together; s) of one run;
    raises if it fails."""
    cpu0, t0 = _children_cpu(), time.perf_counter()
    subprocess.run(command, env=env, cwd=cwd, check=True, capture_output=True)
    return time.perf_counter() - t0, _children_cpu() - cpu0


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


@dataclass(frozen=True)
class StudyBench:
    """Medians over the repeats (s), both fronts' hypervolumes and the batched API's cost.

    Attributes:
        old, cold, warm: wall times of the old commit, HEAD with an empty cache, HEAD warm.
        cpu: their CPU times (user + system of all their processes), the same order; on shared
            cores the load moves these less than the wall times.
        hv_old, hv_new: hypervolumes against ``reference``.
        api_ns, loop_ns: ns per design of ``BatchEvaluator.__call__`` and of its bare compiled
            loop, ``BATCH_DESIGNS`` designs per call.
    """

    old_commit: str
    repeats: int
    old: float
    cold: float
    warm: float
    hv_old: float
    hv_new: float
    reference: tuple[float, float]
    api_ns: float
    loop_ns: float
    cpu: tuple[float, float, float] = (math.nan, math.nan, math.nan)

    def format(self) -> str:
        r = self.reference
        return "\n".join(
            [
                f"toe-count study, median of {self.repeats} runs each, same machine, interleaved:",
                f"  {self.old_commit}: {self.old:.2f} s",
                f"  HEAD cold cache: {self.cold:.2f} s  ({self.cold / self.old:.2f} x {self.old_commit})",
                f"  HEAD warm cache: {self.warm:.2f} s  ({self.warm / self.old:.2f} x {self.old_commit})",
                f"  CPU time (user + system): {self.old_commit} {self.cpu[0]:.2f} s, HEAD cold {self.cpu[1]:.2f} s "
                f"({self.cpu[1] / self.cpu[0]:.2f} x), warm {self.cpu[2]:.2f} s ({self.cpu[2] / self.cpu[0]:.2f} x)",
                f"front hypervolume (external_norm, internal_norm), reference ({r[0]:.6g}, {r[1]:.6g}) N s:",
                f"  {self.old_commit}: {self.hv_old:.6e}   HEAD: {self.hv_new:.6e}"
                f"   ratio {self.hv_new / self.hv_old:.4f}",
                f"batched API, {BATCH_DESIGNS} designs per call: {self.api_ns:.1f} ns per design against "
                f"{self.loop_ns:.1f} ns in its bare compiled loop ({self.api_ns / self.loop_ns:.2f} x)",
            ]
        )


def study_bench(study: Path = DEFAULT_STUDY, old_commit: str = DEFAULT_OLD, repeats: int = 2) -> StudyBench:
    """Run the comparison (see the module docstring)."""
    with tempfile.TemporaryDirectory(prefix="footopt_bench_") as tmp:
        root = Path(tmp)
        git = ["git", "-C", str(REPO), "worktree"]
        subprocess.run([*git, "add", "--detach", str(root / "old"), old_commit], check=True, capture_output=True)
        try:
            times = _timed_versions(root, study.resolve(), repeats)
            fronts = {name: read_front(root / f"{name}0") for name in ("old", "cold")}
        finally:
            subprocess.run([*git, "remove", "--force", str(root / "old")], capture_output=True)
    reference = 1.1 * np.vstack(list(fronts.values())).max(axis=0)
    hv_old, hv_new = (hypervolume_2d(fronts[k], reference) for k in ("old", "cold"))
    names = ("old", "cold", "warm")
    medians = (statistics.median(w for w, _ in times[k]) for k in names)
    cpu = tuple(statistics.median(c for _, c in times[k]) for k in names)
    reference_point = tuple(reference.tolist())
    return StudyBench(old_commit, repeats, *medians, hv_old, hv_new, reference_point, *batch_api_cost(), cpu)


def _timed_versions(root: Path, study: Path, repeats: int) -> dict[str, list[tuple[float, float]]]:
    """Wall and CPU times of the old worktree (``root/old``), HEAD cold and HEAD warm,
    interleaved; run ``k`` of each writes to ``root/<name><k>``."""
    times: dict[str, list[tuple[float, float]]] = {"old": [], "cold": [], "warm": []}
    old = ([sys.executable, "-m", "optimizer", "optimize"], root / "old", {})
    for r in range(repeats):
        cache = {"FOOTOPT_CACHE_DIR": str(root / f"c{r}")}
        head = ([sys.executable, "-m", "optimizer.cli.main", "optimize"], REPO, cache)
        for name, (command, tree, extra) in {"old": old, "cold": head, "warm": head}.items():
            env = {**os.environ, "PYTHONPATH": str(tree), **extra}
            args = [*command, str(study), "--out", str(root / f"{name}{r}"), "--quiet"]
            times[name].append(timed_run(args, env, tree))
    return times


def batch_api_cost(cache_dir: Path | None = None, repeats: int = 101) -> tuple[float, float]:
    """ns per design of the batch evaluator's ``__call__`` and of its bare compiled loop, on the
    toe-count study's best shape (one toe of three rods), ``BATCH_DESIGNS`` designs per call:
    the best of ``repeats`` calls each, the two calls taking turns."""
    from impulse_core.compile.batch import batch_evaluator
    from impulse_core.evaluate import approach_velocity
    from impulse_core.model.tree import design_vector
    from optimizer.design_space import FootDesign, Leg, Segment, foot_tree

    design = FootDesign(heel=(Segment(0.1, 0.05, -0.5),), toes=((Segment(0.1, 0.1, 1.0),) * 3,))
    tree = foot_tree(Leg(), design)
    topology = tree.topology()
    cache = cache_dir or default_root()
    evaluator = batch_evaluator(topology, cache)
    rng = np.random.default_rng(0)
    P = np.tile(design_vector(tree), (BATCH_DESIGNS, 1))
    P[:, 6 * 2 + 2] += rng.uniform(-0.1, 0.1, BATCH_DESIGNS)
    V = np.tile(approach_velocity(topology, 3.43), (BATCH_DESIGNS, 1))
    E = np.full((BATCH_DESIGNS, 1), 0.8)

    calls = (lambda: evaluator(P, 3.43, 0.8), lambda: evaluator.run_impact(P, V, E))
    best = [math.inf, math.inf]
    for f in calls:
        f()
    for _ in range(repeats):  # interleaved, so that both see the same load; the best of each
        for i, f in enumerate(calls):
            best[i] = min(best[i], _seconds(f))
    return best[0] / BATCH_DESIGNS * 1e9, best[1] / BATCH_DESIGNS * 1e9


def _seconds(f) -> float:
    t0 = time.perf_counter()
    f()
    return time.perf_counter() - t0


__all__ = ["StudyBench", "batch_api_cost", "hypervolume_2d", "read_front", "study_bench"]
