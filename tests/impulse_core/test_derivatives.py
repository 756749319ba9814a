"""CasADi's derivatives of the compiled impulse model equal finite differences.

The gradient of ``external_norm`` and ``internal_norm`` with respect to every value of the design
vector ``p`` (lengths, masses, angles, joint positions, centres of mass, gyration radii, contact
fractions), from ``casadi.jacobian`` of a symbolic call of the compiled ``impact`` Function,
against Richardson-extrapolated central differences of the numeric Function; the hot path's
adjoint gradients (``norms_gradient_function``) against both, and against the mass scaling law.
"""

from __future__ import annotations

import functools

import casadi as ca
import numpy as np
import pytest

from impulse_core.evaluate import approach_velocity, compiled_model
from impulse_core.impact.delassus import LeanAlgorithm, norms_gradient_function
from impulse_core.model.tree import BODY_VALUES, JointKind, Tree, design_vector, value_names
from tests.conftest import (
    contact_independence,
    delassus_condition,
    leg_with_heel_and_toe,
    random_tree,
    redraw_values,
    report,
)

RTOL = 1e-6
OUTPUTS = ("external_norm", "internal_norm")


def _random_trees() -> list[tuple[str, Tree]]:
    rng = np.random.default_rng(4242)
    out = []
    for n, p_fixed in ((2, 0.0), (4, 0.3), (6, 0.3), (9, 0.2)):
        structure = random_tree(rng, n, p_fixed=p_fixed, p_contact=0.7)
        for draw in range(40):
            tree = structure if draw == 0 else redraw_values(rng, structure)
            if contact_independence(tree)[0] and delassus_condition(tree) < 1e4:
                out.append((f"random-{n}b", tree))
                break
    return out


CASES = [("leg", leg_with_heel_and_toe()), ("leg-nonuniform", leg_with_heel_and_toe(uniform=False))] + _random_trees()


@functools.lru_cache(maxsize=None)
def _gradient_function(topology, speed: float, restitution: float) -> ca.Function:
    """p -> (external_norm, internal_norm, their gradients), by AD through the compiled Function."""
    impact = compiled_model(topology).impact
    p = ca.MX.sym("p", topology.n_values)
    out = impact(p=p, v_minus=approach_velocity(topology, speed), restitution=restitution)
    values = [out[k] for k in OUTPUTS]
    grads = [ca.jacobian(v, p).T for v in values]
    return ca.Function("gradients", [p], values + grads, ["p"], list(OUTPUTS) + [f"d_{k}" for k in OUTPUTS])


def _finite_differences(f, p: np.ndarray, name: str) -> np.ndarray:
    """Central differences, Richardson-extrapolated (error O(h^4)), step relative to |p_i|."""
    g = np.zeros_like(p)
    for i in range(len(p)):
        h = 1e-4 * max(abs(p[i]), 0.05)

        def central(step):
            up, down = p.copy(), p.copy()
            up[i] += step
            down[i] -= step
            return (float(f(p=up)[name]) - float(f(p=down)[name])) / (2 * step)

        g[i] = (4 * central(h / 2) - central(h)) / 3
    return g


def test_cases_present():
    assert len(CASES) >= 5
    assert any(any(b.joint is JointKind.FIXED for b in t.bodies) for _, t in CASES)


@pytest.mark.parametrize("case_id,tree", CASES, ids=[c[0] for c in CASES])
@pytest.mark.parametrize("name", OUTPUTS)
def test_gradient_equals_finite_differences(case_id, tree, name):
    topology = tree.topology()
    grads = _gradient_function(topology, 3.43, 0.8)
    impact = compiled_model(topology).impact
    p = design_vector(tree)
    v = approach_velocity(topology, 3.43)

    def f(p):
        return impact(p=p, v_minus=v, restitution=0.8)

    g_ad = np.array(grads(p=p)[f"d_{name}"]).ravel()
    g_fd = _finite_differences(f, p, name)
    assert float(grads(p=p)[name]) == pytest.approx(float(f(p)[name]), rel=1e-14)
    scale = np.abs(g_fd).max()
    err = np.abs(g_ad - g_fd)
    worst = int(np.argmax(err / (RTOL * np.abs(g_fd) + 1e-8 * scale)))
    names = value_names(tree)
    significant = np.abs(g_fd) > 1e-6 * scale
    rel = (err[significant] / np.abs(g_fd[significant])).max()
    report("derivatives", f"{case_id} d{name}/dp ({len(p)} values): worst relative error {rel:.1e} on the "
           f"{significant.sum()} non-zero entries; worst |AD - FD| / max|grad| {err.max() / scale:.1e} "
           f"(at {names[worst]})")
    bad = [(names[i], g_ad[i], g_fd[i]) for i in np.flatnonzero(err > RTOL * np.abs(g_fd) + 1e-8 * scale)]
    assert not bad, f"AD and finite differences disagree: {bad[:6]}"


@pytest.mark.parametrize("case_id,tree", CASES, ids=[c[0] for c in CASES])
def test_length_sensitivities_vanish_per_rigid_cluster(case_id, tree):
    """With a purely translational approach impulses do not depend on lengths (test_laws.py,
    scaling): d/dL_i is zero for a rod with no fixed joints, and sum_i L_i d/dL_i over a welded
    cluster is zero. The derivative sees the same zero sensitivities the optimiser will."""
    grads = _gradient_function(tree.topology(), 3.43, 0.8)
    p = design_vector(tree)
    out = grads(p=p)
    n = len(BODY_VALUES)
    lengths = p[0 : n * tree.n_bodies : n]
    root = list(range(tree.n_bodies))
    for i, b in enumerate(tree.bodies):
        if b.parent is not None and b.joint is JointKind.FIXED:
            root[i] = root[b.parent]
    for name in OUTPUTS:
        g = np.array(out[f"d_{name}"]).ravel()
        dL = g[0 : n * tree.n_bodies : n]
        scale = np.abs(g).max()
        for r in set(root):
            cluster = [i for i in range(tree.n_bodies) if root[i] == r]
            assert abs(np.dot(lengths[cluster], dL[cluster])) <= 1e-10 * scale * lengths.max(), (name, cluster)
        # the other values do matter: e.g. masses
        assert np.abs(g[1 : n * tree.n_bodies : n]).max() > 1e-6 * scale


def test_gradient_would_catch_a_wrong_derivative():
    """Control: the comparison rejects a gradient off by 1e-4 relative in one entry."""
    tree = CASES[0][1]
    topology = tree.topology()
    grads = _gradient_function(topology, 3.43, 0.8)
    impact = compiled_model(topology).impact
    p = design_vector(tree)
    v = approach_velocity(topology, 3.43)
    g_ad = np.array(grads(p=p)["d_external_norm"]).ravel()
    g_fd = _finite_differences(lambda p: impact(p=p, v_minus=v, restitution=0.8), p, "external_norm")
    i = int(np.argmax(np.abs(g_fd)))
    g_bad = g_ad.copy()
    g_bad[i] *= 1 + 1e-4
    assert np.abs(g_bad - g_fd)[i] > RTOL * abs(g_fd[i])


@pytest.mark.parametrize("algorithm", [LeanAlgorithm.COMPOSITE, LeanAlgorithm.ARTICULATED])
@pytest.mark.parametrize("case_id,tree", CASES, ids=[c[0] for c in CASES])
def test_adjoint_gradient_equals_autodiff_of_the_full_model(case_id, tree, algorithm):
    """The hot path's adjoint gradients (factorizations not differentiated, tree algorithms)
    equal reverse-mode AD through the full model (dense Jacobians, a different graph), which
    test_gradient_equals_finite_differences checks against finite differences."""
    topology = tree.topology()
    p = design_vector(tree)
    ref = _gradient_function(topology, 3.43, 0.8)(p=p)
    out = norms_gradient_function(topology, algorithm=algorithm)(
        p=p, v_minus=approach_velocity(topology, 3.43), restitution=0.8
    )
    for name in OUTPUTS:
        g, g_ref = np.array(out[f"d_{name}"]).ravel(), np.array(ref[f"d_{name}"]).ravel()
        scale = np.abs(g_ref).max()
        assert float(out[name]) == pytest.approx(float(ref[name]), rel=1e-12)
        report("derivatives", f"{case_id} adjoint ({algorithm.value}) d{name}/dp vs AD of the full model: "
               f"worst |diff| / max|grad| {np.abs(g - g_ref).max() / scale:.1e}")
        np.testing.assert_allclose(g, g_ref, rtol=1e-8, atol=1e-10 * scale, err_msg=name)


@pytest.mark.parametrize("case_id,tree", CASES, ids=[c[0] for c in CASES])
def test_adjoint_gradient_obeys_mass_scaling(case_id, tree):
    """Every mass times k scales every impulse by k (A = J M^-1 J^T scales by 1/k), so by Euler's
    theorem for homogeneous functions sum_b m_b dN/dm_b = N for both norms N."""
    topology = tree.topology()
    p = design_vector(tree)
    out = norms_gradient_function(topology)(p=p, v_minus=approach_velocity(topology, 3.43), restitution=0.8)
    n = len(BODY_VALUES)
    masses = slice(BODY_VALUES.index("mass"), n * tree.n_bodies, n)
    for name in OUTPUTS:
        g = np.array(out[f"d_{name}"]).ravel()
        assert np.dot(p[masses], g[masses]) == pytest.approx(float(out[name]), rel=1e-10), name
