"""The gradient w.r.t. the values a search varies (``norms_gradient_function(..., columns=
search_columns(...))``, what ``footopt bench`` times as "the gradient"): the columns are exactly the
values ``design_from`` changes between two designs, its entries equal the all-values gradient's to
1e-12 and CasADi's reverse mode to 1e-10, and central differences of the lean evaluation on
spatial case 3."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from impulse_core.evaluate import active_contacts, approach_velocity
from impulse_core.impact.delassus import lean_impact_function, norms_gradient_function
from impulse_core.kinematics.spatial import PLANAR, SPATIAL, rods_only
from impulse_core.model.tree import Body, Tree, design_vector
from optimizer.config.model_file import load_model_file
from optimizer.design_space import FootLimits, Leg, design_from, foot_tree, search_columns

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


def test_search_columns_are_what_a_search_changes() -> None:
    """Two splayed designs of one shape (every toe yawed) differ in exactly the searched columns:
    the foot rods' lengths, masses and angles and the toe roots' rpy; in the plane, the same
    without rpy; a tree not of a foot's layout has none."""
    angles = [((-0.7,), (1.1, 0.1), (1.0, -0.2), (1.2, 0.2)), ((-0.5,), (0.9, -0.1), (1.3, 0.25), (1.0, 0.05))]
    masses = [((0.1,), (0.08, 0.04), (0.09, 0.05), (0.07, 0.03)), ((0.12,), (0.06, 0.05), (0.08, 0.02), (0.1, 0.04))]
    for space, yaws in ((SPATIAL, [(-0.3, 0.1, 0.3), (-0.5, 0.2, 0.4)]), (PLANAR, [None, None])):
        trees = [foot_tree(Leg(), design_from(Leg(), a, m, FootLimits(), toe_yaws=y))
                 for a, m, y in zip(angles, masses, yaws, strict=True)]
        p0, p1 = (design_vector(t, space.body_values) for t in trees)
        assert trees[0].n_bodies == 9
        columns = search_columns(trees[0].topology(), space)
        assert np.flatnonzero(p0 != p1).tolist() == list(columns)
        assert len(columns) == (30 if space is SPATIAL else 21)
    model, topology, _ = _case("spatial_case3")
    assert search_columns(topology, model.space) == search_columns(trees[0].topology(), SPATIAL)
    assert search_columns(Tree((Body("base", None, 0.5, 1.0, 0.3, contacts=(1.0,)),)).topology(), PLANAR) is None


@pytest.mark.parametrize("name", ["spatial_case3", "paper_case3"])
def test_searched_gradient_is_the_full_gradients_columns(name: str) -> None:
    """Adjoint, searched: the all-values adjoint's entries to 1e-12 and reverse mode's to 1e-10."""
    model, topology, args = _case(name)
    rods = rods_only(model.tree, model.space)
    columns = list(search_columns(topology, model.space))
    searched = norms_gradient_function(topology, model.space, rods=rods, columns=columns).call(args)
    full = norms_gradient_function(topology, model.space, rods=rods).call(args)
    autodiff = norms_gradient_function(topology, model.space, adjoint=False, rods=rods, columns=columns).call(args)
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
    columns = search_columns(topology, model.space)
    out = norms_gradient_function(topology, model.space, rods=True, columns=columns).call(args)
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


def _three_rod_leg_design(spatial: bool):
    """A footopt design on a three-rod leg (the thigh cut in two welded halves), splayed or planar."""
    from tests.optimizer.test_leg_chains import _split_thigh

    from optimizer.design_space import symmetric_yaws

    chain = _split_thigh(Leg())
    design = design_from(chain, ((-0.6,), (0.9, 0.2), (1.0, 0.1)), ((0.1,), (0.1, 0.05), (0.15, 0.1)), FootLimits(),
                         toe_yaws=symmetric_yaws(2, 0.3) if spatial else None)
    return chain, design


@pytest.mark.parametrize("spatial", [False, True], ids=["planar", "splayed"])
def test_bench_columns_follow_the_files_leg(spatial: bool, tmp_path: Path, capsys, quick_timings) -> None:
    """``footopt bench FILE`` on a design whose leg has three rods: the gradient is taken w.r.t.
    the values a search varies on that leg (the two-rod assumption took the shank for the heel,
    the heel for a toe root and lost the toes' splay), and the output says which; a tree that is
    no footopt design (a foot rod's name missing) is timed w.r.t. every value, and says so."""
    import json

    from impulse_core.model.tree import Scene
    from optimizer.analysis.bench import gradient_columns
    from optimizer.cli.main import main
    from optimizer.config.model_file import dump_model_file
    from optimizer.design_space import design_model

    chain, design = _three_rod_leg_design(spatial)
    model = design_model(chain, design, Scene(), FootLimits())
    tree, space = model.tree, model.space
    topology = tree.topology()
    assert [b.name for b in tree.bodies[:4]] == ["thigh_a", "thigh_b", "shank", "heel"]
    columns, words = gradient_columns(tree, topology, space)
    n = len(space.body_values)
    p = design_vector(tree, space.body_values)
    # what a search changes on this leg: design_from's values, and nothing of the leg's
    other = design_from(chain, ((-0.5,), (0.8, 0.25), (1.1, 0.05)), ((0.12,), (0.08, 0.06), (0.1, 0.08)), FootLimits(),
                        toe_yaws=(-0.5, 0.4) if spatial else None)
    other_tree = design_model(chain, other, Scene(), FootLimits()).tree
    changed = np.flatnonzero(design_vector(other_tree, space.body_values) != p)
    assert columns == changed.tolist()
    assert min(columns) == 3 * n  # the heel, body 3: not the shank (body 2) as on a two-rod leg
    assert len(columns) == (5 * 3 + 2 * 3 if spatial else 5 * 3)  # 5 foot rods' length, mass, angle; 2 toes' rpy
    assert "below a leg of 3 rods (thigh_a, thigh_b, shank)" in words
    assert ("toe roots' rpy" in words) is spatial
    path = tmp_path / "three_rod_leg.yaml"
    dump_model_file(model, path)
    assert main(["bench", str(path), "--batch", "2", "--json", "--no-compile"]) == 0
    record = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert record["n_gradient_values"] == len(columns) and record["gradient_values"] == words
    assert record["gradient_equals_full"] is True
    renamed = Tree(tuple(dataclasses.replace(b, name=b.name.replace("heel", "pad")) for b in tree.bodies))
    every, words = gradient_columns(renamed, topology, space)
    assert every == list(range(len(p))) and words.startswith("every value: not a footopt design")


def test_bench_columns_of_every_example_file() -> None:
    """Every file in configs/ has a two-rod leg: the columns the two-rod rule gave (the paper's
    hand-written feet, named heel, toe, toe_proximal..., too); spatial case 3: 30 of 193."""
    from optimizer.analysis.bench import gradient_columns

    files = [p for p in sorted(CONFIGS.glob("*.yaml")) if "\nmodel:" in p.read_text()]
    assert len(files) == 7  # the model files; the rest are study configs
    for path in files:
        model = load_model_file(path)
        topology = model.tree.topology()
        columns, words = gradient_columns(model.tree, topology, model.space)
        assert columns == list(search_columns(topology, model.space, 2)), path.name
        assert "below a leg of 2 rods (thigh, shank)" in words, path.name
        if path.stem == "spatial_case3":
            assert (len(columns), len(design_vector(model.tree, model.space.body_values))) == (30, 193)
