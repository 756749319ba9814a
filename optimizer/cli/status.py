"""Exit statuses and the one-line error of every ``footopt`` command.

0 finished and wrote its results; 1 ran but has nothing to show (or an internal error); 2 invalid
input (the message names the field); 130 interrupted (the message says how to resume).
"""

from __future__ import annotations

import sys

from optimizer.config.redact import redact_url

EXIT_OK, EXIT_FAILURE, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130


def error(where: str, message: str) -> None:
    """Print ``footopt: error: WHERE: MESSAGE`` on one line of stderr, passwords redacted."""
    one_line = " ".join(line.strip() for line in message.splitlines())
    print(redact_url(f"footopt: error: {where}: {one_line}"), file=sys.stderr)


def warn(message: str) -> None:
    """Print ``footopt: warning: MESSAGE`` on stderr."""
    print(redact_url(f"footopt: warning: {message}"), file=sys.stderr)


__all__ = ["EXIT_FAILURE", "EXIT_INTERRUPTED", "EXIT_OK", "EXIT_USAGE", "error", "warn"]
