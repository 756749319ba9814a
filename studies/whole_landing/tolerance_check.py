"""Does a whole landing meet the tolerance it reports? Random landings against finer runs.

``landing()`` halves its step until two runs differ by at most ``--tolerance`` and reports that
difference as ``error_estimate`` (``docs/MODEL_FORMAT.md``: a rung's error is its relative
difference from the limit of the same model as the discretisation is refined). This study checks
the claim on random landings (``random_landings.random_model``: planar and spatial trees, terrains,
heightfields, friction, springs, stops):

- each file is landed at the default tolerance (1e-3, the default settings, step code vm);
- its reference is the same model (same integrator, same settings) run once at an eighth of the
  returned run's step, and again at a sixteenth: the "true" error is the relative difference
  (``landing_difference``: peaks, totals, final angles) of the returned run from the reference at
  h / 16, and the reference's own spread is its difference from the one at h / 8;
- a file is counted where both references ran and the reference's spread is below a tenth of the
  tolerance (else the reference is not converged enough to judge; listed as such).

Run: python studies/whole_landing/tolerance_check.py --seeds 70000 70040 [--limit 20]
(writes tolerance_check.md next to this file; ``--limit``: seconds for the returned landing, a
file whose landing takes longer is skipped, since its references cost 24 x its finest run).
"""

from __future__ import annotations

import argparse
import signal
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import random_landings as rl  # noqa: E402

from impulse_core.timedomain.events.run import _Landing  # noqa: E402
from impulse_core.timedomain.landing import LandingSettings, landing, landing_difference  # noqa: E402
from optimizer.config.model_file import load_model_file  # noqa: E402

TOLERANCE = 1e-3


class _Timeout(Exception):
    pass


def _alarm(*_: object) -> None:
    raise _Timeout()


@dataclass(frozen=True)
class Row:
    seed: int
    kind: str
    integrator: str = ""
    events: int = 0
    estimate: float = float("nan")
    error: float = float("nan")
    spread: float = float("nan")
    seconds: float = float("nan")
    note: str = ""

    @property
    def judged(self) -> bool:
        return self.spread <= 0.1 * TOLERANCE

    def line(self) -> str:
        ratio = self.error / self.estimate if self.estimate > 0 else float("nan")
        return (f"| {self.seed} | {self.kind} | {self.integrator} | {self.events} | {self.estimate:.2g} | "
                f"{self.error:.2g} | {ratio:.2g} | {self.spread:.2g} | {self.seconds:.1f} | {self.note} |")


def check(seed: int, limit: float, folder: Path) -> Row:
    """Land random file ``seed`` at the default tolerance and against its two finer references."""
    data = rl.random_model(seed, rl.Options())
    path = folder / f"{seed}.yaml"
    rl.write_model(data, path)
    m = load_model_file(path)
    kind = f"{m.space.name} {rl.ground_kind(data)} mu {m.scene.friction:g}"
    settings = LandingSettings(tolerance=TOLERANCE, step_code="vm")
    start = time.process_time()
    signal.alarm(int(limit))
    try:
        r = landing(m.tree, m.scene, m.joints, settings, space=m.space)
    except _Timeout:
        return Row(seed, kind, note=f"landing over {limit:g} s: skipped")
    except Exception as e:  # a numerical failure: the random sweeps' business, not this study's
        return Row(seed, kind, note=f"{type(e).__name__}: skipped")
    finally:
        signal.alarm(0)
    seconds = time.process_time() - start
    fixed = replace(settings, integrator=r.integrator)
    try:
        eighth = _Landing(m.tree, m.scene, m.joints, fixed, m.space).run(r.step / 8)
        sixteenth = _Landing(m.tree, m.scene, m.joints, fixed, m.space).run(r.step / 16)
    except Exception as e:
        return Row(seed, kind, r.integrator, len(r.events), r.error_estimate, seconds=seconds,
                   note=f"reference: {type(e).__name__}")
    return Row(seed, kind, r.integrator, len(r.events), r.error_estimate, landing_difference(r, sixteenth),
               landing_difference(eighth, sixteenth), seconds, "" if r.converged else "unmet")


def report(rows: list[Row], seeds: tuple[int, int], limit: float) -> str:
    judged = [r for r in rows if r.judged]
    met = [r for r in judged if r.error <= TOLERANCE]
    under = [r for r in judged if r.error > r.estimate]
    worst = max(judged, key=lambda r: r.error / max(r.estimate, 1e-300), default=None)
    lines = [
        "# Does a whole landing meet its tolerance? Random landings against finer runs",
        "",
        f"`python studies/whole_landing/tolerance_check.py --seeds {seeds[0]} {seeds[1]} --limit {limit:g}`; "
        "what is measured: the script's docstring. Tolerance 1e-3, default settings.",
        "",
        "| seed | model | integrator | events | estimate | error (vs h/16) | error / estimate | reference spread "
        "(h/8 vs h/16) | landing CPU s | note |",
        "|---|---|---|---|---|---|---|---|---|---|",
        *[r.line() for r in rows],
        "",
        f"Judged (references converged to a tenth of the tolerance): {len(judged)} of {len(rows)} files. "
        f"Within the tolerance: **{len(met)} of {len(judged)}**. The error above its estimate: {len(under)} of "
        f"{len(judged)}" + (f"; the largest ratio error / estimate {worst.error / worst.estimate:.2g} (seed "
                            f"{worst.seed})." if worst is not None and worst.estimate > 0 else "."),
    ]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, nargs=2, default=(70000, 70040), metavar=("FIRST", "END"))
    p.add_argument("--limit", type=float, default=20.0, help="seconds for a file's landing (else skipped)")
    p.add_argument("--folder", type=Path, default=Path("/tmp/tolerance_check"), help="where the files go")
    args = p.parse_args(argv)
    args.folder.mkdir(parents=True, exist_ok=True)
    signal.signal(signal.SIGALRM, _alarm)
    rows = []
    for seed in range(*args.seeds):
        rows.append(check(seed, args.limit, args.folder))
        print(rows[-1].line(), flush=True)
    (HERE / "tolerance_check.md").write_text(report(rows, tuple(args.seeds), args.limit))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
