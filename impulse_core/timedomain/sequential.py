"""Rigid impacts in sequence on a terrain, with resting contacts: the stiff limit of the compliant
rung when contacts touch down at different times or stay pressed.

It is the whole landing (:class:`impulse_core.timedomain.events.run._Landing`) without what the
first-impact models ignore: no joint springs, dampers or stops, gravity only as
``SequentialSettings.gravity`` (default 0), one run at the fixed RK4 step ``flight_step`` (no
step halving). Between events the tree flies freely, or moves with resting contacts as rigid
unilateral constraints (with ``scene.friction > 0`` sticking or sliding by Coulomb's law), each
carrying a continuous force. At each touchdown every contact at the ground takes part in one
rigid impact along its local normal by the landing's law: Newton's restitution with
complementarity (the frictionless LCP, redundant contacts the lcp rung's smallest-norm split), or
with friction exact Coulomb friction on the impulses (the plane's LCP by Lemke's method, in space
the circular cone). An approach slower than :data:`~impulse_core.timedomain.landing.PLASTIC_SPEED`
(1e-4 m/s) is plastic, and a plastic contact rests from then on until its force would pull (a
lift-off event), so a contact that the tree keeps turning into the ground no longer chatters.

The run ends when the impacts are over (as the compliant rung's ``SEPARATED``): no contact pushes
(a closed contact whose force is zero rests unloaded and does not hold it) and none approaches the
ground that is below it or has not touched yet; or at ``max_time``. ``external`` and
``tangential`` per contact are the impulses over the events and the resting phases (the compliant
rung's contact impulse includes both), ``internal`` the joint impulses over the same (each
subtree's momentum change minus the contact impulses on it). With simultaneous touchdowns on flat
ground and all impulses positive this is the paper's eq. 11 (:func:`sequential_impacts` equals
``impulse_core.evaluate``), with friction the friction rung.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from impulse_core.impact.coulomb import ContactMode
from impulse_core.kinematics.spatial import PLANAR, Space
from impulse_core.model.heightfield import Heightfield
from impulse_core.model.terrain import Terrain
from impulse_core.model.tree import ContactSelection, Scene, Tree
from impulse_core.timedomain.compliant import joint_impulses, landing_ground, touchdown_order

if TYPE_CHECKING:
    from impulse_core.timedomain.events.rows import _Mode
    from impulse_core.timedomain.events.run import _Landing
    from impulse_core.timedomain.events.tally import _Totals
    from impulse_core.timedomain.landing import LandingResult

MODEL_NAME = "newton-sequential on terrain (LCP at each touchdown, resting contacts, RK4 between events)"
#: With friction: the exact Newton-Coulomb law at each touchdown.
FRICTION_MODEL_NAME = ("newton-coulomb-sequential on terrain (exact Coulomb friction at each touchdown, resting "
                       "contacts sticking or sliding, RK4 between events)")


@dataclass(frozen=True)
class SequentialSettings:
    """Parameters of the sequential rigid model.

    Attributes:
        flight_step: the RK4 step between events (s; events are located within it).
        contact_tolerance: at the first touchdown, contacts within this height (m) of the lowest
            touch; later, a contact within it of the ground rests on it after a plastic impact.
        gravity: m/s^2 along -y.
        max_time: stop after this long (s).
    """

    flight_step: float = 1.0e-4
    contact_tolerance: float = 1.0e-9
    gravity: float = 0.0
    max_time: float = 0.1


@dataclass(frozen=True)
class ImpactEvent:
    """One rigid impact: when, which contacts took part (declared indices: those at the ground that
    approached it or were pushed), their normal impulses (N s) and, with friction, their tangential
    impulses (the plane: along each contact's ground tangent; space: [t_x, t_z]) and modes; None
    without friction."""

    time: float
    contacts: tuple[int, ...]
    impulses: np.ndarray
    tangential: np.ndarray | None = None
    modes: tuple[ContactMode, ...] | None = None


@dataclass(frozen=True)
class SequentialResult:
    """The sequence of rigid impacts and resting phases. Same fields and units as the compliant
    result where they exist: external (normal impulse per declared contact over the events and the
    resting phases), external_vector (n_c x d), internal (joint impulses over the same, n_joints x
    3), internal_magnitude, norms, touchdown_time (each contact's first impact) and order, the state
    at the end, kinetic energy before the first impact and at the end, and the events;
    ``tangential`` per declared contact (summed as ``external``: n_c in the plane, n_c x 2 in space;
    0 without friction) and, with friction, ``modes``: each contact's mode at its last impact
    (``separating`` if it never touched); ``end``: the time the run ended (s)."""

    external: np.ndarray
    external_vector: np.ndarray
    internal: np.ndarray
    internal_magnitude: np.ndarray
    external_norm: float
    internal_norm: float
    touchdown_time: np.ndarray
    touchdown_order: tuple[int, ...]
    events: tuple[ImpactEvent, ...]
    q_plus: np.ndarray
    v_plus: np.ndarray
    energy_before: float
    energy_after: float
    energy_gain: bool
    model: str = MODEL_NAME
    tangential: np.ndarray | None = None
    modes: tuple[ContactMode, ...] | None = None
    end: float = 0.0

    @property
    def active(self) -> tuple[int, ...]:
        """Contacts that touched, in declaration order."""
        return tuple(int(i) for i in np.flatnonzero(np.isfinite(self.touchdown_time)))

    @property
    def max_internal(self) -> float:
        return float(self.internal_magnitude.max()) if self.internal_magnitude.size else 0.0


def sequential_impacts(
    tree: Tree,
    scene: Scene,
    settings: SequentialSettings = SequentialSettings(),
    terrain: Terrain | Heightfield | None = None,
    base_x: float | None = None,
    v_minus: np.ndarray | None = None,
    space: Space = PLANAR,
) -> SequentialResult:
    """Rigid impacts of ``tree`` landing on ``terrain``, with resting contacts (module docstring).

    ``terrain`` and ``base_x``, when given, override the scene's own ``scene.terrain`` and
    ``scene.base_x`` (:func:`impulse_core.timedomain.compliant.scene_ground`); ``v_minus``, the
    scene's approach. In space (``space`` SPATIAL) the ground is ``scene.heightfield`` (or
    ``terrain``, a ``Heightfield``), impulse vectors and joint impulses have three components, and
    ``v_plus`` is the core's velocity (world angular velocity), as the compliant rung's.

    Raises:
        NumericalError: a non-finite state, more than the landing's events, or no solution of the
            impact law.
    """
    run = _sequential_landing(tree, scene, settings, terrain, base_x, v_minus, space)
    log: list = []
    run.impact_log = log
    touched = np.zeros(run.nc, bool)
    kept: list[_Totals] = []  # the run's totals, as the end test last saw them

    def over(q: np.ndarray, v: np.ndarray, mode: _Mode, totals: _Totals) -> bool:
        kept[:] = [totals]
        return _impacts_over(run, q, v, mode, _touched(log, touched))

    out = run.run(settings.flight_step, until=over)  # asked first at t = 0: kept is set
    return _sequential_result(run, out, log, kept[0])


def _sequential_landing(
    tree: Tree, scene: Scene, settings: SequentialSettings, terrain: Terrain | Heightfield | None,
    base_x: float | None, v_minus: np.ndarray | None, space: Space,
) -> _Landing:
    """The whole landing of :func:`sequential_impacts`: on its ground, with ``settings``' gravity,
    to ``max_time``, no joint laws, the first impact over the lowest contacts (within
    ``contact_tolerance``), one RK4 run at ``flight_step``, keeping joint impulses and impacts.
    Imported here: the landing needs scipy, which importing this module does not (``test_imports``)."""
    from impulse_core.timedomain.events.run import _Landing
    from impulse_core.timedomain.landing import NUMPY_CODE, RK4, LandingSettings

    ground, x, z = landing_ground(scene, terrain, base_x, space)
    on = (replace(scene, terrain=ground, base_x=x) if space.joint_axis is not None
          else replace(scene, heightfield=ground, base_x=x, base_z=z))
    on = replace(on, duration=settings.max_time, gravity=settings.gravity, selection=ContactSelection.LOWEST,
                 contact_tolerance=settings.contact_tolerance)
    run = _Landing(tree, on, (), LandingSettings(step=settings.flight_step, integrator=RK4, step_code=NUMPY_CODE),
                   space)
    run.tally_joint = True
    run.v_minus = None if v_minus is None else np.array(v_minus, dtype=float).ravel()
    return run


def _took_part(entry: tuple) -> np.ndarray:
    """The contacts of a logged impact (:attr:`_Landing.impact_log`) that approached the ground or
    were pushed."""
    _, v, contacts, pt, law = entry
    return contacts[(pt.vn(v)[contacts] < 0.0) | (law.normal[contacts] > 0.0)]


def _touched(log: list, touched: np.ndarray) -> np.ndarray:
    """``touched`` (updated in place) with the contacts of the impacts logged since: every contact
    that took part in one."""
    for entry in log[-1:]:  # asked after every event: only the last impact is new
        touched[_took_part(entry)] = True
    return touched


def _impacts_over(run: _Landing, q: np.ndarray, v: np.ndarray, mode: _Mode, touched: np.ndarray) -> bool:
    """No contact pushes (:meth:`_Landing.pressing`) and none approaches the ground that has not
    touched yet or is below it (as the compliant rung's ``SEPARATED``)."""
    pt = run.point(q, v)
    approaching = pt.vn(v) < 0.0
    if np.any(approaching & (~touched | (pt.gap < 0.0))):
        return False
    return not np.any(run.pressing(q, v, mode))


def _sequential_result(run: _Landing, out: LandingResult, log: list, totals: _Totals) -> SequentialResult:
    """The :class:`SequentialResult` of the run ``out`` (its impacts ``log``, its ``totals``)."""
    from impulse_core.timedomain.landing import impact_modes

    friction = run.mu > 0
    touchdown = np.full(run.nc, np.nan)
    modes = [ContactMode.SEPARATING] * run.nc
    events = []
    for event, entry in zip(out.events, log, strict=True):
        _, v, _, pt, law = entry
        idx = _took_part(entry)
        touchdown[idx[np.isnan(touchdown[idx])]] = event.time
        public = run.public_tangential(law.tangential)[idx] if friction else None
        these = impact_modes(pt, v, law.v_plus, idx, law.normal[idx]) if friction else None
        for i, m in zip(idx, these or (), strict=False):
            modes[i] = m
        events.append(ImpactEvent(event.time, tuple(int(i) for i in idx), law.normal[idx], public, these))
    internal, magnitude = joint_impulses(totals.joint)
    external = out.total_external
    return SequentialResult(
        external=external,
        external_vector=totals.vectors.T.copy(),
        internal=internal,
        internal_magnitude=magnitude,
        external_norm=float(np.linalg.norm(external)),
        internal_norm=float(np.linalg.norm(magnitude)),
        touchdown_time=touchdown,
        touchdown_order=touchdown_order(touchdown, 0.0),
        events=tuple(events),
        q_plus=out.q_final,
        v_plus=out.v_final,
        energy_before=out.energy_before,
        energy_after=out.energy_final,
        energy_gain=out.energy_final > out.energy_before * (1.0 + 1e-9),
        model=FRICTION_MODEL_NAME if friction else MODEL_NAME,
        tangential=out.total_tangential,
        modes=tuple(modes) if friction else None,
        end=out.duration,
    )


__all__ = ["ImpactEvent", "SequentialResult", "SequentialSettings", "sequential_impacts"]
