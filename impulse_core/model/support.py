"""The support polygon of a spatial foot: does the centre of mass stand over its contacts?

The ground is the x-z plane (y up). The support polygon is the convex hull of the contact points'
ground projections; the margin is the signed distance from the centre of mass's projection to
the polygon's boundary: positive inside, negative outside. Contacts on one line (a planar foot)
or at one point span no area: the margin is then minus the distance to that segment or point
(zero at best), since such a foot cannot stand on its own sideways.
"""

from __future__ import annotations

import numpy as np


def convex_hull(points: np.ndarray) -> np.ndarray:
    """The hull's vertices counter-clockwise (Andrew's monotone chain), duplicates removed."""
    pts = np.unique(np.asarray(points, dtype=float), axis=0)
    if len(pts) <= 2:
        return pts

    def cross(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
        return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))

    def chain(seq: np.ndarray) -> list[np.ndarray]:
        out: list[np.ndarray] = []
        for p in seq:
            while len(out) >= 2 and cross(out[-2], out[-1], p) <= 0:
                out.pop()
            out.append(p)
        return out

    lower, upper = chain(pts), chain(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    d = b - a
    t = 0.0 if not d.any() else float(np.clip(np.dot(p - a, d) / np.dot(d, d), 0.0, 1.0))
    return float(np.linalg.norm(p - (a + t * d)))


def support_margin(points: np.ndarray, com: np.ndarray) -> float:
    """Signed distance (m) from ``com`` (2,) to the boundary of the convex hull of ``points``
    (n x 2): positive inside (module docstring)."""
    hull = convex_hull(points)
    p = np.asarray(com, dtype=float)
    edges = list(zip(hull, np.roll(hull, -1, axis=0), strict=True)) if len(hull) > 1 else [(hull[0], hull[0])]
    distance = min(_segment_distance(p, a, b) for a, b in edges)
    if len(hull) < 3:  # no area: a segment or a point
        return -distance
    inside = all((b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]) >= 0 for a, b in edges)
    return distance if inside else -distance


__all__ = ["convex_hull", "support_margin"]
