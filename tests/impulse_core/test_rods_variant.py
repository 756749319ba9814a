"""The hot path's rods variant (``rods=True``: every body's mass-property values folded to 0, for
models whose bodies are all rods): the same outputs as the general functions, bit for bit for the
evaluation and to 1e-13 for both gradients (adjoint and reverse mode), every gradient entry kept
(the mass-property ones against central differences of the general function); a model with any
offset or tensor is not served by it, and its batch evaluator refuses rows that carry one."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from impulse_core.compile.batch import batch_evaluator
from impulse_core.errors import ModelError
from impulse_core.evaluate import pre_impact_velocity
from impulse_core.impact.delassus import lean_impact_function, norms_gradient_function
from impulse_core.kinematics.spatial import SPATIAL, mass_columns, rods_only
from impulse_core.model.tree import SPATIAL_BODY_VALUES, Tree, design_vector
from tests.impulse_core.test_spatial import SCENE, _delassus, spatial_trees


def _inputs(tree: Tree) -> dict:
    topology = tree.topology()
    return {"p": design_vector(tree, SPATIAL_BODY_VALUES), "v_minus": pre_impact_velocity(topology, SCENE, SPATIAL),
            "restitution": SCENE.restitution}


def _well_posed() -> Tree:
    return next(t for t in spatial_trees() if len(t.contacts) >= 2 and t.n_bodies >= 3
                and np.linalg.cond(_delassus(t, SCENE)) < 1e5)


@pytest.mark.parametrize("adjoint", [True, False])
def test_the_rods_variant_gives_the_general_outputs(adjoint: bool) -> None:
    """Rod trees: the lean outputs equal bit for bit, both gradients to 1e-13, fewer instructions."""
    for tree in spatial_trees()[:6]:
        topology, args = tree.topology(), _inputs(tree)
        assert rods_only(tree, SPATIAL)
        general, rods = (lean_impact_function(topology, SPATIAL, rods=r) for r in (False, True))
        assert rods.n_instructions() < general.n_instructions()
        for k, out in general.call(args).items():
            np.testing.assert_array_equal(np.array(rods.call(args)[k]), np.array(out), err_msg=k)
        general, rods = (norms_gradient_function(topology, SPATIAL, adjoint=adjoint, rods=r) for r in (False, True))
        for k, out in general.call(args).items():
            ref = np.array(out, dtype=float)
            np.testing.assert_allclose(np.array(rods.call(args)[k]), ref, rtol=0,
                                       atol=1e-13 * max(1.0, np.abs(ref).max()), err_msg=k)


def test_the_rods_gradient_keeps_the_mass_property_entries() -> None:
    """d norm / d (com_y, com_z, tensor) of the rods variant: central differences of the general
    function about the rod (these entries are not zero)."""
    tree = _well_posed()
    args = _inputs(tree)
    p0 = args["p"]
    general = norms_gradient_function(tree.topology(), SPATIAL)
    out = norms_gradient_function(tree.topology(), SPATIAL, rods=True).call(args)
    columns = list(mass_columns(tree.topology(), SPATIAL))
    for key in ("external_norm", "internal_norm"):
        grad = np.array(out[f"d_{key}"]).ravel()
        fd = np.zeros(len(columns))
        for n, k in enumerate(columns):
            h = 1e-6
            up, down = p0.copy(), p0.copy()
            up[k] += h
            down[k] -= h
            fd[n] = (float(general.call({**args, "p": up})[key]) - float(general.call({**args, "p": down})[key])) / (2 * h)
        assert np.abs(grad[columns] - fd).max() <= 1e-6 * np.abs(grad).max(), key
        assert np.abs(grad[columns]).max() > 1e-3 * np.abs(grad).max(), key


@pytest.mark.parametrize(("change", "name"), [({"com_offset": (0.0, 0.01)}, "com_z"),
                                            ({"tensor": (1e-5, 1e-5, 1e-5, 0.0, 0.0, 0.0)}, "ixx")])
def test_a_body_with_mass_properties_is_not_served_by_the_rods_variant(change: dict, name: str) -> None:
    """One offset or one tensor entry anywhere: not rods only; the rods evaluator refuses the row."""
    tree = spatial_trees()[0]
    bodies = list(tree.bodies)
    bodies[-1] = dataclasses.replace(bodies[-1], **change)
    general = Tree(tuple(bodies))
    assert rods_only(tree, SPATIAL) and not rods_only(general, SPATIAL)
    evaluator = batch_evaluator(tree.topology(), None, space=SPATIAL, rods=True)
    evaluator(design_vector(tree, SPATIAL_BODY_VALUES), speed=1.0, restitution=0.5)
    with pytest.raises(ModelError, match=rf"body {tree.n_bodies - 1} {name} must be .* \[0, 0\]"):
        evaluator(design_vector(general, SPATIAL_BODY_VALUES), speed=1.0, restitution=0.5)


def test_the_compiled_rods_evaluator_refuses_mass_properties(tmp_path) -> None:
    """The compiled API driver checks the same [0, 0] bounds (a three-body tree, compiled)."""
    tree = next(t for t in spatial_trees() if t.n_bodies <= 3 and t.contacts)
    evaluator = batch_evaluator(tree.topology(), tmp_path, space=SPATIAL, rods=True)
    P = np.repeat(design_vector(tree, SPATIAL_BODY_VALUES)[None, :], 5, axis=0)
    evaluator(P, speed=1.0, restitution=0.5)
    P[3, mass_columns(tree.topology(), SPATIAL)[-1]] = 1e-6
    with pytest.raises(ModelError, match=r"p\[3\]: body .* iyz must be .* \[0, 0\]"):
        evaluator(P, speed=1.0, restitution=0.5)
