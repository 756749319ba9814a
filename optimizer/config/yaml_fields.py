"""Checks shared by the YAML readers (model files, study files): each raises ConfigError with the
YAML path of the bad value (``model.bodies[2].mass: ...``)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from optimizer.errors import ConfigError


def join(path: str, key: object) -> str:
    """The YAML path of ``key`` under ``path`` (``scene`` + ``speed`` -> ``scene.speed``)."""
    return f"{path}.{key}" if path else str(key)


def describe(value: Any) -> str:
    """A short description of a bad value for an error message."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return f"{str(value).lower()} (a boolean)"
    if isinstance(value, str):
        return f"{value!r} (a string)"
    if isinstance(value, Mapping):
        return "a mapping"
    if isinstance(value, Sequence):
        return "a list"
    return repr(value)


def mapping(value: Any, where: str, allowed: tuple[str, ...], what: str | None = None) -> dict[str, Any]:
    """``value`` if it is a mapping whose keys are all ``allowed`` (a typo gets a suggestion)."""
    what = what or where
    if not isinstance(value, dict):
        raise ConfigError(f"{what}: must be a mapping with keys {', '.join(allowed)}; got {describe(value)}")
    for key in value:
        if key not in allowed:
            close = closest(str(key), allowed)
            hint = f"did you mean '{close}'? " if close else ""
            raise ConfigError(f"{join(where, key)}: unknown key ({hint}allowed: {', '.join(allowed)})")
    return value


def edit_distance(a: str, b: str) -> int:
    """Levenshtein distance (insertions, deletions, substitutions)."""
    row = list(range(len(b) + 1))
    for i, ca in enumerate(a, 1):
        prev, row[0] = row[0], i
        for j, cb in enumerate(b, 1):
            prev, row[j] = row[j], min(row[j] + 1, row[j - 1] + 1, prev + (ca != cb))
    return row[-1]


def closest(key: str, allowed: Sequence[str], within: int = 2) -> str | None:
    """The allowed key nearest to ``key`` if it is within ``within`` edits (case ignored), else None."""
    if not allowed:
        return None
    best = min(allowed, key=lambda k: edit_distance(key.lower(), k.lower()))
    return best if edit_distance(key.lower(), best.lower()) <= within else None


def number(value: Any, where: str) -> float:
    """A finite number (booleans are not numbers)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f"{where}: must be a number, got {describe(value)}")
    x = float(value)
    if not math.isfinite(x):
        raise ConfigError(f"{where}: must be a finite number, got {x!r}")
    return x


#: The largest |angle| (rad) a file may give a joint or its spring's rest: far beyond, a landing's
#: steps are lost in the angle's rounding (at 1e12 rad a 1e-4 rad step is) and it never ends.
MAX_ANGLE = 1.0e6


def angle(value: Any, where: str) -> float:
    """A finite angle (rad) within +-MAX_ANGLE."""
    x = number(value, where)
    if abs(x) > MAX_ANGLE:
        raise ConfigError(f"{where}: must be an angle within [-{MAX_ANGLE:g}, {MAX_ANGLE:g}] rad, got {x!r}")
    return x


def string(value: Any, where: str) -> str:
    """A non-empty string."""
    if not isinstance(value, str) or not value.strip():
        raise ConfigError(f"{where}: must be a non-empty string, got {describe(value)}")
    return value


def required(m: dict[str, Any], key: str, where: str) -> Any:
    """``m[key]``, or ConfigError naming ``where.key`` when it is missing or null."""
    if key not in m:
        raise ConfigError(f"{join(where, key)}: missing (required)")
    if m[key] is None:
        raise ConfigError(f"{join(where, key)}: required, got null")
    return m[key]


def positive(value: Any, where: str) -> float:
    """A finite number > 0, or ConfigError naming ``where``."""
    x = number(value, where)
    if x <= 0:
        raise ConfigError(f"{where}: must be a finite number > 0, got {x!r}")
    return x

