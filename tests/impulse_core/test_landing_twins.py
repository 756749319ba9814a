"""Identical toes (twins: equal sibling subtrees) in the whole landing: found by
:func:`twin_groups`, held alike (:meth:`_Landing.twinned`), and in the plane n of them land as one
toe of n times the mass, stiffness and damping."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from impulse_core.model.tree import Tree
from impulse_core.timedomain.events.run import _Landing
from impulse_core.timedomain.events.twins import symmetrized, twin_groups
from optimizer.config.model_file import load_model_file
from optimizer.design_space import study_landing

TRIAL38 = Path(__file__).parent / "data" / "twin_toes_trial38.yaml"
#: the step of the study's run that chattered (landing(): RK4's stable step 1.958e-5 s halved)
STEP38 = 9.791398987245882e-06


def _one_toe(tree: Tree, laws: tuple, n: int) -> tuple[Tree, tuple]:
    """``tree`` (heel, then n identical two-rod toes after body 3) with one toe of n times the mass,
    stiffness and damping (the same rods, so n times the inertia)."""
    bodies = tuple(replace(b, mass=n * b.mass) if k >= 3 else b for k, b in enumerate(tree.bodies[:5]))
    joints = tuple(replace(j, stiffness=n * j.stiffness, damping=n * j.damping) if k >= 3 else j
                   for k, j in enumerate(laws[:5]))
    return Tree(bodies), joints


def test_twin_groups_are_equal_sibling_subtrees():
    m = load_model_file(TRIAL38)
    run = _Landing(m.tree, m.scene, m.joints, study_landing(1e-3))
    (group,) = run.twins
    assert group.tolist() == [[5, 6], [7, 8]]  # toe1's two joints, toe2's
    case3 = load_model_file("configs/landing_case3.yaml")
    (group,) = _Landing(case3.tree, case3.scene, case3.joints, study_landing(1e-3)).twins
    assert group.tolist() == [[5, 6], [7, 8], [9, 10]]
    # a toe rod a rounding longer, or a joint law apart: no twins
    bodies = list(m.tree.bodies)
    bodies[6] = replace(bodies[6], length=bodies[6].length * (1 + 1e-15))
    assert not _Landing(Tree(tuple(bodies)), m.scene, m.joints, study_landing(1e-3)).twins
    laws = list(m.joints)
    laws[6] = replace(laws[6], damping=laws[6].damping * 2)
    assert not twin_groups(m.tree, _Landing(m.tree, m.scene, tuple(laws), study_landing(1e-3)).joints,
                           run.layout)
    x = np.arange(9.0)
    assert symmetrized(x, run.twins).tolist() == [0, 1, 2, 3, 4, 6, 7, 6, 7]
    same = symmetrized(x, run.twins)
    assert symmetrized(same, run.twins) is same  # twins equal to the bit: untouched


def test_identical_toes_land_as_one_toe_of_twice_the_mass():
    """Trial 38 of the landing study (configs/landing_study.yaml): a heel and two identical toes,
    whose distal joints pass within 2e-4 rad of straight at t = 0.107 s while both tips stick.
    Rounding had parted the twins by 3e-8 rad and 3e-5 rad/s there, and the rows pinning both tips
    (condition 5e7 near straight) turned that into a squeeze: 5.2 N and -4.3 N of friction on 9.8 N
    and 11.4 N, the first toe outside its cone, where the twins' mean state has 0.46 N on 10.6 N
    each; no mode held, and the run at the study's third step (9.79e-6 s) stopped, chattering (toe2
    flipped its slip at every event). Held alike, the twins land as one toe of twice the mass,
    stiffness and damping does (the law of n identical toes in the plane), to rounding."""
    m = load_model_file(TRIAL38)
    settings = replace(study_landing(1e-3), integrator="rk4")  # landing()'s switch from its implicit first run
    twins = _Landing(m.tree, m.scene, m.joints, settings, space=m.space).run(STEP38)
    tree, laws = _one_toe(m.tree, m.joints, 2)
    one = _Landing(tree, m.scene, laws, settings, space=m.space).run(STEP38)
    assert len(twins.events) == len(one.events) == 12
    assert np.max(np.abs(twins.final_angles[3:5] - twins.final_angles[5:7])) <= 1e-12  # alike since the last event
    angles = np.concatenate([twins.final_angles[:5], twins.final_angles[5:]])
    assert np.max(np.abs(angles - np.concatenate([one.final_angles, one.final_angles[3:]]))) <= 1e-9
    external = [twins.total_external[0], twins.total_external[1] + twins.total_external[2]]
    assert np.max(np.abs(np.array(external) - one.total_external)) <= 1e-9 * np.max(one.total_external)
    tangential = [twins.total_tangential[0], twins.total_tangential[1] + twins.total_tangential[2]]
    assert np.max(np.abs(np.array(tangential) - one.total_tangential)) <= 1e-9 * np.max(one.total_external)
    assert np.max(np.abs(twins.final_base - one.final_base)) <= 1e-9
    assert twins.momentum_balance <= 1e-6


def test_three_identical_toes_land_as_one_toe_of_three_times_the_mass():
    """configs/landing_case3.yaml (three identical toes, 441 events in 0.3 s) at its reported step
    against one toe of three times the mass, stiffness and damping."""
    m = load_model_file("configs/landing_case3.yaml")
    settings = replace(study_landing(1e-3), integrator="rk4")
    step = 0.001333873624308736  # landing()'s at the default tolerance
    three = _Landing(m.tree, m.scene, m.joints, settings).run(step)
    tree, laws = _one_toe(m.tree, m.joints, 3)
    one = _Landing(tree, m.scene, laws, settings).run(step)
    assert len(three.events) == len(one.events)
    assert np.max(np.abs(three.final_angles[:5] - one.final_angles)) <= 1e-12
    external = [three.total_external[0], three.total_external[1:].sum()]
    assert np.max(np.abs(np.array(external) - one.total_external)) <= 1e-12 * np.max(one.total_external)
