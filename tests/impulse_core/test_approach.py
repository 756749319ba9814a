"""Landings that are not straight down (scene.velocity, scene.angular_velocity): the pre-impact
velocity is the whole tree moving as one rigid body; every rigid rung and the time-domain rungs
start from it. Checked against the independent numpy model (its own Jacobians and mass matrix)
and the laws: Newton's law on the oblique approach, the exact friction law at each contact, and
horizontal momentum kept by frictionless ground."""

from __future__ import annotations

import dataclasses

import numpy as np

from impulse_core.evaluate import evaluate
from impulse_core.impact.laws import ImpactModel
from impulse_core.model.tree import Scene
from impulse_core.timedomain.sequential import SequentialSettings, sequential_impacts
from tests.impulse_core.test_contact_models import FRICTION_SCENES, LCP_SCENES, _active, numpy_model
from tests.impulse_core.test_coulomb import _law_residuals


def _oblique(scene: Scene, rng: np.random.Generator) -> Scene:
    return dataclasses.replace(
        scene, velocity_x=float(rng.uniform(-2, 2)), angular_velocity=float(rng.uniform(-0.5, 0.5))
    )


def _rigid_body_velocity(nv: int, scene: Scene) -> np.ndarray:
    v = np.zeros(nv)
    v[:3] = scene.velocity_x, -scene.speed, scene.angular_velocity
    return v


def test_newton_on_an_oblique_approach_equals_the_numpy_model() -> None:
    rng = np.random.default_rng(7)
    for name, tree, scene in LCP_SCENES[:20]:
        scene = _oblique(scene, rng)
        res = evaluate(tree, scene, ImpactModel.NEWTON)
        m = numpy_model(tree, res.active, scene.speed)
        v = _rigid_body_velocity(m.M.shape[0], scene)
        np.testing.assert_array_equal(res.v_minus, v)
        expected = np.linalg.solve(m.A, -(1 + scene.restitution) * (m.Jn @ v))
        np.testing.assert_allclose(_active(res), expected, rtol=1e-8, atol=1e-10 * np.abs(expected).max(), err_msg=name)


def test_exact_friction_law_on_oblique_approaches() -> None:
    rng = np.random.default_rng(8)
    sliding_before = 0
    for name, tree, scene in FRICTION_SCENES:
        scene = _oblique(scene, rng)
        res = evaluate(tree, scene)
        m = numpy_model(tree, res.active, scene.speed)
        m = dataclasses.replace(m, v_minus=_rigid_body_velocity(m.M.shape[0], scene))
        for law, r in _law_residuals(res, m, scene).items():
            assert r < 1e-8, (name, law, r)
        sliding_before += int(np.sum(np.abs(m.Jt @ m.v_minus) > 1e-3))
    assert sliding_before > 20  # the contacts really came in sliding


def test_a_horizontal_velocity_on_frictionless_ground_changes_nothing_else_in_the_sequential_rung() -> None:
    """Galilean invariance: on flat frictionless ground a uniform horizontal velocity adds to the
    base's vx after the landing and changes no impulse."""
    for name, tree, scene in LCP_SCENES[:3]:
        down = sequential_impacts(tree, scene, SequentialSettings())
        moving = sequential_impacts(tree, dataclasses.replace(scene, velocity_x=1.5), SequentialSettings())
        np.testing.assert_allclose(moving.external, down.external, rtol=1e-9, atol=1e-12, err_msg=name)
        shift = np.zeros_like(down.v_plus)
        shift[0] = 1.5
        np.testing.assert_allclose(moving.v_plus, down.v_plus + shift, rtol=1e-9, atol=1e-9, err_msg=name)
