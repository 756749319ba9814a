"""The compliant rung integrated adaptively: Dormand-Prince 5(4) steps between located contact
switches (``--model compliant`` without ``--steps-per-period``).

The fixed-step scheme (:func:`impulse_core.timedomain.compliant.simulate_impact`) is first order
because the contact force is not smooth where a contact touches down or stops pushing, and those
instants fall between its steps. Here they are steps' ends.

State. y = (q, v, p, P): configuration and rates (q' = v, as in the fixed-step rung), the normal
impulses p (p' = f, the normal forces) and the impulse vectors P (d x n_c, P' = n_i f_i). The
impulses are states, so the step-size control holds them to the same tolerance as the motion.
The joint impulses (the fixed-step rung's: each subtree's momentum rate minus the contact and
gravity forces on it, integrated while some contact pushes) are that integral done exactly: the
subtrees' momentum changes over the intervals in which some contact pushes (their ends are
events), minus the contact impulses on each subtree and gravity's over those intervals.

Modes and events. Which contacts push is the *mode*; within a mode the contact law is smooth:
``PENALTY``: f_i = -k g_i - c_i g_i' for the pushing contacts (unclipped), 0 for the others;
``CONSTRAINT``: the pushing set S solves (A + R)_SS f_S = (a_ref - a_0)_S, the others 0. The mode
changes only where an event function changes sign: each contact's gap g_i (touchdown, leaving the
ground) and, while it touches, its switch s_i (penalty: -k g_i - c_i g_i'; constraint: f_i inside
S, -w_i outside it, w = (A + R) f - (a_ref - a_0), complementary to f). A contact pushes while
g_i < 0 and s_i > 0. Each step's end is checked for sign changes; the first change is located by
the Illinois variant of regula falsi on the step length itself (each trial one Dormand-Prince
step, so the event lands on the integrated trajectory, to a bracket of a few ulps of t) and the
step is cut there. Every step then integrates a smooth right-hand side and keeps its fifth order.
Sign changes inside a step that undo themselves by its end (a graze) are not seen.

Step size. Per step, e = max over components |y5 - y4| / (tau * scale): scale = v0 / omega_max
(a penetration) for q, v0 (the approach speed) for v, total mass x v0 for the impulses, so tau is
relative to the impact's own scales; the step is accepted when e <= 1 and the next is
h * clip(0.9 e^(-1/5), 0.2, 5), at most one contact period. Each Dormand-Prince step is one
compiled CasADi function (six evaluations of the dynamics inlined; the seventh is the next
step's first, FSAL).

Error estimate (:func:`adaptive_to_tolerance`). A local tolerance tau bounds each step's error, not
the impulses'. The rung runs at tau and at tau / :data:`REFINEMENT` and reports the finer run with
the relative difference of the two (``compliant_difference``) as ``error_estimate``; if it exceeds
the tolerance, tau is divided again. The global error scales about like tau (measured: 0.03 tau
on the uneven-terrain example), so that difference is about (REFINEMENT - 1) x the finer run's
error: an estimate from above, 1.2 to 3.8 times the true error in the measured cases (the example
at 1e-3 to 1e-5, studies/fidelity/tolerance_cost.md; random trees, both laws:
tests/impulse_core/test_compliant_adaptive.py), not a bound.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace

import casadi as ca
import numpy as np

from impulse_core.errors import ModelError, NumericalError
from impulse_core.kinematics.spatial import PLANAR, Space, values_space
from impulse_core.model.heightfield import Heightfield
from impulse_core.model.terrain import Terrain
from impulse_core.model.tree import Scene, Topology, Tree, design_vector
from impulse_core.timedomain.compliant import (
    BufferedFunction,
    CompliantResult,
    CompliantSettings,
    CompliantStatus,
    ContactLaw,
    _check_chart,
    _contact_parameters,
    _End,
    _result,
    _Run,
    _setup,
    _Tally,
    _touchdown_state,
    compliant_difference,
    damping_ratio_for_restitution,
    expressions,
    landing_ground,
    normal_terms,
    tune_damping,
)

#: Dormand-Prince 5(4): the stages' coefficients (row i: a_i1 .. a_i,i-1), the fifth-order weights
#: (= the last row: FSAL) and the difference of the fifth- and fourth-order weights.
DOPRI_A = (
    (),
    (1 / 5,),
    (3 / 40, 9 / 40),
    (44 / 45, -56 / 15, 32 / 9),
    (19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729),
    (9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656),
    (35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84),
)
DOPRI_E = (71 / 57600, 0.0, -71 / 16695, 71 / 1920, -17253 / 339200, 22 / 525, -1 / 40)
#: Each refinement divides the local tolerance by this; the error estimate compares two runs.
REFINEMENT = 4.0
#: The first run's local tolerance per unit of the requested one: the two runs' difference is then
#: about a third of the requested tolerance on the uneven-terrain example (global error ~0.03 tau).
LOCAL_TOLERANCE = 16.0
#: The finest local tolerance: below it the positions' rounding (1e-16 m on 1 m) is the error.
LOCAL_FLOOR = 1e-12
#: The integrator's name in the result (``CompliantResult.integrator``, the JSON's ``integrator``).
INTEGRATOR = "dopri5"
#: Events are located to a bracket of this many contact periods (about 1e-16 s at 1e8 1/s^2, a
#: gap of a few 1e-16 m at the approach speed: the rounding of the positions themselves).
EVENT_RESOLUTION = 1e-13
#: Accepted steps after which a run stops with a NumericalError (chattering events).
MAX_STEPS = 200_000

_RHS_INPUTS = ("mode", "damping", "law", "p", "gravity")


@dataclass(frozen=True)
class StateLayout:
    """Where each part of y sits: q, v (nv each), p (n_c), P (d n_c, contact-major)."""

    nv: int
    nc: int
    d: int

    @property
    def impulse(self) -> slice:
        return slice(2 * self.nv, 2 * self.nv + self.nc)

    @property
    def impulse_vector(self) -> slice:
        return slice(self.impulse.stop, self.impulse.stop + self.d * self.nc)

    @property
    def size(self) -> int:
        return self.impulse_vector.stop


def state_layout(topology: Topology, space: Space) -> StateLayout:
    x = expressions(topology, space)
    return StateLayout(x.q.shape[0], x.contacts.shape[1], x.dims)


def _contact_forces(x, gap, Jn, minv_jnt, mode, damping, law, penalty: bool) -> tuple[ca.SX, ca.SX]:
    """The normal forces f in ``mode`` and the switches s (module docstring), as expressions."""
    rate = Jn @ x.v
    if penalty:
        raw = -law[0] * gap - damping * rate
        return mode * raw, raw
    k, b, d = law[0], law[1], law[2]
    A = Jn @ minv_jnt
    H = A + ca.diag((1 - d) / d * ca.diag(A))
    rhs = -(b * rate + k * gap) / d - Jn @ x.free_acceleration
    pushing = ca.diag(mode)
    f = ca.solve(pushing @ H @ pushing + ca.diag(1 - mode), mode * rhs)
    w = H @ f - rhs
    return f, mode * f - (1 - mode) * w


@functools.lru_cache(maxsize=64)
def rate_function(
    topology: Topology, terrain: Terrain | Heightfield, law: ContactLaw, space: Space = PLANAR
) -> ca.Function:
    """dy/dt in a mode, as a CasADi function of (y, mode, damping, law, p, gravity)
    (law = (k, b, impedance): the constraint law's; the penalty law's k first), with the event
    functions (gaps, then switches), the gaps' rates and the kinetic energy at y."""
    x = expressions(topology, space)
    lay = state_layout(topology, space)
    gap, N, Jn, minv_jnt = normal_terms(x, terrain, space)
    mode, damping = ca.SX.sym("mode", lay.nc), ca.SX.sym("damping", lay.nc)
    law_constants = ca.SX.sym("law", 3)
    f, switch = _contact_forces(x, gap, Jn, minv_jnt, mode, damping, law_constants, law is ContactLaw.PENALTY)
    a = x.free_acceleration + minv_jnt @ f
    F = N @ ca.diag(f) if lay.nc else ca.SX(lay.d, 0)
    tail = ca.vertcat(a, f, ca.vec(F))
    inner = ca.Function(
        "inner", [x.q, x.v, mode, damping, law_constants, x.p, x.gravity],
        [tail, ca.vertcat(gap, switch), Jn @ x.v, x.kinetic_energy],
    )
    y = ca.SX.sym("y", lay.size)
    rest = [ca.SX.sym(n, inner.size1_in(k + 2)) for k, n in enumerate(_RHS_INPUTS)]
    out = inner(y[: lay.nv], y[lay.nv : 2 * lay.nv], *rest)
    ydot = ca.vertcat(y[lay.nv : 2 * lay.nv], out[0])
    return ca.Function(
        "compliant_rate", [y, *rest], [ydot, *out[1:]], ["y", *_RHS_INPUTS], ["ydot", "events", "rate", "kinetic"]
    )


@functools.lru_cache(maxsize=64)
def dopri_step(
    topology: Topology, terrain: Terrain | Heightfield, law: ContactLaw, space: Space = PLANAR
) -> ca.Function:
    """One Dormand-Prince 5(4) step as a CasADi function of (y, k1 = dy/dt at y, h, mode, ...:
    :func:`rate_function`'s inputs): the fifth-order y(h), its difference from the fourth-order
    one, dy/dt there (the next step's k1) and the events, gap rates and kinetic energy there."""
    rate = rate_function(topology, terrain, law, space)
    y, k1, h = ca.SX.sym("y", rate.size1_in(0)), ca.SX.sym("k1", rate.size1_in(0)), ca.SX.sym("h")
    rest = [ca.SX.sym(n, rate.size1_in(k + 1)) for k, n in enumerate(_RHS_INPUTS)]
    ks, out = [k1], None
    for row in DOPRI_A[1:]:
        stage = y + h * sum((a * k for a, k in zip(row, ks) if a), ca.SX.zeros(y.shape))
        out = rate(stage, *rest)
        ks.append(out[0])
    error = h * sum((e * k for e, k in zip(DOPRI_E, ks) if e), ca.SX.zeros(y.shape))
    return ca.Function(
        "compliant_dopri5", [y, k1, h, *rest], [stage, error, *out],
        ["y", "k1", "h", *_RHS_INPUTS], ["y5", "error", "ydot", "events", "rate", "kinetic"],
    )


# --------------------------------------------------------------------------------------------
# Integration


@dataclass(frozen=True)
class _Adaptive:
    """What one adaptive run keeps fixed: the compiled step and rate (their argument arrays hold
    the mode and the damping), the layout, the error scales and the step limits."""

    step: BufferedFunction
    rate: BufferedFunction
    layout: StateLayout
    inverse_scale: np.ndarray  # 1 / (tau * scale) per component of y
    period: float  # of the fastest contact oscillation: the largest step
    run: _Run
    tally: _Tally
    loaded_time: np.ndarray  # 1 element: time with some contact pushing, accumulated at the loaded intervals' ends


@dataclass(frozen=True)
class _Modes:
    """The event functions' signs (gaps, then switches; +1 or -1) and the mode they make."""

    sign: np.ndarray  # 2 n_c
    pushing: np.ndarray  # n_c bools

    def update(self) -> None:
        nc = len(self.pushing)
        np.logical_and(self.sign[:nc] < 0, self.sign[nc:] > 0, out=self.pushing)

    def watched(self) -> np.ndarray:
        """Every gap; the switches of the contacts that touch."""
        nc = len(self.pushing)
        return np.concatenate([np.ones(nc, dtype=bool), self.sign[:nc] < 0])


def _buffers(fn: ca.Function, run: _Run, law: np.ndarray, p: np.ndarray) -> BufferedFunction:
    """A :class:`BufferedFunction` of :func:`rate_function` or :func:`dopri_step` with the run's
    constant inputs set."""
    b = BufferedFunction(fn)
    first = fn.n_in() - len(_RHS_INPUTS)
    b.args[first + 2][:] = law
    b.args[first + 3][:] = p
    b.args[first + 4][:] = run.settings.gravity
    return b


def _set_mode(ad: _Adaptive, modes: _Modes) -> None:
    """Copy the mode and the damping into both functions' inputs."""
    for b in (ad.step, ad.rate):
        first = len(b.args) - len(_RHS_INPUTS)
        b.args[first][:] = modes.pushing
        b.args[first + 1][:] = ad.tally.c


def _evaluate_rate(ad: _Adaptive, y: np.ndarray) -> list[np.ndarray]:
    """dy/dt, events, gap rates and kinetic energy at y in the current mode (buffers)."""
    ad.rate.args[0][:] = y
    ad.rate.evaluate()
    return ad.rate.flat


def _try(ad: _Adaptive, y: np.ndarray, k1: np.ndarray, h: float) -> float:
    """One Dormand-Prince step of length h from y (outputs in ``ad.step.flat``): its error norm."""
    args = ad.step.args
    args[0][:] = y
    args[1][:] = k1
    args[2][0] = h
    ad.step.evaluate()
    return float(np.max(np.abs(ad.step.flat[1]) * ad.inverse_scale))


def _locate(ad: _Adaptive, y: np.ndarray, k1: np.ndarray, h: float, u_lo: np.ndarray, u_hi: np.ndarray,
            watched: np.ndarray, sign: np.ndarray, t: float) -> float:
    """The step length, within (0, h], at which the first watched event function changes sign
    (u = events x sign: > 0 before, < 0 after), by Illinois regula falsi on the step length, to a
    bracket of :data:`EVENT_RESOLUTION` contact periods (or a few ulps of t); the step's outputs
    are left in ``ad.step.flat`` (just past it)."""
    lo, hi = 0.0, h
    u_lo = np.where(watched, np.maximum(u_lo, 0.0), 1.0)
    u_hi = np.where(watched, u_hi, 1.0)
    side, at_hi = 0, True
    resolution = max(EVENT_RESOLUTION * ad.period, 4.0 * np.finfo(float).eps * (t + h))
    for iteration in range(60):
        if hi - lo <= resolution:
            break
        crossed = u_hi < 0.0
        root = float(np.min(lo + (hi - lo) * u_lo[crossed] / (u_lo[crossed] - u_hi[crossed])))
        # within half the resolution of an end: half the resolution inside, closing the bracket
        trial = min(max(root, lo + 0.5 * resolution), hi - 0.5 * resolution) if iteration < 30 else 0.5 * (lo + hi)
        _try(ad, y, k1, trial)
        u = np.where(watched, ad.step.flat[3] * sign, 1.0)
        if (u < 0.0).any():
            hi, u_hi, at_hi = trial, u, True
            u_lo = 0.5 * u_lo if side == 1 else u_lo  # Illinois: the same end kept twice
            side = 1
        else:
            lo, u_lo, at_hi = trial, u, False
            u_hi = 0.5 * u_hi if side == -1 else u_hi
            side = -1
    if not at_hi:
        _try(ad, y, k1, hi)
    return hi


def _advance(ad: _Adaptive, y: np.ndarray, ydot: np.ndarray, events: np.ndarray, modes: _Modes, t: float,
             h: float) -> tuple[float, float, bool]:
    """One accepted step from (t, y), outputs in ``ad.step.flat``: its length (cut at the first
    event), the next step's proposed length, and whether it ended on an event."""
    while True:
        e = _try(ad, y, ydot, h)
        if e <= 1.0:
            break
        h *= max(0.2, 0.9 * e**-0.2) if math.isfinite(e) else 0.2
        if h < 1e-12 * ad.period:
            raise NumericalError(f"the adaptive compliant integration could not meet its tolerance at t = {t:.3g} s")
    h_next = h * (min(5.0, 0.9 * e**-0.2) if e > 0 else 5.0)
    watched = modes.watched()
    u_end = ad.step.flat[3] * modes.sign
    crossed = watched & (u_end < 0.0)
    if not crossed.any():
        return h, h_next, False
    nc = ad.layout.nc
    leaving = crossed[:nc] & (modes.sign[:nc] < 0.0) & ~modes.pushing  # a released contact leaves the ground
    if not crossed[nc:].any() and np.array_equal(crossed[:nc], leaving):
        return h, h_next, True  # no force changes there: its sign flips at the step's end
    return _locate(ad, y, ydot, h, events * modes.sign, u_end, watched, modes.sign, t), h_next, True


def _switch(ad: _Adaptive, modes: _Modes, y: np.ndarray, events: np.ndarray, t: float) -> list[np.ndarray]:
    """At an event (y just past it, ``events`` there in the old mode): flip the signs that changed,
    record touchdowns, then the mode and dy/dt in it. A contact that lands takes its switch's sign
    outside the pushing set; switches that disagree with the new mode (the constraint law's
    coupled forces) are flipped too, the ones that just crossed excepted."""
    nc = ad.layout.nc
    flipped = modes.watched() & (events * modes.sign < 0.0)
    modes.sign[flipped] *= -1.0
    landed = flipped[:nc] & (modes.sign[:nc] < 0.0)
    modes.sign[nc:][landed] = np.where(events[nc:][landed] > 0.0, 1.0, -1.0)
    new = landed & ad.tally.untouched
    if new.any():
        nv = ad.layout.nv
        tune_damping(ad.run.evaluate_step(y[:nv], y[nv : 2 * nv]), new, t, ad.run, ad.tally)
    for _ in range(nc + 1):
        modes.update()
        _set_mode(ad, modes)
        out = _evaluate_rate(ad, y)
        wrong = modes.watched() & ~flipped & (out[1] * modes.sign < 0.0)
        if not wrong.any():
            break
        modes.sign[wrong] *= -1.0
    return [a.copy() for a in out]


def _deepest(g0: float, r0: float, g1: float, r1: float, h: float) -> float:
    """The least gap over a step on the cubic Hermite interpolant of its ends' gaps and rates."""
    a, b, c = 2.0 * (g0 - g1) + h * (r0 + r1), 3.0 * (g1 - g0) - h * (2.0 * r0 + r1), h * r0
    roots = np.roots([3.0 * a, 2.0 * b, c]) if abs(a) + abs(b) > 0 else np.array([])
    s = [float(r.real) for r in np.atleast_1d(roots) if abs(r.imag) < 1e-12 and 0.0 < r.real < 1.0]
    return min([g0, g1] + [((a * x + b) * x + c) * x + g0 for x in s])


def _account(ad: _Adaptive, modes: _Modes, t: float, h: float, ydot: np.ndarray, start: tuple[np.ndarray, np.ndarray],
             end: tuple[np.ndarray, np.ndarray]) -> None:
    """A step's bookkeeping: release times of the contacts that pushed, deepest penetrations
    (``start``, ``end``: gaps and rates at the step's ends), the force profile."""
    tally, nc = ad.tally, ad.layout.nc
    tally.release[modes.pushing] = t + h
    touching = (start[0] < 0.0) | (end[0] < 0.0)
    for i in np.flatnonzero(touching):
        g = _deepest(start[0][i], start[1][i], end[0][i], end[1][i], h) if start[1][i] < 0.0 < end[1][i] else end[0][i]
        tally.max_penetration[i] = max(tally.max_penetration[i], -g)
    if ad.run.settings.record:
        tally.times.append(t)
        tally.forces.append(ydot[ad.layout.impulse].copy())


def _finished(ad: _Adaptive, modes: _Modes, rate: np.ndarray, t: float,
              still_since: float | None) -> tuple[CompliantStatus | None, float | None]:
    """After the first touchdown, whether the impact has ended (as the fixed-step rung decides,
    with the settling measured in time: one contact period); with when the contacts came to rest."""
    tally, settings = ad.tally, ad.run.settings
    if tally.untouched.all():
        return None, None
    touching = modes.sign[: ad.layout.nc] < 0.0
    if not modes.pushing.any():
        blocking = rate < 0.0 if settings.follow_recontacts else (rate < 0.0) & (touching | tally.untouched)
        return (None if blocking.any() else CompliantStatus.SEPARATED), None
    if np.abs(rate[touching]).max() < ad.run.settle_speed:
        still_since = t if still_since is None else still_since
        return (CompliantStatus.SETTLED if t - still_since >= ad.period else None), still_since
    return None, None


def _integrate(ad: _Adaptive, y: np.ndarray) -> tuple[_End, np.ndarray, float]:
    """Integrate from the first touchdown (y: q, v, zero impulses) until the impact ends or
    ``max_time``: the end, the final y and the time spent with some contact touching."""
    settings, lay = ad.run.settings, ad.layout
    nc = lay.nc
    modes = _Modes(np.ones(2 * nc), np.zeros(nc, dtype=bool))
    _set_mode(ad, modes)
    ydot, events, rate, kinetic = (a.copy() for a in _evaluate_rate(ad, y))
    modes.sign[:] = np.where(events >= 0.0, 1.0, -1.0)
    t, h, still_since, status = 0.0, ad.period / 20.0, None, CompliantStatus.TIMEOUT
    n_steps = n_flight = 0
    contact_time = 0.0
    while t < settings.max_time:
        h, h_next, event = _advance(ad, y, ydot, events, modes, t, min(h, ad.period, settings.max_time - t))
        out = ad.step.flat
        _account(ad, modes, t, h, ydot, (events[:nc], rate), (out[3][:nc], out[4]))
        touching = bool((events[:nc] < 0.0).any() or (out[3][:nc] < 0.0).any())
        n_steps, n_flight = n_steps + touching, n_flight + (not touching)
        contact_time += h if touching else 0.0
        t += h
        y = out[0].copy()
        _check_finite(y, t)
        _check_chart(y[: lay.nv], ad.run.space, t)
        if event:
            loaded = bool(modes.pushing.any())
            ydot, events, rate, kinetic = _switch(ad, modes, y, out[3].copy(), t)
            if loaded != bool(modes.pushing.any()):
                _loaded_boundary(ad, y, t, -1.0 if not loaded else 1.0)
        else:
            ydot, events, rate, kinetic = (a.copy() for a in out[2:])
        ended, still_since = _finished(ad, modes, rate, t, still_since)
        if ended is not None:
            status = ended
            break
        if n_steps + n_flight >= MAX_STEPS:
            raise NumericalError(f"the adaptive compliant integration took {MAX_STEPS} steps by t = {t:.3g} s")
        h = h_next
    if modes.pushing.any():
        _loaded_boundary(ad, y, t, 1.0)
    q, v = y[: lay.nv], y[lay.nv : 2 * lay.nv]
    return _End(q, v, rate, float(kinetic[0]), t, n_steps, n_flight, status), y, contact_time


def _loaded_boundary(ad: _Adaptive, y: np.ndarray, t: float, sign: float) -> None:
    """Open (``sign`` -1) or close (+1) an interval in which some contact pushes, at (t, y): the
    joint impulses are the subtrees' momentum changes over these intervals minus the contact and
    gravity impulses on them (exact: no quadrature beyond the state's)."""
    nv = ad.layout.nv
    momentum = ad.run.evaluate_step(y[:nv], y[nv : 2 * nv]).momentum
    np.add(ad.tally.joint_impulse, sign * momentum, out=ad.tally.joint_impulse)
    ad.loaded_time[0] += sign * t


def _check_finite(y: np.ndarray, t: float) -> None:
    if not math.isfinite(float(y.sum())):
        raise NumericalError(f"the adaptive compliant integration diverged at t = {t:.3g} s")


def _adaptive_run(tree: Tree, scene: Scene, settings: CompliantSettings, local_tolerance: float,
                  terrain, base_x, v_minus, space: Space) -> tuple[_Adaptive, np.ndarray, float, float]:
    """The run's constants at the first touchdown, y there, its kinetic energy and the step
    that resolves simultaneous touchdowns (the fixed-step rung's at ``settings``)."""
    space = values_space(tree, space)  # a planar tree with centres of mass off its rods: their offsets too
    evaluate_step, q, v = _touchdown_state(tree, scene, settings, terrain, base_x, v_minus, space)
    zeta = settings.damping_ratio
    zeta = damping_ratio_for_restitution(scene.restitution) if zeta is None else zeta
    s = evaluate_step(q, v)
    energy_before = float(s.kinetic[0])
    run, tally = _setup(tree, scene, settings, evaluate_step, s, v, zeta, space)
    omega = _contact_parameters(s, settings, zeta)[3]
    ground = landing_ground(scene, terrain, base_x, space)[0]
    topology, lay = tree.topology(), state_layout(tree.topology(), space)
    law = np.array([settings.stiffness, tally.c[0] if lay.nc else 0.0, settings.impedance])
    p = design_vector(tree, space.body_values)
    speed = max(abs(scene.speed), float(np.max(np.abs(v))), 1e-12)
    scale = np.concatenate([
        np.full(lay.nv, speed / omega),
        np.full(lay.nv, speed),
        np.full(lay.size - 2 * lay.nv, speed * sum(b.mass for b in tree.bodies)),
    ])
    ad = _Adaptive(
        step=_buffers(dopri_step(topology, ground, settings.law, space), run, law, p),
        rate=_buffers(rate_function(topology, ground, settings.law, space), run, law, p),
        layout=lay, inverse_scale=1.0 / (local_tolerance * scale), period=2.0 * math.pi / omega, run=run, tally=tally,
        loaded_time=np.zeros(1),
    )
    return ad, np.concatenate([q, v, np.zeros(lay.size - 2 * lay.nv)]), energy_before, run.dt


def simulate_adaptive(
    tree: Tree,
    scene: Scene,
    settings: CompliantSettings = CompliantSettings(),
    local_tolerance: float = 1e-4,
    terrain: Terrain | Heightfield | None = None,
    base_x: float | None = None,
    v_minus: np.ndarray | None = None,
    space: Space = PLANAR,
) -> CompliantResult:
    """:func:`impulse_core.timedomain.compliant.simulate_impact` (same arguments and result; the
    settings' step is used only to group simultaneous touchdowns) by Dormand-Prince 5(4) steps at
    ``local_tolerance`` with the contact switches located (module docstring). ``timestep`` is the
    mean step while some contact touches, ``steps_per_period`` the contact period over it."""
    if scene.friction > 0:
        raise ModelError("scene.friction: the compliant rung models frictionless contact only (friction: 0)")
    ad, y0, energy_before, _ = _adaptive_run(tree, scene, settings, local_tolerance, terrain, base_x, v_minus, space)
    end, y, contact_time = _integrate(ad, y0)
    lay, tally = ad.layout, ad.tally
    tally.impulse[:] = y[lay.impulse]
    tally.impulse_vector[:] = y[lay.impulse_vector].reshape(lay.d, lay.nc, order="F")
    applied = tally.impulse_vector @ ad.run.in_subtree.T + ad.run.gravity_force * ad.loaded_time[0]
    np.subtract(tally.joint_impulse, applied, out=tally.joint_impulse)
    result = _result(ad.run, tally, end, y0[: lay.nv].copy(), y0[lay.nv : 2 * lay.nv].copy(), energy_before)
    step = contact_time / max(end.n_steps, 1)
    return replace(
        result,
        timestep=step,
        steps_per_period=ad.period / step if step > 0 else None,
        integrator=INTEGRATOR,
        model=f"compliant ({settings.law.value}, Dormand-Prince 5(4), located contact switches), {ad.run.space.name}",
    )


def adaptive_to_tolerance(
    tree: Tree,
    scene: Scene,
    settings: CompliantSettings,
    tolerance: float,
    max_refinements: int = 7,
    space: Space = PLANAR,
) -> CompliantResult:
    """:func:`simulate_adaptive` at the local tolerance :data:`LOCAL_TOLERANCE` x ``tolerance``,
    then divided by :data:`REFINEMENT` until two runs differ by at most ``tolerance``: the finer
    run, with that difference as its ``error_estimate`` (module docstring). An unmet tolerance
    after ``max_refinements``, or at :data:`LOCAL_FLOOR`: the estimate says so (the caller warns)."""
    local = max(LOCAL_TOLERANCE * tolerance, REFINEMENT * LOCAL_FLOOR)
    previous = simulate_adaptive(tree, scene, settings, local, space=space)
    error = math.inf
    for _ in range(max_refinements):
        if local <= LOCAL_FLOOR:
            break
        local = max(local / REFINEMENT, LOCAL_FLOOR)
        current = simulate_adaptive(tree, scene, settings, local, space=space)
        error = compliant_difference(current, previous)
        previous = current
        if error <= tolerance:
            break
    return replace(previous, error_estimate=error, tolerance=tolerance)
