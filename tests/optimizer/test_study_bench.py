"""The study benchmark's hypervolume: Optuna's own computation on random fronts, and a front
whose area is plain to see."""

from __future__ import annotations

import numpy as np
import pytest
from optuna._hypervolume import compute_hypervolume

from optimizer.analysis.study_bench import hypervolume_2d


def test_hypervolume_of_a_staircase():
    # points (1, 3), (2, 2), (3, 1) under reference (4, 4): 3 + 2 + 1 unit squares
    assert hypervolume_2d(np.array([[1, 3], [2, 2], [3, 1]]), np.array([4.0, 4.0])) == pytest.approx(6.0)


@pytest.mark.parametrize("seed", range(5))
def test_hypervolume_is_optunas(seed: int):
    rng = np.random.default_rng(seed)
    points = rng.uniform(0, 1, (40, 2))
    reference = np.array([1.1, 1.2])
    assert hypervolume_2d(points, reference) == pytest.approx(compute_hypervolume(points, reference), rel=1e-12)
