"""The whole landing against an independent peer of the same rigid law: Moreau-Jean time stepping
on Pinocchio's dynamics, solved by nonsmooth Gauss-Seidel (:mod:`optimizer.validation.moreau_jean`).

The peer converges at first order in its step to the rigid landing, so each check runs it at two
steps and asks footopt's answer to lie within the finer run's reach and the gap to shrink with the
step (footopt's own error at its default tolerance is below 1e-6 on these landings)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pinocchio")

from impulse_core.timedomain.landing import LandingSettings, landing  # noqa: E402
from optimizer.config.model_file import load_model_file  # noqa: E402
from optimizer.validation.moreau_jean import moreau_jean_landing  # noqa: E402
from tests.studies.scripts import study_module  # noqa: E402

REPO = Path(__file__).resolve().parents[2]


def _gaps(tree, laws, scene, steps):  # type: ignore[no-untyped-def]
    """Per peer step: footopt's landing's distance from the peer's (final angles in rad; each
    contact's total normal impulse and the peak step impulse, relative)."""
    ours = landing(tree, scene, laws, LandingSettings())
    rows = []
    for h in steps:
        peer = moreau_jean_landing(tree, scene, laws, h)
        rows.append((float(np.max(np.abs(peer.final_angles - ours.final_angles))),
                     float(np.max(np.abs(peer.total_external - ours.total_external)) / np.max(ours.total_external)),
                     abs(peer.peak_external_norm - ours.peak_external_norm) / ours.peak_external_norm))
    return rows


@pytest.mark.parametrize("velocity_x, friction", [(0.0, 0.5), (1.0, 0.3)])
def test_case3_landing_agrees_with_moreau_jean(velocity_x, friction):
    """Case 3 (heel and three toes with springs, restitution 0.8), its first 50 ms: the double Zeno
    cascade of 440 impacts and the toes' rest; straight down at friction 0.5 (every impact inside
    the cone), and at 1 m/s forward at friction 0.3 (the first impact slides every contact, at the
    cone's edge). The peer at 4e-5 and 2e-5 s is 1.0e-4 and 3.0e-5 rad from footopt's final angles
    straight down (1.9e-4 and 9.6e-5 sliding), its contact totals 5e-4 and 3e-4 (1e-3, 5e-4), its
    peak 6e-5 and 3e-5 (MuJoCo, a soft law, is 4.5e-3 rad away over the whole landing straight down:
    studies/whole_landing/speed.md)."""
    model = load_model_file(REPO / "configs" / "landing_case3.yaml")
    scene = replace(model.scene, duration=0.05, velocity_x=velocity_x, friction=friction)
    coarse, fine = _gaps(model.tree, model.joints, scene, (4e-5, 2e-5))
    assert fine[0] < 1.5e-4 and fine[1] < 1e-3 and fine[2] < 1e-4
    assert fine[0] < 0.6 * coarse[0]  # converging on footopt's answer


def test_a_rest_held_by_friction_agrees_with_moreau_jean():
    """``settled_posture.py --tips``'s random leg 6 over 0.12 s: a 1.7 kg plank on three sprung
    chains, friction 1, restitution 0.125; its first chain's tip bounces to rest at 52 ms, held by
    friction. There its free acceleration along the normal changes sign, so that at the velocity
    level both staying and leaving solve the contact problem: footopt keeps the rest while it holds
    (MODEL_FORMAT's transition rule), as the warm-started peer does (a peer started from zero
    impulses left it and was 7e-2 rad away by 0.1 s, MuJoCo 8e-2 after 3 s). At 4e-5 s the peer is
    within 1e-3 rad and 1e-3 of the totals."""
    tree, laws, scene = study_module("settled_posture").random_leg(6, True)
    (angles, totals, peak), = _gaps(tree, laws, replace(scene, duration=0.12), (4e-5,))
    assert angles < 1e-3 and totals < 1e-3 and peak < 2e-3
