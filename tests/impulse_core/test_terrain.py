"""Ground profiles: heights, normals and the signed gap, against an independent brute-force
distance to the polyline."""

from __future__ import annotations

import math

import numpy as np
import pytest

from impulse_core.errors import ModelError
from impulse_core.model.terrain import FLAT, Terrain, flat, height, signed_gap, slope_normal, vertical_clearance


def brute_gap(terrain: Terrain, p: np.ndarray) -> tuple[float, int, float]:
    """Signed distance of p to the polyline (with flat rays 1e3 m long at the ends), the index of
    the nearest piece, and the margin to the second-nearest piece: plain loops, no vectorisation."""
    pts = [(terrain.x[0] - 1e3, terrain.y[0]), *terrain.points, (terrain.x[-1] + 1e3, terrain.y[-1])]
    dists = []
    for (ax, ay), (bx, by) in zip(pts[:-1], pts[1:]):
        dx, dy = bx - ax, by - ay
        t = min(1.0, max(0.0, ((p[0] - ax) * dx + (p[1] - ay) * dy) / (dx * dx + dy * dy)))
        dists.append(math.hypot(p[0] - ax - t * dx, p[1] - ay - t * dy))
    order = np.argsort(dists)
    sign = 1.0 if p[1] >= np.interp(p[0], terrain.x, terrain.y) else -1.0
    return sign * dists[order[0]], int(order[0]), dists[order[1]] - dists[order[0]]


def random_terrain(rng: np.random.Generator, n: int) -> Terrain:
    x = np.cumsum(rng.uniform(0.05, 0.5, n)) - 1.0
    return Terrain(tuple(x), tuple(rng.uniform(-0.2, 0.2, n)))


def test_flat_default_is_level_ground_at_zero():
    pts = np.array([[-3.0, 0.2], [0.0, -0.01], [5.0, 0.0]])
    g = signed_gap(FLAT, pts)
    np.testing.assert_allclose(g.gap, [0.2, -0.01, 0.0], atol=1e-15)
    np.testing.assert_allclose(g.normal, [[0.0, 1.0]] * 3, atol=1e-15)
    np.testing.assert_allclose(height(flat(0.3), [-1.0, 7.0]), [0.3, 0.3])
    assert FLAT.is_flat and not Terrain((0.0, 1.0), (0.0, 0.1)).is_flat


@pytest.mark.parametrize("n_points", [1, 2, 5])
def test_signed_gap_equals_brute_force_distance(rng, n_points):
    terrain = random_terrain(rng, n_points)
    P = np.column_stack([rng.uniform(-1.5, 2.0, 400), rng.uniform(-0.4, 0.4, 400)])
    g = signed_gap(terrain, P)
    ref = np.array([brute_gap(terrain, p)[0] for p in P])
    np.testing.assert_allclose(g.gap, ref, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(g.normal, axis=1), 1.0, atol=1e-12)


def test_normal_is_the_gradient_of_the_gap(rng):
    """d(gap)/dp = normal wherever the nearest piece is unique (finite differences)."""
    terrain = random_terrain(rng, 6)
    P = np.column_stack([rng.uniform(-1.5, 2.5, 300), rng.uniform(-0.3, 0.3, 300)])
    h = 1e-7
    g = signed_gap(terrain, P)
    fd = np.column_stack(
        [
            (signed_gap(terrain, P + [h, 0.0]).gap - signed_gap(terrain, P - [h, 0.0]).gap) / (2 * h),
            (signed_gap(terrain, P + [0.0, h]).gap - signed_gap(terrain, P - [0.0, h]).gap) / (2 * h),
        ]
    )
    unique = np.array([brute_gap(terrain, p)[2] > 1e-4 and abs(brute_gap(terrain, p)[0]) > 1e-4 for p in P])
    assert unique.sum() > 200
    np.testing.assert_allclose(g.normal[unique], fd[unique], atol=1e-6)


def test_the_brute_force_check_can_fail(rng):
    """Control: a terrain with one breakpoint moved by 1 mm is told apart."""
    terrain = random_terrain(rng, 4)
    moved = Terrain(terrain.x, (terrain.y[0], terrain.y[1] + 1e-3, *terrain.y[2:]))
    P = np.column_stack([np.linspace(terrain.x[0], terrain.x[2], 50), np.full(50, 0.01)])
    ref = np.array([brute_gap(terrain, p)[0] for p in P])
    assert np.max(np.abs(signed_gap(moved, P).gap - ref)) > 5e-4


def test_ramp_heights_and_normals():
    ramp = Terrain((0.0, 1.0, 2.0), (0.0, 1.0, 1.0))  # 45 deg up, then flat
    np.testing.assert_allclose(height(ramp, [-1.0, 0.5, 1.5, 3.0]), [0.0, 0.5, 1.0, 1.0])
    s = 1 / math.sqrt(2)
    np.testing.assert_allclose(slope_normal(ramp, 0.5), [-s, s])
    np.testing.assert_allclose(slope_normal(ramp, -1.0), [0.0, 1.0])
    np.testing.assert_allclose(slope_normal(ramp, 1.5), [0.0, 1.0])
    mean = np.array([-s, s + 1.0]) / np.linalg.norm([-s, s + 1.0])
    np.testing.assert_allclose(slope_normal(ramp, 1.0), mean)
    # a point 0.1 m above the ramp along its normal
    g = signed_gap(ramp, [[0.5 - 0.1 * s, 0.5 + 0.1 * s]])
    np.testing.assert_allclose(g.gap, [0.1], atol=1e-14)
    np.testing.assert_allclose(g.normal, [[-s, s]], atol=1e-14)
    # above the convex corner (1, 1): radial normal
    g = signed_gap(ramp, [[1.0 + 0.03, 1.0 + 0.04]])
    np.testing.assert_allclose(g.gap, [0.04], atol=1e-14)
    np.testing.assert_allclose(g.normal, [[0.0, 1.0]], atol=1e-14)
    g = signed_gap(ramp, [[0.97, 1.04]])  # above the corner, on the ramp's side: radial
    np.testing.assert_allclose(g.gap, [0.05], atol=1e-14)
    np.testing.assert_allclose(g.normal, [[-0.6, 0.8]], atol=1e-14)


def test_vertical_clearance():
    ramp = Terrain((0.0, 1.0), (0.0, 0.5))
    np.testing.assert_allclose(vertical_clearance(ramp, [[0.5, 0.5], [2.0, 0.4]]), [0.25, -0.1])


@pytest.mark.parametrize(
    "x, y, message",
    [
        ((0.0, 0.0), (0.0, 1.0), r"scene\.terrain\[1\]: x must increase strictly"),
        ((0.0, 1.0, 0.5), (0.0, 1.0, 1.0), r"scene\.terrain\[2\]"),
        ((0.0,), (math.nan,), r"scene\.terrain\[0\]: must be finite"),
        ((0.0, 1.0), (0.0,), r"scene\.terrain: 2 x values but 1 heights"),
        ((), (), r"scene\.terrain: needs at least one point"),
    ],
)
def test_bad_profiles_are_refused_with_their_place(x, y, message):
    with pytest.raises(ModelError, match=message):
        Terrain(x, y)


def test_from_points():
    t = Terrain.from_points([[0, 0], [1, 2.5]])
    assert t == Terrain((0.0, 1.0), (0.0, 2.5))
    with pytest.raises(ModelError, match=r"scene\.terrain\[1\]: must be a pair"):
        Terrain.from_points([[0, 0], [1, 2, 3]])
