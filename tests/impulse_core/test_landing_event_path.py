"""The landing's event path, made cheaper without changing a result: each shortcut against the
plain computation it replaces (bit for bit where the arithmetic is the same), and landings that
take the shortcuts against the same landings without them."""

from __future__ import annotations

import math

import numpy as np

from impulse_core.timedomain.landing import _ROOT_SAMPLES, _hermite_root


def _reference_root(g0: float, d0: float, g1: float, d1: float) -> float:
    """The first sign change of the cubic Hermite fit on the samples by np.polyval, then bisection."""
    coeffs = np.array([2 * g0 + d0 - 2 * g1 + d1, -3 * g0 - 2 * d0 + 3 * g1 - d1, d0, g0])
    below = np.flatnonzero(np.polyval(coeffs, _ROOT_SAMPLES) < 0)
    if not below.size or below[0] == 0:
        return math.nan
    a, b = _ROOT_SAMPLES[below[0] - 1], _ROOT_SAMPLES[below[0]]
    for _ in range(40):
        m = 0.5 * (a + b)
        a, b = (m, b) if np.polyval(coeffs, m) >= 0 else (a, m)
    return float(b)


def test_the_hermite_root_is_numpys_polyval_bit_for_bit():
    """The event location's cubic root (Horner's rule on the samples written out) equals np.polyval's
    sampling and bisection bit for bit: gaps that dip and come back, cross once, stay above, start
    below, and unknown slopes."""
    rng = np.random.default_rng(3)
    found = 0
    for k in range(2000):
        g0, g1 = rng.uniform(0.0, 1.0), rng.uniform(-1.0, 1.0) * (k % 4 != 0)
        d0, d1 = rng.standard_normal(2) * 4.0
        if k % 7 == 0:
            g0 = -abs(g0)  # below at the start
        root, ref = _hermite_root(g0, d0, g1, d1), _reference_root(g0, d0, g1, d1)
        assert (math.isnan(root) and math.isnan(ref)) or root == ref
        found += not math.isnan(root)
    assert 500 < found < 1800
    assert math.isnan(_hermite_root(1.0, math.nan, -1.0, 0.0))
