"""What a whole landing returns: its impacts (:class:`LandingEvent`) and the landing itself
(:class:`LandingResult`), built by :meth:`.tally._Tally.result` at the end of a run."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from impulse_core.kinematics.spatial import PLANAR
from impulse_core.timedomain.events.settings import MODEL_NAME, RK4, VM_CODE


@dataclass(frozen=True)
class LandingEvent:
    """One impact of the landing.

    Attributes:
        time: s from the first touchdown.
        kind: "touchdown" (a contact touched or re-touched) or "stop" (a joint reached a stop).
        external: normal impulse per declared contact (0 where not involved), N s.
        tangential: tangential impulse per contact (along the ground tangent, +x on flat ground;
            space: n_c x 2, [t_x, t_z], :func:`tangent_basis`).
        internal: force impulse through each joint, parent onto child (n_joints x d, d = 2 or 3).
        internal_magnitude: |internal| per joint.
        stop: torque impulse of each joint's stop (N m s; 0 where not involved), per non-base body.
        v_minus, v_plus: generalized velocities before and after (space: base origin velocity,
            world angular velocity, joint rates).
        energy_before, energy_after: kinetic energy before and after (J).
        jam: an impulsive jam (:meth:`_Landing.jam`: Painleve's paradox at a sliding contact,
            no collision), reported with kind "touchdown" (an impact at the contacts).
    """

    time: float
    kind: str
    external: np.ndarray
    tangential: np.ndarray
    internal: np.ndarray
    internal_magnitude: np.ndarray
    stop: np.ndarray
    v_minus: np.ndarray
    v_plus: np.ndarray
    energy_before: float
    energy_after: float
    jam: bool = False

    @property
    def external_norm(self) -> float:
        return float(np.linalg.norm(self.external))

    @property
    def internal_norm(self) -> float:
        return float(np.linalg.norm(self.internal_magnitude))


@dataclass(frozen=True)
class LandingResult:
    """The whole landing (world frame; SI units).

    Attributes:
        events: every impact, in time order; the first is at t = 0.
        total_external: per contact, the normal impulse over [0, T], impulsive and continuous.
        total_tangential: the same for the tangential impulse (space: n_c x 2).
        settled_at: the earliest t after which every generalized velocity stays below
            :data:`SETTLE_SPEED`, or None.
        q_final, v_final: the state at T (q: base x, y, angle, then joint angles; space: base
            x, y, z, rotation vector phi, joint angles, and v_final world velocities as v_plus).
        final_angles: the base's absolute angle (space: its turn since touchdown, phi_x, phi_y,
            phi_z), then every joint's angle in file order (fixed joints: their fixed angle).
        energy_before: kinetic energy just before the first touchdown (J).
        energy_final: kinetic plus spring energy at T (J).
        gravity_work: work of gravity over [0, T] (J).
        spring_energy: the springs' energy at touchdown (J; 0 where each is at rest there).
        duration, step: the landing's length and the Runge-Kutta step of this run (s).
        n_steps: accepted steps.
        error_estimate: relative difference from the run at half the step (None: not estimated).
        trajectory: (time, q) at every step end and event, for plots.
        integrator: ``rk4``, ``implicit`` or ``radau``, the integrator between events
            (:attr:`LandingSettings.integrator`).
        space: ``planar`` or ``spatial``.
        momentum_balance: the run's momentum balance residual (the change of the linear
            momentum over [0, T] minus the contact impulses and the weight's, largest component)
            over the touchdown momentum (or the weight's impulse, if larger); the steps keep it
            below :data:`MOMENTUM_BALANCE` plus the projections' rounding.
    """

    events: tuple[LandingEvent, ...]
    total_external: np.ndarray
    total_tangential: np.ndarray
    settled_at: float | None
    q_final: np.ndarray
    v_final: np.ndarray
    final_angles: np.ndarray
    energy_before: float
    energy_final: float
    gravity_work: float
    duration: float
    step: float
    n_steps: int
    error_estimate: float | None = None
    tolerance: float | None = None
    spring_energy: float = 0.0
    trajectory: tuple[np.ndarray, np.ndarray] = field(default=(np.zeros(0), np.zeros((0, 0))), repr=False)
    model: str = MODEL_NAME
    integrator: str = RK4
    space: str = PLANAR.name
    #: space: impacts and mode choices where the circular cone's exact law was not met and its
    #: 16-gon (polyhedral) answer was used (:func:`impulse_core.impact.cone.cone_unilateral`)
    inexact: int = 0
    momentum_balance: float = 0.0
    #: the share of the momentum balance's budget its steps kept (:meth:`_Landing.run`'s ``share``:
    #: :func:`balance_share` of the tolerance, shrunk where the step halving found runs split alike);
    #: the derivatives replay the run at it
    share: float = 1.0
    #: impacts whose rows were redundant: the velocities after are unique, the split is not
    #: (frictionless: the smallest-norm non-negative split, as the lcp rung; with friction: the
    #: smallest-norm split the law allows, as the friction rung: :func:`least_norm_law_split`)
    non_unique: int = 0
    #: the code the run's integrator steps ran on (:attr:`LandingSettings.step_code`; ``auto``
    #: resolved to c or vm)
    step_code: str = VM_CODE
    #: why ``integrator`` is RK4 or Radau IIA where ``auto`` first chose the implicit one (its run's
    #: steps overran their budget or fell behind RK4's stable step: :func:`landing`), else ""
    integrator_switch: str = ""
    #: the step halving's comparisons of distinct runs, in order (:func:`landing`): (the coarser
    #: run's step, the finer's, and their differences of the peak impulses, the total external
    #: impulses and the final angles, :func:`landing_differences`)
    halving: tuple[tuple[float, float, float, float, float], ...] = ()
    #: the step halving stopped because its runs' final angles did not approach each other while
    #: their impulses agreed (:func:`runs_apart`): ``error_estimate`` is the final angles'
    runs_apart: bool = False
    #: the times at which events stalled with no Painleve jam to explain them (or with one that
    #: did not end the slip) and the run crossed a span of them by Moreau-Jean steps
    #: (:meth:`_Landing.bridge`), with each span (s)
    bridges: tuple[tuple[float, float], ...] = ()

    @property
    def peak_external_norm(self) -> float:
        return max(e.external_norm for e in self.events)

    @property
    def peak_internal_norm(self) -> float:
        return max(e.internal_norm for e in self.events)

    @property
    def peak_max_internal(self) -> float:
        """The largest joint impulse magnitude of any event (N s)."""
        return max((float(e.internal_magnitude.max()) for e in self.events if e.internal_magnitude.size), default=0.0)

    @property
    def final_base(self) -> np.ndarray:
        """The base origin at T: [x, y] in the plane, [x, y, z] in space (world frame)."""
        return self.q_final[: 2 if self.space == PLANAR.name else 3].copy()

    @property
    def energy_absorbed(self) -> float:
        """Fraction of the energy brought in (kinetic at touchdown, the springs' at touchdown and
        gravity's work) that the impacts, dampers and friction dissipated by T; the rest is kinetic
        or in the springs. Springs wound at touchdown count: without them a spring unwinding made
        the fraction negative (-285 for a spring holding 1.8 J against 0.006 J of motion)."""
        brought = self.energy_before + self.spring_energy + self.gravity_work
        return 1.0 - self.energy_final / brought if brought > 0 else 0.0

    # The first event under the names every impact result has (the first-impact answer), so that
    # reports read a landing like any other result; the landing's own figures are above.

    @property
    def external(self) -> np.ndarray:
        return self.events[0].external

    @property
    def tangential(self) -> np.ndarray:
        return self.events[0].tangential

    @property
    def internal(self) -> np.ndarray:
        e = self.events[0]
        return np.column_stack([e.internal, np.zeros((len(e.internal), 3 - e.internal.shape[1]))])

    @property
    def internal_magnitude(self) -> np.ndarray:
        return self.events[0].internal_magnitude

    @property
    def external_norm(self) -> float:
        return self.events[0].external_norm

    @property
    def internal_norm(self) -> float:
        return self.events[0].internal_norm

    @property
    def max_internal(self) -> float:
        m = self.events[0].internal_magnitude
        return float(m.max()) if m.size else 0.0

    @property
    def v_plus(self) -> np.ndarray:
        return self.events[0].v_plus

    @property
    def energy_after(self) -> float:
        """Kinetic energy just after the first impact (J)."""
        return self.events[0].energy_after

    @property
    def touchdown_time(self) -> np.ndarray:
        """Per contact: the first event that pushed on it (s), NaN if none did."""
        out = np.full(len(self.total_external), np.nan)
        for e in reversed(self.events):
            out[e.external > 0] = e.time
        return out

    @property
    def touchdown_order(self) -> tuple[int, ...]:
        t = self.touchdown_time
        touched = np.flatnonzero(np.isfinite(t))
        return tuple(int(i) for i in touched[np.argsort(t[touched], kind="stable")])

    @property
    def active(self) -> tuple[int, ...]:
        return tuple(int(i) for i in np.flatnonzero(np.isfinite(self.touchdown_time)))

    @property
    def gaining_events(self) -> tuple[LandingEvent, ...]:
        """The impacts that raised the kinetic energy: none without friction or at e = 0; with
        friction and a restitution near 1 a contact that sticks or reverses its slip can (Kane's
        paradox of Newton's restitution with Coulomb friction; random file 33016 at e = 1)."""
        return tuple(e for e in self.events if e.energy_after > e.energy_before * (1 + 1e-9) + 1e-12)

    @property
    def energy_gained(self) -> bool:
        """True when some impact raised the kinetic energy (:attr:`gaining_events`)."""
        return bool(self.gaining_events)

    @property
    def converged(self) -> bool:
        return self.error_estimate is not None and self.tolerance is not None and self.error_estimate <= self.tolerance
