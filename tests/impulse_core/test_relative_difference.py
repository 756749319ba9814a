"""``MODEL_FORMAT.md``'s relative difference (``impulse_core.timedomain.compliant.relative_difference``),
which the compliant rung's error estimate and the accuracy reports use, by hand: per pair the
largest absolute difference over the largest magnitude of the reference (the second list), the
worst pair's; a pair whose reference is all zero is skipped."""

from __future__ import annotations

import pytest

from impulse_core.timedomain.compliant import relative_difference


def test_the_reference_is_the_second_list_of_each_pair() -> None:
    assert relative_difference([([1.0, 3.0], [1.0, 2.0])]) == pytest.approx(0.5)  # 1 / 2, not 1 / 3
    assert relative_difference([([1.0, 2.0], [1.0, 3.0])]) == pytest.approx(1.0 / 3.0)
    assert relative_difference([([0.0, -4.0], [0.5, -2.0])]) == pytest.approx(1.0)  # magnitudes: |-2| = 2


def test_the_worst_pair_counts_and_an_all_zero_reference_is_skipped() -> None:
    pairs = [([1.1, 0.0], [1.0, 0.0]), ([5.0], [0.0]), ([2.0, 2.6], [2.0, 2.0])]
    assert relative_difference(pairs) == pytest.approx(0.3)  # 0.6 / 2.0 beats 0.1 / 1.0
    assert relative_difference([([5.0], [0.0])]) == 0.0
