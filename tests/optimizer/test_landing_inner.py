"""The inner search's landing NLP (optimizer.search.landing_inner): its objective gradient, the
exact landing gradient chained to the NLP's variables, agrees with central differences along
directions that keep the tips level (where the lowest-contact touchdown height has no kink) with
the event sequence unchanged; a few IPOPT iterations lower the objective as the numeric landing
measures it, within the bounds."""

from __future__ import annotations

import math

import numpy as np
import pytest

from impulse_core.timedomain.landing import landing
from impulse_core.timedomain.landing_derivatives import sequence_signature, taped_run
from optimizer.config.study_config import load_study
from optimizer.design_space import FootShape
from optimizer.search.landing_inner import _Landed, build_landing_nlp, solve_landing, start_landing
from tests.optimizer.test_landing_study import TINY_LANDING_YAML


def _tiny_nlp(folder, leg: str | None = None):
    text = TINY_LANDING_YAML.replace("duration: 0.02", "duration: 0.01")
    if leg is not None:
        text = text.replace("leg: {shank: {stiffness: 150.0, damping: 3.0, limits: [-2.0, 0.0]}}", leg)
    (folder / "tiny.yaml").write_text(text, encoding="utf-8")
    return build_landing_nlp(load_study(folder / "tiny.yaml"), FootShape(1, 1))


@pytest.fixture(scope="module")
def nlp(tmp_path_factory):
    return _tiny_nlp(tmp_path_factory.mktemp("landing_inner"))


@pytest.fixture(scope="module")
def offset_nlp(tmp_path_factory):
    """The tiny NLP on a leg whose thigh's and shank's centres of mass are off the rods."""
    leg = ("leg: {thigh: {com_offset: [0.03, 0]}, shank: {stiffness: 150.0, damping: 3.0, limits: [-2.0, 0.0], "
           "com_offset: [-0.02, 0]}}")
    return _tiny_nlp(tmp_path_factory.mktemp("landing_inner_offsets"), leg)


def _tangent(nlp, x: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A random direction in the null space of the NLP's equality rows (level tips) at x."""
    import casadi as ca

    xs = ca.MX.sym("x", nlp.n_x)
    J = np.asarray(ca.Function("J", [xs], [ca.jacobian(nlp.geometric(xs), xs)])(x))
    eq = nlp.lbg[1:] == nlp.ubg[1:]
    _, _, vt = np.linalg.svd(J[eq])
    basis = vt[int(eq.sum()):].T
    return basis @ rng.standard_normal(basis.shape[1])


@pytest.mark.parametrize("which", ["nlp", "offset_nlp"])
def test_the_nlp_gradient_agrees_with_central_differences_along_level_directions(which, request):
    nlp = request.getfixturevalue(which)
    x0 = start_landing(nlp, np.random.default_rng(0))
    landed = _Landed(nlp)
    tree, laws, scene = landed.model(x0)
    nlp.step = landing(tree, scene, laws).step
    G = landed.gradient(x0)
    assert np.all(np.isfinite(G)) and np.any(G[:, len(x0) - len(nlp.laws):])  # the law values have theirs

    def sequence(x):
        t, l, s = landed.model(x)
        _, tape, run = taped_run(t, s, l, nlp.step)
        return sequence_signature(tape, run)

    rng = np.random.default_rng(3)
    for _ in range(2):
        assert_gradient_along(nlp, x0, G, _tangent(nlp, x0, rng), sequence)


def assert_gradient_along(nlp, x0: np.ndarray, G: np.ndarray, u: np.ndarray, sequence, eps: float = 1e-6) -> None:
    """The landed values' exact gradient ``G`` along ``u`` against central differences of fresh
    landings, the event sequence(s) the same at x0 +- eps u (``sequence``: x -> its signature)."""
    seq0 = sequence(x0)
    assert sequence(x0 + eps * u) == seq0 and sequence(x0 - eps * u) == seq0
    fd = (_Landed(nlp).values(x0 + eps * u) - _Landed(nlp).values(x0 - eps * u)) / (2 * eps)
    assert np.all(np.abs(fd - G @ u) <= 1e-4 * np.maximum(np.abs(G @ u), 1e-3)), (fd, G @ u)


def test_a_few_ipopt_iterations_lower_the_landing_objective(nlp):
    x0 = start_landing(nlp, np.random.default_rng(1))
    s = solve_landing(nlp, (1.0, 0.0), math.inf, x0, {"ipopt.max_iter": 2})
    f0 = _Landed(nlp).values(x0)[0]
    f1 = _Landed(nlp).values(s.x)[0]
    assert f1 < f0  # as the numeric landing at the solve's step measures it
    assert np.all(s.x >= nlp.lbx) and np.all(s.x <= nlp.ubx)  # (its rows converge with more iterations)
    assert nlp.gradients >= 2  # the gradient was derived afresh at the iterates


def test_an_inner_whole_landing_study_runs_and_records_its_designs(tmp_path, monkeypatch, unsaved_drawings):
    """A tiny inner whole-landing study (3 ms, IPOPT cut to 1 iteration per solve: the realised
    designs are evaluated and checked by the study's own landing, whatever IPOPT's status)."""
    import csv

    import optimizer.search.landing_inner as landing_inner
    from optimizer.cli.main import main

    monkeypatch.setitem(landing_inner.LANDING_IPOPT, "ipopt.max_iter", 1)
    study = (TINY_LANDING_YAML.replace("duration: 0.02", "duration: 0.003").replace("toes: [1, 2]", "toes: [1, 1]")
             .replace("search: {method: outer, trials: 6, startup_trials: 6, landing_tolerance: 1.0e-2}",
                      "search: {method: inner, inner: {starts: 1, front_points: 0}, landing_tolerance: 1.0e-2}"))
    path = tmp_path / "tiny_inner_landing.yaml"
    path.write_text(study, encoding="utf-8")
    assert main(["optimize", str(path), "--out", str(tmp_path / "run"), "--quiet"]) == 0
    rows = list(csv.DictReader((tmp_path / "run" / "pareto.csv").open()))
    assert rows and all(r["method"] == "inner" for r in rows)
    assert all(0 < float(r["energy_absorbed"]) <= 1 and float(r["peak_external_norm"]) > 0 for r in rows)


@pytest.mark.parametrize("objectives, message", [
    ("[settled_at, peak_external_norm]", "settled_at has no derivative"),
    ("[peak_external_norm, external_norm]", "landing objectives only"),
])
def test_the_inner_search_refuses_what_it_cannot_differentiate(tmp_path, objectives, message):
    from optimizer.config.study_config import ConfigError

    study = (TINY_LANDING_YAML.replace("objectives: [peak_external_norm, energy_absorbed]", f"objectives: {objectives}")
             .replace("method: outer", "method: inner"))
    path = tmp_path / "s.yaml"
    path.write_text(study, encoding="utf-8")
    with pytest.raises(ConfigError, match=message):
        load_study(path)
