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


__all__ = ["ConfigError", "FootoptError"]
