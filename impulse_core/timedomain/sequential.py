"""Rigid impacts in sequence on a terrain: the stiff limit of the compliant rung when contacts
touch down at different times.

Between touchdowns the tree flies freely (the same Lagrangian dynamics as
:mod:`impulse_core.timedomain.compliant`, integrated with classical Runge-Kutta 4 and a fixed step; a
touchdown is located by bisection on the step length). At each touchdown every contact that
touches (|gap| <= ``contact_tolerance``) and approaches the ground takes part in one rigid impact
by Newton's restitution law with complementarity (the frictionless LCP: impulses lambda >= 0,
post-impact normal velocities u+ = u- + A lambda >= -e u-, complementary), A = Jn M^-1 Jn^T
along the terrain normals. With simultaneous touchdowns on flat ground and all impulses positive
this is the paper's eq. 11, and :func:`sequential_impacts` equals ``impulse_core.evaluate``.

With friction (``scene.friction > 0``) each touchdown is the whole landing's impact law
(:meth:`impulse_core.timedomain.landing._Landing.contact_impact`: Newton's restitution with exact
Coulomb friction on the impulses, the plane's LCP by Lemke's method, in space the circular cone)
over the same contacts, each along its local normal and tangents; tangential impulses are summed
over the events as the normal ones, and each contact's mode is the one of its last impact
(``separating`` if it never touched). With simultaneous touchdowns on flat ground this is the
friction rung.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from impulse_core.errors import NumericalError
from impulse_core.evaluate import pre_impact_velocity
from impulse_core.impact.coulomb import ContactMode
from impulse_core.impact.nnls import nnls
from impulse_core.kinematics.spatial import PLANAR, Space, values_space
from impulse_core.model.heightfield import Heightfield
from impulse_core.model.terrain import Terrain
from impulse_core.model.tree import Scene, Tree
from impulse_core.timedomain.compliant import (
    _check_chart,
    _Evaluator,
    _State,
    joint_impulses,
    landing_ground,
    subtree_incidence,
    touchdown_evaluator,
    touchdown_order,
    world_velocity,
)

if TYPE_CHECKING:
    from impulse_core.timedomain.landing import _Landing

MODEL_NAME = "newton-sequential on terrain (LCP at each touchdown, RK4 flight)"
#: With friction: the exact Newton-Coulomb law at each touchdown.
FRICTION_MODEL_NAME = "newton-coulomb-sequential on terrain (exact Coulomb friction at each touchdown, RK4 flight)"


@dataclass(frozen=True)
class SequentialSettings:
    """Parameters of the sequential rigid model.

    Attributes:
        flight_step: RK4 step of the free flight between touchdowns (s).
        contact_tolerance: a contact within this distance of the ground (m) touches.
        time_tolerance: touchdowns are located to this (s).
        gravity: m/s^2 along -y.
        max_time: stop looking for touchdowns after this long (s).
    """

    flight_step: float = 1.0e-4
    contact_tolerance: float = 1.0e-9
    time_tolerance: float = 1.0e-12
    gravity: float = 0.0
    max_time: float = 0.1


@dataclass(frozen=True)
class ImpactEvent:
    """One rigid impact: when, which contacts (declared indices), their normal impulses (N s) and,
    with friction, their tangential impulses (the plane: along each contact's ground tangent; space:
    [t_x, t_z]) and modes; None without friction."""

    time: float
    contacts: tuple[int, ...]
    impulses: np.ndarray
    tangential: np.ndarray | None = None
    modes: tuple[ContactMode, ...] | None = None


@dataclass(frozen=True)
class SequentialResult:
    """The sequence of rigid impacts. Same fields and units as the compliant result where they
    exist: external (normal impulse per declared contact, summed over events), external_vector
    (n_c x 2), internal (joint impulses summed over events, n_joints x 3), internal_magnitude,
    norms, touchdown_time and order, the state after the last impact, kinetic energy before the
    first and after the last impact, and the events; ``tangential`` per declared contact (summed over
    the events as ``external``: n_c in the plane, n_c x 2 in space; 0 without friction) and, with
    friction, ``modes``: each contact's mode at its last impact (``separating`` if it never touched)."""

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

    @property
    def active(self) -> tuple[int, ...]:
        """Contacts that touched, in declaration order."""
        return tuple(int(i) for i in np.flatnonzero(np.isfinite(self.touchdown_time)))

    @property
    def max_internal(self) -> float:
        return float(self.internal_magnitude.max()) if self.internal_magnitude.size else 0.0


def _lcp_impulse(A: np.ndarray, u: np.ndarray, e: float) -> np.ndarray:
    """Newton's law with complementarity: lambda >= 0, A lambda + (1 + e) u >= 0, complementary;
    the QP min lambda^T A lambda / 2 + (1 + e) u^T lambda, lambda >= 0, as an NNLS on the Cholesky
    factor of A (slightly regularised: redundant contacts make A singular)."""
    n = len(u)
    A = 0.5 * (A + A.T) + 1e-12 * np.trace(A) / n * np.eye(n)
    if n == 1:
        return np.array([max(0.0, -(1.0 + e) * u[0] / A[0, 0])])
    L = np.linalg.cholesky(A)
    return nnls(L.T, np.linalg.solve(L, -(1.0 + e) * u))


def _touchdown_state(
    tree: Tree,
    scene: Scene,
    settings: SequentialSettings,
    terrain: Terrain | Heightfield | None,
    base_x: float | None,
    v_minus: np.ndarray | None,
    space: Space = PLANAR,
) -> tuple[_Evaluator, np.ndarray, np.ndarray]:
    """The step function on the ground and the state (q, v) at the first touchdown
    (:func:`sequential_impacts`' arguments)."""
    evaluate_step, q = touchdown_evaluator(tree, scene, settings.gravity, terrain, base_x, space)
    if v_minus is None:
        v = pre_impact_velocity(tree.topology(), scene, space)
    else:
        v = np.array(v_minus, dtype=float).ravel()
    return evaluate_step, q, v


def _rk4_flight(evaluate_step: _Evaluator, q0: np.ndarray, v0: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """One RK4 step of the free flight (contact forces off)."""

    def accel(qq, vv):
        return evaluate_step(qq, vv).free.copy()

    k1q, k1v = v0, accel(q0, v0)
    k2q, k2v = v0 + 0.5 * dt * k1v, accel(q0 + 0.5 * dt * k1q, v0 + 0.5 * dt * k1v)
    k3q, k3v = v0 + 0.5 * dt * k2v, accel(q0 + 0.5 * dt * k2q, v0 + 0.5 * dt * k2v)
    k4q, k4v = v0 + dt * k3v, accel(q0 + dt * k3q, v0 + dt * k3v)
    return (
        q0 + dt / 6.0 * (k1q + 2 * k2q + 2 * k3q + k4q),
        v0 + dt / 6.0 * (k1v + 2 * k2v + 2 * k3v + k4v),
    )


def _fly(
    evaluate_step: _Evaluator, q: np.ndarray, v: np.ndarray, settings: SequentialSettings
) -> tuple[np.ndarray, np.ndarray, float]:
    """One flight step from (q, v): ``settings.flight_step`` long or, when a contact crosses the
    ground within it, up to that contact's touchdown (bisection on the step length); the state
    after it and its length."""
    h = settings.flight_step
    q1, v1 = _rk4_flight(evaluate_step, q, v, h)
    g1 = evaluate_step(q1, v1).gap.copy()
    crossing = g1 < -settings.contact_tolerance
    if not np.any(crossing):
        return q1, v1, h
    lo, hi = 0.0, h  # bisect the step length for the first touchdown
    while hi - lo > settings.time_tolerance:
        mid = 0.5 * (lo + hi)
        qm, vm = _rk4_flight(evaluate_step, q, v, mid)
        if np.min(evaluate_step(qm, vm).gap[crossing]) < 0.0:
            hi = mid
        else:
            lo = mid
    q1, v1 = _rk4_flight(evaluate_step, q, v, hi)
    return q1, v1, hi


def _rigid_impact(
    evaluate_step: _Evaluator,
    s: _State,
    q: np.ndarray,
    v: np.ndarray,
    idx: np.ndarray,
    e: float,
    in_subtree: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One rigid impact of the contacts ``idx`` at (q, v), ``s`` evaluated there: the velocity
    after it, their normal impulses (:func:`_lcp_impulse`), the impulse vectors of every contact
    (d x n_c, d = 2 in the plane, 3 in space) and the joint impulses (d x bodies: each subtree's
    momentum change minus the contact impulses on it)."""
    A = s.Jn[idx] @ s.minv_jnt[:, idx]
    lam = _lcp_impulse(A, s.rate[idx], e)
    momentum = s.momentum.copy()
    F = np.zeros((s.normal.shape[0], len(s.gap)))
    F[:, idx] = s.normal[:, idx] * lam
    v = v + s.minv_jnt[:, idx] @ lam
    s = evaluate_step(q, v)
    return v, lam, F, s.momentum - momentum - F @ in_subtree.T


def _impacts_over(s: _State, touchdown: np.ndarray) -> bool:
    """Some contact has touched and none approaches the ground that has not touched yet or is
    below it (as the compliant rung's ``SEPARATED``)."""
    untouched = np.isnan(touchdown)
    return bool(np.any(np.isfinite(touchdown)) and np.all((s.rate >= 0.0) | ~(untouched | (s.gap < 0.0))))


@dataclass(frozen=True)
class _Impacts:
    """The impacts so far, accumulated in place (:func:`_add_impact`): normal impulse per contact,
    impulse vectors (d x n_c), joint impulses (d x bodies), touchdown times, the events, tangential
    impulse per contact (n_c x (d - 1)) and each contact's mode at its last impact."""

    external: np.ndarray
    external_vector: np.ndarray
    joint: np.ndarray
    touchdown: np.ndarray
    events: list[ImpactEvent]
    tangential: np.ndarray
    modes: list[ContactMode]


def _no_impacts(nc: int, n_bodies: int, d: int = 2) -> _Impacts:
    """No impact yet: zero impulses, no touchdown (NaN), no events (d: 2 in the plane, 3 in space)."""
    return _Impacts(np.zeros(nc), np.zeros((d, nc)), np.zeros((d, n_bodies)), np.full(nc, np.nan), [],
                    np.zeros((nc, d - 1)), [ContactMode.SEPARATING] * nc)


def _add_impact(
    impacts: _Impacts, t: float, idx: np.ndarray, lam: np.ndarray, F: np.ndarray, joint_impulse: np.ndarray,
    tangential: np.ndarray | None = None, modes: tuple[ContactMode, ...] | None = None,
) -> None:
    """Add one rigid impact at ``t`` (:func:`_rigid_impact`'s or :func:`_friction_impact`'s output)
    to ``impacts``; the first impact of a contact is its touchdown.

    Raises:
        NumericalError: more than 1000 impacts (the contacts chatter).
    """
    impacts.external[idx] += lam
    np.add(impacts.external_vector, F, out=impacts.external_vector)
    touchdown = impacts.touchdown
    touchdown[idx[np.isnan(touchdown[idx])]] = t
    if tangential is not None and modes is not None:
        impacts.tangential[idx] += tangential
        for i, mode in zip(idx, modes, strict=True):
            impacts.modes[i] = mode
    public = None if tangential is None else tangential[:, 0].copy() if tangential.shape[1] == 1 else tangential
    impacts.events.append(ImpactEvent(t, tuple(int(i) for i in idx), lam, public, modes))
    np.add(impacts.joint, joint_impulse, out=impacts.joint)
    if len(impacts.events) > 1000:
        raise NumericalError("more than 1000 rigid impacts: the contacts chatter (lower the restitution?)")


def _sequential_result(
    impacts: _Impacts, q: np.ndarray, v: np.ndarray, energy_before: float, energy_after: float, friction: bool
) -> SequentialResult:
    """The :class:`SequentialResult` of the accumulated impacts, ending at (q, v)."""
    internal, magnitude = joint_impulses(impacts.joint)
    external, touchdown = impacts.external, impacts.touchdown
    return SequentialResult(
        external=external,
        external_vector=impacts.external_vector.T.copy(),
        internal=internal,
        internal_magnitude=magnitude,
        external_norm=float(np.linalg.norm(external)),
        internal_norm=float(np.linalg.norm(magnitude)),
        touchdown_time=touchdown,
        touchdown_order=touchdown_order(touchdown, 0.0),
        events=tuple(impacts.events),
        q_plus=q,
        v_plus=v,
        energy_before=energy_before,
        energy_after=energy_after,
        energy_gain=energy_after > energy_before * (1.0 + 1e-9),
        model=FRICTION_MODEL_NAME if friction else MODEL_NAME,
        tangential=impacts.tangential[:, 0].copy() if impacts.tangential.shape[1] == 1 else impacts.tangential.copy(),
        modes=tuple(impacts.modes) if friction else None,
    )


def sequential_impacts(
    tree: Tree,
    scene: Scene,
    settings: SequentialSettings = SequentialSettings(),
    terrain: Terrain | None = None,
    base_x: float | None = None,
    v_minus: np.ndarray | None = None,
    space: Space = PLANAR,
) -> SequentialResult:
    """Rigid impacts of ``tree`` landing on ``terrain``, one per touchdown (module docstring).

    Ends when no contact that has not touched yet approaches the ground (as the compliant rung),
    or at ``settings.max_time``. ``terrain`` and ``base_x``, when given, override the scene's own
    ``scene.terrain`` and ``scene.base_x`` (:func:`impulse_core.timedomain.compliant.scene_ground`).
    In space (``space`` SPATIAL) the ground is ``scene.heightfield`` (or ``terrain``, a
    ``Heightfield``), impulse vectors and joint impulses have three components, and ``v_plus`` is
    the core's velocity (world angular velocity), as the compliant rung's.

    With ``scene.friction > 0`` each touchdown has exact Coulomb friction (module docstring).

    Raises:
        NumericalError: a non-finite state, chattering contacts, or no solution of the impact law.
    """
    space = values_space(tree, space)  # a planar tree with centres of mass off its rods: their offsets too
    evaluate_step, q, v = _touchdown_state(tree, scene, settings, terrain, base_x, v_minus, space)
    law = _friction_law(tree, scene, terrain, base_x, space) if scene.friction > 0 else None
    in_subtree = subtree_incidence(tree)
    s = evaluate_step(q, v)
    energy_before = float(s.kinetic[0])
    impacts = _no_impacts(len(s.gap), tree.n_bodies, s.normal.shape[0])
    t = 0.0
    approaching = -1e-12 * max(abs(scene.speed), float(np.max(np.abs(v))), 1.0)  # m/s: below this, a contact hits
    while True:
        s = evaluate_step(q, v)
        hitting = (s.gap <= settings.contact_tolerance) & (s.rate < approaching)
        if np.any(hitting):
            idx = np.flatnonzero(hitting)
            if law is None:
                v, lam, F, joint_impulse = _rigid_impact(evaluate_step, s, q, v, idx, scene.restitution, in_subtree)
                _add_impact(impacts, t, idx, lam, F, joint_impulse)
            else:
                v, lam, F, joint_impulse, tangential, modes = _friction_impact(
                    law, evaluate_step, q, v, idx, scene.restitution, in_subtree
                )
                _add_impact(impacts, t, idx, lam, F, joint_impulse, tangential, modes)
            continue
        if _impacts_over(s, impacts.touchdown) or t >= settings.max_time:
            break
        q, v, step = _fly(evaluate_step, q, v, settings)
        t += step
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
            raise NumericalError(f"the free flight diverged at t = {t:.3g} s")
        _check_chart(q, space, t)
    energy_after = float(evaluate_step(q, v).kinetic[0])
    return _sequential_result(impacts, q, world_velocity(q, v, space), energy_before, energy_after, law is not None)


def _friction_law(
    tree: Tree, scene: Scene, terrain: Terrain | Heightfield | None, base_x: float | None, space: Space
) -> _Landing:
    """The whole landing's dynamics on the sequential model's ground, for its impact law
    (:meth:`_Landing.contact_impact`); nothing of it acts over time here. Imported here: the
    landing needs scipy, which the frictionless model does not (``test_imports``)."""
    from impulse_core.timedomain.landing import NUMPY_CODE, LandingSettings, _Landing

    ground, x, z = landing_ground(scene, terrain, base_x, space)
    on = (replace(scene, terrain=ground, base_x=x) if space.joint_axis is not None
          else replace(scene, heightfield=ground, base_x=x, base_z=z))
    return _Landing(tree, replace(on, duration=None), (), LandingSettings(step_code=NUMPY_CODE), space)


def _friction_impact(
    law: _Landing,
    evaluate_step: _Evaluator,
    q: np.ndarray,
    v: np.ndarray,
    idx: np.ndarray,
    e: float,
    in_subtree: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, tuple[ContactMode, ...]]:
    """One rigid impact of the contacts ``idx`` at (q, v) with exact Coulomb friction: the velocity
    after, their normal impulses, the impulse vectors of every contact (d x n_c), the joint impulses
    (d x bodies, as :func:`_rigid_impact`), their tangential impulses (len(idx) x (d - 1)) and modes."""
    from impulse_core.timedomain.landing import contact_impulses, impact_modes

    pt, impact = law.contact_impact(q, v, idx, e)
    F = contact_impulses(pt, impact.normal, impact.tangential)
    momentum = evaluate_step(q, v).momentum.copy()
    joint = evaluate_step(q, impact.v_plus).momentum - momentum - F @ in_subtree.T
    modes = impact_modes(pt, v, impact.v_plus, idx, impact.normal[idx])
    return impact.v_plus, impact.normal[idx], F, joint, impact.tangential[idx], modes


__all__ = ["ImpactEvent", "SequentialResult", "SequentialSettings", "sequential_impacts"]
