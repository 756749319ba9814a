"""Planar imports carry each link's centre of mass in the plane exactly (``com`` and ``com_offset``
[dy, 0]; MODEL_FORMAT "Bodies", "Import"): on real legs whose centres of mass sit millimetres off
the line between their joints, footopt's impulse equals Pinocchio's on the source file's chain (a
planar base joint) to 1e-12; the same model file read as spatial (``model.space: spatial``) gives
the same answer (one kinematic core); ``--com-on-rods`` keeps the former approximation."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from impulse_core.evaluate import evaluate
from impulse_core.kinematics.spatial import PLANAR, SPATIAL
from impulse_core.model.tree import Scene
from optimizer.config.model_file import format_model_file, load_yaml, parse_model
from optimizer.imports.leg import _plane, import_leg
from optimizer.imports.read import read_description
from tests.optimizer.imports.peers import footopt_impulse, reference, robot_file

GO1 = "go1_description/urdf/go1.urdf"
# (file, root, ankle, touchdown angles): planar legs with centres of mass off their rods
LEGS = [
    (GO1, "FL_hip", "FL_foot", {"FL_thigh_joint": 0.8, "FL_calf_joint": -1.5}),  # 3.05 and 4.3 mm off
    ("a1_description/urdf/a1.urdf", "FL_hip", "FL_foot", {"FL_thigh_joint": 0.8, "FL_calf_joint": -1.5}),
    # its shank's centre of mass 39 mm off the knee-foot line; the plane tilted 30 degrees
    ("anymal_c_simple_description/urdf/anymal.urdf", "LF_HIP", "LF_FOOT", {"LF_HFE": 0.6, "LF_KFE": -1.0}),
]


def _pinocchio(leg, path, root, ankle, angles):
    """Pinocchio's impulse on the source's chain on a planar joint in the leg's plane (ANYmal's legs
    turn about axes 30 degrees off the description's y)."""
    plane, normal = _plane(list(leg.segments))
    ref = reference(path, root, ankle, planar_basis=np.vstack([plane, normal]))
    for name, value in angles.items():
        ref.q[ref.model.joints[ref.model.getJointId(name)].idx_q] = value
    return ref.impulse()


@pytest.mark.parametrize("robot, root, ankle, angles", LEGS, ids=[r.split("_")[0] for r, *_ in LEGS])
def test_planar_leg_with_offsets_against_pinocchio_and_as_spatial(robot, root, ankle, angles):
    path = robot_file(robot)
    leg = import_leg(read_description(path), root, ankle, angles=angles)
    assert leg.space is PLANAR and max(abs(b.com_offset[0]) for b in leg.model.tree.bodies) > 1e-3
    ours, theirs = footopt_impulse(leg), _pinocchio(leg, path, root, ankle, angles)
    print(f"{robot.split('_')[0]} planar with com_offset: footopt {ours:.9g}, Pinocchio {theirs:.9g}, "
          f"{abs(ours / theirs - 1):.1e}")
    assert abs(ours / theirs - 1) < 1e-12
    # the same file read as spatial: the plane is the spatial core restricted
    text = format_model_file(leg.model).replace("model:\n", "model:\n  space: spatial\n", 1)
    spatial = parse_model(load_yaml(text))
    assert spatial.space is SPATIAL and spatial.tree.bodies == leg.model.tree.bodies
    scene = Scene(speed=1.0, restitution=0.3, velocity_x=0.4, angular_velocity=1.5)
    planar, space = evaluate(leg.model.tree, scene), evaluate(spatial.tree, scene, space=SPATIAL)
    for a, b in ((planar.external, space.external), (planar.internal, space.internal)):
        assert np.abs(np.subtract(a, b)).max() <= 1e-12 * np.abs(b).max()
    # --com-on-rods: the former approximation (each centre of mass moved onto its rod), measurably off
    rods = import_leg(read_description(path), root, ankle, angles=angles, com_on_rods=True)
    assert all(b.com_offset == (0.0, 0.0) for b in rods.model.tree.bodies)
    assert "approximated as above (--com-on-rods)" in rods.summary()
    assert abs(footopt_impulse(rods) / theirs - 1) > 1e-6


def test_a_centre_of_mass_behind_a_planar_joint_is_moved_and_reported(tmp_path):
    """A planar rod starts at its joint: a centre of mass behind it (not the base's) is moved onto
    the joint (along the rod; the offset across it kept) and the summary says so."""
    from tests.optimizer.imports.test_leg import SPATIAL_LEG, rod_urdf

    links = [list(x) for x in SPATIAL_LEG if x[0] != "hip"]
    links[1] = ["thigh", "base", "continuous", (0.2, 0.1, 0.0), (0.0, 0.0, 0.0), (0, 1, 0), (0.02, 0.0, -0.2), 1.0, 0.4]
    text = rod_urdf(links)
    head = '<link name="thigh"><inertial><origin xyz="'
    k = text.index(head) + len(head)
    text = text[:k] + "-0.01 0.0 0.03" + text[text.index('"', k):]  # 30 mm above the hip, 10 mm back
    (tmp_path / "behind.urdf").write_text(text)
    leg = import_leg(read_description(tmp_path / "behind.urdf"), "base", "foot")
    assert leg.space is PLANAR and leg.rods[1].com_clamped and leg.model.tree.bodies[1].com == 0.0
    assert "moved onto its joint (behind it: a planar rod starts at its joint)" in leg.summary()
    assert "(except where said above)" in leg.summary()


@pytest.mark.parametrize("rung", ["compliant", "sequential", "landing"])
def test_the_time_domain_rungs_take_an_offset(tmp_path, capsys, rung):
    import json

    from optimizer.cli.main import main

    leg = import_leg(read_description(robot_file(GO1)), "FL_hip", "FL_foot", angles={"FL_calf_joint": -1.5},
                     joint_laws=False)
    text = format_model_file(replace(leg.model, scene=replace(leg.model.scene, restitution=0.3)))
    if rung == "landing":
        text = text.replace("scene:\n", "scene:\n  duration: 0.05\n", 1)
    (tmp_path / "leg.yaml").write_text(text)
    code = main(["evaluate", "--json", "--model", rung, str(tmp_path / "leg.yaml")])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert json.loads(out)["model"] == rung


def test_planar_centres_of_mass_behind_the_base_and_past_a_joint_are_exact(tmp_path):
    """The base's centre of mass behind the root's origin (its rod starts further back) and the
    thigh's past the knee (its rod reaches beyond it, the shank hangs at ``at`` < 1), both off
    their rods in the plane: the impulse is Pinocchio's on a planar joint."""
    from tests.optimizer.imports.test_leg import SPATIAL_LEG, rod_urdf

    links = [list(x) for x in SPATIAL_LEG if x[0] != "hip"]
    links[1] = ["thigh", "base", "continuous", (0.2, 0.1, 0.0), (0.0, 0.3, 0.0), (0, 1, 0), (0.02, 0.0, -0.2), 1.0, 0.4]
    text = rod_urdf(links)
    for link, xyz in (("base", "-0.05 0.0 0.02"), ("thigh", "0.03 0.0 -0.26")):
        head = f'<link name="{link}"><inertial><origin xyz="'
        k = text.index(head) + len(head)
        text = text[:k] + xyz + text[text.index('"', k):]
    (tmp_path / "far.urdf").write_text(text)
    leg = import_leg(read_description(tmp_path / "far.urdf"), "base", "foot")
    base, thigh, shank = leg.model.tree.bodies
    assert leg.space is PLANAR and leg.rods[0].slide > 0.0 and base.com == 0.0
    assert thigh.com == 1.0 and shank.at < 1.0 and min(abs(base.com_offset[0]), abs(thigh.com_offset[0])) > 1e-3
    assert "back along the rod" in leg.summary()
    ref = reference(tmp_path / "far.urdf", "base", "foot", planar_basis=np.vstack([*_plane(list(leg.segments))]))
    assert footopt_impulse(leg) == pytest.approx(ref.impulse(), rel=1e-12)
