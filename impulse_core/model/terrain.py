"""Piecewise-linear ground profiles in the plane (x forward, y up; world frame, m).

A :class:`Terrain` is a height function y = h(x) given by breakpoints; between breakpoints it is
linear, beyond the first and last breakpoint it continues flat (constant height). Flat ground
at y = 0 is the default.

Contact detection uses the signed distance to the profile: ``gap`` is the Euclidean distance from
a point to the nearest point of the profile, positive above the ground and negative below it.
Over the interior of a segment this is exactly the distance along that segment's outward normal;
near a convex corner (a ridge) the normal turns radially about the corner, so the gap and the
normal stay continuous as a contact slides over it.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from impulse_core.errors import ModelError

#: Two points closer than this (m) are the same point when a normal must be chosen.
_COINCIDENT = 1e-12


@dataclass(frozen=True)
class Terrain:
    """A ground profile y = h(x): breakpoints ``x`` (strictly increasing) and ``y`` (m, world frame).

    Linear between breakpoints, flat beyond the ends. One breakpoint is flat ground at that height;
    the default is flat ground at y = 0. A step is a steep ramp (e.g. 2 cm up over 2 mm): the
    profile is a function of x, so a vertical face is not representable.
    """

    x: tuple[float, ...] = (0.0,)
    y: tuple[float, ...] = (0.0,)

    def __post_init__(self) -> None:
        if len(self.x) != len(self.y):
            raise ModelError(f"scene.terrain: {len(self.x)} x values but {len(self.y)} heights")
        if not self.x:
            raise ModelError("scene.terrain: needs at least one point [x, y]")
        for i, (xi, yi) in enumerate(zip(self.x, self.y)):
            if not (math.isfinite(xi) and math.isfinite(yi)):
                raise ModelError(f"scene.terrain[{i}]: must be finite numbers [x, y], got [{xi}, {yi}]")
        for i in range(1, len(self.x)):
            if not self.x[i] > self.x[i - 1]:
                raise ModelError(
                    f"scene.terrain[{i}]: x must increase strictly along the profile, got {self.x[i]} after "
                    f"{self.x[i - 1]} (a step is a steep ramp, e.g. [[0.0, 0.0], [0.002, 0.02]])"
                )

    @classmethod
    def from_points(cls, points) -> Terrain:
        """From a list of ``[x, y]`` pairs (the model file's ``scene.terrain``)."""
        pts = [tuple(float(v) for v in p) for p in points]
        for i, p in enumerate(pts):
            if len(p) != 2:
                raise ModelError(f"scene.terrain[{i}]: must be a pair [x, y], got {list(p)}")
        return cls(tuple(p[0] for p in pts), tuple(p[1] for p in pts))

    @property
    def points(self) -> tuple[tuple[float, float], ...]:
        return tuple(zip(self.x, self.y))

    @property
    def is_flat(self) -> bool:
        """True when every breakpoint has the same height (a horizontal line)."""
        return len(set(self.y)) == 1


FLAT = Terrain()


def flat(height: float = 0.0) -> Terrain:
    """Horizontal ground at ``height`` (m)."""
    return Terrain((0.0,), (float(height),))


def height(terrain: Terrain, x) -> np.ndarray:
    """Ground height h(x) (m), linear between breakpoints and constant beyond the ends."""
    return np.interp(np.asarray(x, dtype=float), terrain.x, terrain.y)


def _segment_normals(terrain: Terrain) -> np.ndarray:
    """Outward (upward) unit normal of each finite segment, (n_points - 1) x 2."""
    d = np.diff(np.column_stack([terrain.x, terrain.y]), axis=0)
    n = np.column_stack([-d[:, 1], d[:, 0]])
    return n / np.linalg.norm(n, axis=1, keepdims=True) if len(n) else n


def slope_normal(terrain: Terrain, x) -> np.ndarray:
    """Outward unit normal of the profile above x (..., 2).

    Inside a segment: the segment's normal. Beyond the ends: (0, 1). Exactly at an interior
    breakpoint: the normalised mean of the two adjacent segments' normals.
    """
    x = np.asarray(x, dtype=float)
    out = np.zeros(x.shape + (2,))
    out[..., 1] = 1.0
    xs = np.asarray(terrain.x)
    if len(xs) < 2:
        return out
    seg_n = np.vstack([[0.0, 1.0], _segment_normals(terrain), [0.0, 1.0]])  # left ray, segments, right ray
    right = np.searchsorted(xs, x, side="right")  # segment index + 1 of the segment to the right of x
    left = np.searchsorted(xs, x, side="left")
    n = seg_n[right]
    at_vertex = right != left
    if np.any(at_vertex):
        mean = seg_n[left] + seg_n[right]
        mean = mean / np.linalg.norm(mean, axis=-1, keepdims=True)
        n = np.where(at_vertex[..., None], mean, n)
    return n


@dataclass(frozen=True)
class Gap:
    """Contact detection for a set of points (n points).

    Attributes:
        gap: signed distance to the profile (m): > 0 above the ground, < 0 penetrating.
        normal: outward unit normal of the ground at the nearest point (n x 2): the gradient of
            the signed distance, so that d(gap)/dt = normal . (point velocity).
    """

    gap: np.ndarray
    normal: np.ndarray


def gap_expression(terrain: Terrain, W_p: ca.SX) -> tuple[ca.SX, ca.SX]:
    """Signed distance of the planar point ``W_p`` (SX, 2 x 1, m) to the profile and the outward
    unit normal at the nearest profile point (2 x 1), as CasADi expressions (see :class:`Gap`).

    The profile is split into the left ray (x <= x_0), the segments, and the right ray; the
    nearest piece wins. The normal is the piece's own where the nearest point is inside it, and
    radial (the signed distance's gradient) where it is a breakpoint; at zero distance from a
    breakpoint, the mean of the adjacent normals. The sign is that of y - h(x).
    """
    xs, ys = terrain.x, terrain.y
    n_pts = len(xs)
    seg_normals = _segment_normals(terrain)
    pieces = [((xs[0], ys[0]), (-1.0, 0.0), math.inf, (0.0, 1.0))]
    pieces += [
        ((xs[i], ys[i]), (xs[i + 1] - xs[i], ys[i + 1] - ys[i]), 1.0, tuple(seg_normals[i])) for i in range(n_pts - 1)
    ]
    pieces += [((xs[-1], ys[-1]), (1.0, 0.0), math.inf, (0.0, 1.0))]
    vertex_normals = slope_normal(terrain, np.asarray(xs))
    px, py = W_p[0], W_p[1]
    h = ys[0]
    for i in range(n_pts - 1):  # h(x) = y_0 + sum_i slope_i (clip(x, x_i, x_i+1) - x_i): linear, flat beyond
        slope = (ys[i + 1] - ys[i]) / (xs[i + 1] - xs[i])
        h = h + slope * (ca.fmin(ca.fmax(px, xs[i]), xs[i + 1]) - xs[i])
    sign = ca.if_else(py - h >= 0, 1.0, -1.0)
    best_d = best_nx = best_ny = None
    for k, ((ax, ay), (dx, dy), upper, (nx, ny)) in enumerate(pieces):
        t = ((px - ax) * dx + (py - ay) * dy) / (dx * dx + dy * dy)
        t = ca.fmax(t, 0.0) if math.isinf(upper) else ca.fmin(ca.fmax(t, 0.0), upper)
        cx, cy = ax + t * dx, ay + t * dy
        d = ca.sqrt((px - cx) ** 2 + (py - cy) ** 2)
        # the breakpoint this piece ends at, if the nearest point is one
        end = 0 if k == 0 else (n_pts - 1 if k == len(pieces) - 1 else None)
        if end is None:
            vnx = ca.if_else(t <= 0.0, vertex_normals[k - 1][0], vertex_normals[k][0])
            vny = ca.if_else(t <= 0.0, vertex_normals[k - 1][1], vertex_normals[k][1])
            interior = ca.logic_and(t > 0.0, t < upper)
        else:
            vnx, vny = vertex_normals[end][0], vertex_normals[end][1]
            interior = t > 0.0
        safe = ca.fmax(d, _COINCIDENT)
        radial = d > _COINCIDENT
        kx = ca.if_else(interior, nx, ca.if_else(radial, sign * (px - cx) / safe, vnx))
        ky = ca.if_else(interior, ny, ca.if_else(radial, sign * (py - cy) / safe, vny))
        if best_d is None:
            best_d, best_nx, best_ny = d, kx, ky
        else:
            closer = d < best_d
            best_d = ca.if_else(closer, d, best_d)
            best_nx = ca.if_else(closer, kx, best_nx)
            best_ny = ca.if_else(closer, ky, best_ny)
    return sign * best_d, ca.vertcat(best_nx, best_ny)


@functools.lru_cache(maxsize=64)
def gap_function(terrain: Terrain) -> ca.Function:
    """:func:`gap_expression` as a CasADi function ``(point) -> (gap, normal)``, built once per terrain."""
    W_p = ca.SX.sym("point", 2)
    gap, normal = gap_expression(terrain, W_p)
    return ca.Function("terrain_gap", [W_p], [gap, normal], ["point"], ["gap", "normal"])


def signed_gap(terrain: Terrain, points) -> Gap:
    """Signed distance of planar points (n x 2, world frame, m) to the profile, with the outward
    normal at the nearest profile point (see :class:`Gap` and :func:`gap_expression`)."""
    P = np.atleast_2d(np.asarray(points, dtype=float))[:, :2]
    if len(P) == 0:
        return Gap(np.zeros(0), np.zeros((0, 2)))
    gap, normal = gap_function(terrain).map(len(P))(P.T)
    return Gap(gap=np.array(gap).ravel(), normal=np.array(normal).T)


def vertical_clearance(terrain: Terrain, points) -> np.ndarray:
    """Height of each point above the ground directly below it, y - h(x) (m): what a straight-down
    approach closes. The first point to touch is the one with the smallest clearance."""
    P = np.atleast_2d(np.asarray(points, dtype=float))
    return P[:, 1] - height(terrain, P[:, 0])


__all__ = [
    "FLAT",
    "Gap",
    "Terrain",
    "flat",
    "gap_expression",
    "gap_function",
    "height",
    "signed_gap",
    "slope_normal",
    "vertical_clearance",
]
