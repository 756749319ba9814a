"""The whole landing against an independent peer of the same rigid law: Moreau-Jean time stepping
on Pinocchio's dynamics, solved by nonsmooth Gauss-Seidel (:mod:`optimizer.validation.moreau_jean`).

The peer converges at first order in its step to the rigid landing, so each check runs it at two
steps and asks footopt's answer to lie within the finer run's reach and the gap to shrink with the
step (footopt's own error at its default tolerance is below 1e-6 on these landings)."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")

from impulse_core.kinematics.spatial import SPATIAL, dof_layout  # noqa: E402
from impulse_core.timedomain.landing import LandingSettings, landing  # noqa: E402
from optimizer.config.model_file import load_model_file  # noqa: E402
from optimizer.validation.moreau_jean import SWEEPS, _cone_contact, _leg, _to_pin, moreau_jean_landing  # noqa: E402
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


def _spatial_gaps(seed: int, steps: tuple[float, ...], **changes):  # type: ignore[no-untyped-def]
    """Per peer step on ``settled_posture.py``'s spatial leg ``seed`` (its scene with ``changes``):
    footopt's landing's distance from the peer's (the posture frame-free, ``posture_gaps``: the
    larger of the base's relative turn and the largest joint gap, rad; each contact's total normal
    and tangential impulses, relative; the final velocity, relative), and the peer's landings."""
    study = study_module("settled_posture")
    tree, laws, scene = study.random_spatial_leg(seed)
    scene = replace(scene, **changes)
    ours = landing(tree, scene, laws, LandingSettings(), space=SPATIAL)
    rows, peers = [], []
    for h in steps:
        peer = moreau_jean_landing(tree, scene, laws, h, space=SPATIAL)
        turn, _, joints = study.posture_gaps(ours.final_angles, peer.final_angles, SPATIAL)
        tangential = np.abs(ours.total_tangential).max()
        rows.append((max(turn, joints),
                     float(np.max(np.abs(peer.total_external - ours.total_external)) / np.max(ours.total_external)),
                     float(np.max(np.abs(peer.total_tangential - ours.total_tangential)) / tangential)
                     if tangential > 0 else 0.0,
                     float(np.max(np.abs(peer.final_velocity - ours.v_final)) / np.max(np.abs(ours.v_final)))))
        peers.append(peer)
    return rows, peers


def test_a_spatial_leg_dropped_straight_agrees_with_moreau_jean():
    """``settled_posture.py --spatial``'s leg 3 (a body with a welded cross on three sprung chains,
    frictionless, restitution 0.19) over its first 50 ms: the spatial peer (a free-flyer base) at
    4e-5 and 2e-5 s is 6.1e-5 and 3.1e-5 rad from footopt's posture (first order), 1e-4 and 5e-5
    of its contact totals, 3.0e-4 and 1.5e-4 of its final velocity (the base's in the world
    frame)."""
    (coarse, fine), _ = _spatial_gaps(3, (4e-5, 2e-5), duration=0.05)
    assert fine[0] < 4e-5 and fine[1] < 1e-4 and fine[3] < 3e-4
    assert fine[0] < 0.6 * coarse[0]


def test_a_spatial_leg_sliding_obliquely_agrees_with_moreau_jean():
    """Leg 1 landing at 0.7 m/s forward and 0.7 m/s sideways (friction 0.3, restitution 0.08) over
    80 ms: its tips slide along the diagonal, where a square cone (|t_x|, |t_z| <= mu n) would hold
    more than the circular one. The peer at 4e-5 and 2e-5 s is 6.0e-5 and 3.0e-5 rad from
    footopt's posture, its tangential totals (x and z per contact, footopt's ``total_tangential``)
    1.2e-4 and 5.8e-5 apart, its final velocity 2.1e-4 and 1.0e-4."""
    (coarse, fine), peers = _spatial_gaps(1, (4e-5, 2e-5), duration=0.08, friction=0.3, velocity_x=0.7,
                                          velocity_z=-0.7)
    assert all(peer.sweeps < SWEEPS for peer in peers)  # Gauss-Seidel converged at every step
    assert fine[0] < 4e-5 and fine[1] < 1e-4 and fine[2] < 1e-4 and fine[3] < 3e-4
    assert fine[0] < 0.6 * coarse[0] and fine[2] < 0.6 * coarse[2]


def test_the_one_contact_law_is_the_circular_cones():
    """:func:`_cone_contact` on random one-contact problems (u = A r + b, A symmetric positive
    definite, mu 0.1-1.5): r in the circular cone; u_n >= 0, r_n u_n = 0; sticking (inside the
    cone) u = 0; on the cone's edge u_n = 0 and u_t against r_t. Every other problem solved again
    from the answer's opposite as the slide's start, and every fourth a slow slip (its sticking
    answer 1e-4 outside the cone: seed 1 of the spatial study at 0.26 s, where no scanned direction
    next to the root had u_t against d). Both sliding and sticking occur."""
    rng = np.random.default_rng(3)
    kinds = set()
    for k in range(800):
        L = rng.normal(size=(3, 3))
        A = L @ L.T + 0.05 * np.eye(3)
        b, mu = rng.normal(size=3), float(rng.uniform(0.1, 1.5))
        if k % 4 == 3:  # a slow slip: the sticking answer 1e-4 outside the cone
            turn = rng.uniform(0, 2 * math.pi)
            b = -A @ np.array([1.0, mu * (1 + 1e-4) * math.cos(turn), mu * (1 + 1e-4) * math.sin(turn)])
        r = _cone_contact(A, np.linalg.inv(A), b, mu, np.zeros(3))
        if k % 2:  # the slide's Newton started the other way round (its fallback's scan where it ends wrong)
            r = _cone_contact(A, np.linalg.inv(A), b, mu, -r)
        u = A @ r + b
        scale = np.abs(b).max()
        tangent = math.hypot(r[1], r[2])
        assert r[0] >= 0 and tangent <= mu * r[0] * (1 + 1e-12) and u[0] >= -1e-12 * scale
        assert abs(r[0] * u[0]) <= 1e-12 * scale * max(r[0], 1)
        if r[0] == 0:
            kinds.add("open")
        elif tangent < mu * r[0] * (1 - 1e-9):
            kinds.add("stick")
            assert np.abs(u).max() <= 1e-10 * scale
        else:
            kinds.add("slide")
            slip = u[1:]
            assert abs(u[0]) <= 1e-10 * scale
            assert abs(slip[0] * r[2] - slip[1] * r[1]) <= 1e-9 * scale * tangent and slip @ r[1:] <= 0
    assert kinds == {"open", "stick", "slide"}


def test_the_spatial_peer_balances_linear_momentum():
    """Over leg 1's oblique landing (80 ms), the change of the peer's linear momentum (Pinocchio's
    centre of mass velocity at its final state, read back from footopt's coordinates) equals the
    ground's impulses it reports (normal along y, tangential along x and z) and the weight's, to
    the scheme's first order in the step (the momentum at a step's end is read at the next
    configuration): 1.4e-4 and 6.9e-5 of the touchdown momentum at 4e-5 and 2e-5 s."""
    study = study_module("settled_posture")
    tree, laws, scene = study.random_spatial_leg(1)
    scene = replace(scene, duration=0.08, friction=0.3, velocity_x=0.7, velocity_z=-0.7)
    residuals = []
    for h in (4e-5, 2e-5):
        peer = moreau_jean_landing(tree, scene, laws, h, space=SPATIAL)
        leg = _leg(tree, scene.gravity, SPATIAL)
        revolute = [d is not None for d in dof_layout(tree.topology(), SPATIAL).body_dof[1:]]
        q_ours = np.concatenate([peer.final_base, peer.final_angles[:3], peer.final_angles[3:][revolute]])
        q, v = _to_pin(leg, q_ours, peer.final_velocity)
        data = leg.model.createData()
        pin.centerOfMass(leg.model, data, q, v)
        mass = sum(b.mass for b in tree.bodies)
        change = mass * (data.vcom[0] - np.array(scene.velocity))
        impulse = np.array([peer.total_tangential[:, 0].sum(), peer.total_external.sum() - mass * scene.gravity
                            * round(scene.duration / h) * h, peer.total_tangential[:, 1].sum()])
        residuals.append(float(np.abs(change - impulse).max()) / (mass * np.linalg.norm(scene.velocity)))
    assert residuals[1] < 1e-4 and residuals[1] < 0.6 * residuals[0]
