"""The paper's three feet (configs/paper_case{1,2,3}.yaml) against the paper's printed tables.

Golden values: Kim & Yi, "Analysis of Multi-Chained and Multiple Contact Characteristics of Foot
Mechanisms in Aspect of Impulse Absorption" (notes: docs/ERRATA.md), section 6.1:
Table 2 and Table 3 (case 1, flat foot), Table 5 and Table 6 (case 2, one two-link toe),
Table 8 and Table 9 (case 3, three two-link toes), mapped to the files' order as
studies/paper_reproduction/README.md explains. Table 5's "0.602" is read 0.2602 (its norm says so).

The touchdown angles were fitted to these tables (studies/paper_reproduction/fit_paper_cases.py):
the fit reproduces the ratios between the entries to rounding, and with the printed inputs
(3.43 m/s, e = 0.8) every impulse sits one common factor (~1/1.037) below the tables, because the
printed inputs and tables disagree (docs/ERRATA.md). Case 1 is not reproduced by any
reading of the lost figure; its test asserts only the measured gap.

The files are read with plain ``yaml.safe_load`` and built with ``impulse_core.model.tree`` directly,
so this test does not depend on the model-file loader.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from impulse_core.evaluate import evaluate, touchdown_geometry
from impulse_core.model.tree import Body, ContactSelection, JointKind, Scene, Tree

CONFIGS = Path(__file__).resolve().parents[1] / "configs"

# Paper tables, in the files' order: external per contact (declaration order), internal per
# non-base body (file order); None where the paper prints "-".
TABLES = {
    # Table 5: 1F_I heel, 2F_I toe (printed 0.602: dropped digit). Table 6: F1 toe root,
    # F2 middle toe joint, F3 heel joint, F4 knee -> ours (shank, heel, toe_proximal, toe_distal).
    "paper_case2.yaml": {
        "external": [0.2806, 0.2602],
        "internal": [0.0484, 0.1668, 0.0818, 0.0937],
        "external_norm": 0.3827,
        "internal_norm": 0.2136,
    },
    # Table 8: heel, toe 1-3. Table 9: F1/F3/F5 middle toe joints, F2/F4/F6 toe roots, F7 heel
    # joint, F8 knee -> ours (shank, heel, toe1_proximal, toe1_distal, ..., toe3_distal).
    "paper_case3.yaml": {
        "external": [0.2823, 0.0867, 0.0867, 0.0867],
        "internal": [0.0485, 0.1677, 0.0274, 0.0312, 0.0274, 0.0312, 0.0274, 0.0312],
        "external_norm": 0.3198,
        "internal_norm": 0.1888,
    },
    # Table 2: 1F_I (heel), 2F_I (toe). Table 3: F1 "-", F2 (heel joint = ankle), F3 (knee)
    # -> ours (shank = knee, heel = ankle, toe = weld inside the one-piece sole).
    "paper_case1.yaml": {
        "external": [2.9507, 1.9206],
        "internal": [0.4002, 1.1587, None],
        "external_norm": 3.5207,
        "internal_norm": 1.2259,
    },
}

#: Cases 2 and 3: measured worst |ours / paper - 1| with the printed inputs is 3.6 %; rounded up.
REPRODUCED_TOL = 0.04
#: Cases 2 and 3: ours / paper is one common factor for every entry; measured spread (max / min
#: - 1) 0.15 % (case 2) and 0.12 % (case 3), the size of the tables' four-decimal rounding.
COMMON_FACTOR_SPREAD = 0.0025
COMMON_FACTOR_RANGE = (1.03, 1.04)  # table / ours (ERRATA: about 1.037)
#: Case 1 (NOT reproduced): the measured gap per entry of the closest reading, rounded up.
CASE1_GAP = {"external": [0.05, 0.05], "internal": [0.23, 0.79, None]}

BODY_KEYS = {"name", "parent", "at", "length", "mass", "angle", "joint", "contacts", "com", "inertia"}
SCENE_KEYS = {"speed", "restitution", "friction", "contacts"}
GROUND_TOL = 1e-9


def load(name: str) -> tuple[dict, Tree, Scene]:
    data = yaml.safe_load((CONFIGS / name).read_text())
    bodies = data["model"]["bodies"]
    index = {b["name"]: i for i, b in enumerate(bodies)}
    for b in bodies:  # uniform rods only: the files carry no com / inertia
        assert "com" not in b and "inertia" not in b
    tree = Tree(
        tuple(
            Body(
                name=b["name"],
                parent=index[b["parent"]] if "parent" in b else None,
                length=float(b["length"]),
                mass=float(b["mass"]),
                angle=float(b.get("angle", 0.0)),
                at=float(b.get("at", 1.0)),
                joint=JointKind(b.get("joint", "revolute")),
                contacts=tuple(float(c) for c in b.get("contacts", ())),
            )
            for b in bodies
        )
    )
    s = data["scene"]
    scene = Scene(
        speed=float(s["speed"]),
        restitution=float(s["restitution"]),
        friction=float(s.get("friction", 0.0)),
        selection=ContactSelection.ALL if s.get("contacts") == "all" else ContactSelection.LOWEST,
    )
    return data, tree, scene


def ratios(name: str) -> tuple[np.ndarray, object]:
    """ours / paper for every printed entry (external then internal), and the result."""
    _, tree, scene = load(name)
    res = evaluate(tree, scene)
    table = TABLES[name]
    ours = np.r_[res.external, res.internal_magnitude]
    paper = table["external"] + table["internal"]
    return np.array([o / p for o, p in zip(ours, paper) if p is not None]), res


@pytest.mark.parametrize("name", sorted(TABLES))
def test_file_follows_the_format_and_the_paper_inputs(name):
    data, tree, scene = load(name)
    assert set(data) <= {"scene", "model", "reference", "notes"}
    assert set(data["scene"]) <= SCENE_KEYS
    for b in data["model"]["bodies"]:
        assert set(b) <= BODY_KEYS, b["name"]
    # the paper's landing, with the printed inputs (the ~1.037 factor is not folded in)
    assert (scene.speed, scene.restitution, scene.friction) == (3.43, 0.8, 0.0)
    assert data["scene"]["contacts"] == "all"
    assert isinstance(data["notes"], str) and data["notes"].strip()


@pytest.mark.parametrize("name", sorted(TABLES))
def test_reference_block_holds_the_paper_values(name):
    data, tree, _ = load(name)
    ref, table = data["reference"], TABLES[name]
    assert ref["external"] == table["external"]
    assert ref["internal"] == table["internal"]
    assert ref["external_norm"] == table["external_norm"]
    assert ref["internal_norm"] == table["internal_norm"]
    assert len(ref["external"]) == len(tree.contacts)
    assert len(ref["internal"]) == tree.n_bodies - 1
    assert "Table" in ref["source"] and ref["note"]


@pytest.mark.parametrize("name", ["paper_case2.yaml", "paper_case3.yaml"])
def test_articulated_feet_reproduce_every_printed_entry(name):
    r, res = ratios(name)
    assert np.all(np.abs(r - 1) <= REPRODUCED_TOL), r - 1
    table = TABLES[name]
    assert res.external_norm == pytest.approx(table["external_norm"], rel=REPRODUCED_TOL)
    assert res.internal_norm == pytest.approx(table["internal_norm"], rel=REPRODUCED_TOL)
    assert res.split_unique and not res.pulling


@pytest.mark.parametrize("name", ["paper_case2.yaml", "paper_case3.yaml"])
def test_articulated_feet_differ_from_the_tables_by_one_common_factor(name):
    r, _ = ratios(name)
    assert r.max() / r.min() - 1 <= COMMON_FACTOR_SPREAD
    lo, hi = COMMON_FACTOR_RANGE
    assert lo <= 1 / np.exp(np.mean(np.log(r))) <= hi


def test_case3_identical_toes_share_the_impulse_equally():
    _, tree, scene = load("paper_case3.yaml")
    res = evaluate(tree, scene)
    toes = res.external[1:]
    assert np.allclose(toes, toes[0], rtol=1e-12, atol=0)
    joints = res.internal_magnitude[2:].reshape(3, 2)  # (proximal, distal) per toe
    assert np.allclose(joints, joints[0], rtol=1e-12, atol=0)


def test_case3_equals_one_toe_of_three_times_the_mass_split_in_three():
    """Symmetry law: three identical toes in one plane move as one toe of the summed mass, each
    taking a third of its impulses. (Cases 2 and 3 were fitted separately and their postures
    differ slightly, so this is checked at case 3's angles, not against case 2's file.)"""
    _, tree, scene = load("paper_case3.yaml")
    b = tree.bodies
    merged = Tree(
        (
            *b[:3],
            Body("toe_proximal", 1, b[3].length, 3 * b[3].mass, b[3].angle, b[3].at, b[3].joint),
            Body("toe_distal", 3, b[4].length, 3 * b[4].mass, b[4].angle, b[4].at, b[4].joint, b[4].contacts),
        )
    )
    three, one = evaluate(tree, scene), evaluate(merged, scene)
    assert three.external[0] == pytest.approx(one.external[0], rel=1e-9)
    assert three.external[1:] == pytest.approx([one.external[1] / 3] * 3, rel=1e-9)
    assert three.internal_magnitude[:2] == pytest.approx(one.internal_magnitude[:2], rel=1e-9)
    assert three.internal_magnitude[2:] == pytest.approx(list(one.internal_magnitude[2:] / 3) * 3, rel=1e-9)


@pytest.mark.parametrize("name", sorted(TABLES))
def test_contacts_are_level_and_nothing_is_below_the_ground(name):
    _, tree, _ = load(name)
    g = touchdown_geometry(tree)
    heights = g.contacts[:, 1]
    assert heights.max() - heights.min() <= GROUND_TOL
    ground = heights.min()
    assert np.all(g.origins[:, 1] >= ground - GROUND_TOL)
    assert np.all(g.tips[:, 1] >= ground - GROUND_TOL)


@pytest.mark.parametrize("name", ["paper_case2.yaml", "paper_case3.yaml"])
def test_articulated_postures_are_plausible(name):
    """Thigh and shank point down, the knee is bent, the heel points back, the toes forward."""
    _, tree, _ = load(name)
    g = touchdown_geometry(tree)
    d = g.tips - g.origins
    names = [b.name for b in tree.bodies]
    absolute = {n: math.atan2(v[1], v[0]) for n, v in zip(names, d)}
    assert d[0, 1] < 0 and d[1, 1] < 0  # thigh, shank downwards
    assert abs(tree.bodies[1].angle) > 0.2  # knee bent (> 11 deg)
    assert d[2, 0] < 0 and d[2, 1] < 0  # heel back and down
    for n in names[3:]:
        assert abs(absolute[n]) < math.pi / 2, n  # toes forward


def test_case1_is_not_reproduced_and_the_gap_is_as_documented():
    data, _, _ = load("paper_case1.yaml")
    assert "NOT REPRODUCED" in data["reference"]["note"]
    _, tree, scene = load("paper_case1.yaml")
    res = evaluate(tree, scene)
    table = TABLES["paper_case1.yaml"]
    for ours, paper, gap in zip(res.external, table["external"], CASE1_GAP["external"]):
        assert abs(ours / paper - 1) <= gap
    worst = 0.0
    for ours, paper, gap in zip(res.internal_magnitude, table["internal"], CASE1_GAP["internal"]):
        if paper is None:
            continue
        assert abs(ours / paper - 1) <= gap
        worst = max(worst, abs(ours / paper - 1))
    assert worst > 0.5  # the ankle: the documented failure to reproduce Table 3
