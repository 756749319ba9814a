"""The whole landing (impulse_core.timedomain.landing): laws it must obey and hand derivations.

- a vertical rod bouncing on its tip: every event's impulse, time and restitution by hand, the
  plastic end of the bounces, settled_at and the momentum balance;
- the first event equals the first-impact answer (lcp, friction) for the same file;
- seeded random legs with springs, stops, gravity and friction: momentum balance over the
  landing, Newton's restitution and Coulomb's cone at every event, subtree balance behind every
  joint impulse;
- a foot resting flat with a sprung, damped upright: the settled angle solves the static
  equilibrium;
- the accuracy setting: a finer tolerance moves the answer by less than the coarser one's estimate.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from impulse_core.evaluate import evaluate
from impulse_core.impact.laws import ImpactModel
from impulse_core.model.joints import FREE, JointLaw
from impulse_core.model.tree import Body, ContactSelection, Scene, Tree
from impulse_core.timedomain.landing import PLASTIC_SPEED, SETTLE_SPEED, LandingSettings, _Landing, landing

G = 9.81


def _rod(mass: float = 2.0, length: float = 0.5, angle: float = -math.pi / 2) -> Tree:
    return Tree((Body("rod", None, length, mass, angle, contacts=(1.0,)),))


def test_vertical_rod_bounces_as_derived_by_hand():
    """A rod standing on its tip, dropped at v0 with restitution e: impulse k is m (1 + e) e^k v0
    at t_k = sum_{j<k} 2 e^(j+1) v0 / g, until the approach is below the plastic speed; it then
    rests, and the ground carries m g for the rest of the landing."""
    m, v0, e, T = 2.0, 1.5, 0.5, 0.5
    scene = Scene(speed=v0, restitution=e, gravity=G, duration=T)
    r = _Landing(_rod(m), scene, (), LandingSettings()).run(1e-3)
    approach, t = v0, 0.0
    for k, event in enumerate(r.events):
        assert event.time == pytest.approx(t, abs=1e-9), k
        e_k = e if approach > PLASTIC_SPEED else 0.0
        assert event.external[0] == pytest.approx(m * (1 + e_k) * approach, rel=1e-7, abs=1e-9 * m * v0), k
        assert event.v_plus[1] == pytest.approx(e_k * approach, rel=1e-6, abs=1e-9 * v0), k
        t += 2 * e * approach / G
        approach *= e
    n_bounces = 1 + math.ceil(math.log(PLASTIC_SPEED / v0) / math.log(e))  # the last one plastic
    assert len(r.events) == n_bounces
    assert r.events[-1].v_plus[1] == 0.0 and -r.events[-1].v_minus[1] < PLASTIC_SPEED
    last_fast = next(ev for ev in r.events if ev.v_plus[1] < SETTLE_SPEED)
    assert r.settled_at == pytest.approx(last_fast.time, abs=1e-9)
    assert r.total_external[0] == pytest.approx(m * v0 + m * G * T, rel=1e-9)
    assert abs(r.v_final).max() < 1e-9
    assert r.final_angles[0] == pytest.approx(-math.pi / 2, abs=1e-12)
