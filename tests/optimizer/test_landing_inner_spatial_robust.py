"""The inner search over whole landings in a spatial design space scored over ``landings:``
(optimizer.search.landing_inner): each scenario's scene carries its spatial approach in its own
slots ([velocity_x, -speed, velocity_z], [roll_rate, 0, angular_velocity]); at a level start the
NLP's per-scenario values are the spatial landings of the design's model file in each scenario's
scene and its statistics the outer search's evaluation over the same landings; its per-scenario
and statistic gradients agree with central differences along each landing's event sequence; a
tiny study runs end to end and its records re-evaluate; what changes the tree is refused."""

from __future__ import annotations

import csv
import re
from dataclasses import replace

import numpy as np
import pytest

from impulse_core.kinematics.spatial import SPATIAL
from impulse_core.timedomain.landing import landing
from impulse_core.timedomain.landing_derivatives import sequence_signature
from optimizer.config.study_config import ConfigError, load_study
from optimizer.design_space import FootShape, Objective, design_model
from optimizer.search.landing_inner import (
    _Landed,
    build_landing_nlp,
    landing_settings,
    set_steps,
    start_landing,
)
from optimizer.search.outer import evaluate_design_over_landings
from tests.optimizer.test_landing_inner import _tangent, assert_gradient_along
from tests.optimizer.test_landing_inner_robust import _statistics, landed_gradient, statistic_functions
from tests.optimizer.test_landing_inner_spatial import SPATIAL_LANDING_YAML

#: Every parameter the spatial whole-landing inner search varies, each scenario different.
LANDINGS = ("landings: {count: 3, seed: 4, speed: {uniform: [1.6, 2.4]}, velocity_x: {uniform: [-0.3, 0.3]}, "
            "angular_velocity: {uniform: [-2.0, 2.0]}, restitution: {uniform: [0.1, 0.5]}, friction: [0.3, 0.6], "
            "roll_rate: {uniform: [-2.0, 2.0]}, velocity_z: {uniform: [-0.3, 0.3]}}\n")


def spatial_robust_yaml(statistic: str) -> str:
    """The tiny spatial whole-landing study (one toe on its own yaw, 4 ms) over 3 landings."""
    return SPATIAL_LANDING_YAML + LANDINGS + f"statistic: {statistic}\n"


def _nlp(tmp_path, statistic: str, duration: float = 0.004, count: int = 3):
    path = tmp_path / "spatial_robust.yaml"
    path.write_text(spatial_robust_yaml(statistic).replace("duration: 0.004", f"duration: {duration}")
                    .replace("count: 3", f"count: {count}"), encoding="utf-8")
    return build_landing_nlp(load_study(path), FootShape(1, 1))


def _drawn(config) -> dict[str, np.ndarray]:
    return dict(zip(config.landings.names, config.landings.draw().T, strict=True))


@pytest.mark.parametrize("statistic", ["{peak_external_norm: max, energy_absorbed: mean}",
                                       pytest.param("{peak_external_norm: 'cvar:0.5', energy_absorbed: std}",
                                                    marks=pytest.mark.slow)],
                         ids=["max_mean", "cvar_std"])  # cvar, std by default: in the plane (test_landing_inner_robust)
def test_the_spatial_nlp_scores_each_scenario_and_the_outer_search_statistics(tmp_path, statistic, taped_once):
    nlp = _nlp(tmp_path, statistic)
    cfg = nlp.config
    assert nlp.space is SPATIAL and nlp.yaws == ("toe1.yaw",)
    x = start_landing(nlp, np.random.default_rng(0))
    assert set_steps(nlp, x) and len(nlp.scenes) == 3
    d = _drawn(cfg)
    for k, s in enumerate(nlp.scenes):  # the approach in its slots, the draws' own values
        assert (s.velocity_x, -s.speed, s.velocity_z) == (d["velocity_x"][k], -d["speed"][k], d["velocity_z"][k])
        assert (s.angular_velocity_x, s.angular_velocity_y, s.angular_velocity) == (d["roll_rate"][k], 0.0,
                                                                                   d["angular_velocity"][k])
        assert (s.restitution, s.friction) == (d["restitution"][k], d["friction"][k])
    # per scenario: the design's model file landed in space in a scene written from the draws
    model = design_model(cfg.leg, nlp.design(x), cfg.scene, cfg.limits, cfg.space.joint_laws.stop_restitution)
    assert model.space is SPATIAL
    values = _Landed(nlp).values(x).reshape(2, 3)
    for k in range(3):
        scene = replace(model.scene, speed=d["speed"][k], velocity_x=d["velocity_x"][k], velocity_z=d["velocity_z"][k],
                        angular_velocity_x=d["roll_rate"][k], angular_velocity=d["angular_velocity"][k],
                        restitution=d["restitution"][k], friction=d["friction"][k])
        r = landing(model.tree, scene, model.joints, landing_settings(cfg), model.space)
        for j, o in enumerate(cfg.objectives[:2]):
            assert values[j, k] == pytest.approx(o.sign * getattr(r, o.value), rel=1e-9, abs=1e-12), (o, k)
    # the statistics: the outer search's evaluation over the same landings
    nlp_f = _statistics(nlp, x)
    outer = evaluate_design_over_landings(cfg, nlp.design(x))
    assert outer.objectives is not None
    for j, o in enumerate(cfg.objectives[:2]):
        assert nlp_f[j] == pytest.approx(o.sign * outer.objectives.value(o), rel=1e-9, abs=1e-12), o


def test_the_spatial_gradients_agree_with_central_differences_per_landing_and_statistic(tmp_path, taped_once):
    """Per scenario (each along its own spatial event sequence, unchanged at +-eps; a level
    direction and the toe's yaw alone), and the statistics mean and std through the NLP's graph
    (2 landings of 3 ms, each its own approach in space)."""
    nlp = _nlp(tmp_path, "{peak_external_norm: std, energy_absorbed: mean}", duration=0.003, count=2)
    x0, landed, G = landed_gradient(nlp)
    S = len(nlp.scenes)
    assert S == 2 and len({(s.speed, s.velocity_x, s.velocity_z, s.angular_velocity_x) for s in nlp.scenes}) == 2
    assert np.max(np.abs(G[:, -1])) > 1e-3 * np.max(np.abs(G))  # the yaw matters
    settings = landing_settings(nlp.config)

    def sequences(x):
        t, l, scenes = landed.models(x)
        return [sequence_signature(*taped_once(t, s, l, h, settings, SPATIAL)[1:])
                for s, h in zip(scenes, nlp.steps, strict=True)]

    stats, J, _callback = statistic_functions(nlp, landed)  # the callback lives as long as they are called
    dJ = np.asarray(J(x0))
    yaw = np.zeros(nlp.n_x)
    yaw[-1] = 1.0
    v, eps = landed.values(x0).reshape(2, S), 1e-6
    for u in (_tangent(nlp, x0, np.random.default_rng(3)), yaw):
        assert_gradient_along(nlp, x0, G, u, sequences, eps)
        fd_stat = (np.asarray(stats(x0 + eps * u)).ravel() - np.asarray(stats(x0 - eps * u)).ravel()) / (2 * eps)
        assert np.all(np.abs(fd_stat - dJ @ u) <= 1e-4 * np.maximum(np.abs(dJ @ u), 1e-3)), (fd_stat, dJ @ u)
        dv = (G @ u).reshape(2, S)  # std over the scenarios of objective 0, mean of objective 1's
        assert (dJ @ u)[0] == pytest.approx(np.sum((v[0] - v[0].mean()) * dv[0]) / (S * np.std(v[0])), rel=1e-9)
        assert (dJ @ u)[1] == pytest.approx(dv[1].mean(), rel=1e-9)


def test_a_tiny_spatial_inner_study_over_landings_runs_and_its_designs_re_evaluate(tmp_path, monkeypatch,
                                                                                   unsaved_drawings):
    """``footopt optimize`` (3 ms, 2 landings, IPOPT cut to 1 iteration; the foot's joint laws
    not searched, fewer variables to carry: searched laws in space are the gradient test's): every
    recorded design, rebuilt from its record, re-evaluates by the outer search's evaluation to its
    statistics; its yaw in range."""
    import optimizer.search.landing_inner as landing_inner
    from optimizer.cli.main import main
    from optimizer.results.runs import storage_url
    from optimizer.search.outer import open_study, recorded_trials

    monkeypatch.setitem(landing_inner.LANDING_IPOPT, "ipopt.max_iter", 1)
    text = spatial_robust_yaml("{peak_external_norm: max}").replace("duration: 0.004", "duration: 0.003").replace(
        "[peak_external_norm, energy_absorbed]", "[peak_external_norm]").replace("count: 3", "count: 2")
    text = re.sub(r"  joint_laws:\n(    .*\n)+", "", text)
    assert "joint_laws" not in text and "splay: [0.1, 0.4]" in text
    path = tmp_path / "tiny.yaml"
    path.write_text(text, encoding="utf-8")
    out = tmp_path / "run"
    assert main(["optimize", str(path), "--out", str(out), "--quiet"]) == 0
    rows = list(csv.DictReader((out / "pareto.csv").open(encoding="utf-8")))
    assert rows and all(r["method"] == "inner" and 0.1 <= float(r["toe1.yaw"]) <= 0.4 for r in rows)
    config = load_study(path)
    trials = list(recorded_trials(open_study(config, storage_url(out, config))))
    assert trials and len(trials) == len(rows)
    for t in trials:
        again = evaluate_design_over_landings(config, t.evaluation.design)
        value = again.objectives.value(Objective.PEAK_EXTERNAL_NORM)
        assert value == pytest.approx(t.evaluation.objectives.value(Objective.PEAK_EXTERNAL_NORM), rel=1e-9)


def test_the_support_margin_rows_over_landings_are_the_nominal_ones(tmp_path):
    """Two toes per toe with a support margin: over landings the NLP keeps the same rows and bounds
    (the margin is the touchdown's geometry, the same in every scenario)."""
    from tests.optimizer.test_landing_inner_spatial import MARGIN_STUDIES

    text, shape = MARGIN_STUDIES["per_toe"]
    (tmp_path / "a.yaml").write_text(text, encoding="utf-8")
    (tmp_path / "b.yaml").write_text(text + LANDINGS, encoding="utf-8")
    nominal, robust = (build_landing_nlp(load_study(tmp_path / f), shape) for f in ("a.yaml", "b.yaml"))
    assert robust.config.landings is not None and robust.config.limits.support_margin == 0.01
    assert np.array_equal(robust.lbg, nominal.lbg) and np.array_equal(robust.ubg, nominal.ubg)
    x = start_landing(robust, np.random.default_rng(5))
    assert np.array_equal(np.asarray(robust.geometric(x)), np.asarray(nominal.geometric(x)))


@pytest.mark.parametrize("name, distribution", [("roll", "{uniform: [-0.1, 0.1]}"), ("pitch", "{uniform: [-0.1, 0.1]}"),
                                                ("terrain_step", "[0.0, 0.01]")], ids=["roll", "pitch", "step"])
def test_what_changes_the_tree_or_the_ground_is_refused_naming_the_field(tmp_path, capsys, name, distribution):
    """One line naming ``landings.<name>``, exit status 2 in the CLI."""
    from optimizer.cli.main import main

    text = spatial_robust_yaml("{}").replace("velocity_z: {uniform: [-0.3, 0.3]}}",
                                             f"velocity_z: {{uniform: [-0.3, 0.3]}}, {name}: {distribution}}}")
    path = tmp_path / "s.yaml"
    path.write_text(text, encoding="utf-8")
    message = (rf"^landings\.{name}: the inner search over whole landings varies speed, velocity_x, angular_velocity, "
               r"restitution, velocity_z, roll_rate, friction only")
    with pytest.raises(ConfigError, match=message):
        load_study(path)
    capsys.readouterr()
    assert main(["optimize", str(path), "--out", str(tmp_path / "run"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and f"landings.{name}: the inner search over whole landings" in err
