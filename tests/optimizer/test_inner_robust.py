"""The inner search over a distribution of landings (issue #14 item 2): the NLP's per-scenario
impacts are the ones ``footopt evaluate`` gives each scenario's file, its statistics
(mean, std, max, and cvar by Rockafellar and Uryasev's reformulation) reach their definitions at
the optimum over their auxiliary variables, its derivatives are exact, and its minima beat a
sample of designs scored by the outer search's evaluation."""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np
import optuna
import pytest

from optimizer.config.model_file import load_yaml
from optimizer.config.study_config import parse_study
from optimizer.design_space import FootDesign, FootShape, Objective, Segment, design_model
from optimizer.errors import ConfigError
from optimizer.evaluation.robust import evaluate_over_landings
from optimizer.evaluation.statistics import parse_statistic
from optimizer.search.compiled import NlpCache, SCENARIO_OUTPUTS, _scenario_function, foot_kind, scenario_approach
from optimizer.search.inner import build_nlp, realise, run_inner, start_point
from optimizer.search.outer import evaluate_design_over_landings, open_study, recorded_trials

optuna.logging.set_verbosity(optuna.logging.WARNING)

STUDY = """\
name: inner_robust
seed: 2
scene: {speed: 3.43, restitution: 0.8}
design_space: {toes: [2, 2], toe_segments: [1, 1]}
constraints: {foot_mass: 0.5, min_link_mass: 0.02}
objectives: [external_norm, internal_norm]
search: {method: inner, inner: {starts: 3, front_points: 2}}
landings:
  count: 9
  seed: 4
  speed: {uniform: [2.5, 4.0]}
  velocity_x: {normal: [0.0, 0.3]}
  angular_velocity: {uniform: [-1.0, 1.0]}
  restitution: {uniform: [0.6, 0.9]}
"""


def config_with(**statistic: str):
    config = parse_study(load_yaml(STUDY))
    stats = tuple((Objective(k), parse_statistic(v, k)) for k, v in statistic.items())
    return dataclasses.replace(config, statistic=stats)


def nlp_of(config, shape=FootShape(2, 1), tmp_path=None):
    return build_nlp(config, shape, NlpCache(config, [], tmp_path))


def design_at(nlp, x) -> FootDesign:
    """The design of an NLP point, with its own angles, masses and lengths."""
    chains = [
        tuple(Segment(L, m, a) for a, m, L in zip(*rods, strict=True))
        for rods in zip(*(nlp.expand(block) for block in nlp.unpack(x)), strict=True)
    ]
    return FootDesign(heel=chains[0], toes=tuple(chains[1:]))


def test_per_scenario_impacts_are_footopt_evaluates(tmp_path):
    """The merged NLP's external and internal norms per scenario (two identical toes as one toe
    of twice the mass, the approach and restitution from the landings) against each scenario's
    model file evaluated by the model ``auto`` picks: 1e-9."""
    config = config_with()
    nlp = nlp_of(config, tmp_path=tmp_path)
    rng = np.random.default_rng(0)
    checked = 0
    while checked < 3:
        x = start_point(config, nlp, rng)
        if x is None:
            continue
        n = nlp.compiled.n_rods
        base, e = scenario_approach(config)
        mapped = _scenario_function(config, foot_kind(config, nlp.shape)).map(base.shape[1])
        out = dict(zip(SCENARIO_OUTPUTS, mapped(x[:n], x[n : 2 * n], x[2 * n : 3 * n], nlp.shape.n_toes, base, e), strict=True))
        design = design_at(nlp, x)
        model = design_model(config.leg, design, config.scene, config.limits)
        rows = evaluate_over_landings(model, config.landings, config.statistic_of).rows
        if any(r.objectives is None for r in rows) or np.min(np.array(out["external"])) < 0:
            continue  # a contact pulls: not the Newton answer the NLP keeps feasible
        for key in ("external_norm", "internal_norm", "energy_after"):
            ours = np.array(out[key]).ravel()
            theirs = np.array([getattr(r.objectives, key) for r in rows])
            np.testing.assert_allclose(ours, theirs, rtol=1e-9, atol=1e-12, err_msg=key)
        checked += 1


@pytest.mark.parametrize("text", ["mean", "std", "max", "cvar:0.5", "cvar:0.9", "cvar:0.0"])
def test_statistics_reach_their_definitions(text, tmp_path):
    """Design variables fixed at a level start: the NLP's minimum over its auxiliary variables
    (max's level, cvar's level and excesses) is the statistic of the per-scenario values, as
    :mod:`optimizer.evaluation.statistics` defines it (1e-7 relative)."""
    config = config_with(external_norm=text, internal_norm="mean")
    nlp = nlp_of(config, tmp_path=tmp_path)
    c = nlp.compiled
    rng = np.random.default_rng(1)
    x = next(x for x in (start_point(config, nlp, rng) for _ in range(20)) if x is not None)
    fixed = 3 * c.n_rods + 1
    lbx, ubx = c.lbx.copy(), c.ubx.copy()
    lbx[:fixed] = ubx[:fixed] = x[:fixed]
    lbg, ubg = np.full_like(c.lbg, -np.inf), np.full_like(c.ubg, np.inf)
    aux = _statistic_rows(config, nlp)
    lbg[aux], ubg[aux] = c.lbg[aux], c.ubg[aux]
    sol = c.solver(x0=x, p=[1.0, 0.0, nlp.shape.n_toes], lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
    n = c.n_rods
    base, e = scenario_approach(config)
    mapped = _scenario_function(config, foot_kind(config, nlp.shape)).map(base.shape[1])
    values = np.array(mapped(x[:n], x[n : 2 * n], x[2 * n : 3 * n], nlp.shape.n_toes, base, e)[3]).ravel()
    expected = config.statistic_of(Objective.EXTERNAL_NORM).of(values)
    assert float(sol["f"]) == pytest.approx(expected, rel=1e-7)


def _statistic_rows(config, nlp) -> np.ndarray:
    """The rows that only the statistic's auxiliary variables enter (max: t >= u_s; cvar:
    z_s >= u_s - t): found as the rows whose Jacobian touches the auxiliary variables."""
    c = nlp.compiled
    fixed = 3 * c.n_rods + 1
    jac = c.solver.get_function("nlp_jac_g")
    pattern = np.array(ca.DM(jac.sparsity_out("jac_g_x"), 1)) != 0
    return np.flatnonzero(pattern[:, fixed:].any(axis=1))

def test_gradient_of_the_statistics_is_exact(tmp_path):
    """The NLP's objective gradient (CasADi's exact derivatives through the mapped impacts and
    the statistics) against central differences at a level start, std and cvar together."""
    config = config_with(external_norm="std", internal_norm="cvar:0.8")
    nlp = nlp_of(config, tmp_path=tmp_path)
    c = nlp.compiled
    rng = np.random.default_rng(3)
    x = next(x for x in (start_point(config, nlp, rng) for _ in range(20)) if x is not None)
    x = x + rng.uniform(0.0, 0.05, x.size) * (np.arange(x.size) >= 3 * c.n_rods + 1)
    assert_objective_gradient(c.solver.get_function("nlp_grad_f"), x, [1.0, 0.7, nlp.shape.n_toes])


def test_inner_minima_beat_a_sample_scored_over_the_landings(tmp_path):
    """The inner search's best cvar:0.9 of the external norm for one shape, against 150 random
    level designs of that shape scored by the outer search's evaluation (every scenario by
    ``footopt evaluate``'s model): none is feasible and better."""
    config = config_with(external_norm="cvar:0.9", internal_norm="mean")
    config = dataclasses.replace(config, space=dataclasses.replace(config.space, toes=(1, 1)))
    study = open_study(config, optuna.storages.InMemoryStorage())
    run_inner(study, config)
    trials = list(recorded_trials(study))
    assert trials
    best = min(t.evaluation.objectives.external_norm for t in trials)
    nlp = nlp_of(config, FootShape(1, 1), tmp_path)
    rng = np.random.default_rng(5)
    sampled = []
    for _ in range(150):
        x = start_point(config, nlp, rng)
        evaluation = realise(config, nlp, x) if x is not None else None
        if evaluation is not None:
            sampled.append(evaluation.objectives.external_norm)
    assert len(sampled) > 50
    assert min(sampled) >= best * (1 - 1e-6)


def test_recorded_values_are_the_statistics_over_the_landings(tmp_path):
    """What the inner search records for a design is the outer evaluation of that design."""
    config = config_with(external_norm="max", internal_norm="cvar:0.75")
    study = open_study(config, optuna.storages.InMemoryStorage())
    run_inner(study, config)
    trials = list(recorded_trials(study))
    assert len(trials) >= 2
    for t in trials:
        again = evaluate_design_over_landings(config, t.evaluation.design).objectives
        assert t.evaluation.objectives.external_norm == pytest.approx(again.external_norm, rel=1e-12)
        assert t.evaluation.objectives.internal_norm == pytest.approx(again.internal_norm, rel=1e-12)


@pytest.mark.parametrize(
    "extra, message",
    [
        ("  pitch: {uniform: [-0.1, 0.1]}\n", "landings.pitch: the inner search varies"),
        ("  terrain_step: [0.0, 0.01]\n", "landings.terrain_step: the inner search varies"),
        ("statistic: {external_norm: 'quantile:0.9'}\n", "statistic.external_norm: the inner search takes mean"),
    ],
)
def test_what_the_inner_search_cannot_differentiate_is_refused(extra, message):
    with pytest.raises(ConfigError) as info:
        parse_study(load_yaml(STUDY + extra))
    assert str(info.value).startswith(message), str(info.value)


def test_the_std_of_a_maximum_is_refused():
    text = STUDY.replace("[external_norm, internal_norm]", "[max_internal, internal_norm]")
    with pytest.raises(ConfigError, match="statistic.max_internal: the inner search cannot take the std"):
        parse_study(load_yaml(text + "statistic: {max_internal: std}\n"))


@pytest.mark.parametrize("landings", [True, False])
def test_an_epigraph_objective_first_keeps_the_epsilon_row_first(landings: bool):
    """With ``max_internal`` first (an epigraph variable and its rows), the epsilon row is still
    row 0: the sweep's points sit at their epsilons, evenly spaced between the anchors in the
    second objective (a regression: the epsilon once bounded an epigraph row instead)."""
    text = STUDY.replace("[external_norm, internal_norm]", "[max_internal, external_norm]")
    if not landings:
        text = text.split("landings:")[0]
    config = parse_study(load_yaml(text))
    study = open_study(config, optuna.storages.InMemoryStorage())
    run_inner(study, config)
    second = np.sort([t.evaluation.objectives.external_norm for t in recorded_trials(study)])
    assert len(second) == 2 + config.search.front_points
    np.testing.assert_allclose(second, np.linspace(second[0], second[-1], second.size), rtol=1e-4)


def assert_objective_gradient(grad: ca.Function, x: np.ndarray, p: list) -> None:
    """An NLP's exact objective gradient (``nlp_grad_f``, the library's own) against central
    differences of its objective in every variable."""
    exact = np.array(grad(x, p)[1]).ravel()
    h = 1e-6
    for i in range(x.size):
        step = np.zeros(x.size)
        step[i] = h
        fd = (float(grad(x + step, p)[0]) - float(grad(x - step, p)[0])) / (2 * h)
        assert exact[i] == pytest.approx(fd, rel=1e-5, abs=1e-8), f"variable {i}"
