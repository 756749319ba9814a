"""``footopt optimize`` and ``footopt pareto``: run a study into a run directory, and print and
re-export its front. Registered in :data:`optimizer.cli.main.SUBCOMMANDS`.

Exit status as the rest of ``footopt``: 0 success; 2 a bad study file or bad usage (one line on
stderr naming the file and the YAML path); 130 interrupted (run the same command to resume).
"""

from __future__ import annotations

import argparse
import logging
import shlex
import sys
import time
from dataclasses import replace
from pathlib import Path

from impulse_core.errors import FootoptError
from optimizer.cli.status import EXIT_FAILURE, EXIT_INTERRUPTED, EXIT_OK, EXIT_USAGE, warn
from optimizer.cli.status import error as _error
from optimizer.errors import interrupted


def add_optimize(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "optimize",
        help="search a study's design space for Pareto-optimal feet",
        description=(
            "Search toe count, rods per toe and heel, joint angles and masses of a foot under the study's "
            "constraints, minimising its objectives (landing impulses, energy, ...). Every evaluated design is "
            "kept in an Optuna storage; the Pareto designs are written to the run directory as pareto.csv, "
            "pareto.json, front.png and one model file each (designs/), with its URDF and MJCF beside it. An interrupted study resumes where it "
            "stopped when the same command is run again."
        ),
    )
    p.add_argument(
        "study",
        metavar="STUDY.yaml",
        nargs="?",
        help="the study file (see configs/quick_study.yaml); none: the quick study shipped with footopt",
    )
    p.add_argument("--out", metavar="DIR", help="run directory (default: runs/<study name>)")
    p.add_argument(
        "--trials", type=int, metavar="N", help="outer search: finished trials to reach (default: the study's)"
    )
    p.add_argument(
        "--storage",
        metavar="URL",
        help="an Optuna storage URL, e.g. sqlite:///study.db (default: the study's, else a journal file in DIR)",
    )
    p.add_argument(
        "--force",
        action="store_true",
        help="start over in a DIR that holds other files or another study's run: this run's own files (and the "
        "study in its storage) are replaced; other files are left alone",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=1,
        metavar="N",
        help="outer search: N processes sharing the study's storage (default 1); several machines share a "
        "PostgreSQL storage (--storage postgresql://...) by each running footopt optimize",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar and no front table")
    p.set_defaults(run=run_optimize)


def add_pareto(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "pareto",
        help="print and re-export the Pareto front of a run directory",
        description="Read a run directory's study and storage, print its Pareto front and write its front files again.",
    )
    p.add_argument("run_dir", metavar="DIR", help="a run directory of 'footopt optimize'")
    p.set_defaults(run=run_pareto)


def run_optimize(args: argparse.Namespace) -> int:
    """``footopt optimize``."""
    from optimizer.cli.init import DEFAULT_STUDY, example_path
    from optimizer.config.study_config import SearchMethod, load_study, redact_url

    study_file = args.study or str(example_path(DEFAULT_STUDY))
    try:
        config = load_study(study_file)
    except FootoptError as e:
        _error(study_file, str(e))
        return EXIT_USAGE
    if args.trials is not None:
        if args.trials < 1:
            _error("--trials", f"must be >= 1, got {args.trials}")
            return EXIT_USAGE
        if config.search.method is SearchMethod.INNER:
            warn("--trials counts the outer search's trials; the inner search runs every shape once (ignored)")
        config = replace(config, search=replace(config.search, trials=args.trials))
    if args.storage is not None:
        config = replace(config, storage=args.storage)
    if args.workers < 1:
        _error("--workers", f"must be >= 1, got {args.workers}")
        return EXIT_USAGE
    if args.workers > 1 and config.search.method is SearchMethod.INNER:
        _error("--workers", "the inner search runs in one process (its shapes share one compiled model); "
               "several workers need search.method: outer")
        return EXIT_USAGE
    run_dir = Path(args.out) if args.out else Path("runs") / config.name
    words = ["footopt", "optimize", *([args.study] if args.study else []), "--out", str(run_dir)]
    resume = " ".join(shlex.quote(a) for a in words)
    if args.storage is not None:
        resume += " --storage " + shlex.quote(redact_url(args.storage))
    return optimize(config, run_dir, force=args.force, quiet=args.quiet, resume=resume, workers=args.workers)


def optimize(
    config, run_dir: Path, force: bool = False, quiet: bool = False, resume: str | None = None, workers: int = 1
) -> int:
    """Run ``config`` into ``run_dir`` (the body of ``footopt optimize``); returns the exit status.
    ``resume`` is the command that resumes it (printed when interrupted)."""
    import optuna
    # before the study starts, not at a trial's first length assignment (design_space imports it
    # lazily): a Ctrl-C landing inside that first import can surface as an ordinary error
    import scipy.optimize  # noqa: F401
    from tqdm import tqdm

    from optimizer.config.study_config import SearchMethod
    from optimizer.results.runs import (
        RunState,
        export_front,
        format_front,
        infeasible_summary,
        plural,
        prepare_run,
        storage_url,
        write_run_file,
        write_study_file,
    )
    from optimizer.interrupts import interrupt_handled, interruptible
    from optimizer.search.inner import run_inner
    from optimizer.search.outer import failed_designs, finished_trials, open_study, run_outer

    optuna.logging.set_verbosity(logging.WARNING)
    try:
        state = prepare_run(run_dir, config, force=force)
        study = open_study(config, storage_url(run_dir, config))
    except FootoptError as e:
        _error(str(run_dir), str(e))
        return EXIT_USAGE
    except (ValueError, ImportError, RuntimeError, OSError, _storage_errors()) as e:  # a bad or unreachable storage
        _error("--storage", f"{config.storage}: {str(e).splitlines()[0] if str(e) else type(e).__name__}")
        return EXIT_USAGE
    write_study_file(run_dir, config)
    inner = config.search.method is SearchMethod.INNER
    already = finished_trials(study)
    if not quiet:
        what = "resuming" if state is RunState.RESUME else "starting"
        print(f"{what} study '{config.name}' ({config.search.method.value} search) in {run_dir}", file=sys.stderr)
    bar = tqdm(
        total=len(config.space.shapes()) if inner else config.search.trials,
        initial=0 if inner else min(already, config.search.trials),
        unit="shape" if inner else "trial",
        disable=True if quiet else None,
        dynamic_ncols=True,
    )

    def progress(done: int, total: int) -> None:
        bar.n = done
        bar.refresh()

    started = time.perf_counter()
    status = EXIT_OK
    try:
        with interruptible():
            if inner:
                run_inner(study, config, progress)
            elif workers == 1:
                run_outer(study, config, config.search.trials, progress)
            else:
                run_workers(study, config, run_dir, workers, progress)
    except KeyboardInterrupt:
        status = EXIT_INTERRUPTED
    except Exception as e:  # a Ctrl-C that surfaced inside a C extension's call
        if not interrupted(e):
            raise
        status = EXIT_INTERRUPTED
    finally:
        bar.close()
    if status == EXIT_INTERRUPTED:
        interrupt_handled()  # answered below (the resume command), not again by main's block
    wall = time.perf_counter() - started
    points = export_front(run_dir, config, study)
    failed = failed_designs(study)
    write_run_file(
        run_dir,
        config,
        finished_trials=finished_trials(study),
        trials_this_run=finished_trials(study) - already,
        pareto_designs=len(points),
        failed_designs=[{"trial": n, "failure": why} for n, why in failed],
        wall_time_s=round(wall, 3),
        interrupted=status == EXIT_INTERRUPTED,
    )
    if failed:
        print(failed_warning(failed, finished_trials(study)), file=sys.stderr)
    if status == EXIT_INTERRUPTED:
        resume = resume or f"footopt optimize {shlex.quote(str(config.source))} --out {shlex.quote(str(run_dir))}"
        print(f"footopt: interrupted; the finished trials are kept. Resume: {resume}", file=sys.stderr)
        return status
    if not points:
        _error(config.name, infeasible_summary(study))
        return EXIT_FAILURE
    if not quiet:
        print(format_front(config, points), end="")
    print(f"{plural(len(points), 'Pareto design')} in {run_dir} ({wall:.1f} s)")
    return EXIT_OK


def failed_warning(failed: list[tuple[int, str]], trials: int, shown: int = 3) -> str:
    """One line on the designs that failed (no objectives, left out of the front): how many, and the
    first ``shown`` trials with why (all in run.json's ``failed_designs``)."""
    listed = "; ".join(f"trial {n}: {why}" for n, why in failed[:shown])
    more = f"; {len(failed) - shown} more in run.json" if len(failed) > shown else ""
    return f"footopt: warning: {len(failed)} of {trials} designs failed and are left out of the front: {listed}{more}"


def _storage_errors() -> type[Exception]:
    """What an unreachable database storage raises (SQLAlchemy's errors, when it is installed)."""
    try:
        from sqlalchemy.exc import SQLAlchemyError
    except ImportError:
        return RuntimeError
    return SQLAlchemyError


def run_workers(study, config, run_dir: Path, workers: int, progress) -> None:  # type: ignore[no-untyped-def]
    """``workers`` processes on one study: this one and ``workers - 1`` started here (each
    :func:`optimizer.search.outer.run_worker`); trials RUNNING from a killed earlier run are marked
    first. A Ctrl-C reaches every process of the terminal; each marks its own trials."""
    import multiprocessing

    from optimizer.search.outer import mark_interrupted, run_outer, run_worker

    mark_interrupted(study)
    context = multiprocessing.get_context("spawn")
    others = [context.Process(target=run_worker, args=(config, str(run_dir), config.search.trials, workers))
              for _ in range(workers - 1)]
    for p in others:
        p.start()
    try:
        run_outer(study, config, config.search.trials, progress, workers)
    finally:
        for p in others:
            p.join()
    if any(p.exitcode for p in others):
        warn(f"{sum(1 for p in others if p.exitcode)} of {workers - 1} worker processes failed; resume to finish")


def run_pareto(args: argparse.Namespace) -> int:
    """``footopt pareto DIR``."""
    import optuna

    from optimizer.config.study_config import load_study
    from optimizer.results.runs import STUDY_FILE, export_front, format_front, storage_url
    from optimizer.search.outer import open_study

    optuna.logging.set_verbosity(logging.WARNING)
    run_dir = Path(args.run_dir)
    study_file = run_dir / STUDY_FILE
    if not study_file.exists():
        _error(str(run_dir), f"not a run directory of 'footopt optimize' (no {STUDY_FILE})")
        return EXIT_USAGE
    try:
        config = load_study(study_file)
        study = open_study(config, storage_url(run_dir, config))
        if not study.trials:  # e.g. a run directory copied without its storage: keep its files
            _error(
                str(run_dir), f"its storage ({config.storage or 'study.journal'}) holds no trials; nothing re-exported"
            )
            return EXIT_USAGE
        points = export_front(run_dir, config, study)
    except FootoptError as e:
        _error(str(study_file), str(e))
        return EXIT_USAGE
    print(format_front(config, points), end="")
    return EXIT_OK


__all__ = ["add_optimize", "add_pareto", "optimize", "run_optimize", "run_pareto"]
