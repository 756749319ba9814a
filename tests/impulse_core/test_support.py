"""The support polygon's margin against scipy's convex hull (Qhull) and hand values."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from impulse_core.model.support import convex_hull, support_margin


def test_hand_values() -> None:
    square = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0], [1.0, 1.0]])
    assert support_margin(square, np.array([1.0, 1.0])) == pytest.approx(1.0)
    assert support_margin(square, np.array([1.5, 1.0])) == pytest.approx(0.5)
    assert support_margin(square, np.array([3.0, 1.0])) == pytest.approx(-1.0)
    assert support_margin(square, np.array([3.0, 3.0])) == pytest.approx(-np.sqrt(2.0))
    line = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])  # a planar foot: no area
    assert support_margin(line, np.array([1.0, 0.0])) == 0.0
    assert support_margin(line, np.array([1.0, 0.3])) == pytest.approx(-0.3)
    assert support_margin(np.array([[1.0, 1.0]]), np.array([1.0, 2.0])) == pytest.approx(-1.0)


def test_random_polygons_match_qhull() -> None:
    """Inside: the distance to the nearest facet line of Qhull's hull; outside: negative, and
    equal to the distance to the nearest hull edge."""
    rng = np.random.default_rng(7)
    for _ in range(200):
        pts = rng.normal(size=(int(rng.integers(3, 9)), 2))
        p = rng.normal(size=2)
        hull = ConvexHull(pts)
        signed = -(hull.equations[:, :2] @ p + hull.equations[:, 2])  # >= 0 for every facet inside
        margin = support_margin(pts, p)
        if signed.min() >= 0:
            assert margin == pytest.approx(signed.min(), abs=1e-12)
        else:
            verts = pts[hull.vertices]
            assert set(map(tuple, convex_hull(pts))) == set(map(tuple, verts))
            gaps = []
            for i, j in hull.simplices:  # Qhull's edges
                a, b = pts[i], pts[j]
                t = np.clip(np.dot(p - a, b - a) / np.dot(b - a, b - a), 0.0, 1.0)
                gaps.append(np.linalg.norm(p - (a + t * (b - a))))
            assert margin == pytest.approx(-min(gaps), abs=1e-12)
