"""Typed errors of the optimizer layer (files, command line)."""

from __future__ import annotations

from pathlib import Path

from impulse_core.errors import FootoptError


class ConfigError(FootoptError, ValueError):
    """A file footopt cannot use: missing, unreadable, not YAML, or a field with a bad value.

    The message is one line and starts with the YAML path of the bad field when there is one
    (``model.bodies[2].mass: must be a finite number > 0, got -1.0``); the file itself is kept
    apart, in ``source``, so that a caller can name it once.

    Attributes:
        source: the file the error is about, when known.
    """

    def __init__(self, message: str, source: str | Path | None = None) -> None:
        super().__init__(" ".join(line.strip() for line in message.splitlines()))
        self.source = source

    def __reduce__(self):  # raised in a worker process, it arrives with its source
        return type(self), (str(self), self.source)


def interrupted(exc: BaseException) -> bool:
    """True when ``exc`` is a Ctrl-C: a KeyboardInterrupt, or an error a C extension raised
    because a KeyboardInterrupt arrived inside its call (CasADi's and NumPy's conversions then
    raise ``SystemError: ... returned a result with an exception set``, caused by it)."""
    seen: set[int] = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__  # type: ignore[assignment]
    return False


__all__ = ["ConfigError", "FootoptError", "interrupted"]
