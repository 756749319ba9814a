"""A turning base's unwrapped rotation vector (``impulse_core.timedomain.compliant.continued_rotation_vector``):
a turn by phi about a unit axis u, given the previous rotation vector near phi u, is phi u itself,
for turns of many revolutions either way (R alone knows phi only modulo 2 pi)."""

from __future__ import annotations

import math

import numpy as np

from impulse_core.model.rods import rotation_axis
from impulse_core.timedomain.compliant import continued_rotation_vector


def test_a_turn_of_many_revolutions_is_continued_from_the_previous_vector() -> None:
    rng = np.random.default_rng(12)
    for _ in range(200):
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        phi = float(rng.uniform(-20.0, 20.0))  # about three turns either way
        previous = (phi + float(rng.uniform(-0.5, 0.5))) * u + rng.normal(scale=0.05, size=3)
        got = continued_rotation_vector(rotation_axis(u, phi), previous)
        assert np.allclose(got, phi * u, rtol=0, atol=1e-9), (phi, got / np.linalg.norm(got), u)


def test_without_a_previous_turn_the_principal_vector_is_returned() -> None:
    u = np.array([0.0, 0.6, 0.8])
    got = continued_rotation_vector(rotation_axis(u, 2.5 + 2 * math.pi), np.zeros(3))
    assert np.allclose(got, 2.5 * u, rtol=0, atol=1e-12)
