"""Robust studies: statistics against their definitions, the landings block validated, common
random numbers, and scenarios.csv rows that ``footopt evaluate`` reproduces exactly."""

from __future__ import annotations

import csv
import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from impulse_core.model.tree import ContactSelection
from optimizer.cli.main import main

from optimizer.config.model_file import load_model_file, load_yaml
from optimizer.config.study_config import load_study, parse_study
from optimizer.design_space import FootLimits, Leg, Objective, design_from, design_model
from optimizer.errors import ConfigError
from optimizer.evaluation.scenarios import Landings, apply_overrides, overrides
from optimizer.evaluation.statistics import Statistic, StatisticKind, cvar, parse_statistic

ROBUST_YAML = """\
name: robust_tiny
seed: 3
design_space: {toes: [1, 2], toe_segments: [1, 2]}
constraints: {min_link_mass: 0.02}
objectives: [external_norm, internal_norm]
search: {method: outer, trials: 8, startup_trials: 8}
landings:
  count: 7
  seed: 5
  speed: {uniform: [2.5, 4.0]}
  velocity_x: {normal: [0.0, 0.3]}
  pitch: {uniform: [-0.1, 0.1]}
  angular_velocity: [-0.5, 0.0, 0.5]
  restitution: {uniform: [0.5, 0.9]}
  terrain_step: {uniform: [0.0, 0.01]}
statistic: {external_norm: "cvar:0.8", internal_norm: "quantile:0.5", energy_after: std}
"""


@pytest.mark.parametrize("seed", range(5))
def test_statistics_follow_their_definitions(seed):
    rng = np.random.default_rng(seed)
    x = rng.lognormal(size=int(rng.integers(3, 40)))
    assert Statistic(StatisticKind.MEAN).of(x) == pytest.approx(x.sum() / x.size, rel=1e-14)
    assert Statistic(StatisticKind.STD).of(x) == pytest.approx(np.sqrt(((x - x.mean()) ** 2).mean()), rel=1e-12)
    assert Statistic(StatisticKind.MAX).of(x) == x.max()
    for q in (0.0, 0.3, 0.75, 0.9):
        assert Statistic(StatisticKind.QUANTILE, q).of(x) == pytest.approx(np.quantile(x, q), rel=1e-14)
        t = np.linspace(x.min() - 1, x.max() + 1, 200001)  # Rockafellar-Uryasev by brute force over t
        brute = np.min(t + np.maximum(0.0, x[None, :] - t[:, None]).sum(axis=1) / ((1 - q) * x.size))
        assert cvar(x, q) == pytest.approx(brute, abs=1e-4 * (x.max() - x.min()))
        assert cvar(x, q) <= brute + 1e-12  # the exact minimum is never above a sampled one


def test_cvar_counts_the_boundary_scenario_fractionally():
    """n = 4, q = 0.6: the worst 1.6 scenarios: the worst whole and 0.6 of the next."""
    x = np.array([1.0, 2.0, 3.0, 10.0])
    assert cvar(x, 0.6) == pytest.approx((10.0 + 0.6 * 3.0) / 1.6, rel=1e-14)
    assert cvar(x, 0.0) == pytest.approx(x.mean(), rel=1e-14)


@pytest.mark.parametrize(
    "text, message",
    [
        ("median", "statistic.external_norm: must be one of mean, std, max, quantile:q or cvar:q"),
        ("cvar", "statistic.external_norm: cvar needs a level"),
        ("cvar:1", "statistic.external_norm: the level of cvar must be in [0, 1)"),
        ("mean:0.3", "statistic.external_norm: mean takes no level"),
    ],
)
def test_bad_statistics_name_their_path(text, message):
    with pytest.raises(ConfigError, match=message.replace("[", r"\[").replace("(", r"\(").replace(")", r"\)")):
        parse_statistic(text, "statistic.external_norm")


@pytest.mark.parametrize(
    "extra, message",
    [
        ("landings: {speed: {normal: [1.0, 2.0]}}", "landings.speed: draws"),
        ("landings: {restitution: {uniform: [0.5, 1.5]}}", "landings.restitution: draws"),
        ("landings: {speed: {uniform: [3, 2]}}", "landings.speed.uniform: lo 3.0 is above hi 2.0"),
        ("landings: {pitch: [1.0e12]}", "landings.pitch: draws"),  # the fuzzer's: blamed the model's angle
        ("landings: {speed: {gauss: [3, 1]}}", "landings.speed.gauss: unknown key"),
        ("landings: {pitch: []}", "landings.pitch: an empty list"),
        ("landings: {count: 0}", "landings.count: must be an integer >= 1"),
        ("landings: {yaw: [0.1]}", "landings.yaw: unknown key"),
        ("statistic: {speed: mean}", "statistic.speed: unknown key"),
    ],
)
def test_bad_landings_name_their_path(extra, message):
    base = ROBUST_YAML.split("landings:")[0]
    with pytest.raises(ConfigError) as info:
        parse_study(load_yaml(base + extra + "\n"))
    assert str(info.value).startswith(message), str(info.value)


def test_a_step_with_friction_lands_by_the_sequential_model_with_friction():
    """A terrain step with friction (no duration): each scenario is the sequential model with
    exact Coulomb friction at each touchdown, as ``footopt evaluate`` picks it."""
    from optimizer.evaluation.robust import evaluate_over_landings, scenario_objectives
    from optimizer.evaluation.scenarios import Distribution, DistributionKind, model_data, scenario_model

    base = ROBUST_YAML.split("landings:")[0]
    parse_study(load_yaml(base + "landings: {terrain_step: [0.01], friction: [0.5]}\n"))  # accepted
    model = load_model_file(Path(__file__).resolve().parents[2] / "configs" / "paper_case2.yaml")
    V = DistributionKind.VALUES
    landings = Landings(count=2, seed=1, distributions=(("terrain_step", Distribution(V, (0.005, 0.01))),
                                                        ("friction", Distribution(V, (0.5,)))))
    robust = evaluate_over_landings(model, landings, lambda o: Statistic())
    for row in robust.rows:
        assert row.objectives is not None
        alone = scenario_model(model_data(model), row.overrides)
        assert alone.scene.friction == 0.5 and not alone.scene.terrain.is_flat
        assert scenario_objectives(alone) == row.objectives  # the same model, one by one


def test_landings_the_inner_search_cannot_differentiate_need_the_outer_search():
    text = ROBUST_YAML.replace("method: outer", "method: inner")
    with pytest.raises(ConfigError, match="landings.pitch: the inner search varies speed, velocity_x, "
                                          "angular_velocity, restitution only"):
        parse_study(load_yaml(text))


def test_the_landings_block_round_trips(tmp_path):
    from optimizer.config.study_config import format_study

    config = parse_study(load_yaml(ROBUST_YAML))
    again = tmp_path / "again.yaml"
    again.write_text(format_study(config), encoding="utf-8")
    assert load_study(again) == config
    assert config.statistic_of(Objective.ENERGY_AFTER) == Statistic(StatisticKind.STD)
    assert config.statistic_of(Objective.MAX_INTERNAL) == Statistic()


def test_every_design_meets_the_same_landings():
    """Common random numbers: two different feet get the same speeds, tilts, restitutions and
    step heights (the step sits under each foot's own toes)."""
    config = parse_study(load_yaml(ROBUST_YAML))
    landings: Landings = config.landings
    a = design_from(Leg(), ((-0.5,), (1.0,)), ((0.2,), (0.3,)), FootLimits())
    b = design_from(Leg(), ((-0.9,), (0.6, 0.2)), ((0.1,), (0.2, 0.2)), FootLimits())
    for values in landings.draw():
        oa, ob = (overrides(design_model(Leg(), d, config.scene, FootLimits()), landings.names, values) for d in (a, b))
        for key in ("scene.velocity", "scene.angular_velocity", "scene.restitution", "model.bodies.0.angle"):
            assert oa[key] == ob[key]
        assert oa["scene.terrain"][1][1] == ob["scene.terrain"][1][1] == values[landings.names.index("terrain_step")]
    assert np.array_equal(landings.draw(), landings.draw())


def test_overrides_follow_the_contract():
    data = {"scene": {"speed": 3.0, "restitution": 0.8}, "model": {"bodies": [{"angle": -1.0}]}}
    out = apply_overrides(data, {"scene.velocity": [0.3, -3.1], "model.bodies.0.angle": -1.2})
    assert out == {"scene": {"velocity": [0.3, -3.1], "restitution": 0.8}, "model": {"bodies": [{"angle": -1.2}]}}
    assert apply_overrides(out, {"scene.speed": 2.0})["scene"] == {"speed": 2.0, "restitution": 0.8}
    assert data["scene"] == {"speed": 3.0, "restitution": 0.8}  # the input is left alone


@pytest.fixture(scope="module")
def robust_run(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("robust")
    study = folder / "robust.yaml"
    study.write_text(ROBUST_YAML, encoding="utf-8")
    assert main(["optimize", str(study), "--out", str(folder / "run"), "--quiet"]) == 0
    return folder / "run"


def test_scenario_rows_are_reproduced_by_footopt_evaluate(robust_run: Path, tmp_path, capsys):
    """Apply a row's overrides to the design's model file (as YAML data), run footopt evaluate:
    the row's objectives come back exactly; the statistics of the rows are the front's values."""
    rows = list(csv.DictReader((robust_run / "scenarios.csv").open(encoding="utf-8")))
    front = {r["model_file"]: r for r in csv.DictReader((robust_run / "pareto.csv").open(encoding="utf-8"))}
    assert len(rows) == 7 * len(front) > 0
    for row in rows[:3] + rows[-2:]:
        model = robust_run / "designs" / f"{row['design']}.yaml"
        data = apply_overrides(yaml.safe_load(model.read_text(encoding="utf-8")), json.loads(row["overrides"]))
        path = tmp_path / f"{row['design']}_{row['scenario']}.yaml"
        path.write_text(yaml.safe_dump(data), encoding="utf-8")
        capsys.readouterr()
        assert main(["evaluate", "--json", str(path)]) == 0
        got = json.loads(capsys.readouterr().out)
        for key in ("external_norm", "internal_norm"):
            assert got[key] == pytest.approx(float(row[key]), rel=1e-12, abs=1e-15), key
    config = load_study(robust_run / "study.yaml")
    for model_file, point in front.items():
        mine = [r for r in rows if f"designs/{r['design']}.yaml" == model_file]
        for objective in (Objective.EXTERNAL_NORM, Objective.INTERNAL_NORM, Objective.ENERGY_AFTER):
            values = np.array([float(r[objective.value]) for r in mine])
            expected = config.statistic_of(objective).of(values)
            assert float(point[objective.value]) == pytest.approx(expected, rel=1e-9)


def test_evaluate_landings_prints_the_statistics(robust_run: Path, capsys):
    point = next(csv.DictReader((robust_run / "pareto.csv").open(encoding="utf-8")))
    capsys.readouterr()
    study = str(robust_run / "study.yaml")
    assert main(["evaluate", "--json", "--landings", study, str(robust_run / point["model_file"])]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["statistic"]["external_norm"] == "cvar:0.8"
    for key in ("external_norm", "internal_norm", "energy_after"):
        assert got["statistics"][key] == pytest.approx(float(point[key]), rel=1e-12)
    assert (robust_run / "scenarios.png").stat().st_size > 0
    assert load_model_file(robust_run / point["model_file"]).scene.speed == 3.43  # the nominal file is untouched


def test_batched_first_impacts_equal_one_by_one_evaluation():
    """Frictionless flat-ground scenarios evaluated together give what each scenario's file
    gives alone (the lean algorithm against the full impact function: 1e-12 relative); pitches
    change which contacts hit (several groups), friction rows and pulling contacts are left to
    the one-by-one path."""
    from optimizer.evaluation.batched import active_sets, first_impacts, scenario_inputs
    from optimizer.evaluation.robust import evaluate_over_landings, scenario_objectives
    from optimizer.evaluation.scenarios import Distribution, DistributionKind, model_data, scenario_model

    model = load_model_file(Path(__file__).resolve().parents[2] / "configs" / "paper_case3.yaml")
    model = dataclasses.replace(model, scene=dataclasses.replace(model.scene, selection=ContactSelection.LOWEST))
    U, V = DistributionKind.UNIFORM, DistributionKind.VALUES
    landings = Landings(count=300, seed=3, distributions=(
        ("speed", Distribution(U, (2.0, 4.0))), ("velocity_x", Distribution(U, (-1.0, 1.0))),
        ("pitch", Distribution(U, (-0.4, 0.4))), ("angular_velocity", Distribution(U, (-2.0, 2.0))),
        ("restitution", Distribution(U, (0.3, 0.9))), ("friction", Distribution(V, (0.0, 0.0, 0.5))),
    ))
    draws = landings.draw()
    frictionless = draws[:, landings.names.index("friction")] == 0
    fast = first_impacts(model, landings.names, draws)
    P, _, _ = scenario_inputs(model, landings.names, draws)
    assert len(set(active_sets(model, P))) >= 2
    assert all(f is not None for f, free in zip(fast, frictionless, strict=True) if free)
    case1 = load_model_file(Path(__file__).resolve().parents[2] / "configs" / "paper_case1.yaml")
    everywhere = dataclasses.replace(case1, scene=dataclasses.replace(case1.scene, selection=ContactSelection.ALL))
    pulled = [f is None for f, free in zip(first_impacts(everywhere, landings.names, draws), frictionless) if free]
    assert 0 < sum(pulled) < len(pulled)  # some Newton answers pull: lcp runs for them, one by one
    for m in (model, everywhere):
        robust = evaluate_over_landings(m, landings, lambda o: Statistic())
        data = model_data(m)
        for row in robust.rows:
            alone = scenario_objectives(scenario_model(data, row.overrides))
            for key, value in alone.items():
                assert getattr(row.objectives, key) == pytest.approx(value, rel=1e-12, abs=1e-15), (row.scenario, key)


def test_batched_rows_in_compiled_c_equal_the_virtual_machine(monkeypatch):
    """From ``COMPILE_ROWS`` rows on the scenarios run as compiled C (SIMD lanes): the values of
    CasADi's virtual machine below it, to 1e-13 relative (the vector lanes' sine and cosine
    differ from libm's in the last bits)."""
    from optimizer.evaluation import batched

    model = load_model_file(Path(__file__).resolve().parents[2] / "configs" / "paper_case3.yaml")
    model = dataclasses.replace(model, scene=dataclasses.replace(model.scene, selection=ContactSelection.LOWEST))
    config = load_study(Path(__file__).resolve().parents[2] / "configs" / "robust_study.yaml")
    kept = tuple((n, d) for n, d in config.landings.distributions if n != "terrain_step")
    draws = Landings(count=40, seed=9, distributions=kept).draw()
    names = tuple(n for n, _ in kept)
    monkeypatch.setattr(batched, "COMPILE_ROWS", 10**9)
    on_vm = batched.first_impact_values(model, names, draws)
    kernels, original = [], batched._batch_kernel

    def spy(f, root):
        kernels.append(original(f, root))
        return kernels[-1]

    monkeypatch.setattr(batched, "_batch_kernel", spy)
    monkeypatch.setattr(batched, "COMPILE_ROWS", 1)
    compiled = batched.first_impact_values(model, names, draws)
    assert kernels and all(k is not None for k in kernels)  # C ran (geometry and impacts)
    assert np.isfinite(on_vm).all()
    np.testing.assert_allclose(compiled, on_vm, rtol=1e-13, atol=0.0)


def test_designs_times_scenarios_in_one_call_per_shape_and_contact_set(monkeypatch):
    """A batch of designs over the landings: one impact call per (shape, contact set), not one
    per design, and each design's statistics as each scenario's ``footopt evaluate`` gives them
    (1e-12 relative)."""
    from optimizer.evaluation import batched
    from optimizer.evaluation.robust import scenario_objectives
    from optimizer.evaluation.scenarios import model_data, scenario_model
    from optimizer.search.outer import evaluate_designs_over_landings

    config = parse_study(load_yaml(ROBUST_YAML.replace("  pitch: {uniform: [-0.1, 0.1]}\n", "")
                                   .replace("  terrain_step: {uniform: [0.0, 0.01]}\n", "")))
    rng = np.random.default_rng(11)
    designs = []
    for toes, rods in ((1, 1), (2, 1), (1, 1), (2, 1), (1, 2)):
        angles = ((-1.2,), *((tuple(rng.uniform(0.9, 1.4, rods)),) * toes))
        masses = ((0.05,), *((tuple(np.full(rods, 0.4 / (toes * rods))),) * toes))
        designs.append(design_from(config.leg, angles, masses, config.limits))
    calls = []
    original = batched._newton_rows

    def spy(topology, space, P, V, E):
        calls.append(len(P))
        return original(topology, space, P, V, E)

    monkeypatch.setattr(batched, "_newton_rows", spy)
    found = evaluate_designs_over_landings(config, designs)
    assert len(calls) == 3 and sum(calls) == len(designs) * config.landings.count  # three shapes
    for design, evaluation in zip(designs, found, strict=True):
        model = design_model(config.leg, design, config.scene, config.limits)
        data, draws = model_data(model), config.landings.draw()
        alone = [scenario_objectives(scenario_model(data, overrides(model, config.landings.names, v))) for v in draws]
        for objective in (Objective.EXTERNAL_NORM, Objective.INTERNAL_NORM):
            expected = config.statistic_of(objective).of(np.array([a.value(objective) for a in alone]))
            assert evaluation.objectives.value(objective) == pytest.approx(expected, rel=1e-12)


def test_whole_landing_scenarios_run_in_worker_processes_as_one_by_one(tmp_path, monkeypatch):
    """A design's whole landings over the landings, two at once in worker processes (a machine
    with two cores): each row is that scenario's model landed alone here, to the bit."""
    from optimizer.evaluation.robust import evaluate_over_landings, scenario_objectives
    from optimizer.evaluation.scenarios import Distribution, DistributionKind, model_data, scenario_model

    text = (Path(__file__).resolve().parents[2] / "configs" / "landing_case3.yaml").read_text(encoding="utf-8")
    file = tmp_path / "short.yaml"
    file.write_text(text.replace("duration: 0.3", "duration: 0.01"), encoding="utf-8")
    model = load_model_file(file)
    landings = Landings(count=3, seed=2, distributions=(
        ("speed", Distribution(DistributionKind.UNIFORM, (2.0, 3.5))),
        ("restitution", Distribution(DistributionKind.VALUES, (0.3, 0.8)))))
    monkeypatch.setenv("FOOTOPT_WORKERS", "2")
    told: list[tuple[int, int]] = []
    robust = evaluate_over_landings(model, landings, lambda o: Statistic(), progress=lambda d, n: told.append((d, n)))
    assert told == [(1, 3), (2, 3), (3, 3)]
    for row in robust.rows:
        assert row.objectives is not None and row.objectives.peak_external_norm is not None
        assert scenario_objectives(scenario_model(model_data(model), row.overrides)) == row.objectives
    assert len({row.objectives.peak_external_norm for row in robust.rows}) == 3


def test_a_scenario_whose_spring_is_too_stiff_to_follow_fails_it_without_ending_the_study():
    """A design's joint law that the landing refuses (a spring RK4 could not follow within
    LANDING_STEPS: a ModelError naming it) makes its scenario fail, as a numerical failure does,
    instead of stopping a robust study; alone, ``footopt evaluate`` names it (test_landing_stiff_joint)."""
    from impulse_core.errors import ModelError
    from impulse_core.timedomain.landing import LandingSettings, landing
    from optimizer.evaluation.robust import scenario_objectives

    model = load_model_file(Path(__file__).resolve().parents[2] / "configs" / "landing_case3.yaml")
    joints = tuple(dataclasses.replace(j, stiffness=1e12) if i == 2 else j for i, j in enumerate(model.joints))
    stiff = dataclasses.replace(model, joints=joints)
    with pytest.raises(ModelError, match=r"model.bodies\[2\].stiffness"):
        landing(stiff.tree, stiff.scene, joints, LandingSettings(), stiff.space)
    assert scenario_objectives(stiff) is None
