"""The first instant on uneven ground: the lcp and friction rungs where the ground is not flat.

On a ``scene.terrain`` (planar) or ``scene.heightfield`` (spatial) that is not flat, the contacts
that touch at t = 0 are those of the whole landing's first event: the model, lowered straight
down until its first contact touches, and every contact within ``scene.contact_tolerance`` of
that gap (``contacts: all``: every declared one). Each pushes along its local ground normal, by
the landing's impact law (:func:`impulse_core.timedomain.landing.rigid_impact`): Newton's
restitution with the frictionless complementarity law (``lcp``) or exact Coulomb friction on the
impulses (``friction``; the plane's LCP by Lemke's method, in space the circular cone). This is
the whole landing's first event (its :meth:`~impulse_core.timedomain.events.run._Landing.touchdown`)
without what acts over time (gravity, joint laws), and on flat ground the flat rungs' answer.
``tangential`` is along each contact's ground tangent (:func:`~impulse_core.timedomain.events.point.tangent_basis`:
in space [t_x, t_z]).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from impulse_core.errors import ModelError
from impulse_core.evaluate import POLYHEDRAL_NOTE, ZERO_IMPULSE, ImpactResult, compiled_friction
from impulse_core.impact.coulomb import ContactMode
from impulse_core.impact.laws import ImpactModel
from impulse_core.kinematics.spatial import PLANAR, Space
from impulse_core.model.tree import Scene, Tree
from impulse_core.timedomain.events.run import _Landing
from impulse_core.timedomain.landing import NUMPY_CODE, LandingSettings, contact_impulses, impact_modes

#: What the result's ``reason`` says ran.
REASON = "first instant on uneven ground: contacts touching at t = 0 along their local normals"


def first_instant(tree: Tree, scene: Scene, model: ImpactModel, space: Space = PLANAR) -> ImpactResult:
    """The first impact of ``tree`` on the scene's ground (module docstring) by ``model``
    (``LCP`` or ``FRICTION``), as an :class:`~impulse_core.evaluate.ImpactResult`.

    Raises:
        ModelError: another model (newton, decoupled and friction-relaxed assume flat ground).
        NumericalError: the impact law found no solution.
    """
    if model not in (ImpactModel.LCP, ImpactModel.FRICTION):
        raise ModelError(f"model: {model.value} assumes flat ground; on uneven ground the first instant is lcp or friction")
    mu = scene.friction if model is ImpactModel.FRICTION else 0.0
    instant = replace(scene, friction=mu, duration=None, gravity=0.0)  # nothing acts over time
    run = _Landing(tree, instant, (), LandingSettings(step_code=NUMPY_CODE), space)
    q, v, v_plus, event, _ = run.touchdown()
    law = run.last_impact
    assert law is not None
    pt = run.point(q, v)
    active = tuple(int(i) for i in np.flatnonzero(_hit(run, pt)))
    internal = np.zeros((len(event.internal), 3))
    internal[:, : run.dims] = event.internal
    momentum = run.mass * scene.speed
    normal = event.external[list(active)]
    notes = () if law.exact else (POLYHEDRAL_NOTE,)
    return ImpactResult(
        external=event.external,
        active=active,
        internal=internal,
        internal_torque=_joint_torques(run, q, v, active, law.normal, law.tangential),
        internal_magnitude=event.internal_magnitude,
        external_norm=float(np.linalg.norm(normal)),
        internal_norm=event.internal_norm,
        v_minus=event.v_minus,
        v_plus=event.v_plus,
        energy_before=event.energy_before,
        energy_after=event.energy_after,
        contact_velocity=pt.Jn[list(active)] @ v_plus,
        split_unique=law.split_unique,
        pulling=tuple(i for i in active if event.external[i] < 0),
        model=model,
        reason=_reason(model, scene),
        tangential=event.tangential,
        tangent_velocity=None if model is ImpactModel.LCP else _slip(pt.Jt[list(active)] @ v_plus, run.dims),
        separating=tuple(i for i in active if abs(event.external[i]) <= ZERO_IMPULSE * momentum),
        modes=None if model is ImpactModel.LCP else _modes(len(tree.contacts), active, impact_modes(
            pt, v, v_plus, np.array(active, int), normal)),
        notes=notes,
    )


def _hit(run: _Landing, pt) -> np.ndarray:  # type: ignore[no-untyped-def]
    """Per declared contact: whether it takes part in the first event (:meth:`_Landing.first_contacts`)."""
    hit = np.zeros(run.nc, bool)
    hit[run.first_contacts(pt)] = True
    return hit


def _joint_torques(run: _Landing, q: np.ndarray, v: np.ndarray, active: tuple[int, ...], normal: np.ndarray,
                   tangential: np.ndarray) -> np.ndarray:
    """Each joint's torque impulse (n_joints x 3): the compiled response to the contacts' impulse
    vectors (world x, y(, z) components: the flat rungs' rows take any vector)."""
    F = contact_impulses(run.point(q, v), normal, tangential)[:, list(active)]
    along_x = F[0] if run.dims == 2 else np.concatenate([F[0], F[2]])
    out = compiled_friction(run.tree.topology(active), run.space)(
        p=run.design, v_minus=v, external=F[1], tangential=along_x
    )
    return np.array(out["internal_torque"]).T.reshape(-1, 3)


def _slip(rows: np.ndarray, dims: int) -> np.ndarray:
    """Tangential velocities per active contact: (n,) in the plane, (n, 2) in space."""
    return rows[:, 0].copy() if dims == 2 else rows.copy()


def _modes(nc: int, active: tuple[int, ...], modes: tuple[ContactMode, ...]) -> tuple[ContactMode, ...]:
    """Per declared contact: its mode in the impact, ``separating`` where it does not hit."""
    out = [ContactMode.SEPARATING] * nc
    for i, mode in zip(active, modes, strict=True):
        out[i] = mode
    return tuple(out)


def _reason(model: ImpactModel, scene: Scene) -> str:
    notes = ["requested", REASON]
    if model is ImpactModel.LCP and scene.friction > 0:
        notes.append(f"scene.friction = {scene.friction:g} is ignored by this frictionless rung")
    if model is ImpactModel.FRICTION and scene.friction == 0:
        notes.append("scene.friction = 0, so the friction rung gives the LCP answer")
    return "; ".join(notes)


__all__ = ["REASON", "first_instant"]
