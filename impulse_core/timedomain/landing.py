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
* Identical toes (twins: sibling subtrees equal in everything but their names, with equal joint
  laws) move alike in the exact landing; after every event their angles and velocities are set
  to their mean (:meth:`_Landing.twinned`), so that rounding does not part them (in the plane n
  of them then land as one toe of n times the mass, stiffness and damping); also
  after every accepted step and at a located event, where the mode treats them alike
  (:meth:`_Landing.held_alike`: the integrators' rounding parts them, and an impact on both at
  once can be ill-conditioned in their parting).

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

import math
from dataclasses import replace

import numpy as np

from impulse_core.errors import ModelError, NumericalError
from impulse_core.kinematics.spatial import PLANAR, Space
from impulse_core.model.joints import JointLaw
from impulse_core.model.tree import Scene, Tree
from impulse_core.timedomain.compliant import relative_difference
from impulse_core.timedomain.events.forces import contact_impulses
from impulse_core.timedomain.events.impact_law import RigidImpact, impact_modes, rigid_impact
from impulse_core.timedomain.events.point import joint_law_rate, landing_function
from impulse_core.timedomain.events.results import LandingEvent, LandingResult
from impulse_core.timedomain.events.run import _Landing
from impulse_core.timedomain.events.settings import (
    AUTO, AUTO_CODE, AUTO_IMPLICIT, AUTO_RADAU, BALANCE_CHECK, BALANCE_TOLERANCE, C_CODE, DISTINCT_RUNS, IMPLICIT,
    IMPULSES_AGREE, LANDING_STEPS, MAX_EVENTS, MIN_BOUNCE, MODEL_NAME, NUMPY_CODE, PLASTIC_SPEED, POSTURE_SPREAD,
    RADAU, RK4, RK4_STABLE, SETTLE_SPEED, VM_CODE, Diverged, LandingProgress, LandingSettings, PainleveParadox,
    Progress, RadauTries, balance_share, retry_factor,
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


def fastest_joint_law(run: _Landing) -> tuple[int, str, float, float]:
    """The joint law whose rate at touchdown is the fastest of ``run``'s (:func:`joint_law_rate`, each
    law on its own: a damper's D / m, a spring's sqrt(K / m), m the inertia its joint moves,
    1 / (M^-1)_jj): (its body's index, ``stiffness`` or ``damping``, the law's value, its rate, 1/s)."""
    M = run.mass_matrix_at(run.q0)
    w, V = np.linalg.eigh(M)
    inverse = np.diag((V / np.maximum(w, np.finfo(float).eps * w[-1])) @ V.T)  # M^-1's diagonal, floored
    D, K = run.joints.damping, run.joints.stiffness
    rates = np.stack([D * inverse, np.sqrt(np.maximum(K * inverse, 0.0))])
    law, j = np.unravel_index(int(np.argmax(rates)), rates.shape)
    return int(run.joints.dof_body[j]), ("damping", "stiffness")[law], float((D, K)[law][j]), float(rates[law, j])


def follows_oscillation(run: _Landing) -> None:
    """Refuse, before any run, a landing whose fastest joint law is a spring (its frequency above its
    damper's rate: an oscillation that the joint's damping does not end within a period) that RK4
    at its stable step cannot follow within :data:`LANDING_STEPS` (:func:`afford`): ROS2 and Radau
    IIA would land it, but with that oscillation damped away (the case-3 leg over 5 ms with a heel
    of 1e12 N m/rad: 0.413 N s of peak impulse on Radau, 0.5124 on RK4), and ``auto`` tries them
    first, the step halving's retries on the way (that leg over 0.3 s: minutes before RK4 was refused).

    Raises:
        ModelError: as :func:`afford`'s, naming the spring.
    """
    if fastest_joint_law(run)[1] == "stiffness":
        afford(run, None)


def _law_units(name: str) -> str:
    return "N m/rad" if name == "stiffness" else "N m s/rad"


def fastest_law_text(run: _Landing) -> str:
    """:func:`fastest_joint_law` in words: "heel's joint stiffness 1e+12 N m/rad (rate ... 1/s at touchdown)"."""
    b, name, value, rate = fastest_joint_law(run)
    return f"{run.tree.bodies[b].name}'s joint {name} {value:.3g} {_law_units(name)} (rate {rate:.3g} 1/s at touchdown)"


def afford(run: _Landing, h: float | None, cause: str = "") -> None:
    """Refuse a run of ``run``'s landing at step ``h`` where it and the step halving's first finer run
    would take over :data:`LANDING_STEPS` steps between them (3 x duration / h at least; h None:
    RK4 from its stable step, :func:`follows_oscillation`): as a
    ModelError naming the fastest joint law where RK4 at its stable step would too (the joint's
    rate sets the step: a spring so stiff that only RK4 follows its oscillation), else as a
    NumericalError with ``cause``, the failure that shortened the step this far.

    Raises:
        ModelError: the fastest joint law, its value and rate, and what would fit.
        NumericalError: ``cause``, the steps the run would take, and the fastest joint law.
    """
    T = float(run.scene.duration)
    planned = math.inf if h is None else 3.0 * T / h
    needed = 3.0 * T * run.rate / RK4_STABLE  # RK4 from its stable step, and the first halving
    if (needed if h is None else planned) <= LANDING_STEPS:
        return
    b, name, value, rate = fastest_joint_law(run)
    unit, law = _law_units(name), fastest_law_text(run)
    if needed > LANDING_STEPS:
        fits = value * (LANDING_STEPS / needed) ** (2 if name == "stiffness" else 1)
        damps = " (only an explicit step follows the joint's oscillation after an impact: ROS2 and Radau IIA " \
            "damp it away)" if name == "stiffness" else ""
        raise ModelError(
            f"model.bodies[{b}].{name}: {law}: RK4's stable step is {RK4_STABLE / run.rate:.3g} s{damps}, and over the "
            f"{T:.3g} s landing that and the step halving's first check take {needed:.3g} steps, over the "
            f"{LANDING_STEPS} a landing may plan; at most {fits:.3g} {unit} fits (or a shorter scene.duration)")
    raise NumericalError(
        f"the landing would take over {planned:.3g} steps at step {h:.3g} s, over the {LANDING_STEPS} it "
        f"may plan ({cause or 'the step asked for'}; the fastest joint law: {law})")


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
    Between events each run's steps keep the momentum balance within a budget
    (:data:`MOMENTUM_BALANCE`, set for the default tolerance 1e-3); below 1e-3 the budget shrinks
    with the tolerance (:func:`balance_share`: tolerance / 1e-3 of it), since runs at h and h / 2
    split alike by one budget agree while both sit off the limit by its error, which the
    estimate does not see (random file 70037: estimate 1e-7, error 3.2e-5 with the default
    budget). So below 1e-3 the finer run of every pair asks a share smaller by 2^p than the
    coarser's (p: the integrator's ``balance_order``, RK4 4) wherever the balance split any of
    the coarser's steps (:attr:`_Landing.balance_splits`): those steps are then halved with the
    rest, and the pair's difference, the estimate, includes their error (random file 70025 at
    1e-5: estimate 1.5e-10 against an error of 1.1e-8 before, now 1.05e-8 against 7e-10; 70002 with
    slow-slip splits off: 1.7e-11 against 3.9e-6 before). Radau IIA's pairs do so at every
    tolerance: its steps are long (h x rate over AUTO_RADAU), the balance splits them in the stiff
    transients, and its runs split alike there agreed away from the limit at 1e-3 (the landing
    study's trial 371, ``tests/impulse_core/data/radau_split_alike_371.yaml``: estimate 6.9e-8,
    error 2.9e-3). A landing whose balance split no step is unchanged to the bit, as is every
    landing at 1e-3 and above on RK4 or ROS2. ``progress`` is told where each
    run is (:class:`LandingProgress`; a run that diverged is
    followed by one at a shorter step, and an implicit run that ``auto`` chose and whose steps
    overran their budget, or fell behind RK4's stable step (:data:`RK4_PACE`), by one of RK4 at its
    stable step, :meth:`_Landing.stable_step`, or where the first step is over AUTO_RADAU / rate,
    by one of Radau IIA from that first step, :data:`AUTO_RADAU`, whose run gives way to RK4 at its
    stable step in turn where its tries fall behind that step or overrun their budget:
    :meth:`_Landing.check_budget`). No run starts that, with the step halving's first finer run,
    would take over :data:`LANDING_STEPS` steps (:func:`afford`), and with ``auto`` or ``rk4``
    a landing whose fastest joint law is a spring that RK4 could not follow so is refused before
    any run (:func:`follows_oscillation`).

    Raises:
        ModelError: no ``scene.duration``, joint laws that do not match the tree, or a joint law
            that RK4 could not follow within LANDING_STEPS (naming it: ``model.bodies[i].stiffness``).
        NumericalError: the integration diverged or chattered, no consistent contact forces, or a
            retry at a step so short that its runs would take over LANDING_STEPS steps.
    """
    if scene.duration is None:
        raise ModelError("scene.duration: the whole landing needs a duration (s)")
    if joints and len(joints) != tree.n_bodies:
        raise ModelError(f"joints: {len(joints)} joint laws for {tree.n_bodies} bodies")
    run = _Landing(tree, scene, joints, settings, space)
    h, switch, share = run.first_step(), "", balance_share(settings.tolerance)
    auto = settings.integrator == AUTO
    if settings.integrator in (AUTO, RK4):  # before ROS2 and Radau IIA damp a stiff spring's oscillation away
        follows_oscillation(run)
    if run.method == IMPLICIT and auto:  # RK4 where ROS2's split steps fall behind it
        run.rk4_pace = run.stable_step()
    cause = ""
    for halvings in range(settings.max_refinements + 1):  # a step too long for the stiffest joint diverges
        afford(run, h, cause)
        try:
            previous = run.run(h, progress, halvings, share=share)
            run.rk4_pace = None
            break
        except Diverged as e:
            if halvings == settings.max_refinements:
                raise
            cause = str(e)
            if isinstance(e, RadauTries) and not auto:  # a shorter step does not help (RadauTries)
                raise NumericalError(
                    f"{e}; a shorter step would not help: its iterations fail where the fastest joint law "
                    f"({fastest_law_text(run)}) is far beyond the step (h x rate {h * fastest_joint_law(run)[3]:.3g}); "
                    "integrator auto or rk4 follows it") from None
            if e.reached > 0 and auto and run.method in (IMPLICIT, RADAU):
                # Radau IIA from ROS2's first step, else (and where Radau IIA gives way too) RK4
                stiff = run.method == IMPLICIT and run.first_step() * run.rate > AUTO_RADAU
                run = _Landing(tree, scene, joints, replace(settings, integrator=RADAU if stiff else RK4), space)
                h, switch = run.first_step() if stiff else run.stable_step(), str(e)
                if stiff:  # RK4 where Radau IIA's tries fall behind it (RK4_PACE)
                    run.rk4_pace = run.stable_step()
                continue
            h /= retry_factor(e.reached)
    error, halving, apart = math.inf, [], False
    current, splits, fine = previous, run.balance_splits, settings.tolerance < BALANCE_TOLERANCE
    for k in range(settings.max_refinements):
        h /= 2.0
        if k + 1 < settings.max_refinements and split_alike_at_half(previous):
            # the run at h would be the last one over again (the balance split its steps alike):
            # go on as after such a pair, at half that step and a smaller share (balance_order)
            h /= 2.0
            share /= 2.0**run.balance_order
        elif (fine or run.method == RADAU) and splits and share == previous.share:
            # below the default tolerance, and on Radau IIA at any, where the balance split any of
            # the coarser run's steps, the finer asks a smaller share, so that those steps are
            # halved too and the pair's difference sees their error (balance_order; random file
            # 70037 at 1e-5; on Radau at 1e-3 the landing study's trial 371: runs split alike
            # before its peak impact agreed to 6.9e-8 while 2.9e-3 off, now 9.7e-4 and within it)
            share /= 2.0**run.balance_order
        current = run.run(h, progress, halvings + 1 + k, share=share)
        splits = run.balance_splits
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
    "balance_share",
    "retry_factor",
    "joint_law_rate",
    "fastest_joint_law",
    "afford",
    "follows_oscillation",
    "LANDING_STEPS",
    "landing_function",
    "RigidImpact",
    "contact_impulses",
    "impact_modes",
    "rigid_impact",
    "Diverged",
    "PainleveParadox",
    # what LandingSettings is told (its integrator and step_code) and landing()'s progress callback
    "RADAU",
    "AUTO_CODE",
    "C_CODE",
    "NUMPY_CODE",
    "VM_CODE",
    "Progress",
]

