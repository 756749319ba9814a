"""The ``footopt`` program: :func:`optimizer.cli.main.main`, with a Ctrl-C while its modules load
an interrupt (exit 130) rather than a traceback."""

from __future__ import annotations

import sys


def main() -> int:
    """Load the command line and run it on ``sys.argv``; the exit status."""
    try:
        from optimizer.cli.main import main as run
    except BaseException as e:  # also an ImportError an extension raised because of the Ctrl-C
        from optimizer.errors import interrupted

        if not interrupted(e):
            raise
        print("footopt: interrupted", file=sys.stderr)
        return 130  # optimizer.cli.status.EXIT_INTERRUPTED (not imported: it may be half-loaded)
    return run()


__all__ = ["main"]
