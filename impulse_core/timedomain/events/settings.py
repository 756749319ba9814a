"""What a whole landing is asked: its settings (:class:`LandingSettings`), the engine's constants,
its errors and progress reports; the lowest module of :mod:`impulse_core.timedomain.events`."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from impulse_core.errors import NumericalError


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
#: The finest tolerance a landing accepts: below, rounding keeps two runs from agreeing and the
#: step halving never ends (1e-14 on a 10 ms landing ran for ever; 1e-12 takes 3 s).
MIN_TOLERANCE = 1e-12
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
#: each step is halved until its own residual is below its share (its length over the duration),
#: at tolerances of BALANCE_TOLERANCE and above (below it the budget shrinks with the tolerance).
MOMENTUM_BALANCE = 2e-5
#: The tolerance MOMENTUM_BALANCE is set for (the default ``--tolerance``): a landing asked a
#: finer tolerance gives its steps a share of the budget smaller in proportion (:func:`balance_share`),
#: as runs at h and h / 2 split alike by one budget agree while both sit off the limit by its
#: error (random file 70037 with this budget, at tolerances 1e-3 and 1e-5 alike: estimate 1e-7,
#: error 3.2e-5, above the latter; ``studies/whole_landing/tolerance_check_1e-05.md``).
BALANCE_TOLERANCE = 1e-3
#: Two successive runs of the step-halving estimate count as two only where the finer took at
#: least this many times the coarser's steps: where the momentum balance splits most steps alike
#: in both, their difference understates the error (random file 30113 on ROS2: runs of 2855 and
#: 2858 steps differed by 1.4e-6 while the finer was 1.6e-5 from the converged answer), and the
#: halving goes on.
DISTINCT_RUNS = 1.1
#: Halvings of the nominal step for the momentum balance (a step that short is taken as it is).
MAX_SPLITS = 14
#: Halvings of the nominal step for a slow sliding contact in space, where
#: :attr:`LandingSettings.slip_splits` asks for them (:meth:`_Landing.slip_length`; the default):
#: a step whose regularisation core (:meth:`_Landing.steer`, proportional to the step) would
#: exceed a sliding contact's slip speed is halved down to h / 2^SLIP_SPLITS, below which the
#: regularised direction takes over. Random file 61600 (a 32 g rod sliding at 0.13 to 2.8 m/s
#: after touchdown, core 4 to 8 m/s at h = 1.1e-4 s): with the direction regularised on every
#: step, the core's first-order error made the runs' differences fall at first order (8.4e-2
#: ... 4.1e-4 down to h / 128, 655 s); split (up to 2^8 at h), its runs at h and h / 2 differ
#: by 9e-8.
SLIP_SPLITS = 10
#: A slow slip is split (:data:`SLIP_SPLITS`) only where it turns: its acceleration across its
#: line above this fraction of its acceleration. The regularised direction of a slip that keeps
#: its line is s / |s| exactly, and a planar leg read in space lands on the plane's steps.
SLIP_TURN = 1e-6
#: Steps per step of the run's nominal length after which a run no longer splits slow slips
#: (:data:`SLIP_SPLITS`; a quarter of :data:`STEP_BUDGET`): a slip slower than its split steps
#: can follow for long (random file 30891: 2e-6 m/s, turning past a right angle every 1e-7 s,
#: a stall that the run bridges) is regularised as before, and its run stays within budget.
SLIP_BUDGET = 16
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
#: terms (the momenta at both ends and their terms, the contact impulses, the weight's:
#: :meth:`_Landing.balance_rounding`) is rounding's: shorter
#: steps do not shrink it (random file 32787's run at h / 64, its share of the balance 1 / 4096:
#: after a 55 g rod's tip stuck, residuals of 6e-16 to 1e-14 N s, up to 3.5 eps times the tree's
#: 12.5 N s, at h / 2^13 and h / 2^14 alike, above their shares of 9e-16 and 5e-16 N s: the steps
#: stayed at those lengths, some 1e8 of them for the landing's rest). Such a step is taken, held
#: to that level as to its share: its successor doubles where 2^p times its residual is within it
#: (:meth:`_Landing.balanced_step`); summed over a run's step budget
#: (STEP_BUDGET per nominal step: 8e5 steps at h / 2^7 from duration / 100) these residuals come
#: to about 3e-9 of the momenta (4e-7 where the terms are 130 times the momentum, as random file
#: 70025's in flight), far below the balance's own bound (MOMENTUM_BALANCE).
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
#: The steps a landing may plan (:func:`~impulse_core.timedomain.landing.landing`): a run at step h
#: and the step halving's first finer run take at least 3 x duration / h steps between them, and a
#: run is not started where that is over this. RK4's stable step shrinks as 1 / the joint laws'
#: fastest rate, so a stiff joint with little damping, whose oscillation after every impact only
#: an explicit step resolves (ROS2 and Radau IIA damp it away: the case-3 leg over 5 ms with a
#: heel of 1e12 N m/rad landed on Radau with a peak impulse of 0.413 N s, on RK4 at its stable step
#: 0.5124, as at 1e8 and 1e10 N m/rad), would otherwise run for hours: that leg's 5 ms take
#: 2.9e5 steps (33 s), over its 0.3 s 1.7e7 (refused). A run retried at a far shorter step after
#: its steps overran their budget (:func:`~impulse_core.timedomain.landing.retry_factor`) is held
#: to it too.
LANDING_STEPS = 2**19
#: A Radau IIA run is abandoned as a run that overran :data:`STEP_BUDGET` once its tries (steps
#: tried, pieces of split steps and the balance's rejections included: :attr:`_Landing.radau_tries`)
#: exceed this many times that budget (a run cut to 9 ms of random file 33096 at the full file's
#: step: 198 steps of a budget of 256, in more tries than that).
RADAU_TRIES = 4
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
#: faster but unconverged (estimate 0.25, RK4's 6.7e-4), 32700 (44.7) 1.6 x slower: it stayed 100.
#: It is 32 since Radau IIA holds twin toes alike (:meth:`_Landing.held_alike`): on the landing
#: study's 16 of 384 designs below 100 whose ROS2 run gave way (h x rate 32.4 to 97.8;
#: ``studies/whole_landing/stiff_designs.md``, 2026-11-28, branch ``twins``) Radau IIA lands every
#: one within its estimate and within 1.9e-6 of an RK4 reference at a quarter of the finest step
#: (trial 64, twin toes on their stops at once: 0.33 off before, with an estimate of 8e-8), and
#: ``auto`` at 32 (ROS2's run before the switch included) takes 20.8 s of CPU where at 100 it took
#: 104.5 s (5.0 x; 2.7 to 16 x a design). The two files that held it at 100, landed again on the
#: same day (Radau IIA since b0d5865's shares; CPU of one run each): 32700 (44.7) 1.9 x faster
#: than on RK4 (19.9 s against 37.7 s), 6.1e-6 from RK4's answer (estimate 3.5e-4); 33491 (66.2)
#: 1.7e-4 from RK4 at its stable step / 32 (that and / 16: 4.9e-7 apart), its estimate 1.1e-3.
#: 32507 (76.3) and 60113 (88.5) as above (60113 ends in one of two postures on either
#: integrator; Radau's estimate says so). 32: below the least h x rate measured (the study's 32.4);
#: none of the study's 384 designs had ROS2 give way between AUTO_IMPLICIT's 16 and it.
AUTO_RADAU = 32.0
#: Space: beyond this |phi| (rad) the base's rotation coordinates are re-centred on its current
#: orientation (:meth:`_Landing.rechart`), far inside the chart's good region (singular at
#: |phi| = 2 pi), so a base may turn any number of times.
RECHART = 3.0
#: Events shorter than REPEAT_SPAN (s, times the duration where that is longer than 1 s) that
#: each give back the mode they stopped (:func:`_same_kind`), more than REPEATS in a row, are a
#: stall (:meth:`_Landing.stall_message`) as events shorter than 1e-12 s are: the mode fails at
#: once again each time (random file 30891: two contacts starting to slide from rest, an event
#: every 4e-12 s, each with two failed slip searches of 0.4 s, for hours). So are, whatever
#: their length, such events whose arrest was refused (:attr:`_Landing.refused`: a slow slip
#: turned that friction cannot stop, the same one each time; 30891 again: an event every 1e-7
#: s, 7e5 to its end).
REPEAT_SPAN = 1e-9
REPEATS = 50


class Diverged(NumericalError):
    """The integration blew up, or its steps overran their budget (the momentum balance split them):
    the step is too long for the model's fastest motion; :func:`landing` shortens it
    (:func:`retry_factor`). ``reached``: the fraction of the duration a run reached when its steps
    overran their budget (0: it blew up)."""

    def __init__(self, message: str, reached: float = 0.0) -> None:
        super().__init__(message)
        self.reached = reached


class RadauTries(Diverged):
    """A Radau IIA run whose tries overran their budget (:data:`RADAU_TRIES`): where ``auto`` chose
    Radau IIA, :func:`landing` goes on with RK4 from its stable step; asked for, the landing fails,
    as a shorter step does not bring its Newton iterations back (the case-3 leg with a heel of 1e12
    N m/rad: runs at h / 8 and h / 32 crawled alike, 36 s and over 140 s of CPU)."""


class _Jams(Exception):
    """A run stopped by Painleve's paradox before the landing took impulsive jams
    (:meth:`_Landing.run` then starts it again taking them); ``failure``: the error it stopped with."""

    def __init__(self, failure: NumericalError) -> None:
        super().__init__(str(failure))
        self.failure = failure


class _Unjammed(NumericalError):
    """A jam taken, and the paradox still there after it, whose next jam cannot be taken
    (:meth:`_Landing.resolve_or_jam`): ``failure``'s message, and the state and mode after the jam
    taken, from which :meth:`_Landing.jam_or_bridge` bridges (uncaught, it is ``failure``)."""

    def __init__(self, failure: NumericalError, q, v, mode) -> None:
        super().__init__(str(failure))
        self.failure, self.q, self.v, self.mode = failure, q, v, mode


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
        slip_splits: k > 0 (default :data:`SLIP_SPLITS` = 10): a step from where a turning slip
            in space is slow for it (:meth:`_Landing.steer`'s core above its slip speed) is halved,
            down to h / 2^k, so that the exact law s / |s| holds at its start
            (:meth:`_Landing.slip_length`: random file 61600 converges at its first halving, 8.8 s,
            instead of at h / 128, 655 s), or 0: the direction is regularised on every such step,
            an error of first order in the step (the runs some tests pin: a coarse run that
            diverged). The derivatives replay the run's splits (``landing_derivatives``).
    """

    tolerance: float = 1e-3
    step: float | None = None
    max_refinements: int = 7
    gap_tolerance: float = 1e-12
    max_events: int = MAX_EVENTS
    integrator: str = AUTO
    step_code: str = VM_CODE
    bounce_steps: float = 0.0
    slip_splits: int = SLIP_SPLITS


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


def balance_share(tolerance: float) -> float:
    """The share of the momentum balance's budget (:data:`MOMENTUM_BALANCE`) that :func:`landing`'s
    first run asks of its steps at ``tolerance``: 1 up to :data:`BALANCE_TOLERANCE` (the default
    tolerance, its landings unchanged to the bit), tolerance / BALANCE_TOLERANCE below it, so that
    the error the budget leaves (unseen by the step halving where it splits the runs' steps alike)
    shrinks with the tolerance: random file 70037, 1.6 x the budget. Not a bound: the budget holds
    the momentum, not the angles (random file 70002 at 1e-5: 3.9e-6 off, its share 2.4e-6).
    Each run of the halving starts from it (and shrinks it after runs split alike, and below
    BALANCE_TOLERANCE for the finer run of a pair whose coarser run the balance split,
    :func:`landing`, so that the estimate sees the budget's error)."""
    return min(1.0, tolerance / BALANCE_TOLERANCE)
