"""Radau IIA (and RK4) keep identical toes (twins) identical (:meth:`_Landing.held_alike`): trial 64 of the
landing study (``configs/landing_study.yaml``, ``studies/whole_landing/stiff_designs.md``), two
identical two-rod toes that reach their stops at once with both tips pressed at 3.77 ms, an
impact whose split between the toes is ill-conditioned in their parting. Left to themselves,
Radau's Newton iterations parted the toes by rounding (5.6e-11 rad by the impact, where the
study's RK4 landing kept them equal to the bit), the impact split 2.94 and 0.09 N s where the
even split is 1.52 and 1.52, and the landing ended 0.33 from RK4's reference with an estimate of
8e-8."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from impulse_core.timedomain.events.run import _Landing
from impulse_core.timedomain.events.settings import RADAU, RK4
from impulse_core.timedomain.events.twins import mode_alike
from optimizer.config.model_file import load_model_file
from optimizer.design_space import study_landing

DATA = Path(__file__).parent / "data"
#: past the impact of both toes on their stops (3.774 ms)
UNTIL = 0.005


def _run(integrator: str, step: float | None = None, hold: bool | None = None):
    m = load_model_file(DATA / "twin_stops_64.yaml")
    scene = replace(m.scene, duration=UNTIL)
    run = _Landing(m.tree, scene, m.joints, replace(study_landing(1e-3), integrator=integrator), m.space)
    if hold is not None:
        run.hold_twins = hold
    # the study's landing: Radau IIA from its first step (duration / 200 of the whole landing)
    result = run.run(step if step is not None else m.scene.duration / 200.0)
    return run, result


def test_radau_keeps_twin_toes_identical_through_their_stops() -> None:
    run, r = _run(RADAU)
    (group,) = run.twins
    assert group.tolist() == [[5, 6], [7, 8]]
    assert run.twin_contacts[0].tolist() == [[1], [2]]  # the toes' tips (the heel's is contact 0)
    t, q = r.trajectory
    assert t[-1] >= UNTIL * (1 - 1e-12)
    toe1, toe2 = group[0][0] - 3, group[1][0] - 3  # the proximal joints' stops (per non-base body)
    peak = max(r.events, key=lambda e: e.external_norm)
    assert 3.7e-3 < peak.time < 3.85e-3 and peak.stop[toe1] and peak.stop[toe2]  # both toes reach their stops
    # equal to the bit up to that impact (RK4 and the exact landing keep them so; Radau IIA parted them by 5.6e-11)
    before = t < peak.time
    assert np.array_equal(q[before][:, group[0]], q[before][:, group[1]])
    # after it the contacts' mode lifts toe2's tip for 9 us (one of the rows' choices, as on RK4): the toes
    # part (a mode that treats them apart is followed, not averaged against its projection), then meet again
    # when it touches down, and are equal to the bit at the end
    after = (t > peak.time) & (t < peak.time + 2e-5)
    assert np.max(np.abs(q[after][:, group[0]] - q[after][:, group[1]])) > 1e-6
    assert np.array_equal(r.q_final[group[0]], r.q_final[group[1]])
    assert np.array_equal(r.v_final[group[0]], r.v_final[group[1]])
    # the impact on both toes at once splits evenly between them (contacts 1 and 2: the toes' tips)
    assert abs(peak.external[1] - peak.external[2]) <= 1e-12 * peak.external[1] and peak.external[1] > 1.5
    assert abs(peak.stop[toe1] - peak.stop[toe2]) <= 1e-12 * abs(peak.stop[toe1]) and peak.stop[toe1] < -0.1
    # as an RK4 run at a quarter of its stable step, its twins held alike too (left alone, RK4's steps part
    # them by rounding here as well: 1e-16 rad by 0.25 ms at its stable step, and that impact split 2.94 and 0.09)
    _, ref = _run(RK4, 2.06e-5 / 4, hold=True)
    ref_peak = max(ref.events, key=lambda e: e.external_norm)
    assert abs(ref_peak.time - peak.time) < 1e-5
    assert abs(peak.external_norm - ref_peak.external_norm) <= 1e-3 * ref_peak.external_norm


def test_a_mode_that_parts_the_twins_is_not_held_alike() -> None:
    """:func:`mode_alike`: the twins' stops, contacts and slips equal twin by twin, or the mode
    parts them (one tip resting, the other lifted: the state is left as its projection put it)."""
    m = load_model_file(DATA / "twin_stops_64.yaml")
    run = _Landing(m.tree, m.scene, m.joints, replace(study_landing(1e-3), integrator=RADAU), m.space)
    stop, closed, slip = np.zeros(run.nv, int), np.array([False, True, True]), np.array([[0.0], [1.0], [1.0]])
    assert mode_alike(stop, closed, slip, run.twins, run.twin_contacts)
    assert not mode_alike(stop, np.array([False, True, False]), slip, run.twins, run.twin_contacts)
    assert not mode_alike(stop, closed, np.array([[0.0], [1.0], [-1.0]]), run.twins, run.twin_contacts)
    stop[5] = 1
    assert not mode_alike(stop, closed, slip, run.twins, run.twin_contacts)
    stop[7] = 1
    assert mode_alike(stop, closed, slip, run.twins, run.twin_contacts)


def test_rk4_keeps_twin_toes_identical_too() -> None:
    """RK4 at its stable step (2.06e-5 s) holds them too (the default on every integrator): left
    alone, its steps part the toes by rounding (1e-16 rad by 0.25 ms) and the impact on both toes
    splits unevenly, as Radau IIA's did."""
    run, r = _run(RK4, 2.06e-5)
    (group,) = run.twins
    t, q = r.trajectory
    peak = max(r.events, key=lambda e: e.external_norm)
    assert 3.7e-3 < peak.time < 3.85e-3
    assert np.array_equal(q[t < peak.time][:, group[0]], q[t < peak.time][:, group[1]])
    assert abs(peak.external[1] - peak.external[2]) <= 1e-12 * peak.external[1] and peak.external[1] > 1.5
    _, loose = _run(RK4, 2.06e-5, hold=False)
    parted = max(loose.events, key=lambda e: e.external_norm)
    assert abs(parted.external[1] - parted.external[2]) > 0.5 * max(parted.external[1], parted.external[2])
