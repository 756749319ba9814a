"""Rigid impacts in sequence on a terrain: equal to the core's evaluation on flat ground, one
impact per touchdown on uneven ground, complementarity when Newton's law would pull."""

from __future__ import annotations

import numpy as np
import pytest
from fidelity_scenes import PAPER_SCENE, UNEVEN, case2, case3

from impulse_core.evaluate import evaluate
from impulse_core.timedomain.sequential import SequentialSettings, _lcp_impulse, sequential_impacts
from impulse_core.model.terrain import Terrain
from tests.conftest import random_tree


@pytest.mark.parametrize("make", [case2, case3])
def test_flat_simultaneous_contacts_equal_the_core(make):
    tree = make()
    rigid = evaluate(tree, PAPER_SCENE)
    seq = sequential_impacts(tree, PAPER_SCENE)
    assert len(seq.events) == 1 and seq.touchdown_order == tuple(range(len(tree.contacts)))
    np.testing.assert_allclose(seq.external, rigid.external, rtol=1e-10)
    np.testing.assert_allclose(seq.internal_magnitude, rigid.internal_magnitude, rtol=1e-9)
    np.testing.assert_allclose(seq.v_plus, rigid.v_plus, rtol=1e-9, atol=1e-9)
    assert seq.energy_after == pytest.approx(rigid.energy_after, rel=1e-12)


def test_uneven_terrain_gives_one_impact_per_touchdown():
    seq = sequential_impacts(case2(), PAPER_SCENE, terrain=UNEVEN)
    assert [e.contacts for e in seq.events] == [(1,), (0,)]
    assert seq.touchdown_order == (1, 0)
    assert seq.touchdown_time[0] == pytest.approx(0.0054, abs=2e-4)  # ~18 mm at ~3.4 m/s
    assert not seq.energy_gain
    # the toe's impulse is along the ramp's normal
    normal = np.array([-0.04, 0.30]) / np.hypot(0.04, 0.30)
    np.testing.assert_allclose(seq.external_vector[1] / seq.external[1], normal, atol=1e-12)
    # one contact per impact: each restitution is met at its own touchdown (checked in the event)
    assert all(len(e.impulses) == 1 and e.impulses[0] > 0 for e in seq.events)


def test_flight_step_converges():
    coarse = sequential_impacts(case2(), PAPER_SCENE, SequentialSettings(flight_step=4e-4), terrain=UNEVEN)
    fine = sequential_impacts(case2(), PAPER_SCENE, SequentialSettings(flight_step=5e-5), terrain=UNEVEN)
    np.testing.assert_allclose(coarse.external, fine.external, rtol=1e-7)
    assert coarse.touchdown_time[0] == pytest.approx(fine.touchdown_time[0], abs=1e-9)


def test_complementarity_when_newton_would_pull(rng):
    """The impact law at a touchdown, on the Delassus matrices of seeded random trees (several
    contacts, straight-down approach): impulses >= 0, post-impact normal velocities >= -e times the
    approach, complementary (1e-9); where eq. 11 asks a contact to pull, it separates instead."""
    from impulse_core.timedomain.compliant import _Evaluator, compiled_step, touchdown_configuration
    from impulse_core.model.tree import design_vector

    e = 0.5
    pulling = 0
    for _ in range(40):
        tree = random_tree(rng, 4, p_contact=1.0, max_contacts_per_body=2)
        ev = _Evaluator(compiled_step(tree.topology(), Terrain()), design_vector(tree), 0.0)
        q = touchdown_configuration(tree)
        v = np.zeros(len(q))
        v[1] = -2.0
        s = ev(q, v)
        A = s.Jn @ s.minv_jnt
        u = s.rate.copy()
        lam = _lcp_impulse(A, u, e)
        w = u + A @ lam + e * u
        scale = np.abs(u).max()
        assert np.all(lam >= 0.0)
        assert np.all(w >= -1e-9 * scale)
        assert abs(lam @ w) <= 1e-9 * scale * max(1.0, np.abs(lam).max())
        if np.linalg.cond(A) < 1e8 and np.any(np.linalg.solve(A, -(1 + e) * u) < -1e-9):
            pulling += 1
            assert np.any(lam == 0.0)
    assert pulling >= 3  # the check met contacts that eq. 11 makes pull


@pytest.mark.parametrize("module", ["impulse_core.model.terrain", "impulse_core.timedomain.compliant", "impulse_core.timedomain.sequential"])
def test_terrain_modules_import_only_casadi_and_numpy(module):
    """Dependency direction (STYLE.md), as tests/impulse_core/test_imports.py checks the others."""
    import json
    import subprocess
    import sys
    from pathlib import Path

    code = (
        f"import json, sys, {module}\n"
        "print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in "
        "['yaml', 'optuna', 'scipy', 'matplotlib', 'cvxpy', 'mujoco'])))"
    )
    root = Path(__file__).resolve().parents[2]
    out = subprocess.run([sys.executable, "-c", code], cwd=root, capture_output=True, text=True, check=True)
    assert json.loads(out.stdout.strip().splitlines()[-1]) == []


def test_a_scene_carrying_its_terrain_is_used():
    """Both time-domain models take ``scene.terrain`` and ``scene.base_x`` without arguments, and
    an argument overrides the scene's."""
    import dataclasses

    from impulse_core.timedomain.compliant import CompliantSettings, simulate_impact

    scene = dataclasses.replace(PAPER_SCENE, terrain=UNEVEN, base_x=0.0)
    assert sequential_impacts(case2(), scene).touchdown_order == (1, 0)
    assert simulate_impact(case2(), scene, CompliantSettings(steps_per_period=30)).touchdown_order == (1, 0)
    assert sequential_impacts(case2(), PAPER_SCENE, terrain=UNEVEN).touchdown_order == (1, 0)
    shifted = sequential_impacts(case2(), dataclasses.replace(scene, base_x=0.01))
    assert shifted.touchdown_time[0] != sequential_impacts(case2(), scene).touchdown_time[0]
