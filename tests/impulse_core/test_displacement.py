"""Design derivatives of the placed tree by rigid displacements of subtrees
(``impulse_core/kinematics/displacement.py``) against CasADi's reverse mode through the forward
kinematics, and the spatial adjoint gradient that uses them against reverse mode through the
whole impact model."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from impulse_core.evaluate import pre_impact_velocity
from impulse_core.impact.delassus import GRADIENT_OUTPUTS, LeanAlgorithm, norms_gradient_function
from impulse_core.kinematics.displacement import placed_gradient, placed_symbols
from impulse_core.kinematics.spatial import PLANAR, SPATIAL, forward_kinematics, n_values, unpack_values
from impulse_core.model.tree import Tree, design_vector
from tests.conftest import random_tree
from tests.impulse_core.test_spatial import SCENE, spatial_trees
from tests.impulse_core.test_spatial_inertia import general_trees

FIELDS = ("W_R_B", "W_p_O", "W_p_G", "W_p_T", "W_p_C", "joint_axis")


def _stacked(kin) -> ca.SX:
    return ca.vertcat(*[ca.vec(x) for f in FIELDS for x in getattr(kin, f) if x is not None])


def _objective(kin, values, rng: np.random.Generator) -> ca.SX:
    """A random nonlinear function of every placed quantity (rotations, points, axes) and of
    the masses (which place nothing: their part is the direct gradient)."""
    k = _stacked(kin)
    c, d = rng.normal(size=k.shape[0]), rng.normal(size=k.shape[0])
    masses = ca.vertcat(*[v.mass for v in values])
    return ca.DM(c).T @ k + (ca.DM(d).T @ k) ** 2 + ca.sin(ca.DM(d).T @ k) * ca.sum1(masses)


def _planar_trees() -> list[Tree]:
    rng = np.random.default_rng(7)
    return [random_tree(rng, int(rng.integers(1, 7)), p_contact=0.6) for _ in range(6)]


@pytest.mark.parametrize(
    "trees, space", [(_planar_trees, PLANAR), (spatial_trees, SPATIAL), (general_trees, SPATIAL)],
    ids=["planar", "spatial", "offsets-and-tensors"],
)
def test_placement_gradient_equals_reverse_mode_through_the_kinematics(trees, space) -> None:
    """Every design value's derivative (angle, rpy, axis, at, length, com, com offset, contact
    fractions, and the masses' direct part) to rounding, for a random objective of the whole
    placed tree."""
    rng = np.random.default_rng(3)
    for tree in trees()[:12]:
        topology = tree.topology()
        p = ca.SX.sym("p", n_values(topology, space))
        values = unpack_values(topology, p, space)
        kin = forward_kinematics(topology, values, space)
        seed = int(rng.integers(1 << 30))
        reference = ca.gradient(_objective(kin, values, np.random.default_rng(seed)), p)
        placed = placed_symbols(kin, p)
        objective = _objective(placed.kin, values, np.random.default_rng(seed))
        ours = placed_gradient(topology, values, kin, placed, objective, p)
        ours = ca.substitute(ours, placed.symbols, placed.placed)
        f = ca.Function("f", [p], [reference, ours])
        x = design_vector(tree, space.body_values)
        a, b = (np.array(y).ravel() for y in f(x))
        assert np.abs(a).max() > 0
        np.testing.assert_allclose(b, a, rtol=0, atol=1e-11 * np.abs(a).max())


@pytest.mark.parametrize("algorithm", [LeanAlgorithm.COMPOSITE, LeanAlgorithm.ARTICULATED])
def test_spatial_adjoint_gradient_equals_reverse_mode(algorithm) -> None:
    """Both norms' gradients w.r.t. every design value of random spatial trees with centre-of-mass
    offsets and added tensors: the adjoint (placed tree by displacements) against CasADi's
    reverse mode through every factorization and the forward kinematics."""
    rng = np.random.default_rng(5)
    compared = 0
    for tree in general_trees()[:6]:
        topology = tree.topology()
        if not topology.active:
            continue
        v = pre_impact_velocity(topology, SCENE, SPATIAL)
        v = v + 0.3 * rng.normal(size=v.size)  # a turning base and moving joints: J v_minus depends on p
        args = {"p": design_vector(tree, SPATIAL.body_values), "v_minus": v, "restitution": SCENE.restitution}
        a = norms_gradient_function(topology, SPATIAL, algorithm=algorithm)(**args)
        b = norms_gradient_function(topology, SPATIAL, algorithm=algorithm, adjoint=False)(**args)
        for k in GRADIENT_OUTPUTS:
            ref = np.array(b[k]).ravel()
            np.testing.assert_allclose(np.array(a[k]).ravel(), ref, rtol=1e-7, atol=1e-9 * np.abs(ref).max(), err_msg=k)
        compared += 1
    assert compared >= 4
