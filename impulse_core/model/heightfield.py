"""Uneven ground in space: a heightfield y = h(x, z) on a rectangular grid (world frame, m).

A :class:`Heightfield` holds a grid ``x`` (strictly increasing), ``z`` (strictly increasing) and
``heights[i][j]``, the ground height y at (x_i, z_j). Between grid points the ground is bilinear
(each cell [x_i, x_i+1] x [z_j, z_j+1] a bilinear patch); beyond the grid it is flat along the
direction it leaves by: h(x, z) = h(clip(x), clip(z)), the nearest edge value. A one-point grid
is flat ground at that height; the default is flat ground at y = 0.

Contact detection (``gap_expression``). At a point p = (x, y, z) with N = (-h_x, 1, -h_z) the
upward normal of the patch below it (the bilinear patch's gradient at (x, z)), the normal is
n = N / |N| and the gap is the point's height above the surface along the vertical scaled by the
cosine of the slope,

    gap = (y - h(x, z)) / |N|,

which is the distance from p to the surface's tangent plane at the point vertically below p:
exactly the distance to the ground where the patch is a plane (a heightfield that is one tilted
plane gives the same gaps and normals as flat ground with the scene rotated), and equal to it to
first order in the patch's twist otherwise. Where several cells meet (a grid line), the gradient
is the cell's on the +x (+z) side, half-open cells [x_i, x_i+1); beyond the grid the gradient is
zero along the direction the point left by.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from impulse_core.errors import ModelError

WHERE = "scene.heightfield"


@dataclass(frozen=True)
class Heightfield:
    """Ground height y = h(x, z) on a grid (module docstring). ``heights[i][j]`` at (x[i], z[j])."""

    x: tuple[float, ...] = (0.0,)
    z: tuple[float, ...] = (0.0,)
    heights: tuple[tuple[float, ...], ...] = ((0.0,),)

    def __post_init__(self) -> None:
        for name in ("x", "z"):
            grid = getattr(self, name)
            if not grid:
                raise ModelError(f"{WHERE}.{name}: needs at least one value (m)")
            for i, v in enumerate(grid):
                if not math.isfinite(v):
                    raise ModelError(f"{WHERE}.{name}[{i}]: must be a finite number (m), got {v}")
            for i in range(1, len(grid)):
                if not grid[i] > grid[i - 1]:
                    raise ModelError(
                        f"{WHERE}.{name}[{i}]: the grid must increase strictly, got {grid[i]} after {grid[i - 1]}"
                    )
        nx, nz = len(self.x), len(self.z)
        if len(self.heights) != nx or any(len(row) != nz for row in self.heights):
            raise ModelError(
                f"{WHERE}.heights: expected {nx} rows of {nz} values (one row per x, one value per z), got "
                f"{len(self.heights)} rows of {sorted({len(r) for r in self.heights}) or [0]} values"
            )
        for i, row in enumerate(self.heights):
            for j, v in enumerate(row):
                if not math.isfinite(v):
                    raise ModelError(f"{WHERE}.heights[{i}][{j}]: must be a finite number (m), got {v}")

    @classmethod
    def from_arrays(cls, x, z, heights) -> Heightfield:
        """From array-likes (``heights`` of shape len(x) x len(z))."""
        return cls(
            tuple(float(v) for v in np.ravel(x)),
            tuple(float(v) for v in np.ravel(z)),
            tuple(tuple(float(v) for v in row) for row in np.atleast_2d(np.asarray(heights, dtype=float))),
        )

    @property
    def grid(self) -> np.ndarray:
        """``heights`` as an array (len(x) x len(z))."""
        return np.array(self.heights, dtype=float).reshape(len(self.x), len(self.z))

    @property
    def is_flat(self) -> bool:
        """True when every height is the same (a horizontal plane)."""
        return len({v for row in self.heights for v in row}) == 1

    @property
    def level(self) -> float:
        """The lowest height (m): the ground's height when it is flat."""
        return float(min(v for row in self.heights for v in row))


FLAT_HEIGHTFIELD = Heightfield()


def is_twisted(hf: Heightfield) -> bool:
    """Some cell is a twisted bilinear patch (h11 - h10 - h01 + h00 != 0): its normal turns
    under a point moving across it, so a contact sliding there has a normal acceleration of
    its own (:func:`impulse_core.timedomain.landing.landing_function`)."""
    H = hf.grid
    return bool(np.any(H[1:, 1:] - H[1:, :-1] - H[:-1, 1:] + H[:-1, :-1] != 0.0))


def flat_heightfield(height: float = 0.0) -> Heightfield:
    """Horizontal ground at ``height`` (m)."""
    return Heightfield((0.0,), (0.0,), ((float(height),),))


def _weights(grid: tuple[float, ...], s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Hat-function weights of the grid points at s (..., n) with flat extension, and their
    derivatives in s (half-open cells [g_k, g_k+1))."""
    g = np.asarray(grid)
    n = len(g)
    s = np.asarray(s, dtype=float)
    if n == 1:
        return np.ones(s.shape + (1,)), np.zeros(s.shape + (1,))
    dg = np.diff(g)
    u = np.clip((s[..., None] - g[:-1]) / dg, 0.0, 1.0)  # (..., n-1): progress through each cell
    du = ((s[..., None] >= g[:-1]) & (s[..., None] < g[1:])) / dg
    ones, zeros = np.ones(s.shape + (1,)), np.zeros(s.shape + (1,))
    w = np.concatenate([ones, u], axis=-1) - np.concatenate([u, zeros], axis=-1)
    dw = np.concatenate([zeros, du], axis=-1) - np.concatenate([du, zeros], axis=-1)
    return w, dw


def height(hf: Heightfield, x, z) -> np.ndarray:
    """Ground height h(x, z) (m): bilinear on the grid, flat beyond it."""
    wx, _ = _weights(hf.x, x)
    wz, _ = _weights(hf.z, z)
    return np.einsum("...i,ij,...j->...", wx, hf.grid, wz)


def gradient(hf: Heightfield, x, z) -> np.ndarray:
    """(dh/dx, dh/dz) at (x, z) (..., 2): the bilinear patch's gradient (module docstring)."""
    wx, dwx = _weights(hf.x, x)
    wz, dwz = _weights(hf.z, z)
    H = hf.grid
    return np.stack([np.einsum("...i,ij,...j->...", dwx, H, wz), np.einsum("...i,ij,...j->...", wx, H, dwz)], -1)


def normal(hf: Heightfield, x, z) -> np.ndarray:
    """Upward unit normal of the ground at (x, z) (..., 3): (-h_x, 1, -h_z) made unit length."""
    g = gradient(hf, x, z)
    N = np.stack([-g[..., 0], np.ones(g.shape[:-1]), -g[..., 1]], -1)
    return N / np.linalg.norm(N, axis=-1, keepdims=True)


def gap(hf: Heightfield, points) -> tuple[np.ndarray, np.ndarray]:
    """Gaps (n) and normals (n x 3) of points (n x 3, world frame, m): :func:`gap_expression` in numpy."""
    P = np.atleast_2d(np.asarray(points, dtype=float))
    n = normal(hf, P[:, 0], P[:, 2])
    return (P[:, 1] - height(hf, P[:, 0], P[:, 2])) * n[:, 1], n


def vertical_clearance(hf: Heightfield, points) -> np.ndarray:
    """Height of each point (n x 3) above the ground directly below it, y - h(x, z) (m): what a
    straight-down approach closes. The first point to touch is the one with the smallest."""
    P = np.atleast_2d(np.asarray(points, dtype=float))
    return P[:, 1] - height(hf, P[:, 0], P[:, 2])


def _symbolic_weights(grid: tuple[float, ...], s: ca.SX) -> tuple[list, list]:
    """:func:`_weights` as CasADi expressions of the scalar s."""
    n = len(grid)
    if n == 1:
        return [ca.SX(1.0)], [ca.SX(0.0)]
    u, du = [], []
    for k in range(n - 1):
        d = grid[k + 1] - grid[k]
        u.append((ca.fmin(ca.fmax(s, grid[k]), grid[k + 1]) - grid[k]) / d)
        du.append(ca.if_else(ca.logic_and(s >= grid[k], s < grid[k + 1]), 1.0 / d, 0.0))
    w = [1.0 - u[0]] + [u[k - 1] - u[k] for k in range(1, n - 1)] + [u[-1]]
    dw = [-du[0]] + [du[k - 1] - du[k] for k in range(1, n - 1)] + [du[-1]]
    return w, dw


def gap_expression(hf: Heightfield, W_p: ca.SX) -> tuple[ca.SX, ca.SX]:
    """Gap of the point ``W_p`` (SX, 3 x 1, m) and the ground's upward unit normal below it
    (3 x 1), as CasADi expressions (module docstring)."""
    px, py, pz = W_p[0], W_p[1], W_p[2]
    wx, dwx = _symbolic_weights(hf.x, px)
    wz, dwz = _symbolic_weights(hf.z, pz)
    H = hf.heights
    h = hx = hz = 0
    for j in range(len(hf.z)):
        col = sum(H[i][j] * wx[i] for i in range(len(hf.x)) if H[i][j] != 0.0)
        dcol = sum(H[i][j] * dwx[i] for i in range(len(hf.x)) if H[i][j] != 0.0)
        h = h + col * wz[j]
        hx = hx + dcol * wz[j]
        hz = hz + col * dwz[j]
    norm = ca.sqrt(1.0 + hx * hx + hz * hz)
    return (py - h) / norm, ca.vertcat(-hx, 1.0, -hz) / norm


@functools.lru_cache(maxsize=64)
def gap_function(hf: Heightfield) -> ca.Function:
    """:func:`gap_expression` as a CasADi function ``(point) -> (gap, normal)``."""
    W_p = ca.SX.sym("point", 3)
    g, n = gap_expression(hf, W_p)
    return ca.Function("heightfield_gap", [W_p], [g, n], ["point"], ["gap", "normal"])


__all__ = [
    "FLAT_HEIGHTFIELD",
    "Heightfield",
    "flat_heightfield",
    "gap",
    "gap_expression",
    "gap_function",
    "gradient",
    "height",
    "is_twisted",
    "normal",
    "vertical_clearance",
]
