"""The whole landing where the first impact's contacts are not simply those touching: ``contacts:
all`` (contacts above the ground hit at t = 0 by the paper's assumption) and redundant contacts
(the split of the impulse is not unique). Both were found by a random sweep of model files."""

from __future__ import annotations

import math

import numpy as np
import pytest

from impulse_core.evaluate import evaluate
from impulse_core.impact.laws import ImpactModel
from impulse_core.kinematics.spatial import PLANAR, SPATIAL
from impulse_core.model.tree import Body, ContactSelection, JointKind, Scene, Tree
from impulse_core.timedomain.landing import LandingSettings, landing

SETTINGS = LandingSettings(step=1e-3)


@pytest.mark.parametrize("space", [PLANAR, SPATIAL], ids=["planar", "spatial"])
def test_a_contact_above_the_ground_hits_at_t0_and_then_flies_free(space):
    """A tilted rod with ``contacts: all``: its upper contact takes its share of the first impact
    (the lcp rung's answer) and is then in the air, not held at its height: the momentum balance
    holds (a contact kept closed 4 cm above the ground was projected down onto it, 2e-2), and it
    touches down later by itself."""
    rod = Tree((Body("rod", None, 0.4, 0.5, -0.3, contacts=(0.5, 1.0)),))
    scene = Scene(speed=0.6, velocity_x=0.8, restitution=0.0, selection=ContactSelection.ALL, gravity=9.81,
                  duration=0.2)
    r = landing(rod, scene, (), SETTINGS, space)
    first = evaluate(rod, scene, ImpactModel.LCP, space)
    assert np.max(np.abs(r.events[0].external - first.external)) <= 1e-9 * np.max(first.external)
    assert r.momentum_balance <= 1e-6
    later = [e for e in r.events[1:] if e.external[0] > 0]
    assert later and later[0].time > 0.01  # the upper contact (0.5) lands on its own, later


def test_redundant_frictionless_contacts_take_the_lcp_rungs_split():
    """Two rods welded into one body with four contacts in a row on the ground (a plank: three
    base DOFs, four rows): Newton's law fixes the velocity after, not the split; the landing's
    first event takes the lcp rung's smallest-norm non-negative split and counts the impact as
    non-unique."""
    plank = Tree((
        Body("a", None, 0.3, 1.0, 0.0, contacts=(0.0, 1.0)),
        Body("b", 0, 0.2, 0.7, 0.0, joint=JointKind.FIXED, contacts=(0.5, 1.0)),
    ))
    scene = Scene(speed=2.0, restitution=0.5, angular_velocity=1.5, selection=ContactSelection.ALL, gravity=9.81,
                  duration=0.05)
    r = landing(plank, scene, (), SETTINGS)
    first = evaluate(plank, scene, ImpactModel.LCP)
    assert not first.split_unique
    assert np.max(np.abs(r.events[0].external - first.external)) <= 1e-9 * np.max(first.external)
    assert r.non_unique >= 1
    assert math.isclose(np.sum(r.events[0].external), np.sum(first.external), rel_tol=1e-12)
