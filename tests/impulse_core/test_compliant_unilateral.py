"""The compliant rung's contact forces never pull, under either contact law: a single contact (the
constraint law solves it in closed form) and several, landing and bouncing off (e = 0.8, where
the spring-damper's own force would turn negative before the contact leaves the ground)."""

from __future__ import annotations

import numpy as np
import pytest
from fidelity_scenes import PAPER_SCENE, case2, rod

from impulse_core.timedomain.adaptive import simulate_adaptive
from impulse_core.timedomain.compliant import CompliantSettings, ContactLaw, simulate_impact


@pytest.mark.parametrize("law", [ContactLaw.PENALTY, ContactLaw.CONSTRAINT])
@pytest.mark.parametrize("make", [rod, case2])
def test_contact_forces_never_pull(law: ContactLaw, make) -> None:  # type: ignore[no-untyped-def]
    settings = CompliantSettings(law=law, stiffness=1e5)
    for r in (simulate_impact(make(), PAPER_SCENE, settings), simulate_adaptive(make(), PAPER_SCENE, settings)):
        assert r.force.size and np.all(r.force >= 0.0), r.force.min()
        assert np.all(r.external >= 0.0) and r.external.max() > 0.0
