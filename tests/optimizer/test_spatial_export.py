"""Spatial models exported (``footopt export`` on a ``model.space: spatial`` file): the URDF read
by Pinocchio with a free-flyer gives footopt's impulses; the MJCF read by MuJoCo has the model's
masses, inertia tensors and contact sites, and Newton's law on MuJoCo's own mass matrix and site
Jacobians gives footopt's impulses (1e-8)."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from impulse_core.evaluate import evaluate, touchdown_geometry
from impulse_core.impact.laws import ImpactModel
from impulse_core.kinematics.spatial import SPATIAL
from impulse_core.model.rods import body_rotation, centre_of_mass, inertia_tensor
from impulse_core.model.tree import JointKind, Tree
from optimizer.config.model_file import load_model_file
from optimizer.results.export import INERTIA_FLOOR, base_pose, to_mjcf, to_urdf
from tests.conftest import report
from tests.impulse_core.test_spatial import SCENE, _delassus, spatial_trees
from tests.impulse_core.test_spatial_inertia import general_trees

pin = pytest.importorskip("pinocchio")
mujoco = pytest.importorskip("mujoco")

REPO = Path(__file__).resolve().parents[2]
TOL = 1e-8


def cases() -> list[tuple[str, Tree]]:
    example = load_model_file(REPO / "configs" / "spatial_case3.yaml").tree
    randoms = [t for t in spatial_trees() if np.linalg.cond(_delassus(t, SCENE)) < 1e5][:10]
    # bodies with their centre of mass off the rod and a full inertia tensor (com_offset, inertia_tensor)
    general = [t for t in general_trees() if np.linalg.cond(_delassus(t, SCENE)) < 1e5][:6]
    return ([("spatial_case3", example)] + [(f"random{k}", t) for k, t in enumerate(randoms)]
            + [(f"general{k}", t) for k, t in enumerate(general)])


CASES = cases()
IDS = [name for name, _ in CASES]


def _points(tree: Tree) -> dict[str, np.ndarray]:
    """footopt's contact points at touchdown in the exported world (base lowered onto y = 0)."""
    origin, _ = base_pose(tree, SCENE, SPATIAL)
    contacts = touchdown_geometry(tree, SPATIAL).contacts + origin
    return {f"{tree.bodies[b].name}_contact{k}": p for (b, k), p in zip(tree.contacts, contacts, strict=True)}


def _joint_rates(tree: Tree, v: np.ndarray):
    revolute = [b for b in tree.bodies[1:] if b.joint is JointKind.REVOLUTE]
    return [(b.name, v[6 + k]) for k, b in enumerate(revolute)]


@pytest.mark.parametrize("name, tree", CASES, ids=IDS)
def test_spatial_urdf_in_pinocchio_gives_footopts_impulses(name: str, tree: Tree) -> None:
    res = evaluate(tree, SCENE, ImpactModel.NEWTON, space=SPATIAL)
    model = pin.buildModelFromXML(to_urdf(tree, SCENE, space=SPATIAL), pin.JointModelFreeFlyer())
    data = model.createData()
    q = pin.neutral(model)
    names = list(_points(tree))
    frames = [model.getFrameId(n, pin.BODY) for n in names]
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    J = np.array([pin.getFrameJacobian(model, data, frames[c], pin.LOCAL_WORLD_ALIGNED)[1] for c in res.active])
    # the root link is the world frame at touchdown: its origin moves at v_O + w x (0 - O)
    origin, _ = base_pose(tree, SCENE, SPATIAL)
    v = np.zeros(model.nv)
    v[:3] = res.v_minus[:3] + np.cross(res.v_minus[3:6], -origin)
    v[3:6] = res.v_minus[3:6]
    for joint, rate in _joint_rates(tree, res.v_minus):
        v[model.joints[model.getJointId(joint)].idx_v] = rate
    pin.impulseDynamics(model, data, q, v, J.reshape(len(res.active), model.nv), SCENE.restitution, 0.0)
    lam = np.array(data.impulse_c)
    expected = res.external[list(res.active)]
    e_lam = np.abs(lam - expected).max() / np.abs(expected).max()
    e_at = max(np.abs(data.oMf[f].translation - p).max() for f, p in zip(frames, _points(tree).values(), strict=True))
    report("export", f"{name} (spatial): URDF in Pinocchio vs evaluate: impulses {e_lam:.1e}, contacts {e_at:.1e} m")
    assert e_lam < TOL and e_at < TOL


@pytest.mark.parametrize("name, tree", CASES, ids=IDS)
def test_spatial_mjcf_in_mujoco_has_the_models_bodies_and_gives_its_impulses(name: str, tree: Tree) -> None:
    res = evaluate(tree, SCENE, ImpactModel.NEWTON, space=SPATIAL)
    m = mujoco.MjModel.from_xml_string(to_mjcf(tree, SCENE, space=SPATIAL))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    worst = 0.0
    for b in tree.bodies:
        i = m.body(b.name).id
        assert m.body_mass[i] == pytest.approx(b.mass, rel=TOL)
        R = np.zeros(9)
        mujoco.mju_quat2Mat(R, m.body_iquat[i])
        R = R.reshape(3, 3)
        tensor = R @ np.diag(m.body_inertia[i]) @ R.T
        want = inertia_tensor(b, INERTIA_FLOOR)  # a rod's diagonal, a general body's full tensor
        worst = max(worst, np.abs(tensor - want).max() / np.abs(want).max())
        worst = max(worst, np.abs(m.body_ipos[i] - centre_of_mass(b)).max() / b.length)
    e_at = max(np.abs(d.site(n).xpos - p).max() for n, p in _points(tree).items())
    base = m.body(tree.bodies[0].name).id
    R0 = np.zeros(9)
    mujoco.mju_quat2Mat(R0, d.xquat[base])
    assert np.abs(R0.reshape(3, 3) - body_rotation(tree.bodies[0])).max() < TOL
    # Newton's law on MuJoCo's mass matrix and site Jacobians; freejoint: world linear velocity of
    # the base origin, angular velocity in the base frame
    M = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, M, d.qM) if hasattr(d, "qM") else mujoco.mj_fullM(m, d, M)
    J = np.zeros((len(res.active), m.nv))
    jacp = np.zeros((3, m.nv))
    for row, c in enumerate(res.active):
        mujoco.mj_jacSite(m, d, jacp, None, m.site(list(_points(tree))[c]).id)
        J[row] = jacp[1]
    v = np.zeros(m.nv)
    v[:3] = res.v_minus[:3]
    v[3:6] = R0.reshape(3, 3).T @ res.v_minus[3:6]
    for joint, rate in _joint_rates(tree, res.v_minus):
        v[m.joint(joint).dofadr[0]] = rate
    lam = -(1.0 + SCENE.restitution) * np.linalg.solve(J @ np.linalg.solve(M, J.T), J @ v)
    expected = res.external[list(res.active)]
    e_lam = np.abs(lam - expected).max() / np.abs(expected).max()
    report("export", f"{name} (spatial): MJCF in MuJoCo: inertia {worst:.1e}, sites {e_at:.1e} m, impulses {e_lam:.1e}")
    assert worst < TOL and e_at < TOL and e_lam < TOL


def test_footopt_export_writes_a_spatial_file(tmp_path: Path) -> None:
    out = tmp_path / "foot.urdf"
    proc = subprocess.run(
        [sys.executable, "-m", "optimizer", "export", str(REPO / "configs" / "spatial_case3.yaml"), "-o", str(out)],
        capture_output=True, text=True, cwd=REPO,
    )
    assert proc.returncode == 0, proc.stderr
    model = pin.buildModelFromXML(out.read_text(encoding="utf-8"), pin.JointModelFreeFlyer())
    assert model.nv == 6 + 8 and "spatial model" in out.read_text(encoding="utf-8")



def _without_radius(tree: Tree) -> Tree:
    return Tree(tuple(dataclasses.replace(b, radius=0.0) for b in tree.bodies))


THIN = [(f"thin{k}", _without_radius(t)) for k, (_, t) in enumerate(CASES[1:9])]


@pytest.mark.parametrize("name, tree", THIN, ids=[n for n, _ in THIN])
def test_rods_without_radius_keep_footopts_impulses_in_the_urdf(name: str, tree: Tree) -> None:
    """Rods of radius 0 turn about their own axes in space: the URDF holds footopt's own axial
    floor, m (1e-7 L)^2, so Pinocchio's impulses are footopt's (a 1e-9 kg m^2 floor moved them by
    up to 7e-6 relative on a random file)."""
    test_spatial_urdf_in_pinocchio_gives_footopts_impulses(name, tree)
