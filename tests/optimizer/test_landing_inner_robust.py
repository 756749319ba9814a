"""The inner search over whole landings scored over ``landings:`` (optimizer.search.landing_inner):
at a level start its NLP's statistics are the outer search's evaluation over the same landings
(each scenario landed at its own step), its per-scenario gradients agree with central differences
along each landing's event sequence, the statistics' gradients follow; a tiny study runs end to
end and its recorded designs re-evaluate to their recorded statistics."""

from __future__ import annotations

import csv
import math

import casadi as ca
import numpy as np
import pytest

from impulse_core.timedomain.landing_derivatives import sequence_signature
from optimizer.config.study_config import ConfigError, load_study
from optimizer.design_space import FootShape, Objective
from optimizer.search.landing_inner import (
    _extra_start,
    _Landed,
    _Objectives,
    build_landing_nlp,
    landing_settings,
    realise_landing,
    set_steps,
    start_landing,
    statistic_objectives,
)
from optimizer.search.outer import evaluate_design_over_landings
from tests.optimizer.test_landing_inner import _tangent, assert_gradient_along
from tests.optimizer.test_landing_study import TINY_LANDING_YAML

LANDINGS = ("landings: {count: 3, seed: 4, speed: {uniform: [1.6, 2.4]}, velocity_x: {uniform: [-0.3, 0.3]}, "
            "angular_velocity: {uniform: [-2.0, 2.0]}, restitution: {uniform: [0.1, 0.5]}, friction: [0.3, 0.6]}\n")


def robust_yaml(statistic: str, method: str = "inner") -> str:
    """The tiny whole-landing study (one toe, 10 ms) over 3 landings, ``statistic`` a mapping."""
    return (TINY_LANDING_YAML.replace("duration: 0.02", "duration: 0.01").replace("toes: [1, 2]", "toes: [1, 1]")
            .replace("method: outer", f"method: {method}") + LANDINGS + f"statistic: {statistic}\n")


def _nlp(tmp_path, statistic: str, duration: float = 0.01):
    path = tmp_path / "robust.yaml"
    path.write_text(robust_yaml(statistic).replace("duration: 0.01", f"duration: {duration}"), encoding="utf-8")
    return build_landing_nlp(load_study(path), FootShape(1, 1))


def _statistics(nlp, x: np.ndarray) -> np.ndarray:
    """The NLP's signed objectives at x, its statistics' extra variables tight (as a solve starts)."""
    landed = _Landed(nlp)
    F = _Objectives(landed, nlp.n_x, landed.n_f)
    xs = ca.MX.sym("x", nlp.n_x)
    f, extra, _ = statistic_objectives(nlp, landed, F(xs))
    fun = ca.Function("f", [xs, *extra], f)
    start = _extra_start(nlp, landed, x)
    args, k = [x], 0
    for e in extra:
        args.append(start[k : k + e.numel()])
        k += e.numel()
    return np.array([float(v) for v in fun(*args)])


def landed_gradient(nlp) -> tuple[np.ndarray, _Landed, np.ndarray]:
    """A start x0 (its scenarios' steps set there), the NLP's landings and their gradient at x0
    (2 objectives x each scenario, finite)."""
    x0 = start_landing(nlp, np.random.default_rng(0))
    assert set_steps(nlp, x0)
    landed = _Landed(nlp)
    G = landed.gradient(x0)
    assert G.shape == (2 * nlp.config.landings.count, nlp.n_x) and np.all(np.isfinite(G))
    return x0, landed, G


def statistic_functions(nlp, landed) -> tuple[ca.Function, ca.Function, _Objectives]:
    """The NLP's statistics as written without extra variables (mean, std) and their Jacobian,
    through the NLP's own graph: (f(x), J(x)), and the landing callback they call (keep it)."""
    F = _Objectives(landed, nlp.n_x, landed.n_f)
    xs = ca.MX.sym("x", nlp.n_x)
    f, extra, _ = statistic_objectives(nlp, landed, F(xs))
    assert not extra  # std and mean: no epigraph
    return ca.Function("f", [xs], [ca.vertcat(*f)]), ca.Function("J", [xs], [ca.jacobian(ca.vertcat(*f), xs)]), F


@pytest.mark.parametrize("statistic", ["{peak_external_norm: max, energy_absorbed: mean}",
                                       "{peak_external_norm: 'cvar:0.5', energy_absorbed: std}"])
def test_the_nlp_statistics_are_the_outer_search_evaluation_over_the_landings(tmp_path, statistic):
    nlp = _nlp(tmp_path, statistic)
    cfg = nlp.config
    x = start_landing(nlp, np.random.default_rng(0))
    assert set_steps(nlp, x) and len(set(nlp.steps)) >= 1 and len(nlp.scenes) == 3
    assert len({(s.speed, s.restitution, s.friction, s.angular_velocity) for s in nlp.scenes}) == 3
    nlp_f = _statistics(nlp, x)
    outer = evaluate_design_over_landings(cfg, nlp.design(x))
    realised = realise_landing(nlp, x)
    assert outer.objectives is not None and realised is not None
    for j, o in enumerate(cfg.objectives[:2]):
        want = o.sign * outer.objectives.value(o)
        assert nlp_f[j] == pytest.approx(want, rel=1e-9, abs=1e-12), (o, nlp_f[j], want)
        assert realised.objectives.value(o) == pytest.approx(outer.objectives.value(o), rel=1e-6)


def test_the_gradients_agree_with_central_differences_per_landing_and_statistic(tmp_path, taped_once):
    """Per scenario (each along its own event sequence, unchanged at +-eps), and the statistics
    mean and std (smooth) through the NLP's graph; the nominal-scene statistic would differ."""
    nlp = _nlp(tmp_path, "{peak_external_norm: std, energy_absorbed: mean}")
    x0, landed, G = landed_gradient(nlp)
    settings = landing_settings(nlp.config)

    def sequences(x):
        t, l, scenes = landed.models(x)
        return [sequence_signature(*taped_once(t, s, l, h, settings)[1:])
                for s, h in zip(scenes, nlp.steps, strict=True)]

    stats, J, _callback = statistic_functions(nlp, landed)  # the callback lives as long as they are called
    dJ = np.asarray(J(x0))
    rng = np.random.default_rng(3)
    for _ in range(2):
        u = _tangent(nlp, x0, rng)
        eps = 1e-6
        assert_gradient_along(nlp, x0, G, u, sequences, eps)
        fd_stat = (np.asarray(stats(x0 + eps * u)).ravel() - np.asarray(stats(x0 - eps * u)).ravel()) / (2 * eps)
        assert np.all(np.abs(fd_stat - dJ @ u) <= 1e-4 * np.maximum(np.abs(dJ @ u), 1e-3)), (fd_stat, dJ @ u)
        # the std's chain rule: d std = sum (v_s - mean) dv_s / (S std)
        v = landed.values(x0)[:3]
        dv = (G @ u)[:3]
        std = np.std(v)
        assert (dJ @ u)[0] == pytest.approx(np.sum((v - v.mean()) * dv) / (3 * std), rel=1e-9)


def test_a_solve_keeps_the_max_epigraph_tight_and_lowers_the_statistic(tmp_path):
    """One IPOPT iteration on a max (3 ms landings): its level stays above every scenario (one
    row each), and the realised statistic (the outer evaluation) goes down."""
    from optimizer.search.landing_inner import solve_landing

    nlp = _nlp(tmp_path, "{peak_external_norm: max, energy_absorbed: mean}", duration=0.003)
    x0 = start_landing(nlp, np.random.default_rng(1))
    s = solve_landing(nlp, (1.0, 0.0), math.inf, x0, {"ipopt.max_iter": 1})
    assert s.x.shape == (nlp.n_x,)
    before = _statistics(nlp, x0)[0]
    assert set_steps(nlp, x0)
    after = float(np.max(_Landed(nlp).values(s.x)[:3]))
    assert after < before


def test_the_inner_search_refuses_what_it_cannot_take_over_whole_landings(tmp_path, capsys):
    """One line naming the field (exit status 2 in the CLI)."""
    from optimizer.cli.main import main

    cases = [
        (robust_yaml("{}").replace("friction: [0.3, 0.6]}", "pitch: {uniform: [-0.1, 0.1]}}"), r"^landings\.pitch: "),
        (robust_yaml("{peak_external_norm: 'quantile:0.9'}"), r"^statistic\.peak_external_norm: "),
        (robust_yaml("{energy_absorbed: max}"), r"^statistic\.energy_absorbed: the inner search cannot maximise"),
    ]
    for text, message in cases:
        path = tmp_path / "s.yaml"
        path.write_text(text, encoding="utf-8")
        with pytest.raises(ConfigError, match=message):
            load_study(path)
        capsys.readouterr()
        assert main(["optimize", str(path), "--out", str(tmp_path / "run"), "--quiet"]) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and message.strip("^").replace("\\", "").split(":")[0] in err


def test_a_tiny_inner_study_over_landings_runs_and_its_designs_re_evaluate(tmp_path, monkeypatch, unsaved_drawings):
    """``footopt optimize`` on the tiny study (3 ms, 2 landings, IPOPT cut to 1 iteration): every
    recorded design, rebuilt from its record, re-evaluates by the outer search's evaluation to its
    statistics."""
    import optimizer.search.landing_inner as landing_inner
    from optimizer.cli.main import main
    from optimizer.results.runs import storage_url
    from optimizer.search.outer import open_study, recorded_trials

    monkeypatch.setitem(landing_inner.LANDING_IPOPT, "ipopt.max_iter", 1)
    text = (robust_yaml("{peak_external_norm: max, energy_absorbed: mean}").replace("duration: 0.01", "duration: 0.003")
            .replace("search: {method: inner, trials: 6, startup_trials: 6, landing_tolerance: 1.0e-2}",
                     "search: {method: inner, inner: {starts: 1, front_points: 0}, landing_tolerance: 1.0e-2}")
            .replace("count: 3", "count: 2"))
    path = tmp_path / "tiny.yaml"
    path.write_text(text, encoding="utf-8")
    out = tmp_path / "run"
    assert main(["optimize", str(path), "--out", str(out), "--quiet"]) == 0
    rows = list(csv.DictReader((out / "pareto.csv").open(encoding="utf-8")))
    assert rows and all(r["method"] == "inner" for r in rows)
    config = load_study(path)
    trials = list(recorded_trials(open_study(config, storage_url(out, config))))
    assert trials and len(trials) == len(rows)
    for t in trials:
        again = evaluate_design_over_landings(config, t.evaluation.design)
        for o in (Objective.PEAK_EXTERNAL_NORM, Objective.ENERGY_ABSORBED):
            assert again.objectives.value(o) == pytest.approx(t.evaluation.objectives.value(o), rel=1e-12)


def test_every_scenario_lands_with_the_studys_landing_settings(tmp_path, monkeypatch):
    """Over landings, the outer search (and so the inner search's NLP, which scores what it
    computes) lands every scenario with the study's settings (``search.landing_tolerance``,
    :func:`study_landing`), as the nominal scene's landing: not ``footopt evaluate``'s defaults,
    which ignored the study's tolerance."""
    from optimizer.design_space import study_landing
    from optimizer.evaluation import robust

    seen = []
    real = robust.evaluate_landing

    def spy(*args, **kwargs):
        seen.append(kwargs.get("whole"))
        return real(*args, **kwargs)

    monkeypatch.setattr(robust, "evaluate_landing", spy)
    path = tmp_path / "robust.yaml"
    path.write_text(robust_yaml("{peak_external_norm: max, energy_absorbed: mean}", "outer")
                    .replace("landing_tolerance: 1.0e-2", "landing_tolerance: 3.0e-4"), encoding="utf-8")
    cfg = load_study(path)
    nlp = build_landing_nlp(cfg, FootShape(1, 1))
    x = start_landing(nlp, np.random.default_rng(0))
    assert evaluate_design_over_landings(cfg, nlp.design(x)).objectives is not None
    assert len(seen) == 3 and all(s == study_landing(3e-4) for s in seen)
    assert landing_settings(cfg) == study_landing(3e-4)
