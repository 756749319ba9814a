"""Pareto filtering and hypervolume, and the optimiser's front against an exhaustive grid."""

from __future__ import annotations

import itertools

import numpy as np
import optuna
import pytest

from optimizer.design_space import design_from, evaluate_design
from optimizer.search.inner import run_inner
from optimizer.config.model_file import load_yaml
from optimizer.results.pareto import dominates, hypervolume, non_dominated
from optimizer.results.runs import pareto_front
from optimizer.search.outer import open_study, recorded_trials
from optimizer.config.study_config import parse_study

optuna.logging.set_verbosity(optuna.logging.WARNING)


def test_non_dominated_filters_sorts_and_merges_duplicates():
    values = np.array([[1.0, 5.0], [2.0, 2.0], [3.0, 3.0], [1.0, 5.0], [5.0, 1.0], [2.0, 2.0 + 1e-13]])
    idx = non_dominated(values)
    assert list(idx) == [0, 1, 4]
    front = values[idx]
    for a, b in itertools.permutations(front, 2):
        assert not dominates(a, b)


def test_a_point_tied_in_one_objective_and_worse_in_another_is_dominated():
    """Pareto dominance is weak in each objective: a design that ties the best in one objective
    and is worse in the other is off the front (also in three objectives, tied in two)."""
    assert dominates(np.array([1.0, 5.0]), np.array([1.0, 6.0]))
    assert not dominates(np.array([1.0, 5.0]), np.array([1.0, 5.0]))
    values = np.array([[1.0, 6.0], [3.0, 1.0], [1.0, 5.0], [3.0, 2.0], [2.0, 5.0]])
    assert list(non_dominated(values)) == [2, 1]
    values = np.array([[1.0, 2.0, 3.0], [1.0, 2.0, 4.0], [0.5, 9.0, 9.0]])
    assert list(non_dominated(values)) == [2, 0]


def test_non_dominated_random_points_are_mutually_non_dominated(rng):
    values = rng.random((200, 3))
    idx = non_dominated(values)
    front = values[idx]
    for a, b in itertools.permutations(front, 2):
        assert not dominates(a, b)
    others = np.delete(values, idx, axis=0)
    assert all(any(dominates(f, o) for f in front) for o in others)


def test_hypervolume_known_values():
    ref = np.array([4.0, 4.0])
    assert hypervolume(np.array([[1.0, 1.0]]), ref) == pytest.approx(9.0)
    assert hypervolume(np.array([[1.0, 3.0], [3.0, 1.0]]), ref) == pytest.approx(3 + 3 - 1)
    assert hypervolume(np.array([[5.0, 1.0]]), ref) == 0.0  # beyond the reference
    assert hypervolume(np.array([[1.0, 1.0, 1.0]]), np.array([2.0, 3.0, 4.0])) == pytest.approx(6.0)


def test_hypervolume_3d_matches_monte_carlo(rng):
    points = rng.random((12, 3))
    ref = np.ones(3) * 1.2
    samples = rng.random((200_000, 3)) * 1.2
    dominated = np.zeros(len(samples), dtype=bool)
    for p in points:
        dominated |= np.all(samples >= p, axis=1)
    assert hypervolume(points, ref) == pytest.approx(dominated.mean() * 1.2**3, rel=0.02)


#: One toe of one rod and the heel: three continuous values (two angles, one mass split).
GRID_STUDY = """\
name: grid
seed: 3
design_space: {toes: [1, 1], toe_segments: [1, 1]}
constraints: {min_link_mass: 0.02}
objectives: [external_norm, internal_norm]
search: {method: inner, inner: {front_points: 8, starts: 3}}
"""
#: A grid point counts as matched when a front point is within this fraction of its value in
#: every objective (the grid is coarse; IPOPT's points are local optima to 1e-8).
GRID_TOLERANCE = 2e-3


def test_optimiser_front_matches_exhaustive_grid():
    """On a 3-value design space the inner search's front is at least as good as a 9^3 grid:
    its hypervolume is not smaller, and every feasible grid design is dominated by a front
    design up to ``GRID_TOLERANCE`` (relative)."""
    config = parse_study(load_yaml(GRID_STUDY))
    study = open_study(config, optuna.storages.InMemoryStorage())
    run_inner(study, config)
    front = pareto_front(config, list(recorded_trials(study)))
    F = np.array([[t.evaluation.objectives.external_norm, t.evaluation.objectives.internal_norm] for t in front])
    lim, n = config.limits, 9
    grid = []
    for heel, toe, w in itertools.product(np.linspace(*lim.heel_root, n), np.linspace(*lim.toe_root, n), np.linspace(0, 1, n)):
        m_heel = lim.min_link_mass + w * (lim.foot_mass - 2 * lim.min_link_mass)
        design = design_from(config.leg, ((heel,), (toe,)), ((m_heel,), (lim.foot_mass - m_heel,)), lim)
        ev = evaluate_design(config.leg, design, config.scene, lim)
        if ev.feasible:
            grid.append([ev.objectives.external_norm, ev.objectives.internal_norm])
    G = np.array(grid)
    assert len(G) > 100 and len(F) >= 2
    ref = np.maximum(F.max(axis=0), G.max(axis=0)) * 1.1
    assert hypervolume(F, ref) >= hypervolume(G, ref) * (1 - 1e-9)
    for g in G:
        assert np.any(np.all(F <= g * (1 + GRID_TOLERANCE), axis=1)), g
