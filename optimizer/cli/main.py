"""The ``footopt`` command line: a thin layer over the library.

Exit status: 0 success; 1 a numerical failure; 2 a bad file or bad usage (one line on stderr,
``footopt: error: <file>: <message>``); 130 interrupted.

To add a subcommand, write ``_add_<name>(subparsers)`` that builds its parser and sets
``run=<function(args) -> int>``, and list it in ``SUBCOMMANDS``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn

import numpy as np

from impulse_core.errors import FootoptError, NumericalError
from impulse_core.evaluate import touchdown_geometry
from impulse_core.timedomain.compliant import CompliantSettings, ContactLaw
from impulse_core.timedomain.sequential import SequentialSettings
from optimizer.analysis.sizes import SCALING_SIZES
from optimizer.cli.export import add_export
from optimizer.cli.drop import add_drop
from optimizer.cli.importer import add_import
from optimizer.cli.init import add_init
from optimizer.cli.optimize import add_optimize, add_pareto
from optimizer.cli.status import EXIT_FAILURE, EXIT_INTERRUPTED, EXIT_OK, EXIT_USAGE
from optimizer.cli.status import error as _error
from optimizer.config.model_file import ModelFile, load_model_file
from optimizer.config.redact import redact_url
from optimizer.errors import ConfigError, interrupted
from optimizer.interrupts import check_interrupt, interruptible
from impulse_core.timedomain.events.settings import MIN_TOLERANCE
from impulse_core.timedomain.landing import AUTO_CODE, LandingProgress, LandingSettings
from optimizer.evaluation.model_choice import COMPLIANT, LANDING, MODEL_CHOICES, TIME_DOMAIN_MODELS, evaluate_landing
from optimizer.report.plot import PLOT_SUFFIXES, plot_speed, plot_touchdown, plot_views
from impulse_core.kinematics.spatial import PLANAR
from optimizer.report.text import Result, format_report, is_finite, result_record, rung

if TYPE_CHECKING:
    from impulse_core.timedomain.landing_derivatives import LandingGradient

#: The paper's three-toed foot, evaluated when no file is given.
DEFAULT_MODEL = Path(__file__).resolve().parents[2] / "configs" / "paper_case3.yaml"

_MODEL_HELP = "model files (YAML or JSON, format: MODEL_FORMAT.md)"

#: ``footopt evaluate --model`` choices: 'auto', an :class:`ImpactModel` value, 'sequential' or 'compliant'.
IMPACT_MODEL_CHOICES = MODEL_CHOICES
#: ``--steps-per-period`` when not given.
DEFAULT_STEPS_PER_PERIOD = 120.0


def _add_evaluate(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "evaluate",
        help="compute the landing impulses of model files",
        description=(
            "Compute the external impulse at each contact and the internal impulse through each joint "
            "of a floating tree of rods landing straight down (on flat ground: Newton's restitution law "
            "at simultaneous contacts, its complementarity form where a contact would pull, or Coulomb "
            "friction; on a scene.terrain that is not flat: rigid impacts in sequence, one per touchdown, "
            "or compliant contacts in the time domain: see --model), and report them beside any reference "
            "values the file gives."
        ),
    )
    p.add_argument("files", nargs="+", metavar="FILE", help=_MODEL_HELP)
    p.add_argument("--json", action="store_true", help="print one JSON object per file per line (JSON Lines)")
    p.add_argument(
        "--model",
        choices=IMPACT_MODEL_CHOICES,
        default="auto",
        help="the impact model (rung of the fidelity ladder): 'auto' (default) picks the cheapest exact one per "
        "scene: with scene.duration, landing (the whole landing, see --tolerance); on a terrain that is not flat, sequential; else friction if scene.friction > 0, else newton (paper "
        "eq. 11) unless Newton's law would make a contact pull, then lcp (complementarity: the contact separates); "
        "'decoupled' is the paper's eq. 14 approximation; on uneven ground lcp and friction give the first instant "
        "(the contacts touching at t = 0, along their local normals) and newton and decoupled refuse. 'sequential': a "
        "rigid impact (LCP; with scene.friction exact Coulomb friction) along the local ground normal at each "
        "touchdown, free flight between, a plastic contact resting with a contact force; 'compliant': "
        "spring-damper contacts integrated through the landing (see --law, --stiffness, --steps-per-period); "
        "'landing': every impact until scene.duration, with resting contact, friction, joint springs and stops",
    )
    p.add_argument(
        "--law",
        choices=[law.value for law in ContactLaw],
        default=None,
        help="--model compliant: the contact law, 'penalty' (default: a spring-damper pad per contact, stiffness "
        "in N/m) or 'constraint' (MuJoCo's soft constraint, stiffness in 1/s^2)",
    )
    p.add_argument(
        "--stiffness",
        type=float,
        default=None,
        help=f"--model compliant: contact stiffness (N/m, or 1/s^2 for the constraint law; default "
        f"{CompliantSettings().stiffness:g})",
    )
    p.add_argument(
        "--steps-per-period",
        type=float,
        default=None,
        help=f"--model compliant: integration steps per period of the fastest contact oscillation (default "
        f"{DEFAULT_STEPS_PER_PERIOD:g}; 4 to 1e5)",
    )
    p.add_argument(
        "--gravity",
        type=float,
        default=None,
        help="--model sequential or compliant (or auto, when it runs sequential): gravity along -y in m/s^2 "
        "(default off: impact time scales); the rigid rungs are instantaneous, gravity gives them no impulse",
    )
    p.add_argument(
        "--tolerance",
        type=float,
        default=None,
        help=f"--model landing (or auto with scene.duration): the error the landing must meet, relative, in its "
        f"peak impulses, total contact impulses and final angles (default {LandingSettings().tolerance:g}); the step "
        "is halved until two runs agree to it (or, with a warning, until its runs' final angles are seen not to "
        "approach each other while their impulses agree), and the JSON reports the estimate as error_estimate; "
        "--model compliant: the same for its external and internal impulses, by adaptive Dormand-Prince 5(4) steps "
        "between located contact switches, their local tolerance refined until two runs agree (unless "
        "--steps-per-period fixes semi-implicit Euler steps)",
    )
    p.add_argument(
        "--plot",
        metavar="PATH",
        help="draw the tree at touchdown with its impulses to PATH (.png or .svg); with several files, "
        "PATH gets '_<file stem>' before its suffix; a whole landing draws its impulses over time and the leg "
        "at up to 12 events spread over the landing's time",
    )
    p.add_argument(
        "--landings",
        metavar="STUDY.yaml",
        help="score each file over a study's landings (its landings: and statistic: blocks): each objective's "
        "statistic over the scenarios (--json: an object with 'statistics')",
    )
    p.add_argument(
        "--sensitivity",
        action="store_true",
        help="a whole landing (scene.duration): also report which values move its objectives (peak_external_norm, "
        "peak_internal_norm, peak_max_internal, energy_absorbed) and by how much: per objective each design value "
        "(lengths, masses, angles, ..., joint stiffness, damping, rest, limits) and scene value (friction, speed, "
        "restitution, each joint's stop_restitution) with its derivative and elasticity x/f df/dx, largest first. "
        "The derivatives are exact for the reported run (its step) along its event sequence and cost about 4-11 "
        "landings; where they are refused (redundant rows, an impact off the exact cone law, ...) the landing is "
        "reported with a warning. --json adds a 'sensitivity' object (MODEL_FORMAT.md)",
    )
    p.add_argument(
        "--animate",
        metavar="PATH",
        help="a whole landing as an animated GIF to PATH (.gif); with several files, PATH gets '_<file stem>'",
    )
    p.set_defaults(run=run_evaluate)


def _add_bench(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "bench",
        help="time the evaluation of a model, next to pinocchio.impulseDynamics",
        description=(
            "Time one design's evaluation (external + internal impulses + norms, the optimiser's hot path): "
            "one call per design, batched over many designs (virtual machine, compiled C, a C loop, a SIMD "
            "loop, 2 threads), the gradient of both norms (adjoint, beside reverse-mode AD), beside "
            "pinocchio.impulseDynamics on the same model in the same run (if `pin` is installed); check that "
            "batched results equal single calls and the full model, and the two gradients each other. "
            "'footopt bench speed' (the default mode) times the paper's case 3 and the scaling series "
            "(5 to 200 bodies); 'footopt bench FILE...' times the given model files. Quote ratios, not times."
        ),
    )
    p.add_argument(
        "files",
        nargs="*",
        metavar="FILE",
        help=f"'speed' (default: case 3 and the scaling series), or {_MODEL_HELP}",
    )
    p.add_argument("--batch", type=int, default=2000, help="designs per batched call (default 2000)")
    p.add_argument("--json", action="store_true", help="print one JSON object per model")
    p.add_argument(
        "--cache-dir",
        default=str(Path.home() / ".cache" / "footopt"),
        help="where compiled C libraries are cached (default ~/.cache/footopt)",
    )
    p.add_argument("--no-compile", action="store_true", help="time CasADi's virtual machine only")
    p.add_argument(
        "--plot",
        metavar="PATH",
        help="also draw the first model's paths and the scaling series to PATH (.png or .svg)",
    )
    p.add_argument(
        "--sizes",
        default=None,
        help="body counts of the scaling series, comma-separated (default with 'speed': "
        + ",".join(str(n) for n in SCALING_SIZES)
        + "; 'none' to skip; with model files: none unless given)",
    )
    p.add_argument("--old", default="087e17f", help="with 'study': the commit to time beside HEAD (default 087e17f)")
    p.add_argument("--repeats", type=int, default=2, help="with 'study': runs of each version (default 2)")
    p.set_defaults(run=run_bench)


#: Functions that add one subcommand each to the parser.
SUBCOMMANDS: tuple[Callable[[argparse._SubParsersAction], None], ...] = (
    _add_evaluate,
    _add_bench,
    add_optimize,
    add_pareto,
    add_export,
    add_init,
    add_drop,
    add_import,
)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every subcommand of ``SUBCOMMANDS``."""
    parser = _Parser(
        prog="footopt",
        description="Design robot feet that spread landing impulses.",
        epilog="Run 'footopt COMMAND --help' for a command's options.",
    )
    parser.add_argument("--version", action=_VersionAction)
    parser.add_argument("--debug", action="store_true", help="show a Python traceback for any error")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for add in SUBCOMMANDS:
        add(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line.

    Args:
        argv: the arguments after the program name (default: ``sys.argv[1:]``).

    Returns:
        The exit status.
    """
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as e:  # --help, --version (0) and usage errors (2, their line already printed)
        return e.code if isinstance(e.code, int) else EXIT_OK if e.code is None else EXIT_USAGE
    try:
        with interruptible():
            return int(args.run(args))
    except KeyboardInterrupt:
        print("footopt: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:  # e.g. `footopt evaluate --json ... | head -1`
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # Python would complain again when flushing at exit
        return EXIT_FAILURE
    except Exception as exc:
        if interrupted(exc):  # a Ctrl-C that surfaced inside a C extension's call
            print("footopt: interrupted", file=sys.stderr)
            return EXIT_INTERRUPTED
        if args.debug:
            raise
        return _internal_error(exc)


def _internal_error(exc: Exception) -> int:
    """An error footopt did not expect: its traceback and a request to report it."""
    import traceback

    traceback.print_exception(exc, file=sys.stderr)
    _error(
        "internal error",
        f"{type(exc).__name__}: {exc}. This is a bug in footopt: please report it with the "
        "command and the files it read (footopt --debug ... shows the same traceback on purpose)",
    )
    return EXIT_FAILURE


def run_evaluate(args: argparse.Namespace) -> int:
    """``footopt evaluate``: report, or print as JSON Lines, each file's impact; a bad file is
    reported on stderr and the others still run."""
    files: list[str] = args.files
    plots: dict[int, Path] = {}
    if args.plot is not None:
        if Path(args.plot).suffix.lower() not in PLOT_SUFFIXES:
            _error("--plot", f"{args.plot}: must end in {' or '.join(PLOT_SUFFIXES)}")
            return EXIT_USAGE
        plots = _plot_paths(Path(args.plot), files)
    animations: dict[int, Path] = {}
    if args.animate is not None:
        if Path(args.animate).suffix.lower() != ".gif":
            _error("--animate", f"{args.animate}: must end in .gif")
            return EXIT_USAGE
        animations = _plot_paths(Path(args.animate), files)
    if args.landings is not None:
        if args.sensitivity:
            _error("--sensitivity", "not with --landings: it differentiates one landing of each file")
            return EXIT_USAGE
        return _evaluate_over_landings(args)
    if args.sensitivity and args.model not in ("auto", LANDING):
        _error("--sensitivity", f"needs the whole landing (--model landing, or auto with scene.duration), "
               f"got --model {args.model}")
        return EXIT_USAGE
    options = _time_domain_options(args)
    if options is None:
        return EXIT_USAGE
    status = EXIT_OK
    for n, file in enumerate(files):
        try:
            model = load_model_file(file)
            result = _evaluate(model, args.model, *options)
            if isinstance(result, str):
                _error(file, f"numerical failure: {result}")
                status = max(status, EXIT_FAILURE)
                continue
            if args.sensitivity and not _is_landing(result):
                _error(file, f"--sensitivity: the file runs the {rung(result)[0]} model, "
                       "a first impact: derivatives are offered for the whole landing only (give scene.duration)")
                status = EXIT_USAGE
                continue
            gradient, refused = _sensitivity(model, result) if args.sensitivity else (None, None)
            if args.json:
                record = result_record(model, result, file)
                if args.sensitivity:
                    from optimizer.report.landing_sensitivity import sensitivity_record

                    record["sensitivity"] = None if gradient is None else sensitivity_record(model, gradient)
                    if refused is not None:
                        record["warnings"].append(refused)
                print(json.dumps(record, allow_nan=False))
            else:
                text = format_report(model, result, file)
                if gradient is not None:
                    from optimizer.report.landing_sensitivity import format_sensitivity

                    text += "\n".join(format_sensitivity(model, gradient)) + "\n"
                if refused is not None:
                    text += f"warning: {refused}\n"
                print(("\n" if n else "") + text, end="")
            if n in plots and _is_landing(result):
                from optimizer.report.landing_plot import plot_landing

                plot_landing(model.tree, result.result, plots[n], title=Path(file).name, scene=model.scene,
                             space=model.space)
                if not args.json:
                    print(f"plot: {plots[n]}")
            elif n in plots and model.space is not PLANAR:
                plot_views(model.tree, touchdown_geometry(model.tree, model.space), result, plots[n], Path(file).name,
                           model.scene)
                if not args.json:
                    print(f"plot: {plots[n]}")
            elif n in plots:
                plot_touchdown(
                    model.tree, touchdown_geometry(model.tree, model.space), result, plots[n], title=Path(file).name, scene=model.scene
                )
                if not args.json:
                    print(f"plot: {plots[n]}")
            if n in animations:
                _animate(model, result, animations[n], quiet=args.json)
        except FootoptError as e:
            _error(file, str(e))
            status = EXIT_USAGE
        sys.stdout.flush()
    return status


def _evaluate_over_landings(args: argparse.Namespace) -> int:
    """``footopt evaluate --landings STUDY.yaml MODEL.yaml...``: each file's statistics over the
    study's landings (each scenario by the model ``auto`` picks)."""
    from optimizer.config.study_config import load_study
    from optimizer.design_space import Objective, study_landing
    from optimizer.evaluation.robust import evaluate_over_landings

    try:
        config = load_study(args.landings)
    except FootoptError as e:
        _error(args.landings, str(e))
        return EXIT_USAGE
    if config.landings is None:
        _error("--landings", f"{args.landings}: the study has no landings: block")
        return EXIT_USAGE
    status = EXIT_OK
    for file in args.files:
        try:
            with _ScenarioBar(file) as bar:
                robust = evaluate_over_landings(load_model_file(file), config.landings, config.statistic_of,
                                                study_landing(config.search.landing_tolerance), bar.show)
        except FootoptError as e:
            _error(file, str(e))
            status = EXIT_USAGE
            continue
        failed = sum(r.objectives is None for r in robust.rows)
        if robust.statistics is None:
            _error(file, f"{failed} of {len(robust.rows)} landings failed numerically: no statistics")
            status = max(status, EXIT_FAILURE)
            continue
        stats = dict(robust.statistics.items())
        names = {k: config.statistic_of(Objective(k)).text for k in stats}
        if args.json:
            print(json.dumps({"file": file, "scenarios": len(robust.rows), "statistic": names, "statistics": stats}))
        else:
            print(f"{file}: over {len(robust.rows)} landings of {args.landings}")
            print("\n".join(f"  {k:<22} {names[k]:<14} {v:.6g}" for k, v in stats.items()))
    return status


def _sensitivity(model: ModelFile, result: Result) -> tuple[LandingGradient | None, str | None]:
    """The whole landing's exact derivatives at its reported step, or None and the warning saying
    why they are refused (the landing itself is still reported)."""
    from optimizer.report.landing_sensitivity import landing_sensitivity

    shown = sys.stderr.isatty()
    if shown:
        print("sensitivity: differentiating the landing (about 4-11 landings) ...", end="\r", file=sys.stderr,
              flush=True)
    try:
        with np.errstate(all="ignore"):
            return landing_sensitivity(model, result), None
    except (np.linalg.LinAlgError, NumericalError) as e:
        why = str(e).splitlines()[0] if str(e) else "a singular solve"
        return None, f"no sensitivity: the landing's derivatives are refused ({why})"
    finally:
        if shown:
            print(" " * 70, end="\r", file=sys.stderr, flush=True)


def _animate(model: ModelFile, result: Result, path: Path, quiet: bool) -> None:
    """Write the landing's animation (ConfigError when the result is not a whole landing)."""
    if not _is_landing(result):
        raise ConfigError("--animate: only a whole landing moves (give scene.duration, or --model landing)")
    from optimizer.report.landing_plot import animate_landing

    animate_landing(model.tree, result.result, path, scene=model.scene, space=model.space)
    if not quiet:
        print(f"animation: {path}")


def _is_landing(result: Result) -> bool:
    from impulse_core.timedomain.landing import LandingResult

    return isinstance(getattr(result, "result", None), LandingResult)


def _time_domain_options(
    args: argparse.Namespace,
) -> tuple[CompliantSettings, SequentialSettings, LandingSettings, float | None] | None:
    """The settings of the time-domain models from ``--law``, ``--stiffness``,
    ``--steps-per-period`` and ``--gravity``; None (after one line on stderr) when an option is
    bad or does not apply to ``--model``."""
    compliant_options = {"--law": args.law, "--stiffness": args.stiffness, "--steps-per-period": args.steps_per_period}
    for flag, value in compliant_options.items():
        if value is not None and args.model != COMPLIANT:
            _error(flag, f"applies to --model compliant only (got --model {args.model})")
            return None
    if args.gravity is not None and args.model not in ("auto", *TIME_DOMAIN_MODELS):
        _error("--gravity", f"applies to --model sequential or compliant only: the {args.model} rung is instantaneous")
        return None
    if args.tolerance is not None and args.model not in ("auto", LANDING, COMPLIANT):
        _error("--tolerance", f"applies to --model landing or compliant (or auto with scene.duration), "
               f"got --model {args.model}")
        return None
    if args.tolerance is not None and args.steps_per_period is not None:
        _error("--tolerance", "give --tolerance (refined steps) or --steps-per-period (fixed steps), not both")
        return None
    tolerance = LandingSettings().tolerance if args.tolerance is None else args.tolerance
    if not (np.isfinite(tolerance) and tolerance > 0):
        _error("--tolerance", f"must be a finite number > 0 (relative), got {tolerance!r}")
        return None
    if args.model != COMPLIANT and tolerance < MIN_TOLERANCE:  # the compliant rung warns when unmet
        _error("--tolerance", f"a landing's must be >= {MIN_TOLERANCE:g} (finer never ends), got {tolerance!r}")
        return None
    gravity = 0.0 if args.gravity is None else args.gravity
    if not (np.isfinite(gravity) and gravity >= 0):
        _error("--gravity", f"must be a finite number >= 0 (m/s^2, along -y), got {gravity!r}")
        return None
    try:
        compliant = CompliantSettings(
            law=ContactLaw(args.law or ContactLaw.PENALTY.value),
            stiffness=CompliantSettings().stiffness if args.stiffness is None else args.stiffness,
            steps_per_period=DEFAULT_STEPS_PER_PERIOD if args.steps_per_period is None else args.steps_per_period,
            gravity=gravity,
        )
    except FootoptError as e:  # "compliant.stiffness: must be > 0, ..."
        name = str(e).split(":", 1)[0].removeprefix("compliant.").replace("_", "-")
        _error(f"--{name}", str(e).split(":", 1)[-1].strip())
        return None
    refine = tolerance if args.steps_per_period is None else None  # fixed steps when given
    # the landing's C where the compile cache holds it (a study's builds; the same numbers), else the VM
    landing = LandingSettings(tolerance=tolerance, step_code=AUTO_CODE)
    return compliant, SequentialSettings(gravity=gravity), landing, refine


def _evaluate(
    model: ModelFile,
    choice: str = "auto",
    compliant: CompliantSettings | None = None,
    sequential: SequentialSettings | None = None,
    whole: LandingSettings | None = None,
    compliant_tolerance: float | None = None,
) -> Result | str:
    """The landing of one model file by the model named on the command line, or the cause (one
    line) when the numerics fail (overflow, a singular solve, a diverging integration): a status
    to report, not a traceback."""
    with np.errstate(all="ignore"), _LandingBar() as bar:
        try:
            result = evaluate_landing(
                model.tree,
                model.scene,
                choice,
                compliant,
                sequential,
                model.joints,
                whole,
                compliant_tolerance,
                model.space,
                bar.show,
            )
        except (np.linalg.LinAlgError, NumericalError) as e:
            return str(e).splitlines()[0] if str(e) else "a singular solve"
    return result if is_finite(result) else "the impact solve returned no finite answer (extreme values?)"


class _LandingBar:
    """A whole landing's progress on stderr, on a terminal only (tqdm's ``disable=None``): one
    bar from 0 to the duration per run of the step halving, with its step and impacts so far;
    gone once the landing ends."""

    def __init__(self) -> None:
        self.bar, self.run = None, -1

    def __enter__(self) -> _LandingBar:
        return self

    def __exit__(self, *exc: object) -> None:
        if self.bar is not None:
            self.bar.close()

    def show(self, p: LandingProgress) -> None:
        check_interrupt()  # after each step and event: a Ctrl-C CasADi swallowed while the landing was built
        if self.bar is None:
            from tqdm import tqdm

            self.bar = tqdm(total=p.duration, unit="s", disable=None, leave=False, dynamic_ncols=True,
                            desc=f"landing, run {p.run + 1} (step {p.step:.3g} s)", postfix=f"{p.impacts} impacts",
                            bar_format="{desc}: {percentage:3.0f}%|{bar}| t = {n:.4g} of {total:.4g} s{postfix}")
        if p.run != self.run:
            self.run = p.run
            self.bar.set_description_str(f"landing, run {p.run + 1} (step {p.step:.3g} s)", refresh=False)
            self.bar.set_postfix_str(f"{p.impacts} impacts", refresh=False)
            self.bar.reset(total=p.duration)
        self.bar.set_postfix_str(f"{p.impacts} impacts", refresh=False)
        self.bar.update(p.t - self.bar.n)


class _ScenarioBar:
    """The landings evaluated one by one (whole landings) on stderr, on a terminal only (tqdm's
    ``disable=None``): one bar per file; gone once its statistics are in."""

    def __init__(self, file: str) -> None:
        self.file, self.bar = file, None

    def __enter__(self) -> _ScenarioBar:
        return self

    def __exit__(self, *exc: object) -> None:
        if self.bar is not None:
            self.bar.close()

    def show(self, done: int, of: int) -> None:
        check_interrupt()
        if self.bar is None:
            from tqdm import tqdm

            self.bar = tqdm(total=of, unit="landing", disable=None, leave=False, dynamic_ncols=True, mininterval=0,
                            desc=f"{self.file}: landings")
        self.bar.update(done - self.bar.n)


def run_bench(args: argparse.Namespace) -> int:
    """``footopt bench [speed] [FILE...]``: timings and the ratio to Pinocchio per model file, and
    the scaling series attached to the first model's report."""
    from optimizer.analysis.bench import format_report as format_bench
    from optimizer.analysis.bench import speed_report

    if args.files[:1] == ["study"]:  # footopt bench study: the toe-count study beside --old
        from optimizer.analysis.study_bench import study_bench

        print(study_bench(old_commit=args.old, repeats=max(args.repeats, 1)).format())
        return EXIT_OK
    if args.batch < 1:
        _error("--batch", f"must be >= 1, got {args.batch}")
        return EXIT_USAGE
    files = list(args.files)
    speed_mode = not files or files[0] == "speed"
    files = [f for f in files if f != "speed"] or [str(DEFAULT_MODEL)]
    try:
        sizes = _sizes(args.sizes, SCALING_SIZES if speed_mode else ())
    except ValueError as e:
        _error("--sizes", str(e))
        return EXIT_USAGE
    if args.plot is not None and Path(args.plot).suffix.lower() not in PLOT_SUFFIXES:
        _error("--plot", f"{args.plot}: must end in {' or '.join(PLOT_SUFFIXES)}")
        return EXIT_USAGE
    cache = None if args.no_compile else Path(args.cache_dir)
    for n, file in enumerate(files):
        try:
            model = load_model_file(file)
        except FootoptError as e:
            _error(file, str(e))
            return EXIT_USAGE
        print(f"timing {file} ...", file=sys.stderr)
        report = speed_report(
            Path(file).stem, model.tree, model.scene, batch=args.batch, cache_dir=cache, space=model.space
        )
        if n == 0 and sizes:
            report = replace(report, scaling=_scaling_with_progress(sizes, min(args.batch, 500), cache))
        if n == 0 and args.plot is not None:
            try:
                print(f"plot: {plot_speed(report, Path(args.plot))}", file=sys.stderr)
            except FootoptError as e:
                _error("--plot", str(e))
                return EXIT_USAGE
        if args.json:
            print(json.dumps(report.as_dict(), allow_nan=False))
        else:
            print(("\n" if n else "") + format_bench(report))
        sys.stdout.flush()
    return EXIT_OK


def _scaling_with_progress(sizes: tuple[int, ...], batch: int, cache: Path | None) -> list[dict]:
    """The scaling series with a progress bar on stderr (compiling the large trees takes minutes)."""
    from tqdm import tqdm

    from optimizer.analysis.bench import scaling_series

    rows: list[dict] = []
    with tqdm(total=len(sizes), unit="tree", desc="scaling series", disable=None, dynamic_ncols=True) as bar:
        for n in sizes:
            bar.set_postfix_str(f"{n} bodies")
            rows += scaling_series((n,), batch=batch, cache_dir=cache)
            check_interrupt()  # a Ctrl-C that CasADi swallowed while this tree's graph was built
            bar.update(1)
    return rows


def _sizes(text: str | None, default: tuple[int, ...]) -> tuple[int, ...]:
    """``--sizes``: body counts >= 3, comma-separated, or 'none'."""
    if text is None:
        return default
    if text.strip().lower() == "none":
        return ()
    try:
        sizes = tuple(int(x) for x in text.split(",") if x.strip())
    except ValueError:
        raise ValueError(f"must be comma-separated integers or 'none', got {text!r}") from None
    if not sizes or min(sizes) < 3:
        raise ValueError(f"body counts must be >= 3, got {text!r}")
    return sizes


def _plot_paths(path: Path, files: list[str]) -> dict[int, Path]:
    """One plot path per file: ``path`` itself for one file, else ``path`` with ``_<stem>``
    before the suffix (``_<stem>-<k>`` when two files share a stem)."""
    if len(files) == 1:
        return {0: path}
    out: dict[int, Path] = {}
    used: set[Path] = set()
    for n, file in enumerate(files):
        stem = Path(file).stem
        candidate = path.with_name(f"{path.stem}_{stem}{path.suffix}")
        k = 2
        while candidate in used:
            candidate = path.with_name(f"{path.stem}_{stem}-{k}{path.suffix}")
            k += 1
        used.add(candidate)
        out[n] = candidate
    return out


class _Parser(argparse.ArgumentParser):
    """argparse's parser (its subcommands' too), whose usage errors are one line naming the
    option, with where to read the command's options (argparse prints the usage before it)."""

    def error(self, message: str) -> NoReturn:  # type: ignore[override]
        one_line = redact_url(f"{self.prog}: error: {' '.join(message.split())}")
        self.exit(EXIT_USAGE, f"{one_line} (see '{self.prog} --help')\n")


class _VersionAction(argparse._VersionAction):
    """argparse's ``version`` action, the version looked up only when ``--version`` is given
    (importlib.metadata and its scan of the installed packages are not free)."""

    def __call__(self, parser, namespace, values, option_string=None):  # type: ignore[no-untyped-def]
        self.version = f"%(prog)s {_version()}"
        super().__call__(parser, namespace, values, option_string)


def _version() -> str:
    from importlib import metadata

    try:
        return metadata.version("footopt")
    except metadata.PackageNotFoundError:
        return "(not installed)"


__all__ = ["SUBCOMMANDS", "build_parser", "main", "run_bench", "run_evaluate"]


if __name__ == "__main__":
    raise SystemExit(main())
