"""The inner search (IPOPT) with a spatial leg (``leg: {file}`` whose joint axes are not all
parallel: solo12's front left leg from its trunk, four rods): the NLP hangs the splayed foot from
the leg's last rod as the outer search's model files do (the leg's axes, frames and masses its
own). Every objective value and support row the NLP computes equals ``footopt evaluate`` of the
design's model file (1e-9); over ``landings:`` each scenario's impact is that scenario's outer
evaluation; the NLP's gradients are central differences of its own functions; a tiny study runs
end to end and its front re-evaluates; and the whole-landing NLP's gradient is exact."""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from impulse_core.evaluate import touchdown_geometry
from impulse_core.kinematics.spatial import SPATIAL
from optimizer.cli.main import main
from optimizer.config.model_file import format_model_file, load_yaml
from optimizer.config.study_config import StudyConfig, load_study
from optimizer.design_space import FootShape, SplayMode, SplaySpace, ToeSymmetry, design_model, foot_tree
from optimizer.evaluation.robust import evaluate_over_landings
from optimizer.search.compiled import VALUE_OUTPUTS
from optimizer.search.inner import ShapeNlp, _evaluate, start_point
from tests.optimizer.test_inner_splay import vm_nlp_of
from tests.optimizer.test_inner_splay_robust import LANDINGS, NAMES, per_scenario
from tests.optimizer.test_leg_chains import SPATIAL as SPATIAL_STUDY
from tests.optimizer.test_leg_chains import optimized, solo_leg

INNER = SPATIAL_STUDY.replace("method: outer, trials: 16, startup_trials: 8", "method: inner")
#: Independent toes, each at its own yaw in [-0.3, 0.5] rad.
PER_TOE = {"toe_symmetry": ToeSymmetry.INDEPENDENT, "splay": SplaySpace((-0.3, 0.5), SplayMode.PER_TOE)}


@pytest.fixture(scope="module")
def leg_folder(tmp_path_factory) -> Path:
    """solo12's front left leg from its trunk (spatial: the abduction axis is not parallel to the
    others) as ``leg.yaml``, beside which the studies are written."""
    folder = tmp_path_factory.mktemp("spatial_leg")
    solo_leg(folder, root="base_link")
    return folder


def study(folder: Path, text: str = INNER, **data) -> StudyConfig:
    """The study ``text`` (YAML) with ``data`` on top, its leg ``folder/leg.yaml``."""
    path = folder / "s.yaml"
    path.write_text(json.dumps({**load_yaml(text, path), **data}))
    return load_study(path)


def design_of(config: StudyConfig, nlp: ShapeNlp, x: np.ndarray):
    """The design the NLP's point makes (its own lengths, masses and yaws)."""
    return _evaluate(config, nlp, *nlp.unpack(x), nlp.toe_yaws(x)).design


def evaluated(folder: Path, config: StudyConfig, design, capsys) -> dict:
    """``footopt evaluate --json`` of the design's model file, with the values ``foot_values``
    names (the base's turn |omega| from ``v_plus``, the least contact impulse)."""
    path = folder / "design.yaml"
    path.write_text(format_model_file(design_model(config.leg, design, config.scene, config.limits)))
    capsys.readouterr()
    assert main(["evaluate", "--json", str(path)]) == 0
    record = json.loads(capsys.readouterr().out)
    turn = float(np.linalg.norm(record["v_plus"][3:6]))
    return {**record, "base_angular_velocity": turn, "min_external": min(record["external"])}


def level_start(config: StudyConfig, nlp: ShapeNlp, rng: np.random.Generator) -> np.ndarray:
    """A random start the linear program levels (:func:`start_point` returns None when it cannot)."""
    while (x := start_point(config, nlp, rng)) is None:
        pass
    return x


@pytest.mark.parametrize(("space", "shape"), [({}, FootShape(2, 1)), (PER_TOE, FootShape(3, 2))])
def test_every_objective_is_the_evaluated_model_file(leg_folder, capsys, space, shape):
    """The NLP's ``foot_values`` (every first-impact objective) and its objective rows at level
    starts equal ``footopt evaluate`` of the design's model file, whose leg is the file's four
    spatial rods: identical toes under a symmetric splay, independent toes each at its own yaw."""
    config = study(leg_folder, objectives=["external_norm", "internal_norm"])
    config = dataclasses.replace(config, space=dataclasses.replace(config.space, **space))
    assert config.leg.spatial and len(config.leg.rods) == 4
    nlp = vm_nlp_of(config, shape)
    c = nlp.compiled
    n_design = 2 * c.n_rods + c.n_lengths + 1 + c.kind.yaws
    f = c.solver.get_function("nlp_f")
    rng = np.random.default_rng(4)
    for _ in range(2):
        x = level_start(config, nlp, rng)
        ours = dict(zip(VALUE_OUTPUTS, (float(v) for v in c.values(x[:n_design], shape.n_toes)), strict=True))
        design = design_of(config, nlp, x)
        record = evaluated(leg_folder, config, design, capsys)
        assert len(record["joints"]) == 3 + shape.n_links  # the leg's three joints, then the foot's
        for key in VALUE_OUTPUTS:
            assert ours[key] == pytest.approx(record[key], rel=1e-9, abs=1e-15), key
        for w, key in (([1.0, 0.0, 2.0], "external_norm"), ([0.0, 1.0, 2.0], "internal_norm")):
            assert float(f(x, w)) == pytest.approx(record[key], rel=1e-9), key


def test_the_support_rows_are_the_model_files_centre_of_mass_and_contacts(leg_folder):
    """The support margin's rows (per edge, the cross product of the edge with the centre of mass's
    ground projection: heel, then the toes by decreasing yaw) from the whole tree's centre of mass,
    the leg's heavy trunk in it, and the contacts of the design's model file."""
    from optimizer.search.compiled import _splayed_values, support_edges, toe_yaws

    config = study(leg_folder, constraints={"foot_mass": 0.05, "min_link_mass": 0.005, "mass_per_length": [0.05, 2.0],
                                            "foot_length": [0.03, 0.12], "min_clearance": 0.002,
                                            "support_margin": 0.0})
    nlp = vm_nlp_of(config, FootShape(3, 1))
    c = nlp.compiled
    x = level_start(config, nlp, np.random.default_rng(1))
    n, n_L = c.n_rods, c.n_lengths
    psi = x[2 * n + n_L + 1 : 2 * n + n_L + 1 + c.kind.yaws]
    p, masses, topology = _splayed_values(config, c.kind, ca.DM(x[:n]), ca.DM(x[n : 2 * n]),
                                          ca.DM(x[2 * n : 2 * n + n_L]), toe_yaws(config.space.splay, 3, list(psi)))
    cross, _ = (np.array(ca.evalf(v)).ravel() for v in support_edges(c.kind, topology, p, masses))
    tree = foot_tree(config.leg, design_of(config, nlp, x))
    geometry = touchdown_geometry(tree, SPATIAL)
    mass = np.array([b.mass for b in tree.bodies])
    com = (mass @ geometry.coms / mass.sum())[[0, 2]]
    corners = geometry.contacts[[0, 3, 2, 1]][:, [0, 2]]
    d, w = np.roll(corners, -1, axis=0) - corners, com - corners
    np.testing.assert_allclose(cross, d[:, 0] * w[:, 1] - d[:, 1] * w[:, 0], rtol=1e-9, atol=1e-15)


def test_per_scenario_impacts_are_the_outer_evaluation(leg_folder):
    """Over ``landings:`` (level first impacts whose approach and restitution vary) each
    scenario's impact in the NLP is the outer evaluation of that scenario's model file."""
    config = study(leg_folder, landings={**LANDINGS, "count": 3})
    nlp = vm_nlp_of(config, FootShape(2, 1))
    x = level_start(config, nlp, np.random.default_rng(0))
    ours = per_scenario(config, nlp, x)
    rows = evaluate_over_landings(design_model(config.leg, design_of(config, nlp, x), config.scene, config.limits),
                                  config.landings, config.statistic_of).rows
    for key in NAMES:
        theirs = np.array([getattr(r.objectives, key) for r in rows])
        np.testing.assert_allclose(ours[key], theirs, rtol=1e-9, atol=1e-12, err_msg=key)


def test_the_nlps_gradients_are_central_differences(leg_folder):
    """The NLP's exact objective gradient and constraint Jacobian (the base's turn by its spatial
    epigraph, the support rows, the geometric rows) against central differences of its own
    objective and constraints, in every variable."""
    config = study(leg_folder, objectives=["external_norm", "base_angular_velocity"],
                   constraints={"foot_mass": 0.05, "min_link_mass": 0.005, "mass_per_length": [0.05, 2.0],
                                "foot_length": [0.03, 0.12], "min_clearance": 0.002, "support_margin": -0.5})
    config = dataclasses.replace(config, space=dataclasses.replace(config.space, **PER_TOE))
    nlp = vm_nlp_of(config, FootShape(2, 1))
    c = nlp.compiled
    x = level_start(config, nlp, np.random.default_rng(2))
    p = [1.0, 0.7, 2.0]
    f, g = c.solver.get_function("nlp_f"), c.solver.get_function("nlp_g")
    exact_f = np.array(c.solver.get_function("nlp_grad_f")(x, p)[1]).ravel()
    exact_g = np.array(c.solver.get_function("nlp_jac_g")(x, p)[1].full())
    h, fd_f, fd_g = 1e-6, np.zeros(c.n_x), np.zeros_like(exact_g)
    for k in range(c.n_x):
        e = np.zeros(c.n_x)
        e[k] = h
        fd_f[k] = (float(f(x + e, p)) - float(f(x - e, p))) / (2 * h)
        fd_g[:, k] = (np.array(g(x + e, p)) - np.array(g(x - e, p))).ravel() / (2 * h)
    assert np.abs(fd_g[:, 2 * c.n_rods + c.n_lengths + 1]).max() > 1e-3  # a yaw acts
    np.testing.assert_allclose(exact_f, fd_f, rtol=1e-6, atol=1e-7 * np.abs(fd_f).max())
    np.testing.assert_allclose(exact_g, fd_g, rtol=1e-6, atol=1e-7 * np.abs(fd_g).max())


def test_a_tiny_study_runs_and_its_front_reevaluates(leg_folder, capsys, monkeypatch, unsaved_drawings):
    """``footopt optimize`` with the spatial leg and the inner search, its two shapes swept by two
    forked workers (each unpickles the study: its leg must stay spatial there): every front
    design's model file hangs the foot from the leg's four rods and re-evaluates to its recorded
    objectives."""
    monkeypatch.setenv("FOOTOPT_WORKERS", "2")
    text = INNER.replace("method: inner", "method: inner, inner: {front_points: 1, starts: 4}")
    text = text.replace("toe_segments: [1, 2]", "toe_segments: [1, 1]")
    found = optimized(leg_folder, text, capsys)
    assert found
    for row, rec, path in found:
        for key in ("external_norm", "internal_norm", "max_internal"):
            assert rec[key] == pytest.approx(float(row[key]), rel=1e-9, abs=1e-15), key
        assert len(rec["joints"]) == 3 + 1 + int(row["toes"])


@pytest.mark.slow  # the same derivative on the same leg, its joints sprung: the next test's (by default)
def test_the_whole_landing_nlp_differentiates_the_spatial_leg(leg_folder):
    """The whole-landing inner search with the spatial leg: the toe's yaw derivative (chained
    through its root's rpy on the leg's last rod) is the central difference of the landed
    objectives."""
    from tests.optimizer.test_landing_inner_spatial import SPATIAL_LANDING_YAML
    from tests.optimizer.test_leg_chains import assert_the_yaw_derivative

    text = re.sub(r"leg:.*?\n(?=\S)", "leg: {file: leg.yaml}\n", SPATIAL_LANDING_YAML, flags=re.S)
    (leg_folder / "landing.yaml").write_text(text)
    tree = assert_the_yaw_derivative(load_study(leg_folder / "landing.yaml"))
    assert len(tree.bodies) == 6 and tree.bodies[5].parent == 3


def test_the_spatial_legs_own_springs_dampers_and_stops_act_over_the_landing(tmp_path):
    """solo12's leg from its trunk with a spring, a damper and stops (+-0.05 rad about the
    touchdown angle) on each of its three joints, written into its model file: the whole-landing
    NLP's landed model carries them on the leg's joints, they change the landing (against the
    same model with the leg's joints free), and the toe yaw's exact derivative is still the
    central difference of the landed objectives (the toe chained through its root's rpy on the
    leg's last rod: the derivative the free leg's test checks with ``--slow``)."""
    import yaml

    from impulse_core.kinematics.spatial import SPATIAL
    from impulse_core.model.joints import FREE
    from impulse_core.timedomain.landing import LandingSettings, landing
    from optimizer.search.landing_inner import _Landed, build_landing_nlp, start_landing
    from tests.optimizer.test_landing_inner_spatial import SPATIAL_LANDING_YAML
    from tests.optimizer.test_leg_chains import assert_the_yaw_derivative

    solo_leg(tmp_path, root="base_link")
    data = yaml.safe_load((tmp_path / "leg.yaml").read_text())
    for body in data["model"]["bodies"][1:]:
        body.update(stiffness=3.0, damping=0.05, limits=[body["angle"] - 0.05, body["angle"] + 0.05])
    (tmp_path / "leg.yaml").write_text(yaml.safe_dump(data))
    text = re.sub(r"leg:.*?\n(?=\S)", "leg: {file: leg.yaml}\n", SPATIAL_LANDING_YAML, flags=re.S)
    (tmp_path / "landing.yaml").write_text(text)
    config = load_study(tmp_path / "landing.yaml")
    nlp = build_landing_nlp(config, FootShape(1, 1))
    tree, laws, scene = _Landed(nlp).model(start_landing(nlp, np.random.default_rng(0)))
    leg = list(laws[1:4])
    assert leg == list(config.leg.joints[1:4]) and all(law.stiffness == 3.0 and law.limits for law in leg)
    settings = LandingSettings(tolerance=1e-2)
    sprung = landing(tree, scene, laws, settings, SPATIAL)
    free = landing(tree, scene, (FREE,) * 4 + tuple(laws[4:]), settings, SPATIAL)
    assert np.max(np.abs(sprung.final_angles[1:4] - free.final_angles[1:4])) > 1e-3  # 1.1e-2 rad
    assert assert_the_yaw_derivative(config, nlp) == tree  # the same NLP, its yaw derivative
    assert len(tree.bodies) == 6 and tree.bodies[5].parent == 3  # the toe hangs from the leg's last rod
