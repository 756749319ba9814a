"""The sequential rung's touchdown times are each contact's first impact, when a contact hits again.

A steep plank (a rigid rod with a contact at each end) comes down slowly under gravity onto its
lower end, which bounces (e = 0.9) twice more before the upper end lands: the lower end's
touchdown time is its first impact's (t = 0), not its last's, and the order is lower end first.
"""

from __future__ import annotations

import numpy as np

from impulse_core.model.tree import Body, Scene, Tree
from impulse_core.timedomain.sequential import SequentialSettings, sequential_impacts


def test_a_contact_that_bounces_keeps_its_first_touchdown_time() -> None:
    plank = Tree((Body("plank", None, 1.0, 1.0, -1.0, contacts=(0.0, 1.0)),))
    seq = sequential_impacts(plank, Scene(speed=0.5, restitution=0.9),
                             SequentialSettings(flight_step=1e-3, max_time=0.4, gravity=9.81))
    hits = {i: [ev.time for ev in seq.events if i in ev.contacts] for i in range(2)}
    assert len(hits[1]) >= 2 and len(hits[0]) >= 1  # the lower end hits again before the upper lands
    assert np.array_equal(seq.touchdown_time, [min(hits[0]), min(hits[1])])
    assert seq.touchdown_time[1] == 0.0 and seq.touchdown_time[0] > max(hits[1])
    assert seq.touchdown_order == (1, 0)
