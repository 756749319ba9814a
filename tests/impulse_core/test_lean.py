"""The optimiser's hot path (``lean_impact_function``) computes what the full model computes,
by either tree algorithm, on seeded random trees (fixed joints, several contacts per body, chains)
and on extreme values; so do its adjoint gradients (``norms_gradient_function``) against
CasADi's reverse mode of the same graph; the composite mass matrix equals the sum of J^T M J."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from impulse_core.kinematics import dynamics as dyn
from impulse_core.evaluate import approach_velocity
from impulse_core.impact.delassus import (
    GRADIENT_OUTPUTS,
    LEAN_OUTPUTS,
    LeanAlgorithm,
    impact_function,
    lean_impact_function,
    mass_matrix_function,
    norms_gradient_function,
)
from impulse_core.kinematics.spatial import dof_layout, forward_kinematics, unpack_values
from impulse_core.model.tree import design_vector
from tests.conftest import contact_independence, random_tree


def _trees(seed: int, count: int, **options):
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < count:
        tree = random_tree(rng, int(rng.integers(1, 14)), **options)
        if contact_independence(tree)[0]:
            out.append(tree)
    return out


OPTIONS = pytest.mark.parametrize(
    "options",
    [
        {},
        {"chain": True, "p_fixed": 0.0},
        {"max_contacts_per_body": 2},
        {"mass_ratio": 1e6, "length_range": (1e-3, 5.0)},
    ],
    ids=["random", "chain", "two-contacts", "extreme"],
)


@pytest.mark.parametrize("algorithm", [LeanAlgorithm.COMPOSITE, LeanAlgorithm.ARTICULATED, LeanAlgorithm.AUTO])
@OPTIONS
def test_lean_equals_full_model(algorithm, options) -> None:
    for tree in _trees(7, 6, **options):
        topology = tree.topology()
        full, lean = impact_function(topology), lean_impact_function(topology, algorithm=algorithm)
        v = approach_velocity(topology, 2.5)
        args = {"p": design_vector(tree), "v_minus": v, "restitution": 0.7}
        a, b = full(**args), lean(**args)
        assert lean.name_out() == list(LEAN_OUTPUTS)
        for k in LEAN_OUTPUTS:
            ref = np.array(a[k]).ravel()
            scale = max(1.0, float(np.abs(ref).max(initial=0.0)))
            np.testing.assert_allclose(np.array(b[k]).ravel(), ref, rtol=1e-7, atol=1e-7 * scale, err_msg=k)


@pytest.mark.parametrize("algorithm", [LeanAlgorithm.COMPOSITE, LeanAlgorithm.ARTICULATED])
@OPTIONS
def test_adjoint_gradient_equals_reverse_mode(algorithm, options) -> None:
    """The adjoint of the impact equations gives what CasADi's reverse mode gives when it
    differentiates through every factorization of the same graph; for a pure translation and for
    a random pre-impact velocity (rotating base, moving joints: J v_minus then depends on p)."""
    rng = np.random.default_rng(12)
    for i, tree in enumerate(_trees(11, 6, **options)):
        topology = tree.topology()
        v = approach_velocity(topology, 2.5)
        if i % 2:
            v = v + rng.normal(size=v.size)
        args = {"p": design_vector(tree), "v_minus": v, "restitution": 0.7}
        a = norms_gradient_function(topology, algorithm=algorithm)(**args)
        b = norms_gradient_function(topology, algorithm=algorithm, adjoint=False)(**args)
        for k in GRADIENT_OUTPUTS:
            ref = np.array(b[k]).ravel()
            scale = float(np.abs(ref).max(initial=0.0))
            np.testing.assert_allclose(np.array(a[k]).ravel(), ref, rtol=1e-7, atol=1e-9 * scale, err_msg=k)


def test_composite_mass_matrix_equals_jacobian_sum() -> None:
    for tree in _trees(8, 8):
        topology = tree.topology()
        p = ca.SX.sym("p", topology.n_values)
        values = unpack_values(topology, p)
        kin = forward_kinematics(topology, values)
        layout = dof_layout(topology)
        crba = ca.Function("m", [p], [dyn.composite_mass_matrix(topology.parents, kin, layout, values)])
        ref = np.array(mass_matrix_function(topology)(design_vector(tree))[0])
        np.testing.assert_allclose(np.array(crba(design_vector(tree))), ref, rtol=1e-10, atol=1e-12 * np.abs(ref).max())
