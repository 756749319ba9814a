"""Study files: the shipped studies load, the resolved form round-trips, and every bad value is
one ConfigError naming its YAML path."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from optimizer.design_space import MassMode, Objective, ToeSymmetry
from optimizer.errors import ConfigError
from optimizer.config.study_config import SamplerKind, SearchMethod, format_study, load_study, parse_study
from optimizer.config.model_file import load_yaml

REPO = Path(__file__).resolve().parents[2]
STUDIES = sorted([REPO / "configs" / "quick_study.yaml", REPO / "configs" / "landing_study.yaml",
                  REPO / "configs" / "robust_study.yaml",
                  *(REPO / "studies").glob("*/study.yaml")])


@pytest.mark.parametrize("path", STUDIES, ids=lambda p: str(p.relative_to(REPO)))
def test_shipped_studies_load_and_round_trip(path: Path, tmp_path: Path):
    config = load_study(path)
    assert config.objectives and config.search.trials >= 1
    again = tmp_path / "resolved.yaml"
    again.write_text(format_study(config, "resolved"), encoding="utf-8")
    assert load_study(again) == config


def test_quick_study_values():
    config = load_study(REPO / "configs" / "quick_study.yaml")
    assert config.name == "quick_study" and config.seed == 1 and config.storage is None
    assert config.objectives == (Objective.EXTERNAL_NORM, Objective.INTERNAL_NORM)
    assert config.space.toes == (1, 3) and config.space.toe_symmetry is ToeSymmetry.IDENTICAL
    assert config.limits.foot_mass == 0.5 and config.limits.mass_mode is MassMode.EQUAL
    assert config.limits.contact_tolerance == 1e-6  # YAML 1.2: a number, not a string


def test_defaults_and_name_from_file(tmp_path: Path):
    path = tmp_path / "my_study.yaml"
    path.write_text("objectives: [energy_after]\nsearch: {sampler: nsga2}\n", encoding="utf-8")
    config = load_study(path)
    assert config.name == "my_study"
    assert config.search.method is SearchMethod.INNER and config.search.sampler is SamplerKind.NSGA2
    assert config.objectives == (Objective.ENERGY_AFTER,)


def test_every_default_is_what_quick_study_documents():
    """configs/quick_study.yaml shows every key with its default unless a line is marked
    ``[study: ...]``: a study file with only its objectives equals it once the marked values are
    put back, and README says the same search and seed."""
    import re

    text = (REPO / "configs" / "quick_study.yaml").read_text()
    documented = load_study(REPO / "configs" / "quick_study.yaml")
    marked = {m.group(1) for m in re.finditer(r"^\s*(\w+):.*\[study:", text, re.M)}
    assert marked == {"toes", "toe_segments"}
    bare = parse_study({"name": "quick_study", "objectives": [o.value for o in documented.objectives]})
    space = replace(bare.space, toes=documented.space.toes, toe_segments=documented.space.toe_segments)
    assert replace(bare, space=space, source=documented.source) == documented
    readme = (REPO / "README.md").read_text()
    assert "`inner` (default)" in readme and documented.search.method is SearchMethod.INNER


BAD = [
    ("search:\n  trials: ten\n", "search.trials: must be an integer >= 1, got 'ten'"),
    ("search:\n  trials: 0\n", "search.trials: must be an integer >= 1, got 0"),
    ("search:\n  trials: 2.5\n", "search.trials: must be an integer >= 1, got 2.5"),
    ("search:\n  method: gradient\n", "search.method: must be one of outer, inner, got 'gradient'"),
    ("search:\n  sampler: cmaes\n", "search.sampler: must be one of tpe, nsga2"),
    ("search:\n  inner: {starts: 0}\n", "search.inner.starts: must be an integer >= 1"),
    ("search:\n  trails: 3\n", "search.trails: unknown key (did you mean 'trials'?"),
    ("scene: {speed: -1}\n", "scene.speed: must be > 0"),
    ("scene: {restitution: 1.5}\n", "scene.restitution: must be in [0, 1]"),
    ("scene: {friction: 0.3}\n", "scene.friction: the inner search optimises frictionless landings only"),
    ("scene: {friction: -1}\n", "scene.friction: must be >= 0"),
    ("scene: {gravity: -9.81}\n", "scene.gravity: must be >= 0"),
    ("scene: {duration: 0}\n", "scene.duration: must be a finite number > 0"),
    ("design_space: {joint_laws: {toe_root: {stiffness: [1, 2]}}}\n", "design_space.joint_laws: springs, dampers and stops act only over a whole landing"),
    ("leg: {shank: {stiffness: 100}}\n", "leg.shank: springs, dampers and stops act only over a whole landing"),
    ("design_space: {joint_laws: {toe_root: {stop: [0, 0.2]}}}\n", "design_space.joint_laws.toe_root.stop[0]: must be > 0"),
    ("design_space: {joint_laws: {toe_root: {damping: [2, 1]}}}\n", "design_space.joint_laws.toe_root.damping: min 2"),
    ("design_space: {joint_laws: {toe_tip: {damping: [1, 2]}}}\n", "design_space.joint_laws.toe_tip: unknown key"),
    ("search: {landing_tolerance: 0}\n", "search.landing_tolerance: must be >= 1e-12"),
    ("search: {landing_tolerance: 1.0e-300}\n", "search.landing_tolerance: must be >= 1e-12"),  # ran for ever
    ("leg: {thigh: {mass: 0}}\n", "leg.thigh.mass: must be > 0"),
    ("leg: {shank: {angle: up}}\n", "leg.shank.angle: must be a number, got 'up'"),
    ("design_space: {toes: [3, 1]}\n", "design_space.toes: min 3 is above max 1"),
    ("design_space: {toes: 3}\n", "design_space.toes: must be a list [min, max] of integers, got 3"),
    ("design_space: {toe_segments: [3, 2]}\n", "design_space.toe_segments: min 3 is above max 2"),
    ("design_space: {toe_symmetry: mirrored}\n", "design_space.toe_symmetry: must be one of identical, independent"),
    ("constraints: {foot_mass: -0.5}\n", "constraints.foot_mass: must be a finite number > 0"),
    ("constraints: {foot_mass_mode: about}\n", "constraints.foot_mass_mode: must be one of equal, at_most"),
    ("constraints: {mass_per_length: [5, 0.1]}\n", "constraints.mass_per_length: min 5.0 must be below max 0.1"),
    ("constraints: {joint_angles: {toe_root: [1, 0]}}\n", "constraints.joint_angles.toe_root: min 1.0 must be below"),
    ("constraints: {joint_angles: {ankle: [0, 1]}}\n", "constraints.joint_angles.ankle: unknown key"),
    ("constraints: {contact_tolerance: -1e-6}\n", "constraints.contact_tolerance: must be >= 0"),
    ("constraints: {min_link_mass: 0.3}\n", "constraints.min_link_mass: 2 foot rods of 0.3 kg exceed"),
    ("colour: red\n", "colour: unknown key"),
]


@pytest.mark.parametrize("text, message", BAD, ids=[m.split(":")[0] + f"-{i}" for i, (_, m) in enumerate(BAD)])
def test_bad_values_name_their_path(text: str, message: str):
    data = load_yaml("objectives: [external_norm, internal_norm]\n" + text)
    with pytest.raises(ConfigError) as info:
        parse_study(data)
    assert str(info.value).startswith(message), str(info.value)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize(
    "text, message",
    [
        ("seed: 1\n", "objectives: missing (required)"),
        ("objectives: []\n", "objectives: must be a non-empty list"),
        ("objectives: [external_norm, speed]\n", "objectives[1]: must be one of external_norm"),
        ("objectives: [external_norm, external_norm]\n", "objectives[1]: 'external_norm' is listed twice"),
        ("- 1\n", "the top level: must be a mapping"),
        ("objectives: [peak_external_norm]\n", "scene.duration: missing: the objective peak_external_norm"),
        ("objectives: [settled_at]\nscene: {duration: 0.1}\n", "search.method: the objective settled_at has no derivative"),
    ],
)
def test_bad_objectives_and_top_level(text: str, message: str):
    with pytest.raises(ConfigError) as info:
        parse_study(load_yaml(text))
    assert str(info.value).startswith(message), str(info.value)


def test_missing_and_unreadable_files(tmp_path: Path):
    with pytest.raises(ConfigError, match="file not found"):
        load_study(tmp_path / "nope.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("objectives: [external_norm\n", encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        load_study(bad)
    assert info.value.source == bad and "YAML syntax error" in str(info.value)


def test_leg_from_an_imported_model_file(tmp_path: Path):
    """``leg: {file: F}``: a two-rod planar leg from ``footopt import`` (solo12's front left
    upper and lower leg) becomes the study's thigh and shank with their own mass properties."""
    from optimizer.config.model_file import format_model_file
    from optimizer.design_space import FootDesign, Segment, foot_tree
    from optimizer.imports.leg import import_leg
    from optimizer.imports.read import read_description
    from tests.optimizer.imports.peers import robot_file

    desc = read_description(robot_file("solo_description/robots/solo12.urdf"))
    (tmp_path / "legs").mkdir()
    laws = import_leg(desc, "FL_UPPER_LEG", "FL_FOOT", com_on_rods=True)
    (tmp_path / "legs" / "solo.yaml").write_text(format_model_file(laws.model))
    study = tmp_path / "s.yaml"
    study.write_text("leg: {file: legs/solo.yaml}\nobjectives: [external_norm, internal_norm]\n")
    with pytest.raises(ConfigError, match="leg.shank: .*whole landing.*--no-joint-laws"):  # its knee's stops
        load_study(study)
    leg = import_leg(desc, "FL_UPPER_LEG", "FL_FOOT", joint_laws=False)
    (tmp_path / "legs" / "solo.yaml").write_text(format_model_file(leg.model))
    exact = load_study(study)  # its upper leg's centre of mass 0.014 mm off the rod, carried exactly
    assert (exact.leg.thigh_offset, exact.leg.shank_offset) == tuple(b.com_offset[0] for b in leg.model.tree.bodies)
    assert exact.leg.thigh_offset != 0.0 and "com_offset: [" in format_study(exact)
    again = tmp_path / "again.yaml"
    again.write_text(format_study(exact))
    assert load_study(again) == exact
    leg = import_leg(desc, "FL_UPPER_LEG", "FL_FOOT", joint_laws=False, com_on_rods=True)
    (tmp_path / "legs" / "solo.yaml").write_text(format_model_file(leg.model))
    config = load_study(study)
    thigh, shank = leg.model.tree.bodies
    assert (config.leg.thigh_length, config.leg.thigh_mass, config.leg.thigh_angle) == (thigh.length, thigh.mass, thigh.angle)
    assert (config.leg.shank_com, config.leg.shank_gyration, config.leg.knee_angle) == (shank.com, shank.gyration, shank.angle)
    tree = foot_tree(config.leg, FootDesign(heel=(Segment(0.05, 0.01, -0.5),), toes=((Segment(0.08, 0.02, 1.0),),)))
    assert tree.bodies[0].inertia == thigh.inertia and tree.bodies[1].com == shank.com
    again = tmp_path / "again.yaml"
    again.write_text(format_study(config))
    assert load_study(again) == config and "com: " in again.read_text()


def test_leg_file_is_refused_when_the_design_space_cannot_hang_a_foot_on_it(tmp_path: Path):
    """Any chain of rods is a leg (tests/optimizer/test_leg_chains.py); its joint laws need a whole
    landing, a spatial one a spatial design space."""
    from optimizer.config.model_file import format_model_file
    from optimizer.imports.leg import import_leg
    from optimizer.imports.read import read_description
    from tests.optimizer.imports.peers import robot_file

    desc = read_description(robot_file("solo_description/robots/solo12.urdf"))
    (tmp_path / "three.yaml").write_text(format_model_file(import_leg(desc, "FL_SHOULDER", "FL_FOOT", com_on_rods=True).model))
    (tmp_path / "spatial.yaml").write_text(format_model_file(import_leg(desc, "base_link", "FL_FOOT").model))
    cases = {
        "{file: three.yaml}": "leg.file: springs, dampers and stops act only over a whole landing",
        "{file: spatial.yaml}": "leg.file: .* is a spatial leg: it needs design_space.space: spatial",
        "{file: missing.yaml}": "leg.file: .*missing.yaml: file not found",
        "{file: three.yaml, thigh: {length: 1.0}}": "leg.file: give the leg as a file or as thigh and shank, not both",
        "{file: 3}": "leg.file: ",
    }
    for leg, message in cases.items():
        study = tmp_path / "s.yaml"
        study.write_text(f"leg: {leg}\nobjectives: [external_norm]\n")
        with pytest.raises(ConfigError, match=message):
            load_study(study)


def test_an_inline_leg_takes_planar_offsets_in_every_search(tmp_path: Path):
    study = tmp_path / "s.yaml"
    study.write_text("leg: {thigh: {com_offset: [0.01, 0]}}\nobjectives: [external_norm]\n")
    assert load_study(study).leg.thigh_offset == 0.01
    study.write_text("leg: {thigh: {com_offset: [0.01, 0.02]}}\nobjectives: [external_norm]\n")
    with pytest.raises(ConfigError, match=r"leg.thigh.com_offset: must be \[dy, 0\]"):
        load_study(study)
    study.write_text("leg: {shank: {com_offset: [0.01, 0]}}\nscene: {duration: 0.1}\n"
                     "objectives: [peak_external_norm]\nsearch: {method: outer}\n")
    assert load_study(study).leg.shank_offset == 0.01  # the outer search lands it
    study.write_text("leg: {shank: {com_offset: [0.01, 0]}}\nscene: {duration: 0.1}\n"
                     "objectives: [peak_external_norm, peak_internal_norm]\nsearch: {method: inner}\n")
    assert load_study(study).leg.shank_offset == 0.01  # and the inner search's landing derivatives take it
