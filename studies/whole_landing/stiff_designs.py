"""Stiff designs of a whole-landing study: ``auto``'s RK4 against Radau IIA, both against a reference.

``auto`` starts a landing on ROS2 where its first step (duration / 200) times the joint laws'
rate exceeds AUTO_IMPLICIT; where the momentum balance splits ROS2's steps until it falls behind
RK4's pace (RK4_PACE) or overruns its budget, it goes on with Radau IIA from that first step if
first step x rate exceeds AUTO_RADAU, else with RK4 from its stable step
(``impulse_core/timedomain/landing.py``). This study asks, on the designs a study evaluates,
whether RK4 or Radau IIA is the better second integrator below AUTO_RADAU:

- the designs are drawn as ``footopt optimize`` draws them (``optimizer.search.outer.ask_batch``
  and ``suggest_design``, the config's seed, batches of 8, one worker); no trial is told its
  values, so beyond the config's ``startup_trials`` the TPE sampler, having no finished trial,
  draws as in its start-up (the designs a study's first trials land, not its later ones);
- each design's model (``design_model``) is landed with the study's settings
  (``study_landing(search.landing_tolerance)``) where ``auto`` starts on ROS2 (first step x rate
  over AUTO_IMPLICIT; the others never switch); a design is kept where the landing's
  ``integrator_switch`` is set (its ROS2 run gave way);
- each kept design is landed again with ``integrator="radau"`` (Radau IIA from the first step,
  its own step halving), and once at a fixed RK4 step, a quarter of the shortest of the two
  landings' returned steps and RK4's stable step (``_Landing.run``, the smallest share either
  asked): the reference. The true error of a landing is its ``landing_difference`` from the
  reference; the reference's own error is below ``auto``'s where auto ended on RK4 (a run at
  4 x its step), which the table lists. The reference holds twin toes alike after each step
  (:attr:`_Landing.hold_twins`, as every landing does since 3e04d30): left alone, RK4's steps part them by
  rounding too (trial 64 at its stable step in a 5 ms landing: 1e-16 rad by 0.25 ms, and the
  impact on both stops then split 2.94 and 0.09 N s, not 1.52 and 1.52), and where twins stay
  equal to the bit it changes nothing;
- with ``--candidate C``, each kept design is also landed by ``auto`` with AUTO_RADAU at C
  (``impulse_core.timedomain.landing.AUTO_RADAU`` set for that landing; the other column then
  lands with AUTO_RADAU at ``--main``, 100 by default: the shipped rule before this study): the
  CPU that rule would save on the design, ROS2's run before the switch included.

Where the design's two toes are identical (``toe_symmetry: identical``), "twins apart" is the largest
difference between their joint angles (rad) along a landing's trajectory up to its peak event: the
model is mirror-symmetric, so the exact landing keeps them equal, and an impact on both toes at
once is ill-conditioned in their split (trial 64: ``stiff_designs.md``, Findings).

Figures are CPU seconds (``time.process_time``) of this one process, the landings one after the
other (auto, Radau, reference), on a machine shared with other jobs.

Run: python studies/whole_landing/stiff_designs.py [--config configs/landing_study.yaml]
[--trials 64] [--start 0] [--only 19,21] [--candidate C [--main 100]] [--limit 300] (writes
stiff_designs.md next to this file; ``--start``: the first trial measured; ``--only``: measure these
trials alone (the others are drawn, not landed); ``--limit``: wall-clock seconds for any one
landing, a design over it is listed as such; ``--out``: another file; the file's part from
``## Findings`` on, written by hand, is kept).
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import optuna

import impulse_core.timedomain.landing as landing_module
from impulse_core.timedomain.events.run import _Landing
from impulse_core.timedomain.events.settings import AUTO, AUTO_RADAU, IMPLICIT, RADAU, RK4
from impulse_core.timedomain.landing import LandingResult, landing, landing_difference
from optimizer.config.study_config import load_study
from optimizer.design_space import design_model, study_landing
from optimizer.search.outer import ask_batch, suggest_design

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from tolerance_check import _alarm, _timed, _Timeout  # noqa: E402  (one copy of the wall-clock limit)

#: Batches of the outer search (its default workers' batch).
BATCH = 8
#: The reference's step: the shortest returned step (or RK4's stable step) over this.
REFERENCE_DIVISOR = 4.0
#: The output's hand-written part from this heading on is kept when the table is rewritten.
FINDINGS = "## Findings"


@dataclass
class Row:
    trial: int
    h_rate: float
    toes: int = 0
    #: q's indices of the first toe's joints and of the second's where the toes are identical
    twins: tuple[list[int], list[int]] | None = None
    switch: str = ""
    auto: LandingResult | None = None
    auto_seconds: float = math.nan
    radau: LandingResult | None = None
    radau_seconds: float = math.nan
    reference: LandingResult | None = None
    reference_seconds: float = math.nan
    #: ``auto`` with AUTO_RADAU at ``--candidate`` (None: not asked)
    candidate: LandingResult | None = None
    candidate_seconds: float = math.nan
    note: str = ""

    def error(self, r: LandingResult | None) -> float:
        return math.nan if r is None or self.reference is None else landing_difference(r, self.reference)

    def apart(self, r: LandingResult | None) -> float:
        """The largest difference between the twin toes' joint angles over ``r``'s trajectory up to
        its peak event (the largest external impulse, ``peak_external_norm``)."""
        if r is None or self.twins is None:
            return math.nan
        t, q = r.trajectory
        peak = max(r.events, key=lambda e: e.external_norm).time
        q = q[t <= peak]
        return float(np.max(np.abs(q[:, self.twins[0]] - q[:, self.twins[1]]), initial=0.0))

    def line(self) -> str:
        a, b = self.auto, self.radau
        if a is None or b is None:
            return f"| {self.trial} | {self.h_rate:.1f} | {self.toes} |" + " |" * 15 + f" {self.note} |"
        ratio = self.auto_seconds / self.radau_seconds
        c = self.candidate
        extra = "" if c is None else (f" {c.integrator} | {self.candidate_seconds:.2f} | {c.error_estimate:.2g} | "
                                      f"{self.error(c):.2g} | {self.auto_seconds / self.candidate_seconds:.2f} |")
        return (f"| {self.trial} | {self.h_rate:.1f} | {self.toes} | {self.auto_seconds:.2f} | {a.n_steps} | "
                f"{len(a.events)} | {a.error_estimate:.2g} | {self.error(a):.2g} | {self.radau_seconds:.2f} | "
                f"{b.n_steps} | {len(b.events)} | {b.error_estimate:.2g} | {len(b.halving) + 1} | "
                f"{self.error(b):.2g} | {self.apart(a):.2g} | {self.apart(b):.2g} | {ratio:.2f} | "
                f"{self.reference_seconds:.1f} |{extra} {self.note} |")


def summary(rows: list[Row], what: str) -> str:
    """How many of ``rows`` Radau IIA landed within its estimate and the tolerance, and the CPU."""
    done = [r for r in rows if r.reference is not None]
    honest = [r for r in done if r.error(r.radau) <= r.radau.error_estimate]
    within = [r for r in done if r.error(r.radau) <= r.radau.tolerance]
    auto = [r.auto_seconds for r in done]
    radau = [r.radau_seconds for r in done]
    return (f"- {what}: {len(done)} with a reference. Radau's error within its estimate: {len(honest)} of "
            f"{len(done)}; within the tolerance: {len(within)} of {len(done)}. CPU: auto {sum(auto):.1f} s, "
            f"Radau {sum(radau):.1f} s" + _speedup(auto, radau))


def _speedup(before: list[float], after: list[float]) -> str:
    """The CPU seconds ``before`` over ``after`` (per design) as " (total x, per design a to b x).", or "."."""
    if not sum(after):
        return "."
    ratios = sorted(b / a for b, a in zip(before, after, strict=True))
    return f" ({sum(before) / sum(after):.2f} x, per design {ratios[0]:.2f} to {ratios[-1]:.2f} x)."


def designs(config_path: str, trials: int, start: int = 0):
    """(trial number, config, model) of the designs the outer search asks as trials ``start`` to
    ``trials`` - 1 (the earlier batches asked too, their designs not drawn)."""
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    config = load_study(config_path)
    study = optuna.create_study(directions=["minimize"] * len(config.objectives))
    e = config.space.joint_laws.stop_restitution
    for k in range(math.ceil(trials / BATCH)):
        batch = ask_batch(study, config, BATCH, BATCH * k, 1)
        if BATCH * (k + 1) <= start:
            continue
        # every trial of a batch suggested in order, as the search does: the sampler seeded last draws them all
        for t, design in [(t, suggest_design(t, config)) for t in batch]:
            if start <= t.number < trials:
                yield t.number, config, design_model(config.leg, design, config.scene, config.limits, e)


def with_auto_radau(value: float | None, run):
    """``run`` with :func:`landing`'s AUTO_RADAU at ``value`` (None: as shipped)."""
    def call():
        if value is None:
            return run()
        kept = landing_module.AUTO_RADAU
        landing_module.AUTO_RADAU = value
        try:
            return run()
        finally:
            landing_module.AUTO_RADAU = kept
    return call


def measure(number: int, config, m, limit: float, candidate: float | None = None,
            main: float | None = None) -> Row | None:
    """A design's row where ``auto``'s ROS2 run gave way, else None (``auto`` with AUTO_RADAU at
    ``main``, and with ``candidate`` where given: None, as shipped)."""
    settings = study_landing(config.search.landing_tolerance)
    run = _Landing(m.tree, m.scene, m.joints, settings, m.space)
    if run.method != IMPLICIT or settings.integrator != AUTO:
        return None
    names = [b.name for b in m.tree.bodies]
    toes = len({n.split("_")[0] for n in names if n.startswith("toe")})
    row = Row(number, run.first_step() * run.rate, toes)
    if toes == 2 and config.space.toe_symmetry.value == "identical" and m.space.name == "planar":
        # planar q: the base's x, y, angle, then each body's joint after the first body's
        pairs = [(3 + i - 1, 3 + names.index("toe2" + n[4:]) - 1) for i, n in enumerate(names) if n.startswith("toe1")]
        row.twins = ([i for i, _ in pairs], [j for _, j in pairs])

    def land(s):
        return lambda: landing(m.tree, m.scene, m.joints, s, m.space)

    try:
        row.auto, row.auto_seconds = _timed(limit, with_auto_radau(main, land(settings)))
    except _Timeout:
        row.note = f"auto over {limit:g} s"
        return row
    if not row.auto.integrator_switch:
        return None
    row.switch = row.auto.integrator_switch
    if row.auto.integrator != RK4:
        row.note = f"auto ended on {row.auto.integrator}"
    try:
        row.radau, row.radau_seconds = _timed(limit, land(replace(settings, integrator=RADAU)))
    except _Timeout:
        row.note += f" radau over {limit:g} s"
        return row
    if candidate is not None:
        try:
            row.candidate, row.candidate_seconds = _timed(limit, with_auto_radau(candidate, land(settings)))
        except _Timeout:
            row.note += f" auto at {candidate:g} over {limit:g} s"
    share = min(1.0, row.auto.share, row.radau.share)
    reference_run = _Landing(m.tree, m.scene, m.joints, replace(settings, integrator=RK4), m.space)
    finest = min(row.auto.step, row.radau.step, reference_run.stable_step(),
                 math.inf if row.candidate is None else row.candidate.step)
    share = min(share, 1.0 if row.candidate is None else row.candidate.share)
    try:
        row.reference, row.reference_seconds = _timed(
            20 * limit, lambda: reference_run.run(finest / REFERENCE_DIVISOR, share=share))
    except _Timeout:
        row.note += " reference over its limit"
    return row


def candidate_summary(rows: list[Row], candidate: float) -> str:
    """``auto`` at AUTO_RADAU ``candidate`` against the auto column: within the tolerance, the CPU."""
    done = [r for r in rows if r.reference is not None and r.candidate is not None]
    within = [r for r in done if r.error(r.candidate) <= r.candidate.tolerance]
    before = [r.auto_seconds for r in done]
    after = [r.candidate_seconds for r in done]
    return (f"- auto at AUTO_RADAU {candidate:g}: {len(done)} with a reference; within the tolerance: {len(within)} "
            f"of {len(done)}. CPU: {sum(after):.1f} s against the auto column's {sum(before):.1f} s"
            + _speedup(before, after))


HEADER = ("| trial | h x rate | toes | auto s | steps | events | estimate | error | Radau s | steps | events | "
          "estimate | pairs | error | twins apart to the peak: auto | Radau | auto / Radau | reference s | note |\n|"
          + "---|" * 19)
CANDIDATE_HEADER = HEADER.replace(
    "reference s | note |\n|" + "---|" * 19,
    "reference s | candidate ends on | s | estimate | error | auto / candidate | note |\n|" + "---|" * 24)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="configs/landing_study.yaml")
    parser.add_argument("--trials", type=int, default=64)
    parser.add_argument("--start", type=int, default=0, help="the first trial measured")
    parser.add_argument("--only", default="", help="comma-separated trials: measure these alone")
    parser.add_argument("--candidate", type=float, default=None,
                        help="also land auto with AUTO_RADAU at this value")
    parser.add_argument("--main", type=float, default=None,
                        help="with --candidate: the auto column's AUTO_RADAU (default 100, the rule before)")
    parser.add_argument("--limit", type=float, default=300.0)
    parser.add_argument("--out", default=str(HERE / "stiff_designs.md"))
    args = parser.parse_args()
    signal.signal(signal.SIGALRM, _alarm)
    rows, started, asked = [], time.process_time(), 0
    only = {int(t) for t in args.only.split(",") if t.strip()}
    main_value = args.main if args.main is not None else (100.0 if args.candidate is not None else None)
    for number, config, m in designs(args.config, args.trials, args.start):
        if only and number not in only:
            continue
        asked += 1
        row = measure(number, config, m, args.limit, args.candidate, main_value)
        if row is not None:
            rows.append(row)
            print(row.line(), flush=True)
    command = " ".join(["python", "studies/whole_landing/stiff_designs.py", *sys.argv[1:]])
    text = [
        "# Stiff designs of a whole-landing study: auto's RK4 against Radau IIA",
        "",
        f"`{command}` ({time.strftime('%Y-%m-%d %H:%M', time.gmtime())} UTC; AUTO_RADAU "
        f"{AUTO_RADAU if main_value is None else main_value:g}; "
        f"{time.process_time() - started:.0f} CPU s). Method: the script's docstring.",
        "",
        f"Designs asked: {asked}; where auto's ROS2 run gave way: {len(rows)}.",
        "",
        summary([r for r in rows if r.auto is not None and r.auto.integrator == RK4],
                "auto went on with RK4 (first step x rate below AUTO_RADAU)"),
        summary([r for r in rows if r.auto is not None and r.auto.integrator == RADAU],
                "auto went on with Radau IIA (above AUTO_RADAU: the same landing twice)"),
        *([] if args.candidate is None else [candidate_summary(rows, args.candidate)]),
        "",
        "error: `landing_difference` from the reference (RK4 at a quarter of the finest step); auto: the "
        "landing as `auto` lands it (ROS2, then RK4 from its stable step); Radau: `integrator=\"radau\"`.",
        "",
        HEADER if args.candidate is None else CANDIDATE_HEADER,
        *[r.line() for r in rows],
        "",
        "Switch messages:",
        "",
        *[f"- {r.trial}: {r.switch}" for r in rows],
        "",
    ]
    out = Path(args.out)
    kept = out.read_text() if out.exists() else ""
    kept = kept[kept.index(FINDINGS):] if FINDINGS in kept else ""  # the hand-written findings stay
    out.write_text("\n".join(text) + ("\n" + kept if kept else ""))
    print("\n".join(text[4:9]))


if __name__ == "__main__":
    main()
