"""``studies/whole_landing/settled_posture.py --spatial``: a random spatial leg, its MuJoCo model
read back at touchdown as footopt's angles, the frame-free posture gap, and one quick
frictionless leg settling where MuJoCo's does."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from impulse_core.kinematics.spatial import SPATIAL
from impulse_core.timedomain.compliant import chart_rotation
from tests.studies.scripts import study_module


def _module():
    return study_module("settled_posture")


def test_a_spatial_leg_and_its_mujoco_model_read_at_touchdown_as_footopt() -> None:
    """Seed 3: a base with its welded cross (three contacts) on 3-4 sprung chains whose tips are
    the other contacts, every joint sprung and damped; MuJoCo's model (the export's free base)
    at its touchdown state reads as footopt's touchdown: no turn, the touchdown joint angles."""
    mujoco = pytest.importorskip("mujoco")
    sp = _module()
    tree, laws, scene = sp.random_spatial_leg(3)
    chains = [b for b in tree.bodies if b.parent == 0 and b.name.startswith("chain")]
    assert 3 <= len(chains) <= 4 and len(tree.contacts) == 3 + len(chains)
    assert all(law.stiffness > 0 and law.damping > 0 for law in laws[2:])
    mj = sp.StudyMujoco(SimpleNamespace(tree=tree, scene=scene, joints=laws), space=SPATIAL)
    d = mujoco.MjData(mj.m)
    mujoco.mj_forward(mj.m, d)
    touchdown = np.concatenate([np.zeros(3), [b.angle for b in tree.bodies[1:]]])
    np.testing.assert_allclose(mj.angles(d), touchdown, atol=1e-12)


def test_the_posture_gap_is_the_relative_turn_whatever_the_frame() -> None:
    """Two orientations a known turn apart (0.01 rad about a tilted axis of the first's frame),
    both turned alike by a large rotation: the base's gap is 0.01 rad, its tilt the part of it
    about axes off the vertical (as the first base sees the vertical)."""
    sp = _module()
    axis = np.array([1.0, 2.0, 0.5]) / np.linalg.norm([1.0, 2.0, 0.5])
    common = np.asarray(chart_rotation(np.array([0.4, -1.1, 0.7])))
    a = sp._rotation_vector(common)
    b = sp._rotation_vector(common @ np.asarray(chart_rotation(0.01 * axis)))
    ours, theirs = np.r_[a, 0.3, -0.2], np.r_[b, 0.3, -0.2 + 1e-4]
    base, tilt, joints = sp.posture_gaps(ours, theirs, SPATIAL)
    assert base == pytest.approx(0.01, rel=1e-9) and joints == pytest.approx(1e-4, rel=1e-9)
    up = common.T @ np.array([0.0, 1.0, 0.0])
    assert tilt == pytest.approx(0.01 * np.linalg.norm(np.cross(axis, up)), rel=1e-3)


def test_a_frictionless_spatial_leg_settles_where_mujoco_does() -> None:
    """Seed 3 (frictionless, 76 events, settled at 2.1 s): footopt's joint angles and base tilt
    within 2e-3 rad of MuJoCo's (measured 6.6e-6 and 8.1e-6; the turn about the vertical, which
    no statics sets, 2.5e-4), and both final states rests of footopt's statics (residuals over
    the weight measured 3e-8 and 7e-7 m)."""
    pytest.importorskip("mujoco")
    row = _module().compare(3, False, spatial=True)
    assert row["friction"] == 0 and row["settled_at"] is not None
    assert row["joints"][0] < 2e-3 and row["tilt"][0] < 2e-3 and row["base"][0] < 2e-3
    assert row["statics_ours"] < 1e-6 and row["statics_theirs"] < 1e-5
