"""The parametric foot: its tree, the length-free physics, the linear program that picks the
lengths, and the constraint values."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from impulse_core.evaluate import touchdown_geometry
from impulse_core.model.tree import JointKind, Scene
from optimizer.design_space import (
    FEASIBILITY_TOL,
    MARGIN_CAP,
    DesignSpace,
    FootDesign,
    FootLimits,
    FootShape,
    Leg,
    Segment,
    assign_lengths,
    constraint_values,
    design_from,
    evaluate_design,
    foot_geometry,
    foot_tree,
    intended_contacts,
    segment_names,
)
from optimizer.analysis.sensitivity import QUANTITIES, sensitivities

LEG = Leg()
LIMITS = FootLimits()
SCENE = Scene()
#: The paper's case-2 masses (heel 0.1 kg, toe 0.2667 + 0.1333 kg) at plausible angles.
CASE2_ANGLES = ((-0.9,), (1.2, 0.25))
CASE2_MASSES = ((0.1,), (0.2667, 0.1333))


def case2() -> FootDesign:
    return design_from(LEG, CASE2_ANGLES, CASE2_MASSES, LIMITS)


def three_toes(k: int = 2) -> FootDesign:
    angles = ((-0.8,), *[(1.0 + 0.1 * i, *[-0.2] * (k - 1)) for i in range(3)])
    masses = ((0.08,), *[(0.1, *[0.04] * (k - 1))] * 3)
    total = sum(sum(m) for m in masses)
    masses = tuple(tuple(x * 0.5 / total for x in m) for m in masses)
    return design_from(LEG, angles, masses, LIMITS)


def test_tree_structure():
    design = three_toes(k=3)
    tree = foot_tree(LEG, design)
    names = [b.name for b in tree.bodies]
    assert names[:3] == ["thigh", "shank", "heel"]
    assert names[3:6] == ["toe1_proximal", "toe1_middle", "toe1_distal"]
    assert len(names) == 2 + 1 + 3 * 3
    assert tree.bodies[0].parent is None and tree.bodies[1].parent == 0
    for chain_root in (2, 3, 6, 9):  # the heel and every toe hang from the shank's tip
        assert tree.bodies[chain_root].parent == 1 and tree.bodies[chain_root].at == 1.0
    assert all(b.joint is JointKind.REVOLUTE for b in tree.bodies[1:])
    with_contacts = [b.name for b in tree.bodies if b.contacts]
    assert with_contacts == ["heel", "toe1_distal", "toe2_distal", "toe3_distal"]
    assert intended_contacts(design) == (0, 1, 2, 3)
    assert segment_names(design.shape) == tuple(names[2:])
    assert design.shape == FootShape(3, 3, 1)
    assert math.isclose(design.foot_mass, 0.5)


def test_design_space_shapes():
    space = DesignSpace(toes=(1, 3), toe_segments=(1, 2), heel_segments=(1, 2))
    shapes = space.shapes()
    assert len(shapes) == 3 * 2 * 2 and len(set(shapes)) == len(shapes)
    assert shapes[0] == FootShape(1, 1, 1) and shapes[-1] == FootShape(3, 2, 2)


@pytest.mark.parametrize("design", [case2(), three_toes(1), three_toes(3)], ids=["case2", "3x1", "3x3"])
def test_lengths_level_every_tip(design: FootDesign):
    """The linear program's lengths put every chain tip on one ground line (to rounding), keep
    every geometric limit, and the core's own touchdown geometry agrees."""
    c = constraint_values(LEG, design, LIMITS)
    assert c.feasible, c
    tips = touchdown_geometry(foot_tree(LEG, design)).contacts[:, 1]
    assert np.ptp(tips) < 1e-12
    geo = foot_geometry(LEG, design)
    assert np.allclose(np.sort(geo.tips[:, 1] - geo.tips[:, 1].min()), 0, atol=1e-12)
    assert geo.clearance >= LIMITS.min_clearance


def test_margin_is_capped_then_shortest_foot():
    shape = FootShape(1, 2)
    a = assign_lengths(LEG, shape, CASE2_ANGLES, CASE2_MASSES, LIMITS)
    assert a is not None and math.isclose(a.margin, MARGIN_CAP, rel_tol=1e-9)
    # a tighter foot-length range that no lengths can meet gives a negative margin, not None
    tight = replace(LIMITS, foot_length=(0.39, 0.4), mass_per_length=(4.0, 5.0))
    b = assign_lengths(LEG, shape, CASE2_ANGLES, CASE2_MASSES, tight)
    assert b is not None and b.margin < 0
    assert not constraint_values(LEG, design_from(LEG, CASE2_ANGLES, CASE2_MASSES, tight), tight).feasible


def test_no_lengths_when_a_chain_rises():
    """A heel pointing up can never meet a toe pointing down on one ground line."""
    angles = ((2.5,), (1.2,))  # heel: shank angle -1.7 + 2.5 = 0.8 rad, above the horizontal
    assert assign_lengths(LEG, FootShape(1, 1), angles, ((0.2,), (0.3,)), LIMITS) is None
    design = design_from(LEG, angles, ((0.2,), (0.3,)), LIMITS)
    assert constraint_values(LEG, design, LIMITS).touchdown > 0


def test_impulses_do_not_depend_on_lengths():
    """Scaling any foot rod at fixed angles and masses leaves every objective unchanged (the
    tips then no longer touch at once: that is the geometry's business, not the impulse's)."""
    design = three_toes(k=2)
    base = evaluate_design(LEG, design, SCENE, LIMITS).objectives
    rng = np.random.default_rng(7)
    chains = [tuple(Segment(s.length * rng.uniform(0.2, 5.0), s.mass, s.joint_angle) for s in c) for c in design.chains]
    scaled = FootDesign(heel=chains[0], toes=tuple(chains[1:]))
    ev = evaluate_design(LEG, scaled, SCENE, LIMITS)
    for name in ("external_norm", "internal_norm", "max_internal", "base_angular_velocity", "energy_after"):
        assert math.isclose(getattr(ev.objectives, name), getattr(base, name), rel_tol=1e-10, abs_tol=1e-13), name
    assert ev.constraints.touchdown > 0  # but the tips are not level any more


def test_sensitivities_lengths_zero_angles_and_masses_not():
    """Exact derivatives: zero for every rod length (but the base's for its own rate)."""
    design = three_toes(k=2)
    s = sensitivities(LEG, design, SCENE)
    for q in QUANTITIES:
        d = s.of(q)
        scale = max(abs(v) for v in d.values())
        # the thigh's own rate scales as 1/length (it is the base): every other length is free
        free = [k for k in d if k.endswith(".length") and not (q == "base_angular_velocity" and k == "thigh.length")]
        assert max(abs(d[k]) for k in free) < 1e-12 * max(scale, 1.0), q
        for rod in segment_names(design.shape):
            assert abs(d[f"{rod}.mass"]) + abs(d[f"{rod}.angle"]) > 1e-6 * scale, (q, rod)
    # budget-neutral mass moves sum to zero effect when spread evenly
    assert np.allclose(s.budget_neutral_mass.sum(axis=1), 0.0, atol=1e-12)


@pytest.mark.parametrize("offsets", [False, True])
def test_sensitivities_match_finite_differences(offsets):
    """A toe angle's derivative against central differences; ``offsets``: a leg whose thigh's and
    shank's centres of mass are off the rods (their com_y are values too, and matter)."""
    leg = replace(LEG, thigh_offset=0.03, shank_offset=-0.02) if offsets else LEG
    design = case2()
    s = sensitivities(leg, design, SCENE)
    if offsets:
        assert abs(s.of("external_norm")["thigh.com_y"]) > 1e-6
    else:
        assert "thigh.com_y" not in s.names
    h = 1e-6
    chains = list(design.chains)
    toe = chains[1]
    bumped = (toe[0], Segment(toe[1].length, toe[1].mass, toe[1].joint_angle + h))
    up = evaluate_design(leg, FootDesign(heel=chains[0], toes=(bumped,)), SCENE, LIMITS).objectives
    bumped = (toe[0], Segment(toe[1].length, toe[1].mass, toe[1].joint_angle - h))
    down = evaluate_design(leg, FootDesign(heel=chains[0], toes=(bumped,)), SCENE, LIMITS).objectives
    fd = (up.external_norm - down.external_norm) / (2 * h)
    assert math.isclose(s.of("external_norm")["toe1_distal.angle"], fd, rel_tol=1e-5, abs_tol=1e-8)
    if offsets:
        up, down = (evaluate_design(replace(leg, thigh_offset=leg.thigh_offset + d), design, SCENE, LIMITS).objectives
                    for d in (h, -h))
        fd = (up.external_norm - down.external_norm) / (2 * h)
        assert math.isclose(s.of("external_norm")["thigh.com_y"], fd, rel_tol=1e-5, abs_tol=1e-8)


def test_constraint_values_name_each_violation():
    design = case2()
    ok = evaluate_design(LEG, design, SCENE, LIMITS)
    assert ok.feasible and ok.constraints.pulling < 0 and ok.constraints.energy_gain < 0
    heavy = replace(LIMITS, foot_mass=0.4)
    assert constraint_values(LEG, design, heavy).foot_mass == pytest.approx(0.1)
    narrow = replace(LIMITS, toe_root=(0.0, 1.0))
    assert constraint_values(LEG, design, narrow).joint_angles == pytest.approx(0.2)
    light = replace(LIMITS, min_link_mass=0.2)
    assert constraint_values(LEG, design, light).min_link_mass == pytest.approx(0.1)
    violated = dict(constraint_values(LEG, design, narrow).violations())
    assert violated["joint_angles"] > 0 and violated["foot_mass"] == 0.0
    assert all(v <= FEASIBILITY_TOL for _, v in ok.constraints.items())


def test_design_validation():
    with pytest.raises(ValueError):
        FootDesign(heel=(), toes=((Segment(0.1, 0.1, 0.0),),))
    with pytest.raises(ValueError):
        FootDesign(heel=(Segment(0.1, 0.1, 0.0),), toes=((Segment(0.1, 0.1, 0.0),), ()))
    with pytest.raises(ValueError):
        FootShape(0, 1)
    with pytest.raises(ValueError):
        FootShape(1, 1, 0)
    names = segment_names(FootShape(1, 5))  # any number of rods: proximal, middle1..3, distal
    assert names == ("heel", "toe1_proximal", "toe1_middle1", "toe1_middle2", "toe1_middle3", "toe1_distal")


def test_a_contact_newton_would_make_pull_is_infeasible():
    """Heel nearly under the ankle, toe far forward: Newton's law (eq. 11) asks the toe to pull
    (-0.16 N s); the core would let it separate, the design space calls the foot infeasible."""
    limits = replace(LIMITS, heel_root=(-2.0, 0.5), toe_root=(-1.5, 2.0), toe_inner=(-2.0, 2.0))
    angles = ((0.11854166118435128,), (0.22294454682199882, 0.039644135306503125))
    masses = ((0.21688029047050744,), (0.21119373701593872, 0.1994754246107062))
    design = design_from(LEG, angles, masses, limits)
    ev = evaluate_design(LEG, design, SCENE, limits)
    assert ev.constraints.pulling == pytest.approx(0.1622, abs=1e-3)
    assert ev.constraints.touchdown <= 0 and not ev.feasible
