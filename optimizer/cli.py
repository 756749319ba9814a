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
from importlib import metadata
from pathlib import Path

import numpy as np

from impulse_core.contact_models import ImpactModel
from impulse_core.errors import FootoptError, NumericalError
from impulse_core.evaluate import ImpactResult, evaluate, touchdown_geometry
from optimizer.model_file import ModelFile, load_model_file
from optimizer.optimize_cli import add_optimize, add_pareto
from optimizer.plot import PLOT_SUFFIXES, plot_touchdown
from optimizer.report import format_report, is_finite, result_record

EXIT_OK, EXIT_FAILURE, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130

#: The paper's three-toed foot, evaluated when no file is given.
DEFAULT_MODEL = Path(__file__).resolve().parent.parent / "configs" / "paper_case3.yaml"

_MODEL_HELP = "model files (YAML or JSON, format: MODEL_FORMAT.md)"

#: ``footopt evaluate --model`` choices: 'auto' or an :class:`ImpactModel` value.
IMPACT_MODEL_CHOICES = ("auto", *(m.value for m in ImpactModel))


def _add_evaluate(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "evaluate",
        help="compute the landing impulses of model files",
        description=(
            "Compute the external impulse at each contact and the internal impulse through each joint "
            "of a floating tree of rods landing straight down on flat ground (Newton's restitution law "
            "at simultaneous contacts, its complementarity form where a contact would pull, or Coulomb "
            "friction: see --model), and report them beside any reference values the file gives."
        ),
    )
    p.add_argument("files", nargs="+", metavar="FILE", help=_MODEL_HELP)
    p.add_argument("--json", action="store_true", help="print one JSON object per file per line (JSON Lines)")
    p.add_argument(
        "--model",
        choices=IMPACT_MODEL_CHOICES,
        default="auto",
        help="the impact model (rung of the fidelity ladder): 'auto' (default) picks the cheapest exact one per "
        "scene: friction if scene.friction > 0, else newton (paper eq. 11) unless Newton's law would make a contact "
        "pull, then lcp (complementarity: the contact separates); 'decoupled' is the paper's eq. 14 approximation",
    )
    p.add_argument(
        "--plot",
        metavar="PATH",
        help="draw the tree at touchdown with its impulses to PATH (.png or .svg); with several files, "
        "PATH gets '_<file stem>' before its suffix",
    )
    p.set_defaults(run=run_evaluate)


def _add_bench(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "bench",
        help="time the evaluation of a model, next to pinocchio.impulseDynamics",
        description=(
            "Time one design's evaluation (external + internal impulses + norms): one call per design, "
            "batched over many designs, and the full evaluate() path; beside pinocchio.impulseDynamics on "
            "the same model in the same run (if `pin` is installed). Quote the ratio, not the times."
        ),
    )
    p.add_argument("files", nargs="*", metavar="FILE", help=f"{_MODEL_HELP} (default: configs/paper_case3.yaml)")
    p.add_argument("--batch", type=int, default=2000, help="designs per batched call (default 2000)")
    p.add_argument("--json", action="store_true", help="print one JSON object per model")
    p.add_argument(
        "--cache-dir",
        default=str(Path.home() / ".cache" / "footopt"),
        help="where compiled C libraries are cached (default ~/.cache/footopt)",
    )
    p.add_argument("--no-compile", action="store_true", help="time CasADi's virtual machine only")
    p.set_defaults(run=run_bench)


#: Functions that add one subcommand each to the parser.
SUBCOMMANDS: tuple[Callable[[argparse._SubParsersAction], None], ...] = (
    _add_evaluate,
    _add_bench,
    add_optimize,
    add_pareto,
)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every subcommand of ``SUBCOMMANDS``."""
    parser = argparse.ArgumentParser(
        prog="footopt",
        description="Design robot feet that spread landing impulses.",
        epilog="Run 'footopt COMMAND --help' for a command's options.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
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
    except SystemExit as e:  # --help, --version (0) and usage errors (2, message already printed)
        return e.code if isinstance(e.code, int) else EXIT_OK if e.code is None else EXIT_USAGE
    try:
        return int(args.run(args))
    except KeyboardInterrupt:
        print("footopt: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:  # e.g. `footopt evaluate --json ... | head -1`
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # Python would complain again when flushing at exit
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
    status = EXIT_OK
    for n, file in enumerate(files):
        try:
            model = load_model_file(file)
            result = _evaluate(model, _impact_model(args.model))
            if result is None:
                _error(file, "numerical failure: the impact solve returned no finite answer (extreme values?)")
                status = max(status, EXIT_FAILURE)
                continue
            if args.json:
                print(json.dumps(result_record(model, result, file), allow_nan=False))
            else:
                print(("\n" if n else "") + format_report(model, result, file), end="")
            if n in plots:
                plot_touchdown(model.tree, touchdown_geometry(model.tree), result, plots[n], title=file)
                if not args.json:
                    print(f"plot: {plots[n]}")
        except FootoptError as e:
            _error(file, str(e))
            status = EXIT_USAGE
        sys.stdout.flush()
    return status


def _impact_model(choice: str) -> ImpactModel | None:
    """The rung named on the command line; None for 'auto' (the library picks)."""
    return None if choice == "auto" else ImpactModel(choice)


def _evaluate(model: ModelFile, impact_model: ImpactModel | None = None) -> ImpactResult | None:
    """The impact of one model file, or None when the numerics fail (overflow, a singular
    solve): a status to report, not a traceback (the cause is printed once, as one line)."""
    with np.errstate(all="ignore"):
        try:
            result = evaluate(model.tree, model.scene, impact_model)
        except (np.linalg.LinAlgError, NumericalError):
            return None
    return result if is_finite(result) else None


def run_bench(args: argparse.Namespace) -> int:
    """``footopt bench``: timings and the ratio to Pinocchio per model file."""
    from optimizer.bench import format_report as format_bench, speed_report

    if args.batch < 1:
        _error("--batch", f"must be >= 1, got {args.batch}")
        return EXIT_USAGE
    files = args.files or [str(DEFAULT_MODEL)]
    for n, file in enumerate(files):
        try:
            model = load_model_file(file)
        except FootoptError as e:
            _error(file, str(e))
            return EXIT_USAGE
        cache = None if args.no_compile else Path(args.cache_dir)
        report = speed_report(Path(file).stem, model.tree, model.scene, batch=args.batch, cache_dir=cache)
        if args.json:
            print(json.dumps(report.as_dict(), allow_nan=False))
        else:
            print(("\n" if n else "") + format_bench(report))
    return EXIT_OK


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


def _error(where: str, message: str) -> None:
    one_line = " ".join(line.strip() for line in message.splitlines())
    print(f"footopt: error: {where}: {one_line}", file=sys.stderr)


def _version() -> str:
    try:
        return metadata.version("footopt")
    except metadata.PackageNotFoundError:
        return "(not installed)"


__all__ = ["SUBCOMMANDS", "build_parser", "main", "run_bench", "run_evaluate"]


if __name__ == "__main__":
    raise SystemExit(main())
