"""The gradient w.r.t. the values the search varies (``norms_gradient_function(..., searched=True)``,
what ``footopt bench`` times as "the gradient"): its columns are every value a search changes
(``design_from`` of two designs), its entries equal the all-values gradient's to 1e-12 and CasADi's
reverse mode to 1e-10, and central differences of the lean evaluation on spatial case 3."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from impulse_core.evaluate import active_contacts, approach_velocity
from impulse_core.impact.delassus import lean_impact_function, norms_gradient_function
from impulse_core.kinematics.spatial import PLANAR, SPATIAL, rods_only, search_columns
from impulse_core.model.tree import design_vector
from optimizer.config.model_file import load_model_file
from optimizer.design_space import FootLimits, Leg, design_from, foot_tree

CONFIGS = Path(__file__).resolve().parents[2] / "configs"


def _case(name: str):
    model = load_model_file(CONFIGS / f"{name}.yaml")
    topology = model.tree.topology(active_contacts(model.tree, model.scene, space=model.space))
    args = {
        "p": design_vector(model.tree, model.space.body_values),
        "v_minus": approach_velocity(topology, model.scene.speed, model.space),
        "restitution": model.scene.restitution,
    }
    return model, topology, args


def test_search_columns_cover_every_value_a_search_changes() -> None:
    """Two splayed designs of one shape differ only in the searched columns (and differ in
    lengths, masses, angles and rpy); a planar space's columns are length, mass, angle."""
    angles = [((-0.7,), (1.1, 0.1), (1.0, -0.2), (1.2, 0.2)), ((-0.5,), (0.9, -0.1), (1.3, 0.25), (1.0, 0.0))]
    masses = [((0.1,), (0.08, 0.04), (0.09, 0.05), (0.07, 0.03)), ((0.12,), (0.06, 0.05), (0.08, 0.02), (0.1, 0.04))]
    yaws = [(-0.3, 0.0, 0.3), (-0.5, 0.1, 0.4)]
    trees = [foot_tree(Leg(), design_from(Leg(), a, m, FootLimits(), toe_yaws=y)) for a, m, y in zip(angles, masses, yaws)]
    p0, p1 = (design_vector(t, SPATIAL.body_values) for t in trees)
    changed = set(np.flatnonzero(p0 != p1).tolist())
    columns = set(search_columns(trees[0].topology(), SPATIAL))
    assert changed <= columns
    n = len(SPATIAL.body_values)
    names = {SPATIAL.body_values[k % n] for k in changed}
    assert names == {"length", "mass", "angle", "roll", "pitch", "yaw"}
    planar = search_columns(trees[0].topology(), PLANAR)
    assert [PLANAR.body_values[k % len(PLANAR.body_values)] for k in planar[:3]] == ["length", "mass", "angle"]


@pytest.mark.parametrize("name", ["spatial_case3", "paper_case3"])
def test_searched_gradient_is_the_full_gradients_columns(name: str) -> None:
    """Adjoint, searched: the all-values adjoint's entries to 1e-12 and reverse mode's to 1e-10."""
    model, topology, args = _case(name)
    rods = rods_only(model.tree, model.space)
    columns = list(search_columns(topology, model.space))
    searched = norms_gradient_function(topology, model.space, rods=rods, searched=True).call(args)
    full = norms_gradient_function(topology, model.space, rods=rods).call(args)
    autodiff = norms_gradient_function(topology, model.space, adjoint=False, rods=rods, searched=True).call(args)
    for key in ("d_external_norm", "d_internal_norm"):
        got = np.array(searched[key]).ravel()
        ref = np.array(full[key]).ravel()
        assert got.shape == (len(columns),) and np.abs(got).max() > 0
        np.testing.assert_allclose(got, ref[columns], rtol=0, atol=1e-12 * np.abs(ref).max(), err_msg=key)
        np.testing.assert_allclose(got, np.array(autodiff[key]).ravel(), rtol=0, atol=1e-10 * np.abs(ref).max(),
                                   err_msg=key)
    for key in ("external_norm", "internal_norm"):
        assert float(searched[key]) == float(full[key])


def test_searched_gradient_matches_central_differences_on_spatial_case3() -> None:
    """The bench's spatial model: every searched entry against central differences of the lean
    function (step 1e-6, relative 1e-6 of the largest entry)."""
    model, topology, args = _case("spatial_case3")
    lean = lean_impact_function(topology, model.space)
    out = norms_gradient_function(topology, model.space, rods=True, searched=True).call(args)
    columns = search_columns(topology, model.space)
    h = 1e-6
    for key in ("external_norm", "internal_norm"):
        grad = np.array(out[f"d_{key}"]).ravel()
        fd = np.empty(len(columns))
        for n, k in enumerate(columns):
            up, down = args["p"].copy(), args["p"].copy()
            up[k] += h
            down[k] -= h
            fd[n] = (float(lean.call({**args, "p": up})[key]) - float(lean.call({**args, "p": down})[key])) / (2 * h)
        np.testing.assert_allclose(grad, fd, rtol=0, atol=1e-6 * np.abs(fd).max(), err_msg=key)
