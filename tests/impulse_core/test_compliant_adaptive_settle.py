"""The adaptive compliant rung settles as the fixed-step one does: a pad landing at 1 cm/s under
gravity never lets go, and the run ends only once the contact has rested for a contact period,
with the weight carried (the contact's impulse m v0 + m g T) and the pad at rest on its static
deflection m g / k, not at a turning point of its first oscillation."""

from __future__ import annotations

import numpy as np
import pytest

from impulse_core.model.tree import Body, Scene, Tree
from impulse_core.timedomain.adaptive import simulate_adaptive
from impulse_core.timedomain.compliant import CompliantSettings, CompliantStatus


def test_a_slow_landing_under_gravity_settles_at_rest() -> None:
    puck = Tree((Body("puck", None, 0.2, 1.0, 0.0, contacts=(0.5,)),))
    g, k = 9.81, 1e5
    settings = CompliantSettings(stiffness=k, gravity=g, max_time=0.5)
    c = simulate_adaptive(puck, Scene(speed=0.01, restitution=0.5), settings)
    assert c.status is CompliantStatus.SETTLED
    assert abs(c.v_plus[1]) < 1e-4
    assert c.external[0] == pytest.approx(0.01 + g * c.duration, rel=1e-6)  # m v0 + m g T (m = 1 kg)
    assert c.duration > 2 * np.pi / np.sqrt(k)  # more than one contact period
    assert -c.q_plus[1] == pytest.approx(g / k, rel=1e-2)  # resting on its static deflection
    assert c.force[-1][0] == pytest.approx(g, rel=1e-2)  # carrying its weight
