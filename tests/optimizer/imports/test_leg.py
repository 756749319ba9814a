"""import_leg on a made-up URDF whose links a rod carries exactly (centre of mass on the line
between joints, inertia symmetric about it): footopt's impulse and mass matrix equal
Pinocchio's on the same file, planar and spatial; and the chain's rules (merging, refusals)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from impulse_core.kinematics.spatial import PLANAR, SPATIAL
from impulse_core.model.rods import rotation_rpy
from optimizer.errors import ConfigError
from optimizer.imports.leg import TO_FOOTOPT, import_leg
from optimizer.imports.read import read_description
from tests.optimizer.imports.peers import footopt_impulse, footopt_joint_mass_matrix, reference

# (name, parent, joint kind, origin xyz, origin rpy, axis, next joint / foot in this link's frame, mass, com fraction)
SPATIAL_LEG = [
    ("base", None, None, None, None, None, (0.2, 0.1, 0.0), 3.0, 0.3),
    ("hip", "base", "revolute", (0.2, 0.1, 0.0), (0.1, 0.0, 0.2), (1, 0, 0), (0.0, 0.06, -0.01), 0.5, 0.6),
    ("thigh", "hip", "continuous", (0.0, 0.06, -0.01), (0.0, 0.3, 0.0), (0, 1, 0), (0.02, 0.0, -0.2), 1.0, 0.4),
    ("shank", "thigh", "revolute", (0.02, 0.0, -0.2), (0.0, -0.2, 0.0), (0, -1, 0), (0.0, 0.0, -0.21), 0.2, 0.5),
    ("foot", "shank", "fixed", (0.0, 0.0, -0.21), (0.0, 0.0, 0.0), None, None, 0.05, None),
]


def rod_urdf(links) -> str:
    """A URDF of rods: each link's centre of mass on the segment to its next joint, its inertia
    0.002 m kg across that segment and 0.0004 m kg along it (a point mass: none)."""
    out = ['<?xml version="1.0"?>', '<robot name="rods">']
    for name, parent, kind, xyz, rpy, axis, nxt, mass, f in links:
        if nxt is None:
            inertial = f'<inertial><mass value="{mass}"/><inertia ixx="0" iyy="0" izz="0" ixy="0" ixz="0" iyz="0"/></inertial>'
        else:
            p = np.array(nxt, dtype=float)
            u = p / np.linalg.norm(p)
            I = mass * (0.002 * (np.eye(3) - np.outer(u, u)) + 0.0004 * np.outer(u, u))
            c = f * p
            inertial = (f'<inertial><origin xyz="{c[0]} {c[1]} {c[2]}"/><mass value="{mass}"/><inertia '
                        f'ixx="{I[0, 0]}" iyy="{I[1, 1]}" izz="{I[2, 2]}" ixy="{I[0, 1]}" ixz="{I[0, 2]}" iyz="{I[1, 2]}"/></inertial>')
        out.append(f'<link name="{name}">{inertial}</link>')
        if parent is not None:
            ax = "" if axis is None else f'<axis xyz="{axis[0]} {axis[1]} {axis[2]}"/>'
            limit = '<limit lower="-3" upper="3" effort="1" velocity="1"/>' if kind == "revolute" else ""
            out.append(f'<joint name="{name}_joint" type="{kind}"><parent link="{parent}"/><child link="{name}"/>'
                       f'<origin xyz="{xyz[0]} {xyz[1]} {xyz[2]}" rpy="{rpy[0]} {rpy[1]} {rpy[2]}"/>{ax}{limit}</joint>')
    return "\n".join(out + ["</robot>"]) + "\n"


def write(tmp_path: Path, links, name="rods.urdf") -> Path:
    path = tmp_path / name
    path.write_text(rod_urdf(links))
    return path


def test_spatial_rods_are_exact_against_pinocchio(tmp_path):
    path = write(tmp_path, SPATIAL_LEG)
    leg = import_leg(read_description(path), "base", "foot")
    assert leg.space is SPATIAL
    assert [r.name for r in leg.rods] == ["base", "hip", "thigh", "shank"]
    assert leg.rods[-1].merged == ("shank", "foot")
    ref = reference(path, "base", "foot")
    assert max(r.com_offset for r in leg.rods) < 1e-15 and max(r.inertia_residual for r in leg.rods) < 1e-12
    assert footopt_impulse(leg) == pytest.approx(ref.impulse(), rel=1e-9)
    np.testing.assert_allclose(footopt_joint_mass_matrix(leg), ref.joint_mass_matrix(), rtol=0, atol=1e-12)
    assert sum(b.mass for b in leg.model.tree.bodies) == pytest.approx(3.0 + 0.5 + 1.0 + 0.2 + 0.05, rel=1e-15)


def test_planar_rods_are_exact_against_pinocchio(tmp_path):
    links = [list(x) for x in SPATIAL_LEG if x[0] != "hip"]
    links[1] = ["thigh", "base", "continuous", (0.2, 0.1, 0.0), (0.0, 0.3, 0.0), (0, 1, 0), (0.02, 0.03, -0.2), 1.0, 0.4]
    links[2][3] = (0.02, 0.03, -0.2)  # the shank's joint 30 mm to the side: out of the plane
    path = write(tmp_path, links)
    leg = import_leg(read_description(path), "base", "foot")
    assert leg.space is PLANAR and [r.flipped for r in leg.rods] == [False, True, False]  # footopt's z is -y here
    ref = reference(path, "base", "foot", planar_basis=TO_FOOTOPT)
    assert footopt_impulse(leg) == pytest.approx(ref.impulse(), rel=1e-9)
    s = np.array([-1.0 if r.flipped else 1.0 for r in leg.rods[1:]])  # footopt counts -z joints the other way
    np.testing.assert_allclose(footopt_joint_mass_matrix(leg) * np.outer(s, s), ref.joint_mass_matrix(), atol=1e-12)
    # forced spatial: the free-flying leg (its lateral offsets turn it out of the plane) against a free-flyer
    spatial = import_leg(read_description(path), "base", "foot", space="spatial")
    free = reference(path, "base", "foot")
    assert footopt_impulse(spatial) == pytest.approx(free.impulse(), rel=1e-9)
    assert abs(footopt_impulse(spatial) / footopt_impulse(leg) - 1) > 1e-3  # not the planar answer


def test_an_off_axis_centre_of_mass_is_carried_exactly_and_reported(tmp_path):
    text = rod_urdf(SPATIAL_LEG)
    head = '<link name="thigh"><inertial><origin xyz="'
    k = text.index(head) + len(head)
    x, y, z = (float(v) for v in text[k:text.index('"', k)].split())
    text = text[:k] + f"{x} {y + 0.01} {z}" + text[text.index('"', k):]  # 10 mm off the rod (link y)
    (tmp_path / "off.urdf").write_text(text)
    leg = import_leg(read_description(tmp_path / "off.urdf"), "base", "foot")
    assert leg.rods[2].com_offset == pytest.approx(0.01, rel=1e-9)
    assert [r.com_offset < 1e-15 for r in leg.rods] == [True, True, False, True]
    assert "thigh: joint 'thigh_joint', 1 kg; centre of mass 10 mm off the rod's axis (com_offset)" in leg.summary()
    thigh = leg.model.tree.bodies[2]
    assert np.hypot(*thigh.com_offset) == pytest.approx(0.01, rel=1e-9) and thigh.gyration == 0.0
    ref = reference(tmp_path / "off.urdf", "base", "foot")
    assert footopt_impulse(leg) == pytest.approx(ref.impulse(), rel=1e-12)
    np.testing.assert_allclose(footopt_joint_mass_matrix(leg), ref.joint_mass_matrix(), rtol=0, atol=1e-12)


def test_a_centre_of_mass_behind_its_joint_slides_the_joint_along_its_axis(tmp_path):
    """The hip's centre of mass 30 mm behind its joint along the rod (and 5 mm across): its rod
    starts further along the hip's axis, the base's rod ends there, and the answer stays exact."""
    text = rod_urdf(SPATIAL_LEG)
    head = '<link name="hip"><inertial><origin xyz="'
    k = text.index(head) + len(head)
    text = text[:k] + "0.005 -0.03 0.0" + text[text.index('"', k):]
    (tmp_path / "behind.urdf").write_text(text)
    leg = import_leg(read_description(tmp_path / "behind.urdf"), "base", "foot")
    assert leg.rods[1].slide > 0.0 and [r.slide for r in leg.rods[2:]] == [0.0, 0.0]
    assert "along its joint axis (so the centre of mass projects onto the rod)" in leg.summary()
    ref = reference(tmp_path / "behind.urdf", "base", "foot")
    assert footopt_impulse(leg) == pytest.approx(ref.impulse(), rel=1e-12)
    np.testing.assert_allclose(footopt_joint_mass_matrix(leg), ref.joint_mass_matrix(), rtol=0, atol=1e-12)


@pytest.mark.parametrize(
    "root, ankle, foot, message",
    [
        ("nope", "foot", None, "--root: no link named 'nope'"),
        ("base", "nope", None, "--ankle: no link named 'nope'"),
        ("shank", "hip", None, "--ankle: 'hip' does not hang below 'shank' (--root): the chain is not connected"),
        ("shank", "foot", None, "--ankle: no revolute joint between 'shank' (--root) and 'foot'"),
        ("base", "shank", None, "the rod of 'shank' would have no length"),
        ("base", "foot", "hip", "--foot: 'hip' is not welded to the ankle's rod"),
    ],
)
def test_bad_chains_are_refused_naming_the_option(tmp_path, root, ankle, foot, message):
    desc = read_description(write(tmp_path, SPATIAL_LEG))
    with pytest.raises(ConfigError, match=message.replace("(", r"\(").replace(")", r"\)")):
        import_leg(desc, root, ankle, foot)


def test_unsupported_joint_and_massless_link_are_refused(tmp_path):
    prismatic = rod_urdf(SPATIAL_LEG).replace('type="continuous"', 'type="prismatic"')
    (tmp_path / "p.urdf").write_text(prismatic)
    with pytest.raises(ConfigError, match="joint 'thigh_joint': is prismatic"):
        import_leg(read_description(tmp_path / "p.urdf"), "base", "foot")
    massless = [list(x) for x in SPATIAL_LEG]
    massless[2][7] = 0.0
    with pytest.raises(ConfigError, match="link 'thigh': has no mass"):
        import_leg(read_description(write(tmp_path, massless, "m.urdf")), "base", "foot")
    with pytest.raises(ConfigError, match="--space: planar needs every revolute joint axis"):
        import_leg(read_description(write(tmp_path, SPATIAL_LEG)), "base", "foot", space="planar")


def test_xml_with_entities_is_refused(tmp_path):
    bomb = '<?xml version="1.0"?><!DOCTYPE r [<!ENTITY a "aaaa">]><robot name="x"><link name="a"/></robot>'
    (tmp_path / "b.urdf").write_text(bomb)
    with pytest.raises(ConfigError, match="DOCTYPE"):
        read_description(tmp_path / "b.urdf")


def test_rpy_convention_of_the_reader():
    R = rotation_rpy((0.1, 0.2, 0.3))
    assert np.allclose(R @ R.T, np.eye(3))


def test_a_centre_of_mass_past_the_next_joint_lengthens_the_rod(tmp_path):
    """The thigh's and the shank's centres of mass beyond their next joint (the knee, the foot):
    their rods reach past it, the shank hangs at ``at`` < 1 and the contact sits at < 1; exact."""
    text = rod_urdf(SPATIAL_LEG)
    for link, xyz in (("thigh", "0.03 0.004 -0.3"), ("shank", "0.0 0.002 -0.25")):
        head = f'<link name="{link}"><inertial><origin xyz="'
        k = text.index(head) + len(head)
        text = text[:k] + xyz + text[text.index('"', k):]
    (tmp_path / "past.urdf").write_text(text)
    leg = import_leg(read_description(tmp_path / "past.urdf"), "base", "foot")
    thigh, shank = leg.model.tree.bodies[2:]
    assert thigh.com == 1.0 and shank.at < 1.0 and shank.com == 1.0 and shank.contacts[0] < 1.0
    ref = reference(tmp_path / "past.urdf", "base", "foot")
    assert footopt_impulse(leg) == pytest.approx(ref.impulse(), rel=1e-12)
    np.testing.assert_allclose(footopt_joint_mass_matrix(leg), ref.joint_mass_matrix(), rtol=0, atol=1e-12)
