"""URDF and MJCF exports (``optimizer.results.export``, ``footopt export``) read back by the engines
they are for, and checked against footopt's own answers.

- URDF in Pinocchio (``buildModelFromXML`` with a free-flyer, at ``pin.neutral``): the Newton
  impulses of ``pinocchio.impulseDynamics`` at the contact frames equal ``evaluate``'s to 1e-8
  (relative: max|a - b| / max|b|), and so do the velocities after the impact; the contact frames
  sit where footopt puts the contacts at touchdown.
- MJCF in MuJoCo (``MjModel.from_xml_string``, ``mj_kinematics`` at ``qpos0``): every body's mass,
  centre of mass and inertia tensor (``body_inertia`` turned by ``body_iquat`` into the body
  frame) equal the model's, every site sits at its contact at touchdown (1e-8 m); and the impulses
  of Newton's law on MuJoCo's own mass matrix and site Jacobians equal ``evaluate``'s to 1e-8.
- On every model file in configs/ and on seeded random trees (fixed joints, several contacts,
  off-centre masses, turning and sideways approaches, base_x); the controls show a planted 1 %
  error in one centre of mass fails both.
"""

from __future__ import annotations

import dataclasses
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from impulse_core.evaluate import evaluate, touchdown_geometry
from impulse_core.impact.laws import ImpactModel
from impulse_core.model.terrain import FLAT
from impulse_core.model.tree import Body, ContactSelection, JointKind, Scene, Tree
from impulse_core.timedomain.compliant import touchdown_configuration
from optimizer.cli.main import main
from optimizer.config.model_file import load_model_file
from optimizer.errors import ConfigError
from optimizer.results.export import INERTIA_FLOOR, check_names, to_mjcf, to_urdf
from tests.conftest import contact_independence, delassus_condition, random_tree, report
from tests.exported_models import pinocchio_landing

pin = pytest.importorskip("pinocchio")
mujoco = pytest.importorskip("mujoco")

REPO = Path(__file__).resolve().parents[2]
# Spatial models are not exported yet (refused with exit 2: tests/optimizer/test_spatial_cli.py).
CONFIGS = sorted(p for p in (REPO / "configs").glob("*.yaml") if "bodies:" in (t := p.read_text()) and "space: spatial" not in t)
TOL = 1e-8
SEED = 20261125


def relative(a, b) -> float:
    """max|a - b| / max|b| (MODEL_FORMAT.md, "Precise meanings")."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.abs(a - b).max() / np.abs(b).max())


def random_cases() -> list[tuple[str, Tree, Scene]]:
    """Seeded random trees whose contacts are independent and well conditioned (the impulses are
    then unique and both codes keep their digits; tests/impulse_core/test_pinocchio.py says why),
    each with a random landing: sideways, turning, above base_x."""
    rng = np.random.default_rng(SEED)
    cases: list[tuple[str, Tree, Scene]] = []
    while len(cases) < 12:
        tree = random_tree(rng, int(rng.integers(1, 9)), p_fixed=0.3, p_contact=0.6, max_contacts_per_body=2)
        scene = Scene(
            speed=float(rng.uniform(0.5, 5.0)),
            restitution=float(rng.uniform(0.0, 1.0)),
            selection=ContactSelection.ALL,
            base_x=float(rng.uniform(-1.0, 1.0)),
            velocity_x=float(rng.uniform(-1.0, 1.0)),
            angular_velocity=float(rng.uniform(-3.0, 3.0)),
        )
        independent, cond = contact_independence(tree)
        if independent and cond < 1e3 and delassus_condition(tree) < 1e5:
            cases.append((f"random{len(cases)}", tree, scene))
    return cases


def config_cases() -> list[tuple[str, Tree, Scene]]:
    return [(p.stem, (m := load_model_file(p)).tree, m.scene) for p in CONFIGS]


def offset_cases() -> list[tuple[str, Tree, Scene]]:
    """Random planar trees whose centres of mass lie off their rods in the plane (``com_offset``
    [dy, 0], up to 0.3 of the length): the URDF and MJCF write each centre of mass where it is."""
    rng = np.random.default_rng(16)
    out = []
    for k, (_, tree, scene) in enumerate(random_cases()[:4]):
        bodies = tuple(dataclasses.replace(b, com_offset=(float(rng.uniform(-0.3, 0.3)) * b.length, 0.0))
                       for b in tree.bodies)
        out.append((f"offset{k}", Tree(bodies), scene))
    return out


CASES = config_cases() + random_cases() + offset_cases()
IDS = [name for name, _, _ in CASES]


def reference(tree: Tree, scene: Scene):
    """``evaluate``'s answer: ``footopt evaluate``'s (auto) on a file, Newton's law on a random
    tree (all contacts, some of which may pull), on flat ground (impulses do not depend on height)."""
    flat = dataclasses.replace(scene, terrain=FLAT)
    return evaluate(tree, flat, None if scene.selection is ContactSelection.LOWEST else ImpactModel.NEWTON)


def touchdown_points(tree: Tree, scene: Scene) -> dict[str, np.ndarray]:
    """footopt's contact points at touchdown (world frame, 3D), by contact frame name."""
    q = touchdown_configuration(tree, scene.terrain, scene.base_x, clearance=0.0)
    points = touchdown_geometry(tree).contacts + q[:2]
    names = [f"{tree.bodies[b].name}_contact{k}" for b, k in tree.contacts]
    return {n: np.array([x, y, 0.0]) for n, (x, y) in zip(names, points, strict=True)}


# --------------------------------------------------------------------------------------------
# URDF in Pinocchio


@pytest.mark.parametrize("name, tree, scene", CASES, ids=IDS)
def test_urdf_in_pinocchio_gives_footopts_impulses(name: str, tree: Tree, scene: Scene):
    res = reference(tree, scene)
    assert res.model is ImpactModel.NEWTON, res.reason
    lam, v_plus, at, v_pin = pinocchio_landing(to_urdf(tree, scene), tree, scene, res.v_minus, res.active)
    e_lam = relative(lam, res.external[list(res.active)])
    e_v = relative(v_plus, res.v_plus)
    where = touchdown_points(tree, scene)
    e_at = max(np.abs(at[n] - p).max() for n, p in where.items())
    report(
        "export",
        f"{name}: URDF in Pinocchio vs evaluate: impulses {e_lam:.1e}, v_plus {e_v:.1e}, contacts {e_at:.1e} m",
    )
    assert e_lam < TOL and e_v < TOL
    assert np.abs(v_pin[[2, 3, 4]]).max() < TOL * np.abs(v_pin).max()  # nothing leaves the plane
    assert e_at < TOL


def moving_joint(tree: Tree, i: int) -> str | None:
    """The joint that moves body ``i``: its own if revolute, else its parent's (None: the base's)."""
    while i != 0 and tree.bodies[i].joint is JointKind.FIXED:
        i = tree.bodies[i].parent
    return None if i == 0 else tree.bodies[i].name


@pytest.mark.parametrize("name, tree, scene", CASES, ids=IDS)
def test_urdf_inertias_in_pinocchio_are_the_models(name: str, tree: Tree, scene: Scene):
    """Each Pinocchio joint's rigid group (its rods welded together) at the touchdown pose, in the
    world frame: mass, centre of mass and full inertia tensor equal the sum of the model's rods,
    each turned by its absolute angle (out-of-plane terms too, which no planar impulse sees)."""
    model = pin.buildModelFromXML(to_urdf(tree, scene), pin.JointModelFreeFlyer())
    data = model.createData()
    pin.forwardKinematics(model, data, pin.neutral(model))
    q = touchdown_configuration(tree, scene.terrain, scene.base_x, clearance=0.0)
    coms = touchdown_geometry(tree).coms + q[:2]
    turn = [b.angle for b in tree.bodies]
    for i in range(1, tree.n_bodies):
        turn[i] += turn[tree.bodies[i].parent]
    expected: dict[str | None, pin.Inertia] = {}
    for i, b in enumerate(tree.bodies):
        R = pin.utils.rotate("z", turn[i])
        rod = pin.Inertia(b.mass, np.array([*coms[i], 0.0]), R @ expected_inertia(b, "urdf") @ R.T)
        key = moving_joint(tree, i)
        expected[key] = expected[key] + rod if key in expected else rod
    worst = 0.0
    for key, want in expected.items():
        j = 1 if key is None else model.getJointId(key)
        got = data.oMi[j].act(model.inertias[j])
        assert got.mass == pytest.approx(want.mass, rel=TOL)
        np.testing.assert_allclose(got.lever, want.lever, rtol=0, atol=TOL * max(1.0, np.abs(want.lever).max()))
        worst = max(worst, np.abs(got.inertia - want.inertia).max() / np.abs(want.inertia).max())
    report("export", f"{name}: URDF in Pinocchio: world inertia tensors of the joints' rigid groups {worst:.1e}")
    assert worst < TOL


# --------------------------------------------------------------------------------------------
# MJCF in MuJoCo


def mujoco_at_touchdown(mjcf: str):
    m = mujoco.MjModel.from_xml_string(mjcf)
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    return m, d


def inertia_in_body_frame(m, body: int) -> np.ndarray:
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, m.body_iquat[body])
    R = R.reshape(3, 3)
    return R @ np.diag(m.body_inertia[body]) @ R.T


def expected_inertia(b: Body, fmt: str = "mjcf") -> np.ndarray:
    """The model's tensor about the centre of mass in the rod's frame: in MJCF every moment
    raised to MuJoCo's floor, in URDF the dynamics' own (the rod axis at m (1e-7 L)^2)."""
    across = b.mass * (b.gyration * b.length) ** 2
    if fmt == "urdf":
        return np.diag([b.mass * (1e-7 * b.length) ** 2, across, across])
    return np.diag([INERTIA_FLOOR, max(across, INERTIA_FLOOR), max(across, INERTIA_FLOOR)])


@pytest.mark.parametrize("name, tree, scene", CASES, ids=IDS)
def test_mjcf_in_mujoco_has_the_models_bodies_and_contacts(name: str, tree: Tree, scene: Scene):
    m, d = mujoco_at_touchdown(to_mjcf(tree, scene))
    assert m.nbody == tree.n_bodies + 1  # and the world
    worst = 0.0
    for b in tree.bodies:
        i = m.body(b.name).id
        assert m.body_mass[i] == pytest.approx(b.mass, rel=TOL)
        tensor, want = inertia_in_body_frame(m, i), expected_inertia(b)
        worst = max(worst, np.abs(tensor - want).max() / np.abs(want).max())
        np.testing.assert_allclose(m.body_ipos[i], [b.com * b.length, *b.com_offset], rtol=0, atol=TOL * b.length)
    where = touchdown_points(tree, scene)
    e_at = max(np.abs(d.site(n).xpos - p).max() for n, p in where.items())
    if scene.terrain.is_flat:  # the pose, told independently: base above base_x, lowest contact on the ground
        assert d.body(tree.bodies[0].name).xpos[0] == pytest.approx(scene.base_x, abs=TOL)
        assert min(d.site(n).xpos[1] for n in where) == pytest.approx(scene.terrain.y[0], abs=TOL)
    report("export", f"{name}: MJCF in MuJoCo: inertia tensors {worst:.1e}, sites {e_at:.1e} m")
    assert worst < TOL and e_at < TOL
    assert m.nsite == len(tree.contacts)
    np.testing.assert_array_equal(m.opt.gravity, [0.0, -9.81, 0.0])


@pytest.mark.parametrize("name, tree, scene", CASES, ids=IDS)
def test_mjcf_dynamics_give_footopts_impulses(name: str, tree: Tree, scene: Scene):
    """Newton's law, lambda = -(1 + e) (J M^-1 J^T)^-1 J v, on MuJoCo's own mass matrix (qM at
    qpos0) and site Jacobians (mj_jacSite), with the freejoint's velocity (world linear velocity of
    the base origin, body-frame angular velocity: about z either way)."""
    res = reference(tree, scene)
    m, d = mujoco_at_touchdown(to_mjcf(tree, scene))
    mujoco.mj_forward(m, d)
    M = np.zeros((m.nv, m.nv))
    if hasattr(d, "qM"):  # MuJoCo 3
        mujoco.mj_fullM(m, M, d.qM)
    else:  # MuJoCo 4
        mujoco.mj_fullM(m, d, M)
    J = np.zeros((len(res.active), m.nv))
    jacp = np.zeros((3, m.nv))
    for row, c in enumerate(res.active):
        b, k = tree.contacts[c]
        mujoco.mj_jacSite(m, d, jacp, None, m.site(f"{tree.bodies[b].name}_contact{k}").id)
        J[row] = jacp[1]
    v = np.zeros(m.nv)
    v[[0, 1, 5]] = res.v_minus[:3]
    revolute = [b for b in tree.bodies[1:] if b.joint is JointKind.REVOLUTE]
    for k, b in enumerate(revolute):
        v[m.joint(b.name).dofadr[0]] = res.v_minus[3 + k]
    A = J @ np.linalg.solve(M, J.T)
    lam = -(1.0 + scene.restitution) * np.linalg.solve(A, J @ v)
    e_lam = relative(lam, res.external[list(res.active)])
    report("export", f"{name}: Newton's law on MuJoCo's M and site Jacobians vs evaluate: {e_lam:.1e}")
    assert e_lam < TOL


# --------------------------------------------------------------------------------------------
# Controls and structure


def test_a_planted_error_is_caught():
    """The checks are sensitive: the exports of a tree whose first body with contacts has its
    centre of mass moved by 1 % of its length fail both comparisons with the true tree."""
    _, tree, scene = CASES[0]
    i = next(i for i, b in enumerate(tree.bodies) if b.contacts and b.parent is not None)
    bodies = list(tree.bodies)
    bodies[i] = dataclasses.replace(bodies[i], com=bodies[i].com + 0.01)
    wrong = Tree(tuple(bodies))
    res = reference(tree, scene)
    lam, *_ = pinocchio_landing(to_urdf(wrong, scene), tree, scene, res.v_minus, res.active)
    assert relative(lam, res.external[list(res.active)]) > 1e3 * TOL
    m, _ = mujoco_at_touchdown(to_mjcf(wrong, scene))
    assert abs(m.body_ipos[m.body(tree.bodies[i].name).id][0] - tree.bodies[i].com * tree.bodies[i].length) > 1e3 * TOL


def test_joints_frames_and_the_note():
    """Joints named as their rods (revolute about z, fixed welded), the base floating, a frame
    per contact, and the comment that says what was floored."""
    tree = Tree(
        (
            Body("base", None, 1.0, 1.0, 0.3, contacts=(0.0, 1.0)),
            Body("weld", 0, 0.5, 0.5, 0.2, joint=JointKind.FIXED),
            Body("hinge", 1, 0.5, 0.5, -0.4, contacts=(1.0,), gyration=0.0),
        )
    )
    scene = Scene(selection=ContactSelection.ALL)
    urdf = ET.fromstring(to_urdf(tree, scene))
    joints = {j.get("name"): j.get("type") for j in urdf.iter("joint")}
    assert joints == {
        "weld": "fixed",
        "hinge": "continuous",
        "base_contact0": "fixed",
        "base_contact1": "fixed",
        "hinge_contact0": "fixed",
    }
    frames = {"base_contact0", "base_contact1", "hinge_contact0"}
    assert {link.get("name") for link in urdf.iter("link")} == {"base", "weld", "hinge", *frames}
    assert not any(link.find("inertial") for link in urdf.iter("link") if link.get("name") in frames)
    assert [j.find("axis").get("xyz") for j in urdf.iter("joint") if j.get("type") == "continuous"] == ["0 0 1"]
    m, _ = mujoco_at_touchdown(to_mjcf(tree, scene))
    kinds = {m.joint(j).name: int(m.jnt_type[j]) for j in range(m.njnt)}
    assert kinds == {"base": mujoco.mjtJoint.mjJNT_FREE, "hinge": mujoco.mjtJoint.mjJNT_HINGE}
    np.testing.assert_array_equal(m.jnt_axis[m.joint("hinge").id], [0.0, 0.0, 1.0])
    mjcf, urdf = to_mjcf(tree, scene), to_urdf(tree, scene)
    assert "1e-09 kg m^2" in mjcf and "1 rod(s) have less than 1e-09 kg m^2 across the rod too" in mjcf
    assert "1e-09" not in urdf and "m (1e-07 L)^2 about its own axis (x), footopt's own floor" in urdf


def test_names_are_escaped_and_clashes_refused():
    odd = 'a<b & "c"'
    tree = Tree((Body(odd, None, 1.0, 1.0, -0.5, contacts=(1.0,)), Body("x", 0, 0.5, 0.5, 0.5, contacts=(1.0,))))
    scene = Scene()
    m, _ = mujoco_at_touchdown(to_mjcf(tree, scene))
    assert m.body(odd).id == 1 and m.site(f"{odd}_contact0").id == 0
    model = pin.buildModelFromXML(to_urdf(tree, scene), pin.JointModelFreeFlyer())
    assert model.existFrame(f"{odd}_contact0") and model.existFrame(odd)
    clash = Tree((Body("a", None, 1.0, 1.0, 0.0, contacts=(1.0,)), Body("a_contact0", 0, 1.0, 1.0, 0.0)))
    with pytest.raises(ConfigError, match=r"model.bodies\[1\].name: 'a_contact0' is also the name of a contact frame"):
        check_names(clash)


# --------------------------------------------------------------------------------------------
# footopt export


def test_cli_writes_both_formats_and_never_overwrites(tmp_path: Path, capsys):
    model = REPO / "configs" / "paper_case3.yaml"
    urdf, mjcf = tmp_path / "leg.urdf", tmp_path / "leg.xml"
    assert main(["export", str(model), "-o", str(urdf)]) == 0
    assert main(["export", "--format", "mjcf", str(model), "--out", str(mjcf)]) == 0
    m = load_model_file(model)
    assert urdf.read_text() == to_urdf(m.tree, m.scene, "paper_case3")
    assert mjcf.read_text() == to_mjcf(m.tree, m.scene, "paper_case3")
    urdf.write_text("mine")
    capsys.readouterr()
    assert main(["export", str(model), "-o", str(urdf)]) == 2
    err = capsys.readouterr().err
    assert err == f"footopt: error: {urdf}: already exists; not overwriting it (pass --force to replace it)\n"
    assert urdf.read_text() == "mine"
    assert main(["export", str(model), "-o", str(urdf), "--force"]) == 0
    assert urdf.read_text() == to_urdf(m.tree, m.scene, "paper_case3")


@pytest.mark.parametrize(
    "args, start",
    [
        (["{model}", "-o", "{tmp}/leg.txt"], "footopt: error: --format: give urdf or mjcf"),
        (["{tmp}/missing.yaml", "-o", "{tmp}/leg.urdf"], "footopt: error: {tmp}/missing.yaml: file not found"),
        (["{clash}", "-o", "{tmp}/leg.xml"], "footopt: error: {clash}: model.bodies[1].name: 'a_contact0' is also"),
    ],
    ids=["no format", "missing file", "name clash"],
)
def test_cli_bad_input_is_one_line_exit_2(tmp_path: Path, capsys, args: list[str], start: str):
    clash = tmp_path / "clash.yaml"
    clash.write_text(
        "scene: {speed: 1, restitution: 0.5}\nmodel:\n  bodies:\n"
        "    - {name: a, length: 1, mass: 1, angle: 0, contacts: [1.0]}\n"
        "    - {name: a_contact0, parent: a, length: 1, mass: 1, angle: 0}\n"
    )
    fill = {"model": REPO / "configs" / "paper_case2.yaml", "tmp": tmp_path, "clash": clash}
    assert main(["export", *(a.format(**fill) for a in args)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(start.format(**fill)) and err.count("\n") == 1
    assert not list(tmp_path.glob("leg.*"))


def test_joint_laws_are_carried_over_relative_to_the_touchdown_angle(tmp_path):
    """configs/landing_case3.yaml (a knee with stops, springs and dampers everywhere): MuJoCo reads
    each hinge's range, stiffness, spring rest and damping, Pinocchio each stop and damper, all
    relative to the touchdown angle (the exported zero); URDF's missing springs are said."""
    pin = pytest.importorskip("pinocchio")
    mujoco = pytest.importorskip("mujoco")
    model = load_model_file(REPO / "configs" / "landing_case3.yaml")
    tree, laws = model.tree, model.joints
    m = mujoco.MjModel.from_xml_string(to_mjcf(tree, model.scene, joints=laws))
    urdf = to_urdf(tree, model.scene, joints=laws)
    p = pin.buildModelFromXML(urdf, pin.JointModelFreeFlyer())
    assert "URDF has no joint springs" in urdf
    bouncy = tuple(dataclasses.replace(law, stop_restitution=0.5) if law.limits else law for law in laws)
    assert "has no counterpart in the format: not written" in to_urdf(tree, model.scene, joints=bouncy)
    assert "Stops (" not in urdf and "Stops (" in to_mjcf(tree, model.scene, joints=bouncy)
    for i, (b, law) in enumerate(zip(tree.bodies, laws)):
        if i == 0 or b.joint is not JointKind.REVOLUTE:
            continue
        j = m.joint(b.name)
        rest = 0.0 if law.rest is None else law.rest - b.angle
        assert m.jnt_stiffness[j.id] == law.stiffness and m.dof_damping[j.dofadr[0]] == law.damping
        assert m.qpos_spring[j.qposadr[0]] == pytest.approx(rest, abs=1e-15) if law.stiffness else True
        k = p.getJointId(b.name)
        assert p.damping[p.joints[k].idx_v] == law.damping
        if law.limits is not None:
            expected = (law.limits[0] - b.angle, law.limits[1] - b.angle)
            assert bool(m.jnt_limited[j.id]) and tuple(m.jnt_range[j.id]) == pytest.approx(expected, abs=1e-15)
            q = p.joints[k].idx_q
            assert (p.lowerPositionLimit[q], p.upperPositionLimit[q]) == pytest.approx(expected, abs=1e-15)
        else:
            assert not m.jnt_limited[j.id]
