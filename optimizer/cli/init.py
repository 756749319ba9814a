"""``footopt init``: copy the starter study and model files, shipped with the package, into a
folder. Registered in :data:`optimizer.cli.main.SUBCOMMANDS`.

Exit status: 0 written; 2 a file would be overwritten (without ``--force``) or cannot be written,
one line on stderr naming it.
"""

from __future__ import annotations

import argparse
from importlib import resources
from pathlib import Path

from optimizer.cli.status import EXIT_OK, EXIT_USAGE
from optimizer.cli.status import error as _error

#: What ``footopt init`` writes: two studies (first impact, whole landing) and two model files.
STARTERS = ("quick_study.yaml", "landing_study.yaml", "paper_case3.yaml", "landing_case3.yaml")
#: The study ``footopt optimize`` runs when given none.
DEFAULT_STUDY = "quick_study.yaml"


def example_text(name: str) -> str:
    """A shipped example file's text (``optimizer/examples/``, the repository's ``configs/``)."""
    return resources.files("optimizer.examples").joinpath(name).read_text(encoding="utf-8")


def example_path(name: str) -> Path:
    """The path of a shipped example file (package data: a real file in a wheel or a checkout)."""
    return Path(str(resources.files("optimizer.examples").joinpath(name)))


def add_init(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "init",
        help="write starter study and model files into a folder",
        description=(
            f"Copy the starter files shipped with footopt into DIR: {', '.join(STARTERS)}. Then run "
            "'footopt optimize quick_study.yaml' (or landing_study.yaml) and 'footopt evaluate paper_case3.yaml'."
        ),
    )
    p.add_argument("folder", metavar="DIR", nargs="?", default=".", help="where to write them (default: here)")
    p.add_argument("--force", action="store_true", help="replace files of the same names")
    p.set_defaults(run=run_init)


def run_init(args: argparse.Namespace) -> int:
    """``footopt init``: refuse before writing anything if a file exists (unless --force)."""
    folder = Path(args.folder)
    targets = [folder / name for name in STARTERS]
    existing = [t for t in targets if t.exists()]
    if existing and not args.force:
        _error(str(existing[0]), "exists; footopt init --force replaces it")
        return EXIT_USAGE
    try:
        folder.mkdir(parents=True, exist_ok=True)
        for name, target in zip(STARTERS, targets, strict=True):
            target.write_text(example_text(name), encoding="utf-8")
    except OSError as e:
        _error(str(folder), f"cannot write the starter files ({e.strerror or e})")
        return EXIT_USAGE
    for target in targets:
        print(f"wrote {target}")
    print(f"next: footopt optimize {targets[0]}")
    return EXIT_OK
