"""Pareto fronts by exact enumeration (``optimizer.results.pareto``): on integer points the
hypervolume is a count of unit cells, and non-domination a comparison of every pair.

A cell [c, c + 1) (c integer, componentwise) lies in the dominated region exactly when some point
p has p <= c in every objective and c + 1 <= reference: the hypervolume is the number of such
cells. Random small fronts in one to four objectives, with ties and duplicates.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from optimizer.results.pareto import dominates, hypervolume, non_dominated


def _cells(points: np.ndarray, reference: np.ndarray) -> int:
    ranges = [range(int(points[:, k].min()) if len(points) else 0, int(reference[k])) for k in range(len(reference))]
    return sum(1 for c in itertools.product(*ranges) if np.any(np.all(points <= np.array(c), axis=1)))


@pytest.mark.parametrize("dims", [1, 2, 3, 4])
def test_hypervolume_is_the_count_of_dominated_cells(dims: int) -> None:
    rng = np.random.default_rng(40 + dims)
    for _ in range(25):
        points = rng.integers(0, 6, size=(int(rng.integers(1, 8)), dims)).astype(float)
        reference = rng.integers(3, 7, size=dims).astype(float)
        inside = points[np.all(points < reference, axis=1)]
        assert hypervolume(points, reference) == _cells(inside, reference), (points, reference)


@pytest.mark.parametrize("dims", [2, 3])
def test_non_dominated_is_the_exact_pairwise_filter(dims: int) -> None:
    """Every kept row is dominated by no row; every dropped row is dominated by some row or
    duplicates an earlier one (duplicates keep their first row); the rows come sorted; no kept
    row dominates another."""
    rng = np.random.default_rng(50 + dims)
    for _ in range(40):
        values = rng.integers(0, 4, size=(int(rng.integers(1, 12)), dims)).astype(float)
        keep = non_dominated(values)
        for i in range(len(values)):
            dominated = any(np.all(values[j] <= values[i]) and np.any(values[j] < values[i])
                            for j in range(len(values)))
            first_copy = not any(np.array_equal(values[j], values[i]) for j in range(i))
            assert (i in keep) == (not dominated and first_copy), (values, keep, i)
        assert [tuple(values[k]) for k in keep] == sorted(tuple(values[k]) for k in keep)
        assert not any(dominates(values[a], values[b]) for a in keep for b in keep)


def test_points_merge_only_within_the_same_point_tolerance() -> None:
    """Two trade-offs 1e-6 apart (relative) are two points of the front; 1e-12 apart, one (the
    first row)."""
    apart = np.array([[1.0, 2.0], [1.0 + 1e-6, 2.0 - 1e-6]])
    assert list(non_dominated(apart)) == [0, 1]
    same = np.array([[1.0 + 1e-12, 2.0 - 1e-12], [1.0, 2.0]])
    assert list(non_dominated(same)) == [0]
