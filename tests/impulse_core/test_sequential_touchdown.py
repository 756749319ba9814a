"""The sequential rung's touchdown times and impact contacts: each contact's first impact, when one hits
again; every approaching contact takes part in an impact, with or without impulse.

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


def test_a_contact_that_approaches_takes_part_even_when_the_law_leaves_it_no_impulse() -> None:
    """Straight-down landings of seeded random trees with every contact in the first impact (a
    contact tolerance of 1 m): all approach, so all take part in it (its ``contacts``, touchdown
    at t = 0), also those that complementarity leaves without impulse (where eq. 11 would pull)."""
    from tests.conftest import random_tree

    rng = np.random.default_rng(11)
    unloaded = 0
    for _ in range(8):
        tree = random_tree(rng, 3, p_contact=1.0, max_contacts_per_body=2, p_fixed=0.0)
        seq = sequential_impacts(tree, Scene(speed=2.0, restitution=0.5),
                                 SequentialSettings(contact_tolerance=1.0, max_time=0.02, flight_step=1e-3))
        first = seq.events[0]
        assert first.time == 0.0 and first.contacts == tuple(range(len(tree.contacts)))
        assert np.all(seq.touchdown_time == 0.0)
        unloaded += int(np.sum(first.impulses == 0.0))
    assert unloaded >= 3
