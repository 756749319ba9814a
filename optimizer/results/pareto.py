"""Pareto fronts of minimised objectives: non-dominated filtering and hypervolume (pure numpy)."""

from __future__ import annotations

import numpy as np

#: Two objective vectors closer than this (relative) are the same point of a front.
SAME_POINT = 1e-9


def dominates(a: np.ndarray, b: np.ndarray) -> bool:
    """True when ``a`` is no worse than ``b`` in every objective and better in one (minimising)."""
    return bool(np.all(a <= b) and np.any(a < b))


def non_dominated(values: np.ndarray) -> np.ndarray:
    """Indices of the rows of ``values`` (points x objectives) that no other row dominates,
    keeping one row (the first) of points that coincide within ``SAME_POINT``; sorted by the
    first objective, then the others."""
    values = np.asarray(values, dtype=float)
    if values.size == 0:
        return np.zeros(0, dtype=int)
    keep: list[int] = []
    for i, v in enumerate(values):
        if any(dominates(values[j], v) for j in range(len(values)) if j != i):
            continue
        scale = np.maximum(np.abs(v), 1.0)
        if any(np.all(np.abs(values[j] - v) <= SAME_POINT * scale) for j in keep):
            continue
        keep.append(i)
    order = np.lexsort(values[keep].T[::-1])
    return np.array(keep, dtype=int)[order]


def hypervolume(points: np.ndarray, reference: np.ndarray) -> float:
    """The volume dominated by ``points`` and bounded by ``reference`` (minimising): exact, by
    slicing along the last objective (fine for the fronts of a study: tens of points, few
    objectives). Points not better than the reference in every objective add nothing."""
    points = np.asarray(points, dtype=float).reshape(-1, len(reference))
    reference = np.asarray(reference, dtype=float)
    points = points[np.all(points < reference, axis=1)]
    if len(points) == 0:
        return 0.0
    if points.shape[1] == 1:
        return float(reference[0] - points[:, 0].min())
    if points.shape[1] == 2:
        p = points[np.argsort(points[:, 0])]
        volume, best_y = 0.0, reference[1]
        for x, y in p:
            if y < best_y:
                volume += (reference[0] - x) * (best_y - y)
                best_y = y
        return float(volume)
    order = np.argsort(points[:, -1])
    p = points[order]
    volume = 0.0
    for k in range(len(p)):
        upper = p[k + 1, -1] if k + 1 < len(p) else reference[-1]
        depth = upper - p[k, -1]
        if depth > 0:
            volume += depth * hypervolume(p[: k + 1, :-1], reference[:-1])
    return float(volume)


__all__ = ["SAME_POINT", "dominates", "hypervolume", "non_dominated"]
