"""A spatial body's general mass properties (MODEL_FORMAT "Spatial models": ``com_offset``,
``inertia_tensor``): random spatial trees whose centres of mass sit off their rods and whose
inertia tensors are full give Pinocchio's impulses, velocities and joint impulses (1e-8); the
derivatives with respect to the new values match central differences; a rod (no offset, no tensor
added) gives the answers of commit 871616f, before these values existed, to rounding (1e-12); a tensor
that is no rigid body's is refused naming the field."""

from __future__ import annotations

import dataclasses
import functools
import json
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from impulse_core.compile.batch import batch_evaluator
from impulse_core.errors import ModelError
from impulse_core.evaluate import evaluate, pre_impact_velocity
from impulse_core.impact.delassus import mass_matrix_function, norms_gradient_function
from impulse_core.impact.laws import ImpactModel
from impulse_core.kinematics import dynamics as dyn
from impulse_core.kinematics.spatial import (
    PLANAR,
    SPATIAL,
    dof_layout,
    forward_kinematics,
    n_values,
    unpack_values,
)
from impulse_core.model.rods import centre_of_mass, inertia_tensor
from impulse_core.model.tree import SPATIAL_BODY_VALUES, Tree, design_vector, tensor_matrix
from tests.conftest import random_tree, report
from tests.impulse_core.test_spatial import SCENE, _delassus, pinocchio_errors, spatial_trees

SEED = 20261126
GOLDEN = Path(__file__).parent / "data" / "rod_answers_871616f.json"


def random_tensor(rng: np.random.Generator, scale: float) -> tuple[float, ...]:
    """A rigid body's inertia tensor about its centre of mass (principal moments obeying the
    triangle inequality, random principal axes) as (ixx, iyy, izz, ixy, ixz, iyz)."""
    moments = np.sort(scale * rng.uniform(0.05, 1.0, 3))
    moments[2] = min(moments[2], moments[0] + moments[1])
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    T = Q @ np.diag(moments) @ Q.T
    return (T[0, 0], T[1, 1], T[2, 2], T[0, 1], T[0, 2], T[1, 2])


def generalize(rng: np.random.Generator, tree: Tree) -> Tree:
    """Each body with a random centre-of-mass offset (up to ~0.3 of its length) and a random
    tensor: half as a file's ``inertia_tensor`` (gyration and radius 0), half added to the rod's own."""
    bodies = []
    for b in tree.bodies:
        tensor = random_tensor(rng, b.mass * (0.3 * b.length) ** 2)
        offset = tuple(float(x) for x in rng.normal(scale=0.3 * b.length, size=2))
        whole = rng.uniform() < 0.5
        bodies.append(dataclasses.replace(
            b, com_offset=offset, tensor=tuple(float(x) for x in tensor),
            gyration=0.0 if whole else b.gyration, radius=0.0 if whole else b.radius,
        ))
    return Tree(tuple(bodies))


@functools.lru_cache(maxsize=None)
def general_trees() -> tuple[Tree, ...]:
    rng = np.random.default_rng(SEED)
    return tuple(generalize(rng, t) for t in spatial_trees())


def test_general_spatial_trees_match_pinocchio() -> None:
    """External impulses, post-impact velocities and joint impulses against Pinocchio (its bodies
    built from rods.py's centre of mass and full tensor) within 1e-8 relative."""
    worst, compared = pinocchio_errors(general_trees())
    report("spatial", f"{compared} random spatial trees with com offsets and full tensors vs Pinocchio: external "
           f"{worst[0]:.1e}, v_plus {worst[1]:.1e}, joint impulses {worst[2]:.1e}")
    assert compared >= len(general_trees()) // 2
    assert worst.max() < 1e-8, worst


def test_the_offset_and_the_tensor_change_the_answer() -> None:
    """Each of the two matters: the same tree without the offsets, or without the added tensors,
    gives another impulse (the comparison above is not blind to either)."""
    tree = next(t for t in general_trees() if t.n_bodies >= 3 and np.linalg.cond(_delassus(t, SCENE)) < 1e5)
    full = evaluate(tree, SCENE, ImpactModel.NEWTON, space=SPATIAL).external
    for change in ({"com_offset": (0.0, 0.0)}, {"tensor": (0.0,) * 6}):
        other = Tree(tuple(dataclasses.replace(b, **change) for b in tree.bodies))
        r = evaluate(other, SCENE, ImpactModel.NEWTON, space=SPATIAL).external
        assert np.abs(r - full).max() > 1e-4 * np.abs(full).max(), change


def test_centre_of_mass_and_tensor_in_the_body_frame() -> None:
    """rods.py (exports, bridges): the centre of mass at (com L, dy, dz); the tensor the rod's
    diag(m r^2 / 2, I, I) plus the added one, entry by entry in (ixx, iyy, izz, ixy, ixz, iyz)."""
    b = general_trees()[0].bodies[0]
    b = dataclasses.replace(b, com_offset=(0.01, -0.02), tensor=(0.5, 0.6, 0.7, 0.01, 0.02, 0.03), radius=0.01)
    np.testing.assert_array_equal(centre_of_mass(b), [b.com * b.length, 0.01, -0.02])
    rod = np.diag([b.axial_inertia, b.inertia, b.inertia])
    np.testing.assert_allclose(inertia_tensor(b), rod + [[0.5, 0.01, 0.02], [0.01, 0.6, 0.03], [0.02, 0.03, 0.7]],
                               rtol=0, atol=1e-15)
    np.testing.assert_array_equal(tensor_matrix(b.tensor), tensor_matrix(b.tensor).T)


def test_gradients_with_respect_to_the_offsets_and_tensors_match_central_differences() -> None:
    """d external_norm / dp and d internal_norm / dp (adjoint) against central differences, for
    every design value, the new ones included (they matter)."""
    tree = next(t for t in general_trees() if len(t.contacts) >= 2 and t.n_bodies >= 3
                and np.linalg.cond(_delassus(t, SCENE)) < 1e5)
    topology = tree.topology()
    p0 = design_vector(tree, SPATIAL_BODY_VALUES)
    v = pre_impact_velocity(topology, SCENE, SPATIAL)
    f = norms_gradient_function(topology, SPATIAL)
    out = f(p=p0, v_minus=v, restitution=SCENE.restitution)
    n = len(SPATIAL_BODY_VALUES)
    new = [b * n + SPATIAL_BODY_VALUES.index(name) for b in range(tree.n_bodies)
           for name in ("com_y", "com_z", "ixx", "iyy", "izz", "ixy", "ixz", "iyz")]
    for key in ("external_norm", "internal_norm"):
        grad = np.array(out[f"d_{key}"]).ravel()
        fd = np.zeros_like(p0)
        for k in range(p0.size):
            h = 1e-6 * max(1.0, abs(p0[k]))
            up, down = p0.copy(), p0.copy()
            up[k] += h
            down[k] -= h
            fd[k] = (float(f(p=up, v_minus=v, restitution=SCENE.restitution)[key])
                     - float(f(p=down, v_minus=v, restitution=SCENE.restitution)[key])) / (2 * h)
        assert np.abs(grad - fd).max() <= 1e-6 * np.abs(grad).max(), key
        assert np.abs(grad[new]).max() > 1e-3 * np.abs(grad).max(), key


def test_the_batch_evaluator_takes_general_bodies() -> None:
    """The lean function (batched, CasADi's VM) on general bodies equals evaluate (1e-12)."""
    tree = next(t for t in general_trees() if np.linalg.cond(_delassus(t, SCENE)) < 1e5)
    r = evaluate(tree, dataclasses.replace(SCENE, speed=1.0, velocity_x=0.0, velocity_z=0.0, angular_velocity=0.0,
                                           angular_velocity_x=0.0, angular_velocity_y=0.0),
                 ImpactModel.NEWTON, space=SPATIAL)
    fast = batch_evaluator(tree.topology(r.active), None, space=SPATIAL)
    out = fast(design_vector(tree, SPATIAL_BODY_VALUES)[None, :], speed=1.0, restitution=SCENE.restitution)
    np.testing.assert_allclose(out.external_norm[0], np.linalg.norm(r.external), rtol=1e-12)


def test_rods_give_the_answers_of_commit_871616f_to_rounding() -> None:
    """Seeded random trees (planar, planar read as spatial, spatial; Newton and the exact cone) with
    no offset and no tensor: today's external and joint impulses and velocities are those written
    by commit 871616f's code (data/make_rod_answers.py) to rounding: 1e-12 of each list's largest
    entry. Not to the bit, since numpy's matrix kernels round by the CPU they dispatch to: on an
    AVX2 machine the file, written on another, is met to 6e-14 (Newton) where the machine that
    wrote it met it bit for bit. A rod's inertia scaled by 1 + 1e-10 fails it."""
    golden = json.loads(GOLDEN.read_text())
    out = {}
    for k, t in enumerate(spatial_trees()):
        out[f"spatial{k}.newton"] = evaluate(t, SCENE, ImpactModel.NEWTON, space=SPATIAL)
        if k < 10:
            out[f"spatial{k}.friction"] = evaluate(t, dataclasses.replace(SCENE, friction=0.5), ImpactModel.FRICTION,
                                                   space=SPATIAL)
    rng = np.random.default_rng(7)
    scene = dataclasses.replace(SCENE, velocity_z=0.0, angular_velocity_x=0.0, angular_velocity_y=0.0)
    for k in range(15):
        t = random_tree(rng, int(rng.integers(1, 8)), p_contact=0.6)
        out[f"planar{k}.newton"] = evaluate(t, scene, ImpactModel.NEWTON, space=PLANAR)
        out[f"planar{k}.as_spatial"] = evaluate(t, scene, ImpactModel.NEWTON, space=SPATIAL)
    assert set(out) == set(golden)
    for key, r in out.items():
        for name, values in (("external", r.external), ("internal", r.internal_magnitude), ("v_plus", r.v_plus)):
            a = np.asarray(values, dtype=float).ravel()
            b = np.array([float.fromhex(x) for x in golden[key][name]])
            assert a.shape == b.shape and np.all(np.abs(a - b) <= 1e-12 * np.max(np.abs(b), initial=0.0)), (key, name)


@pytest.mark.parametrize(
    "tensor, message",
    [
        ((1.0, 1.0, 1.0, 2.0, 0.0, 0.0), "not positive semidefinite"),
        ((1.0, 1.0, 3.0, 0.0, 0.0, 0.0), "triangle inequality"),
        ((1.0, 1.0, 1.0, 0.0, 0.0), "must be 6 numbers"),
        ((1.0, 1.0, float("nan"), 0.0, 0.0, 0.0), "finite"),
    ],
)
def test_a_tensor_of_no_rigid_body_is_refused_naming_the_field(tensor, message) -> None:
    b = general_trees()[0].bodies[0]
    with pytest.raises(ModelError, match=r"model\.bodies\[0\]\.inertia_tensor: .*" + message):
        Tree((dataclasses.replace(b, tensor=tensor),) + general_trees()[0].bodies[1:])
    with pytest.raises(ModelError, match=r"model\.bodies\[0\]\.com_offset"):
        Tree((dataclasses.replace(b, com_offset=(0.0, float("inf"))),) + general_trees()[0].bodies[1:])


def test_kinetic_bilinear_is_the_mass_matrix_bilinear_form() -> None:
    """``dynamics.kinetic_bilinear`` (the adjoint gradient's a^T M dv at the centres of mass)
    equals x^T M y with M the tree's mass matrix (1e-12 relative), on general bodies (offsets,
    full tensors) and on rods."""
    rng = np.random.default_rng(SEED)
    trees = [*general_trees()[:4], *spatial_trees()[:2]]
    for tree in trees:
        topology = tree.topology()
        layout = dof_layout(topology, SPATIAL)
        p = ca.SX.sym("p", n_values(topology, SPATIAL))
        x, y = ca.SX.sym("x", layout.nv), ca.SX.sym("y", layout.nv)
        values = unpack_values(topology, p, SPATIAL)
        kin = forward_kinematics(topology, values, SPATIAL)
        motions = dyn.joint_motions(kin, layout, SPATIAL)
        twists = [dyn.body_velocities(topology.parents, kin, layout, motions, z) for z in (x, y)]
        f = ca.Function("xMy", [p, x, y], [dyn.kinetic_bilinear(kin, values, *twists)])
        p0 = design_vector(tree, SPATIAL_BODY_VALUES)
        M = np.array(mass_matrix_function(topology, SPATIAL)(p0)[0])
        for _ in range(3):
            x0, y0 = rng.normal(size=layout.nv), rng.normal(size=layout.nv)
            scale = np.abs(M).max() * np.abs(x0).max() * np.abs(y0).max() * layout.nv**2
            assert abs(float(f(p0, x0, y0)) - x0 @ M @ y0) <= 1e-12 * scale
