"""The inner search (IPOPT) over a spatial design space (splayed toes): a small study runs on
CasADi's virtual machine, its front's model files re-evaluate to the recorded figures through
``footopt evaluate`` (1e-9), every constraint holds (the support margin too), the NLP's exact
gradient is the central difference of the tool's own evaluation, and on a tiny case the inner
search is no worse than the outer one with more time."""

from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path

import casadi as ca
import matplotlib.pyplot as plt
import numpy as np
import optuna
import pytest

from optimizer.cli.main import main
from optimizer.config.study_config import parse_study
from optimizer.report import plot
from optimizer.design_space import (
    FEASIBILITY_TOL,
    FootShape,
    Objective,
    SplayMode,
    SplaySpace,
    ToeSymmetry,
    evaluate_design,
    foot_geometry,
    foot_support_margin,
)
from optimizer.search import compiled
from optimizer.search.compiled import NlpCache, foot_kind, support_edges
from optimizer.search.inner import ShapeNlp, _evaluate, anchors, build_nlp, run_inner, start_point
from optimizer.search.outer import open_study, recorded_trials, run_outer

optuna.logging.set_verbosity(optuna.logging.WARNING)

BOUND = 0.06  # binds on the tiny study (its optimum without it stands at about 0.03 m)
STUDY = {
    "name": "tiny_splay_inner",
    "seed": 1,
    "scene": {"speed": 3.43, "restitution": 0.8},
    "design_space": {"toes": [1, 2], "toe_segments": [1, 1], "space": "spatial", "splay": [0.0, 0.8]},
    "constraints": {"foot_mass": 0.5, "min_link_mass": 0.02, "support_margin": BOUND},
    "objectives": ["external_norm", "internal_norm"],
    "search": {"method": "inner", "inner": {"starts": 2, "front_points": 2}},
}


def config_of(**space):
    config = parse_study(STUDY)
    return dataclasses.replace(config, space=dataclasses.replace(config.space, **space))


def vm_nlp_of(config, shape: FootShape = FootShape(2, 1)) -> ShapeNlp:
    """The shape's NLP on CasADi's virtual machine (no C build: zero planned solves)."""
    kind = foot_kind(config, shape)
    return build_nlp(config, shape, NlpCache(config, [kind], solves={kind: 0}))


@pytest.fixture(scope="module")
def study() -> optuna.Study:
    config = config_of()
    s = open_study(config, optuna.storages.InMemoryStorage())
    run_inner(s, config, workers=1)
    return s


def test_every_design_is_feasible_reevaluates_and_stands(study: optuna.Study):
    config = config_of()
    found = [r.evaluation for r in recorded_trials(study)]
    assert {e.design.shape for e in found} == {FootShape(2, 1)}  # one toe spans no area: refused up front
    assert "support_margin" in study.user_attrs["infeasible:1x1"]
    assert len(found) >= 3
    for e in found:
        assert e.feasible and e.design.spatial
        again = evaluate_design(config.leg, e.design, config.scene, config.limits)
        for name, value in e.objectives.items():
            assert again.objectives.value(Objective(name)) == pytest.approx(value, rel=1e-9, abs=1e-15)
        assert max(v for _, v in again.constraints.items()) <= FEASIBILITY_TOL
        assert foot_support_margin(config.leg, e.design) >= BOUND - FEASIBILITY_TOL
    assert min(foot_support_margin(config.leg, e.design) for e in found) < BOUND + 1e-6  # the margin binds


def test_front_files_reevaluate_through_the_cli(tmp_path: Path, capsys, monkeypatch):
    def unsaved(fig, path: Path, layout: bool = True) -> Path:  # the drawings cost seconds and are not the point
        plt.close(fig)
        Path(path).touch()
        return Path(path)

    monkeypatch.setattr(plot, "_save", unsaved)
    path = tmp_path / "study.yaml"
    path.write_text(json.dumps({**STUDY, "design_space": {**STUDY["design_space"], "toes": [2, 2]}}), encoding="utf-8")
    assert main(["optimize", str(path), "--out", str(tmp_path / "run"), "--quiet"]) == 0
    entries = json.loads((tmp_path / "run" / "pareto.json").read_text())["designs"]
    assert entries
    capsys.readouterr()
    assert main(["evaluate", "--json", *(str(tmp_path / "run" / e["model_file"]) for e in entries)]) == 0
    records = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    for entry, record in zip(entries, records, strict=True):
        for name in ("external_norm", "internal_norm"):
            assert record[name] == pytest.approx(entry["objectives"][name], rel=1e-9)
        assert record["support_margin"] >= BOUND - 1e-9


@pytest.mark.parametrize(
    ("symmetry", "splay"),
    [
        (ToeSymmetry.IDENTICAL, SplaySpace((0.0, 0.8))),
        (ToeSymmetry.INDEPENDENT, SplaySpace((-0.5, 0.7), SplayMode.PER_TOE)),
    ],
)
def test_nlp_gradient_is_the_central_difference_of_the_evaluation(symmetry, splay):
    """Every objective's exact gradient in the NLP's design variables (angles, masses, lengths,
    ankle height, yaws) against central differences of :func:`evaluate_design` on the designs
    those variables make; and the NLP's own objective gradient and epsilon row are those rows."""
    config = config_of(toe_symmetry=symmetry, splay=splay)
    nlp = vm_nlp_of(config, FootShape(2, 1))
    c = nlp.compiled
    assert c.kind.yaws == (1 if splay.mode is SplayMode.SYMMETRIC else 2)
    x = start_point(config, nlp, np.random.default_rng(4))
    n_design = 2 * c.n_rods + c.n_lengths + 1 + c.kind.yaws
    names = ("external_norm", "internal_norm", "max_internal", "base_angular_velocity", "energy_after")

    def evaluated(z: np.ndarray) -> np.ndarray:
        ev = _evaluate(config, nlp, *nlp.unpack(z), nlp.toe_yaws(z))
        return np.array([ev.objectives.value(Objective(k)) for k in names])

    design = ca.SX.sym("design", n_design)
    rows = ca.vertcat(*c.values(design, 2)[:5])
    exact = np.array(ca.Function("gradient", [design], [ca.jacobian(rows, design)])(x[:n_design]))
    np.testing.assert_allclose(np.array(ca.Function("v", [design], [rows])(x[:n_design])).ravel(), evaluated(x),
                               rtol=1e-12)
    h = 1e-6
    fd = np.zeros_like(exact)
    for k in range(n_design):
        e = np.zeros_like(x)
        e[k] = h
        fd[:, k] = (evaluated(x + e) - evaluated(x - e)) / (2 * h)
    assert np.abs(fd[:, -c.kind.yaws:]).max() > 1e-3  # the yaws act
    np.testing.assert_allclose(exact, fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())
    _, grad_f = c.solver.get_function("nlp_grad_f")(x, [1.0, 0.0, 2.0])
    _, jac_g = c.solver.get_function("nlp_jac_g")(x, [1.0, 0.0, 2.0])
    np.testing.assert_allclose(np.array(grad_f).ravel()[:n_design], exact[0], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(np.array(jac_g.full())[0, :n_design], exact[1], rtol=1e-9, atol=1e-12)


def test_inner_is_no_worse_than_a_longer_outer_search():
    """On the tiny study at a support margin of 2 cm (at 6 cm the outer search's 120 trials find
    no feasible foot), each objective's best: the inner search's (about 0.5 s) at most the outer
    search's (120 trials, several times longer)."""
    config = config_of(toes=(2, 2))
    config = dataclasses.replace(config, limits=dataclasses.replace(config.limits, support_margin=0.02))
    t = time.perf_counter()
    inner = open_study(config, optuna.storages.InMemoryStorage())
    run_inner(inner, config, workers=1)
    t_inner = time.perf_counter() - t
    outer_config = dataclasses.replace(config, search=dataclasses.replace(config.search, trials=120, startup_trials=30))
    t = time.perf_counter()
    outer = open_study(outer_config, optuna.storages.InMemoryStorage())
    run_outer(outer, outer_config, 120)
    t_outer = time.perf_counter() - t

    def best(study: optuna.Study) -> np.ndarray:
        found = [r.evaluation.objectives for r in recorded_trials(study) if r.evaluation.feasible]
        return np.array([min(o.external_norm for o in found), min(o.internal_norm for o in found)])

    assert np.all(best(inner) <= best(outer) * (1 + 1e-9)), (best(inner), best(outer), t_inner, t_outer)


@pytest.mark.parametrize("n_toes", [2, 3])
def test_support_rows_are_the_support_margin_of_the_evaluated_design(n_toes: int):
    """The NLP's support polygon (its design vector built from the NLP's variables, the toes'
    yaws as rpy, the edges in its fixed order): the smallest signed edge distance of the centre
    of mass is the support margin of the design :func:`_evaluate` builds (its model file's), on
    random level starts inside the hull (one-rod identical toes: their tips on a circle about the
    ankle, so the fixed order is the hull's and the rows are exact), and of the same sign outside."""
    config = config_of(toes=(n_toes, n_toes))
    nlp = vm_nlp_of(config, FootShape(n_toes, 1))
    kind = nlp.compiled.kind
    rng = np.random.default_rng(7)
    margins = []
    for _ in range(6):
        x = start_point(config, nlp, rng)
        angles, masses, lengths = nlp.unpack(x)
        flat = [np.concatenate([np.array(ch) for ch in block]) for block in (angles, masses, lengths)]
        p, body_masses, topology = compiled._splayed_values(config, kind, *map(ca.DM, flat), nlp.toe_yaws(x))
        cross, squared = (np.array(ca.evalf(v)).ravel() for v in support_edges(kind, topology, p, body_masses))
        design = _evaluate(config, nlp, angles, masses, lengths, nlp.toe_yaws(x)).design
        margins.append(foot_support_margin(config.leg, design))
        edge = np.min(cross / np.sqrt(squared))
        if margins[-1] >= 0:  # inside: the distance to the boundary is the nearest edge line's
            assert edge == pytest.approx(margins[-1], abs=1e-12)
        else:  # outside: some edge line has it on its outer side, no further than the hull
            assert margins[-1] - 1e-12 <= edge < 0
    assert min(margins) < 0 < max(margins)  # inside and outside both seen


def test_each_anchor_is_feasible_as_the_nlp_left_it():
    """The NLP's rows are the evaluation's constraints: each anchor's own point (its lengths and
    yaws, before :func:`realise` could re-choose lengths) evaluates feasible, with the support
    margin and a toe's forward reach (cos(yaw) times its run) at their bounds."""
    config = parse_study({**STUDY, "constraints": {**STUDY["constraints"], "foot_length": [0.1, 0.2]}})
    nlp = vm_nlp_of(config, FootShape(2, 1))
    found = anchors(config, nlp, np.random.default_rng(0))
    assert len(found) == 2
    reaches = []
    for s, _ in found:
        own = _evaluate(config, nlp, *nlp.unpack(s.x), nlp.toe_yaws(s.x))
        assert own.feasible
        assert foot_support_margin(config.leg, own.design) == pytest.approx(BOUND, abs=1e-6)
        reaches.append(foot_geometry(config.leg, own.design).reaches.max())
    assert max(reaches) == pytest.approx(0.2, abs=1e-6)
