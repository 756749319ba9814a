"""The adaptive rung's deepest penetration within a step (``impulse_core.timedomain.adaptive._deepest``):
the least gap on the cubic Hermite interpolant of the step's ends, which is exact when the gap
itself is a cubic in time. Seeded random cubics that dip below both ends (falling at the start,
rising at the end), against their minimum on a fine grid refined by Newton's method."""

from __future__ import annotations

import numpy as np
import pytest

from impulse_core.timedomain.adaptive import _deepest


@pytest.mark.parametrize("h", [1.0, 3e-4])
def test_the_least_gap_of_a_cubic_step_is_found_exactly(h: float) -> None:
    rng = np.random.default_rng(8)
    checked = 0
    while checked < 30:
        coefficients = rng.normal(size=4) * np.array([1.0, 1.0, 1.0, 1e-3])  # in s = t / h: a s^3 + b s^2 + c s + d
        cubic = np.polynomial.Polynomial(coefficients[::-1])
        slope = cubic.deriv()
        g0, g1 = cubic(0.0), cubic(1.0)
        r0, r1 = slope(0.0) / h, slope(1.0) / h  # rates per unit time
        if not r0 < 0.0 < r1:
            continue
        s = np.linspace(0.0, 1.0, 20001)
        x = s[np.argmin(cubic(s))]
        for _ in range(5):  # Newton on the slope from the grid's best point
            x = min(max(x - slope(x) / slope.deriv()(x), 0.0), 1.0)
        least = min(cubic(x), g0, g1)
        assert _deepest(g0, r0, g1, r1, h) == pytest.approx(least, rel=1e-9, abs=1e-12 * np.abs(coefficients).max())
        checked += 1
