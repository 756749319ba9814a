"""The support margin's rows (optimizer.search.compiled.margin_rows, the NLPs' rows of
``constraints.support_margin``) as a law on random polygons: a point meeting them is at least b
inside the corners' hull (impulse_core.model.support.support_margin), in any corner order and
with a near-degenerate or degenerate edge; where the order is the hull's, a point at least
b sqrt(1 + eps^2 / min |d|^2) inside meets the distance form, b inside the quadratic form."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from impulse_core.model.support import support_margin
from optimizer.search.compiled import MARGIN_EPS, MARGIN_FORMS, TIGHTEN, margin_rows, polygon_edges


def _rows(corners: np.ndarray, c: np.ndarray, b: float, unit: float, form: str) -> np.ndarray:
    cross, squared = polygon_edges([ca.DM(p) for p in corners], ca.DM(c))
    return np.concatenate([np.asarray(r).ravel() for r in margin_rows(cross, squared, b, unit, form)])


@pytest.mark.parametrize("form", MARGIN_FORMS)
def test_a_point_meeting_the_rows_is_within_the_margin(form: str) -> None:
    rng = np.random.default_rng(11)
    met, met_short, hull_order = 0, 0, 0
    for trial in range(800):
        n = int(rng.integers(3, 6))  # the heel and 2-4 toes
        corners = rng.uniform(-0.1, 0.1, (n, 2))
        centre = corners.mean(axis=0)
        corners = corners[np.argsort(np.arctan2(*(corners - centre).T[::-1]))]  # counter-clockwise about it
        short, permuted = rng.random() < 0.5, rng.random() < 0.2
        if short:  # a near-degenerate edge (or a degenerate one): along the edge it shortens, or any way
            k = int(rng.integers(1, n))
            length = 0.0 if rng.random() < 0.15 else 10.0 ** rng.uniform(-7, -3)
            u = corners[k] - corners[k - 1]
            t = np.arctan2(u[1], u[0]) + (rng.uniform(0, 2 * np.pi) if rng.random() < 0.25 else 0.0)
            corners[k] = corners[k - 1] + length * np.array([np.cos(t), np.sin(t)])
        if permuted:
            corners = corners[rng.permutation(n)]  # any order
        c = corners.T @ rng.dirichlet(np.ones(n)) if rng.random() < 0.85 else rng.uniform(-0.12, 0.12, 2)
        b = rng.uniform(0.002, 0.02)
        unit = 0.1 if trial % 2 else 1.0
        margin = support_margin(corners, c)
        if np.all(_rows(corners, c, b, unit, form) >= 0):  # sound
            met += 1
            met_short += short
            assert margin >= b, (trial, margin, b)
        d = np.roll(corners, -1, axis=0) - corners
        e = np.roll(corners, -2, axis=0) - corners
        if not permuted and np.min(d[:, 0] * e[:, 1] - d[:, 1] * e[:, 0]) > 0:
            hull_order += 1  # left turns only, winding once about the centre: the hull's order
            dd = np.min(np.sum(d**2, axis=1))
            enough = (b + TIGHTEN) * (np.sqrt(1 + MARGIN_EPS**2 / dd) if form == "distance" else 1.0)
            if margin >= enough + 1e-12:  # conservative by no more than that
                assert np.all(_rows(corners, c, b, unit, form) >= 0), (trial, margin, enough)
    assert met >= 100 and met_short >= 20 and hull_order >= 200, (met, met_short, hull_order)


def test_the_distance_form_refuses_a_degenerate_edge_where_the_quadratic_asks_nothing() -> None:
    """Two coincident corners (d = 0): the quadratic form's rows are 0 (met), the distance form's
    -b eps (the conservatism its docstring states); b <= 0 asks s >= 0 of either."""
    corners, c, b = np.array([[0.0, -0.1], [0.1, 0.05], [0.1, 0.05], [-0.1, 0.05]]), np.zeros(2), 0.02
    assert support_margin(corners, c) >= b
    assert np.all(_rows(corners, c, b, 1.0, "quadratic") >= 0)
    distance = _rows(corners, c, b, 1.0, "distance")
    assert distance[1] == pytest.approx(-(b + TIGHTEN) * MARGIN_EPS, rel=1e-12)
    assert np.all(np.delete(distance, 1) > 0)
    for form in MARGIN_FORMS:
        assert np.all(_rows(corners, c, 0.0, 0.1, form) >= 0)
    with pytest.raises(ValueError, match="form"):
        _rows(corners, c, b, 1.0, "squared")
