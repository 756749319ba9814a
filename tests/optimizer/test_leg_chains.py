"""A study's leg as any chain of rods from a model file (``leg: {file: F}``): a three-rod planar
leg imported from solo12 (shoulder, upper and lower leg) in an outer study whose front designs
re-evaluate (``footopt evaluate``) to their recorded objectives; the general chain against the
two-rod leg (a thigh split in two welded halves is the same mechanism); a spatial leg (solo12 from
its body) in a spatial study; bad leg files refused in one line naming ``leg.file``."""

from __future__ import annotations

import csv
import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from impulse_core.evaluate import evaluate
from impulse_core.model.joints import FREE
from impulse_core.model.tree import ContactSelection, JointKind, Scene, Tree
from optimizer.cli.main import main
from optimizer.config.model_file import ModelFile, format_model_file, load_model_file
from optimizer.config.study_config import StudyConfig, format_study, load_study
from optimizer.design_space import (
    FootLimits,
    Leg,
    LegChain,
    design_from,
    evaluate_design,
    foot_geometry,
    foot_joint_laws,
    foot_space,
    foot_tree,
    symmetric_yaws,
)
from optimizer.errors import ConfigError
from optimizer.imports.leg import import_leg
from optimizer.imports.read import read_description
from tests.optimizer.imports.peers import robot_file

SOLO = "solo_description/robots/solo12.urdf"
#: solo12's front left leg crouched: the upper leg back and down, the lower leg forward and down.
ANGLES = {"FL_HFE": 0.4, "FL_KFE": -0.8}
STUDY = """\
name: chain
seed: 2
scene: {speed: 1.0, restitution: 0.0, friction: 0.0}
leg: {file: leg.yaml}
design_space: {toes: [1, 2], toe_segments: [1, 2], heel_segments: [1, 1], toe_symmetry: identical}
constraints: {foot_mass: 0.05, min_link_mass: 0.005, mass_per_length: [0.05, 2.0], foot_length: [0.03, 0.12],
              min_clearance: 0.002}
objectives: [external_norm, internal_norm]
search: {method: outer, trials: 16, startup_trials: 8}
"""


def solo_leg(folder: Path, root: str = "FL_SHOULDER", joint_laws: bool = False, **kw) -> Path:
    """solo12's front left leg from ``root`` to the foot, crouched, as ``folder/leg.yaml``."""
    desc = read_description(robot_file(SOLO))
    leg = import_leg(desc, root, "FL_FOOT", angles=ANGLES, joint_laws=joint_laws, **kw)
    path = folder / "leg.yaml"
    path.write_text(format_model_file(leg.model, header_comment=leg.summary()))
    return path


def optimized(folder: Path, study: str, capsys) -> list[tuple[dict, dict, Path]]:
    """``footopt optimize`` of ``study`` in ``folder``, then ``footopt evaluate --json`` on its
    front's model files: (front row, evaluated record, model file) per design."""
    (folder / "s.yaml").write_text(study)
    out = folder / "run"
    assert main(["optimize", str(folder / "s.yaml"), "--out", str(out), "--quiet"]) == 0
    rows = list(csv.DictReader((out / "pareto.csv").open(encoding="utf-8")))
    assert rows
    capsys.readouterr()
    files = [out / r["model_file"] for r in rows]
    assert main(["evaluate", "--json", *map(str, files)]) == 0
    records = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    return list(zip(rows, records, files, strict=True))


@pytest.mark.parametrize("method", ["outer", "inner"])
def test_a_three_rod_imported_leg_runs_a_study_that_reevaluates(tmp_path, capsys, method, unsaved_drawings):
    """Both searches on solo12's shoulder, upper and lower leg (planar): each front design's model
    file gives the recorded objectives again, its leg the file's rods, its foot at the ankle."""
    leg_file = solo_leg(tmp_path)
    study = STUDY if method == "outer" else STUDY.replace("method: outer", "method: inner, inner: {front_points: 2, starts: 2}")
    config = load_study(_study(tmp_path, study))
    assert isinstance(config.leg, LegChain) and len(config.leg.rods) == 3
    again = tmp_path / "again.yaml"
    again.write_text(format_study(config))  # the study written back names the leg file
    assert load_study(again) == config
    source = load_model_file(leg_file).tree.bodies
    for row, rec, path in optimized(tmp_path, study, capsys):
        for key in ("external_norm", "internal_norm", "max_internal"):
            assert rec[key] == pytest.approx(float(row[key]), rel=1e-9, abs=1e-15), key
        bodies = load_model_file(path).tree.bodies
        assert bodies[:3] == tuple(dataclasses.replace(b, contacts=()) for b in source)
        # the foot hangs at the ankle: every foot root on the lower leg's tip
        roots = [b for b in bodies[3:] if b.parent == 2]
        assert len(roots) >= 2 and all(b.at == 1.0 for b in roots)
        assert all(b.parent >= 2 for b in bodies[3:])


def _study(folder: Path, text: str) -> Path:
    (folder / "s.yaml").write_text(text)
    return folder / "s.yaml"


def _split_thigh(leg: Leg) -> LegChain:
    """``leg`` with its (uniform) thigh cut in two welded halves: the same mechanism, three rods."""
    thigh, shank = leg.chain.rods
    half = dataclasses.replace(thigh, name="thigh_a", length=thigh.length / 2, mass=thigh.mass / 2)
    rest = dataclasses.replace(half, name="thigh_b", parent=0, angle=0.0, joint=JointKind.FIXED)
    return LegChain((half, rest, dataclasses.replace(shank, parent=1)), (FREE, FREE, leg.knee))


@pytest.mark.parametrize("spatial", [False, True])
def test_the_general_chain_is_the_two_rod_leg(spatial):
    """A thigh cut in two welded halves moves as the thigh: the same contact impulses, knee and
    foot joint impulses and geometry (the weld's own impulse aside), planar and splayed."""
    leg, limits = Leg(), FootLimits()
    chain = _split_thigh(leg)
    angles, masses = ((-0.6,), (0.9, 0.2), (1.0, 0.1)), ((0.1,), (0.1, 0.05), (0.15, 0.1))
    yaws = symmetric_yaws(2, 0.3) if spatial else None
    a, b = (design_from(x, angles, masses, limits, toe_yaws=yaws) for x in (leg, chain))
    assert a == b
    ga, gb = foot_geometry(leg, a), foot_geometry(chain, b)
    assert np.allclose(ga.tips, gb.tips, atol=1e-15) and np.allclose(ga.leg_points, gb.leg_points[[0, 2]], atol=1e-15)
    ea, eb = evaluate_design(leg, a, Scene(), limits), evaluate_design(chain, b, Scene(), limits)
    assert ea.objectives.external_norm == pytest.approx(eb.objectives.external_norm, rel=1e-10)
    assert dict(ea.constraints.items()) == pytest.approx(dict(eb.constraints.items()), rel=1e-9, abs=1e-12)
    scene = Scene(selection=ContactSelection.ALL)
    ra = evaluate(foot_tree(leg, a), scene, space=foot_space(leg, a))
    rb = evaluate(foot_tree(chain, b), scene, space=foot_space(chain, b))
    assert np.allclose(ra.external, rb.external, rtol=1e-10, atol=1e-14)
    # joint impulses from the knee down (the chain's first joint is the weld)
    assert np.allclose(ra.internal_magnitude, np.delete(rb.internal_magnitude, 0), rtol=1e-9, atol=1e-13)
    assert foot_joint_laws(chain, b)[2:] == foot_joint_laws(leg, a)[1:]


def test_a_two_rod_file_is_the_inline_leg(tmp_path, capsys):
    """A two-rod leg file and the same thigh and shank written inline: equal studies and fronts."""
    leg = Leg(thigh_length=0.3, thigh_mass=0.8, thigh_angle=-2.0, shank_length=0.3, shank_mass=0.2,
              knee_angle=1.1, thigh_com=0.4, shank_gyration=0.3, thigh_offset=0.002)
    thigh, shank = leg.chain.rods
    tree = Tree((thigh, dataclasses.replace(shank, contacts=(1.0,))))  # the ankle at the shank's tip
    (tmp_path / "leg.yaml").write_text(format_model_file(ModelFile(tree, Scene())))
    inline = format_study(dataclasses.replace(load_study(_study(tmp_path, STUDY)), source=None))
    file_config = load_study(tmp_path / "s.yaml")
    assert file_config.leg == leg
    fronts = []
    for name, text in (("file", STUDY), ("inline", inline)):
        folder = tmp_path / name
        folder.mkdir()
        (folder / "leg.yaml").write_text((tmp_path / "leg.yaml").read_text())
        fronts.append([(r["trial"], r["external_norm"], r["internal_norm"]) for r, _, _ in optimized(folder, text, capsys)])
    assert fronts[0] == fronts[1]


SPATIAL = STUDY.replace("toe_symmetry: identical}", "toe_symmetry: identical, space: spatial, splay: [0.0, 0.6]}")


def test_a_spatial_imported_leg_runs_a_spatial_outer_study(tmp_path, capsys):
    solo_leg(tmp_path, root="base_link")
    config = load_study(_study(tmp_path, SPATIAL.replace("trials: 16, startup_trials: 8", "trials: 8, startup_trials: 8")))
    assert isinstance(config.leg, LegChain) and config.leg.spatial and len(config.leg.rods) == 4
    text = SPATIAL.replace("trials: 16, startup_trials: 8", "trials: 8, startup_trials: 8")
    for row, rec, path in optimized(tmp_path, text, capsys):
        for key in ("external_norm", "internal_norm", "max_internal"):
            assert rec[key] == pytest.approx(float(row[key]), rel=1e-9, abs=1e-15), key
        model = load_model_file(path)
        assert model.space.joint_axis is None
        tips = [b for b in model.tree.bodies if b.contacts]
        assert len(tips) == int(row["toes"]) + 1


#: Model files no leg is made of: (file text, the one-line error).
HEAD = "scene: {speed: 1.0, restitution: 0.0}\nmodel:\n  bodies:\n"
BAD = {
    "chain.yaml": (HEAD + "    - {name: a, length: 0.2, mass: 1.0, angle: -1.5}\n"
                   "    - {name: b, parent: a, length: 0.2, mass: 1.0, angle: 0.3}\n"
                   "    - {name: c, parent: a, length: 0.2, mass: 1.0, angle: 0.3, contacts: [1.0]}\n",
                   r"leg.file: .*chain.yaml: rod 'c' hangs from 'a', not from 'b': a leg is a chain"),
    "two_ankles.yaml": (HEAD + "    - {name: a, length: 0.2, mass: 1.0, angle: -1.5, contacts: [0.5, 1.0]}\n",
                        r"leg.file: .*: its last rod 'a' has 2 contacts: the foot hangs at one ankle"),
    "named.yaml": (HEAD + "    - {name: heel, length: 0.2, mass: 1.0, angle: -1.5, contacts: [1.0]}\n",
                   r"leg.file: .*: rod 'heel' takes a foot rod's name"),
    "broken.yaml": (HEAD + "    - {name: a, length: -0.2, mass: 1.0, angle: -1.5, contacts: [1.0]}\n",
                    r"leg.file: .*broken.yaml: model.bodies\[0\].length"),
}


def test_bad_leg_files_are_refused_in_one_line(tmp_path, capsys):
    solo_leg(tmp_path, root="base_link")  # spatial: refused by a planar design space
    cases = {name: (text, message) for name, (text, message) in BAD.items()}
    cases["leg.yaml"] = (None, r"leg.file: .*leg.yaml is a spatial leg: it needs design_space.space: spatial")
    cases["missing.yaml"] = (None, r"leg.file: .*missing.yaml: file not found")
    for name, (text, message) in cases.items():
        if text is not None:
            (tmp_path / name).write_text(text)
        study = _study(tmp_path, STUDY.replace("leg.yaml", name))
        with pytest.raises(ConfigError, match=message) as info:
            load_study(study)
        assert "\n" not in str(info.value)
        capsys.readouterr()
        assert main(["optimize", str(study), "--out", str(tmp_path / "run"), "--quiet"]) == 2
        err = capsys.readouterr().err.strip()
        assert "leg.file: " in err and len(err.splitlines()) == 1, err


def test_a_leg_chains_joint_laws_need_a_whole_landing(tmp_path):
    """The imported leg's stops and springs come along: a first-impact study refuses them, naming
    ``leg.file``; a whole-landing study carries them onto every design's model file."""
    solo_leg(tmp_path, joint_laws=True)
    with pytest.raises(ConfigError, match=r"leg.file: springs, dampers and stops act only over a whole landing"):
        load_study(_study(tmp_path, STUDY))
    landing = STUDY.replace("friction: 0.0}", "friction: 0.0, gravity: 9.81, duration: 0.02}").replace(
        "[external_norm, internal_norm]", "[peak_external_norm, energy_absorbed]")
    config = load_study(_study(tmp_path, landing))
    laws = load_model_file(tmp_path / "leg.yaml").joints
    assert any(not law.is_default for law in laws) and config.leg.joints == laws
    design = design_from(config.leg, ((-0.6,), (0.9,)), ((0.02,), (0.03,)), config.limits)
    assert foot_joint_laws(config.leg, design)[:3] == laws


def test_the_landing_search_differentiates_a_three_rod_leg(tmp_path):
    """The inner search over whole landings maps the exact landing gradient onto its variables
    from the foot's bodies below the chain (its springs and stops too): finite differences agree."""
    from impulse_core.timedomain.landing import landing
    from optimizer.design_space import STUDY_LANDING, FootShape
    from optimizer.search.landing_inner import _Landed, build_landing_nlp, start_landing

    solo_leg(tmp_path, joint_laws=True)
    text = STUDY.replace("friction: 0.0}", "friction: 0.0, gravity: 9.81, duration: 0.02}").replace(
        "[external_norm, internal_norm]", "[peak_external_norm, peak_internal_norm]").replace(
        "method: outer, trials: 16, startup_trials: 8", "method: inner")
    nlp = build_landing_nlp(load_study(_study(tmp_path, text)), FootShape(1, 1))
    x0 = start_landing(nlp, np.random.default_rng(0))
    tree, laws, scene = _Landed(nlp).model(x0)
    nlp.step = landing(tree, scene, laws, dataclasses.replace(STUDY_LANDING, tolerance=1e-3)).step  # as a solve sets it
    g = _Landed(nlp).gradient(x0)
    fd = np.zeros_like(g)
    for j in range(nlp.n_x):
        e = np.zeros(nlp.n_x)
        e[j] = 1e-6
        fd[:, j] = (_Landed(nlp).values(x0 + e) - _Landed(nlp).values(x0 - e)) / 2e-6
    assert np.abs(g - fd).max() <= 1e-6 * np.abs(fd).max()


def test_search_columns_skip_a_chains_rods():
    """The searched entries of the design vector on a three-rod leg: the two-rod leg's, one body on."""
    from impulse_core.kinematics.spatial import PLANAR, SPATIAL
    from optimizer.design_space import search_columns

    leg, limits = Leg(), FootLimits()
    chain = _split_thigh(leg)
    for space, yaws in ((PLANAR, None), (SPATIAL, symmetric_yaws(2, 0.3))):
        design = design_from(chain, ((-0.6,), (0.9, 0.2), (1.0, 0.1)), ((0.1,), (0.1, 0.05), (0.15, 0.1)), limits,
                             toe_yaws=yaws)
        topology = foot_tree(chain, design).topology()
        two = search_columns(foot_tree(leg, design).topology(), space)
        assert search_columns(topology, space, leg_rods=3) == tuple(c + len(space.body_values) for c in two)
        assert search_columns(topology, space, leg_rods=4) is None


def test_the_inner_search_takes_a_spatial_leg_under_a_spatial_design_space_only(tmp_path, capsys):
    """The inner search takes a spatial leg (its NLP: tests/optimizer/test_inner_spatial_leg.py)
    when the design space is spatial; a planar one still refuses it in one line naming leg.file."""
    solo_leg(tmp_path, root="base_link")
    inner = SPATIAL.replace("method: outer, trials: 16, startup_trials: 8", "method: inner")
    assert load_study(_study(tmp_path, inner)).leg.spatial
    study = _study(tmp_path, inner.replace(", space: spatial, splay: [0.0, 0.6]", ""))
    with pytest.raises(ConfigError, match=r"leg.file: .*leg.yaml is a spatial leg: it needs design_space.space: "
                                          r"spatial \(either search\)"):
        load_study(study)
    assert main(["optimize", str(study), "--out", str(tmp_path / "run"), "--quiet"]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


def test_the_spatial_inner_search_hangs_splayed_toes_on_a_three_rod_leg(tmp_path, capsys, unsaved_drawings):
    """The inner search's spatial NLP on solo12's three planar rods: the foot starts after the
    leg's rods (not at body 2) and each front design re-evaluates to its recorded objectives."""
    solo_leg(tmp_path)
    study = SPATIAL.replace("method: outer, trials: 16, startup_trials: 8", "method: inner, inner: {front_points: 1, starts: 4}")
    study = study.replace("toes: [1, 2]", "toes: [2, 2]").replace("toe_segments: [1, 2]", "toe_segments: [1, 1]")
    for row, rec, path in optimized(tmp_path, study, capsys):
        for key in ("external_norm", "internal_norm"):
            assert rec[key] == pytest.approx(float(row[key]), rel=1e-9, abs=1e-15), key
        bodies = load_model_file(path).tree.bodies
        assert all(b.parent >= 2 for b in bodies[3:]) and len(bodies) == 3 + 1 + 2


def test_the_spatial_nlp_on_a_three_rod_leg_is_the_evaluated_design(tmp_path):
    """The spatial NLP's objective rows at a start point equal evaluate_design's on the design
    they make: the NLP writes the foot after the chain's three rods, turned about its foot angle."""
    import casadi as ca
    from optimizer.design_space import FootShape, Objective
    from optimizer.search.inner import _evaluate, build_nlp, start_point

    solo_leg(tmp_path)
    config = load_study(_study(tmp_path, SPATIAL.replace("method: outer, trials: 16, startup_trials: 8", "method: inner")))
    nlp = build_nlp(config, FootShape(2, 1))
    c = nlp.compiled
    x = start_point(config, nlp, np.random.default_rng(4))
    n_design = 2 * c.n_rods + c.n_lengths + 1 + c.kind.yaws
    design = ca.SX.sym("design", n_design)
    rows = np.array(ca.Function("v", [design], [ca.vertcat(*c.values(design, 2)[:2])])(x[:n_design])).ravel()
    ev = _evaluate(config, nlp, *nlp.unpack(x), nlp.toe_yaws(x))
    expected = [ev.objectives.value(Objective(k)) for k in ("external_norm", "internal_norm")]
    np.testing.assert_allclose(rows, expected, rtol=1e-10)


def test_the_spatial_landing_nlp_turns_toes_about_a_three_rod_legs_foot_angle(tmp_path):
    """The whole-landing inner search in space on solo12's three planar rods: the toe's yaw
    derivative (chained through its root's rpy about the chain's foot angle) is the central
    difference of the landed objectives."""
    import re

    from tests.optimizer.test_landing_inner_spatial import SPATIAL_LANDING_YAML

    solo_leg(tmp_path)
    config = load_study(_study(tmp_path, re.sub(r"leg:.*?\n(?=\S)", "leg: {file: leg.yaml}\n", SPATIAL_LANDING_YAML,
                                                flags=re.S)))
    tree = assert_the_yaw_derivative(config)
    assert len(tree.bodies) == 5 and tree.bodies[4].rpy != (0.0, 0.0, 0.0)


def assert_the_yaw_derivative(config: StudyConfig, nlp=None) -> Tree:
    """The whole-landing NLP of ``config``'s one-toe foot (``nlp``: that NLP, built already):
    the last design value's (the toe's yaw) exact derivative of the landed objectives against
    their central difference; returns the tree at the start. The exact derivative is the NLP's
    own (its chain rule from x to the landing's values, the landing's forward sweep, the
    objectives' signs) carried along the yaw's column alone (``landing_gradient(directions=...)``,
    as ``_Landed.gradient`` carries all n_x)."""
    from dataclasses import replace

    from impulse_core.kinematics.spatial import SPATIAL
    from impulse_core.timedomain.landing import landing
    from impulse_core.timedomain.landing_derivatives import landing_gradient
    from optimizer.design_space import STUDY_LANDING, FootShape
    from optimizer.search.landing_inner import _Landed, build_landing_nlp, landing_settings, start_landing

    nlp = build_landing_nlp(config, FootShape(1, 1)) if nlp is None else nlp
    x0 = start_landing(nlp, np.random.default_rng(0))
    landed = _Landed(nlp)
    tree, laws, scene = landed.model(x0)
    nlp.step = landing(tree, scene, laws, replace(STUDY_LANDING, tolerance=1e-2), SPATIAL).step
    yaw = np.zeros(nlp.n_x)
    yaw[-1] = 1.0
    gr = landing_gradient(tree, scene, laws, landing_settings(nlp.config), step=nlp.step, space=nlp.space,
                          directions=landed.directions(x0, tree) @ yaw[:, None])
    exact = np.array([o.sign * gr.jacobian[o.value][0] for o in landed.objectives])
    fd = (_Landed(nlp).values(x0 + 1e-6 * yaw) - _Landed(nlp).values(x0 - 1e-6 * yaw)) / 2e-6
    assert np.abs(exact).max() > 1e-4
    np.testing.assert_allclose(exact, fd, rtol=1e-5, atol=1e-9)
    return tree
