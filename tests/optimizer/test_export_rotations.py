"""The exporters' rotation formulas (``optimizer.results.export.quaternion_of`` for MJCF,
``impulse_core.model.rods.rpy_of`` for URDF) against independent constructions, on seeded random
rotations and on rotations that send each branch of Shepperd's method its own case (the trace,
or the largest of R's three diagonal entries, leading)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from impulse_core.model.rods import rotation_axis, rpy_of
from optimizer.results.export import quaternion_of


def _from_quaternion(w: float, x: float, y: float, z: float) -> np.ndarray:
    """The textbook rotation matrix of a unit quaternion (w, x, y, z)."""
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def _rotations(rng: np.random.Generator) -> list[np.ndarray]:
    out = []
    for axis in np.eye(3):  # near half turns about each axis: that axis's diagonal entry leads
        for angle in (math.pi, 0.9 * math.pi, -0.8 * math.pi):
            out.append(rotation_axis(axis, angle))
    out.append(np.eye(3))  # the trace leads
    for _ in range(40):
        a = rng.normal(size=3)
        out.append(rotation_axis(a / np.linalg.norm(a), float(rng.uniform(-math.pi, math.pi))))
    return out


def test_every_branch_of_the_quaternion_gives_back_its_rotation() -> None:
    rng = np.random.default_rng(5)
    cases = set()
    for R in _rotations(rng):
        q = np.array(quaternion_of(R))
        cases.add(int(np.argmax([np.trace(R), R[0, 0], R[1, 1], R[2, 2]])))
        assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-12)
        assert q[0] >= 0.0
        assert np.allclose(_from_quaternion(*q), R, rtol=0, atol=1e-12), (R, q)
    assert cases == {0, 1, 2, 3}


def test_urdf_roll_pitch_yaw_gives_back_its_rotation() -> None:
    """R = Rz(yaw) Ry(pitch) Rx(roll), URDF's convention, from the elementary rotations."""
    rng = np.random.default_rng(6)
    for R in _rotations(rng):
        roll, pitch, yaw = rpy_of(R)
        x, y, z = np.eye(3)
        back = rotation_axis(z, yaw) @ rotation_axis(y, pitch) @ rotation_axis(x, roll)
        assert np.allclose(back, R, rtol=0, atol=1e-12), (R, (roll, pitch, yaw))
