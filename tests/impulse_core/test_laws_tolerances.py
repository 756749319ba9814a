"""The documented thresholds of the contact-set checks in ``impulse_core.impact.laws``, from
either side: rows are dependent when a singular value of J with unit columns is below RANK_TOL
(1e-9) of the largest, and two contacts are twins when their rows agree to 1e-12 of the largest
entry; a hundred times inside or outside, the answer is the documented one."""

from __future__ import annotations

import numpy as np
import pytest

from impulse_core.impact.laws import redundant, twin_groups

#: The documented rank tolerance (``laws.RANK_TOL``), written out: the test pins the documented value.
RANK_TOL = 1e-9


def _two_rows(eps: float) -> np.ndarray:
    """Two rows that differ by eps in one entry: their unit-column singular values' ratio is
    proportional to eps for small eps."""
    return np.array([[1.0, 1.0, 0.3], [1.0, 1.0 + eps, 0.3]])


def _ratio(J: np.ndarray) -> float:
    s = np.linalg.svd(J / np.linalg.norm(J, axis=0), compute_uv=False)
    return float(s[-1] / s[0])


@pytest.mark.parametrize("factor", [1e-2, 1e2])
def test_rows_are_dependent_below_the_rank_tolerance_only(factor: float) -> None:
    eps = factor * RANK_TOL * 1e-3 / _ratio(_two_rows(1e-3))  # the ratio factor * RANK_TOL
    J = _two_rows(eps)
    assert _ratio(J) == pytest.approx(factor * RANK_TOL, rel=0.05)
    assert redundant(J) is (factor < 1)
    A = J @ J.T  # the Delassus matrix's fast path answers alike
    assert redundant(J, A) is (factor < 1)


@pytest.mark.parametrize(("gap", "twins"), [(1e-14, True), (1e-10, False)])
def test_twins_agree_to_rounding_only(gap: float, twins: bool) -> None:
    rows = np.array([[0.5, -1.2, 2.0], [0.5, -1.2, 2.0 * (1 + gap)], [0.1, 0.4, -0.7]])
    groups = twin_groups(rows)
    assert [g.tolist() for g in groups] == ([[0, 1]] if twins else [])
