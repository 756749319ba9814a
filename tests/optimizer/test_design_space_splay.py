"""The splayed-toe (spatial) design space: the model files it builds carry the parameters (each
toe's yaw about the vertical, contacts where a hand computation puts them), a splay of zero is
the planar foot, and ``constraints.support_margin`` marks a trial infeasible exactly when the
built model's support margin (``impulse_core.model.support``) is below the bound."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import optuna
import pytest

from impulse_core.evaluate import evaluate, touchdown_geometry
from impulse_core.kinematics.spatial import SPATIAL
from impulse_core.model.support import support_margin
from impulse_core.model.tree import Scene
from optimizer.config.model_file import dump_model_file, load_model_file
from optimizer.config.study_config import parse_study
from optimizer.design_space import (
    FEASIBILITY_TOL,
    FootLimits,
    Leg,
    SupportConstraintValues,
    constraint_values,
    design_from,
    design_model,
    evaluate_design,
    foot_tree,
    symmetric_yaws,
)
from optimizer.errors import ConfigError
from optimizer.evaluation.scenarios import Distribution, DistributionKind
from optimizer.search.inner import run_inner
from optimizer.search.outer import design_from_record, design_record, open_study, read_trial, run_outer

LIMITS = FootLimits()


def random_design(rng: np.random.Generator, n_toes: int, k: int, yaws: tuple[float, ...] | None):
    """A design of ``n_toes`` toes of ``k`` rods (one-rod heel) with angles inside the default
    limits that put the toes forward and down, masses summing to the budget."""
    heel = (float(rng.uniform(-1.0, -0.4)),)
    toe = tuple([float(rng.uniform(0.8, 1.4))] + [float(rng.uniform(-0.3, 0.3)) for _ in range(k - 1)])
    angles = (heel, *([toe] * n_toes))
    shares = rng.uniform(0.2, 1.0, 1 + n_toes * k)
    shares = 0.5 * shares / shares.sum()
    masses, i = [], 0
    for chain in angles:
        masses.append(tuple(float(x) for x in shares[i : i + len(chain)]))
        i += len(chain)
    return design_from(Leg(), angles, tuple(masses), LIMITS, toe_yaws=yaws)


def rz(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rpy_matrix(rpy) -> np.ndarray:
    a, b, c = rpy
    rx = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    ry = np.array([[math.cos(b), 0, math.sin(b)], [0, 1, 0], [-math.sin(b), 0, math.cos(b)]])
    return rz(c) @ ry @ rx


@pytest.mark.parametrize("seed", range(6))
def test_model_file_carries_the_yaws_and_the_contacts(seed: int, tmp_path: Path):
    """Written and read back: each toe root's joint axis is the world's z turned by its yaw about
    +y ((sin psi, 0, cos psi)); the toe yaws spread evenly from -s to +s; every contact sits where
    the planar chain's point (x, y), turned by psi, puts it: (x cos psi, y, -x sin psi) from the ankle."""
    rng = np.random.default_rng(seed)
    n, k = int(rng.integers(2, 5)), int(rng.integers(1, 4))
    s = float(rng.uniform(0.05, 0.9))
    hand_yaws = [-s + 2 * s * i / (n - 1) for i in range(n)]
    design = random_design(rng, n, k, symmetric_yaws(n, s))
    assert np.allclose(design.toe_yaws, hand_yaws, atol=1e-15)
    assert design.toe_yaws[0] < 0 < design.toe_yaws[-1]
    leg = Leg()
    path = tmp_path / "foot.yaml"
    dump_model_file(design_model(leg, design, Scene(), LIMITS), path)
    model = load_model_file(path)
    assert model.space is SPATIAL
    bodies = {b.name: b for b in model.tree.bodies}
    shank = leg.thigh_angle + leg.knee_angle
    for i, psi in enumerate(design.toe_yaws):
        root = bodies[f"toe{i + 1}" if k == 1 else f"toe{i + 1}_proximal"]
        axis = rz(shank) @ rpy_matrix(root.rpy) @ np.array([0.0, 0.0, 1.0])
        assert np.allclose(axis, [math.sin(psi), 0.0, math.cos(psi)], atol=1e-12), (i, psi, axis)
    assert bodies["heel"].rpy == (0.0, 0.0, 0.0)
    # contacts by hand: the shank's tip (ankle), then each chain in its turned plane
    ankle = np.array([leg.thigh_length * math.cos(leg.thigh_angle) + leg.shank_length * math.cos(shank),
                      leg.thigh_length * math.sin(leg.thigh_angle) + leg.shank_length * math.sin(shank), 0.0])
    expected = []
    for chain, psi in zip(design.chains, (0.0, *design.toe_yaws), strict=True):
        phi, x, y = shank, 0.0, 0.0
        for seg in chain:
            phi += seg.joint_angle
            x += seg.length * math.cos(phi)
            y += seg.length * math.sin(phi)
        expected.append(ankle + [x * math.cos(psi), y, -x * math.sin(psi)])
    g = touchdown_geometry(model.tree, SPATIAL)
    assert np.allclose(g.contacts, np.array(expected), atol=1e-12)
    # toe 1 (yaw -s) on the +z side, toe n (yaw +s) on the -z side, the middle toe (odd n) on z = 0
    z = g.contacts[1:, 2]
    assert z[0] > 0 > z[-1] and np.all(np.sign(z) == -np.sign(np.round(design.toe_yaws, 12)))
    # every tip at one height (the length program levels them), reaches forward by cos(psi)
    assert np.ptp(g.contacts[:, 1]) < 1e-9


@pytest.mark.parametrize("seed", range(3))
def test_per_toe_yaws_and_zero_splay_is_the_planar_foot(seed: int):
    rng = np.random.default_rng(100 + seed)
    n, k = int(rng.integers(1, 4)), int(rng.integers(1, 3))
    planar = random_design(np.random.default_rng(seed), n, k, None)
    flat = random_design(np.random.default_rng(seed), n, k, (0.0,) * n)
    a = evaluate_design(Leg(), planar, Scene(), LIMITS)
    b = evaluate_design(Leg(), flat, Scene(), LIMITS)
    assert np.allclose(np.array(a.objectives.items())[:, 1].astype(float),
                       np.array(b.objectives.items())[:, 1].astype(float), rtol=1e-9)
    yaws = tuple(float(y) for y in rng.uniform(-0.7, 0.7, n))
    design = random_design(np.random.default_rng(seed), n, k, yaws)
    assert design_from_record(design_record(design)) == design
    assert "toe_yaws" not in design_record(planar) and design_from_record(design_record(planar)) == planar
    tree = foot_tree(Leg(), design)
    g = touchdown_geometry(tree, SPATIAL)
    ankle_x = g.tips[1, 0]
    for i, psi in enumerate(yaws):  # the tip's bearing from the ankle, seen from above, is its yaw
        d = g.contacts[1 + i] - g.tips[1]
        assert math.isclose(math.atan2(-d[2], d[0]), psi, abs_tol=1e-12), (i, psi)
    assert ankle_x == g.tips[1, 0]


def study(trials: int = 16, margin: float = 0.01, **space) -> dict:
    return {
        "name": "splay", "seed": 5,
        "design_space": {"toes": [1, 3], "toe_segments": [1, 2], "space": "spatial", "splay": [0.0, 0.8], **space},
        "constraints": {"support_margin": margin},
        "objectives": ["external_norm", "internal_norm"],
        "search": {"method": "outer", "trials": trials, "startup_trials": trials},
    }


def built_margin(design) -> float:
    """The support margin of the design's model file, computed from the file's tree alone."""
    model = design_model(Leg(), design, Scene(), LIMITS)
    g = touchdown_geometry(model.tree, model.space)
    masses = np.array([b.mass for b in model.tree.bodies])
    com = masses @ g.coms / masses.sum()
    return support_margin(g.contacts[:, [0, 2]], com[[0, 2]])


@pytest.mark.parametrize("mode", ["symmetric", "per_toe"])
def test_support_margin_constraint_marks_trials_infeasible_exactly_below_the_bound(mode: str):
    bound = 0.01
    config = parse_study(study(24, bound, splay_mode=mode, splay=[0.0, 0.8] if mode == "symmetric" else [-0.8, 0.8]))
    storage = optuna.storages.InMemoryStorage()
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    s = open_study(config, storage)
    run_outer(s, config, 24)
    below = above = 0
    for t in s.get_trials(deepcopy=False):
        r = read_trial(t)
        if r is None:
            continue
        ev = r.evaluation
        assert isinstance(ev.constraints, SupportConstraintValues)
        margin = built_margin(ev.design)
        assert math.isclose(ev.constraints.support_margin, bound - margin, abs_tol=1e-12)
        violations = t.constraints  # what the sampler sees (Optuna's trial constraints)
        assert set(violations) == {n for n, _ in ev.constraints.items()}
        if margin < bound - FEASIBILITY_TOL:
            below += 1
            assert violations["support_margin"] > 0 and not ev.feasible
        else:
            above += 1
            assert violations["support_margin"] == 0
        if ev.design.shape.n_toes == 1:  # heel and one toe: on one line, margin <= 0
            assert margin <= 1e-12
    assert below and above  # both sides of the bound were met


def test_constraint_values_follow_the_bound():
    rng = np.random.default_rng(7)
    design = random_design(rng, 3, 2, symmetric_yaws(3, 0.5))
    m = built_margin(design)
    assert m > 0
    for bound, feasible in ((m - 1e-4, True), (m + 1e-4, False)):
        values = constraint_values(Leg(), design, FootLimits(support_margin=bound))
        assert (values.support_margin <= FEASIBILITY_TOL) is feasible
    assert not hasattr(constraint_values(Leg(), design, LIMITS), "support_margin")


def test_inner_search_takes_a_spatial_design_space_over_level_landings():
    """The spatial inner search scores level first impacts whose approach varies
    (tests/optimizer/test_inner_splay_robust.py); what changes which contacts hit (a roll) is
    refused naming the field, and over whole landings so is a roll (the tree), by the study file
    and by :func:`run_inner` alike."""
    level = {"count": 4, "speed": [3.0, 3.5], "velocity_z": [-0.2, 0.2], "roll_rate": [-0.5, 0.5]}
    config = parse_study({**study(), "search": {"method": "inner"}, "landings": level})
    assert config.landings is not None and config.landings.names == ("speed", "roll_rate", "velocity_z")
    with pytest.raises(ConfigError, match=r"^landings\.roll: the inner search varies"):
        parse_study({**study(), "search": {"method": "inner"}, "landings": {**level, "roll": [0.0, 0.1]}})
    whole = {**study(), "objectives": ["peak_external_norm"], "scene": {"duration": 0.05}, "landings": level}
    inner = {**whole, "search": {"method": "inner"}}
    assert parse_study(inner).landings.names == ("speed", "roll_rate", "velocity_z")  # taken
    with pytest.raises(ConfigError, match=r"^landings\.roll: the inner search over whole landings varies"):
        parse_study({**inner, "landings": {**level, "roll": [0.0, 0.1]}})
    config = parse_study(whole)  # the outer search's study, handed to the inner search
    rolled = replace(config.landings, distributions=(*config.landings.distributions,
                                                     ("roll", Distribution(DistributionKind.UNIFORM, (0.0, 0.1)))))
    config = replace(config, landings=rolled)
    with pytest.raises(ConfigError, match=r"^landings\.roll: the inner search over whole landings varies"):
        run_inner(open_study(config, optuna.storages.InMemoryStorage()), config)
