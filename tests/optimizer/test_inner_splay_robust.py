"""The inner search (IPOPT) over a spatial design space and a distribution of landings (issue
#15): level first impacts whose approach (speed, velocity_x, velocity_z, angular_velocity,
roll_rate) and restitution vary. The NLP's per-scenario impacts are the outer search's
evaluation of each scenario (``footopt evaluate`` on its overridden spatial model file), its
objective statistics at a design are that evaluation's statistics, its gradient is the central
difference of the outer evaluation, and a tiny study runs end to end and re-evaluates."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import casadi as ca
import matplotlib.pyplot as plt
import numpy as np
import optuna
import pytest

from optimizer.cli.main import main
from optimizer.config.study_config import parse_study
from optimizer.design_space import (
    FEASIBILITY_TOL,
    FootShape,
    Objective,
    SplayMode,
    SplaySpace,
    ToeSymmetry,
    design_model,
    foot_support_margin,
)
from optimizer.errors import ConfigError
from optimizer.evaluation.robust import evaluate_over_landings
from optimizer.evaluation.statistics import StatisticKind, parse_statistic
from optimizer.report import plot
from optimizer.search import compiled
from optimizer.search.inner import ShapeNlp, _evaluate, start_point
from optimizer.search.outer import evaluate_design_over_landings, recorded_trials
from tests.optimizer.test_inner_robust import assert_objective_gradient
from tests.optimizer.test_inner_splay import vm_nlp_of

optuna.logging.set_verbosity(optuna.logging.WARNING)

BOUND = 0.02
LANDINGS = {
    "count": 5,
    "seed": 3,
    "speed": {"uniform": [2.5, 4.0]},
    "velocity_x": {"normal": [0.0, 0.3]},
    "angular_velocity": {"uniform": [-1.0, 1.0]},
    "restitution": {"uniform": [0.6, 0.9]},
    "roll_rate": {"uniform": [-1.0, 1.0]},
    "velocity_z": {"normal": [0.0, 0.3]},
}
STUDY = {
    "name": "tiny_splay_inner_robust",
    "seed": 1,
    "scene": {"speed": 3.43, "restitution": 0.8},
    "design_space": {"toes": [2, 2], "toe_segments": [1, 1], "space": "spatial", "splay": [0.0, 0.8]},
    "constraints": {"foot_mass": 0.5, "min_link_mass": 0.02, "support_margin": BOUND},
    "objectives": ["external_norm", "base_angular_velocity"],
    "statistic": {"external_norm": "cvar:0.5", "base_angular_velocity": "mean"},
    "search": {"method": "inner", "inner": {"starts": 2, "front_points": 2}},
    "landings": LANDINGS,
}
NAMES = ("external_norm", "internal_norm", "max_internal", "base_angular_velocity", "energy_after")


def config_of(objectives=("external_norm", "base_angular_velocity"), **statistic: str):
    config = parse_study({**STUDY, "objectives": list(objectives)})
    stats = tuple((Objective(k), parse_statistic(v, k)) for k, v in statistic.items())
    return dataclasses.replace(config, statistic=stats) if stats else config


def per_scenario(config, nlp: ShapeNlp, x: np.ndarray) -> dict[str, np.ndarray]:
    """The NLP's mapped impact at ``x``: ``NAMES`` per scenario (S each), as its rows read them."""
    c = nlp.compiled
    n, n_L = c.n_rods, c.n_lengths
    tree, topology = compiled._splayed_tree_function(config, c.kind)
    p, _ = tree(x[:n], x[n : 2 * n], x[2 * n : 2 * n + n_L], x[2 * n + n_L + 1 : 2 * n + n_L + 1 + c.kind.yaws])
    out = {k: np.array(ca.evalf(v)) for k, v in compiled._splayed_scenario_impacts(config, topology, p).items()}
    return {
        "external_norm": out["external_norm"].ravel(),
        "internal_norm": out["internal_norm"].ravel(),
        "max_internal": out["scaled_magnitude"].max(axis=0),
        "base_angular_velocity": np.linalg.norm(out["omega"], axis=0),
        "energy_after": out["energy_after"].ravel(),
        "external": out["external"],
    }


def newton_starts(config, nlp: ShapeNlp, count: int, seed: int) -> list[np.ndarray]:
    """Level starts whose every scenario is Newton's answer (no contact pulls): the ones the
    NLP's rows keep feasible, and the ones the outer search's ``auto`` scores by Newton's law."""
    rng = np.random.default_rng(seed)
    found = []
    while len(found) < count:
        x = start_point(config, nlp, rng)
        if x is not None and per_scenario(config, nlp, x)["external"].min() > 0:
            found.append(x)
    return found


def aux_values(config, nlp: ShapeNlp, x: np.ndarray) -> np.ndarray:
    """The NLP's auxiliary variables at their optimum for the design of ``x``: per objective (in
    the order the NLP makes them), a per-scenario epigraph u_s = value (max_internal,
    base_angular_velocity), then its statistic's: max's level max u; cvar:q's level t (the
    minimising kink) and excesses max(0, u_s - t)."""
    values = per_scenario(config, nlp, x)
    out: list[float] = []
    for o in config.objectives[:2]:
        u = values[o.value]
        if o in (Objective.MAX_INTERNAL, Objective.BASE_ANGULAR_VELOCITY):
            out += list(u)
        stat = config.statistic_of(o)
        if stat.kind is StatisticKind.MAX:
            out.append(u.max())
        elif stat.kind is StatisticKind.CVAR:
            scale = (1.0 - float(stat.q)) * u.size
            t = min(u, key=lambda t: t + np.maximum(u - t, 0.0).sum() / scale)
            out += [t, *np.maximum(u - t, 0.0)]
    return np.array(out)


def with_aux(config, nlp: ShapeNlp, x: np.ndarray) -> np.ndarray:
    n_design = 2 * nlp.compiled.n_rods + nlp.compiled.n_lengths + 1 + nlp.compiled.kind.yaws
    z = np.concatenate([x[:n_design], aux_values(config, nlp, x)])
    assert z.size == nlp.compiled.n_x
    return z


def aux_rows(nlp: ShapeNlp) -> np.ndarray:
    """The rows the auxiliary variables enter (epigraphs, max's level, cvar's excesses)."""
    c = nlp.compiled
    n_design = 2 * c.n_rods + c.n_lengths + 1 + c.kind.yaws
    pattern = np.array(ca.DM(c.solver.get_function("nlp_jac_g").sparsity_out("jac_g_x"), 1)) != 0
    return np.flatnonzero(pattern[:, n_design:].any(axis=1))


@pytest.mark.parametrize(
    ("space", "shape"),
    [
        ({}, FootShape(2, 1)),
        ({"toe_symmetry": ToeSymmetry.INDEPENDENT, "splay": SplaySpace((-0.5, 0.7), SplayMode.PER_TOE)}, FootShape(3, 2)),
        ({"splay": SplaySpace((0.3, 0.3))}, FootShape(1, 2)),  # one toe, no yaw variable
    ],
)
def test_per_scenario_impacts_are_the_outer_evaluation(space: dict, shape: FootShape):
    """Every first-impact objective per scenario (the approach a 6-vector: lateral velocity and
    roll rate too) against each scenario's spatial model file evaluated by the model ``auto``
    picks: 1e-9; identical toes with a symmetric splay, independent toes each at its own yaw,
    one toe at a fixed yaw."""
    config = config_of()
    config = dataclasses.replace(config, space=dataclasses.replace(config.space, **space))
    nlp = vm_nlp_of(config, shape)
    for x in newton_starts(config, nlp, 3, seed=0):
        ours = per_scenario(config, nlp, x)
        design = _evaluate(config, nlp, *nlp.unpack(x), nlp.toe_yaws(x)).design
        rows = evaluate_over_landings(design_model(config.leg, design, config.scene, config.limits),
                                      config.landings, config.statistic_of).rows
        for key in NAMES:
            theirs = np.array([getattr(r.objectives, key) for r in rows])
            np.testing.assert_allclose(ours[key], theirs, rtol=1e-9, atol=1e-12, err_msg=key)
        assert np.ptp(ours["base_angular_velocity"]) > 0.1  # the scenarios differ


@pytest.mark.parametrize(
    ("objectives", "statistic"),
    [
        (("external_norm", "base_angular_velocity"), {"external_norm": "cvar:0.5", "base_angular_velocity": "max"}),
        (("max_internal", "internal_norm"), {"max_internal": "cvar:0.7", "internal_norm": "std"}),
        (("energy_after", "base_angular_velocity"), {"energy_after": "max", "base_angular_velocity": "mean"}),
    ],
)
def test_objective_statistics_are_the_outer_evaluation(objectives, statistic):
    """At level designs, the NLP's objective (its auxiliary variables at their optimum) and its
    epsilon row are the statistics :func:`evaluate_design_over_landings` gives the same design
    (every scenario by ``footopt evaluate``'s model): 1e-9; the auxiliary rows hold there."""
    config = config_of(objectives, **statistic)
    nlp = vm_nlp_of(config)
    c = nlp.compiled
    f = c.solver.get_function("nlp_f")
    g = c.solver.get_function("nlp_g")
    for x in newton_starts(config, nlp, 2, seed=1):
        z = with_aux(config, nlp, x)
        outer = evaluate_design_over_landings(config, _evaluate(config, nlp, *nlp.unpack(x), nlp.toe_yaws(x)).design)
        f1, f2 = (outer.objectives.value(o) for o in config.objectives)
        assert float(f(z, [1.0, 0.0, 2.0])) == pytest.approx(f1, rel=1e-9, abs=1e-12)
        assert float(f(z, [0.0, 1.0, 2.0])) == pytest.approx(f2, rel=1e-9, abs=1e-12)
        rows = np.array(g(z, [1.0, 0.0, 2.0])).ravel()
        assert rows[0] == pytest.approx(f2, rel=1e-9, abs=1e-12)
        aux = aux_rows(nlp)
        assert aux.size and np.all(rows[aux] >= c.lbg[aux] - 1e-12 * (1 + np.abs(rows[aux])))


def test_gradient_is_the_central_difference_of_the_outer_evaluation():
    """The NLP's exact objective gradient (std of the external norm + 0.7 x mean of the internal
    norm: no auxiliary variables) in every design variable (angles, masses, lengths, ankle
    height, yaw) against central differences of the outer search's statistics of the designs
    those variables make; and the epsilon row's gradient likewise."""
    config = config_of(("external_norm", "internal_norm"), external_norm="std", internal_norm="mean")
    nlp = vm_nlp_of(config)
    c = nlp.compiled
    assert c.n_x == 2 * c.n_rods + c.n_lengths + 1 + c.kind.yaws
    (x,) = newton_starts(config, nlp, 1, seed=4)
    p = [1.0, 0.7, 2.0]

    def outer(z: np.ndarray) -> np.ndarray:
        ev = evaluate_design_over_landings(config, _evaluate(config, nlp, *nlp.unpack(z), nlp.toe_yaws(z)).design)
        return np.array([ev.objectives.external_norm, ev.objectives.internal_norm])

    _, grad_f = c.solver.get_function("nlp_grad_f")(x, p)
    _, jac_g = c.solver.get_function("nlp_jac_g")(x, p)
    exact_f, exact_g = np.array(grad_f).ravel(), np.array(jac_g.full())[0]
    h = 1e-6
    fd = np.zeros((2, c.n_x))
    for k in range(c.n_x):
        e = np.zeros_like(x)
        e[k] = h
        fd[:, k] = (outer(x + e) - outer(x - e)) / (2 * h)
    assert np.abs(fd[:, -1]).max() > 1e-3  # the yaw acts
    np.testing.assert_allclose(exact_f, p[0] * fd[0] + p[1] * fd[1], rtol=1e-5, atol=1e-6 * np.abs(fd).max())
    np.testing.assert_allclose(exact_g, fd[1], rtol=1e-5, atol=1e-6 * np.abs(fd).max())


def test_gradient_with_auxiliary_variables_is_exact():
    """cvar and the spatial epigraph of the base's turn: the NLP's objective gradient against
    central differences of its own objective, in every variable (design and auxiliary)."""
    config = config_of(external_norm="cvar:0.6", base_angular_velocity="cvar:0.5")
    nlp = vm_nlp_of(config)
    c = nlp.compiled
    (x,) = newton_starts(config, nlp, 1, seed=2)
    z = with_aux(config, nlp, x) + np.random.default_rng(3).uniform(0.0, 0.05, c.n_x) * (np.arange(c.n_x) >= 9)
    assert_objective_gradient(c.solver.get_function("nlp_grad_f"), z, [1.0, 0.7, 2.0])


def test_tiny_study_runs_and_its_front_reevaluates(tmp_path: Path, capsys, monkeypatch):
    """``footopt optimize`` on the tiny study (the inner search over 5 landings, on the virtual
    machine: too few solves to compile): every recorded design is feasible, its support margin
    stands, its recorded statistics are the outer evaluation of its design (1e-9), and the
    sweep's anchors are the ends of its front."""
    def unsaved(fig, path: Path, layout: bool = True) -> Path:  # the drawings cost seconds and are not the point
        plt.close(fig)
        Path(path).touch()
        return Path(path)

    monkeypatch.setattr(plot, "_save", unsaved)
    path = tmp_path / "study.yaml"
    path.write_text(json.dumps({**STUDY, "storage": f"sqlite:///{tmp_path / 'study.db'}"}), encoding="utf-8")
    assert main(["optimize", str(path), "--out", str(tmp_path / "run"), "--quiet"]) == 0
    entries = json.loads((tmp_path / "run" / "pareto.json").read_text())["designs"]
    assert entries
    config = parse_study(STUDY)
    study = optuna.load_study(study_name=config.name, storage=f"sqlite:///{tmp_path / 'study.db'}")
    found = list(recorded_trials(study))
    assert len(found) >= 3
    for r in found:
        e = r.evaluation
        assert e.feasible and e.design.spatial
        again = evaluate_design_over_landings(config, e.design)
        for name in ("external_norm", "base_angular_velocity"):
            assert again.objectives.value(Objective(name)) == pytest.approx(e.objectives.value(Objective(name)),
                                                                            rel=1e-9, abs=1e-15)
        assert foot_support_margin(config.leg, e.design) >= BOUND - FEASIBILITY_TOL
    f1 = [r.evaluation.objectives.external_norm for r in found]
    f2 = [r.evaluation.objectives.base_angular_velocity for r in found]
    assert np.argmin(f1) == 0 and np.argmin(f2) == 1  # the anchors: each objective's best
    recorded = {round(v, 12) for v in f1}
    assert {round(e["objectives"]["external_norm"], 12) for e in entries} <= recorded


@pytest.mark.parametrize(
    ("landings", "message"),
    [
        ({"roll": {"uniform": [-0.1, 0.1]}}, r"^landings\.roll: the inner search varies"),
        ({"pitch": {"uniform": [-0.1, 0.1]}}, r"^landings\.pitch: the inner search varies"),
        ({"friction": [0.0, 0.3]}, r"^landings\.friction: the inner search varies"),
    ],
)
def test_what_changes_which_contacts_hit_is_refused(landings, message):
    with pytest.raises(ConfigError, match=message) as info:
        parse_study({**STUDY, "landings": {**LANDINGS, **landings}})
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("space", ["spatial", "planar"])
def test_whole_landings_over_landings_are_taken_in_the_plane_and_in_space(space: str):
    """The inner search over whole landings scores them over landings in the plane
    (tests/optimizer/test_landing_inner_robust.py) and in space, with a lateral velocity and a
    roll rate (tests/optimizer/test_landing_inner_spatial_robust.py); a roll is refused naming it."""
    text = {**STUDY, "objectives": ["peak_external_norm", "peak_internal_norm"], "scene": {"speed": 3.43,
            "restitution": 0.8, "duration": 0.05}, "statistic": {}}
    if space == "planar":
        text["design_space"] = {"toes": [2, 2], "toe_segments": [1, 1]}
        text["constraints"] = {k: v for k, v in text["constraints"].items() if k != "support_margin"}
        text["landings"] = {k: v for k, v in LANDINGS.items() if k not in ("roll_rate", "velocity_z")}
        assert parse_study(text).landings is not None
        return
    assert {"roll_rate", "velocity_z"} <= set(parse_study(text).landings.names)
    with pytest.raises(ConfigError, match=r"^landings\.roll: the inner search over whole landings varies"):
        parse_study({**text, "landings": {**LANDINGS, "roll": {"uniform": [-0.1, 0.1]}}})


def test_the_cli_refuses_a_roll_with_exit_status_2(tmp_path: Path, capsys):
    path = tmp_path / "study.yaml"
    path.write_text(json.dumps({**STUDY, "landings": {**LANDINGS, "roll": {"uniform": [-0.1, 0.1]}}}), encoding="utf-8")
    assert main(["optimize", str(path), "--out", str(tmp_path / "run"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "landings.roll: the inner search varies" in err and len(err.strip().splitlines()) == 1
