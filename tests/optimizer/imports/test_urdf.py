"""footopt import on real URDFs (example-robot-data), checked against Pinocchio's own parse of the
same file: masses, the joints' placement and axes and the ankle exactly; the impulse at the
ankle against pinocchio.impulseDynamics on the same chain (planar: on a planar joint; spatial: on
a free-flyer): planar legs' approximation (centre of mass on the rod, inertia about it) measured,
spatial legs exact (each link's centre of mass and tensor carried)."""

from __future__ import annotations

import numpy as np
import pytest

from impulse_core.kinematics.spatial import PLANAR, SPATIAL
from optimizer.imports.leg import TO_FOOTOPT, import_leg
from optimizer.imports.read import read_description
from tests.optimizer.imports.peers import footopt_impulse, footopt_joint_mass_matrix, reference, robot_file
from tests.optimizer.imports.peers import planar_ankle
from tests.optimizer.imports.peers import spatial_world as _world

SOLO = "solo_description/robots/solo12.urdf"
GO1 = "go1_description/urdf/go1.urdf"
# (file, root, ankle, rods, space, |impulse / Pinocchio's - 1| at most, measured)
LEGS = [
    # planar: each link's centre of mass in the plane (com, com_offset) and inertia about the joint axis
    # exactly (before com_offset, with the centre of mass moved onto the rod: 4.7e-8, 1.8e-8)
    (SOLO, "FL_UPPER_LEG", "FL_FOOT", 2, PLANAR, 1e-12),  # HFE -> KFE: parallel axes
    (SOLO, "FL_SHOULDER", "FL_FOOT", 3, PLANAR, 1e-12),  # the shoulder as base
    (GO1, "FL_hip", "FL_foot", 3, PLANAR, 1e-12),  # the thigh's and calf's centres of mass 3.05 and 4.3 mm off
    # spatial: each link's exact centre of mass (com_offset) and tensor (inertia_tensor); measured
    # 2.9e-15, 1.6e-15, 2.4e-15, 8.9e-16 (before com_offset and inertia_tensor: +22 %, -7.8 %, +12 %, +9.9 %)
    (SOLO, "base_link", "FL_FOOT", 4, SPATIAL, 1e-12),  # HAA too (the shoulder's com 79 mm off its rod)
    ("anymal_c_simple_description/urdf/anymal.urdf", "base", "LF_FOOT", 4, SPATIAL, 1e-12),
    (GO1, "trunk", "FL_foot", 4, SPATIAL, 1e-12),  # the hip's rod starts 22 mm along HAA
    ("a1_description/urdf/a1.urdf", "trunk", "FL_foot", 4, SPATIAL, 1e-12),
]


@pytest.mark.parametrize("robot, root, ankle, rods, space, bound", LEGS, ids=[f"{r.split('/')[0]}:{a}" for r, a, *_ in LEGS])
def test_real_leg_against_pinocchio(robot, root, ankle, rods, space, bound):
    path = robot_file(robot)
    leg = import_leg(read_description(path), root, ankle, joint_laws=False)  # Go1's, A1's knee stops exclude 0
    assert leg.space is space and leg.model.tree.n_bodies == rods
    ref = reference(path, root, ankle, planar_basis=TO_FOOTOPT if space is PLANAR else None)
    # masses: every link of the chain, fixed joints merged (Pinocchio merges them on its own)
    masses = [i.mass for i in ref.model.inertias[1:]]
    assert [b.mass for b in leg.model.tree.bodies] == pytest.approx(masses, rel=1e-14)
    # the ankle and the joints, from the model file's rods, in the description's frame
    if space is SPATIAL:
        joints, foot = _world(leg)
        np.testing.assert_allclose(foot, ref.ankle(), atol=1e-12)
        for (anchor, axis), (ref_anchor, ref_axis), rod in zip(joints, ref.joints(), leg.rods[1:], strict=True):
            # a rod may start anywhere on its joint's axis (the same motion): slid by rod.slide along it
            np.testing.assert_allclose(np.cross(anchor - ref_anchor, ref_axis), 0.0, atol=1e-12)
            assert np.linalg.norm(anchor - ref_anchor) == pytest.approx(rod.slide, abs=1e-12)
            np.testing.assert_allclose(axis, ref_axis, atol=1e-12)
    else:
        np.testing.assert_allclose(leg.segments[-1].tip, ref.ankle(), atol=1e-12)
        for s, (ref_anchor, ref_axis) in zip(leg.segments[1:], ref.joints(), strict=True):
            np.testing.assert_allclose(s.start, ref_anchor, atol=1e-12)
            np.testing.assert_allclose(s.axis, ref_axis, atol=1e-12)
        # the planar rods: lengths and angles are the joints' in-plane distances and directions
        np.testing.assert_allclose(planar_ankle(leg), TO_FOOTOPT[:2] @ ref.ankle(), atol=1e-12)
    # the impact: footopt's answer on the file against Pinocchio's on the source's chain
    ours, theirs = footopt_impulse(leg), ref.impulse()
    assert abs(ours / theirs - 1) <= bound, (ours, theirs)
    # the joints' mass matrix block (the planar angles as the description counts them)
    s = np.array([-1.0 if r.flipped else 1.0 for r in leg.rods[1:]])
    M, M_ref = footopt_joint_mass_matrix(leg) * np.outer(s, s), ref.joint_mass_matrix()
    assert np.abs(M - M_ref).max() / np.abs(M_ref).max() <= 1e-12
    if space is SPATIAL:  # the summary no longer lists approximations
        assert "moved onto it" not in leg.summary() and "not carried" not in leg.summary()


def test_solo_planar_leg_is_the_exact_rods_where_the_offsets_vanish():
    """solo12's lower leg carries its centre of mass on the knee-foot line (the upper leg 0.014 mm
    off it): the lower leg's rod is exact, so its impulse alone (root at the knee) is Pinocchio's."""
    path = robot_file(SOLO)
    leg = import_leg(read_description(path), "FL_UPPER_LEG", "FL_FOOT")
    assert leg.rods[1].com_offset == 0.0 and leg.rods[0].com_offset == pytest.approx(1.377e-5, rel=1e-3)
    assert leg.rods[1].merged == ("FL_LOWER_LEG", "FL_FOOT")


def _pose(ref, angles: dict[str, float]) -> None:
    for name, value in angles.items():
        ref.q[ref.model.joints[ref.model.getJointId(name)].idx_q] = value


@pytest.mark.parametrize(
    "robot, root, ankle, angles, space, bound",
    [
        # bent: exact (with the centre of mass moved onto the rod, --com-on-rods: 1.5e-6, 2e-7)
        (SOLO, "FL_UPPER_LEG", "FL_FOOT", {"FL_KFE": -1.3}, PLANAR, 1e-12),
        (SOLO, "FL_SHOULDER", "FL_FOOT", {"FL_HFE": 0.5, "FL_KFE": -1.3}, PLANAR, 1e-12),
        (GO1, "FL_hip", "FL_foot", {"FL_thigh_joint": 0.8, "FL_calf_joint": -1.5}, PLANAR, 1e-12),
        ("go1_description/urdf/go1.urdf", "trunk", "FL_foot",
         {"FL_hip_joint": 0.15, "FL_thigh_joint": 0.8, "FL_calf_joint": -1.5}, SPATIAL, 1e-12),
    ],
    ids=["solo-knee", "solo-hip-knee", "go1-planar", "go1-three"],
)
def test_touchdown_posture_from_joint_angles(robot, root, ankle, angles, space, bound):
    """``--angle``: the chain at those joint angles is the source's at the same configuration in
    Pinocchio: the ankle (from the model file's rods) and, for planar legs, the impulse."""
    path = robot_file(robot)
    leg = import_leg(read_description(path), root, ankle, angles=angles)
    assert leg.space is space
    ref = reference(path, root, ankle, planar_basis=TO_FOOTOPT if space is PLANAR else None)
    _pose(ref, angles)
    if space is SPATIAL:
        np.testing.assert_allclose(_world(leg)[1], ref.ankle(), atol=1e-12)
        ours, theirs = footopt_impulse(leg), ref.impulse()
        assert abs(ours / theirs - 1) <= bound, (ours, theirs)
        return
    np.testing.assert_allclose(planar_ankle(leg), TO_FOOTOPT[:2] @ ref.ankle(), atol=1e-12)
    ours, theirs = footopt_impulse(leg), ref.impulse()
    assert abs(ours / theirs - 1) <= bound, (ours, theirs)


def test_an_angle_for_a_joint_off_the_chain_names_it():
    from optimizer.errors import ConfigError

    with pytest.raises(ConfigError, match="--angle.*no joint named 'FR_KFE' on the chain"):
        import_leg(read_description(robot_file(SOLO)), "FL_UPPER_LEG", "FL_FOOT", angles={"FR_KFE": 0.3})
