"""The time-domain rungs (sequential; compliant, fixed steps and adaptive) on planar trees whose
centres of mass lie off their rods (``com_offset`` [dy, 0]; MODEL_FORMAT "Bodies").

Laws checked (seeded random trees and paper case 3 with offsets):
- the planar tree equals the same tree read as spatial (the spatial rungs carry general offsets),
  on flat ground and on an uneven terrain (a heightfield constant along z in space);
- the linear momentum, read independently of the rungs (the whole tree's centre of mass from the
  core's touchdown geometry, differentiated along the velocity), changes by the contact and gravity
  impulses; a tree with the same values but its centres of mass on the rods does not balance;
- the stiff limits: the sequential rung on level contacts is the first-impact answer (eq. 11, which
  matches Pinocchio with offsets), and the compliant constraint law converges to it.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from fidelity_scenes import PAPER_SCENE, UNEVEN, case3

from impulse_core.evaluate import evaluate, pre_impact_velocity, touchdown_geometry
from impulse_core.kinematics.spatial import SPATIAL, dof_layout
from impulse_core.model.heightfield import Heightfield
from impulse_core.model.tree import Scene, Tree
from impulse_core.timedomain.adaptive import simulate_adaptive
from impulse_core.timedomain.compliant import (
    CompliantSettings,
    ContactLaw,
    relative_difference,
    simulate_impact,
    subtree_masses,
    touchdown_configuration,
)
from impulse_core.timedomain.sequential import sequential_impacts
from tests.conftest import random_tree, report

SEED = 20261126
OBLIQUE = Scene(speed=2.0, restitution=0.5, velocity_x=0.3, angular_velocity=0.7)


def with_offsets(rng: np.random.Generator, tree: Tree, scale: float = 0.3) -> Tree:
    """Each body's centre of mass moved off its rod by up to ``scale`` of its length, in the plane."""
    return Tree(tuple(dataclasses.replace(b, com_offset=(float(rng.uniform(-scale, scale)) * b.length, 0.0))
                      for b in tree.bodies))


def on_rods(tree: Tree) -> Tree:
    return Tree(tuple(dataclasses.replace(b, com_offset=(0.0, 0.0)) for b in tree.bodies))


def trees(rng: np.random.Generator) -> list[Tree]:
    randoms = [random_tree(rng, int(rng.integers(2, 5)), mass_ratio=5.0, length_range=(0.1, 0.6)) for _ in range(1)]
    return [with_offsets(rng, t) for t in [case3(), *randoms]]


def as_heightfield(terrain) -> Heightfield:
    return Heightfield(terrain.x, (0.0,), tuple((y,) for y in terrain.y))


def difference(a, b) -> float:
    return relative_difference([(a.external, b.external), (a.internal_magnitude, b.internal_magnitude)])


@pytest.mark.parametrize("ground", ["flat", "uneven"])
def test_planar_offsets_equal_the_tree_read_as_spatial(ground):
    rng = np.random.default_rng(SEED)
    terrain = UNEVEN if ground == "uneven" else None
    field = as_heightfield(UNEVEN) if ground == "uneven" else None
    worst = {"compliant": 0.0, "adaptive": 0.0, "sequential": 0.0}
    for tree in trees(rng):
        assert max(abs(b.com_offset[0]) for b in tree.bodies) > 1e-3
        for law in ContactLaw:
            st = CompliantSettings(law=law, stiffness=1e6 if law is ContactLaw.PENALTY else 1e7)
            planar, spatial = simulate_impact(tree, OBLIQUE, st, terrain), simulate_impact(tree, OBLIQUE, st, field,
                                                                                           space=SPATIAL)
            assert planar.n_steps == spatial.n_steps and planar.status is spatial.status
            np.testing.assert_allclose(spatial.v_plus[[0, 1, 5]], planar.v_plus[:3], atol=1e-9)
            worst["compliant"] = max(worst["compliant"], difference(planar, spatial))
        st = CompliantSettings(stiffness=1e6)
        a, b = simulate_adaptive(tree, OBLIQUE, st, 1e-6, terrain), simulate_adaptive(tree, OBLIQUE, st, 1e-6, field,
                                                                                      space=SPATIAL)
        worst["adaptive"] = max(worst["adaptive"], difference(a, b))
        seq, seq_spatial = sequential_impacts(tree, OBLIQUE, terrain=terrain), sequential_impacts(
            tree, OBLIQUE, terrain=field, space=SPATIAL)
        assert len(seq.events) == len(seq_spatial.events)
        worst["sequential"] = max(worst["sequential"], difference(seq, seq_spatial))
        # the offsets matter: the same tree with its centres of mass on the rods lands otherwise
        assert difference(sequential_impacts(on_rods(tree), OBLIQUE, terrain=terrain), seq) > 1e-3
    report("offsets", f"planar offsets vs spatial ({ground}): " + ", ".join(f"{k} {v:.1e}" for k, v in worst.items()))
    assert max(worst.values()) < 1e-10, worst


def linear_momentum(tree: Tree, q: np.ndarray, v: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """The tree's linear momentum at (q, v), from its centre of mass (the core's touchdown geometry
    of the tree posed at q) by central differences along v: independent of the rungs' dynamics."""
    layout = dof_layout(tree.topology())
    masses = np.array([b.mass for b in tree.bodies])

    def centre(qq: np.ndarray) -> np.ndarray:
        bodies = [dataclasses.replace(tree.bodies[0], angle=float(qq[2]))]
        bodies += [dataclasses.replace(b, angle=float(qq[layout.body_dof[i]])) if layout.body_dof[i] is not None
                   else b for i, b in enumerate(tree.bodies) if i > 0]
        coms = touchdown_geometry(Tree(tuple(bodies))).coms
        return masses @ coms / masses.sum() + qq[:2]

    return masses.sum() * (centre(q + h * v) - centre(q - h * v)) / (2 * h)


@pytest.mark.parametrize("rung", ["compliant", "adaptive", "sequential"])
def test_the_momentum_balance_holds_with_offsets(rung):
    """P+ - P- = contact impulses + gravity's (the compliant rungs: to their integration; the
    sequential rung's impacts are exact); read with the centres of mass on the rods it fails."""
    tree = with_offsets(np.random.default_rng(SEED + 1), case3(), 0.4)
    g = 9.81 if rung != "sequential" else 0.0
    if rung == "sequential":
        r, tol = sequential_impacts(tree, OBLIQUE, terrain=UNEVEN), 1e-7
        q0, v0 = touchdown_configuration(tree, UNEVEN), pre_impact_velocity(tree.topology(), OBLIQUE)
    else:
        st = CompliantSettings(stiffness=1e6, gravity=g, steps_per_period=480)
        r, tol = (simulate_adaptive(tree, OBLIQUE, st, 1e-8, UNEVEN), 1e-5) if rung == "adaptive" else (
            simulate_impact(tree, OBLIQUE, st, UNEVEN), 2e-3)
        q0, v0 = r.q_minus, r.v_minus
    duration = getattr(r, "duration", 0.0)
    impulse = r.external_vector.sum(axis=0) + [0.0, -g * subtree_masses(tree)[0] * duration]
    errors = []
    for t in (tree, on_rods(tree)):
        change = linear_momentum(t, r.q_plus, r.v_plus) - linear_momentum(t, q0, v0)
        errors.append(float(np.linalg.norm(change - impulse) / np.linalg.norm(change)))
    report("offsets", f"momentum balance with offsets ({rung}): {errors[0]:.1e}; read on the rods {errors[1]:.1e}")
    assert errors[0] < tol and errors[1] > 1e-2, errors


def test_the_stiff_limits_are_the_first_impact_answer_with_offsets():
    """Level contacts on flat ground: the sequential rung is eq. 11 (the first-impact rung, exact
    against Pinocchio with offsets); the compliant constraint law converges to it as it stiffens."""
    tree = with_offsets(np.random.default_rng(SEED + 2), case3(), 0.4)
    rigid = evaluate(tree, PAPER_SCENE)
    seq = sequential_impacts(tree, PAPER_SCENE)
    assert len(seq.events) == 1 and difference(seq, rigid) < 1e-9
    gaps = []
    for k in (1e7, 1e9):
        st = CompliantSettings(law=ContactLaw.CONSTRAINT, stiffness=k, steps_per_period=480)
        gaps.append(float(np.max(np.abs(simulate_impact(tree, PAPER_SCENE, st).external / rigid.external - 1))))
    report("offsets", f"compliant constraint law vs eq. 11 with offsets: 1e7 {gaps[0]:.1e}, 1e9 {gaps[1]:.1e}")
    assert gaps[1] < 1.5e-3 and gaps[1] < gaps[0] / 3
