"""The compliant rungs' joint impulses under gravity, against a hand derivation.

A welded T lands straight down on the tip of its vertical post: every centre of mass lies on the
vertical through the contact, so the tree translates without turning. While the contact pushes,
the welded mast moves with the post: its momentum rate m_c a is the joint force plus its weight,
and a = F / M - g for the whole tree (mass M, contact force F). The joint force is m_c a + m_c g =
(m_c / M) F at every instant, so the joint impulse is (m_c / M) times the contact impulse, with or
without gravity. A joint tally that adds gravity's impulse instead of subtracting it misses this by
2 m_c g times the loaded time.

Also the touchdown order's grouping (:func:`touchdown_order`), by hand.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from impulse_core.model.tree import Body, JointKind, Scene, Tree
from impulse_core.timedomain.adaptive import simulate_adaptive
from impulse_core.timedomain.compliant import CompliantSettings, ContactLaw, simulate_impact, touchdown_order

POST, MAST = 2.0, 0.7  # kg
TEE = Tree((
    Body("post", None, 1.0, POST, -math.pi / 2, contacts=(1.0,)),  # straight down from the base origin
    Body("mast", 0, 0.5, MAST, math.pi, at=0.0, joint=JointKind.FIXED),  # straight up from it
))
SCENE = Scene(speed=1.5, restitution=0.5)


def _check(r) -> None:  # type: ignore[no-untyped-def]
    expected = MAST / (POST + MAST) * r.external[0]
    assert r.external[0] > 1.0
    assert r.internal[0][1] == pytest.approx(expected, rel=1e-9)
    assert abs(r.internal[0][0]) <= 1e-6 * expected and abs(r.internal[0][2]) <= 1e-12 * expected


@pytest.mark.parametrize("law", [ContactLaw.PENALTY, ContactLaw.CONSTRAINT])
@pytest.mark.parametrize("gravity", [0.0, 9.81])
def test_a_welded_mast_carries_its_share_of_the_contact_impulse(gravity: float, law: ContactLaw) -> None:
    """Fixed steps (semi-implicit Euler); soft contact, so the loaded time (a few ms) makes
    gravity's impulse on the mast 10 % of the joint impulse."""
    r = simulate_impact(TEE, SCENE, CompliantSettings(law=law, stiffness=2e4, gravity=gravity))
    _check(r)


@pytest.mark.parametrize("gravity", [0.0, 9.81])
def test_the_adaptive_rung_balances_the_mast_too(gravity: float) -> None:
    r = simulate_adaptive(TEE, SCENE, CompliantSettings(stiffness=2e4, gravity=gravity), local_tolerance=1e-6)
    _check(r)


def test_touchdowns_within_one_step_of_the_last_are_simultaneous() -> None:
    """A chain of touchdowns each within the resolution of the previous one is one group, kept in
    declaration order; a gap wider than the resolution starts the next group; never-touched
    contacts (inf, nan) are left out."""
    dt = 1e-4
    times = np.array([3.5 * dt, 0.0, 0.6 * dt, np.inf, 1.4 * dt, 2.0 * dt, np.nan])
    # 0, 0.6, 1.4, 2.0 chain within dt of each other: one group {1, 2, 4, 5}; 3.5 is 1.5 dt later
    assert touchdown_order(times, dt) == (1, 2, 4, 5, 0)
    assert touchdown_order(np.array([2 * dt, 0.0]), dt) == (1, 0)
    assert touchdown_order(np.array([0.5 * dt, 0.0]), dt) == (0, 1)
