"""The whole landing: every impact from the first touchdown until ``duration``, with resting
contact, sticking and sliding, joint springs, dampers and stops in between, in the plane or in
space (one code path: the plane is the spatial case restricted).

An event-driven hybrid integration (Pfeiffer & Glocker, *Multibody Dynamics with Unilateral
Contacts*, 1996), the rigid counterpart of Moreau-Jean time stepping:

* Between events the contact modes are fixed: each contact is open, sticking or sliding (with a
  known direction), each joint with stops is free or resting on one. The closed rows are
  constraints on the acceleration, G a + b = 0, with forces F^T lambda (F = G except a sliding
  contact, whose force is along n - mu s t); M a = f + F^T lambda with f = gravity + springs +
  dampers - Coriolis. Classical Runge-Kutta 4 with a fixed step integrates it, with the contact
  force integrals as quadrature states; after each step the closed rows are projected back onto
  their constraints (positions, then velocities; the velocity projection's impulse is counted).
* An event ends a mode: a touchdown (an open contact's gap crosses zero, or touches and leaves
  within a step: a cubic Hermite fit of the gap over the step finds those), a joint reaching a
  stop, a lift-off (lambda_n < 0), a stick-slip transition (|lambda_t| > mu lambda_n), a sliding
  contact stopping (s v_t < 0), a stop releasing. Its time is located by the Illinois method on
  the step length.
* A touchdown or a stop is an impact by the same law as the first impact
  (``impulse_core.impact.coulomb``: Newton's restitution with exact Coulomb friction) over every
  contact that touches and every joint on a stop; an approach slower than
  :data:`PLASTIC_SPEED` is plastic (e = 0), as is one whose rebound the row's free acceleration
  would end within :data:`MIN_BOUNCE` of the duration, and the row rests from then on (on
  request, :attr:`LandingSettings.bounce_steps`, also one that would end within that many of the
  run's steps after the first impact: an approximation, off by default, that ends a light toe's
  cascade of ever shorter bounces early; its threshold halves with the step, so the
  step-halving estimate includes what it changes, but the events differ from the contract's,
  and settled_at can come early by up to the remaining cascade, h b / (1 - e)). After every event the
  modes are chosen by the same LCP at the acceleration level (e = 0; sliding contacts keep their
  direction).
* Where a closed contact slides pressed while its row's effective inverse mass with friction along
  its slip, A = n M^-1 (n - mu u t)^T, is negative (that LCP has no solution) or has fallen to 0
  (its force -B / A grows without bound), Painleve's paradox, the landing takes an impulsive jam
  there (:meth:`_Landing.jam`: Darboux-Keller's sliding phase along the cone's edge until the
  slip stops, then the impact law at e = 0), reported as a "touchdown" event with ``jam`` set;
  only once a run has stopped on the paradox (:meth:`_Landing.run`), so that other landings are
  unchanged to the bit.

The error of a run at step h is estimated by comparing with the run at h / 2; the step is halved
until that estimate meets ``tolerance`` (:func:`landing`).

Space (``space=SPATIAL``): q = (base origin, the base's rotation vector phi about its touchdown
orientation, joint angles) with q' = v, the compliant rung's chart
(:func:`impulse_core.timedomain.compliant._spatial_expressions`); the ground is a heightfield
(:func:`impulse_core.timedomain.compliant.spatial_ground`). Each contact has two tangents
(:func:`tangent_basis`): a sticking contact two tangent rows inside the circular cone, a sliding
one the force n - mu u^T t along its current slip direction u (:func:`slip_direction`,
regularised within one step's stiffness near zero slip: :meth:`_Landing.steer`). Impacts and the
mode LCP are the circular cone's law (:func:`impulse_core.impact.cone.cone_unilateral`). Every
array that is per tangent in the plane is per tangent pair in space, and the plane's arithmetic
is unchanged (its tangent is the spatial t_x of a normal in the x-y plane).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import casadi as ca
import numpy as np

from impulse_core.errors import ModelError, NumericalError
from impulse_core.evaluate import pre_impact_velocity
from impulse_core.impact.cone import POLYGON, cone_unilateral, modes_of
from impulse_core.impact import lemke_c
from impulse_core.impact.nnls import least_distance
from impulse_core.impact.coulomb import (
    ContactMode, UnilateralSolution, contact_modes, solve_unilateral,
)
from impulse_core.impact.laws import least_norm_law_split, least_norm_split, redundant, share_among_twins, twin_groups
from impulse_core.kinematics.spatial import AXIAL_GYRATION_FLOOR, PLANAR, Space, dof_layout, values_space
from impulse_core.model.heightfield import Heightfield, is_twisted
from impulse_core.model.joints import FREE, JointLaw
from impulse_core.model.rods import rotation_rpy
from impulse_core.model.terrain import Terrain, slope_normal
from impulse_core.model.terrain import _segment_normals as terrain_normals
from impulse_core.model.tree import ContactSelection, Scene, Tree, design_vector
from impulse_core.timedomain.compliant import (
    DYNAMICS_INPUTS,
    Expressions,
    BufferedCall,
    _check_chart,
    chart_rotation,
    continued_rotation_vector,
    _require_known,
    expressions,
    ground_expression,
    relative_difference,
    joint_impulses,
    spatial_ground,
    subtree_incidence,
    subtree_masses,
    touchdown_configuration,
    world_velocity,
)

try:  # np.count_nonzero's C function (its wrapper calls it with the array alone: _any)
    from numpy._core.multiarray import count_nonzero as _count_nonzero
except ImportError:  # numpy < 2
    _count_nonzero = np.count_nonzero

MODEL_NAME = "landing"
#: An impact approaching slower than this (m/s at a contact, rad/s at a stop) is plastic.
PLASTIC_SPEED = 1e-4
#: Angles scanned for a starting slip its acceleration follows (:func:`_followed_slip`, space).
SLIP_SCAN = 72
#: A rebound that the row's free acceleration would end within this fraction of the landing's
#: duration is plastic too: a contact driven into the ground (a fast-spinning light rod, a stiff
#: spring) would otherwise chatter at nanosecond intervals without end.
MIN_BOUNCE = 1e-6
#: The landing has settled once every generalized velocity stays below this.
SETTLE_SPEED = 1e-3
#: Events after which the landing is abandoned (a chattering contact).
MAX_EVENTS = 20000
#: The integrators between events (:attr:`LandingSettings.integrator`).
RK4, IMPLICIT, RADAU, AUTO = "rk4", "implicit", "radau", "auto"
#: RK4's stable step times the joint laws' fastest rate at touchdown (:func:`joint_law_rate`):
#: classical RK4 is stable on the negative real axis up to 2.785 (a damper's mode) and on the
#: imaginary axis up to 2.828 (a spring's). With a given step, ``auto`` takes the implicit
#: integrator when that step times the rate exceeds this.
RK4_STABLE = 2.0
#: Without a given step, ``auto`` takes the implicit integrator only when duration / 200 times the
#: rate exceeds this, i.e. when RK4's stable step is over 16 x shorter than ROS2's first step;
#: below it RK4 from its stable step was the faster on the random sweep's files (up to 30 x at
#: h x rate 2-20; ROS2 the faster at 66: ``studies/whole_landing/spatial_chatter.md``).
AUTO_IMPLICIT = 32.0
#: The code of the integrator's step (:attr:`LandingSettings.step_code`): one CasADi function
#: compiled to C through the trusted cache (:mod:`impulse_core.timedomain.landing_step`), the same
#: function on CasADi's virtual machine, or the numpy reference; ``auto``: C where the cache
#: already holds it (nothing is built), else the virtual machine.
C_CODE, VM_CODE, NUMPY_CODE, AUTO_CODE = "c", "vm", "numpy", "auto"
#: The default first step (:attr:`LandingSettings.step`): the implicit integrator's is duration /
#: 200; RK4's is its longest stable step for the joint laws at touchdown (RK4_STABLE /
#: :func:`joint_law_rate`), at most duration / 100. The step-halving
#: estimate that follows is what holds the tolerance (case 3: runs at 2.7 and 1.3 ms instead of
#: 1.5 and 0.75 ms, estimate 4e-7 against a tolerance of 1e-3, 0.6 x the time).
FIRST_STEPS = (1.0 / 200.0, 1.0 / 100.0)
#: ROS2's gamma (Verwer, Spee, Blom and Hundsdorfer 1999): L-stable with the exact Jacobian.
ROS2_GAMMA = 1.0 + 1.0 / math.sqrt(2.0)
#: The two-stage Radau IIA collocation method (Hairer and Wanner, Solving ODEs II, IV.5): order 3,
#: stage order 2, L-stable and stiffly accurate (the step's end is its last stage).
RADAU_A = np.array([[5.0 / 12.0, -1.0 / 12.0], [3.0 / 4.0, 1.0 / 4.0]])
RADAU_B = RADAU_A[1].copy()
#: Its simplified Newton iterations per step at most, and their end: the last correction at most
#: RADAU_TOL times 1 + |y| in every component of the state (a step whose iterations do not get
#: there is halved, :meth:`_Landing.balanced_step`).
RADAU_ITERATIONS, RADAU_TOL = 12, 1e-12
#: Times a Radau IIA step whose iterations do not converge is split in two (:meth:`_Landing.radau_step`).
RADAU_SPLITS = 4
#: An event location's trial step (:meth:`_Landing.trial`): Radau IIA's pieces split at most this
#: many times (2^32 pieces: in practice until RK4's stable step takes them).
TRIAL_SPLITS = 32
#: The momentum balance over a landing (the change of the linear momentum minus the contact
#: impulses and the weight's) that the steps keep below this fraction of the touchdown momentum:
#: each step is halved until its own residual is below its share (its length over the duration).
MOMENTUM_BALANCE = 2e-5
#: Two successive runs of the step-halving estimate count as two only where the finer took at
#: least this many times the coarser's steps: where the momentum balance splits most steps alike
#: in both, their difference understates the error (random file 30113 on ROS2: runs of 2855 and
#: 2858 steps differed by 1.4e-6 while the finer was 1.6e-5 from the converged answer), and the
#: halving goes on.
DISTINCT_RUNS = 1.1
#: Halvings of the nominal step for the momentum balance (a step that short is taken as it is).
MAX_SPLITS = 14
#: The step halving stops early where its runs end in postures that do not approach each other
#: (:func:`runs_apart`): two successive differences of the final angles of at least this
#: (relative, :func:`landing_differences`: a tenth of the largest angle), the later not shrunk by
#: the steps' ratio (what first order would give at least), while the runs' peak and total
#: impulses agree to IMPULSES_AGREE times it. Random file 32924: a tumbling flight of 0.21 s
#: after the impacts whose state a 1e-10 kick moves by 1e-2 rad at its end (Lyapunov-like rate
#: ~90 1/s); runs at h, h / 4, h / 16 and h / 64 ended 1.61, 0.90 and 1.7 apart, their impulses
#: within 1.3e-3, and each halving cost twice the last (``studies/whole_landing/spatial_chatter.md``).
POSTURE_SPREAD = 0.1
#: The impulses' difference, as a fraction of the final angles', below which the runs' impacts
#: agree while their postures do not (:func:`runs_apart`).
IMPULSES_AGREE = 0.01
#: The momentum balance the contract's outside checks hold a whole landing to (its
#: :attr:`LandingResult.momentum_balance`, relative as there): a landing beyond it is reported
#: with a warning (random file 32843 reached 1e-2: a tip sliding along a heightfield's crease, each
#: step's projection across it booked along the other face's normal; since :meth:`_Landing.placed`
#: books it along the rows it acted on, 4.5e-5 and below).
BALANCE_CHECK = 1e-4
#: A step's momentum residual at most this many times eps times the largest of its
#: terms (the momenta at both ends, the contact impulses, the weight's) is rounding's: shorter
#: steps do not shrink it (random file 32787's run at h / 64, its share of the balance 1 / 4096:
#: after a 55 g rod's tip stuck, residuals of 6e-16 to 1e-14 N s, up to 3.5 eps times the tree's
#: 12.5 N s, at h / 2^13 and h / 2^14 alike, above their shares of 9e-16 and 5e-16 N s: the steps
#: stayed at those lengths, some 1e8 of them for the landing's rest). Such a step is taken and
#: its successor may double (:meth:`_Landing.balanced_step`); summed over a run's step budget
#: (STEP_BUDGET per nominal step: 8e5 steps at h / 2^7 from duration / 100) these residuals come
#: to about 3e-9 of the momenta, far below the balance's own bound (MOMENTUM_BALANCE).
BALANCE_ROUNDING = 16
#: Space: a direction of the mass matrix whose eigenvalue is at most this times the number of
#: velocities times the rods' axial floors (sum of mass x (AXIAL_GYRATION_FLOOR x length)^2) is
#: a motion that moves no mass (a rod of radius 0 spinning about its own axis): only the floor
#: gives it inertia, so rounding in an impact or a step (eps x the torques, over 1e-14 of the
#: rod's inertia) drives its velocity, which no law sets. :meth:`_Landing.project` holds it at 0
#: (random file 33016, a lone rod of radius 0 at e = 1: that spin's rate at T was 15, 12 and 4.9
#: rad/s at h / 4, h / 8, h / 16, its turn with it, so the halving never converged). A unit
#: velocity's floor part is at most the number of velocities times their sum, so a direction
#: with real inertia this small would need inertias 1e-13 apart.
MASSLESS = 4.0
#: A massless direction moves a contact where the contact's velocity along it (per unit of the
#: direction) exceeds this times the longest rod (:meth:`_Landing.refuse_massless_contacts`; a rod
#: of radius 0 spinning about its own axis moves its contacts by rounding, ~1e-16 x its length).
MASSLESS_REACH = 1e-6
#: Space: springs along a massless direction with no damper on it (:meth:`_Landing.refuse_swinging_springs`)
#: may start at most this far (rad, a joint's angle) from their balance along it. With a rod's radius r
#: the direction has inertia ~ r^2 and such springs swing it about their balance at a rate ~ 1 / r,
#: undamped and keeping their energy, so the angles along it at T have no limit as r -> 0 (random file
#: 60603: b1's spring 0.18 rad from its balance, 0.1 J; its joint ended at 1.151 rad with b0 of radius
#: 3 mm, 1.412 with 1 mm, the rest of the landing alike to 1e-4). Wound by rounding only, the swing is nil.
MASSLESS_SWING = 1e-6
#: Steps (of any length) after which a run is abandoned, per step of the run's nominal length: a
#: rod spinning at 1e4 rad/s makes the balance split every step (the trial then fails, as it did
#: when the step diverged).
STEP_BUDGET = 64
#: ``auto``'s implicit first run is given up for RK4 from its stable step (:func:`landing`, as
#: where it overruns :data:`STEP_BUDGET`) once it has taken over RK4_PACE_AFTER x duration / h
#: steps and its mean step is below 1 / RK4_PACE of RK4's stable step: at h x rate >> 1 the
#: momentum balance splits ROS2's steps to ~0.02 / rate, where RK4 is stable at 2 / rate (random
#: files 32507, 32700 over their first 30 ms: 5323 and 5326 ROS2 steps against 859 and 492 RK4
#: steps at its stable step, both within 2e-6 of a reference; ``studies/whole_landing/stiff_speed.md``).
RK4_PACE, RK4_PACE_AFTER = 2.0, 4.0
#: Where ``auto``'s implicit run gives way (:data:`RK4_PACE`, :data:`STEP_BUDGET`) and its first
#: step times the joint laws' rate exceeds this, the landing goes on with Radau IIA from that
#: first step (``radau``, :meth:`_Landing.radau_step`) rather than RK4 from its stable step: a
#: stiffly accurate method whose steps the momentum balance splits only in the transients after
#: impacts, where ROS2's it splits throughout. Random files 33096 (h x rate 632), 33053 (297) and
#: 32015 (625) landed 4.5 x, 3.8 x and 6.2 x faster so on numpy's step, 32700 (44.7) 1.4 x slower
#: (``studies/whole_landing/stiff_speed.md``, 2026-11-27). Its compiled step (one or two calls of
#: 6 Newton iterations, ``landing_step._radau``) made them 3.5 x, 1.8 x and 1.6 x faster again, but
#: below 100 the files disagree: 32507 (76) lands 6.8 x faster than on RK4 within its estimate,
#: 33491 (66) 2.3 x faster but 1.9e-3 from RK4's answer (beyond both estimates), 60113 (88) 1.3 x
#: faster but unconverged (estimate 0.25, RK4's 6.7e-4), 32700 (44.7) 1.6 x slower: it stays 100.
AUTO_RADAU = 100.0
#: Space: beyond this |phi| (rad) the base's rotation coordinates are re-centred on its current
#: orientation (:meth:`_Landing.rechart`), far inside the chart's good region (singular at
#: |phi| = 2 pi), so a base may turn any number of times.
RECHART = 3.0


class Diverged(NumericalError):
    """The integration blew up, or its steps overran their budget (the momentum balance split them):
    the step is too long for the model's fastest motion; :func:`landing` shortens it
    (:func:`retry_factor`). ``reached``: the fraction of the duration a run reached when its steps
    overran their budget (0: it blew up)."""

    def __init__(self, message: str, reached: float = 0.0) -> None:
        super().__init__(message)
        self.reached = reached


class _Jams(Exception):
    """A run stopped by Painleve's paradox before the landing took impulsive jams
    (:meth:`_Landing.run` then starts it again taking them); ``failure``: the error it stopped with."""

    def __init__(self, failure: NumericalError) -> None:
        super().__init__(str(failure))
        self.failure = failure


class PainleveParadox(NumericalError):
    """The contact problem at the acceleration level has no solution at an event (Painleve's
    paradox: a pressed sliding contact whose row's effective inverse mass with friction is
    negative): :meth:`_Landing.resolve_or_jam` takes an impulsive jam there."""


def retry_factor(reached: float) -> float:
    """How much shorter the next run's step is after a run diverged: 2, or where its steps overran
    their budget by the fraction ``reached`` of the duration, the power of two 2^k >= 1 / reached.
    Its split steps are as short at any h (the momentum balance sets them), so it needs about
    1 / reached times the budget, and each halving of h doubles the budget: the runs in between
    would overrun it too (a random planar leg with a 4 cm sprung rod, ROS2: its runs at h / 2
    and h / 4 overran at t = 0.037 and 0.078 of 0.1 s, 64 s that its landing, 137 s now, skips)."""
    if not 0.0 < reached < 1.0:
        return 2.0
    return 2.0 ** max(1, math.ceil(math.log2(1.0 / reached) - 1e-9))


@dataclass(frozen=True)
class LandingSettings:
    """Accuracy settings of :func:`landing`.

    Attributes:
        tolerance: the error a run must meet (relative difference of its peak impulses, total
            external impulses and final posture from the refined limit, ``MODEL_FORMAT.md``).
        step: the first Runge-Kutta step (s); None: :data:`FIRST_STEPS` (the implicit integrator
            duration / 200; RK4 the longest step within them that is stable for the joint laws at
            touchdown, :meth:`_Landing.first_step`).
        max_refinements: halvings of the step before giving up (the run then warns).
        gap_tolerance: a contact this close to the ground (m) touches.
        max_events: impacts after which a run is abandoned (a chattering contact, or a budget).
        integrator: between events, ``rk4`` (classical Runge-Kutta 4, explicit), ``implicit``
            (ROS2, a linearly implicit Rosenbrock-W method of order 2 with the joint springs and
            dampers in its matrix: stable for any damper on any rod) or ``auto``: RK4 from its
            stable step unless that is over 16 x shorter than duration / 200
            (:data:`AUTO_IMPLICIT`; with a given step, unless that step is beyond RK4's
            stability, :data:`RK4_STABLE`), then implicit; ``radau``: the two-stage Radau IIA
            method (order 3, stiffly accurate, simplified Newton iterations, compiled as the
            others' steps are: :meth:`_Landing.radau_step`), which ``auto`` takes where its implicit run gave way on a
            stiff landing (:data:`AUTO_RADAU`). One landing keeps one integrator at every step
            length, so that the step-halving estimate compares like with like.
        step_code: the steps of any integrator (plane and space) by one CasADi function of
            the mode (:mod:`impulse_core.timedomain.landing_step`): ``c`` compiled to C through the
            compile cache (~20 x the virtual machine's speed; a first build takes tens of seconds,
            and a missing compiler falls back to ``vm`` with a warning; the events' dynamics at a
            point, :func:`landing_function`, their LCPs by Lemke's method and the location's
            cubic roots then run as C too, :mod:`impulse_core.impact.lemke_c`, with the same
            numbers as the Python code), ``vm`` on CasADi's
            virtual machine (a mode stepped 32 times by its own copy, the mode's rows as
            constants: :class:`~impulse_core.timedomain.landing_step.ModeFunctions`), ``numpy``
            the reference (rows built and solved per stage in numpy; always so for a redundant
            mode), or ``auto``: ``c`` where the compile cache already holds this landing's C (a
            study builds it in the background, :mod:`optimizer.search.landing_code`), else ``vm``;
            nothing is built (:attr:`LandingResult.step_code` says which ran). All agree to
            rounding; c and vm bit for bit in the plane on every file tried (optimizer.search.landing_code).
        bounce_steps: 0 (default: every rebound faster than the plastic speed is an event, as
            ``MODEL_FORMAT.md`` asks), or b > 0: after the first impact a rebound that the row's
            free acceleration would end within b steps is plastic (module docstring; case 3's
            light toes: 441 impacts in 40 ms become 24 at b = 0.25 and step 1.5 ms, the run 0.15 x
            the time and 1e-7 from the converged landing).
    """

    tolerance: float = 1e-3
    step: float | None = None
    max_refinements: int = 7
    gap_tolerance: float = 1e-12
    max_events: int = MAX_EVENTS
    integrator: str = AUTO
    step_code: str = VM_CODE
    bounce_steps: float = 0.0


@dataclass(frozen=True)
class LandingProgress:
    """Where a run of :func:`landing` is: the step halving's run (0 first) and its Runge-Kutta
    step (s), the time reached t of the duration (s), and the impacts so far."""

    run: int
    step: float
    t: float
    duration: float
    impacts: int


#: Told of a run's progress after each accepted step and each event (:func:`landing`'s ``progress``).
Progress = Callable[[LandingProgress], None]
#: Asked at (q, v, mode, totals) after the first impact and each step and event whether a run
#: ends there (:meth:`_Landing.run`'s ``until``; the sequential rigid model's end).
Until = Callable[[np.ndarray, np.ndarray, "_Mode", "_Totals"], bool]


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


# --------------------------------------------------------------------------------------------
# The dynamics at (q, v): one CasADi call


LANDING_OUTPUTS = ("gap", "normal", "contact_jacobian", "contact_bias", "mass_matrix", "force", "kinetic_energy",
                   "subtree_momentum", "com_height", "contacts")


@functools.lru_cache(maxsize=64)
def landing_function(topology, terrain: Terrain | Heightfield, space: Space = PLANAR) -> ca.Function:
    """What the landing needs at (q, v, p, gravity), one call per evaluation: ``gap`` (n_c),
    ``normal`` (d x n_c, outward at the nearest ground point), ``contact_jacobian`` (d n_c x nv),
    ``contact_bias`` ((dJ/dt) v, d n_c), ``mass_matrix``, ``force`` (gravity - Coriolis),
    ``kinetic_energy``, ``subtree_momentum`` (d x bodies), ``com_height``, ``contacts`` (d x n_c);
    d = 2 in the plane (``terrain`` a profile), 3 in space (a heightfield; q and v as in
    :func:`impulse_core.timedomain.compliant._spatial_expressions`)."""
    x = expressions(topology, space)
    nc = x.contacts.shape[1]
    pairs = [ground_expression(terrain, x.contacts[:, c]) for c in range(nc)]
    outs = [
        ca.vertcat(*[g for g, _ in pairs]),
        ca.horzcat(*[n for _, n in pairs]),
        x.contact_jacobian,
        turning_ground_bias(x, [n for _, n in pairs]) if isinstance(terrain, Heightfield) and is_twisted(terrain)
        else x.contact_bias,
        x.mass_matrix,
        x.force,
        x.kinetic_energy,
        x.subtree_momentum,
        x.com_height,
        x.contacts,
    ]
    return ca.Function(
        "landing", [x.q, x.v, x.p, x.gravity], [ca.densify(o) for o in outs], list(DYNAMICS_INPUTS), list(LANDING_OUTPUTS)
    )


def turning_ground_bias(x: Expressions, normals: list[ca.SX]) -> ca.SX:
    """The contacts' bias (dJ/dt) v plus, along each normal n, n' . p' (p' the point's velocity,
    n' = dn/dq q' the turn of the ground's normal under it): so a normal row's bias n . (dJ/dt) v
    + n' . p' is the gap's second derivative at rest on a twisted heightfield patch (at zero gap
    and normal speed, g'' = n . p'' + n' . p'), and the tangent rows' are unchanged (t . n = 0).
    Without it a contact sliding across a twist at speed s had an unmodelled normal acceleration
    of order s^2 times the twist: the contact problem opened it while it sank, and random file
    30992 took 4,400 plastic touchdowns 1.9e-8 s apart."""
    d = x.dims
    parts = []
    for c, n in enumerate(normals):
        J = x.contact_jacobian[d * c : d * c + d, :]
        turn = ca.dot(ca.jtimes(n, x.q, x.v), J @ x.v)
        parts.append(x.contact_bias[d * c : d * c + d] + n * turn)
    return ca.vertcat(*parts)


@dataclass
class _Point:
    """Numeric dynamics at one (q, v), spring and damper torques included (d = 2 in the plane, 3
    in space; each contact has d - 1 tangents: +x's in the plane, the tangent plane's x and z in
    space, :func:`tangent_basis`)."""

    gap: np.ndarray
    normal: np.ndarray  # n_c x d
    tangent: np.ndarray  # n_c x (d - 1) x d
    Jn: np.ndarray  # n_c x nv
    Jt: np.ndarray  # n_c x (d - 1) x nv
    bn: np.ndarray  # (dJn/dt) v
    bt: np.ndarray  # n_c x (d - 1)
    M: np.ndarray
    f: np.ndarray
    kinetic: float
    momentum: np.ndarray  # d x bodies
    com_height: float
    contacts: np.ndarray  # n_c x d
    slip: np.ndarray  # n_c x (d - 1): the tangential velocities at this (q, v)
    slip_floor: float = 0.0  # below this slip speed a sliding contact keeps its mode's direction

    def vn(self, v: np.ndarray) -> np.ndarray:
        return self.Jn @ v

    def vt(self, v: np.ndarray) -> np.ndarray:
        """Tangential velocities (n_c x (d - 1)) of the generalized velocity v."""
        return self.Jt @ v


def tangent_basis(normal: np.ndarray) -> np.ndarray:
    """Per contact (rows of ``normal``, n_c x d), its d - 1 unit tangents (n_c x (d - 1) x d): in
    the plane (n_y, -n_x) (+x on flat ground); in space t_x, x's projection on the tangent plane,
    and t_z = t_x x n (x and z on flat ground), so that a planar normal gives the planar tangent."""
    if normal.shape[1] == 2:
        tangent = np.empty((len(normal), 1, 2))
        tangent[:, 0, 0], tangent[:, 0, 1] = normal[:, 1], -normal[:, 0]
        return tangent
    t_x = np.array([1.0, 0.0, 0.0]) - normal[:, :1] * normal
    t_x /= np.sqrt(np.einsum("ij,ij->i", t_x, t_x))[:, None]
    (a, b, c), (x, y, z) = t_x.T, normal.T
    t_z = np.column_stack([b * z - c * y, c * x - a * z, a * y - b * x])  # t_x x n
    return np.stack([t_x, t_z], axis=1)


def _along(directions: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """sum_k directions[:, k] rows[:, k]: per contact, the component of ``rows`` (n_c x d x ...)
    along its direction (n_c x d)."""
    shape = (-1,) + (1,) * (rows.ndim - 2)
    out = directions[:, 0].reshape(shape) * rows[:, 0]
    for k in range(1, directions.shape[1]):  # in order, as numpy's sum over the axis adds
        out += directions[:, k].reshape(shape) * rows[:, k]
    return out


@dataclass(frozen=True)
class _Joints:
    """Joint laws as arrays over the generalized velocities (base entries inert)."""

    stiffness: np.ndarray
    damping: np.ndarray
    rest: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    restitution: np.ndarray
    dof_body: tuple[int, ...]

    def torque(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        return -self.stiffness * (q - self.rest) - self.damping * v

    def energy(self, q: np.ndarray) -> float:
        return float(0.5 * np.sum(self.stiffness * (q - self.rest) ** 2))

    @functools.cached_property
    def stopped(self) -> np.ndarray:
        """Per DOF: whether it has a stop."""
        return np.isfinite(self.lo) | np.isfinite(self.hi)


def joint_arrays(tree: Tree, laws: tuple[JointLaw, ...], q0: np.ndarray, space: Space = PLANAR) -> _Joints:
    """:class:`_Joints` of ``laws`` (one per body; () = all free), rest angles defaulting to the
    touchdown configuration ``q0``."""
    layout = dof_layout(tree.topology(), space)
    nv = layout.nv
    k, c, e = np.zeros(nv), np.zeros(nv), np.zeros(nv)
    rest, lo, hi = q0.copy(), np.full(nv, -np.inf), np.full(nv, np.inf)
    for b, law in enumerate(laws or (FREE,) * tree.n_bodies):
        j = layout.body_dof[b] if b > 0 else None
        if j is None:
            continue
        k[j], c[j], e[j] = law.stiffness, law.damping, law.stop_restitution
        if law.rest is not None:
            rest[j] = law.rest
        if law.limits is not None:
            lo[j], hi[j] = law.limits
    return _Joints(k, c, rest, lo, hi, e, layout.dof_body)


# --------------------------------------------------------------------------------------------
# Modes and constraint rows


@dataclass
class _Mode:
    """Which rows are closed between two events."""

    closed: np.ndarray  # bool per contact: resting on the ground
    #: per contact (n_c x (d - 1)): 0 sticking (or frictionless), else the unit slip direction in
    #: its tangent basis (the plane: +-1 sliding along +-t); a 1-D array is the plane's signs
    slip: np.ndarray
    stop: np.ndarray  # int per DOF: 0 free, -1 resting on its lower stop, +1 on its upper
    #: the rows are redundant (e.g. two identical toes sticking on one point): their forces are
    #: the least-norm split (:data:`REDUNDANT`), which is the symmetric one between identical toes
    redundant: bool = False
    #: per contact: the slip speed (m/s) below which its sliding friction's direction is
    #: regularised (:func:`slip_direction`, :meth:`_Landing.steer`); None: 0, exact
    core: np.ndarray | None = None
    #: per contact: -1, or the index of the plane's valley breakpoint where it rests held by both
    #: adjacent segments (two normal rows, :func:`_corner_rows`); None: -1 for every contact
    corner: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.slip.ndim == 1:
            self.slip = self.slip.astype(float)[:, None]
        if self.core is None:
            self.core = np.zeros(len(self.closed))
        if self.corner is None:
            self.corner = np.full(len(self.closed), -1)

    def copy(self) -> _Mode:
        return _Mode(self.closed.copy(), self.slip.copy(), self.stop.copy(), self.redundant, self.core.copy(),
                     self.corner.copy())

    @property
    def cornered(self) -> np.ndarray:
        """Per contact: resting in a valley corner (:attr:`corner`)."""
        return self.corner >= 0

    @property
    def has_corner(self) -> bool:
        """Whether some contact rests in a valley corner (``cornered.any()``, in Python ints: the
        step loop asks it a few times a step)."""
        return max(self.corner.tolist(), default=-1) >= 0

    @property
    def sliding(self) -> np.ndarray:
        """Per contact: whether it slides."""
        return (self.slip != 0).any(axis=1)

    @property
    def side(self) -> np.ndarray:
        """The plane's slip per contact: 0, or +-1 sliding along +-t."""
        return np.sign(self.slip[:, 0]).astype(int)


@dataclass(frozen=True)
class _Rows:
    """Constraint rows of a mode: velocity rows G (normal rows first, then the tangent rows: the
    first tangent of every sticking contact, then, in space, the second's), force rows F (= G but
    for sliding contacts), (dG/dt) v, and what each row is."""

    G: np.ndarray
    F: np.ndarray
    b: np.ndarray
    contact: np.ndarray  # per normal row: its contact, or -1 for a stop
    dof: np.ndarray  # per normal row: its DOF (stops), or -1
    owner: np.ndarray  # per sticking contact (its d - 1 tangent rows): its normal row
    mu: np.ndarray  # per sticking contact
    #: per contact (n_c x (d - 1)): the unit direction its sliding friction opposes, or 0
    direction: np.ndarray = field(default_factory=lambda: np.zeros((0, 1)))
    redundant: bool = False  # the mode's rows are redundant: least-norm forces
    #: per normal row, whether it is one of a valley corner's two rows (:func:`_corner_rows`), and
    #: its direction's components along its contact's normal and tangent at the point (n x 2); None:
    #: no corner, every contact row along its contact's normal
    cornered: np.ndarray | None = None
    turn: np.ndarray | None = None

    @property
    def n(self) -> int:
        return len(self.contact)


def slip_direction(pt: _Point, slip: np.ndarray, core: np.ndarray | None = None) -> np.ndarray:
    """Per contact, the direction u of its sliding friction's slip: the current slip velocity's
    s / |s| while it points along the mode's ``slip`` d (s . d > 0) and |s| exceeds the resting
    threshold, else d (a contact starting to slide, or one whose slip reverses: an event). Below
    the speed ``core`` (per contact; 0: none) u = (s + (core - |s|) d) / |...|: the lateral
    sensitivity of the direction, mu f_n / |s|, is capped at mu f_n / core (see
    :meth:`_Landing.steer`). In the plane u is the mode's +-1 in every case (the plane's
    fixed-direction force); in space it turns with the slip."""
    if slip.shape[1] == 1:
        return slip
    speed = np.linalg.norm(pt.slip, axis=1, keepdims=True)
    along = (np.sum(pt.slip * slip, axis=1, keepdims=True) > 0) & (speed > pt.slip_floor)
    lifted = pt.slip if core is None else pt.slip + np.maximum(core[:, None] - speed, 0.0) * slip
    size = np.linalg.norm(lifted, axis=1, keepdims=True)
    current = np.divide(lifted, size, out=np.zeros_like(pt.slip), where=along)
    return np.where(along, current, slip)


def _corner_rows(pt: _Point, contacts: np.ndarray, normals: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The two rows of each contact resting in a plane's valley corner: ``contacts`` (m indices),
    ``normals`` (m x 2 x 2: the left and right segments' outward unit normals). A row along a
    world direction u of the contact's velocity is u . J = (u . n) J_n + (u . t) J_t (n, t the
    point's orthonormal normal and tangent there), its bias likewise. Returns G (2m x nv: each
    contact's left row, then its right row), b (2m) and the rows' (u . n, u . t) (2m x 2)."""
    n, t = pt.normal[contacts], pt.tangent[contacts, 0]
    u = normals.reshape(-1, 2)  # left, right per contact
    c = np.repeat(contacts, 2)
    turn = np.column_stack([np.sum(u * np.repeat(n, 2, axis=0), axis=1), np.sum(u * np.repeat(t, 2, axis=0), axis=1)])
    G = turn[:, :1] * pt.Jn[c] + turn[:, 1:] * pt.Jt[c, 0]
    b = turn[:, 0] * pt.bn[c] + turn[:, 1] * pt.bt[c, 0]
    return G, b, turn


def _rows(pt: _Point, contacts: np.ndarray, slip: np.ndarray, stops: np.ndarray, mu: float, nv: int,
          core: np.ndarray | None = None, corners: tuple[np.ndarray, np.ndarray] | None = None) -> _Rows:
    """Rows for the given contacts (indices; ``slip`` per contact, n_c x (d - 1)), stops (DOF ->
    side, dict-like array: 0 none) and friction coefficient; tangent rows for non-sliding contacts
    when mu > 0; a sliding contact's force row is n - mu u^T t along its slip direction u
    (:func:`slip_direction`). ``corners``: (contacts, their segments' normals m x 2 x 2) resting in
    a valley corner, two frictionless normal rows each after the other contacts' (:func:`_corner_rows`;
    the two normals fix the point in the plane, so a tangent row would be redundant, and with
    both rows pushing no friction is needed: friction acts once one row is released)."""
    if corners is not None and len(corners[0]):
        return _with_corners(_rows(pt, contacts, slip, stops, mu, nv, core), pt, contacts, *corners)
    dofs = np.flatnonzero(stops)
    G_stop = np.zeros((len(dofs), nv))
    G_stop[np.arange(len(dofs)), dofs] = -stops[dofs]
    direction = slip_direction(pt, slip, core) if mu > 0 else np.zeros_like(slip)
    sliding = direction[contacts]
    Fn = pt.Jn[contacts] - _along(mu * sliding, pt.Jt[contacts])
    sticking = contacts[~(sliding != 0).any(axis=1)] if mu > 0 else contacts[:0]
    tangent_rows = pt.Jt[sticking].transpose(1, 0, 2).reshape(-1, nv)
    G = np.vstack([pt.Jn[contacts], G_stop, tangent_rows])
    F = np.vstack([Fn, G_stop, tangent_rows])
    b = np.concatenate([pt.bn[contacts], np.zeros(len(dofs)), pt.bt[sticking].T.ravel()])
    owner = np.searchsorted(contacts, sticking)
    return _Rows(
        G, F, b,
        np.concatenate([contacts, -np.ones(len(dofs), int)]),
        np.concatenate([-np.ones(len(contacts), int), dofs]),
        owner, np.full(len(sticking), mu), direction,
    )


def _with_corners(rows: _Rows, pt: _Point, contacts: np.ndarray, cornered: np.ndarray, normals: np.ndarray) -> _Rows:
    """``rows`` (of ``contacts``) with the corner rows of ``cornered`` (:func:`_corner_rows`)
    inserted after the contacts' normal rows."""
    Gc, bc, turn = _corner_rows(pt, cornered, normals)
    k, m = len(contacts), len(Gc)
    G = np.vstack([rows.G[:k], Gc, rows.G[k:]])
    F = np.vstack([rows.F[:k], Gc, rows.F[k:]])
    b = np.concatenate([rows.b[:k], bc, rows.b[k:]])
    n = rows.n
    flags = np.zeros(n + m, bool)
    flags[k : k + m] = True
    axes = np.zeros((n + m, 2))
    axes[:, 0] = 1.0
    axes[k : k + m] = turn
    return replace(
        rows, G=G, F=F, b=b,
        contact=np.concatenate([rows.contact[:k], np.repeat(cornered, 2), rows.contact[k:]]),
        dof=np.concatenate([rows.dof[:k], -np.ones(m, int), rows.dof[k:]]),
        cornered=flags, turn=axes,
    )


def _mode_bytes(mode: _Mode) -> bytes:
    """What of a mode a compiled step depends on, as bytes (:meth:`_Landing.ended`; a mode with a
    corner, which no compiled step takes, also names its corners). The corners are always in the
    key: within one landing its arrays keep their lengths and a corner-free mode's are all -1, so
    two keys are equal exactly where they were with the corners named only where some contact has
    one (two reductions cheaper; the key is asked about nine times a step)."""
    return b"".join((mode.closed.tobytes(), mode.slip.tobytes(), mode.stop.tobytes(), bytes([mode.redundant]),
                     mode.corner.tobytes()))


def _solve_rows(
    W: np.ndarray, u: np.ndarray, rows: _Rows, restitution: np.ndarray, kernel=None
) -> tuple[UnilateralSolution, np.ndarray, bool]:
    """The unilateral law over the rows (Newton's restitution per normal row, Coulomb friction
    per sticking contact; at the acceleration level with ``restitution`` 0): in the plane the
    LCP by Lemke's method (:func:`impulse_core.impact.coulomb.solve_unilateral`); in space the
    circular cone (:func:`impulse_core.impact.cone.cone_unilateral`: the Stewart-Trinkle 16-gon
    LCP, then Newton's method on the exact law). Returns the solution (tangential impulses and
    tangent-row velocities in :class:`_Rows`' order, ``slip`` the slip speed per sticking contact),
    the tangent rows' velocities after, per sticking contact (m x (d - 1)), and whether the exact
    law was met (False: the cone's polyhedral answer). ``kernel``: Lemke's method as C (the same
    numbers; :func:`impulse_core.impact.lemke_c.compiled_lemke`), or None."""
    m, tangents = len(rows.owner), rows.direction.shape[1]
    if tangents == 1 or not m:
        sol = solve_unilateral(W, u, rows.owner, restitution, rows.mu, kernel)
        return sol, sol.velocity[rows.n :].reshape(tangents, m).T, True
    law = cone_unilateral(W, u, rows.owner, restitution, rows.mu, kernel)
    after = law.velocity[rows.n :].reshape(tangents, m).T
    slip = np.linalg.norm(after, axis=1)
    return UnilateralSolution(law.normal, law.tangential.T.ravel(), law.velocity, slip), after, law.exact


@dataclass(frozen=True)
class RigidImpact:
    """One rigid impact over constraint rows (:func:`rigid_impact`).

    Attributes:
        solution: the law's row impulses and row velocities after (:func:`_solve_rows`; where the
            frictionless split is not unique, the least-norm normal split).
        v_plus: the generalized velocity after.
        normal, tangential: each contact's normal (n_c) and tangential (n_c x (d - 1)) impulse
            (0 where not in the rows; twin contacts share alike where the split is not unique).
        split_unique: the rows are independent (the split of the impulse is unique).
        exact: the exact law was met (False: the circular cone's polyhedral answer).
    """

    solution: UnilateralSolution
    v_plus: np.ndarray
    normal: np.ndarray
    tangential: np.ndarray
    split_unique: bool
    exact: bool


def rigid_impact(pt: _Point, v: np.ndarray, rows: _Rows, restitution: np.ndarray, mu: float, kernel=None
                 ) -> RigidImpact:
    """Newton's restitution (``restitution`` per normal row) with exact Coulomb friction (``mu``;
    0: the frictionless LCP) over ``rows`` at ``pt``, from the velocity ``v`` (:func:`_solve_rows`):
    the law of every impact of the landing and of the first instant on uneven ground. Redundant
    rows: without friction the lcp rung's smallest-norm split, with friction twins share alike.
    ``kernel``: as :func:`_solve_rows`'."""
    u = rows.G @ v
    minv_gt = np.linalg.solve(pt.M, rows.G.T)
    W = rows.G @ minv_gt
    sol, _, exact = _solve_rows(W, u, rows, restitution, kernel)
    split_unique = not redundant(rows.G)
    if not split_unique and mu == 0:  # the lcp rung's split (G has no tangent rows without friction)
        sol = replace(sol, normal=least_norm_split(rows.G, sol.normal))
    law_split = None if split_unique or mu == 0 else _law_split(rows, W, u, sol, restitution, mu)
    sol = sol if law_split is None else law_split
    lam = np.concatenate([sol.normal, sol.tangential])
    fn, ft = _contact_forces(rows, lam, mu, len(pt.gap))
    if not split_unique and mu > 0 and law_split is None:  # twins share alike, as in the friction rung
        c = rows.contact[rows.contact >= 0]
        groups = twin_groups(np.hstack([pt.Jn[c], pt.Jt[c].reshape(len(c), -1)]))
        fn[c], ft[c] = share_among_twins(groups, fn[c], ft[c])
    return RigidImpact(sol, v + minv_gt @ lam, fn, ft, split_unique, exact)


def _law_split(rows: _Rows, W: np.ndarray, u: np.ndarray, sol: UnilateralSolution, restitution: np.ndarray,
               mu: float) -> UnilateralSolution | None:
    """The friction rung's split of a redundant impact (:func:`least_norm_law_split`), or None
    where the law's answer does not meet its own modes to the law's tolerance."""
    t = sol.tangential.reshape(rows.direction.shape[1], len(rows.owner)).T
    split = least_norm_law_split(rows.G, W, u, rows.owner, sol.normal, t, restitution, mu, POLYGON)
    return None if split is None else replace(sol, normal=split[0], tangential=split[1].T.ravel())


def contact_impulses(pt: _Point, normal: np.ndarray, tangential: np.ndarray) -> np.ndarray:
    """The ground's impulse vector on each contact (d x n_c, world frame) from its normal (n_c) and
    tangential (n_c x (d - 1)) impulse along the contact's normal and tangents at ``pt``."""
    return contact_vectors(pt.normal, pt.tangent, normal, tangential)


def contact_vectors(normal: np.ndarray, tangent: np.ndarray, fn: np.ndarray, ft: np.ndarray) -> np.ndarray:
    """Each contact's impulse vector (d x n_c, world): ``fn`` (n_c) along its ``normal`` (n_c x d),
    ``ft`` (n_c x (d - 1)) along its tangents (``tangent``: n_c x (d - 1) x d, :func:`tangent_basis`)."""
    return normal.T * fn + sum(tangent[:, a].T * ft[:, a] for a in range(tangent.shape[1]))


def impact_modes(pt: _Point, v: np.ndarray, v_plus: np.ndarray, contacts: np.ndarray, normal: np.ndarray
                 ) -> tuple[ContactMode, ...]:
    """Each of ``contacts``' mode in an impact at ``pt`` from v to ``v_plus`` with normal impulses
    ``normal`` (per contact of ``contacts``), by the friction rung's thresholds (the scale: the
    largest normal or tangential contact speed before; :func:`contact_modes`, :func:`modes_of`)."""
    Jt = pt.Jt[contacts].transpose(1, 0, 2).reshape(-1, pt.Jt.shape[2])  # the first tangents, then the second
    J = np.vstack([pt.Jn[contacts], Jt])
    scale = max(float(np.max(np.abs(J @ v), initial=0.0)), np.finfo(float).tiny)
    after = J @ v_plus
    if pt.Jt.shape[1] == 1:
        return contact_modes(normal, after, scale)
    return modes_of(normal, None, after, scale)


def _any(x: np.ndarray) -> bool:
    """Whether some entry of ``x`` is nonzero (True, or NaN): ``x.any()``, cheaper on a few entries
    (numpy's own ``count_nonzero`` without its Python wrapper, which only passes an array on)."""
    return _count_nonzero(x) != 0


def _finite(x: np.ndarray) -> bool:
    """``np.isfinite(x).all()``, without the method's wrapper (a few times a step)."""
    return _count_nonzero(np.isfinite(x)) == x.size


def _largest(x: np.ndarray) -> np.floating:
    """``np.max(x)``: the same reduction over every entry (NaN propagating), without its wrapper."""
    return np.maximum.reduce(x, axis=None)


def _newton_verdict(size: float, last: float) -> int:
    """Radau IIA's simplified Newton iterations after a correction of ``size`` (RADAU_TOL (1 + |y|)
    units) following one of ``last``: 1 converged, -1 not contracting (NaN fails too), 0 go on."""
    if size <= 1.0:
        return 1
    return 0 if size < last else -1


def _rests(mode: _Mode) -> bool:
    """Some contact is closed or some joint rests on a stop (the mode has rows)."""
    return bool(_any(mode.closed) or _any(mode.stop))


def _mode_rows(pt: _Point, mode: _Mode, mu: float, valleys: np.ndarray | None = None) -> _Rows:
    """The mode's rows at ``pt``; ``valleys``: per breakpoint of the plane's terrain its two
    segments' normals (:attr:`_Landing.valleys`), for the mode's contacts resting in a corner."""
    if valleys is not None and mode.has_corner:
        cornered = np.flatnonzero(mode.closed & mode.cornered)
        contacts = np.flatnonzero(mode.closed & ~mode.cornered)
        rows = _rows(pt, contacts, mode.slip, mode.stop, mu, pt.M.shape[0], mode.core,
                     (cornered, valleys[mode.corner[cornered]]))
    else:
        rows = _rows(pt, np.flatnonzero(mode.closed), mode.slip, mode.stop, mu, pt.M.shape[0], mode.core)
    return replace(rows, redundant=True) if mode.redundant else rows


def _accelerations(pt: _Point, rows: _Rows) -> tuple[np.ndarray, np.ndarray]:
    """Accelerations and row forces of the mode: M a = f + F^T lambda, G a + b = 0."""
    X = np.linalg.solve(pt.M, np.column_stack([pt.f, rows.F.T]))
    a0, minv_ft = X[:, 0], X[:, 1:]
    if not rows.G.shape[0]:
        return a0, np.zeros(0)
    W = rows.G @ minv_ft
    rhs = -(rows.G @ a0 + rows.b)
    if rows.redundant:  # the least-norm split (np.linalg.solve would return any one, rounding's), pushing
        return _least_norm(W, rhs, a0, minv_ft, rows.n)
    try:
        lam = np.linalg.solve(W, rhs)
    except np.linalg.LinAlgError:  # redundant rows (e.g. two sticking contacts on one rod)
        lam = np.linalg.lstsq(W, rhs, rcond=None)[0]
    return a0 + minv_ft @ lam, lam


#: A closed contact the contact LCP leaves unloaded rests on while the mode's force on it is above
#: -HOLD_FORCE force tolerances (:meth:`_Landing.held`; a force witness is located below -0.1).
HOLD_FORCE = 0.05

#: Events shorter than REPEAT_SPAN (s, times the duration where that is longer than 1 s) that
#: each give back the mode they stopped (:func:`_same_kind`), more than REPEATS in a row, are a
#: stall (:meth:`_Landing.stall_message`) as events shorter than 1e-12 s are: the mode fails at
#: once again each time (random file 30891: two contacts starting to slide from rest, an event
#: every 4e-12 s, each with two failed slip searches of 0.4 s, for hours). So are, whatever
#: their length, such events whose arrest was refused (:attr:`_Landing.refused`: a slow slip
#: turned that friction cannot stop, the same one each time; 30891 again: an event every 1e-7
#: s, 7e5 to its end).
REPEAT_SPAN = 1e-9
#: Events stalled without a Painleve jam: the run crosses BRIDGE x its step by BRIDGE_STEPS
#: Moreau-Jean steps (:meth:`_Landing.bridge`), at most MAX_BRIDGES times a run.
BRIDGE = 1.0 / 8.0
BRIDGE_STEPS = 8
MAX_BRIDGES = 64
REPEATS = 50

#: Contacts closer than this (m) are at one point (:meth:`_Landing.unify`).
COINCIDENT = 1e-9
#: Rows whose matrix G M^-1 F^T has a singular value below this times its largest are redundant.
REDUNDANT = 1e-10


def _same_kind(a: _Mode, b: _Mode) -> bool:
    """The same contacts closed, the same sliding, the same stops (slip directions aside)."""
    return bool(np.array_equal(a.closed, b.closed) and np.array_equal(a.sliding, b.sliding)
                and np.array_equal(a.stop, b.stop))


def _least_norm(W: np.ndarray, rhs: np.ndarray, a0: np.ndarray, minv_ft: np.ndarray, pushing: int = 0
                ) -> tuple[np.ndarray, np.ndarray]:
    """(a0 + M^-1 F^T lambda, lambda) with W lambda = rhs for redundant rows W: the least-norm
    lambda, or where that pulls on one of the first ``pushing`` rows (the normal rows: contacts'
    and stops' forces, which Signorini's law keeps >= 0) the least-norm one of the splits that
    push on all of them (:func:`_pushing_split`), where one exists."""
    lam = np.linalg.lstsq(W, rhs, rcond=REDUNDANT)[0]
    if pushing and np.min(lam[:pushing]) < 0.0:
        lam = _pushing_split(W, lam, pushing)
    return a0 + minv_ft @ lam, lam


def _pushing_split(W: np.ndarray, lam: np.ndarray, pushing: int) -> np.ndarray:
    """The least-norm lambda + N z (N an orthonormal basis of W's null space, as
    :data:`REDUNDANT` ranks it; ``lam`` the least-norm solution, orthogonal to it) whose first
    ``pushing`` entries are >= 0: the least-distance problem min |z| subject to N_p z >= -lam_p
    (:func:`impulse_core.impact.nnls.least_distance`); ``lam`` where none exists (then no split of
    these rows pushes everywhere, and the force witness opens the pulling row). The rows' total
    force differs between splits where friction slides (F is not G): any of these meets the
    contact laws, and the least-norm one pulled while Lemke's answer of the same rows, which
    chose the mode, pushed (random file 30804: a hinged rod's tip at -2e-9 N, its force witness
    at every 4.5e-10 s)."""
    _, s, Vt = np.linalg.svd(W)
    N = Vt[int(np.count_nonzero(s > REDUNDANT * s[0])) :].T
    if not N.shape[1]:
        return lam
    z = least_distance(N[:pushing], -lam[:pushing])
    return lam if z is None else lam + N @ z


def _constrained_solve(W: np.ndarray, rows: _Rows, rhs: np.ndarray, row_rhs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(x, nu) with W x = rhs + F^T nu and G x = row_rhs (the rows of a mode; W symmetric positive
    definite): the mode's accelerations with W for the mass matrix."""
    X = np.linalg.solve(W, np.column_stack([rhs, rows.F.T]))
    x0, winv_ft = X[:, 0], X[:, 1:]
    if not rows.G.shape[0]:
        return x0, np.zeros(0)
    S = rows.G @ winv_ft
    r = row_rhs - rows.G @ x0
    if rows.redundant:
        return _least_norm(S, r, x0, winv_ft)
    try:
        nu = np.linalg.solve(S, r)
    except np.linalg.LinAlgError:  # redundant rows
        nu = np.linalg.lstsq(S, r, rcond=None)[0]
    return x0 + winv_ft @ nu, nu


def joint_law_rate(M: np.ndarray, damping: np.ndarray, stiffness: np.ndarray) -> float:
    """The joint laws' fastest rate (1/s) at a mass matrix M: the largest eigenvalue of M^-1 D (a
    damper's decay rate) or square root of that of M^-1 K (a spring's angular frequency), D and K
    the diagonal damping and stiffness per DOF. Constraints only lower it (interlacing). Where a
    massless direction's eigenvalue rounds below 0 (rods of radius 0 turning about their own axes
    with nothing but the core's floor as inertia: random file 60603, where the Cholesky factor
    failed), M's factor is taken from its eigenvalues floored at eps x the largest."""
    try:
        L = np.linalg.cholesky(M)
    except np.linalg.LinAlgError:
        w, V = np.linalg.eigh(M)
        L = V * np.sqrt(np.maximum(w, np.finfo(float).eps * w[-1]))  # L L^T = M, floored
    rates = [0.0]
    for d, root in ((damping, False), (stiffness, True)):
        if (d > 0).any():
            Li = np.linalg.solve(L, np.diag(d))
            top = float(np.max(np.linalg.eigvalsh(np.linalg.solve(L, Li.T).T)))
            rates.append(math.sqrt(max(top, 0.0)) if root else top)
    return max(rates)


def _contact_forces(rows: _Rows, lam: np.ndarray, mu: float, nc: int) -> tuple[np.ndarray, np.ndarray]:
    """Normal (n_c) and tangential (n_c x (d - 1)) force (or impulse) per contact from the rows'
    multipliers; a sliding contact's tangential force is -mu u lambda_n (u its slip direction)."""
    tangents = rows.direction.shape[1]
    fn, ft = np.zeros(nc), np.zeros((nc, tangents))
    on = rows.contact >= 0
    c = rows.contact[on]
    fn[c] = lam[: rows.n][on]
    ft[c] = -mu * rows.direction[c] * fn[c][:, None]
    ft[rows.contact[rows.owner]] = lam[rows.n :].reshape(tangents, len(rows.owner)).T
    if rows.cornered is not None:  # a corner's two rows: their forces' sum, along the point's normal and tangent
        k = rows.cornered
        corner, force = rows.contact[: rows.n][k], lam[: rows.n][k]
        fn[corner] = 0.0
        ft[corner] = 0.0
        np.add.at(fn, corner, force * rows.turn[k, 0])
        np.add.at(ft[:, 0], corner, force * rows.turn[k, 1])
    return fn, ft


def _corner_side(rows: _Rows) -> np.ndarray:
    """Per normal row: 0 for a corner's left segment's row (and any other row), 1 for its right's."""
    side = np.zeros(rows.n, int)
    k = np.flatnonzero(rows.cornered)
    side[k] = (k - k[0]) % 2  # the corners' rows are consecutive, left then right (:func:`_with_corners`)
    return side


def _corner_row_forces(rows: _Rows, lam: np.ndarray, nc: int) -> np.ndarray:
    """Per contact, its corner's left and right rows' forces (n_c x 2; NaN where it has none)."""
    out = np.full((nc, 2), np.nan)
    k = np.flatnonzero(rows.cornered)
    out[rows.contact[k], _corner_side(rows)[k]] = lam[k]
    return out


def _corner_forces(rows: _Rows, lam: np.ndarray, nc: int) -> np.ndarray:
    """Per contact, the smaller of its two corner rows' forces (inf where it has none)."""
    out = np.full(nc, np.inf)
    if rows.cornered is not None:
        k = rows.cornered
        np.minimum.at(out, rows.contact[: rows.n][k], lam[: rows.n][k])
    return out


def _unit(x: np.ndarray, tol: float) -> np.ndarray:
    """Rows of ``x`` made unit length where longer than ``tol``, else 0 (the plane: their signs)."""
    size = np.linalg.norm(x, axis=1, keepdims=True)
    return np.divide(x, size, out=np.zeros_like(x, dtype=float), where=size > tol)


def _followed_slip(along: Callable[[np.ndarray], tuple[float, float]], dims: int, acc_tol: float) -> np.ndarray | None:
    """A unit slip d whose acceleration follows it (``along(d)`` = (d x a_t(d), d . a_t(d)), the
    cross product 0 and the dot >= -acc_tol), or None: in the plane (``dims`` 1) the sign that
    does; in space the first of :data:`SLIP_SCAN` angles' brackets of the cross product's sign
    with a following acceleration, bisected to rounding."""
    if dims == 1:
        return next((d for d in (np.array([1.0]), np.array([-1.0])) if along(d)[1] >= -acc_tol), None)
    unit = lambda theta: np.array([math.cos(theta), math.sin(theta)])  # noqa: E731
    angles = np.linspace(-math.pi, math.pi, SLIP_SCAN + 1)
    values = [along(unit(theta)) for theta in angles]
    for (a, (ca_, _)), (b, (cb, _)) in zip(zip(angles, values), zip(angles[1:], values[1:])):
        if ca_ == 0.0 or (ca_ < 0.0) != (cb < 0.0):
            for _ in range(60):
                if ca_ == 0.0 or b - a <= 1e-15:
                    break
                mid = 0.5 * (a + b)
                cm = along(unit(mid))[0]
                a, b, ca_ = (a, mid, ca_) if (cm < 0.0) != (ca_ < 0.0) else (mid, b, cm)
            if along(unit(a))[1] >= -acc_tol:
                return unit(a)
    return None


def _stacked(fn: np.ndarray, ft: np.ndarray) -> np.ndarray:
    """[normal per contact, first tangent per contact, (space) second tangent per contact]."""
    return np.concatenate([fn, ft.T.ravel()])


def _unstacked(stacked: np.ndarray, nc: int, tangents: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_stacked`'s inverse: (normal per contact, n_c x ``tangents`` tangential), as views."""
    return stacked[:nc], stacked[nc:].reshape(tangents, nc).T


def impulse_vector(normal: np.ndarray, fn: np.ndarray, ft: np.ndarray, tangent: np.ndarray | None = None
                   ) -> np.ndarray:
    """The sum over contacts of the ground's impulse vectors (:func:`contact_vectors`; ``tangent``
    default :func:`tangent_basis`, ``ft`` n_c x (d - 1), or n_c in the plane)."""
    tangent = tangent_basis(normal) if tangent is None else tangent
    return contact_vectors(normal, tangent, fn, np.reshape(ft, (len(fn), -1))).sum(axis=1)


#: Where :func:`_hermite_root` samples the cubic for its first sign change.
_ROOT_SAMPLES = np.linspace(0.0, 1.0, 65)
#: Where :meth:`_Landing.grazing` samples a step (interior points), and the cubic Hermite basis
#: (h00, h10, h01, h11) there.
_GRAZE_SAMPLES = np.linspace(0.0, 1.0, 17)[1:-1, None]
_GRAZE_BASIS = tuple(
    c[0] * _GRAZE_SAMPLES**3 + c[1] * _GRAZE_SAMPLES**2 + c[2] * _GRAZE_SAMPLES + c[3]
    for c in ((2, -3, 0, 1), (1, -2, 1, 0), (-2, 3, 0, 0), (1, -1, 0, 0))
)


#: A mass matrix whose condition number exceeds this is near singular (:meth:`_Landing.singular_note`).
SINGULAR_MASS = 1e8
#: a diverged run names a pressed sliding contact whose row's effective inverse mass with
#: friction is below this fraction of its frictionless one (:meth:`_Landing.jam_note`)
JAM_NOTE = 1e-4
#: Impulsive jams at one instant after which the run stops with Painleve's paradox's error (the
#: jams did not end it: :meth:`_Landing.take_jam`; a cascade of jams at one instant takes the slip
#: by about a fixed factor each, 0.58 on random file 30325: 40 take it from 1 to 1e-9 m/s).
JAM_REPEATS = 200
#: Jams closer than this fraction of the duration are at one instant (:meth:`_Landing.take_jam`).
JAM_INSTANT = 1e-9
#: A run that diverged with a contact sliding is run again (:meth:`_Landing.run`); a pressed
#: sliding contact whose A = n M^-1 (n - mu u t)^T falls below this fraction of its frictionless
#: value then jams at a step's start, before its force -B / A takes the steps off (random file
#: 40029: by A at 2e-6 of it the steps had taken the slip from -2 to -25 m/s).
JAM_WATCH = 1e-3
#: Darboux-Keller's sliding phase in space (:func:`darboux_keller_slide`): RK4 steps in the normal
#: impulse, each a quarter of the slip over its rate, at most this many.
JAM_SLIDE_STEPS = 4000


def darboux_keller_slide(W: np.ndarray, slip: np.ndarray, mu: float) -> tuple[float, np.ndarray] | None:
    """The sliding phase of one contact's impulsive jam (impact without collision; Darboux-Keller,
    as in Genot and Brogliato 1999 and Champneys and Varkonyi 2016, "The Painleve paradox in
    contact mechanics", section 4): with the contact's normal impulse p as the impact's time,
    its impulse grows along the friction cone's edge, dP = (1, -mu u) dp with u = s / |s| its
    slip direction, its slip s (tangent basis, d - 1 entries) changes as ds/dp = W_tn - mu W_tt u
    and its normal velocity as dv_n/dp = A = W_nn - mu W_nt u (the row's effective inverse mass
    with friction: compression where A < 0), W = [n; t] M^-1 [n; t]^T the contact's Delassus
    matrix (rows normal, then tangents; constant during an impact). It ends when the slip
    vanishes, or (in space, where u and so A turn) when a compression deeper than JAM_NOTE of
    the initial slip speed is over, v_n back to its start (Newton's law at e = 0 against the
    pre-jam normal velocity); a shallower one is the dynamic jam's limit (A -> 0, v_n moving by
    A p -> 0: the slide goes on). In the plane in one step (u and A fixed, s linear in p); in
    space by RK4 in p, the compression's end bisected.

    Returns (p, the tangential impulse P_t, d - 1), or None where the slip does not fall along
    the edge (u . ds/dp >= 0: no edge impulse stops it)."""
    w_tn, w_tt, w_nt = W[1:, 0], W[1:, 1:], W[0, 1:]
    s = np.asarray(slip, dtype=float).copy()
    s0 = float(np.linalg.norm(s))
    if s0 == 0.0:
        return 0.0, np.zeros_like(s)
    if len(s) == 1:  # the plane: the slip falls linearly in p
        u = np.sign(s)
        rate = float(w_tn[0] - mu * w_tt[0, 0] * u[0])
        if rate * u[0] >= 0.0:
            return None
        p = -float(s[0]) / rate
        return p, -mu * u * p

    def derivative(y: np.ndarray) -> np.ndarray:  # y = (s, P_t, v_n - its start)
        u = y[:2] / np.linalg.norm(y[:2])
        return np.concatenate([w_tn - mu * w_tt @ u, -mu * u, [W[0, 0] - mu * w_nt @ u]])

    def rk4(y: np.ndarray, dp: float) -> np.ndarray:
        k1 = derivative(y)
        k2 = derivative(y + 0.5 * dp * k1)
        k3 = derivative(y + 0.5 * dp * k2)
        k4 = derivative(y + dp * k3)
        return y + dp / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)

    y, p, compressed = np.concatenate([s, np.zeros(3)]), 0.0, False
    for _ in range(JAM_SLIDE_STEPS):
        size = float(np.linalg.norm(y[:2]))
        if size <= 1e-12 * s0:
            return p, y[2:4]
        rate = derivative(y)[:2]
        if float(rate @ y[:2]) >= 0.0:
            return None
        dp = 0.25 * size / float(np.linalg.norm(rate))
        y1 = rk4(y, dp)
        if compressed and y1[4] >= 0.0:  # the compression ends within this step: bisect it
            lo, hi = 0.0, dp
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if rk4(y, mid)[4] < 0.0 else (lo, mid)
            return p + lo, rk4(y, lo)[2:4]
        compressed = compressed or y1[4] < -JAM_NOTE * s0
        y, p = y1, p + dp
    return None


#: Where :meth:`_Landing.locate` puts an event, in witness tolerances below zero: gaps and stop
#: margins (LOCATE_DEPTH), forces, cone margins and slips (FORCE_DEPTH); see its docstring.
LOCATE_DEPTH = 0.01
FORCE_DEPTH = 0.1


def location_offsets(start: np.ndarray, geometric: np.ndarray) -> np.ndarray:
    """Per watched witness (scaled, minus 1, at the step's start), d of its location window
    [-2 d, -d] (:meth:`_Landing.locate`): LOCATE_DEPTH for gaps and stop margins (``geometric``),
    FORCE_DEPTH for the others, or as far below the start's own value; at most 1."""
    depth = np.where(geometric, LOCATE_DEPTH, FORCE_DEPTH)
    return np.minimum(1.0, np.maximum(depth, depth - start))


def _hermite_root(g0: float, d0: float, g1: float, d1: float) -> float:
    """The first s in (0, 1) where the cubic Hermite fit of g(s) (values g0, g1 and slopes d0,
    d1 at s = 0, 1) falls below 0; NaN when the slopes are unknown or it does not."""
    if not (math.isfinite(d0) and math.isfinite(d1) and math.isfinite(g0) and math.isfinite(g1)):
        return math.nan
    s = _ROOT_SAMPLES
    c3, c2, c1, c0 = (float(c) for c in (2 * g0 + d0 - 2 * g1 + d1, -3 * g0 - 2 * d0 + 3 * g1 - d1, d0, g0))
    below = ((c3 * s + c2) * s + c1) * s + c0 < 0  # Horner's rule, as np.polyval
    first = int(below.argmax())
    if first == 0:  # none below, or below at s = 0
        return math.nan
    a, b = float(s[first - 1]), float(s[first])
    for _ in range(40):  # bisection on the polynomial: cheap (Horner's rule in Python floats)
        m = 0.5 * (a + b)
        if ((c3 * m + c2) * m + c1) * m + c0 >= 0:
            a = m
        else:
            b = m
    return b


def balanced_length(dt: float, ratio: float, order: int) -> float:
    """The next trial length after a step of length ``dt`` accepted with its momentum residual
    ``ratio`` times its share (:meth:`_Landing.balanced_step`): 2 dt where the ratio, grown as
    dt^p, would stay within 1 (ratio 2^p <= 1; an integrator of ``order`` p: the residual ~
    dt^(p + 1), the share ~ dt), else dt: an error-per-unit-step controller on the lengths h / 2^k.
    Doubling after every split made each accepted step cost a rejected trial where the balance
    sets the step; lengths h / 2^k keep runs at h and h / 2 whose every step the balance set one
    run, as :func:`landing` expects."""
    return 2.0 * dt if ratio * 2.0**order <= 1.0 else dt


# --------------------------------------------------------------------------------------------
# One run at a fixed step


@dataclass
class _Totals:
    """What a run accumulates."""

    normal: np.ndarray
    tangential: np.ndarray
    events: list[LandingEvent] = field(default_factory=list)
    times: list[float] = field(default_factory=list)
    states: list[np.ndarray] = field(default_factory=list)
    moving_until: float = 0.0
    steps: int = 0
    impulse: np.ndarray = field(default_factory=lambda: np.zeros(2))  # the contact impulses' sum (world)
    chart_q: np.ndarray | None = None  # the last recorded q, in the rotation coordinates of its time
    vectors: np.ndarray | None = None  # each contact's impulse vector (d x n_c, world)
    #: joint impulses (d x bodies) of the impacts and of the steps in which a contact rests
    #: (:meth:`_Landing.tally_joints`; None: not kept)
    joint: np.ndarray | None = None


@dataclass(frozen=True)
class _Trial:
    """A step of length ``tau`` (:meth:`_Landing.trial`): its end (q, v), contact impulses, the
    compiled step's end (None: the numpy path's), and the witnesses and their rates at its end."""

    tau: float
    q: np.ndarray
    v: np.ndarray
    impulse: np.ndarray
    end: tuple | None
    w: np.ndarray
    r: np.ndarray
    vectors: np.ndarray | None = None  # a curved heightfield: its impulses' world vectors (_Landing.vectors)


class _Landing:
    """The integration of one landing at one step length (module docstring)."""

    def __init__(self, tree: Tree, scene: Scene, laws: tuple[JointLaw, ...], settings: LandingSettings,
                 space: Space = PLANAR) -> None:
        _require_known(space)
        space = values_space(tree, space)  # the plane with centres of mass off the rods: PLANAR_OFFSET
        self.tree, self.scene, self.settings, self.space = tree, scene, settings, space
        self.topology = tree.topology()
        #: in the plane (PLANAR or PLANAR_OFFSET), not in space
        self.planar = space.joint_axis is not None
        ground = scene.terrain if self.planar else spatial_ground(scene)
        self.ground = ground  # the plane's profile, or space's heightfield
        if settings.step_code not in (C_CODE, VM_CODE, NUMPY_CODE, AUTO_CODE):
            raise ModelError(f"step_code: {settings.step_code!r} is not one of c, vm, numpy, auto")
        if settings.step_code in (C_CODE, AUTO_CODE):  # the point's dynamics compiled too
            from impulse_core.timedomain.landing_step import compiled_landing_function  # it builds on this module

            fn = compiled_landing_function(self.topology, ground, space, build=settings.step_code == C_CODE)
        else:
            fn = landing_function(self.topology, ground, space)
        #: the impacts' and mode choices' LCPs by Lemke's method as C with step code c (the same
        #: numbers; None: Python's, also without a C compiler)
        self.lemke = None
        #: the location's root of a cubic (:func:`_hermite_root`; with step code c as C, the same numbers)
        self.root = _hermite_root
        #: the design vector; a run's re-centred rotation coordinates change the base's orientation
        #: in the call's copy (:meth:`rechart`), and the next run starts from this one again
        self.design = design_vector(tree, space.body_values)
        self.call = BufferedCall(fn, self.design, scene.gravity)
        #: space: the turns the re-centrings put into the base's orientation (None: none), and the
        #: last reported rotation vector since touchdown (:meth:`reported`)
        self.chart: np.ndarray | None = None
        self.turn = np.zeros(3)
        self._last: tuple[tuple[bytes, bytes], _Point] | None = None  # see point()
        base_z = 0.0 if self.planar else float(scene.base_z)
        self.q0 = touchdown_configuration(tree, ground, scene.base_x, space=space, base_z=base_z)
        self.joints = joint_arrays(tree, laws, self.q0, space)
        self.layout = dof_layout(self.topology, space)
        self.nc, self.nv = len(tree.contacts), len(self.q0)
        #: the rows of a point's position: 2 in the plane, 3 in space
        self.dims = 2 if self.planar else 3
        self.mu, self.e = scene.friction, scene.restitution
        self.in_subtree = subtree_incidence(tree)
        self.mass = sum(b.mass for b in tree.bodies)
        #: space: the mass matrix's eigenvalue below which a direction moves no mass (:data:`MASSLESS`)
        self.massless = None if self.planar else MASSLESS * self.nv * sum(
            b.mass * (AXIAL_GYRATION_FLOOR * b.length) ** 2 for b in tree.bodies)
        self.subtree_mass = subtree_masses(tree)
        self.sloped = not ground.is_flat
        #: a curved ground whose normal turns under a sliding contact within a step (a sloped
        #: heightfield; a plane's terrain turns it only at its breakpoints, whose crossings are
        #: events): a step's impulse is then its stages' forces along their own directions
        self.turning = self.sloped and not self.planar
        #: the plane's terrain breakpoints (x, m) where a sloped profile's normal jumps; None: flat
        #: or space (:meth:`vertex_crossing`)
        self.vertices = np.asarray(scene.terrain.x, dtype=float) if self.planar and self.sloped else None
        #: space's sloped heightfield: its x and z grid lines, where the bilinear ground's normal
        #: jumps (a crease), so that a contact sliding across one is an event as a plane's
        #: breakpoint is (:meth:`pieces`); None: flat or the plane
        self.grid = (np.asarray(ground.x, dtype=float), np.asarray(ground.z, dtype=float)) \
            if self.turning else None
        #: the contact normals at the last accepted step's end (None: after an event or a crossing)
        self.end_normals: np.ndarray | None = None
        #: the point (q, v) whose rows the last :meth:`project` took its velocity projection on,
        #: where its impulses act (:meth:`add`)
        self.projected_at: tuple[np.ndarray, np.ndarray] | None = None
        #: per breakpoint of the plane's terrain, its left and right pieces' outward normals
        #: (K x 2 x 2; the rays beyond the ends are flat), and whether it is a valley's (concave:
        #: the slope rises across it), where a contact can rest held by both; None: flat or space
        self.valleys: np.ndarray | None = None
        self.concave: np.ndarray | None = None
        if self.vertices is not None:
            up = np.array([[0.0, 1.0]])
            pieces = np.vstack([up, terrain_normals(scene.terrain), up])
            self.valleys = np.stack([pieces[:-1], pieces[1:]], axis=1)
            left, right = self.valleys[:, 0], self.valleys[:, 1]
            self.concave = left[:, 0] * right[:, 1] - left[:, 1] * right[:, 0] > 1e-12  # the normal turns anticlockwise
        #: per contact, the valley breakpoint where the run's current mode holds it in the corner
        #: (-1: none); there the point's normal and tangent are the breakpoint's (the mean of its
        #: segments' normals, :func:`impulse_core.model.terrain.slope_normal`), whatever rounding
        #: places it on, so that its impulses sum in one frame (:meth:`seat`)
        self.seated = np.full(self.nc, -1)
        self.seat_frames = None if self.vertices is None else slope_normal(scene.terrain, self.vertices)
        weight = self.mass * max(scene.gravity, 1.0)
        self.force_tol = 1e-9 * weight
        self.speed_tol = 1e-9 * max(1.0, scene.speed, abs(scene.velocity_x))
        #: The integrator between events (RK4, IMPLICIT or RADAU), one for every step length.
        self.method = settings.integrator
        #: the joint laws' fastest rate at touchdown (1/s, :func:`joint_law_rate`)
        M0 = self.mass_matrix_at(self.q0)
        self.rate = joint_law_rate(M0, self.joints.damping, self.joints.stiffness)
        if self.method == AUTO:
            h0, limit = ((settings.step, RK4_STABLE) if settings.step
                         else ((scene.duration or 0.0) * FIRST_STEPS[0], AUTO_IMPLICIT))
            self.method = IMPLICIT if h0 * self.rate > limit else RK4
        if self.method not in (RK4, IMPLICIT, RADAU):
            raise ModelError(f"integrator: {settings.integrator!r} is not one of rk4, implicit, radau, auto")
        #: circular-cone solves of the current run that fell back to the polyhedral answer
        self.inexact = self.non_unique = 0
        #: the current run's Moreau-Jean bridges across stalled events: (start, span) (:meth:`bridge`)
        self.bridges: list[tuple[float, float]] = []
        #: the law's answer at the last impact (:meth:`impact`)
        self.last_impact: RigidImpact | None = None
        #: the contacts whose turned slip the last :meth:`arrest` left sliding (its mode with them
        #: sticking does not hold); events that repeat so are a stall (:data:`REPEATS`)
        self.refused = np.zeros(0, int)
        #: None, or a list that each impact appends (q, v, its contacts, its point, the law's answer) to
        self.impact_log: list | None = None
        #: keep the joint impulses of impacts and resting phases (:attr:`_Totals.joint`)
        self.tally_joint = False
        #: the generalized velocity before the first touchdown (None: the scene's approach)
        self.v_minus: np.ndarray | None = None
        #: a rebound shorter than this (s) is plastic: MIN_BOUNCE of the duration at the first
        #: impact, and also ``settings.bounce_steps`` of the step after it (set by :meth:`run`)
        self.min_bounce = MIN_BOUNCE * float(scene.duration or 0.0)
        #: None, or a list that a run appends its committed operations to, in order (what
        #: :mod:`impulse_core.timedomain.landing_derivatives` replays): ("step", q, v, mode, dt,
        #: final), ("event_step", q, v, mode, tau, watch), ("vertex_step", q, v, mode, tau, crossed:
        #: a step to a resting contact passing a terrain breakpoint, :meth:`vertex_crossing`; the
        #: replay refuses it), ("impact", q, v, rows, e, sol, plastic:
        #: the rows whose restitution the plastic rules zeroed) and ("project", q, v, mode), that
        #: followed by ("crease_project",) where its correction carried a resting contact across a
        #: heightfield's grid line (its rows then the next cell's; the replay refuses it); q, v
        #: are the operation's inputs.
        self.tape: list | None = None
        #: the compiled step of the integrator (None: numpy), and the last compiled step's end (ended())
        self.fast = self.compiled_step(settings.step_code)
        #: the code the steps run on: c, vm or numpy (``auto``: c where the compile cache holds it)
        self.code = NUMPY_CODE if self.fast is None else C_CODE if self.fast.compiled else VM_CODE
        if self.code == C_CODE:
            self.lemke = lemke_c.compiled_lemke()
            self.root = lemke_c.hermite_root(_ROOT_SAMPLES) or _hermite_root
        self._end: tuple[bytes, bytes, object] | None = None
        #: a curved heightfield (turning): the last step's contact impulses as world vectors (d x n_c), each
        #: stage's force along its own point's normal and tangents (:meth:`stage_vectors`)
        self.vectors: np.ndarray | None = None
        self._unwatched: dict[bytes, np.ndarray] = {}  # see unwatched()
        self._solutions: tuple[_Point | None, dict] = (None, {})  # see mode_solution()
        self._steering: tuple = (None, b"")  # steer()'s last point, mode and figures
        self._jams: tuple[float, int] = (math.nan, 0)  # the last impulsive jam's time and its count there
        #: None (no impulsive jams), or, once a run of this landing stopped with Painleve's paradox
        #: (:meth:`run`), the fraction of its frictionless value below which a pressed sliding
        #: contact's A = n M^-1 (n - mu u t)^T jams at a step's start
        self.jam_watch: float | None = None
        #: RK4's stable step where this run is ``auto``'s implicit first run (:func:`landing` sets
        #: it; :data:`RK4_PACE`), else None
        self.rk4_pace: float | None = None
        gap_tol, nc, nv = settings.gap_tolerance, self.nc, self.nv
        #: the witnesses' tolerances (:meth:`witness_and_rate`): gaps, forces, cone margins, slip,
        #: stop margins (twice), stop forces; and the NaN rates of the force and slip witnesses
        self.witness_scale = np.concatenate([np.full(nc, gap_tol), np.full(2 * nc, self.force_tol),
                                             np.full(nc, self.speed_tol), np.full(2 * nv, gap_tol),
                                             np.full(nv, self.force_tol)])
        self.unknown_rates = (np.full(3 * nc, np.nan), np.full(nv, np.nan))
        up = np.tile(np.eye(self.dims)[1], (self.nc, 1))
        #: flat ground's normals and tangents at every contact (:func:`tangent_basis`)
        self.flat_ground = (up, tangent_basis(up))
        self.refuse_massless_contacts(tree, M0)
        self.refuse_swinging_springs(tree, M0)

    def first_step(self) -> float:
        """:attr:`LandingSettings.step`, or by default (:data:`FIRST_STEPS`) the implicit
        integrator's duration / 200 and RK4's :meth:`stable_step`."""
        if self.settings.step:
            return self.settings.step
        if self.method in (IMPLICIT, RADAU):
            return FIRST_STEPS[0] * float(self.scene.duration)
        return self.stable_step()

    def stable_step(self) -> float:
        """RK4's longest stable step for the joint laws at touchdown (RK4_STABLE / rate), at most
        duration / 100: where ``auto``'s implicit run overran its step budget (the momentum
        balance split its steps), :func:`landing` runs RK4 from this step instead (random file
        30039, h x rate 3.6: 97 s on ROS2 restarted at h / 16, 3.9 s so; 30094: about 10 min
        against 5.2 s; 30000: over 120 s against 28.5 s)."""
        longest = FIRST_STEPS[1] * float(self.scene.duration)
        return min(longest, RK4_STABLE / self.rate) if self.rate > 0 else longest

    def compiled_step(self, code: str):
        """The compiled step of this landing's integrator (:mod:`impulse_core.timedomain.landing_step`),
        or None where the numpy path integrates (``numpy``)."""
        if code == NUMPY_CODE:
            return None
        from impulse_core.timedomain.landing_step import CompiledStep  # it builds on this module

        return CompiledStep(self.topology, self.ground, self.design, self.scene.gravity, self.mu, self.joints,
                            code=code, space=self.space, floor=self.speed_tol, method=self.method)

    def ended(self, q: np.ndarray, v: np.ndarray, mode: _Mode | None = None):
        """The last compiled step's :class:`~impulse_core.timedomain.landing_step.StepEnd` if it
        ended at (q, v) (in ``mode``, if given), else None."""
        if self._end is None or self._end[0] != q.tobytes() + v.tobytes():
            return None
        if mode is not None and self._end[1] != _mode_bytes(mode):
            return None
        return self._end[2]

    def seat(self, mode: _Mode) -> None:
        """Take ``mode``'s corners as the run's (:attr:`seated`): the kept points are dropped where
        they change."""
        if np.array_equal(mode.corner, self.seated):
            return
        self.seated = mode.corner.copy()
        self._last, self._solutions, self._end = None, (None, {}), None

    @property
    def any_seated(self) -> bool:
        return bool(_any(self.seated >= 0))

    # ---- dynamics

    def point(self, q: np.ndarray, v: np.ndarray) -> _Point:
        """The dynamics at (q, v); the last one is kept, since a step's end is asked for by the
        momentum balance, the divergence check and the witnesses in turn (read only)."""
        key = (q.tobytes(), v.tobytes())
        last = self._last
        if last is not None and last[0] == key:
            return last[1]
        # at the last point's q (an impact's velocity after it): its geometry is this one's
        pt = self._evaluate(q, v, last[1] if last is not None and last[0][0] == key[0] else None)
        self._last = (key, pt)
        return pt

    def _evaluate(self, q: np.ndarray, v: np.ndarray, like: _Point | None = None) -> _Point:
        """The dynamics at (q, v); ``like``: a point at the same q, whose figures of q alone (gap,
        normal and tangents, Jacobians, mass matrix, contact positions: the compiled function
        computes them alike from q) are shared rather than derived again (read only)."""
        self.call.call(q, v)
        o, f = self.call.out, self.call.flat
        d = self.dims
        nc, nv = self.nc, self.nv
        bias = f[3].reshape(nc, d)
        if like is None and d == 2:
            # the plane: the normal and tangent components of the Jacobian rows and of the bias at
            # once, (n_x x + n_y y, as _along adds them) over [J | bias] per contact
            normal = o[1].T.copy()
            if self.any_seated:  # a contact in a valley corner: the breakpoint's frame
                held = self.seated >= 0
                normal[held] = self.seat_frames[self.seated[held]]
            tangent = tangent_basis(normal)
            JB = np.concatenate([o[2].reshape(nc, d, nv), bias[:, :, None]], axis=2)  # nc x d x (nv + 1)
            D = np.stack([normal, tangent[:, 0]], axis=1)[:, :, :, None]  # nc x (normal, tangent) x d x 1
            out = D[:, :, 0] * JB[:, None, 0]
            out += D[:, :, 1] * JB[:, None, 1]
            # in _along's memory order (the compiled function's column-major J), the tangent's axis
            # added as a view as before: matmul takes another path, and rounds otherwise, on other strides
            Jn, Jt = np.asfortranarray(out[:, 0, :nv]), np.asfortranarray(out[:, 1, :nv])[:, None]
            bn, bt = np.ascontiguousarray(out[:, 0, nv]), np.ascontiguousarray(out[:, 1, nv])[:, None]
            gap, M, contacts = f[0].copy(), o[4].copy(), o[9].T.copy()
        else:
            if like is None:
                normal = o[1].T.copy()
                tangent = tangent_basis(normal)
                J = o[2].reshape(nc, d, nv)  # per contact, its x, y, z rows
                Jt = np.stack([_along(tangent[:, a], J) for a in range(d - 1)], axis=1)
                gap, Jn, M, contacts = f[0].copy(), _along(normal, J), o[4].copy(), o[9].T.copy()
            else:
                normal, tangent, Jt = like.normal, like.tangent, like.Jt
                gap, Jn, M, contacts = like.gap, like.Jn, like.M, like.contacts
            bn = _along(normal, bias)
            if d == 2:
                bt = _along(tangent[:, 0], bias)[:, None]
            else:
                bt = np.column_stack([_along(tangent[:, a], bias) for a in range(d - 1)])
        return _Point(
            gap=gap,
            normal=normal,
            tangent=tangent,
            Jn=Jn,
            Jt=Jt,
            bn=bn,
            bt=bt,
            M=M,
            f=f[5] + self.joints.torque(q, v),
            kinetic=float(f[6][0]),
            momentum=o[7].copy(),
            com_height=float(f[8][0]),
            contacts=contacts,
            slip=Jt @ v,
            slip_floor=self.speed_tol,
        )

    def mode_solution(self, pt: _Point, mode: _Mode, solve: bool = True
                      ) -> tuple[_Rows, tuple[np.ndarray, np.ndarray] | None]:
        """The mode's rows at ``pt`` (:func:`_mode_rows`) and, if ``solve``, its accelerations and
        row forces (:func:`_accelerations`), kept for the last point asked: an event's mode choice,
        its checks and the projection after it ask them of one point for one or two modes."""
        if self._solutions[0] is not pt:
            self._solutions = (pt, {})
        known = self._solutions[1]
        key = _mode_bytes(mode) + mode.core.tobytes()
        rows, solution = known.get(key, (None, None))
        if rows is None:
            rows = _mode_rows(pt, mode, self.mu, self.valleys)
        if solve and solution is None:
            solution = _accelerations(pt, rows)
        known[key] = (rows, solution)
        return rows, solution

    def mass_matrix_at(self, q: np.ndarray) -> np.ndarray:
        """The mass matrix at q."""
        self.call.call(q, np.zeros(self.nv))
        return self.call.out[4].copy()

    def derivative(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> tuple[np.ndarray, np.ndarray]:
        """(acceleration, [normal forces, tangential forces]) in the fixed mode."""
        pt = self.point(q, v)
        if not _rests(mode):  # free flight: no rows to build
            return np.linalg.solve(pt.M, pt.f), np.zeros(self.dims * self.nc)
        rows = _mode_rows(pt, mode, self.mu, self.valleys)
        a, lam = _accelerations(pt, rows)
        return a, _stacked(*_contact_forces(rows, lam, self.mu, self.nc))

    def step(self, q: np.ndarray, v: np.ndarray, mode: _Mode, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One step of the landing's integrator: (q, v, contact impulses [normal, tangential])."""
        self.steer(q, v, mode, h)
        if self.method == RADAU:
            return self.radau_step(q, v, mode, h)
        end = self.compiled(q, v, mode, h)
        if end is not None:
            return self.kept(end, mode)
        try:
            return self.implicit_step(q, v, mode, h) if self.method == IMPLICIT else self.rk4_step(q, v, mode, h)
        except np.linalg.LinAlgError:  # a stage far off the motion (random file 60690: |v| ~ 1e21 within
            # one step): the step blew up, which the run reports as such and landing() shortens
            return np.full_like(q, np.nan), np.full_like(v, np.nan), np.full(self.nc * self.dims, np.nan)

    def compiled(self, q: np.ndarray, v: np.ndarray, mode: _Mode, h: float, z0: np.ndarray | None = None):
        """The compiled step's :class:`~impulse_core.timedomain.landing_step.StepEnd` (Radau IIA:
        from the stages' ``z0``), or None where the numpy path answers (no compiled step, a
        valley's corner, a redundant mode, a non-finite result)."""
        return None if self.fast is None or mode.has_corner else self.fast.step(q, v, h, mode, z0)

    def kept(self, end, mode: _Mode) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A compiled step's (q, v, contact impulses), its end kept for :meth:`ended`."""
        self._end = (end.q.tobytes() + end.v.tobytes(), _mode_bytes(mode), end)
        self.vectors = end.vectors.copy() if self.turning else None
        return end.q.copy(), end.v.copy(), end.impulse.copy()

    def steer(self, q: np.ndarray, v: np.ndarray, mode: _Mode, h: float) -> None:
        """Set ``mode.core`` for a step of length h from (q, v) (space, sliding contacts). A
        lateral slip s_perp of a sliding contact decays at the rate mu f_n w / |s| (w: the trace of
        its tangential inverse mass J_t M^-1 J_t^T): stiff as |s| falls, and an explicit step
        beyond 1 / rate amplifies it instead (a slow-slipping loaded toe turned the foot out of
        its plane within two steps). core = h mu f_n w caps that rate at 1 / h (RK4 is stable to
        2.8 / h): the direction is exact s / |s| above |s| = core and regularised below it; core
        shrinks with the step, so the landing's step halving converges to the exact law. The
        plane (one tangent) is untouched."""
        if self.dims == 2 or self.mu <= 0 or not (mode.closed & mode.sliding).any():
            return
        mode.core[:] = 0.0
        pt = self.point(q, v)
        key = _mode_bytes(mode)
        if self._steering[0] is not pt or self._steering[1] != key:  # a new point or mode (not a retrial)
            rows, (_, lam) = self.mode_solution(pt, mode)
            forces, _ = _contact_forces(rows, lam, self.mu, self.nc)
            moving = np.flatnonzero(mode.closed & mode.sliding)
            X = np.linalg.solve(pt.M, pt.Jt[moving].reshape(-1, self.nv).T)
            w = np.einsum("ij,ji->i", pt.Jt[moving].reshape(-1, self.nv), X).reshape(len(moving), -1).sum(axis=1)
            self._steering = (pt, key, moving, np.maximum(forces[moving], 0.0), w)
        _, _, moving, pushing, w = self._steering
        mode.core[moving] = h * self.mu * pushing * w

    def follow_slip(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> None:
        """In space, after a step: each sliding contact's mode direction d becomes its friction's
        slip direction u at the step's end (:func:`slip_direction` with the step's core), so that
        the slip-stop witness (s . d) watches the slip as it turns and the regularised direction
        relaxes towards s / |s|."""
        if self.dims == 2 or self.mu <= 0 or not (mode.closed & mode.sliding).any():
            return
        pt = self.point(q, v)
        moving = mode.closed & mode.sliding
        mode.slip[moving] = slip_direction(pt, mode.slip, mode.core)[moving]

    def implicit_step(self, q: np.ndarray, v: np.ndarray, mode: _Mode, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One step of ROS2 (Verwer, Spee, Blom and Hundsdorfer 1999), a two-stage Rosenbrock-W
        method: second order for any matrix in (I - gamma h A) k = r, so A may hold only the
        stiff part of the Jacobian: here the joint springs and dampers, A = [[0, I], [-P M^-1 K,
        -P M^-1 D]] with P the mode's projection (its rows G, forces F at the step's start).
        Solving (I - gamma h A) k = r is then one constrained solve with the matrix
        W = M + gamma h D + gamma^2 h^2 K (MuJoCo's implicit damping, with the springs too):
        (W k_v - F^T nu = M r_v - gamma h K r_q, G k_v = G r_v; k_q = r_q + gamma h k_v).
        Stages: k1 from r = (v, a(y)); k2 from r = F(y + h k1) - 2 k1; y + h (3 k1 + k2) / 2.
        The contact impulses are the matching combination of the stages' row forces
        (h / 2 (nu_1 + lambda(y + h k1) + nu_2)): the first stage's implicit forces nu_1 and the
        second's correction nu_2 carry what the stiff laws transmit within the step (explicit
        samples of the contact forces would not), with the second stage's force taken with the
        first stage's mass matrix; the momentum balance closes to O(h^2) between events (on a
        random leg of the tests 7.9e-6, 2.0e-6, 5.0e-7 of the momentum at h = 5e-4, 2.5e-4,
        1.25e-4 s; RK4 2e-10 at 5e-4 s). The
        Coriolis terms stay explicit (as in MuJoCo's implicitfast), which keeps W symmetric
        positive definite and its base rows M's."""
        g = ROS2_GAMMA * h
        D, K = self.joints.damping, self.joints.stiffness
        pt = self.point(q, v)
        rows = _mode_rows(pt, mode, self.mu, self.valleys)
        W = pt.M + np.diag(g * D + g * g * K)
        k1v, nu1 = _constrained_solve(W, rows, pt.f - g * K * v, -rows.b)
        k1q = v + g * k1v
        q2, v2 = q + h * k1q, v + h * k1v
        a2, f2 = self.derivative(q2, v2, mode)
        v2_vectors = self.stage_vectors(q2, v2, f2)
        rq, rv = v2 - 2.0 * k1q, a2 - 2.0 * k1v
        k2v, nu2 = _constrained_solve(W, rows, pt.M @ rv - g * K * rq, rows.G @ rv)
        k2q = rq + g * k2v
        f1 = _stacked(*_contact_forces(rows, nu1, self.mu, self.nc))
        f3 = _stacked(*_contact_forces(rows, nu2, self.mu, self.nc))
        if self.turning:
            self.vectors = 0.5 * h * (self.stage_vectors(q, v, f1 + f3) + v2_vectors)
        return q + 0.5 * h * (3.0 * k1q + k2q), v + 0.5 * h * (3.0 * k1v + k2v), 0.5 * h * (f1 + f2 + f3)

    def radau_step(self, q: np.ndarray, v: np.ndarray, mode: _Mode, h: float, splits: int = RADAU_SPLITS
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A Radau IIA step of length h (:meth:`radau_once`), or where its Newton iterations do not
        converge, two of h / 2, each split so again, at most ``splits`` times (then NaN:
        :meth:`balanced_step` halves the step), down to RK4's stable step, where an RK4 step takes
        the piece. Random file 60147: the iterations failed on steps that crossed the point where
        a sliding contact's slip stops (the fixed mode's dynamics turn there), and an event
        location's trial step, NaN, reached the witnesses' least squares, which failed."""
        q1, v1, impulse = self.radau_once(q, v, mode, h)
        if _finite(q1) and _finite(v1):
            return q1, v1, impulse
        if h <= self.stable_step():  # RK4 is stable here: a piece across the mode's end (60147: a slip stopping)
            return self.rk4_step(q, v, mode, h)
        if splits == 0:
            return q1, v1, impulse
        qa, va, pa = self.radau_step(q, v, mode, 0.5 * h, splits - 1)
        if not (_finite(qa) and _finite(va)):
            return qa, va, pa
        first = self.vectors
        qb, vb, pb = self.radau_step(qa, va, mode, 0.5 * h, splits - 1)
        if self.turning:
            self.vectors = first + self.vectors
        self._end = None  # the last piece's end is not the step's (its balance, its start)
        return qb, vb, pa + pb

    def radau_once(self, q: np.ndarray, v: np.ndarray, mode: _Mode, h: float
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One step of the two-stage Radau IIA method: the compiled step's Newton iterations
        (:func:`~impulse_core.timedomain.landing_step._radau`, RADAU_UNROLLED a call, each call
        from the last one's Z) to their convergence, NaN where they stop contracting or do not
        converge within RADAU_ITERATIONS; :meth:`radau_newton` where the compiled step does not answer."""
        Z, last, done = None, math.inf, 0
        while done < RADAU_ITERATIONS:
            end = self.compiled(q, v, mode, h, Z)
            if end is None:
                return self.radau_newton(q, v, mode, h)
            for size in end.newton:
                verdict, last = _newton_verdict(float(size), last), float(size)
                if verdict:
                    return self.kept(end, mode) if verdict > 0 else self.failed_step()
            Z, done = end.z, done + len(end.newton)
        return self.failed_step()

    def radau_newton(self, q: np.ndarray, v: np.ndarray, mode: _Mode, h: float
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One step of the two-stage Radau IIA method (:data:`RADAU_A`) on y' = (v, a(q, v)) in the
        fixed mode (a: the mode's accelerations, its rows' forces solved at each stage as the
        derivative does): stages Y_i = y + Z_i with Z = h A F(Y), the end Y_2. Simplified Newton
        iterations with the matrix I - h A x J, J the stiff part of the Jacobian at the step's
        start: the joint springs and dampers through the mode's constrained inverse mass
        (da/dq = -Pi M^-1 K, da/dv = -Pi M^-1 D, Pi M^-1 = M^-1 - M^-1 F^T (G M^-1 F^T)^-1 G M^-1). Unlike
        ROS2 it is stiffly accurate: at h x rate >> 1 a damped joint's motion keeps third order in
        the slow part (ROS2's error there is what splits its steps by the momentum balance). The
        contact impulses are h sum_i b_i (the stage's row forces). Non-converged iterations
        return NaN (:meth:`radau_step` splits the step). In numpy: the reference, and the step
        where the compiled one does not answer (:meth:`radau_once`)."""
        nv = self.nv
        pt = self.point(q, v)
        C = np.linalg.inv(pt.M)
        if _rests(mode):
            rows = _mode_rows(pt, mode, self.mu, self.valleys)
            if rows.G.shape[0]:
                X = C @ rows.F.T
                C = C - X @ np.linalg.lstsq(rows.G @ X, rows.G @ C, rcond=None)[0]
        n = 2 * nv
        J = np.zeros((n, n))
        J[:nv, nv:] = np.eye(nv)
        J[nv:, :nv] = -C * self.joints.stiffness[None, :]
        J[nv:, nv:] = -C * self.joints.damping[None, :]
        E = np.eye(2 * n) - h * np.kron(RADAU_A, J)
        y0 = np.concatenate([q, v])
        scale = RADAU_TOL * (1.0 + np.abs(y0))
        Z, last = np.zeros((2, n)), math.inf
        for _ in range(RADAU_ITERATIONS):
            stages = [self.derivative(y0[:nv] + Z[i, :nv], y0[nv:] + Z[i, nv:], mode) for i in range(2)]
            Fs = np.array([np.concatenate([y0[nv:] + Z[i, nv:], stages[i][0]]) for i in range(2)])
            dZ = np.linalg.solve(E, (h * (RADAU_A @ Fs) - Z).ravel()).reshape(2, n)
            Z += dZ
            size = float(np.max(np.abs(dZ) / scale))
            verdict, last = _newton_verdict(size, last), size
            if verdict > 0:
                break
            if verdict < 0:
                return self.failed_step()
        else:
            return self.failed_step()
        if self.turning:
            self.vectors = h * sum(RADAU_B[i] * self.stage_vectors(y0[:nv] + Z[i, :nv] - dZ[i, :nv],
                                                                   y0[nv:] + Z[i, nv:] - dZ[i, nv:], stages[i][1])
                                   for i in range(2))
        y1 = y0 + Z[1]
        return y1[:nv], y1[nv:], h * (RADAU_B[0] * stages[0][1] + RADAU_B[1] * stages[1][1])

    def failed_step(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A Radau IIA step whose Newton iterations did not converge: (q, v, contact impulses) NaN."""
        nan = np.full(self.nv, np.nan)
        return nan, nan.copy(), np.full(self.dims * self.nc, np.nan)

    @property
    def balance_order(self) -> int:
        """The order in the step of a step's momentum residual per unit time (RK4 4, Radau IIA 3,
        ROS2 2).
        Where two runs of the step halving were split alike by the balance, the next run asks its
        steps for a share of the balance smaller by 2 to this power (:func:`landing`), so that
        the steps the balance splits are halved with the rest: with the share fixed they stayed
        as long (random file 30730's runs at h / 2 to h / 64 took the same 33,917 steps, and
        their differences said nothing). Only there: shrunk at every halving from then on, the
        share of random file 30649 reached rounding's level by h / 64 (over 300 s instead of 63 s)."""
        return 4 if self.method == RK4 else 3 if self.method == RADAU else 2

    def balanced_step(self, q: np.ndarray, v: np.ndarray, mode: _Mode, trial: float, rate: float, floor: float
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, float]:
        """One step of length ``trial``, halved (not below ``floor``) until the step's momentum
        balance closes to ``rate`` times its length (:data:`MOMENTUM_BALANCE`): the step's change of the linear
        momentum equals its contact impulses plus the weight's, exactly for the true motion. A
        fast-spinning light rod resting on its tip (tens of kN of contact force over one step) is
        where the fixed step is too long; the residual is then the step's error, seen in a law
        the motion obeys. So it is for ROS2 at h x rate >> 1: the momentum P(q) v is not linear
        in the state, and the stiff joint motion's error reaches it (a flight's centre-of-mass
        velocity is off by the residual; studies/whole_landing/spatial_chatter.md). A residual
        within rounding's level (:meth:`balance_rounding`) is taken for none, its step's error
        unseen below it: the step closes and the next may double. Returns (q, v, contact
        impulses, the step's length, the next trial's length: :func:`balanced_length`)."""
        p0 = None
        dt, order = trial, self.balance_order
        while True:
            q1, v1, impulse = self.step(q, v, mode, dt)
            if dt > floor and self.method == RADAU and not (_finite(q1) and _finite(v1)):
                dt /= 2.0  # its Newton iterations did not converge (radau_step)
                continue
            if dt <= floor or not (_finite(q1) and _finite(v1)):
                return q1, v1, impulse, dt, 2.0 * dt
            end = self.ended(q1, v1, mode)
            if end is None and p0 is None:
                p0 = self.point(q, v).momentum[:, 0].copy()
            balance = end.balance if end is not None else self.momentum_change(p0, q1, v1, impulse)
            weight = self.weight(dt)
            residual, share = float(_largest(np.abs(balance - weight))), rate * dt
            ratio = residual / share if share > 0 else (0.0 if residual <= 0 else math.inf)
            if ratio > 1.0 / 2.0**order and residual <= self.balance_rounding(q1, v1, end, p0, balance, weight):
                ratio = 0.0  # rounding's residual: the step's error is below it (BALANCE_ROUNDING)
            if ratio <= 1.0:
                return q1, v1, impulse, dt, balanced_length(dt, ratio, order)
            dt /= 2.0

    def balance_rounding(self, q1: np.ndarray, v1: np.ndarray, end, p0: np.ndarray | None, balance: np.ndarray,
                         weight: np.ndarray) -> float:
        """The rounding level of a step's momentum residual ``balance`` - ``weight`` (the step
        from a state of momentum ``p0`` to (q1, v1); ``end``: a compiled step's end, which holds
        both momenta): BALANCE_ROUNDING x eps times the largest of its terms, the
        momenta at both ends, the contact impulses (p1 - p0 - ``balance``) and the weight's."""
        if end is not None:
            p0, p1 = end.momentum0, end.momentum1
        else:
            p1 = self.point(q1, v1).momentum[:, 0]
        applied = p1 - p0 - balance
        scale = max(float(_largest(np.abs(p0))), float(_largest(np.abs(p1))), float(_largest(np.abs(applied))),
                    float(_largest(np.abs(weight))))
        return BALANCE_ROUNDING * float(np.finfo(float).eps) * scale

    def momentum_change(self, p0: np.ndarray, q1: np.ndarray, v1: np.ndarray, impulse: np.ndarray) -> np.ndarray:
        """The linear momentum at (q1, v1) minus ``p0`` and the contact ``impulse`` ([normal,
        tangential] per contact, along the normals and tangents at (q1, v1); on a curved heightfield the
        step's :attr:`vectors`): a step's momentum balance but for the weight's impulse (numpy; a
        compiled step's is its ``balance``)."""
        pt = self.point(q1, v1)
        if self.turning:
            return pt.momentum[:, 0] - p0 - self.vectors.sum(axis=1)
        return pt.momentum[:, 0] - p0 - impulse_vector(pt.normal, *_unstacked(impulse, self.nc, self.dims - 1))

    def kinetic(self, q: np.ndarray, v: np.ndarray) -> float:
        """The kinetic energy at (q, v)."""
        end = self.ended(q, v)
        return end.kinetic if end is not None else self.point(q, v).kinetic

    def weight(self, duration: float) -> np.ndarray:
        """The weight's impulse over ``duration`` (world frame: along -y)."""
        return -self.mass * self.scene.gravity * duration * self.flat_ground[0][0]

    def rk4_step(self, q: np.ndarray, v: np.ndarray, mode: _Mode, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One classical Runge-Kutta 4 step: (q, v, contact impulses [normal, tangential]); on
        a curved heightfield their world vectors by stage in :attr:`vectors`."""
        a1, f1 = self.derivative(q, v, mode)
        V1 = self.stage_vectors(q, v, f1)
        a2, f2 = self.derivative(q + 0.5 * h * v, v + 0.5 * h * a1, mode)
        V2 = self.stage_vectors(q + 0.5 * h * v, v + 0.5 * h * a1, f2)
        v2 = v + 0.5 * h * a1
        a3, f3 = self.derivative(q + 0.5 * h * v2, v + 0.5 * h * a2, mode)
        V3 = self.stage_vectors(q + 0.5 * h * v2, v + 0.5 * h * a2, f3)
        v3 = v + 0.5 * h * a2
        a4, f4 = self.derivative(q + h * v3, v + h * a3, mode)
        v4 = v + h * a3
        q1 = q + h / 6.0 * (v + 2 * v2 + 2 * v3 + v4)
        v1 = v + h / 6.0 * (a1 + 2 * a2 + 2 * a3 + a4)
        if self.turning:
            self.vectors = h / 6.0 * (V1 + 2 * V2 + 2 * V3 + self.stage_vectors(q + h * v3, v + h * a3, f4))
        return q1, v1, h / 6.0 * (f1 + 2 * f2 + 2 * f3 + f4)

    def stage_vectors(self, q: np.ndarray, v: np.ndarray, forces: np.ndarray) -> np.ndarray | None:
        """On a curved heightfield, the contact ``forces`` ([normal, tangential] per contact) at (q, v)
        as world vectors (d x n_c) along that point's normals and tangents: a step's impulse is
        its stages' forces, each along its own directions, which turn under a contact sliding
        across a curved heightfield (random file 30649: along the end's alone, the step's
        momentum balance is first order in the step, and the balance split steps to h / 2^13);
        elsewhere (flat ground, a plane's terrain: :attr:`turning`) None."""
        if not self.turning:
            return None
        pt = self.point(q, v)
        return contact_vectors(pt.normal, pt.tangent, *_unstacked(forces, self.nc, self.dims - 1))

    # ---- events

    def witness(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> np.ndarray:
        """Values that stay >= 0 while the mode holds (scaled to tolerances of 1): open gaps,
        normal and cone margins of closed contacts, slip of sliding ones, joint-stop margins."""
        return self.witness_and_rate(q, v, mode)[0]

    def witness_and_rate(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`witness` and the time derivative of the geometric ones (gaps and stop margins;
        NaN for the force and slip witnesses)."""
        end = self.ended(q, v, mode)
        if end is None:
            fn, ft, stop_force = np.zeros(self.nc), np.zeros((self.nc, self.dims - 1)), np.zeros(self.nv)
            if _rests(mode):
                pt = self.point(q, v)
                rows, (_, lam) = self.mode_solution(pt, mode)
                fn, ft = _contact_forces(rows, lam, self.mu, self.nc)
                stop_force[rows.dof[rows.dof >= 0]] = lam[: rows.n][rows.dof >= 0]
                gap, vn, moving = pt.gap, pt.vn(v), pt.slip
                if rows.cornered is not None:  # a corner holds while both its rows push
                    fn = np.where(mode.cornered, _corner_forces(rows, lam, self.nc), fn)
            else:  # no rows: the gaps and normal speeds alone (the forces and slips go unwatched)
                gap, vn = self.gaps_and_speeds(q, v)
                moving = np.zeros((self.nc, self.dims - 1))
        else:
            fn, ft, stop_force, gap, vn, moving = end.fn, end.ft, end.stop_force, end.gap, end.vn, end.slip
        if ft.shape[1] == 1:  # the plane: |ft| and s . d of one tangent
            cone, slip = self.mu * fn - np.abs(ft[:, 0]), mode.slip[:, 0] * moving[:, 0]
        else:
            cone, slip = self.mu * fn - np.linalg.norm(ft, axis=1), np.sum(mode.slip * moving, axis=1)
        lo, hi = self.joints.lo, self.joints.hi
        values = np.concatenate([gap, fn, cone, slip, q - lo, hi - q, stop_force]) / self.witness_scale + 1.0
        values[self.unwatched(mode)] = np.inf
        rates = np.concatenate([vn, self.unknown_rates[0], v, -v, self.unknown_rates[1]]) / self.settings.gap_tolerance
        return values, rates

    def gaps_and_speeds(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The gaps and normal contact speeds at (q, v): the point's ``gap`` and ``vn(v)`` to the
        bit (the same normal components of the same Jacobian rows, in the same memory order),
        from the kept point if it is at (q, v), else without the rest of a point (a flight's
        witnesses at the start of a located step need no more)."""
        last = self._last
        if last is not None and last[0] == (q.tobytes(), v.tobytes()):
            return last[1].gap, last[1].vn(v)
        self.call.call(q, v)
        o, f = self.call.out, self.call.flat
        Jn = _along(o[1].T.copy(), o[2].reshape(self.nc, self.dims, self.nv))
        return f[0].copy(), Jn @ v

    def unwatched(self, mode: _Mode) -> np.ndarray:
        """Per witness of :meth:`witness_and_rate`, whether the mode leaves it unwatched (inf):
        gaps of closed contacts, forces of open ones, cone margins but of sticking contacts, slip
        but of sliding ones, stop margins of joints on a stop, stop forces of free joints."""
        # the corners always in the key, as in _mode_bytes (all -1 in a corner-free mode)
        key = b"".join((mode.closed.tobytes(), (mode.slip != 0).tobytes(), mode.stop.tobytes(), mode.corner.tobytes()))
        mask = self._unwatched.get(key)
        if mask is None:
            closed, friction, free = mode.closed, self.mu > 0, mode.stop == 0
            sticking, sliding = closed & ~mode.sliding & friction, closed & mode.sliding & friction
            sticking &= ~mode.cornered  # a corner's frictionless rows: no cone (its force witness is its rows')
            mask = np.concatenate([closed, ~closed, ~sticking, ~sliding, ~free, ~free, free])
            self._unwatched = self._unwatched if len(self._unwatched) < 256 else {}
            self._unwatched[key] = mask
        return mask

    def grazing(self, q0: np.ndarray, v0: np.ndarray, q1: np.ndarray, v1: np.ndarray, mode: _Mode, h: float) -> float | None:
        """The step fraction where an open contact's gap dips below the ground and comes back, or
        a free joint passes its stop and comes back (a stiff spring turns it within one step),
        on cubic Hermite fits over the step; or None."""
        end = self.ended(q1, v1, mode)
        if end is not None:  # the step's own ends
            g0, d0, g1, d1 = end.gap0, end.vn0 * h, end.gap, end.vn * h
        else:
            p0 = self.point(q0, v0)
            g0, d0 = p0.gap, p0.vn(v0) * h
            p1 = self.point(q1, v1)
            g1, d1 = p1.gap, p1.vn(v1) * h
        s, (h00, h10, h01, h11) = _GRAZE_SAMPLES, _GRAZE_BASIS
        g = h00 * g0 + h10 * d0 + h01 * g1 + h11 * d1
        tol = self.settings.gap_tolerance
        dips = (g < -tol) & ~mode.closed
        if _any(self.joints.stopped):
            x = h00 * q0 + h10 * v0 * h + h01 * q1 + h11 * v1 * h
            lo, hi = self.graze_bounds
            past = ((x > hi) | (x < lo)) & (mode.stop == 0)
            dips = np.concatenate([dips, past], axis=1)  # np.hstack's concatenation of 2-D arrays
        if not _any(dips):
            return None
        return float(s[np.argmax(dips.any(axis=1)), 0])

    @property
    def graze_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The stops widened by the gap tolerance, (lo - tol, hi + tol), that :meth:`grazing` asks of
        every step: kept for the joint arrays and tolerance they were made of (both fixed for a landing)."""
        joints, tol = self.joints, self.settings.gap_tolerance
        kept = self.__dict__.get("_graze_bounds")
        if kept is None or kept[0] is not joints or kept[1] != tol:
            kept = self._graze_bounds = (joints, tol, (joints.lo - tol, joints.hi + tol))
        return kept[2]

    def pieces(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Per contact, the piece of the ground below it: in the plane, the number of breakpoints
        of its terrain at or left of its x (0: the left ray); in space, the heightfield's cell
        (the grid lines at or below its x, and its z, as one number; the flat ground beyond the
        grid counts as cells too)."""
        at = self.point(q, v).contacts
        if self.grid is None:
            return np.searchsorted(self.vertices, at[:, 0], side="right")
        x, z = self.grid
        return np.searchsorted(x, at[:, 0], side="right") * (len(z) + 1) + np.searchsorted(z, at[:, 2], side="right")

    def vertex_crossing(self, q: np.ndarray, v: np.ndarray, q1: np.ndarray, v1: np.ndarray, mode: _Mode, h: float
                        ) -> tuple[_Trial, np.ndarray, np.ndarray] | None:
        """Where a closed contact passes a breakpoint of the plane's terrain over the step (q, v)
        -> (q1, v1) of length ``h``: the step to just past it (bisected to rounding) and which
        closed contacts passed one; or None. Beyond a breakpoint the ground's normal is the next
        segment's: a contact sliding into a valley meets it moving into it (an impact), one
        sliding over a ridge leaves it. Unlocated, the projection onto the next segment took the
        valley's impact plastically whatever the restitution, and pulled the contact down onto
        the ridge's far side (a pulling impulse). A crossing that changes no normal speed by more
        than the plastic speed (1e-4 m/s) is left to the projection (a plastic change).

        A contact that passes a valley's breakpoint (:attr:`concave`) is located whatever its
        speed, and where its whole velocity there is below the plastic speed it comes to rest in
        the corner, held by both segments (the third item returned: per contact the breakpoint, or
        -1; :meth:`event`): the rocking across a valley's breakpoint at restitution 0 loses cos a
        of its speed per crossing (a the angle between the normals) and the crossings accumulate
        (Zeno), each step crossing it once its rocking is shorter than a step. That slow, the
        corner's projection takes the point's velocity to zero within the plastic speed, as a
        plastic impact takes an approach that slow (an event: the impact over both rows). A faster
        contact crosses as before, but as an event however slowly it approaches the far segment
        (plastic below the plastic speed; so a contact sliding through a shallow valley keeps its
        speed along the far segment, and every loss at a valley is an event's)."""
        # the normals at the step's ends (the last accepted step's end's for its start): unchanged,
        # no breakpoint passed (nor one between collinear segments, which changes nothing)
        end = self.ended(q1, v1, mode)
        n1 = end.normal if end is not None else self.point(q1, v1).normal
        n0, self.end_normals = self.end_normals, n1
        n0 = n0 if n0 is not None else self.point(q, v).normal
        if not _any(mode.closed & (np.maximum.reduce(np.abs(n1 - n0), axis=1) > 1e-12)):
            return None
        self.end_normals = None
        k0 = self.pieces(q, v)
        k1 = self.pieces(q1, v1)
        passing = mode.closed & ~mode.cornered & (k1 != k0)
        if not _any(passing):
            return None
        if self.grid is not None:  # space: no valley corners (a crease's crossing is an event alike)
            return self.crossing_event(q, v, h, mode, k0, passing)
        # a crossing too slow to locate (the contact's velocity at the step's start along the
        # next segment's normal within half the plastic speed): no bisection (the step's cost x 50)
        # unless it passes a valley's breakpoint, where it may come to rest in the corner
        pt, normal = self.point(q, v), self.point(q1, v1).normal
        velocity = pt.normal * pt.vn(v)[:, None] + pt.tangent[:, 0] * pt.vt(v)[:, 0][:, None]
        valley = passing & (np.abs(k1 - k0) == 1) & self.concave[np.minimum(k0, k1) % len(self.concave)]
        kept_end = self._end
        if not _any(passing & (np.abs(np.sum(normal * velocity, axis=1)) > 0.5 * PLASTIC_SPEED)) and not _any(valley):
            return None
        lo, hi, found, before = self.first_crossing(q, v, mode, h, k0)
        if before is not None:
            # the step to just before the breakpoint (its stages all on this side: a step past it
            # holds the contact to the next segment in its last stages), then on at that speed
            # (the plane's q' = v) over the bracket's rest, twice, to just past it
            nudged = replace(before, tau=lo + 2.0 * (hi - lo), q=before.q + 2.0 * (hi - lo) * before.v, end=None)
            if _any(mode.closed & (self.pieces(nudged.q, nudged.v) != k0)):
                found = nudged
            if _any(valley):
                # past a valley's breakpoint by more than the profile's coincidence radius (1e-12
                # m), where the normal is the far segment's: a leftward crossing located to
                # rounding stayed within it (the segment's parameter rounds to its end), and met
                # the mean of the two normals (its impact sent the puck of the valley file level
                # into the far slope, a loss at the next step's projection)
                k = np.minimum(k0, k1) % len(self.concave)
                far = np.where((k1 > k0)[:, None], self.valleys[k][:, 1], self.valleys[k][:, 0])
                reach = 2.0
                for _ in range(200):
                    if not _any(valley & (np.max(np.abs(self.point(found.q, found.v).normal - far), axis=1) > 1e-12)):
                        break
                    reach *= 2.0
                    if lo + reach * (hi - lo) > h:
                        break
                    found = replace(before, tau=lo + reach * (hi - lo), q=before.q + reach * (hi - lo) * before.v,
                                    end=None)
        crossed = mode.closed & ~mode.cornered & (self.pieces(found.q, found.v) != k0)
        pt = self.point(found.q, found.v)
        cornered = np.full(self.nc, -1)
        if _any(valley):
            speed = np.hypot(pt.vn(found.v), pt.vt(found.v)[:, 0])  # the contact point's whole velocity
            resting = crossed & valley & (speed <= PLASTIC_SPEED)
            cornered[resting] = np.minimum(k0, k1)[resting]
            crossed &= ~resting
        crossed &= (np.abs(pt.vn(found.v)) > PLASTIC_SPEED) | valley  # a valley's: an event, plastic that slow
        if _any(crossed) or _any(cornered >= 0):
            return found, crossed, cornered
        self._end = kept_end  # as unlocated: the step's end (q1, v1) is the compiled step's again
        return None

    def first_crossing(self, q: np.ndarray, v: np.ndarray, mode: _Mode, h: float, k0: np.ndarray
                       ) -> tuple[float, float, _Trial, _Trial | None]:
        """Where a closed contact first leaves its piece of the ground (``k0``, :meth:`pieces`)
        over a step of length ``h`` from (q, v), bisected to rounding: the step lengths (lo, hi)
        that bracket it, the step to hi (just past it) and the step to lo (None where lo is 0)."""
        lo, hi, found, before = 0.0, h, None, None
        for _ in range(200):
            if hi - lo <= 1e-15 * max(1.0, hi):
                break
            mid = 0.5 * (lo + hi)
            trial = self.trial(q, v, mode, mid)
            if _any(mode.closed & (self.pieces(trial.q, trial.v) != k0)):
                hi, found = mid, trial
            else:
                lo, before = mid, trial
        found = found if found is not None else self.trial(q, v, mode, hi)
        return lo, hi, found, before

    def crossing_event(self, q: np.ndarray, v: np.ndarray, h: float, mode: _Mode, k0: np.ndarray,
                       passing: np.ndarray) -> tuple[_Trial, np.ndarray, np.ndarray] | None:
        """Space: where closed contacts (``passing``) leave their heightfield cells (``k0``) over a
        step of length ``h``: the step to the first such crossing (bisected to rounding; its end
        just past the grid line) and which closed contacts crossed, each meeting the next cell's
        surface afresh (:meth:`event`: an impact where it moves into it, a crease's valley, free
        where it leaves it); None where no crossing changes a normal speed by more than the
        plastic speed, which the projection takes (random file 30882: a contact sliding at 1.1
        m/s onto a 32 degree slope met it at 0.6 m/s in a step's projection, 0.38 N s along the
        normal alone, plastic and frictionless whatever the laws, and its momentum balance 1.9e-4)."""
        kept_end = self._end
        found = self.first_crossing(q, v, mode, h, k0)[2]
        crossed = mode.closed & ~mode.cornered & (self.pieces(found.q, found.v) != k0)
        crossed &= np.abs(self.point(found.q, found.v).vn(found.v)) > PLASTIC_SPEED
        if _any(crossed):
            return found, crossed, np.full(self.nc, -1)
        self._end = kept_end  # as unlocated: the step's end is the compiled step's again
        return None

    def trial(self, q: np.ndarray, v: np.ndarray, mode: _Mode, tau: float) -> _Trial:
        """A step of length ``tau`` from (q, v) in ``mode`` and its end's witnesses and rates.
        A trial's length is where it looks, so it is not halved as :meth:`balanced_step` halves a
        step: Radau IIA's pieces are split down to RK4's stable step (random file 60779: its trial
        at 0.98 ms stayed NaN after RADAU_SPLITS); a trial that blows up otherwise is the run's
        divergence (:class:`Diverged`, which :func:`landing` shortens), not its witnesses' failure."""
        q1, v1, impulse = self.step(q, v, mode, tau)
        if self.method == RADAU and not (_finite(q1) and _finite(v1)):
            q1, v1, impulse = self.radau_step(q, v, mode, tau, splits=TRIAL_SPLITS)
        if not (_finite(q1) and _finite(v1)):
            raise Diverged(f"the landing diverged locating an event (a trial step of {tau:.3g} s)")
        w, r = self.witness_and_rate(q1, v1, mode)
        return _Trial(tau, q1, v1, impulse, self._end, w, r, self.vectors)

    def take(self, q: np.ndarray, v: np.ndarray, mode: _Mode, trial: _Trial
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``trial``'s step taken again without its cost: what :meth:`step` of its length would
        return and leave behind (the mode's steering, the compiled step's end for :meth:`ended`)."""
        self.steer(q, v, mode, trial.tau)
        self._end, self.vectors = trial.end, trial.vectors
        return trial.q.copy(), trial.v.copy(), trial.impulse.copy()

    def locate(self, q: np.ndarray, v: np.ndarray, mode: _Mode, first: _Trial, watch: np.ndarray) -> _Trial:
        """The first step length in (0, ``first.tau``] at which a watched witness crosses its
        threshold, and that step (``first``: the step at the bracket's end, already taken).

        Witnesses are triggered at -1 (one tolerance below zero) but located within a window
        ``[-2 d, -d]`` tolerances (or as far below their start's value): d = ``LOCATE_DEPTH`` for
        gaps and stop margins, ``FORCE_DEPTH`` for forces, cone margins and slips. A contact is
        thus met within 0.02 gap tolerances of the ground: each bounce is located that close to
        where the last one left (the projection lifts a bounced contact to zero gap), so the
        drive a pushing it down gains at most a 2 d tol per bounce, far below restitution's loss
        unless the bounce is slower than sqrt(4 a d tol / (1 - e^2)) (the plastic speed, 1e-4 m/s,
        at a = 9e4 m/s^2, e = 0.8). The next guess is the first root, aimed at the window's
        middle, of the cubic Hermite fit of the crossing witness over the bracket where its rate
        is known (gaps and stop margins: the contact's or joint's speed), else the Illinois
        method; a bisection where the bracket stopped halving (rounding's plateau)."""
        w0, r0 = self.witness_and_rate(q, v, mode)
        start = w0[watch] - 1.0
        offset = location_offsets(start, np.isfinite(r0[watch]))
        aim = 0.5 * offset  # the window's middle: rounding either way stays inside

        def phi(trial: _Trial) -> tuple[np.ndarray, np.ndarray]:
            return trial.w[watch] - 1.0 + offset, trial.r[watch]

        lo, hi, (w_lo, r_lo), found = 0.0, first.tau, (start + offset, r0[watch]), first
        w_hi, r_hi = phi(first)
        f_lo, f_hi, side, slow = float(w_lo.min()), float(w_hi.min()), 0, 0
        for _ in range(100):
            if hi - lo <= 1e-14 * max(1.0, hi) or (w_hi >= -offset).all():  # inside the window
                break
            i, width = int(w_hi.argmin()), hi - lo
            mid = lo + width * self.root(w_lo[i] + aim[i], r_lo[i] * width, w_hi[i] + aim[i], r_hi[i] * width)
            if slow >= 2:  # two steps without halving the bracket
                mid, slow = 0.5 * (lo + hi), 0
            elif not lo < mid < hi:  # Illinois
                mid = (lo * f_hi - hi * f_lo) / (f_hi - f_lo) if f_lo != f_hi else 0.5 * (lo + hi)
                if not lo < mid < hi:
                    mid = 0.5 * (lo + hi)
            trial = self.trial(q, v, mode, mid)
            w_mid, r_mid = phi(trial)
            f_mid = float(w_mid.min())
            if f_mid < 0:
                hi, w_hi, r_hi, f_hi, found = mid, w_mid, r_mid, f_mid, trial
                f_lo = f_lo / 2 if side == -1 else f_lo
                side = -1
            else:
                lo, w_lo, r_lo, f_lo = mid, w_mid, r_mid, f_mid
                f_hi = f_hi / 2 if side == 1 else f_hi
                side = 1
            slow = slow + 1 if hi - lo > 0.5 * width else 0
        return found

    def impact(
        self, q: np.ndarray, v: np.ndarray, mode: _Mode, t: float, contacts: np.ndarray, kind: str
    ) -> tuple[np.ndarray, LandingEvent, _Mode]:
        """The rigid impact at (q, v) over ``contacts`` and every joint on or past a stop: the
        velocities after, the event, and which rows rest afterwards."""
        pt = self.point(q, v)
        stops = self.stops_touching(q, mode)
        plain, corners = self.corner_split(mode, contacts)
        rows = _rows(pt, plain, self.no_slip(), stops, self.mu, self.nv, corners=corners)
        n, on_contact, on_stop = rows.n, rows.contact >= 0, rows.dof >= 0
        u = rows.G @ v
        approach = -u[:n]
        e = np.where(on_contact, self.e, self.joints.restitution[np.maximum(rows.dof, 0)])
        e = np.where(approach > PLASTIC_SPEED, e, 0.0)
        plastic = (approach <= PLASTIC_SPEED) | (self.bounce_time(pt, rows, e * approach) < self.min_bounce)
        e = np.where(plastic, 0.0, e)
        law = rigid_impact(pt, v, rows, e, self.mu, self.lemke)
        self.last_impact = law
        if self.impact_log is not None:
            self.impact_log.append((q.copy(), v.copy(), np.array(contacts), pt, law))
        self.inexact += not law.exact
        self.non_unique += not law.split_unique
        sol, v_plus, fn, ft = law.solution, law.v_plus, law.normal, law.tangential
        if self.tape is not None:
            self.tape.append(("impact", q.copy(), v.copy(), rows, e.copy(), sol, plastic))
        F = contact_impulses(pt, fn, ft)
        joint = self.point(q, v_plus).momentum - pt.momentum - F @ self.in_subtree.T
        internal, magnitude = joint_impulses(joint)
        stop = np.zeros(self.nv)
        stop_dofs = rows.dof[on_stop]
        stop[stop_dofs] = (-stops[stop_dofs]) * sol.normal[on_stop]
        # resting afterwards: no bounce, or a plastic row left slower than the plastic speed (it
        # rests unless the forces pull it away; the velocity projection takes the rest)
        leaving = sol.velocity[:n]
        after = (leaving <= self.speed_tol) | ((e == 0) & (leaving < PLASTIC_SPEED))
        # a contact above the ground (``contacts: all`` makes every one hit at t = 0) stays open
        on_ground = pt.gap[np.maximum(rows.contact, 0)] <= self.scene.contact_tolerance + self.settings.gap_tolerance
        new = mode.copy()
        new.closed[:] = False
        new.closed[rows.contact[on_contact & after & on_ground]] = True
        if corners is not None:  # a corner rests on where both its rows do; else it opens (touching again)
            self.keep_corners(new, mode, rows, (on_contact & after & on_ground)[:n])
        new.stop[:] = 0
        at = rows.dof[on_stop & after]
        new.stop[at] = stops[at]
        event = LandingEvent(
            time=t, kind=kind, external=fn, tangential=self.public_tangential(ft), internal=internal[:, : self.dims],
            internal_magnitude=magnitude, stop=self.per_joint(stop), v_minus=world_velocity(q, v, self.space),
            v_plus=world_velocity(q, v_plus, self.space),
            energy_before=float(v @ pt.M @ v) / 2, energy_after=float(v_plus @ pt.M @ v_plus) / 2,
        )
        return v_plus, event, new

    def corner_split(self, mode: _Mode, contacts: np.ndarray
                     ) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray] | None]:
        """``contacts`` split into those with one row each and ``mode``'s resting in a corner,
        with their segments' normals (:func:`_rows`' ``corners``; None: none)."""
        if not mode.has_corner:
            return contacts, None
        held = mode.cornered[contacts] & mode.closed[contacts]
        cornered = contacts[held]
        return contacts[~held], (cornered, self.valleys[mode.corner[cornered]])

    def keep_corners(self, new: _Mode, mode: _Mode, rows: _Rows, rest: np.ndarray) -> None:
        """In ``new`` (closed where some row of the contact rests): each of ``mode``'s corner
        contacts in ``rows`` stays in its corner where both its rows rest (``rest``, per normal
        row), else opens: released from one segment it touches the other again (an event, plastic
        that slow) along that segment's own normal, which a point exactly at the breakpoint would
        not have (its normal is the mean of the two)."""
        both = np.zeros(self.nc, int)
        np.add.at(both, rows.contact[: rows.n][rows.cornered], rest[rows.cornered].astype(int))
        cornered = np.unique(rows.contact[: rows.n][rows.cornered])
        kept = both[cornered] == 2
        new.closed[cornered] = kept
        new.corner[:] = -1
        new.corner[cornered[kept]] = mode.corner[cornered[kept]]
        new.slip[cornered] = 0.0

    def pressing(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> np.ndarray:
        """Per contact: closed in ``mode`` and pushed by its force at (q, v) beyond the force
        tolerance (a contact resting unloaded is not)."""
        pt = self.point(q, v)
        if not _any(mode.closed):
            return np.zeros(self.nc, bool)
        rows, (_, lam) = self.mode_solution(pt, mode)
        return mode.closed & (_contact_forces(rows, lam, self.mu, self.nc)[0] > self.force_tol)

    @staticmethod
    def rests_nowhere(contacts: np.ndarray, stops: np.ndarray) -> bool:
        """No contact near the ground at rest and no joint on a stop: :meth:`resolve`'s LCP would
        have no rows and leave every contact open and every joint free (:meth:`flight`)."""
        return not contacts.size and not _any(stops)

    def flight(self) -> _Mode:
        """The mode without rows: every contact open, every joint free."""
        return _Mode(np.zeros(self.nc, bool), self.no_slip(), np.zeros(self.nv, int))

    def no_slip(self) -> np.ndarray:
        """A mode's ``slip`` with every contact sticking (n_c x (d - 1))."""
        return np.zeros((self.nc, self.dims - 1))

    def public_tangential(self, ft: np.ndarray) -> np.ndarray:
        """Tangential impulses per contact as reported: along +x in the plane (n_c), [t_x, t_z] in
        space (n_c x 2)."""
        return ft[:, 0].copy() if self.dims == 2 else ft.copy()

    def bounce_time(self, pt: _Point, rows: _Rows, rebound: np.ndarray) -> np.ndarray:
        """Per normal row: how long a rebound at speed ``rebound`` would last before the row's
        free acceleration (springs, gravity, spin) brings it back (inf where it pulls away)."""
        free = rows.G[: rows.n] @ np.linalg.solve(pt.M, pt.f) + rows.b[: rows.n]
        time, back = np.full(rows.n, np.inf), free < 0
        time[back] = 2.0 * rebound[back] / -free[back]
        return time

    def stops_touching(self, q: np.ndarray, mode: _Mode) -> np.ndarray:
        """Per DOF: the stop it rests on or has reached (-1 lower, +1 upper), else 0."""
        lo, hi = self.stop_reach
        at = np.where(q <= lo, -1, np.where(q >= hi, 1, 0))
        return np.where(mode.stop != 0, mode.stop, at)

    @functools.cached_property
    def stop_reach(self) -> tuple[np.ndarray, np.ndarray]:
        """Where a joint reaches its stops (:meth:`stops_touching`): within the gap tolerance."""
        tol = self.settings.gap_tolerance
        return self.joints.lo + tol, self.joints.hi - tol

    def per_joint(self, per_dof: np.ndarray) -> np.ndarray:
        """A per-DOF quantity as one entry per non-base body (0 for fixed joints)."""
        jointed, dofs = self.joint_dofs
        out = np.zeros(len(jointed))
        out[jointed] = per_dof[dofs]
        return out

    @functools.cached_property
    def joint_dofs(self) -> tuple[np.ndarray, np.ndarray]:
        """Per non-base body whether it has a DOF, and those DOFs (:meth:`per_joint`)."""
        body_dof = self.layout.body_dof[1:]
        return np.array([k is not None for k in body_dof], bool), np.array([k for k in body_dof if k is not None], int)

    def resolve(self, q: np.ndarray, v: np.ndarray, mode: _Mode, t: float = 0.0) -> _Mode:
        """Which resting rows stay closed, stick or slide: ``mode`` itself where it holds with a
        margin (:meth:`persists`), else the contact LCP at the acceleration level (e = 0; a
        contact already sliding keeps its direction). ``t``: the time, for the error where no
        contact force exists (Painleve's paradox)."""
        if self.persists(q, v, mode):
            return mode
        pt = self.point(q, v)
        vn = pt.vn(v)
        near = mode.closed | ((pt.gap <= self.settings.gap_tolerance) & (np.abs(vn) <= self.speed_tol))
        contacts = np.flatnonzero(near)
        stops = self.stops_touching(q, mode)
        stops = np.where((mode.stop != 0) | (np.abs(v) <= self.speed_tol), stops, 0)
        if self.rests_nowhere(contacts, stops):  # the LCP would have no rows
            return self.flight()
        slip = _unit(pt.slip, self.speed_tol) if self.mu > 0 else self.no_slip()
        plain, corners = self.corner_split(mode, contacts)
        if corners is not None:
            slip[corners[0]] = 0.0
        for attempt in range(2):
            rows = _rows(pt, plain, slip, stops, self.mu, self.nv, corners=corners)
            minv = np.linalg.solve(pt.M, np.column_stack([pt.f, rows.F.T]))
            u = rows.G @ minv[:, 0] + rows.b
            try:
                sol, acceleration, exact = _solve_rows(rows.G @ minv[:, 1:], u, rows, np.zeros(rows.n), self.lemke)
                self.inexact += not exact
                break
            except NumericalError:
                if attempt or not slip[contacts].any():
                    raise PainleveParadox(self.painleve_message(
                        t, contacts, f"the contact problem has no solution with friction {self.mu:g}")) from None
                slip = self.no_slip()  # let the sliding contacts stick or slide afresh
        acc_tol = 1e-9 * max(1.0, float(np.max(np.abs(u), initial=0.0)))
        rest = sol.normal > self.force_tol  # an unloaded row opens (if it sinks, it touches again)
        rest |= self.held(pt, mode, rows, sol, acc_tol)
        new = self.flight()
        c = rows.contact >= 0
        new.closed[rows.contact[c & rest]] = True
        new.slip[:] = np.where(new.closed[:, None], slip, 0)
        if corners is not None:  # a corner rests on where both its rows do, else it opens
            self.keep_corners(new, mode, rows, rest[: rows.n])
        k = rows.contact[rows.owner]
        starting = (sol.slip > acc_tol) & new.closed[k]
        new.slip[k[starting]] = _unit(acceleration[starting], 0.0)
        d = rows.dof >= 0
        new.stop[rows.dof[d & rest]] = stops[rows.dof[d & rest]]
        new.redundant = self.redundant(pt, new)
        checked = self.consistent_slip(pt, v, self.unify(pt, v, self.slide_on_the_edge(q, v, new)), acc_tol)
        if checked is not new:  # the checks changed the mode (they return it unchanged otherwise)
            checked.redundant = self.redundant(pt, checked)
        return self.stick_where_it_can(q, v, checked)

    def stick_where_it_can(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> _Mode:
        """``mode`` with its contacts that start to slide from rest (|v_t| within the speed
        tolerance) sticking instead, where that mode holds with its own forces: every force
        witness (normal forces, cone margins, stop forces) at least one tolerance inside, as
        :meth:`persists` asks. Pfeiffer and Glocker's transition rule: a resting contact slides
        only when its friction force reaches the cone. The contact problem at the acceleration
        level can have both answers (redundant rows: several contacts on one rigid body; large
        friction), and Lemke's pivots may pick the sliding one, whose least-norm forces in the
        mode's own solve then disagree with the LCP's: the run switched slip directions at every
        event, 4000 events in 90 s at 6e-11 s each (random file 20606). Where the answer is unique
        it is the sticking one whenever this mode holds, so nothing else changes."""
        if self.mu <= 0:
            return mode
        starting = mode.closed & mode.sliding & (np.linalg.norm(self.point(q, v).vt(v), axis=1) <= self.speed_tol)
        if not _any(starting):
            return mode
        probe = mode.copy()
        probe.slip[starting] = 0.0
        probe.redundant = self.redundant(self.point(q, v), probe)
        return probe if self.held_by_its_forces(q, v, probe) else mode

    def held_by_its_forces(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> bool:
        """Whether ``mode`` holds at (q, v) with its own forces: every force witness (normal
        forces, cone margins, stop forces) at least one tolerance inside, as :meth:`persists`
        asks: its contacts push and those sticking have their friction inside the cone."""
        w, _ = self.witness_and_rate(q, v, mode)
        nc, nv = self.nc, self.nv
        forces = np.concatenate([w[nc : 3 * nc], w[4 * nc + 2 * nv :]])  # normal forces, cone margins, stop forces
        return bool((forces >= 2.0).all())

    def arrest(self, q: np.ndarray, v: np.ndarray, mode: _Mode, totals: _Totals) -> tuple[np.ndarray, np.ndarray]:
        """(q, v) with the slip of each closed contact whose slip has turned to or past a right
        angle from the direction it slid along (the slip-reversal witness s . d <= 0) at a slip
        speed below :data:`PLASTIC_SPEED` taken to zero, as a plastic impact takes an approach
        that slow: the mode's projection with those contacts sticking (its impulse counted in
        the totals), where that mode holds with its own forces (:meth:`held_by_its_forces`, the
        transition rule :meth:`stick_where_it_can` applies); else the same with each of them
        alone; where none holds, the same projection when it is slight (:meth:`slight_arrest`),
        else nothing changes (the contact LCP slides them on). The
        contact LCP then sticks them or starts them sliding from rest. In the plane a reversal
        is located at s = 0 and nothing changes; in space a slow slip under a lateral drive
        turns rather than stops (the regularised direction lags it: the lateral slip settles at
        the drive times the step), and each right angle was an event: random file 20693 slid at
        1e-5 m/s with an event every 1e-5 s, and a contact the LCP started sliding along its old
        direction kept its turned slip and reversed again at once. Where friction cannot hold
        the arrested contacts, the projection's impulse is no friction's: two resting contacts
        of a nearly redundant pair (random file 31088: the roots of hinged rods 9.4 cm apart,
        the sticking rows' G M^-1 G^T of condition 1e7) took the pair's squeeze, 595 N s
        tangential on a contact with 1.8 N s of normal impulse (the mode with both sticking
        needs 5e5 N of friction there), pulling in later arrests: the momentum balance cannot
        see it (it sums to zero), but the totals carried it. The mode probed and projected onto
        slides the contacts it calls sticking that slip at least at PLASTIC_SPEED
        (:meth:`as_it_slides`). Its normal impulses may pull a little: zeroing a slip at a closed
        contact whose normal velocity stays zero takes the Delassus matrix's normal-tangent
        coupling (random file 31088: a lone contact's slip of 6.7e-5 m/s, rows of condition 3.9,
        2.6e-4 N s tangential and -1.5e-4 N s normal). Released, that row would leave at 3.9e-5
        m/s, slower than PLASTIC_SPEED, which the projection after the contact LCP would take
        back with a pull of its own (a plastic contact that slow rests); against the mode's force
        (39 N) it is that force over 4e-6 s of the friction the arrest stands for."""
        self.refused = np.zeros(0, int)  # the turned contacts it leaves sliding (a stall, REPEATS, where that repeats)
        if self.dims == 2 or self.mu <= 0 or not _any(mode.closed & mode.sliding):
            return q, v
        slip = self.point(q, v).slip
        turned = (mode.closed & mode.sliding & (np.sum(slip * mode.slip, axis=1) <= 0)
                  & (np.linalg.norm(slip, axis=1) < PLASTIC_SPEED))
        if not _any(turned):
            return q, v
        sliding = self.as_it_slides(slip, mode)
        stuck = self.held_arrest(q, v, sliding, turned)
        taken = self.project(q, v, stuck) if stuck is not None else self.slight_arrest(q, v, sliding, turned)
        if taken is None:
            self.refused = np.flatnonzero(turned)
            return q, v
        q1, v1, p = taken
        self.add(totals, p, *self.projected_at)
        self.tally_joints(totals, q, v, q1, v1, p, 0.0, True)
        return q1, v1

    def slight_arrest(self, q: np.ndarray, v: np.ndarray, mode: _Mode, turned: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """Where no mode with the ``turned`` contacts sticking holds (:meth:`held_arrest`): the
        projection that stops their slips all the same, when its rows are well conditioned (not
        :data:`REDUNDANT`) and it moves each contact by less than :data:`PLASTIC_SPEED` times
        the tree's mass of impulse, as a plastic impact takes an approach that slow; else None.
        The contact LCP after it starts them sliding from rest along a slip their acceleration
        follows (:meth:`consistent_slip`). Left sliding, such a slip turns by a right angle at
        each event: random file 32113's lone tip contact slid at 1e-6 m/s, its acceleration
        square to its slip either way it was flagged, an event every 1e-8 s (a stall)."""
        stuck = mode.copy()
        stuck.slip[turned] = 0.0
        stuck.redundant = self.redundant(self.point(q, v), stuck)
        if stuck.redundant:
            return None
        q1, v1, p = self.project(q, v, stuck)
        fn, ft = _unstacked(p, self.nc, self.dims - 1)
        if float(np.max(np.hypot(fn, np.linalg.norm(ft, axis=1)))) > PLASTIC_SPEED * self.mass:
            return None
        return q1, v1, p

    def as_it_slides(self, slip: np.ndarray, mode: _Mode) -> _Mode:
        """``mode`` with each closed contact it calls sticking whose slip ``slip`` (per contact)
        is at least :data:`PLASTIC_SPEED` sliding along that slip instead: the mode an arrest
        probes and projects onto (:meth:`arrest`). An impact keeps the slip flags of the mode
        before it (:meth:`impact`), and the contact LCP that follows the arrest
        (:meth:`modes_after`) starts such a contact sliding; a projection sticking it would take
        its slip to zero by an impulse that is no arrest (random file 31088 before the squeeze
        fix: 0.012 N s at two contacts slipping at 1.2e-2 m/s after 46 impacts at one instant),
        since an arrest stops only slips slower than the plastic speed. A slower one the mode
        calls sticking stays sticking: its slip stops with the turned ones, as a plastic impact
        takes an approach that slow."""
        fast = mode.closed & ~mode.sliding & (np.linalg.norm(slip, axis=1) >= PLASTIC_SPEED)
        if not _any(fast):
            return mode
        sliding = mode.copy()
        sliding.slip[fast] = _unit(slip[fast], 0.0)
        return sliding

    def held_arrest(self, q: np.ndarray, v: np.ndarray, mode: _Mode, turned: np.ndarray) -> _Mode | None:
        """``mode`` with the ``turned`` contacts sticking where that holds with its own forces
        (:meth:`held_by_its_forces`), else with the first of them alone whose sticking does, or
        None (:meth:`arrest`)."""
        pt = self.point(q, v)
        k = np.flatnonzero(turned)
        for each in [k] + ([k[i : i + 1] for i in range(len(k))] if len(k) > 1 else []):
            stuck = mode.copy()
            stuck.slip[each] = 0.0
            stuck.redundant = self.redundant(pt, stuck)
            if self.held_by_its_forces(q, v, stuck):
                return stuck
        return None

    def held(self, pt: _Point, mode: _Mode, rows: _Rows, sol: UnilateralSolution, acc_tol: float) -> np.ndarray:
        """Per normal row of ``rows``: a closed contact that the acceleration-level LCP ``sol``
        leaves unloaded (force within the force tolerance) and not accelerating away (within
        ``acc_tol``), while the mode's own force on it does not pull (above -:data:`HOLD_FORCE`
        force tolerances). Both answers then meet the law, and the contact rests on, as a
        plastic touchdown leaves it: opened, it would touch down again at the closed rows' drift
        (one gap tolerance), microseconds later, with an impulse of rounding (a rod's tip resting
        on the point where the next rod's root rests, the LCP loading either one: f25's 685
        touchdowns in 0.05 s). When its force pulls, its witness opens it (located below -0.1
        tolerances, below the hold), so an unloading contact is never held at its own event."""
        c = rows.contact >= 0
        candidates = c & (sol.normal[: rows.n] <= self.force_tol) & (sol.velocity[: rows.n] <= acc_tol)
        candidates &= mode.closed[np.maximum(rows.contact, 0)]
        if not candidates.any():
            return np.zeros(rows.n, bool)
        probe = mode.copy()
        probe.redundant = self.redundant(pt, probe)
        mode_rows, (_, lam) = self.mode_solution(pt, probe)
        fn = _contact_forces(mode_rows, lam, self.mu, self.nc)[0]
        force = fn[np.maximum(rows.contact, 0)]
        if rows.cornered is not None and mode_rows.cornered is not None:  # a corner's rows: each its own
            own = _corner_row_forces(mode_rows, lam, self.nc)
            k = np.flatnonzero(rows.cornered)
            force[k] = own[rows.contact[k], _corner_side(rows)[k]]
        return candidates & (force >= -HOLD_FORCE * self.force_tol)

    def persists(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> bool:
        """Whether ``mode`` (after an impact: the rows it left resting, the contacts' slip as
        before) holds at (q, v) with a margin: its rows not redundant, its closed rows at rest
        (slower than the plastic speed, sticking contacts in every direction), every force and slip witness at least one
        tolerance inside (:meth:`witness_and_rate`), no gap or stop margin negative. Mode
        persistence: where the contact problem has several answers (toes that can stick with a
        joint held on its stop, or slide with the stop opening), the run keeps the one it is in;
        Lemke's method may pick the other at each event, and the run would switch between them
        every fraction of a microsecond (a study's design did, 2e5 times)."""
        if not _rests(mode):  # no rows to hold
            return False
        pt = self.point(q, v)
        closed_stop = mode.stop != 0
        sticking = mode.closed & ~mode.sliding
        at_rest = ((np.abs(pt.vn(v)[mode.closed]) < PLASTIC_SPEED).all()  # as an impact leaves them: the
                   and (np.abs(pt.vt(v)[sticking]) < PLASTIC_SPEED).all()  # projection takes the rest
                   and (np.abs(v[closed_stop]) < PLASTIC_SPEED).all())
        if not at_rest or self.redundant(pt, mode):
            return False
        w, _ = self.witness_and_rate(q, v, mode)
        nc, nv = self.nc, self.nv
        geometric = np.concatenate([w[:nc], w[4 * nc : 4 * nc + 2 * nv]])
        forces = np.concatenate([w[nc : 4 * nc], w[4 * nc + 2 * nv :]])
        return bool((geometric >= 1.0).all() and (forces >= 2.0).all())

    def unify(self, pt: _Point, v: np.ndarray, mode: _Mode) -> _Mode:
        """Resting contacts at one point moving alike (identical toes: their tips coincide to
        rounding) take one slip: the sliding one's where one slides and another sticks. The
        contact problem at such a point has many answers, and Lemke's method may stick one toe
        on the cone's edge while the other slides at zero slip acceleration; the identical toes'
        symmetric answer is both sliding (the same forces), and the asymmetric one stalled the
        run (the sticking toe leaves the cone at once)."""
        if self.mu <= 0:
            return mode
        closed = np.flatnonzero(mode.closed)
        vt = pt.vt(v)
        out = mode
        for a, i in enumerate(closed):
            for j in closed[a + 1 :]:
                if (out.sliding[i] != out.sliding[j] and not (mode.cornered[i] or mode.cornered[j])
                        and np.max(np.abs(pt.contacts[i] - pt.contacts[j])) <= COINCIDENT
                        and np.linalg.norm(vt[i] - vt[j]) <= self.speed_tol):
                    out = out.copy() if out is mode else out
                    out.slip[i] = out.slip[j] = out.slip[i] if out.sliding[i] else out.slip[j]
        return out

    def redundant(self, pt: _Point, mode: _Mode) -> bool:
        """Whether the mode's rows are redundant (:data:`REDUNDANT`): identical toes resting on
        one point, two sticking contacts of one rod."""
        rows = self.mode_solution(pt, mode, solve=False)[0]
        if rows.G.shape[0] < 2:
            return False
        s = np.linalg.svd(rows.G @ np.linalg.solve(pt.M, rows.F.T), compute_uv=False)
        return bool(s[-1] < REDUNDANT * s[0])

    def consistent_slip(self, pt: _Point, v: np.ndarray, mode: _Mode, acc_tol: float) -> _Mode:
        """A contact that starts sliding (|v_t| within the speed tolerance) must accelerate along
        its slip in the mode's own dynamics; where the LCP's answer is not unique (two identical
        toes on one point share a normal force in any split, and Lemke's pivots may start them
        sliding opposite ways), the mode's forces can make it accelerate against it, and the run
        would switch between mirror modes without end at one instant. Each such contact takes the
        slip of its acceleration in the mode (or sticks when that is below the tolerance), until
        the mode agrees with itself (at most one pass per contact); a mode still at odds with
        itself then has its slips searched (:meth:`searched_slip`)."""
        if self.mu <= 0:
            return mode
        for _ in range(self.nc):
            wrong, at = self.wrong_slip(pt, v, mode, acc_tol)
            if not wrong.any():
                return mode
            mode = mode.copy()
            mode.redundant = False
            mode.slip[wrong] = _unit(at[wrong], acc_tol)
        wrong, _ = self.wrong_slip(pt, v, mode, acc_tol)
        return self.searched_slip(pt, v, mode, wrong, acc_tol) if wrong.any() else mode

    def wrong_slip(self, pt: _Point, v: np.ndarray, mode: _Mode, acc_tol: float) -> tuple[np.ndarray, np.ndarray]:
        """The contacts starting to slide against their own slip acceleration in ``mode``, and
        every contact's slip acceleration."""
        _, (a, _) = self.mode_solution(pt, mode)
        at = pt.Jt @ a + pt.bt
        starting = mode.closed & mode.sliding & (np.linalg.norm(pt.vt(v), axis=1) <= self.speed_tol)
        return starting & (np.sum(mode.slip * at, axis=1) < -acc_tol), at

    def searched_slip(self, pt: _Point, v: np.ndarray, mode: _Mode, wrong: np.ndarray, acc_tol: float) -> _Mode:
        """Where turning each slip to its acceleration cycles (random file 30249: a contact on its
        cone's edge turned from (0.20, -0.98) to (-0.93, -0.36), whose acceleration points 122
        degrees away, at every event), each such contact in turn takes a slip d that its
        acceleration follows, a_t(d) = k d with k >= 0: in the plane the sign that does, in space
        the angle where d x a_t(d) changes sign with d . a_t(d) >= 0 (a scan of :data:`SLIP_SCAN`
        angles, then bisection). Where none exists the mode is left as it was."""
        mode = mode.copy()
        mode.redundant = False
        for k in np.flatnonzero(wrong):
            def along(d: np.ndarray) -> tuple[float, float]:  # (d x a_t(d), d . a_t(d)); the plane's cross is 0
                mode.slip[k] = d
                at = self.wrong_slip(pt, v, mode, acc_tol)[1][k]
                return (float(d[0] * at[1] - d[1] * at[0]) if d.size == 2 else 0.0), float(d @ at)

            kept = mode.slip[k].copy()
            found = _followed_slip(along, kept.size, acc_tol)
            mode.slip[k] = kept if found is None else found
        return mode

    def slide_on_the_edge(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> _Mode:
        """A sticking contact whose force, in the mode's own solve, lies within a force tolerance
        of the cone's edge (or beyond, by rounding) slides against its friction force: the LCP's
        answer at the edge (no slip acceleration) is the same in either mode, but sticking would
        leave the cone at once and stall the run. Repeated until no contact moves to its edge:
        one contact sliding moves the others' share of the friction (random file 20656: twin
        contacts on the edge beside a third, which slid first; the twins then stuck a rounding
        outside the cone and the run stalled)."""
        if self.mu <= 0:
            return mode
        pt = self.point(q, v)
        for _ in range(self.nc):
            if not (mode.closed & ~mode.sliding).any():
                break
            rows, (_, lam) = self.mode_solution(pt, mode)
            fn, ft = _contact_forces(rows, lam, self.mu, self.nc)
            magnitude = np.linalg.norm(ft, axis=1)
            edge = mode.closed & ~mode.sliding & (self.mu * fn - magnitude <= self.force_tol) & (magnitude != 0)
            edge &= ~mode.cornered  # a corner's force lies between its two normals, no cone's
            if not edge.any():
                break
            mode = mode.copy()
            mode.slip[edge] = -_unit(ft[edge], 0.0)
            mode.redundant = self.redundant(pt, mode)
        return mode

    def project(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Back onto the mode's constraints (:meth:`placed`), and in space no velocity along a
        motion that moves no mass (:meth:`unspun`); returns (q, v, the projection's impulses
        [normal, tangential] per contact)."""
        q1, v1, p = self.placed(q, v, mode)
        return q1, self.unspun(q1, v1), p

    def unspun(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``v`` without its part along the mass matrix's massless directions at q (:data:`MASSLESS`:
        a rod of radius 0 spinning about its own axis); ``v`` itself where there is none. The part
        removed carries kinetic energy and momentum at the floor's level (1e-14 of the rod's)."""
        if self.massless is None:
            return v
        n = self.massless_directions(self.point(q, v).M)
        if n is None:
            return v
        if self.tape is not None:
            self.tape.append(("unspun",))
        return v - n @ (n.T @ v)

    def massless_directions(self, M: np.ndarray) -> np.ndarray | None:
        """The unit eigenvectors of ``M`` (columns) whose eigenvalue is at most :attr:`massless`, or
        None where there is none (or in the plane)."""
        if self.massless is None:
            return None
        try:  # every eigenvalue above the bound (the common case): nothing moves without mass
            np.linalg.cholesky(M - self.massless * np.eye(self.nv))
            return None
        except np.linalg.LinAlgError:
            pass
        w, V = np.linalg.eigh(M)
        n = V[:, w <= self.massless]
        return n if n.shape[1] else None

    def refuse_massless_contacts(self, tree: Tree, M0: np.ndarray) -> None:
        """Refuse (ModelError) a landing in which a massless direction of the mass matrix at
        touchdown (``M0``, :data:`MASSLESS`) moves a contact: a rod of radius 0 whose centre of mass is off
        its axis (``com_offset``, no ``inertia_tensor``) turns about the axis through its centre of
        mass with nothing but the core's floor as inertia (1e-14 of its own), and that turn moves
        its contacts, so the landing would follow the floor, not the model: random file 60145
        chattered, its planar reading in space diverged. A rod of radius 0 spinning about its own
        axis moves no contact and is held still instead (:meth:`unspun`)."""
        n = self.massless_directions(M0)
        if n is None:
            return
        pt = self.point(self.q0, np.zeros(self.nv))
        moved = np.vstack([pt.Jn, pt.Jt.reshape(-1, self.nv)]) @ n
        if np.max(np.abs(moved)) <= MASSLESS_REACH * max(b.length for b in tree.bodies):
            return
        off = [i for i, b in enumerate(tree.bodies) if b.radius == 0.0 and not any(b.tensor) and any(b.com_offset)]
        field = f"model.bodies[{off[0]}].com_offset" if off else "model.bodies"
        raise ModelError(
            f"{field}: the whole landing needs inertia wherever a contact moves, but a rod of radius 0 with its "
            "centre of mass off its axis has none about the axis through that centre (only the core's floor, 1e-14 "
            "of its own) and that turn moves its contacts; give the rod a radius or an inertia_tensor")

    def refuse_swinging_springs(self, tree: Tree, M0: np.ndarray) -> None:
        """Refuse (ModelError) a landing whose springs act along a massless direction of the mass
        matrix at touchdown (``M0``: a rod of radius 0 spinning about its own axis, a joint turning
        back) with no damper on it, wound at touchdown more than :data:`MASSLESS_SWING` from their
        balance along it: the small radius's swing keeps their energy at a rate without bound, and
        the landing at radius 0 is no limit of it. A damper along the direction makes the limit a
        relaxation to the balance (random file 60443, which lands); springs at their balance stay
        there as r -> 0, the rod's spin following (60603 with b1's rest at its angle: 3 mm and 1 mm
        end 1e-5 apart), and are taken, though such a run at radius 0 still diverges."""
        n = self.massless_directions(M0)
        if n is None:
            return
        stiffness, damping = self.joints.stiffness, self.joints.damping
        damped = (damping > 0.0) & np.any(np.abs(n) > MASSLESS_REACH, axis=1)
        if np.any(damped):  # the combinations of the directions that no damper moves
            _, s, vt = np.linalg.svd(n[damped], full_matrices=True)
            n = n @ vt[int(np.sum(s > MASSLESS_REACH)):].T
            if n.shape[1] == 0:
                return
        torque = n.T @ (-stiffness * (self.q0 - self.joints.rest))  # the springs' along the directions
        swing = n @ np.linalg.lstsq(n.T @ (stiffness[:, None] * n), torque, rcond=None)[0]
        wound = np.abs(swing) * (stiffness > 0.0)
        if float(np.max(wound)) <= MASSLESS_SWING:
            return
        j = int(np.argmax(wound))
        b = self.joints.dof_body[j]
        energy = 0.5 * float(swing @ (stiffness * swing))
        rods = ", ".join(body.name for body in tree.bodies if body.radius == 0.0 and not any(body.tensor))
        raise ModelError(
            f"model.bodies[{b}].stiffness: {tree.bodies[b].name}'s spring acts along a motion without inertia (a rod "
            "of radius 0 spinning about its own axis, a joint turning back, nothing else moving) with no damper on "
            f"it, and starts {wound[j]:.3g} rad from its balance along it ({energy:.3g} J): with a radius r the spin "
            "swings about that balance ever faster as r -> 0 (~ 1 / r), keeping that energy, so the angles along it at "
            f"T have no limit at radius 0; give the rod a radius (the rods of radius 0: {rods}) or damp the joint")

    def placed(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Back onto the mode's constraints: closed gaps and stops, and open contacts below the
        ground, to zero (positions), then the closed rows' velocities to zero; returns (q, v,
        the projection's impulses [normal, tangential] per contact). A redundant mode's impulses
        are the split of its forces (:func:`_least_norm`: least-norm on the rows as
        :data:`REDUNDANT` ranks them, pushing where a split does): solved to rounding, a nearly
        redundant pair's velocities took its squeeze (random file 31088: an arrest's 1.95e4 N s
        tangential at two contacts 9.4 cm apart, for slips of 2.5e-6 m/s)."""
        if self.tape is not None:
            self.tape.append(("project", q.copy(), v.copy(), mode.copy()))
        end = self.ended(q, v, mode)
        own = (end is not None and not _any(~mode.closed & (end.gap < 0))
               and not _any((mode.stop == 0) & ((q > self.joints.hi) | (q < self.joints.lo))))
        self.projected_at = (q, v)
        if own:  # a compiled step's end whose placement is the mode's own: the compiled projection
            projected = self.fast.project(q, v, mode)
            if projected is not None and not self.carried_across(q, v, projected[0], mode):
                return projected
        pt = self.point(q, v)
        if self.in_place(pt, q, mode):  # what placement() and the velocity rows would find: nothing to do
            return q.copy(), v, np.zeros(self.dims * self.nc)
        corrected = q - self.placement(pt, q, mode)[1]
        if self.carried_across(q, v, corrected, mode):  # the rows of the cell it now rests on
            pt = self.point(corrected, v)
            self.projected_at = (corrected, v)
            if self.tape is not None:
                self.tape.append(("crease_project",))
        if _any(corrected != q):
            v = self.momentum_kept(q, corrected, v)
        q = corrected
        rows = self.mode_solution(pt, mode, solve=False)[0] if _rests(mode) else None
        if rows is None or not rows.G.shape[0]:
            return q, v, np.zeros(self.dims * self.nc)
        minv_gt = np.linalg.solve(pt.M, rows.G.T)
        if rows.redundant:  # the split of its forces (_accelerations): least-norm, pushing where it can
            v, impulse = _least_norm(rows.G @ minv_gt, -rows.G @ v, v, minv_gt, rows.n)
        else:
            impulse = -np.linalg.lstsq(rows.G @ minv_gt, rows.G @ v, rcond=None)[0]
            v = v + minv_gt @ impulse
        return q, v, _stacked(*_contact_forces(rows, impulse, 0.0, self.nc))

    def momentum_kept(self, q: np.ndarray, corrected: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``v`` with the base's translation velocity shifted by dp / m, dp the linear momentum that
        moving q to ``corrected`` at fixed v would change (the velocity projection after it then
        counts what its rows take as impulses): a position correction moves no momentum. Without
        it random file 60624's corrections (348, a tip resting and sliding across a heightfield)
        moved 1.1e-4 of its momentum with no impulse, above the contract's balance of 1e-4."""
        here = self.point(q, v)
        return self.with_momentum(corrected, v, here.momentum[:, 0], here.M[0, 0])

    def with_momentum(self, q: np.ndarray, v: np.ndarray, p: np.ndarray, mass: float) -> np.ndarray:
        """``v`` with the base's translation velocity shifted so that the linear momentum at (q, v)
        is ``p`` (``mass``: M's corner, the whole mass)."""
        out = v.copy()
        out[: self.dims] += (p - self.point(q, v).momentum[:, 0]) / mass
        return out

    def carried_across(self, q: np.ndarray, v: np.ndarray, corrected: np.ndarray, mode: _Mode) -> bool:
        """Whether the position correction from q to ``corrected`` carries a closed contact into
        another heightfield cell (across a crease)."""
        if self.grid is None or not _any(mode.closed):
            return False
        k0 = self.pieces(q, v)
        return bool(_any(mode.closed & (self.pieces(corrected, v) != k0)))

    def in_place(self, pt: _Point, q: np.ndarray, mode: _Mode) -> bool:
        """Whether :meth:`project` has nothing to do at (q, ``pt``): no rows in the mode, no open
        contact below the ground, no joint past a stop (a flight after a bounce)."""
        return not _rests(mode) and not _any(pt.gap < 0) and not _any(self.beyond(q))

    def placement(self, pt: _Point, q: np.ndarray, mode: _Mode) -> tuple[_Mode, np.ndarray]:
        """The rows a projection at (q, ``pt``) zeroes: the mode's, an open contact left below the
        ground (by rounding), and a free joint past a stop, also one that the correction of the
        others would carry past it (it is put back onto the stop); and that position correction."""
        place = mode.copy()
        place.closed |= pt.gap < 0
        place.stop = np.where(place.stop == 0, self.beyond(q), place.stop)
        dq = self.position_correction(pt, q, place)
        carried = np.where(place.stop == 0, self.beyond(q - dq), 0)
        if _any(carried):
            place.stop = np.where(place.stop == 0, carried, place.stop)
            dq = self.position_correction(pt, q, place)
        return place, dq

    def beyond(self, q: np.ndarray) -> np.ndarray:
        """Per DOF: +1 past its upper stop, -1 past its lower one, else 0. A joint that an impact
        left on its stop moving away (the other rows' impulses can do that) may be carried past
        it by the step's rounding; unprojected, its stop margin stays below the event threshold
        and every step is an event of length 0 (the run stalled so)."""
        return np.where(q > self.joints.hi, 1, np.where(q < self.joints.lo, -1, 0))

    def position_correction(self, pt: _Point, q: np.ndarray, mode: _Mode) -> np.ndarray:
        """The smallest (kinetic-metric) change of q that zeroes the mode's closed gaps and stops."""
        # the mode's normal and stop rows alone (:func:`_rows`' first rows, the same numbers)
        contacts, d = np.flatnonzero(mode.closed), np.flatnonzero(mode.stop)
        nc, n = len(contacts), len(contacts) + len(d)
        if not n:
            return np.zeros_like(q)
        G = np.zeros((n, self.nv))
        G[:nc] = pt.Jn[contacts]
        G[nc + np.arange(len(d)), d] = -mode.stop[d]
        residual = np.empty(n)
        residual[:nc] = pt.gap[contacts]
        residual[nc:] = -mode.stop[d] * (q[d] - np.where(mode.stop[d] > 0, self.joints.hi[d], self.joints.lo[d]))
        if _any(mode.cornered & mode.closed):  # a corner's two rows: the point's distances to the two segments' lines
            c = np.flatnonzero(mode.cornered & mode.closed)
            normals = self.valleys[mode.corner[c]]
            Gc, _, _ = _corner_rows(pt, c, normals)
            vertex = np.column_stack([self.vertices, self.ground.y])[mode.corner[c]]
            distance = np.sum(normals * (pt.contacts[c] - vertex)[:, None, :], axis=2).ravel()
            plain = ~np.isin(np.arange(nc), np.flatnonzero(np.isin(contacts, c)))
            G = np.vstack([G[:nc][plain], Gc, G[nc:]])
            residual = np.concatenate([residual[:nc][plain], distance, residual[nc:]])
        minv_gt = np.linalg.solve(pt.M, G.T)
        return minv_gt @ np.linalg.lstsq(G @ minv_gt, residual, rcond=None)[0]

    # ---- the run

    # ---- the base's rotation coordinates (space)

    def base_rotation(self) -> np.ndarray:
        """The base's orientation in the call's design vector: R(rpy) R(axis, angle)."""
        names, p = self.space.body_values, self.call.args[2]
        rpy = tuple(float(p[names.index(k)]) for k in ("roll", "pitch", "yaw"))
        k = np.array([float(p[names.index(k)]) for k in ("axis_x", "axis_y", "axis_z")])
        k /= np.linalg.norm(k)
        angle = float(p[names.index("angle")])
        kk = np.outer(k, k)
        turn = kk + math.cos(angle) * (np.eye(3) - kk) + math.sin(angle) * np.array(
            [[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
        return rotation_rpy(rpy) @ turn

    def set_chart(self, design: np.ndarray, chart: np.ndarray | None) -> None:
        """Evaluate the dynamics with ``design`` from now on (the kept points are dropped)."""
        self.call.args[2][:] = design
        if self.fast is not None:
            self.fast.set_design(design)
        self.chart = chart
        self._last, self._solutions, self._end = None, (None, {}), None

    def rechart(self, q: np.ndarray, v: np.ndarray, totals: _Totals) -> tuple[np.ndarray, np.ndarray]:
        """Re-centre the base's rotation coordinates phi = q[3:6] on its current orientation: the
        base's orientation in the design vector becomes Exp(phi) times it (as an axis and an
        angle, rpy 0), phi becomes 0 and its rates S(phi) phi', the world angular velocity. The
        tree's placement and motion are the same, up to rounding."""
        self.turn = self.reported(q)[3:6]
        from scipy.spatial.transform import Rotation  # here: importing scipy.spatial costs ~0.8 s of CPU

        E = chart_rotation(q[3:6])
        rotvec = Rotation.from_matrix(E @ self.base_rotation()).as_rotvec()
        angle = float(np.linalg.norm(rotvec))
        names, design = self.space.body_values, self.call.args[2].copy()
        design[[names.index(k) for k in ("roll", "pitch", "yaw")]] = 0.0
        design[[names.index(k) for k in ("axis_x", "axis_y", "axis_z")]] = rotvec / angle if angle > 0 else (0, 0, 1)
        design[names.index("angle")] = angle
        q_new, v_new = q.copy(), world_velocity(q, v, self.space)
        q_new[3:6] = 0.0
        self.set_chart(design, E if self.chart is None else E @ self.chart)
        totals.chart_q = q_new.copy()
        if self.tape is not None:
            self.tape.append(("rechart", q.copy(), v.copy()))
        return q_new, v_new

    def reported(self, q: np.ndarray) -> np.ndarray:
        """q as reported: in space the base's rotation vector since touchdown (continued through
        the re-centrings, not wrapped), else q itself."""
        if self.chart is None:
            return q.copy()
        out = q.copy()
        out[3:6] = self.turn = continued_rotation_vector(chart_rotation(q[3:6]) @ self.chart, self.turn)
        return out

    def touchdown(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, LandingEvent, _Mode]:
        """The first event (t = 0): the touchdown state (q, v), the velocity after, the event and
        the rows resting after it; the law's answer is :attr:`last_impact`."""
        self.set_chart(self.design, None)
        self.seated = np.full(self.nc, -1)
        q = self.q0.copy()
        v = pre_impact_velocity(self.topology, self.scene, self.space) if self.v_minus is None else self.v_minus.copy()
        none = self.flight()
        hit = self.first_contacts(self.point(q, v))
        v_plus, event, mode = self.impact(q, v, none, 0.0, hit, "touchdown")
        return q, v, v_plus, event, mode

    def first_impact(self) -> tuple[np.ndarray, np.ndarray, _Mode, _Totals]:
        """t = 0: the first-impact law over the contacts the scene selects."""
        q, v, v_plus, event, mode = self.touchdown()
        totals = _Totals(np.zeros(self.nc), np.zeros((self.nc, self.dims - 1)), [event])
        totals.impulse, totals.vectors = np.zeros(self.dims), np.zeros((self.dims, self.nc))
        totals.joint = np.zeros((self.dims, self.tree.n_bodies)) if self.tally_joint else None
        totals.moving_until = 0.0 if np.max(np.abs(v_plus)) < SETTLE_SPEED else math.nan
        self.add_impact(totals, event, q, v, v_plus)
        q, v_plus, mode = self.resolve_or_jam(q, v_plus, mode, 0.0, totals)
        q1, v1, impulse = self.project(q, v_plus, mode)
        self.add(totals, impulse, *self.projected_at)
        self.tally_joints(totals, q, v_plus, q1, v1, impulse, 0.0, _any(mode.closed))
        return q1, v1, mode, totals

    def first_contacts(self, pt: _Point) -> np.ndarray:
        """The contacts of the first impact: every one (``contacts: all``), or those whose gap is
        within ``scene.contact_tolerance`` of the smallest: on flat ground the rigid rungs' lowest
        contacts (:func:`impulse_core.evaluate.active_contacts`), on uneven ground (a terrain, a
        heightfield) those that touch, not those lowest in the tree's own frame."""
        if self.scene.selection is ContactSelection.ALL:
            return np.arange(self.nc)
        return np.flatnonzero(pt.gap <= np.min(pt.gap) + self.scene.contact_tolerance)

    def add(self, totals: _Totals, impulses: np.ndarray, q: np.ndarray, v: np.ndarray,
            vectors: np.ndarray | None = None) -> None:
        """Add stacked contact impulses (:func:`_stacked`, taken at (q, v)) to the totals (none
        changes where every impulse is 0: a flight's step, a projection without rows);
        ``vectors``: their world vectors where known (:meth:`step_vectors`), else along the
        normals and tangents at (q, v)."""
        if not _any(impulses):  # adding zeros leaves every total as it is, to the bit
            return
        fn, ft = _unstacked(impulses, self.nc, self.dims - 1)
        totals.normal += fn
        totals.tangential += ft
        F = vectors if vectors is not None else self.world_vectors(fn, ft, self.point(q, v) if self.sloped else None)
        totals.impulse += F.sum(axis=1)
        totals.vectors += F

    def world_vectors(self, fn: np.ndarray, ft: np.ndarray, pt: _Point | None) -> np.ndarray:
        """Contact impulses (normal ``fn``, tangential ``ft`` per contact) as world vectors (d x n_c),
        along ``pt``'s normals and tangents on sloped ground, else the flat ground's."""
        if self.sloped:
            return contact_vectors(pt.normal, pt.tangent, fn, ft)
        return contact_vectors(*self.flat_ground, fn, ft)

    def add_impact(self, totals: _Totals, event: LandingEvent, q: np.ndarray, v: np.ndarray, v_plus: np.ndarray
                   ) -> None:
        """Add an impact at q from v to ``v_plus`` (``event``) to the totals."""
        impulses = np.concatenate([event.external, np.reshape(event.tangential, (self.nc, -1)).T.ravel()])
        self.add(totals, impulses, q, v)
        self.tally_joints(totals, q, v, q, v_plus, impulses, 0.0, True)

    def segment_normals(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> np.ndarray | None:
        """On a plane's terrain, the normals at a compiled step's end (q, v) in ``mode``, where
        the projection after it keeps every contact on its segment (no valley corner): the
        normals at the projected point, bit for bit (each segment's is a constant), without the
        numpy point :meth:`add` would evaluate there; else None."""
        if not (self.planar and self.sloped) or self.any_seated or mode.has_corner:
            return None
        end = self.ended(q, v, mode)
        return None if end is None else end.normal

    def segment_vectors(self, normal: np.ndarray, impulses: np.ndarray) -> np.ndarray:
        """Stacked contact impulses (:func:`_stacked`) as world vectors along ``normal`` (n_c x d)
        and its tangents."""
        return contact_vectors(normal, tangent_basis(normal), *_unstacked(impulses, self.nc, self.dims - 1))

    def step_vectors(self, q: np.ndarray, v: np.ndarray, p: np.ndarray) -> np.ndarray | None:
        """On a curved heightfield (:attr:`turning`), the last step's impulse vectors
        (:attr:`vectors`) plus those of the projection after it (stacked ``p``, at its end (q,
        v)); elsewhere None."""
        return None if not self.turning else self.vectors + self.stage_vectors(q, v, p)

    def tally_joints(self, totals: _Totals, q0: np.ndarray, v0: np.ndarray, q1: np.ndarray, v1: np.ndarray,
                     impulses: np.ndarray, dt: float, loaded: bool, vectors: np.ndarray | None = None) -> None:
        """Where kept (:attr:`_Totals.joint`) and a contact pushes (``loaded``: an impact, or a
        step with resting contacts), add the joint impulses from (q0, v0) to (q1, v1): each
        subtree's momentum change minus the contact impulses (stacked, at (q1, v1)) on it and its
        weight's over ``dt``, as the compliant rung counts them; ``vectors``: the impulses' world
        vectors where known (:meth:`add`)."""
        if totals.joint is None or not loaded:
            return
        p0 = self.point(q0, v0).momentum.copy()
        pt = self.point(q1, v1)
        if vectors is None:
            vectors = contact_vectors(pt.normal, pt.tangent, *_unstacked(impulses, self.nc, self.dims - 1))
        weight = np.outer(self.weight(dt), self.subtree_mass / self.mass)
        totals.joint += pt.momentum - p0 - vectors @ self.in_subtree.T - weight

    def run(self, h: float, progress: Progress | None = None, index: int = 0, until: Until | None = None,
            share: float = 1.0) -> LandingResult:
        """The landing at Runge-Kutta step ``h`` (:meth:`run_once`). Where a run stops with
        Painleve's paradox (its contact problem without solution, events stalled on it, or a
        divergence after a contact slid), the landing takes impulsive jams from then on
        (:attr:`jam_watch`, kept for this landing's later runs) and the run starts again: the
        same to the bit until a contact jams, and every run of the step halving judges alike
        where one does (a pressed sliding contact's A falls below JAM_WATCH of its
        frictionless value at a step's start, or the contact problem fails)."""
        try:
            return self.run_once(h, progress, index, until, share)
        except _Jams as paradox:
            if self.jam_watch is not None or self.tape is not None:  # the derivatives' replay: no jams
                raise paradox.failure from None
            self.jam_watch = JAM_WATCH
        return self.run_once(h, progress, index, until, share)

    def run_once(self, h: float, progress: Progress | None = None, index: int = 0, until: Until | None = None,
                 share: float = 1.0) -> LandingResult:
        """The landing at Runge-Kutta step ``h`` (``progress``: told after each step and event,
        as run ``index`` of the step halving); ``until``, asked after the first impact and after
        each step and event, ends it early (its ``duration`` is then the time reached);
        ``share``: the steps' momentum residual per second as a fraction of the default's
        (:data:`MOMENTUM_BALANCE`; :func:`landing`'s finer runs)."""
        T = float(self.scene.duration)
        self.inexact = self.non_unique = 0
        self.bridges = []
        self.min_bounce = MIN_BOUNCE * T
        self._jams = (math.nan, 0)
        self.refused = np.zeros(0, int)
        q, v, mode, totals = self.first_impact()
        slid = bool(self.mu) and _any(mode.closed & mode.sliding)  # a contact slid (a jam may follow)
        self.end_normals = None
        self.min_bounce = max(MIN_BOUNCE * T, self.settings.bounce_steps * h)
        energy_before = totals.events[0].energy_before
        height0 = self.point(self.q0, v).com_height
        # No energy enters (passive joints, a fixed ground): the kinetic energy stays below what
        # touchdown, the springs wound at touchdown and gravity bring; far above it, the step is
        # too long for a stiff joint (random file 32069: a spring 0.21 rad from rest held 0.94 J
        # against 0.035 J of motion, and a landing without gravity stopped as diverged).
        weight = sum(b.mass for b in self.tree.bodies) * self.scene.gravity
        reach = sum(b.length for b in self.tree.bodies)
        wound = self.joints.energy(self.q0)  # the springs at touchdown
        cap = 10.0 * (energy_before + wound + weight * (height0 + reach + 10.0 * T * self.scene.speed)) + 1e-6
        t, stalled, repeated, again, bridged = 0.0, 0, 0, False, 0
        self.record(totals, t, v, t, q, v)
        p0 = self.point(self.q0, totals.events[0].v_minus).momentum[:, 0]
        reference = max(float(np.max(np.abs(p0))), self.mass * self.scene.gravity * T)
        rate = share * MOMENTUM_BALANCE * reference / T  # the steps' momentum residual per second
        trial = h  # the next step's length: h, or h / 2^k after the momentum balance split a step
        while t < T * (1 - 1e-12) and not (until is not None and until(q, v, mode, totals)):
            if not self.planar and float(np.linalg.norm(q[3:6])) > RECHART:
                q, v = self.rechart(q, v, totals)
            if self.jam_watch is not None and _any(mode.closed & mode.sliding):
                jammed, ratio = self.near_jam(q, v, mode, self.jam_watch)
                jammed = jammed[ratio > 0.0]  # A falling to 0 while pressed (A < 0 pressed: a choice, B > 0)
                if jammed.size:
                    failure = NumericalError(self.painleve_message(
                        t, jammed, f"friction {self.mu:g} takes their rows' effective mass to 0"))
                    q, v, mode, t, bridged = self.jam_or_bridge(q, v, mode, t, totals, jammed, failure,
                                                                min(h * BRIDGE, T - t), bridged)
                    if progress is not None:
                        progress(LandingProgress(index, h, t, T, len(totals.events)))
                    continue
            q1, v1, impulse, dt, grown = self.balanced_step(q, v, mode, min(trial, T - t), rate, h / 2.0**MAX_SPLITS)
            step_vectors = self.vectors  # a curved heightfield (trial steps below replace self.vectors)
            if totals.steps > STEP_BUDGET * T / h:
                raise Diverged(  # landing() shortens the step (retry_factor)
                    f"the landing took more than {STEP_BUDGET} x {T / h:.0f} steps by t = {t:.6g} s (the momentum "
                    "balance split its steps: a light rod spinning fast)", reached=t / T,
                )
            if (self.rk4_pace is not None and totals.steps > RK4_PACE_AFTER * T / h
                    and totals.steps * self.rk4_pace > RK4_PACE * t):
                raise Diverged(  # landing() goes on with RK4 from its stable step
                    f"the implicit steps averaged {t / totals.steps:.3g} s by t = {t:.6g} s, below half of RK4's "
                    f"stable step {self.rk4_pace:.3g} s (the momentum balance split them)", reached=t / T,
                )
            final = dt == T - t and dt < trial  # shortened to end at T, not split
            trial = trial if final else min(h, grown)
            if not (_finite(q1) and _finite(v1) and self.kinetic(q1, v1) <= cap):
                failure = Diverged(f"the landing diverged at t = {t:.4g} s (step {h:.3g} s){self.singular_note(q)}"
                                   f"{self.jam_note(q, v, mode) or self.paradox_note()}")
                if self._jams[1] and _any(mode.closed & mode.sliding):
                    # a run that has met Painleve's paradox (a jam taken or tried), a step sliding into
                    # it again (its force without bound): a bridge from the step's start (random file
                    # 60690 at h / 8, after two jams); elsewhere a divergence is a step too long
                    q, v, mode, t, bridged = self.bridge_within(q, v, mode, t, totals, min(h * BRIDGE, T - t),
                                                                bridged, failure)
                    continue
                if self.jam_watch is not None or not slid:
                    raise failure
                # a sliding contact may have run into Painleve's paradox (its force -B / A without
                # bound as A falls to 0: the steps before the divergence are already off)
                raise _Jams(failure)
            _check_chart(q1, self.space, t + dt)
            w, r = self.witness_and_rate(q1, v1, mode)
            all_hold = np.count_nonzero(w >= 0) == w.size  # (w >= 0).all()
            graze = None if all_hold else _Trial(dt, q1, v1, impulse, self._end, w, r, step_vectors)
            if graze is None:
                fraction = self.grazing(q, v, q1, v1, mode, dt)
                graze = None if fraction is None else self.trial(q, v, mode, fraction * dt)
                graze = graze if graze is not None and _any(graze.w < 0) else None
            crossing = None
            if graze is None and (self.vertices is not None or self.grid is not None) and _any(mode.closed):
                crossing = self.vertex_crossing(q, v, q1, v1, mode, dt)
            if graze is not None or crossing is not None:
                self.end_normals = None
            if graze is None and crossing is None:
                if self.tape is not None:
                    self.tape.append(("step", q.copy(), v.copy(), mode.copy(), dt, final))
                q0, v0 = q, v
                segments = self.segment_normals(q1, v1, mode)
                q, v, p = self.project(q1, v1, mode)
                self.follow_slip(q, v, mode)
                self.vectors = step_vectors
                vectors = self.step_vectors(*self.projected_at, p)
                applied = impulse + p  # read only below
                if segments is not None and vectors is None:
                    vectors = self.segment_vectors(segments, applied)
                self.add(totals, applied, q, v, vectors)
                self.tally_joints(totals, q0, v0, q, v, applied, dt, _any(mode.closed), vectors)
                self.record(totals, t, v0, t + dt, q, v)
                t += dt
                totals.steps += 1
                if progress is not None:
                    progress(LandingProgress(index, h, t, T, len(totals.events)))
                continue
            if crossing is not None:  # a closed contact passed a terrain vertex (located just past it)
                located, crossed, cornered = crossing
                if self.tape is not None:
                    self.tape.append(("vertex_step", q.copy(), v.copy(), mode.copy(), located.tau,
                                      crossed | (cornered >= 0)))
            else:
                crossed = cornered = None
                watch = graze.w < 0
                located = self.locate(q, v, mode, graze, watch)
                for _ in range(8):  # a witness that crossed earlier and came back by the step's end
                    missed = (located.w < 0) & ~watch
                    if not _any(missed):
                        break
                    watch = located.w < 0
                    located = self.locate(q, v, mode, located, watch)
                if self.tape is not None:
                    self.tape.append(("event_step", q.copy(), v.copy(), mode.copy(), located.tau, watch))
            tau = located.tau
            q_e, v_e, impulse = self.take(q, v, mode, located)
            self.add(totals, impulse, q_e, v_e, self.vectors)
            self.tally_joints(totals, q, v, q_e, v_e, impulse, tau, _any(mode.closed), self.vectors)
            self.record(totals, t, v, t + tau, q_e, v_e)
            t += tau
            stalled = stalled + 1 if tau < 1e-12 * max(1.0, T) else 0
            repeated = repeated + 1 if again and (tau < REPEAT_SPAN * max(1.0, T) or self.refused.size) else 0
            if stalled > 20 or repeated > REPEATS:
                failure = NumericalError(self.stall_message(q_e, v_e, mode, t))
                jammed = self.painleve(q_e, v_e, mode)
                if not jammed.size:
                    q, v, mode, t, bridged = self.bridge_within(q_e, v_e, mode, t, totals, min(h * BRIDGE, T - t),
                                                                bridged, failure)
                    stalled = repeated = 0
                    again = False
                    if progress is not None:
                        progress(LandingProgress(index, h, t, T, len(totals.events)))
                    continue
                if self.jam_watch is None:
                    raise _Jams(failure)
                # events stalled by Painleve's paradox: the impulsive jam, here
                q, v, mode, t, bridged = self.jam_or_bridge(q_e, v_e, mode, t, totals, jammed, failure,
                                                            min(h * BRIDGE, T - t), bridged)
                stalled = repeated = 0
                again = False
                if progress is not None:
                    progress(LandingProgress(index, h, t, T, len(totals.events)))
                continue
            if len(totals.events) > self.settings.max_events:
                raise NumericalError(self.budget_message(totals.events, t))
            before = mode.copy()
            q, v, mode = self.event(q_e, v_e, mode, t, totals, crossed, cornered)
            again = _same_kind(before, mode)  # the event gave back the mode it stopped
            slid = slid or bool(self.mu) and _any(mode.closed & mode.sliding)
            if progress is not None:
                progress(LandingProgress(index, h, t, T, len(totals.events)))
        pt = self.point(q, v)
        end = t if t < T * (1 - 1e-12) else T  # where ``until`` ended the run, or T
        gravity_work = self.mass * self.scene.gravity * (height0 - pt.com_height)
        residual = pt.momentum[:, 0] - p0 - totals.impulse - self.weight(end)
        balance = float(np.max(np.abs(residual))) / reference
        out = self.result(totals, q, v, h, energy_before, pt.kinetic + self.joints.energy(q), gravity_work)
        self.set_chart(self.design, None)  # q_final's rotation vector is since touchdown
        return replace(out, momentum_balance=balance, duration=end, spring_energy=wound, bridges=tuple(self.bridges))

    def budget_message(self, events: list[LandingEvent], t: float) -> str:
        """Why a run passed its impact budget at ``t``: the contact (or stop) that took most of
        the last thousand impacts, and, where its restitution is 1, that an elastic contact
        pressed to the ground bounces without end (random file 20144: a light base driven down at
        2000 m/s^2 bounced at e = 1 ever faster, 20000 impacts by 18 ms)."""
        recent = events[-1000:]
        external = np.array([e.external for e in recent]) > 0
        stops = np.array([e.stop for e in recent]) != 0
        counts = np.concatenate([external.sum(axis=0), stops.sum(axis=0)])
        k = int(np.argmax(counts))
        head = f"the landing took more than {self.settings.max_events} impacts by t = {t:.6g} s"
        if k < self.nc:
            who, e, field = f"contact {self.contact_labels([k])}", self.e, "scene.restitution"
        else:
            body = self.tree.bodies[k - self.nc + 1]
            e = float(self.per_joint(self.joints.restitution)[k - self.nc])
            who, field = f"the stop of {body.name}", f"{body.name}.stop_restitution"
        note = f": {who} took {counts[k]} of the last {len(recent)}"
        if e >= 1.0:
            note += f" at restitution {e:g} (an elastic contact pressed to the ground bounces without end: lower {field})"
        return head + note

    def contact_labels(self, contacts) -> str:
        """The contacts (indices) as the model file names them: ``body[k]``, comma-separated."""
        return ", ".join(f"{self.tree.bodies[b].name}[{k}]" for b, k in (self.tree.contacts[int(c)] for c in contacts))

    def singular_note(self, q: np.ndarray) -> str:
        """Why a run diverged at ``q`` where its mass matrix is near singular (condition number
        above SINGULAR_MASS): e.g. rods of zero radius, each spinning about its own axis, which
        moves no mass where a hinge lets them (rods in line; random file 32365: a child's axis in
        the plane of its parent's and the hinge's, 11 degrees apart), spin up without bound as they
        pass that posture; else nothing."""
        cond = float(np.linalg.cond(self.mass_matrix_at(q)))
        if cond <= SINGULAR_MASS:
            return ""
        return (f": its mass matrix is near singular there (condition number {cond:.1e}: a motion with almost no "
                "inertia, e.g. rods of zero radius spinning about their own axes, where they lie in line or a "
                "child's axis lies in the plane of its parent's and its hinge's); give the rods a radius")

    def paradox_note(self) -> str:
        """Where a run that diverged had met Painleve's paradox before (its last impulsive jam, taken
        or tried), that and the remedy; else nothing (random file 61227: its run at h / 8 diverged
        1.9 ms after a jam, in a mode no jam note explains)."""
        if not self._jams[1]:
            return ""
        return (f", after Painleve's paradox at t = {self._jams[0]:.6g} s (an impulsive jam taken or tried there: "
                f"friction {self.mu:g} takes a sliding contact's effective mass to 0): lower the friction")

    def jam_note(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> str:
        """Why a run diverged at (q, v) in ``mode`` where a closed sliding contact is pressed
        while its row's effective inverse mass with friction along the slip, A = n M^-1 (n - mu u
        t)^T, has fallen below JAM_NOTE of its frictionless n M^-1 n^T: its force -B / A grows
        without bound as A reaches 0 (Painleve's paradox approached while sliding; Genot and
        Brogliato 1999, Or and Rimon 2012), which no step resolves (random file 40029: at every
        step of the halving, A fell from 0.46 of it at 0.11 s to 2e-6..1e-8 at 0.1423 s, the force
        from 74 N to 1e5-1e9 N); else nothing."""
        contact, ratio = self.near_jam(q, v, mode)
        if not contact.size:
            return ""
        return (f": contacts {self.contact_labels(contact)} slide pressed where their rows' effective mass "
                f"with friction {self.mu:g} has nearly vanished (n M^-1 (n - mu u t)^T at "
                f"{float(np.min(ratio)):.1e} of its frictionless value): Painleve's paradox ahead, the "
                "contact force growing without bound (a dynamic jam, which the landing could not take here: it jams "
                "one sliding contact at a time, by a slide that stops its slip): lower the friction")

    def near_jam(self, q: np.ndarray, v: np.ndarray, mode: _Mode, below: float = JAM_NOTE
                 ) -> tuple[np.ndarray, np.ndarray]:
        """The closed sliding contacts that ``mode`` presses (force above the tolerance) where
        their row's A = n M^-1 (n - mu u t)^T is below ``below`` times n M^-1 n^T (JAM_NOTE:
        :meth:`jam_note`; JAM_WATCH: :meth:`run`'s watch), and those ratios."""
        none = np.zeros(0, int), np.zeros(0)
        if not self.mu or not _any(mode.sliding & mode.closed):
            return none
        try:
            contact, A, A0, fn = self.sliding_rows(q, v, mode)
        except (NumericalError, np.linalg.LinAlgError):
            return none
        ratio = A / A0
        near = (ratio < below) & mode.sliding[contact] & (fn > self.force_tol)
        return contact[near], ratio[near]

    def sliding_rows(self, q: np.ndarray, v: np.ndarray, mode: _Mode
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The contacts of ``mode``'s normal rows at (q, v), each row's effective inverse mass
        with its friction along the slip, A = n M^-1 (n - mu u t)^T (n M^-1 n^T where it sticks),
        its frictionless one n M^-1 n^T, and the mode's normal force on it."""
        pt = self.point(q, v)
        rows, (_, lam) = self.mode_solution(pt, mode)
        fn = _contact_forces(rows, lam, self.mu, self.nc)[0]
        c = np.flatnonzero(rows.contact[: rows.n] >= 0)
        contact, G = rows.contact[c], rows.G[c]
        A = np.einsum("ij,ji->i", G, np.linalg.solve(pt.M, rows.F[c].T))
        return contact, A, np.einsum("ij,ji->i", G, np.linalg.solve(pt.M, G.T)), fn[contact]

    def stall_message(self, q: np.ndarray, v: np.ndarray, mode: _Mode, t: float) -> str:
        """Why events stopped making progress at (q, v): Painleve's paradox where a sliding
        contact has no consistent force (:meth:`painleve`), else chatter."""
        jammed = self.painleve(q, v, mode)
        if not jammed.size:
            pt = self.point(q, v)
            against = np.flatnonzero(self.wrong_slip(pt, v, mode, 0.0)[0]) if self.mu > 0 else []
            note = "" if not len(against) else (
                f": contacts {self.contact_labels(against)} start to slide from rest against their own slip "
                "acceleration in the mode (no slip direction found that it follows)")
            if not note and self.refused.size:
                note = (f": the slow slip of contacts {self.contact_labels(self.refused)} turns at each event, and "
                        "the mode with them sticking does not hold (not arrested)")
            return f"the landing chatters at t = {t:.6g} s (events without progress{note})"
        return self.painleve_message(t, jammed, f"friction {self.mu:g} makes their rows' effective mass negative")

    def painleve_message(self, t: float, contacts: np.ndarray, why: str) -> str:
        """Painleve's paradox at ``t``: the sliding ``contacts`` have no consistent contact
        force, ``why``."""
        return (f"Painleve's paradox at t = {t:.6g} s: contacts {self.contact_labels(contacts)} slide with no "
                f"consistent contact force ({why}; rigid bodies then need an impulsive jam, which the landing could "
                "not take here: it jams one sliding contact at a time, by a slide that stops its slip): lower the "
                "friction")

    def painleve(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> np.ndarray:
        """Closed sliding contacts in Painleve's paradox at (q, v): their own row's effective
        inverse mass with its friction along the slip, n M^-1 (n - mu u t)^T, is negative, so no
        pushing force keeps them on the ground, and the mode's force on them pulls."""
        if not self.mu or not _any(mode.sliding & mode.closed):
            return np.zeros(0, int)
        contact, inverse_mass, _, fn = self.sliding_rows(q, v, mode)
        jammed = (inverse_mass < 0) & mode.sliding[contact] & (fn < -self.force_tol)
        return contact[jammed]

    def sliding_jams(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> np.ndarray:
        """Contacts resting on the ground (closed in ``mode``, or at the ground with no normal
        speed) that slide (|s| above the speed tolerance) where their row's effective inverse
        mass with friction along the slip, A = n M^-1 (n - mu u t)^T with u = s / |s|, is
        negative or below JAM_NOTE of n M^-1 n^T: where the contact problem at the acceleration
        level fails (:class:`PainleveParadox`), the contacts that can jam."""
        if not self.mu:
            return np.zeros(0, int)
        pt = self.point(q, v)
        speed = np.linalg.norm(pt.slip, axis=1)
        near = mode.closed | ((pt.gap <= self.settings.gap_tolerance) & (np.abs(pt.vn(v)) <= self.speed_tol))
        c = np.flatnonzero(near & (speed > self.speed_tol))
        if not c.size:
            return c
        u = pt.slip[c] / speed[c, None]
        F = pt.Jn[c] - _along(self.mu * u, pt.Jt[c])
        minv_jn = np.linalg.solve(pt.M, pt.Jn[c].T)
        A = np.einsum("ij,ji->i", F, minv_jn)
        A0 = np.einsum("ij,ji->i", pt.Jn[c], minv_jn)
        return c[A < JAM_NOTE * A0]

    def jam(self, q: np.ndarray, v: np.ndarray, mode: _Mode, t: float, contact: int
            ) -> tuple[np.ndarray, LandingEvent, _Mode] | None:
        """The impulsive jam at (q, v) of the sliding ``contact`` in Painleve's paradox (an impact
        without collision: Genot and Brogliato 1999; Or and Rimon 2012; Champneys and Varkonyi
        2016): the velocities after, the event (kind "touchdown", ``jam`` set) and the rows resting
        after it; None where the slip does not fall along the cone's edge.

        The law, in two phases (Darboux-Keller with Newton's law):
        1. the contact's sliding phase (:func:`darboux_keller_slide`): its impulse grows along the
           cone's edge, n - mu u t, until its slip stops (or, in space, a compression ends); its
           normal velocity changes by A p (compression where A < 0).
        2. the landing's impact law (:func:`rigid_impact`: Newton's restitution, exact Coulomb
           friction) over every contact at the ground and every joint on a stop, at e = 0 (Newton's
           law refers to the pre-jam normal velocities, 0: v_n+ >= 0), from phase 1's velocities.
        Why this law: (a) where A < 0 and a single contact jams in the plane it is the h -> 0
        limit of velocity-level time stepping (Stewart-Trinkle, Anitescu-Potra) with the pressing
        free velocity: zero is then no solution of the step's LCP, no small one exists (it would
        need p = -h B / A < 0), and the limit is the sticking impulse -W^-1 (0, s), inside the cone
        exactly when A < 0; phase 1 then 2 give that impulse (W invertible: same end velocity). (b)
        where A falls to 0+ while pressed, the mode's own force -B / A integrates (logarithmically
        without bound) to an impulse along the edge within a vanishing time: phase 1 is that limit,
        and A p, the normal velocity it leaves, vanishes with A (the run takes the jam at A below
        JAM_WATCH of its frictionless value; over the jam's vanishing duration the pressing
        free acceleration B takes back the normal speed A p the slide gives: the contact rests
        after it, and the projection takes that O(A) rest).
        The total impulse is in the cone (a sum of cone members), its normal part >= 0; the
        other contacts take part in phase 2 only (the jam's sliding phase is the jammed
        contact's alone: a sequential split where several contacts are loaded)."""
        if self.tape is not None:
            raise NumericalError(f"an impulsive jam at t = {t:.6g} s: exact landing derivatives are refused across it")
        pt = self.point(q, v)
        J = np.vstack([pt.Jn[contact][None], pt.Jt[contact]])  # d x nv: normal, then tangents
        minv_jt = np.linalg.solve(pt.M, J.T)
        slide = darboux_keller_slide(J @ minv_jt, pt.slip[contact], self.mu)
        if slide is None:
            return None
        p, p_t = slide
        impulse = np.concatenate([[p], p_t])
        v1 = v + minv_jt @ impulse
        lift = max(float(J[0] @ minv_jt @ impulse), 0.0)  # the normal speed the slide left (A p where A > 0)
        stops = self.stops_touching(q, mode)
        contacts = np.flatnonzero(mode.closed | (pt.gap <= self.settings.gap_tolerance))
        rows = _rows(pt, contacts, self.no_slip(), stops, self.mu, self.nv)
        law = rigid_impact(pt, v1, rows, np.zeros(rows.n), self.mu, self.lemke)
        self.last_impact = law
        if self.impact_log is not None:
            self.impact_log.append((q.copy(), v.copy(), np.array(contacts), pt, law))
        self.inexact += not law.exact
        self.non_unique += not law.split_unique
        v_plus, fn, ft = law.v_plus, law.normal.copy(), law.tangential.copy()
        fn[contact] += p
        ft[contact] += p_t
        F = contact_impulses(pt, fn, ft)
        internal, magnitude = joint_impulses(self.point(q, v_plus).momentum - pt.momentum - F @ self.in_subtree.T)
        n, on_contact, on_stop = rows.n, rows.contact >= 0, rows.dof >= 0
        stop = np.zeros(self.nv)
        stop[rows.dof[on_stop]] = (-stops[rows.dof[on_stop]]) * law.solution.normal[on_stop]
        leaving = law.solution.velocity[:n]
        after = leaving < PLASTIC_SPEED  # e = 0: a row left slower than the plastic speed rests
        # the jammed contact rests where it leaves only at the speed its slide gave it: where A > 0
        # (a dynamic jam taken at A below JAM_WATCH, not at 0) the pressing free acceleration
        # holds it over the jam's vanishing duration, B dt = -A p, and the projection takes it
        after |= (rows.contact == contact) & (leaving <= lift + PLASTIC_SPEED)
        on_ground = pt.gap[np.maximum(rows.contact, 0)] <= self.scene.contact_tolerance + self.settings.gap_tolerance
        new = mode.copy()
        new.closed[:] = False
        new.closed[rows.contact[on_contact & after & on_ground]] = True
        new.slip[:] = 0.0
        new.stop[:] = 0
        at = rows.dof[on_stop & after]
        new.stop[at] = stops[at]
        event = LandingEvent(
            time=t, kind="touchdown", external=fn, tangential=self.public_tangential(ft),
            internal=internal[:, : self.dims], internal_magnitude=magnitude, stop=self.per_joint(stop),
            v_minus=world_velocity(q, v, self.space), v_plus=world_velocity(q, v_plus, self.space),
            energy_before=float(v @ pt.M @ v) / 2, energy_after=float(v_plus @ pt.M @ v_plus) / 2, jam=True,
        )
        return v_plus, event, new

    def take_jam(self, q: np.ndarray, v: np.ndarray, mode: _Mode, t: float, totals: _Totals,
                 jammed: np.ndarray, failure: NumericalError) -> tuple[np.ndarray, np.ndarray, _Mode]:
        """The impulsive jam (:meth:`jam`) of the one contact in ``jammed`` at (q, v), counted in
        ``totals``, and the slow slips arrested after it (:meth:`arrest`): (q, v, the rows resting
        after it). Raises ``failure`` (the error the landing stopped with before jams were
        modelled) where not one contact jams, where the jam's sliding phase does not stop the
        slip, or where this is the JAM_REPEATS-th jam at one instant (the jam did not end it)."""
        last, count = self._jams
        count = count + 1 if abs(t - last) <= JAM_INSTANT * float(self.scene.duration) else 1
        self._jams = (t, count)
        if len(jammed) != 1 or count >= JAM_REPEATS:
            raise failure
        jam = self.jam(q, v, mode, t, int(jammed[0]))
        if jam is None:
            raise failure
        v_plus, event, new = jam
        totals.events.append(event)
        self.add_impact(totals, event, q, v, v_plus)
        q1, v1 = self.arrest(q, v_plus, new, totals)
        return q1, v1, new

    def bridge(self, q: np.ndarray, v: np.ndarray, mode: _Mode, t: float, totals: _Totals, span: float
               ) -> tuple[np.ndarray, np.ndarray, _Mode, float]:
        """Events stalled where no Painleve jam explains it (a start of slip, or a stick-slip
        cycle among nearly redundant contacts, that the modes do not resolve): the landing crosses
        ``span`` by :data:`BRIDGE_STEPS` Moreau-Jean steps (:meth:`bridge_step`), whose impulses
        are the contacts' (continuous: no events), then takes the modes at the end
        (:meth:`modes_after`). First order in the step, as the step halving's estimate sees.
        Returns (q, v, mode, t) after."""
        if self.tape is not None:
            self.tape.append(("bridge", q.copy(), v.copy(), mode.copy(), span))
        start, dt, v_before, closed = t, span / BRIDGE_STEPS, v, mode.closed
        for _ in range(BRIDGE_STEPS):
            q1, v1, impulses, closed = self.bridge_step(q, v, mode, closed, dt)
            self.add(totals, impulses, q, v)
            self.tally_joints(totals, q, v, q1, v1, impulses, dt, True)
            self.record(totals, t, v, t + dt, q1, v1)
            q, v, t = q1, v1, t + dt
            totals.steps += 1
        after = self.flight()
        after.closed[:] = closed
        after.stop[:] = self.stops_touching(q, mode)
        q, v, mode = self.modes_after(q, v, after, t, totals, v_before)
        self.bridges.append((start, span))
        return q, v, mode, t

    def bridge_step(self, q: np.ndarray, v: np.ndarray, mode: _Mode, closed: np.ndarray, dt: float
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """One Moreau-Jean step (Moreau 1988, Jean 1999; Siconos's ``MoreauJeanOSI`` at theta =
        1): the free velocity v + dt M^-1 f, then the rigid law with e = 0 and exact Coulomb
        friction (:func:`rigid_impact`; every row sticking, so the law picks stick or slip) over
        the contacts ``closed`` or whose gap the free velocity closes within the step, and the
        stops reached (``mode``'s or within the step); then q + dt v+. Returns (q, v, the law's
        impulses [normal, tangential] per contact, the contacts that took a normal impulse)."""
        pt = self.point(q, v)
        v_free = v + dt * np.linalg.solve(pt.M, pt.f)
        reach = closed | (pt.gap + dt * np.minimum(pt.vn(v_free), 0.0) <= self.settings.gap_tolerance)
        plain, corners = self.corner_split(mode, np.flatnonzero(reach))
        rows = _rows(pt, plain, self.no_slip(), self.stops_touching(q + dt * v_free, mode), self.mu, self.nv,
                     corners=corners)
        law = rigid_impact(pt, v_free, rows, np.zeros(rows.n), self.mu, self.lemke)
        self.inexact += not law.exact
        impulses, q1 = _stacked(law.normal, law.tangential), q + dt * law.v_plus
        return q1, self.balance_kept(pt, q1, law.v_plus, impulses, dt), impulses, law.normal > 0

    def balance_kept(self, pt: _Point, q1: np.ndarray, v1: np.ndarray, impulses: np.ndarray, dt: float
                     ) -> np.ndarray:
        """``v1`` with the base's translation velocity shifted so that the linear momentum at (q1, v1)
        is the momentum at ``pt`` plus the weight's impulse over ``dt`` and the contact ``impulses``
        (stacked, along ``pt``'s directions): a Moreau-Jean step's momentum at its end. Its velocity
        after is taken at q1, while its forces were at q: across a velocity jump the step changed
        the momentum by dt times the jump in the Coriolis terms, first order in dt (random file
        60690: a bridge took a tumbling rod from 35 to 26 rad/s, the landing's balance 1.1e-4)."""
        applied = self.world_vectors(*_unstacked(impulses, self.nc, self.dims - 1), pt).sum(axis=1)
        return self.with_momentum(q1, v1, pt.momentum[:, 0] + self.weight(dt) + applied, pt.M[0, 0])

    def jam_event(self, q: np.ndarray, v: np.ndarray, mode: _Mode, t: float, totals: _Totals,
                  jammed: np.ndarray, failure: NumericalError) -> tuple[np.ndarray, np.ndarray, _Mode]:
        """An event that is only an impulsive jam at (q, v) (:meth:`take_jam`; a run's step that
        ran into Painleve's paradox, or events stalled by it), then the modes after it (as
        :meth:`event`): the state and mode after."""
        q1, v1, new = self.take_jam(q, v, mode, t, totals, jammed, failure)
        return self.modes_after(q1, v1, new, t, totals, v, jammed=True)

    def jam_or_bridge(self, q: np.ndarray, v: np.ndarray, mode: _Mode, t: float, totals: _Totals,
                      jammed: np.ndarray, failure: NumericalError, span: float, bridged: int
                      ) -> tuple[np.ndarray, np.ndarray, _Mode, float, int]:
        """:meth:`jam_event`, or where the jam cannot be taken (it raises ``failure``: its slide does
        not stop the slip, or it came back at one instant) a bridge across ``span`` (:meth:`bridge`;
        ``bridged`` so far, at most MAX_BRIDGES): Moreau-Jean's velocity-level law has a solution
        where the acceleration-level one has none (Stewart 1998). Random file 60690: a rod's tip
        at friction 0.3, whose jam stopped ending its slip at t = 0.1777 s. (q, v, mode, t, bridged)."""
        try:
            return (*self.jam_event(q, v, mode, t, totals, jammed, failure), t, bridged)
        except NumericalError as unjammed:
            if unjammed is not failure:
                raise
        return self.bridge_within(q, v, mode, t, totals, span, bridged, failure)

    def bridge_within(self, q: np.ndarray, v: np.ndarray, mode: _Mode, t: float, totals: _Totals, span: float,
                      bridged: int, failure: NumericalError) -> tuple[np.ndarray, np.ndarray, _Mode, float, int]:
        """A bridge across ``span`` (:meth:`bridge`) as the run's next, (q, v, mode, t, bridged + 1);
        raises ``failure`` where the run has taken MAX_BRIDGES already."""
        if bridged >= MAX_BRIDGES:
            raise failure
        return (*self.bridge(q, v, mode, t, totals, span), bridged + 1)

    def modes_after(self, q: np.ndarray, v: np.ndarray, mode: _Mode, t: float, totals: _Totals,
                    v_before: np.ndarray, jammed: bool = False) -> tuple[np.ndarray, np.ndarray, _Mode]:
        """After an event at ``t`` (the velocities ``v_before`` it): the modes
        (:meth:`resolve_or_jam`, ``jammed`` after a jam; a valley's corners seated), the
        projection onto them, counted in ``totals``, and the record: (q, v, mode) after."""
        q, v, mode = self.resolve_or_jam(q, v, mode, t, totals, jammed)
        if self.valleys is not None:
            self.seat(mode)
        q1, v1, p = self.project(q, v, mode)
        self.add(totals, p, *self.projected_at)
        self.tally_joints(totals, q, v, q1, v1, p, 0.0, _any(mode.closed))
        self.record(totals, t, v_before, t, q1, v1)
        return q1, v1, mode

    def resolve_or_jam(self, q: np.ndarray, v: np.ndarray, mode: _Mode, t: float, totals: _Totals,
                       jammed: bool = False) -> tuple[np.ndarray, np.ndarray, _Mode]:
        """:meth:`resolve`, or, where its contact problem has no solution (Painleve's paradox),
        the impulsive jam of the sliding contact there (:meth:`take_jam`) and then this again
        from the velocities after it: (q, v, mode). Right after a jam (``jammed``), also a mode
        whose force pulls on a sliding contact in the paradox (:meth:`painleve`) jams again at
        once: in space a jam that ended with its compression can leave its contact sliding in
        the paradox, and each jam then takes the slip by about the same factor towards 0 (random
        file 30325: 0.58, 21 jams at one instant, 4 at the next), which through the run's
        stalled events (21 per jam) cost 61 s instead of 9 s."""
        while True:
            try:
                new = self.resolve(q, v, mode, t)
            except PainleveParadox as paradox:
                if self.jam_watch is None:
                    raise _Jams(paradox) from None
                q, v, mode = self.take_jam(q, v, mode, t, totals, self.sliding_jams(q, v, mode), paradox)
                jammed = True
                continue
            again = self.painleve(q, v, new) if jammed else np.zeros(0, int)
            if not again.size:
                return q, v, new
            q, v, mode = self.take_jam(q, v, new, t, totals, again, NumericalError(self.stall_message(q, v, new, t)))

    def event(self, q: np.ndarray, v: np.ndarray, mode: _Mode, t: float, totals: _Totals,
              crossed: np.ndarray | None = None, cornered: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray, _Mode]:
        """Handle the event at (q, v): an impact where a contact touches or a joint reaches a
        stop, then the new modes. ``crossed``: the closed contacts that have just passed a
        terrain vertex (:meth:`vertex_crossing`): each meets the segment beyond it afresh, along
        that segment's normal: an impact where it approaches it (a valley), free where it leaves
        it (a ridge). ``cornered``: per contact -1, or the valley breakpoint it has just reached
        slower than the plastic speed: it rests in the corner, held by both segments' rows, while
        the contact LCP loads both (:meth:`resolve`, :meth:`keep_corners`); the projection takes
        its velocity to zero."""
        pt = self.point(q, v)
        vn = pt.vn(v)
        touching = ~mode.closed & (pt.gap <= self.settings.gap_tolerance) & (vn < 0)
        if crossed is not None:
            mode = mode.copy()
            mode.closed[crossed] = False
            mode.slip[crossed] = 0.0
            touching |= crossed & (vn < 0)
        if cornered is not None and _any(cornered >= 0):
            mode = mode.copy()
            at = cornered >= 0
            mode.closed[at], mode.corner[at], mode.slip[at] = True, cornered[at], 0.0
            touching |= at  # a plastic impact over both rows (approaching slower than the plastic speed)
        reaching = (mode.stop == 0) & (((q <= self.joints.lo + self.settings.gap_tolerance) & (v < 0))
                                        | ((q >= self.joints.hi - self.settings.gap_tolerance) & (v > 0)))
        v_before = v
        if _any(touching) or _any(reaching):
            # every contact at the ground takes part (one just released may be pushed back down)
            contacts = np.flatnonzero(mode.closed | (pt.gap <= self.settings.gap_tolerance) | touching)
            v_minus = v
            v, event, mode = self.impact(q, v, mode, t, contacts, "touchdown" if _any(touching) else "stop")
            totals.events.append(event)
            self.add_impact(totals, event, q, v_minus, v)
        q, v = self.arrest(q, v, mode, totals)
        return self.modes_after(q, v, mode, t, totals, v_before)

    def record(self, totals: _Totals, t0: float, v0: np.ndarray, t1: float, q1: np.ndarray, v1: np.ndarray) -> None:
        """Keep the trajectory and when the model last moved (some |v| >= SETTLE_SPEED): a step
        from (t0, v0) to (t1, v1), or a jump (t0 = t1) at an impact. Where every velocity falls
        below SETTLE_SPEED within a step, the crossing is interpolated linearly (exact under
        constant deceleration)."""
        q0 = q1 if totals.chart_q is None else totals.chart_q
        v0, v1 = world_velocity(q0, v0, self.space), world_velocity(q1, v1, self.space)
        totals.chart_q = q1.copy()
        totals.times.append(t1)
        totals.states.append(self.reported(q1))
        if _largest(np.abs(v1)) >= SETTLE_SPEED:
            totals.moving_until = math.nan  # still moving at t1
        elif math.isnan(totals.moving_until):
            a0, a1 = np.abs(v0), np.abs(v1)
            fast = a0 >= SETTLE_SPEED
            s = float(np.max((a0[fast] - SETTLE_SPEED) / (a0[fast] - a1[fast]), initial=0.0))
            totals.moving_until = t0 + s * (t1 - t0)

    def result(self, totals: _Totals, q: np.ndarray, v: np.ndarray, h: float, energy_before: float,
               energy_final: float, gravity_work: float) -> LandingResult:
        layout = self.layout
        v_world, q = world_velocity(q, v, self.space), self.reported(q)
        base = [q[2]] if self.planar else list(q[3:6])
        angles = base + [b.angle if k is None else q[k] for b, k in zip(self.tree.bodies[1:], layout.body_dof[1:])]
        settled = None if math.isnan(totals.moving_until) else totals.moving_until
        return LandingResult(
            events=tuple(totals.events),
            total_external=totals.normal.copy(),
            total_tangential=self.public_tangential(totals.tangential),
            settled_at=settled,
            q_final=q.copy(),
            v_final=v_world,
            final_angles=np.array(angles, dtype=float),
            energy_before=float(energy_before),
            energy_final=float(energy_final),
            gravity_work=float(gravity_work),
            duration=float(self.scene.duration),
            step=h,
            n_steps=totals.steps,
            integrator=self.method,
            trajectory=(np.array(totals.times), np.array(totals.states)),
            space=self.space.name,
            inexact=self.inexact,
            non_unique=self.non_unique,
            step_code=self.code,
        )


# --------------------------------------------------------------------------------------------
# The public function


def split_alike_at_half(result: LandingResult) -> bool:
    """Whether the run at half ``result``'s step would be split alike by the momentum balance
    (fewer than DISTINCT_RUNS x its steps, :func:`landing`): halving the step changes only the
    steps longer than half of it, each into two, and the balance split all but fewer than
    DISTINCT_RUNS - 1 of them shorter (random file 50005: runs of 12,439 steps at h and h / 2,
    a third of its landing's time)."""
    times = result.trajectory[0]
    if times.size < 2:
        return False
    longer = int(np.count_nonzero(np.diff(times) > 0.5 * result.step * (1.0 + 1e-9)))
    return result.n_steps + longer < DISTINCT_RUNS * result.n_steps


def landing_differences(a: LandingResult, b: LandingResult) -> tuple[float, float, float]:
    """Relative differences (``MODEL_FORMAT.md``: max |a_i - b_i| / max |b_i|) of the peak
    impulses, of the total external impulses and of the final angles, each list on its own."""
    return (
        relative_difference([([a.peak_external_norm, a.peak_internal_norm],
                              [b.peak_external_norm, b.peak_internal_norm])]),
        relative_difference([(a.total_external, b.total_external)]),
        relative_difference([(a.final_angles, b.final_angles)]),
    )


def landing_difference(a: LandingResult, b: LandingResult) -> float:
    """Relative difference (``MODEL_FORMAT.md``: max |a_i - b_i| / max |b_i| per list, the
    largest over the lists) of the peak impulses, total external impulses and final angles."""
    return max(landing_differences(a, b))


def runs_apart(halving: tuple[tuple[float, float, float, float, float], ...] | list) -> bool:
    """Whether the step halving's runs end in postures that do not approach each other
    (``halving``: :attr:`LandingResult.halving`): in its last two comparisons the final angles
    differ by at least POSTURE_SPREAD, the later difference is more than the earlier times the
    ratio of their finer steps (a first-order error would shrink at least so), and the later pair's
    peak and total impulses differ by at most IMPULSES_AGREE times their final angles. The motion
    after the impacts then amplifies the step's error beyond what halving removes (random file
    32924: a tumbling flight, a 1e-10 kick grown to 1e-2 rad in 0.21 s), and each halving costs
    twice the last; the impacts' own convergence is not what is missing."""
    if len(halving) < 2:
        return False
    (_, h0, _, _, angles0), (_, h1, peaks, totals, angles1) = halving[-2:]
    return (min(angles0, angles1) >= POSTURE_SPREAD and angles1 > angles0 * h1 / h0
            and max(peaks, totals) <= IMPULSES_AGREE * angles1)


#: The step halving stops early, unmet, where a step STALL_STEPS times shorter left the runs'
#: difference above STALL_FRACTION of what it was (:func:`stall_start`).
STALL_FRACTION = 0.5
STALL_STEPS = 8.0


def stall_start(halving: tuple[tuple[float, float, float, float, float], ...] | list) -> int | None:
    """Where the step halving stalled (``halving``: :attr:`LandingResult.halving`): the index of the
    last comparison whose finer step is at least STALL_STEPS times the last comparison's, where every
    comparison after it left the runs' difference (the largest of the three lists) above
    STALL_FRACTION of its; else None. An error of first order in the step falls eight-fold over
    three halvings; one that has not halved is not converging at a rate worth the cost, since each
    halving costs twice the last (random file 60838: the split of a load between two contacts
    0.66 mm apart changes with the step; 61004, whose runs are mostly four times apart, by 0.137,
    3.7e-3, 1.0e-2, 7.5e-3). Fewer halvings do not judge: random file 60045's differences
    rose from 3.6e-3 to 7.0e-3 and 7.5e-3 as its event sequence changed with the step, then fell
    to 1.1e-3, and its next run met the tolerance."""
    last = halving[-1][1] if halving else math.nan
    for j in range(len(halving) - 2, -1, -1):
        if halving[j][1] >= STALL_STEPS * last * (1.0 - 1e-9):
            before = max(halving[j][2:])
            return j if min(max(c[2:]) for c in halving[j + 1:]) > STALL_FRACTION * before else None
    return None


def halving_stalled(halving: tuple[tuple[float, float, float, float, float], ...] | list) -> bool:
    """Whether the step halving stalled (:func:`stall_start`)."""
    return stall_start(halving) is not None


def landing(
    tree: Tree, scene: Scene, joints: tuple[JointLaw, ...] = (), settings: LandingSettings = LandingSettings(),
    space: Space = PLANAR, progress: Progress | None = None,
) -> LandingResult:
    """The whole landing of ``tree`` (module docstring; in ``space``), to ``settings.tolerance``: the step is
    halved from ``settings.step`` until two successive runs differ by at most the tolerance
    (:func:`landing_difference`); the finer run is returned with that difference as its
    ``error_estimate`` (an unmet tolerance: ``converged`` is False). The halving stops early, unmet,
    where its runs' final angles do not approach each other while their impulses agree
    (:func:`runs_apart`; ``runs_apart`` is then True; ``halving`` holds every comparison), or
    where a step eight times shorter did not halve the runs' difference (:func:`halving_stalled`).
    ``progress`` is told where each run is (:class:`LandingProgress`; a run that diverged is
    followed by one at a shorter step, and an implicit run that ``auto`` chose and whose steps
    overran their budget, or fell behind RK4's stable step (:data:`RK4_PACE`), by one of RK4 at its
    stable step, :meth:`_Landing.stable_step`, or where the first step is over AUTO_RADAU / rate,
    by one of Radau IIA from that first step, :data:`AUTO_RADAU`).

    Raises:
        ModelError: no ``scene.duration``, or joint laws that do not match the tree.
        NumericalError: the integration diverged or chattered, or no consistent contact forces.
    """
    if scene.duration is None:
        raise ModelError("scene.duration: the whole landing needs a duration (s)")
    if joints and len(joints) != tree.n_bodies:
        raise ModelError(f"joints: {len(joints)} joint laws for {tree.n_bodies} bodies")
    run = _Landing(tree, scene, joints, settings, space)
    h, switch = run.first_step(), ""
    if run.method == IMPLICIT and settings.integrator == AUTO:  # RK4 where ROS2's split steps fall behind it
        run.rk4_pace = run.stable_step()
    for halvings in range(settings.max_refinements + 1):  # a step too long for the stiffest joint diverges
        try:
            previous = run.run(h, progress, halvings)
            run.rk4_pace = None
            break
        except Diverged as e:
            if halvings == settings.max_refinements:
                raise
            if e.reached > 0 and run.method == IMPLICIT and settings.integrator == AUTO:
                stiff = run.first_step() * run.rate > AUTO_RADAU  # Radau IIA from ROS2's first step, else RK4
                run = _Landing(tree, scene, joints, replace(settings, integrator=RADAU if stiff else RK4), space)
                h, switch = run.first_step() if stiff else run.stable_step(), str(e)
                continue
            h /= retry_factor(e.reached)
    error, halving, apart = math.inf, [], False
    current, share = previous, 1.0
    for k in range(settings.max_refinements):
        h /= 2.0
        if k + 1 < settings.max_refinements and split_alike_at_half(previous):
            # the run at h would be the last one over again (the balance split its steps alike):
            # go on as after such a pair, at half that step and a smaller share (balance_order)
            h /= 2.0
            share /= 2.0**run.balance_order
        current = run.run(h, progress, halvings + 1 + k, share=share)
        # runs whose steps the momentum balance split alike (all of them: an unstable RK4 step;
        # most of them, DISTINCT_RUNS) are one run: their difference says little, the halving goes
        # on, the next run asking the balance for a smaller share (balance_order)
        distinct = current.n_steps >= DISTINCT_RUNS * previous.n_steps
        differences = landing_differences(current, previous) if distinct else None
        error = math.inf if differences is None else max(differences)  # landing_difference, once
        if error <= settings.tolerance:
            break
        if differences is not None:
            halving.append((previous.step, current.step, *differences))
            apart = runs_apart(halving)
            if apart or halving_stalled(halving):  # no further halving would converge them at its cost
                break
        else:
            share /= 2.0**run.balance_order
        previous = current
    return replace(current, error_estimate=error, tolerance=settings.tolerance, integrator_switch=switch,
                   halving=tuple(halving), runs_apart=apart)


__all__ = [
    "AUTO",
    "BALANCE_CHECK",
    "IMPLICIT",
    "MAX_EVENTS",
    "RK4",
    "RK4_STABLE",
    "AUTO_IMPLICIT",
    "DISTINCT_RUNS",
    "MODEL_NAME",
    "MIN_BOUNCE",
    "PLASTIC_SPEED",
    "SETTLE_SPEED",
    "LandingEvent",
    "LandingProgress",
    "LandingResult",
    "LandingSettings",
    "landing",
    "landing_difference",
    "landing_differences",
    "runs_apart",
    "halving_stalled",
    "STALL_FRACTION",
    "STALL_STEPS",
    "stall_start",
    "POSTURE_SPREAD",
    "IMPULSES_AGREE",
    "split_alike_at_half",
    "retry_factor",
    "joint_law_rate",
    "landing_function",
    "RigidImpact",
    "contact_impulses",
    "impact_modes",
    "rigid_impact",
]
