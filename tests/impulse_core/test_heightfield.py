"""Heightfields (``impulse_core.model.heightfield``): bilinear height, gradient and normal against a
hand computation, flat beyond the grid, the CasADi expressions against numpy, validation."""

from __future__ import annotations

import numpy as np
import pytest

from impulse_core.errors import ModelError
from impulse_core.model import heightfield as hf
from impulse_core.model.heightfield import Heightfield

SEED = 20261126


def random_field(rng: np.random.Generator, nx: int = 4, nz: int = 5) -> Heightfield:
    x = np.cumsum(rng.uniform(0.05, 0.4, nx)) - 0.5
    z = np.cumsum(rng.uniform(0.05, 0.4, nz)) - 0.5
    return Heightfield.from_arrays(x, z, rng.uniform(-0.05, 0.05, (nx, nz)))


def hand_bilinear(field: Heightfield, x: float, z: float) -> tuple[float, float, float]:
    """The height and gradient at (x, z) inside the grid, written out for the one cell that holds
    the point: h = (1-u)(1-w) h00 + u (1-w) h10 + (1-u) w h01 + u w h11."""
    i = max(k for k in range(len(field.x) - 1) if field.x[k] <= x)
    j = max(k for k in range(len(field.z) - 1) if field.z[k] <= z)
    dx, dz = field.x[i + 1] - field.x[i], field.z[j + 1] - field.z[j]
    u, w = (x - field.x[i]) / dx, (z - field.z[j]) / dz
    h00, h10 = field.heights[i][j], field.heights[i + 1][j]
    h01, h11 = field.heights[i][j + 1], field.heights[i + 1][j + 1]
    h = (1 - u) * (1 - w) * h00 + u * (1 - w) * h10 + (1 - u) * w * h01 + u * w * h11
    hx = ((1 - w) * (h10 - h00) + w * (h11 - h01)) / dx
    hz = ((1 - u) * (h01 - h00) + u * (h11 - h10)) / dz
    return h, hx, hz


def test_bilinear_height_gradient_and_normal_match_the_hand_computation():
    rng = np.random.default_rng(SEED)
    for _ in range(5):
        field = random_field(rng)
        fn = hf.gap_function(field)
        for _ in range(40):
            x = rng.uniform(field.x[0], field.x[-1])
            z = rng.uniform(field.z[0], field.z[-1])
            y = rng.uniform(-0.1, 0.1)
            h, hx, hz = hand_bilinear(field, x, z)
            assert hf.height(field, x, z) == pytest.approx(h, abs=1e-15)
            np.testing.assert_allclose(hf.gradient(field, x, z), [hx, hz], rtol=1e-12, atol=1e-14)
            N = np.array([-hx, 1.0, -hz])
            n = N / np.linalg.norm(N)
            np.testing.assert_allclose(hf.normal(field, x, z), n, rtol=0, atol=1e-14)
            assert n[1] > 0  # upward
            gap, normal = fn([x, y, z])
            assert float(gap) == pytest.approx((y - h) / np.linalg.norm(N), abs=1e-14)
            np.testing.assert_allclose(np.array(normal).ravel(), n, atol=1e-14)
            g_np, n_np = hf.gap(field, [[x, y, z]])
            assert g_np[0] == pytest.approx(float(gap), abs=1e-14)


def test_the_gap_is_the_distance_to_a_tilted_plane():
    """A grid of a linear function is that plane (bilinear interpolation is exact); the gap of any
    point is its signed distance to the plane."""
    rng = np.random.default_rng(SEED + 1)
    a, b, c = 0.3, -0.2, 0.05
    x, z = np.linspace(-1, 1, 4), np.linspace(-1, 1, 3)
    field = Heightfield.from_arrays(x, z, a * x[:, None] + b * z[None, :] + c)
    n = np.array([-a, 1.0, -b]) / np.sqrt(1 + a * a + b * b)
    P = rng.uniform(-0.9, 0.9, (50, 3))
    gap, normal = hf.gap(field, P)
    np.testing.assert_allclose(gap, (P - [0.0, c, 0.0]) @ n, atol=1e-14)
    np.testing.assert_allclose(normal, np.tile(n, (50, 1)), atol=1e-14)


def test_flat_beyond_the_grid_at_the_nearest_edge_value():
    field = Heightfield((0.0, 1.0), (0.0, 2.0), ((0.0, 0.2), (0.1, 0.5)))
    assert hf.height(field, -3.0, 1.0) == pytest.approx(hf.height(field, 0.0, 1.0))
    assert hf.height(field, 5.0, 9.0) == pytest.approx(0.5)
    assert hf.height(field, 0.5, -1.0) == pytest.approx(0.05)
    # leaving along x: no slope along x; the slope along z stays the edge's
    gx, gz = hf.gradient(field, 2.0, 1.0)
    assert gx == 0.0 and gz == pytest.approx(0.2)
    assert tuple(hf.gradient(field, 2.0, 3.0)) == (0.0, 0.0)
    fn = hf.gap_function(field)
    for x, z in ((-3.0, 1.0), (5.0, 9.0), (0.5, -1.0), (2.0, 1.0)):
        g, n = fn([x, 1.0, z])
        g_np, n_np = hf.gap(field, [[x, 1.0, z]])
        assert float(g) == pytest.approx(g_np[0], abs=1e-15)
        np.testing.assert_allclose(np.array(n).ravel(), n_np[0], atol=1e-15)


def test_one_point_is_flat_ground_and_flatness_is_detected():
    field = hf.flat_heightfield(0.3)
    assert field.is_flat and field.level == 0.3
    assert hf.height(field, 12.0, -4.0) == pytest.approx(0.3)
    np.testing.assert_allclose(hf.normal(field, 1.0, 2.0), [0, 1, 0])
    assert Heightfield((0.0, 1.0), (0.0,), ((0.2,), (0.2,))).is_flat
    assert not Heightfield((0.0, 1.0), (0.0,), ((0.2,), (0.21,))).is_flat


@pytest.mark.parametrize(
    "kwargs, where",
    [
        (dict(x=(0.0, 0.0), z=(0.0,), heights=((0.0,), (0.0,))), r"scene\.heightfield\.x\[1\]: the grid must increase"),
        (dict(x=(0.0,), z=(1.0, 0.5), heights=((0.0, 0.0),)), r"scene\.heightfield\.z\[1\]"),
        (dict(x=(0.0, 1.0), z=(0.0,), heights=((0.0,),)), r"scene\.heightfield\.heights: expected 2 rows of 1 values"),
        (dict(x=(0.0,), z=(0.0,), heights=((float("nan"),),)), r"scene\.heightfield\.heights\[0\]\[0\]"),
        (dict(x=(), z=(0.0,), heights=()), r"scene\.heightfield\.x: needs at least one value"),
    ],
)
def test_bad_heightfields_are_refused_naming_the_field(kwargs, where):
    with pytest.raises(ModelError, match=where):
        Heightfield(**kwargs)
