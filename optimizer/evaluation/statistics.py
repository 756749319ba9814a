"""Statistics of an objective over a study's landings (``MODEL_FORMAT.md``'s robust studies).

``mean``; ``std`` (population, ddof 0); ``max``; ``quantile:q`` (linear interpolation, numpy's
default); ``cvar:q``, the conditional value at risk of Rockafellar and Uryasev: the minimum over t
of t + sum(max(0, x_i - t)) / ((1 - q) n), the mean of the worst 1 - q fraction of the scenarios
with the boundary one counted fractionally. That function of t is convex and piecewise linear
with its kinks at the x_i, so its minimum is the least of its values there (exact, no search).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import numpy as np

from optimizer.errors import ConfigError


class StatisticKind(Enum):
    MEAN = "mean"
    STD = "std"
    MAX = "max"
    QUANTILE = "quantile"
    CVAR = "cvar"


@dataclass(frozen=True)
class Statistic:
    """One statistic; ``q`` in [0, 1) for quantile and cvar (None otherwise)."""

    kind: StatisticKind = StatisticKind.MEAN
    q: float | None = None

    @property
    def text(self) -> str:
        """As written in a study file: ``mean``, ``quantile:0.9``."""
        return self.kind.value if self.q is None else f"{self.kind.value}:{self.q!r}"

    def of(self, values: np.ndarray) -> float:
        """The statistic of ``values`` (one per scenario)."""
        x = np.asarray(values, dtype=float)
        if self.kind is StatisticKind.MEAN:
            return float(np.mean(x))
        if self.kind is StatisticKind.STD:
            return float(np.std(x, ddof=0))
        if self.kind is StatisticKind.MAX:
            return float(np.max(x))
        if self.kind is StatisticKind.QUANTILE:
            return float(np.quantile(x, self.q, method="linear"))
        return cvar(x, float(self.q))


def cvar(x: np.ndarray, q: float) -> float:
    """Rockafellar-Uryasev CVaR at level q of the samples x (module docstring): at each kink
    t = x_(k) of the sorted samples, the excess sum_(j > k) (x_(j) - x_(k)) from suffix sums
    (O(n log n))."""
    xs = np.sort(np.asarray(x, dtype=float))
    n = xs.size
    above = np.concatenate([np.cumsum(xs[::-1])[::-1][1:], [0.0]])  # sum of the samples after k
    excess = above - (n - 1 - np.arange(n)) * xs
    return float(np.min(xs + excess / ((1.0 - q) * n)))


def parse_statistic(text: object, where: str) -> Statistic:
    """``mean``, ``std``, ``max``, ``quantile:q`` or ``cvar:q`` (0 <= q < 1; quantile also q = 1).

    Raises:
        ConfigError: naming ``where``.
    """
    allowed = "mean, std, max, quantile:q or cvar:q (0 <= q < 1)"
    if not isinstance(text, str):
        raise ConfigError(f"{where}: must be one of {allowed}, got {text!r}")
    name, _, level = text.partition(":")
    try:
        kind = StatisticKind(name.strip())
    except ValueError:
        raise ConfigError(f"{where}: must be one of {allowed}, got {text!r}") from None
    if kind in (StatisticKind.QUANTILE, StatisticKind.CVAR):
        try:
            q = float(level)
        except ValueError:
            raise ConfigError(f"{where}: {kind.value} needs a level, e.g. {kind.value}:0.9, got {text!r}") from None
        top_ok = kind is StatisticKind.QUANTILE and q == 1.0
        if not (0.0 <= q < 1.0 or top_ok):
            raise ConfigError(f"{where}: the level of {kind.value} must be in [0, 1), got {q!r}")
        return Statistic(kind, q)
    if level:
        raise ConfigError(f"{where}: {kind.value} takes no level, got {text!r}")
    return Statistic(kind)


__all__ = ["Statistic", "StatisticKind", "cvar", "parse_statistic"]
