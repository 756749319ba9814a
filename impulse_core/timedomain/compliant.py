"""The compliant, time-domain impact rung: contacts as unilateral spring-dampers along the local
terrain normal, integrated through the impact with the tree's nonlinear dynamics.

Dynamics. Generalized coordinates q = (base x, base y, base angle, revolute joint angles): the
positions whose rates are the core's generalized velocities (``approach_velocity``,
``ImpactResult.v_minus``), q' = v. The equations of motion are Lagrange's,

    M(q) v' + h(q, v) = tau_g(q) + sum_i (n_i^T J_i(q))^T f_i,

with h = (dM/dt) v - d/dq (v^T M v / 2) the Coriolis and centrifugal terms, obtained by automatic
differentiation of the core's own mass matrix: the kinematics (``forward_kinematics``,
``point_jacobian``), the mass matrix (``body_jacobians``, ``mass_matrix``) and its sparse L^T D L
factor (``ltdl``, ``solve``) are the core's, evaluated with the angles of the design vector
replaced by the symbols q (:func:`configured_design`). Gravity is off by default (impact time
scales); ``CompliantSettings.gravity`` adds it.

Space (``space=SPATIAL``, ``model.space: spatial``): q = (base origin x, y, z; the base's rotation
coordinates phi, a rotation vector in the world frame placing it at Exp(phi) times its touchdown
orientation; revolute joint angles), again with v = q' and Lagrange's equations obtained by
automatic differentiation of the core's mass matrix, turned to these coordinates
(:func:`_spatial_expressions`). At the touchdown orientation (phi = 0) q' is the core's velocity
(base origin velocity, world angular velocity, joint rates), which ``v_minus`` and ``v_plus`` report.
Exp is equivariant, so turning the whole scene (ground included) turns the trajectory with it,
step for step. The chart is singular at |phi| = 2 pi: beyond |phi| = 5 rad (286 degrees from the
touchdown orientation) the integration stops with a NumericalError. The ground is a heightfield
(``impulse_core.model.heightfield``: flat, or bilinear on a grid), contacts push along its upward
normal, and impulse vectors, joint impulses and momenta have three components.

Contact laws (:class:`ContactLaw`), frictionless, along the terrain's outward normal n_i at the
nearest ground point; g_i is the signed gap (``terrain.gap_expression``; in space
``heightfield.gap_expression``), g_i' = n_i^T J_i v:

* ``PENALTY`` (default): a force-level linear spring-damper per contact, a physical pad,
  f_i = max(0, -k g_i - c_i g_i'), one stiffness k (N/m) for every contact and
  c_i = 2 zeta sqrt(k m_i), m_i = 1 / A_ii the contact's effective mass when it touches down
  (A = J M^-1 J^T, the Delassus matrix along the normals). Contacts interact only through the
  tree's dynamics; each rings at its own frequency sqrt(k / m_i).
* ``CONSTRAINT``: MuJoCo's soft-constraint law with direct parameters (``solref = (-k, -b)``,
  constant impedance d = ``impedance``): the forces are the non-negative, complementary solution of
  ``(A + R) f = a_ref - a_0``, a_ref = -(b g' + k g) / d, R = (1 - d)/d diag(A),
  a_0 = n^T J M^-1 (tau_g - h) (without a J' v term, as in MuJoCo). While they push, every
  contact's gap follows its own oscillator g'' = -k g - b g' + (1 - d) a_0 (k in 1/s^2:
  mass-normalised), whatever the coupling: with simultaneous touchdowns all contacts release
  together, and the stiff limit is the paper's eq. 11.

Restitution. A linear spring-damper that may not pull releases when k x + c x' falls to 0, before
the spring is back at its free length, so its coefficient of restitution is not the textbook
exp(-zeta pi / sqrt(1 - zeta^2)) but (derived in :func:`clipped_restitution`; e.g. Schwager &
Poeschel 2007, "Coefficient of restitution and linear-dashpot model revisited")

    e(zeta) = exp(-zeta (pi - 2 arcsin zeta) / sqrt(1 - zeta^2)),   zeta < 1,

e(1) = exp(-2), and its overdamped continuation. The damping is tuned with the inverse,
:func:`damping_ratio_for_restitution`: e = 0.8 needs zeta = 0.0744, not the textbook 0.0708 (which
gives e = 0.808). Exact for one contact in the stiff limit; e = 0 would need infinite damping.

Integrator (fixed steps; ``simulate_to_tolerance`` integrates adaptively by default, fifth order:
:mod:`impulse_core.timedomain.adaptive`): semi-implicit (symplectic) Euler with a fixed step, v+ = v + dt a(q, v),
q+ = q + dt v+ (MuJoCo's ``Euler``, so that both integrate the same map). The step is a fraction
of the fastest contact period, dt = 2 pi / (omega_max * steps_per_period), omega_max^2 =
k lambda_max(A) (penalty: the stiffest mode with every contact engaged) or k (constraint). The
scheme is stable for omega dt < 2, its energy error on the elastic part stays bounded instead of
drifting (symplectic), and its impulse error is first order, about 0.2 / steps_per_period
relative (from the touchdown and release falling between steps; measured). The integration starts
1e-12 m above the first touchdown (:data:`TOUCHDOWN_CLEARANCE`) and ends when every contact that
touched has released and no contact that has not touched yet approaches the ground
(``SEPARATED``; a released contact heading back is listed in ``recontacting``, or followed with
``follow_recontacts``), when the loaded contacts have come to rest (``SETTLED``), or at
``max_time`` (``TIMEOUT``).

Outputs (:class:`CompliantResult`): force profiles, external impulses as their time integrals,
internal (joint) impulses as the time integral, over the steps in which a contact pushes, of the
joint force given by each subtree's momentum balance (momentum rate - contact and gravity forces on
the subtree), touchdown and release times and order, the state after the impact, kinetic energy
before and after (a gain is flagged).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace
from typing import Any
from enum import Enum

import casadi as ca
import numpy as np

from impulse_core.errors import ModelError, NumericalError
from impulse_core.evaluate import pre_impact_velocity, touchdown_geometry
from impulse_core.impact.nnls import nnls
from impulse_core.kinematics import dynamics as dyn
from impulse_core.kinematics.spatial import (
    PLANAR,
    PLANAR_OFFSET,
    SPATIAL,
    DofKind,
    Space,
    contact_bodies,
    dof_layout,
    forward_kinematics,
    n_values,
    point_jacobian,
    unpack_values,
    values_space,
)
from impulse_core.model import heightfield as hfield
from impulse_core.model.heightfield import Heightfield
from impulse_core.model.terrain import FLAT, Terrain, gap_expression, vertical_clearance
from impulse_core.model.tree import Scene, Topology, Tree, design_vector


class ContactLaw(Enum):
    """How a compliant contact turns penetration into force (module docstring)."""

    PENALTY = "penalty"
    CONSTRAINT = "constraint"


class CompliantStatus(Enum):
    """How the integration ended."""

    SEPARATED = "separated"  # every contact released, none approaching the ground
    SETTLED = "settled"  # contacts at rest on the ground (gravity, or very low restitution)
    TIMEOUT = "timeout"  # max_time reached with a contact still loaded or approaching


#: The contact stiffness a run accepts (N/m, or 1/s^2 for the constraint law): stiffer, its steps
#: vanish beside the time and a drop never ends (1e300); softer, the bodies sink through the ground.
STIFFNESS_RANGE = (1.0, 1.0e16)
#: Steps per period of the fastest contact oscillation a run accepts: 1e5 already takes seconds.
STEPS_PER_PERIOD_RANGE = (4.0, 1.0e5)


@dataclass(frozen=True)
class CompliantSettings:
    """Parameters of the compliant rung.

    Attributes:
        law: the contact law.
        stiffness: ``PENALTY``: N/m, every contact. ``CONSTRAINT``: 1/s^2, mass-normalised
            (MuJoCo's ``-solref[0]``).
        damping_ratio: zeta of every contact; None: tuned so that one contact in the stiff limit
            rebounds with the scene's restitution (:func:`damping_ratio_for_restitution`).
        steps_per_period: integration steps per period of the fastest contact oscillation.
        timestep: a fixed step (s) instead of ``steps_per_period``.
        gravity: m/s^2 along -y (0: impact time scales, gravity negligible).
        impedance: ``CONSTRAINT`` only: MuJoCo's d in (0, 1) (``solimp = (d, d, ...)``).
        max_time: give up after this long (s) from the first touchdown.
        follow_recontacts: keep integrating while a contact that has already released heads back
            to the ground (secondary impacts); default: the impact ends once every contact that
            touched has released and no contact that has not touched yet approaches; contacts
            heading back then are listed in ``CompliantResult.recontacting``.
        settle_fraction: ``SETTLED`` when every loaded contact moves slower than this fraction
            of the approach speed for one contact period.
        flight_step: between touchdowns, while no contact is within two contact steps of the
            ground, fly with classical Runge-Kutta 4 steps up to this long (s) instead of contact
            steps; None: contact steps throughout (the same map as MuJoCo's, step for step).
        record: keep the force profiles (time x contacts).
    """

    law: ContactLaw = ContactLaw.PENALTY
    stiffness: float = 1.0e6
    damping_ratio: float | None = None
    steps_per_period: float = 120.0
    timestep: float | None = None
    gravity: float = 0.0
    impedance: float = 0.9999
    max_time: float = 0.1
    settle_fraction: float = 1.0e-3
    follow_recontacts: bool = False
    flight_step: float | None = 1.0e-4
    record: bool = True

    def __post_init__(self) -> None:
        checks = (
            (STIFFNESS_RANGE[0] <= self.stiffness <= STIFFNESS_RANGE[1], "stiffness",
             f"must be in [{STIFFNESS_RANGE[0]:g}, {STIFFNESS_RANGE[1]:g}]"),
            (
                self.damping_ratio is None or (math.isfinite(self.damping_ratio) and self.damping_ratio >= 0),
                "damping_ratio",
                "must be >= 0 or None",
            ),
            (STEPS_PER_PERIOD_RANGE[0] <= self.steps_per_period <= STEPS_PER_PERIOD_RANGE[1], "steps_per_period",
             f"must be in [{STEPS_PER_PERIOD_RANGE[0]:g}, {STEPS_PER_PERIOD_RANGE[1]:g}]"),
            (self.timestep is None or (math.isfinite(self.timestep) and self.timestep > 0), "timestep", "must be > 0"),
            (
                self.flight_step is None or (math.isfinite(self.flight_step) and self.flight_step > 0),
                "flight_step",
                "must be > 0 or None",
            ),
            (math.isfinite(self.gravity) and self.gravity >= 0, "gravity", "must be >= 0"),
            (0.0 < self.impedance < 1.0, "impedance", "must be in (0, 1)"),
            (math.isfinite(self.max_time) and self.max_time > 0, "max_time", "must be > 0"),
            (self.settle_fraction >= 0, "settle_fraction", "must be >= 0"),
        )
        for ok, name, problem in checks:
            if not ok:
                raise ModelError(f"compliant.{name}: {problem}, got {getattr(self, name)!r}")


# --------------------------------------------------------------------------------------------
# Restitution of a unilateral (clipped) linear spring-damper


def clipped_restitution(zeta: float) -> float:
    """Coefficient of restitution of m x'' + c x' + k x = 0, x(0) = 0, x'(0) = v0 > 0, when the
    contact force k x + c x' may not pull: the mass leaves at the first zero of that force.

    zeta = c / (2 sqrt(k m)). Underdamped: exp(-zeta (pi - 2 arcsin zeta) / sqrt(1 - zeta^2));
    critical: exp(-2); overdamped (roots r1 > r2 of r^2 + 2 zeta r + 1): the force vanishes at
    t = ln(r2 / r1) / sqrt(zeta^2 - 1) (units of 1/omega_n) and e = -x'(t) / v0.
    """
    if zeta < 0 or not math.isfinite(zeta):
        raise ModelError(f"damping ratio must be finite and >= 0, got {zeta!r}")
    if zeta == 0.0:
        return 1.0
    if zeta < 1.0 - 1e-9:
        return math.exp(-zeta * (math.pi - 2.0 * math.asin(zeta)) / math.sqrt(1.0 - zeta * zeta))
    if zeta <= 1.0 + 1e-9:
        return math.exp(-2.0)
    s = math.sqrt(zeta * zeta - 1.0)
    r2 = -zeta - s
    r1 = 1.0 / r2  # r1 r2 = 1; avoids the cancellation in -zeta + s
    t = math.log(r2 / r1) / s
    velocity = (r1 * math.exp(r1 * t) - r2 * math.exp(r2 * t)) / (r1 - r2)
    return -velocity


def damping_ratio_for_restitution(restitution: float) -> float:
    """The zeta at which a clipped linear spring-damper rebounds with ``restitution``
    (inverse of :func:`clipped_restitution`, by bisection; e is decreasing in zeta).

    Raises:
        ModelError: for e <= 0 (infinite damping) or e > 1.
    """
    e = float(restitution)
    if not 0.0 < e <= 1.0:
        raise ModelError(
            f"scene.restitution: the compliant rung needs 0 < e <= 1, got {e!r} (a clipped spring-damper "
            "reaches e = 0 only with infinite damping)"
        )
    if e == 1.0:
        return 0.0
    lo, hi = 0.0, 1.0
    while clipped_restitution(hi) > e:
        lo, hi = hi, 2.0 * hi
        if hi > 1e12:
            raise ModelError(f"scene.restitution: {e!r} is too small for the compliant rung")
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if clipped_restitution(mid) > e:
            lo = mid
        else:
            hi = mid
        if hi - lo <= 1e-15 * hi:
            break
    return 0.5 * (lo + hi)


# --------------------------------------------------------------------------------------------
# Dynamics as a CasADi function of (q, v, p)

#: Names of the compiled functions' inputs and outputs.
DYNAMICS_INPUTS = ("q", "v", "p", "gravity")
DYNAMICS_OUTPUTS = (
    "contacts",
    "contact_jacobian",
    "minv_jt",
    "free_acceleration",
    "kinetic_energy",
    "subtree_momentum",
)
STEP_OUTPUTS = (
    "gap",
    "normal",
    "rate",
    "normal_jacobian",
    "minv_jnt",
    "free_acceleration",
    "kinetic_energy",
    "subtree_momentum",
    "subtree_jacobian",
    "subtree_bias",
)


def _require_known(space: Space) -> None:
    if space not in (PLANAR, PLANAR_OFFSET, SPATIAL):
        raise ModelError(f"the time-domain rungs run in the plane or in space, got space '{space.name}'")


#: Space: the base's rotation coordinates phi (a rotation vector, world frame) place it at
#: Exp(phi) times its touchdown orientation. Exp is equivariant (Exp(R phi) = R Exp(phi) R^T), so
#: turning the whole scene turns the coordinates with it and the integration is the same, step for
#: step. The chart is singular at |phi| = 2 pi; beyond this |phi| (rad) the integration stops.
CHART_LIMIT = 5.0
#: Below this |phi|^2 the chart's coefficients are their Taylor series (exact in float64 there).
_SERIES = 1e-2


def _coefficients(s: Any) -> tuple[Any, Any, Any]:
    """a(s) = sin(t)/t, b(s) = (1 - cos t)/t^2, c(s) = (t - sin t)/t^3 of s = t^2, smooth at 0
    (CasADi: the closed form at a guarded argument beside the series, both finite for AD)."""
    series = (
        1 - s / 6 + s**2 / 120 - s**3 / 5040 + s**4 / 362880 - s**5 / 39916800,
        0.5 - s / 24 + s**2 / 720 - s**3 / 40320 + s**4 / 3628800 - s**5 / 479001600,
        1 / 6 - s / 120 + s**2 / 5040 - s**3 / 362880 + s**4 / 39916800 - s**5 / 6227020800,
    )
    if isinstance(s, (ca.SX, ca.MX)):
        small = s < _SERIES
        safe = ca.if_else(small, 1.0, s)
        t = ca.sqrt(safe)
        closed = (ca.sin(t) / t, (1 - ca.cos(t)) / safe, (t - ca.sin(t)) / (safe * t))
        return tuple(ca.if_else(small, a, b) for a, b in zip(series, closed))  # type: ignore[return-value]
    if s < _SERIES:
        return series
    t = math.sqrt(s)
    return math.sin(t) / t, (1 - math.cos(t)) / s, (t - math.sin(t)) / (s * t)


def _hat(phi: Any) -> Any:
    if isinstance(phi, (ca.SX, ca.MX)):
        return ca.skew(phi)
    x, y, z = (float(v) for v in phi)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def chart_rotation(phi: Any) -> Any:
    """Exp(phi) = I + a [phi]x + b [phi]x^2, the rotation by |phi| about phi (CasADi or numpy)."""
    K = _hat(phi)
    s = ca.dot(phi, phi) if isinstance(phi, (ca.SX, ca.MX)) else float(np.dot(phi, phi))
    a, b, _ = _coefficients(s)
    eye = ca.SX.eye(3) if isinstance(phi, (ca.SX, ca.MX)) else np.eye(3)
    return eye + a * K + b * (K @ K)


def chart_rates(phi: Any) -> Any:
    """S(phi) = I + b [phi]x + c [phi]x^2 (SO(3)'s left Jacobian): the base's world angular
    velocity is S(phi) phi' for the rotation coordinates phi (:func:`chart_rotation`); S(0) = I, so
    at the touchdown orientation phi' is the angular velocity."""
    K = _hat(phi)
    s = ca.dot(phi, phi) if isinstance(phi, (ca.SX, ca.MX)) else float(np.dot(phi, phi))
    _, b, c = _coefficients(s)
    eye = ca.SX.eye(3) if isinstance(phi, (ca.SX, ca.MX)) else np.eye(3)
    return eye + b * K + c * (K @ K)


def continued_rotation_vector(R: np.ndarray, previous: np.ndarray) -> np.ndarray:
    """The rotation vector of ``R`` nearest to ``previous``. R's representatives are
    (theta + 2 pi k) u (theta in [0, pi], u its unit axis, k any integer); the nearest to
    ``previous`` keeps a turning base's rotation vector continuous and unwrapped (a planar base's
    turn: its angle, not wrapped to one turn)."""
    from scipy.spatial.transform import Rotation

    rv = Rotation.from_matrix(R).as_rotvec()
    theta, size = float(np.linalg.norm(rv)), float(np.linalg.norm(previous))
    if theta > 1e-12:
        u = rv / theta
    elif size > 0.0:
        u = np.asarray(previous, dtype=float) / size
    else:
        return rv
    k = round((float(u @ previous) - theta) / (2.0 * math.pi))
    return (theta + 2.0 * math.pi * k) * u


def world_velocity(q: np.ndarray, v: np.ndarray, space: Space = PLANAR) -> np.ndarray:
    """The core's generalized velocity (base origin velocity, world angular velocity, joint rates)
    of the rates ``v`` of the configuration ``q``: the same in the plane; in space the rotation
    rates become S(a) a' (:func:`chart_rates`)."""
    if space.joint_axis is not None:
        return np.array(v, dtype=float)
    out = np.array(v, dtype=float)
    out[3:6] = chart_rates(q[3:6]) @ out[3:6]
    return out


def _check_chart(q: np.ndarray, space: Space, t: float) -> None:
    """Raise NumericalError when the base's rotation coordinates near the chart's singularity."""
    if space.joint_axis is None and float(np.linalg.norm(q[3:6])) > CHART_LIMIT:
        raise NumericalError(
            f"the base turned {math.degrees(float(np.linalg.norm(q[3:6]))):.0f} degrees from its touchdown "
            f"orientation by t = {t:.3g} s: beyond the spatial time-domain rungs' rotation coordinates "
            f"(at most {math.degrees(CHART_LIMIT):.0f} degrees)"
        )


def configured_design(topology: Topology, p: ca.SX, q: ca.SX, space: Space = PLANAR) -> ca.SX:
    """The design vector with its angles replaced by the configuration q: the base's absolute
    angle by q's base rotation, each revolute joint's angle by its joint coordinate. Fixed joints
    keep their angle. The core's kinematics evaluated at this vector place the tree at q (up to
    the base translation, which :func:`dynamics_function` adds). The vector's layout is
    ``space.body_values``'s (the plane with centres of mass off the rods: PLANAR_OFFSET)."""
    layout = dof_layout(topology, space)
    n = len(space.body_values)
    i_angle = space.body_values.index("angle")
    rotation = [k for k, (kind, _) in enumerate(space.base_dofs) if kind is DofKind.ROTATION]
    entries = [p[i] for i in range(p.shape[0])]
    if rotation:
        entries[i_angle] = q[rotation[0]]
    for b in range(1, topology.n_bodies):
        k = layout.body_dof[b]
        if k is not None:
            entries[n * b + i_angle] = q[k]
    return ca.vertcat(*entries)


@dataclass(frozen=True)
class Expressions:
    """Symbols (q, v, p, gravity) and the dynamics built from the core at configuration q."""

    q: ca.SX
    v: ca.SX
    p: ca.SX
    gravity: ca.SX
    contacts: ca.SX  # d x n_c (d = 2 in the plane, 3 in space)
    contact_jacobian: ca.SX  # d n_c x nv
    minv_jt: ca.SX  # nv x d n_c
    free_acceleration: ca.SX
    kinetic_energy: ca.SX
    subtree_momentum: ca.SX  # d x bodies
    subtree_jacobian: ca.SX  # d bodies x nv: rows (x, y[, z]) of each subtree's momentum Jacobian
    subtree_bias: ca.SX  # d x bodies: d/dt (subtree momentum) at zero acceleration
    mass_matrix: ca.SX  # nv x nv
    force: ca.SX  # nv: gravity's generalized force - Coriolis and centrifugal terms
    contact_bias: ca.SX  # d n_c: (dJ/dt) v, the contact accelerations at zero acceleration
    com_height: ca.SX  # y of the whole tree's centre of mass

    @property
    def dims(self) -> int:
        """2 in the plane, 3 in space: the rows of a point's position."""
        return int(self.contacts.shape[0])


@functools.lru_cache(maxsize=64)
def expressions(topology: Topology, space: Space) -> Expressions:
    """The tree's dynamics as SX expressions of (q, v, p, gravity), built once per topology:
    every terrain's step function (:func:`step_function`) shares them. In space
    (:func:`_spatial_expressions`) q holds the base origin, the base's rotation coordinates and
    the joint angles. PLANAR_OFFSET: the plane with each body's centre of mass off its rod (the
    core's offset terms, :func:`impulse_core.kinematics.spatial.values_space`)."""
    _require_known(space)
    if space.joint_axis is None:
        return _spatial_expressions(topology, space)
    layout = dof_layout(topology, space)
    nv = layout.nv
    q = ca.SX.sym("q", nv)
    v = ca.SX.sym("v", nv)
    p = ca.SX.sym("p", n_values(topology, space))
    g = ca.SX.sym("gravity")
    values = unpack_values(topology, configured_design(topology, p, q, space), space)
    kin = forward_kinematics(topology, values, space)
    offset = ca.SX.zeros(3, 1)
    for k, (kind, axis) in enumerate(space.base_dofs):
        if kind is DofKind.TRANSLATION:
            offset = offset + q[k] * ca.DM(axis)
    jac = dyn.body_jacobians(kin, layout, values, space)
    M = dyn.mass_matrix(jac, values)
    factor = dyn.ltdl(M, layout.dof_parent)

    positions, rows = [], []
    for c, b in enumerate(contact_bodies(topology)):
        Jv, _ = point_jacobian(kin, layout, b, kin.W_p_C[c], space)
        positions.append((kin.W_p_C[c] + offset)[:2])
        rows.append(Jv[:2, :])
    C = ca.horzcat(*positions) if positions else ca.SX(2, 0)
    Jc = ca.vertcat(*rows) if rows else ca.SX(0, nv)

    Mv = M @ v
    kinetic = 0.5 * ca.dot(v, Mv)
    h = ca.jtimes(Mv, q, v) - ca.gradient(kinetic, q)  # Coriolis and centrifugal: (dM/dt) v - dT/dq
    tau_g = ca.SX.zeros(nv, 1)
    down = ca.vertcat(0, -g, 0)
    for b, val in enumerate(values):
        tau_g = tau_g + val.mass * (jac.Jv[b].T @ down)
    free = dyn.solve(factor, tau_g - h)
    minv_jt = dyn.solve(factor, Jc.T) if rows else ca.SX(nv, 0)

    Jsub = [val.mass * jac.Jv[b][:2, :] for b, val in enumerate(values)]
    for b in reversed(range(1, topology.n_bodies)):
        parent = topology.parents[b]
        Jsub[parent] = Jsub[parent] + Jsub[b]
    momentum = ca.horzcat(*[J @ v for J in Jsub])
    bias = ca.jtimes(momentum, q, v)  # (dJ/dt) v of each subtree's momentum
    contact_bias = ca.jtimes(Jc @ v, q, v) if rows else ca.SX(0, 1)
    total = sum(val.mass for val in values)
    com_height = sum(val.mass * (kin.W_p_G[b] + offset)[1] for b, val in enumerate(values)) / total
    return Expressions(
        q, v, p, g, C, Jc, minv_jt, free, kinetic, momentum, ca.vertcat(*Jsub), bias, M, tau_g - h, contact_bias,
        com_height,
    )


def _spatial_expressions(topology: Topology, space: Space) -> Expressions:
    """The spatial tree's Lagrangian dynamics. Coordinates q = (base origin x, y, z; the base's
    rotation coordinates a, a rotation vector in the world frame; joint angles), velocities
    v = q'. The tree sits at Exp(a) x (its touchdown placement, the core's kinematics with the
    joint angles of q, rotated about the base origin) + the base origin: with E = Exp(a) and S(a)
    its rates
    (:func:`chart_rates`), the core's generalized velocity at the touchdown orientation is
    G q', G = blockdiag(E^T, E^T S, I), so a point's world velocity is E J_core G q' and the mass
    matrix G^T M_core G (kinetic energy does not change under a rotation of the whole scene); the
    Coriolis and centrifugal terms follow from it by automatic differentiation, as in the plane.
    At a = 0 (touchdown), G = I: q' is the core's velocity."""
    layout = dof_layout(topology, space)
    nv = layout.nv
    q = ca.SX.sym("q", nv)
    v = ca.SX.sym("v", nv)
    p = ca.SX.sym("p", n_values(topology, space))
    g = ca.SX.sym("gravity")
    n = len(space.body_values)
    i_angle = space.body_values.index("angle")
    entries = [p[i] for i in range(p.shape[0])]
    for b in range(1, topology.n_bodies):
        k = layout.body_dof[b]
        if k is not None:
            entries[n * b + i_angle] = q[k]
    values = unpack_values(topology, ca.vertcat(*entries), space)
    kin = forward_kinematics(topology, values, space)
    jac = dyn.body_jacobians(kin, layout, values, space)
    M_core = dyn.mass_matrix(jac, values)
    offset, a = q[0:3], q[3:6]
    E = chart_rotation(a)
    G = ca.SX.eye(nv)
    G[0:3, 0:3] = E.T
    G[3:6, 3:6] = E.T @ chart_rates(a)
    M = G.T @ M_core @ G
    factor = dyn.ltdl(M, layout.dof_parent)

    positions, rows = [], []
    for c, b in enumerate(contact_bodies(topology)):
        Jv, _ = point_jacobian(kin, layout, b, kin.W_p_C[c], space)
        positions.append(E @ kin.W_p_C[c] + offset)
        rows.append(E @ Jv @ G)
    C = ca.horzcat(*positions) if positions else ca.SX(3, 0)
    Jc = ca.vertcat(*rows) if rows else ca.SX(0, nv)

    Mv = M @ v
    kinetic = 0.5 * ca.dot(v, Mv)
    h = ca.jtimes(Mv, q, v) - ca.gradient(kinetic, q)
    down = ca.vertcat(0, -g, 0)
    Jsub = [val.mass * (E @ jac.Jv[b] @ G) for b, val in enumerate(values)]
    tau_g = ca.SX.zeros(nv, 1)
    for J in Jsub:
        tau_g = tau_g + J.T @ down
    free = dyn.solve(factor, tau_g - h)
    minv_jt = dyn.solve(factor, Jc.T) if rows else ca.SX(nv, 0)
    for b in reversed(range(1, topology.n_bodies)):
        parent = topology.parents[b]
        Jsub[parent] = Jsub[parent] + Jsub[b]
    momentum = ca.horzcat(*[J @ v for J in Jsub])
    bias = ca.jtimes(momentum, q, v)
    contact_bias = ca.jtimes(Jc @ v, q, v) if rows else ca.SX(0, 1)
    total = sum(val.mass for val in values)
    com_height = sum(val.mass * (E @ kin.W_p_G[b] + offset)[1] for b, val in enumerate(values)) / total
    return Expressions(
        q, v, p, g, C, Jc, minv_jt, free, kinetic, momentum, ca.vertcat(*Jsub), bias, M, tau_g - h, contact_bias,
        com_height,
    )


def dynamics_function(topology: Topology, space: Space = PLANAR) -> ca.Function:
    """The tree's planar dynamics at configuration q, as a named CasADi function of
    (q, v, p, gravity).

    Outputs (world frame): ``contacts`` (2 x declared contacts, positions), ``contact_jacobian``
    (2 n_c x nv: the x and y rows of each contact's velocity Jacobian, declaration order),
    ``minv_jt`` (M^-1 of its transpose, by the sparse L^T D L factor), ``free_acceleration``
    (M^-1 (tau_g - h), nv), ``kinetic_energy`` (v^T M v / 2), ``subtree_momentum`` (2 x bodies:
    linear momentum of each body's subtree; column 0 is the whole tree's).
    """
    x = expressions(topology, space)
    outs = [x.contacts, x.contact_jacobian, x.minv_jt, x.free_acceleration, x.kinetic_energy, x.subtree_momentum]
    return ca.Function(
        "compliant_dynamics", [x.q, x.v, x.p, x.gravity], outs, list(DYNAMICS_INPUTS), list(DYNAMICS_OUTPUTS)
    )


def ground_expression(ground: Terrain | Heightfield, W_p: ca.SX) -> tuple[ca.SX, ca.SX]:
    """Gap and outward unit normal of the point ``W_p``: a planar terrain's (2 x 1 point) or a
    heightfield's (3 x 1; ``impulse_core.model.heightfield``)."""
    if isinstance(ground, Heightfield):
        return hfield.gap_expression(ground, W_p)
    return gap_expression(ground, W_p)


def normal_terms(x: Expressions, terrain: Terrain | Heightfield, space: Space) -> tuple[ca.SX, ca.SX, ca.SX, ca.SX]:
    """The contacts' gaps g (n_c), outward normals N (d x n_c), normal Jacobian rows Jn (n_c x nv,
    n_i^T J_i) and M^-1 Jn^T on ``terrain``, as expressions of ``x``'s symbols."""
    d = x.dims
    if (d == 3) != isinstance(terrain, Heightfield):
        ground = "heightfield" if d == 3 else "terrain"
        raise ModelError(f"the {space.name} time-domain rungs take a {ground} as ground")
    nc, nv = x.contacts.shape[1], x.q.shape[0]
    gaps, normals = [], []
    for c in range(nc):
        gap, normal = ground_expression(terrain, x.contacts[:, c])
        gaps.append(gap)
        normals.append(normal)
    N = ca.horzcat(*normals) if nc else ca.SX(d, 0)
    Jn = ca.vertcat(*[N[:, c].T @ x.contact_jacobian[d * c : d * c + d, :] for c in range(nc)]) if nc else ca.SX(0, nv)
    minv_jnt = ca.horzcat(*[x.minv_jt[:, d * c : d * c + d] @ N[:, c] for c in range(nc)]) if nc else ca.SX(nv, 0)
    return (ca.vertcat(*gaps) if nc else ca.SX(0, 1)), N, Jn, minv_jnt


def step_function(topology: Topology, terrain: Terrain | Heightfield, space: Space = PLANAR) -> ca.Function:
    """What one integration step needs at (q, v, p, gravity), with the contact detection of
    ``terrain`` built in (one call per step).

    Outputs: ``gap`` (n_c, signed distance), ``normal`` (2 x n_c, outward, at the nearest ground
    point), ``rate`` (n_c, d gap/dt = n . contact velocity), ``normal_jacobian`` (n_c x nv, rows
    n_i^T J_i), ``minv_jnt`` (M^-1 of its transpose), ``free_acceleration``, ``kinetic_energy``,
    ``subtree_momentum`` (as :func:`dynamics_function`), ``subtree_jacobian`` (2 bodies x nv,
    rows x and y of each subtree's momentum Jacobian) and ``subtree_bias`` (2 x bodies, its
    (dJ/dt) v): a subtree's momentum rate is ``subtree_jacobian @ a + subtree_bias`` for an
    acceleration a. Every output is dense. In space (``terrain`` a ``Heightfield``) every 2 above
    is a 3.
    """
    x = expressions(topology, space)
    gap, N, Jn, minv_jnt = normal_terms(x, terrain, space)
    outs = [
        gap,
        N,
        Jn @ x.v,
        Jn,
        minv_jnt,
        x.free_acceleration,
        x.kinetic_energy,
        x.subtree_momentum,
        x.subtree_jacobian,
        x.subtree_bias,
    ]
    return ca.Function(
        "compliant_step",
        [x.q, x.v, x.p, x.gravity],
        [ca.densify(o) for o in outs],
        list(DYNAMICS_INPUTS),
        list(STEP_OUTPUTS),
    )


@functools.lru_cache(maxsize=64)
def compiled_dynamics(topology: Topology, space: Space = PLANAR) -> ca.Function:
    """:func:`dynamics_function`, built once per topology."""
    return dynamics_function(topology, space)


@functools.lru_cache(maxsize=64)
def compiled_step(topology: Topology, terrain: Terrain | Heightfield, space: Space = PLANAR) -> ca.Function:
    """:func:`step_function`, built once per (topology, terrain)."""
    return step_function(topology, terrain, space)


def joint_impulses(per_body: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Joint impulses (2 x bodies in the plane, 3 x bodies in space; the base's column unused) as
    the result's (n_joints x 3) vectors (z = 0 in the plane) and their magnitudes."""
    joint = per_body[:, 1:].T
    if per_body.shape[0] == 3:
        internal = joint.copy() if len(joint) else np.zeros((0, 3))
    else:
        internal = np.column_stack([joint, np.zeros(len(joint))]) if len(joint) else np.zeros((0, 3))
    return internal, np.linalg.norm(internal, axis=1)


def touchdown_order(touchdown_time: np.ndarray, resolution: float) -> tuple[int, ...]:
    """The contacts that touched (finite times), by time; touchdowns closer than ``resolution``
    (s, one integration step) in a chain are simultaneous and keep their declaration order."""
    touched = np.flatnonzero(np.isfinite(touchdown_time))
    by_time = touched[np.argsort(touchdown_time[touched], kind="stable")]
    group, groups, last = 0, [], None
    for i in by_time:
        if last is not None and touchdown_time[i] - last > resolution:
            group += 1
        groups.append(group)
        last = touchdown_time[i]
    return tuple(int(i) for _, i in sorted(zip(groups, by_time)))


def scene_ground(scene: Scene, terrain: Terrain | None = None, base_x: float | None = None) -> tuple[Terrain, float]:
    """The terrain and base placement to use: the scene's own (``scene.terrain``,
    ``scene.base_x``) unless an argument overrides it."""
    return (scene.terrain if terrain is None else terrain), float(scene.base_x if base_x is None else base_x)


def spatial_ground(scene: Scene, ground: Heightfield | Terrain | None = None) -> Heightfield:
    """The ground of a spatial landing: ``ground`` when given (a flat planar terrain is the
    horizontal heightfield at its height), else ``scene.heightfield``, else the scene's flat
    ``terrain`` as a heightfield.

    Raises:
        ModelError: a terrain that is not flat (a profile y(x) is planar: give ``scene.heightfield``).
    """
    ground = ground if ground is not None else scene.heightfield if scene.heightfield is not None else scene.terrain
    if isinstance(ground, Heightfield):
        return ground
    if not ground.is_flat:
        raise ModelError(
            "scene.terrain: a ground profile y(x) is planar; a spatial model's uneven ground is scene.heightfield "
            "(constant along z: heights equal in each row)"
        )
    return hfield.flat_heightfield(ground.y[0])

def subtree_incidence(tree: Tree) -> np.ndarray:
    """S[b, i] = 1 when contact i sits on body b's subtree (b or a descendant): bodies x contacts."""
    S = np.zeros((tree.n_bodies, len(tree.contacts)))
    for i, (b, _) in enumerate(tree.contacts):
        while b is not None:
            S[b, i] = 1.0
            b = tree.bodies[b].parent
    return S


def subtree_masses(tree: Tree) -> np.ndarray:
    """Mass of each body's subtree (kg)."""
    m = np.array([b.mass for b in tree.bodies], dtype=float)
    for b in reversed(range(1, tree.n_bodies)):
        m[tree.bodies[b].parent] += m[b]
    return m


# --------------------------------------------------------------------------------------------
# Touchdown


#: The first contact starts this far (m) above the ground: a gap of exactly 0 would be rounded to
#: +-1e-17 differently by different engines, moving the first loaded step by one.
TOUCHDOWN_CLEARANCE = 1e-12


def touchdown_configuration(
    tree: Tree,
    terrain: Terrain | Heightfield = FLAT,
    base_x: float = 0.0,
    clearance: float = TOUCHDOWN_CLEARANCE,
    space: Space = PLANAR,
    base_z: float = 0.0,
) -> np.ndarray:
    """The configuration q at the instant the first contact touches, approaching straight down.

    The tree keeps its touchdown angles; its base origin sits at x = ``base_x`` (and, in space,
    z = ``base_z``) and is lowered until the contact with the smallest vertical clearance above
    the terrain (a heightfield in space) is ``clearance`` above it. In space q is (base origin,
    rotation coordinates 0: the touchdown orientation, joint angles).
    """
    if space.joint_axis is None:
        ground = terrain if isinstance(terrain, Heightfield) else hfield.flat_heightfield(terrain.y[0])
        if not isinstance(terrain, Heightfield) and not terrain.is_flat:
            raise ModelError("scene.terrain: a ground profile y(x) is planar; in space give scene.heightfield")
        topology = tree.topology()
        layout = dof_layout(topology, space)
        q = np.zeros(layout.nv)
        for b in range(1, tree.n_bodies):
            if layout.body_dof[b] is not None:
                q[layout.body_dof[b]] = tree.bodies[b].angle
        q[0], q[2] = float(base_x), float(base_z)
        C = touchdown_geometry(tree, space).contacts + np.array([q[0], 0.0, q[2]])
        q[1] = clearance - float(np.min(hfield.vertical_clearance(ground, C)))
        return q
    topology = tree.topology()
    layout = dof_layout(topology)
    q = np.zeros(layout.nv)
    q[2] = tree.bodies[0].angle
    for b in range(1, tree.n_bodies):
        if layout.body_dof[b] is not None:
            q[layout.body_dof[b]] = tree.bodies[b].angle
    q[0] = float(base_x)
    C = touchdown_geometry(tree).contacts + np.array([q[0], 0.0])  # base origin at height 0
    q[1] = clearance - float(np.min(vertical_clearance(terrain, C)))
    return q


# --------------------------------------------------------------------------------------------
# Result


@dataclass(frozen=True)
class CompliantResult:
    """One compliant impact. World frame; N, N s, m/s, s, J. Contacts in declaration order.

    Attributes:
        external: normal impulse of each declared contact, the time integral of its force.
        external_vector: the same impulses as planar vectors (n_c x 2; the normal may turn).
        internal: force impulse through each joint, parent onto child (n_joints x 3, z = 0): the
            joint force from each subtree's momentum balance (momentum rate - contact and gravity
            forces on it) integrated, like the contact forces, over the steps in which some
            contact pushes: the impulsive part, without the finite joint forces of free flight
            between touchdowns.
        internal_magnitude: |internal| per joint (one per non-base body, file order).
        external_norm, internal_norm: Euclidean norms of ``external`` and ``internal_magnitude``.
        touchdown_time: when each contact first touched (s from the first touchdown; NaN: never).
        release_time: when each contact's force last was non-zero (NaN: never loaded).
        touchdown_order: the contacts that touched, by touchdown time (touchdowns within one
            contact step of each other count as simultaneous: declaration order).
        recontacting: contacts that had released and were heading back to the ground when the
            integration stopped (secondary impacts follow; see ``follow_recontacts``).
        max_penetration: deepest penetration of each contact (m).
        time: start of each step (s); ``force``: normal force of each contact over that step
            (steps x n_c); empty when not recorded.
        q_minus, q_plus, v_minus, v_plus: configuration and generalized velocity at the first
            touchdown and at the end.
        energy_before, energy_after: kinetic energy at the first touchdown and at the end.
        energy_gain: the impact created kinetic energy (beyond 1e-9 relative): flagged, not hidden.
        stiffness, damping: per contact, in the law's units (penalty: N/m, N s/m; constraint:
            1/s^2, 1/s); damping_ratio: zeta used.
        effective_mass: 1 / A_ii of each contact at its touchdown (at the first touchdown for
            contacts that never touched), kg: the penalty law's damping is 2 zeta sqrt(k m).
        timestep, n_steps, duration: the contact step (adaptive: the mean step while some contact
            touches), the number of contact steps, and the integrated time; n_flight_steps:
            Runge-Kutta steps of free flight between touchdowns.
        status: how it ended; law: the contact law; model: a one-line description.
        steps_per_period: the discretisation of this run (None: a fixed ``timestep``; adaptive:
            the contact period over the mean step).
        error_estimate, tolerance: from :func:`simulate_to_tolerance` (the relative difference
            from the previous, coarser run: at twice the step, or adaptive at 4 x the local
            tolerance), else None.
        integrator: ``euler`` (fixed semi-implicit Euler steps) or ``dopri5`` (adaptive
            Dormand-Prince 5(4) between located contact switches, :mod:`.adaptive`).
    """

    external: np.ndarray
    external_vector: np.ndarray
    internal: np.ndarray
    internal_magnitude: np.ndarray
    external_norm: float
    internal_norm: float
    touchdown_time: np.ndarray
    release_time: np.ndarray
    touchdown_order: tuple[int, ...]
    recontacting: tuple[int, ...]
    max_penetration: np.ndarray
    time: np.ndarray
    force: np.ndarray
    q_minus: np.ndarray
    q_plus: np.ndarray
    v_minus: np.ndarray
    v_plus: np.ndarray
    energy_before: float
    energy_after: float
    energy_gain: bool
    stiffness: np.ndarray
    damping: np.ndarray
    effective_mass: np.ndarray
    damping_ratio: float
    timestep: float
    n_steps: int
    n_flight_steps: int
    duration: float
    status: CompliantStatus
    law: ContactLaw
    model: str
    steps_per_period: float | None = None
    error_estimate: float | None = None
    tolerance: float | None = None
    integrator: str = "euler"

    @property
    def max_internal(self) -> float:
        return float(self.internal_magnitude.max()) if self.internal_magnitude.size else 0.0

    @property
    def active(self) -> tuple[int, ...]:
        """Contacts that touched, in declaration order."""
        return tuple(int(i) for i in np.flatnonzero(np.isfinite(self.touchdown_time)))


# --------------------------------------------------------------------------------------------
# Integration


@dataclass(frozen=True)
class _State:
    """Per-step quantities at (q, v): views into the evaluator's output buffers, overwritten by
    the next evaluation (copy what must outlive a step)."""

    gap: np.ndarray
    normal: np.ndarray  # 2 x n_c
    rate: np.ndarray  # d gap / dt
    Jn: np.ndarray  # normal Jacobian rows (n_c x nv)
    minv_jnt: np.ndarray  # M^-1 Jn^T (nv x n_c)
    free: np.ndarray
    kinetic: np.ndarray  # 1 element
    momentum: np.ndarray  # 2 x bodies
    subtree_jacobian: np.ndarray  # 2 bodies x nv
    subtree_bias: np.ndarray  # 2 x bodies


class BufferedFunction:
    """Low-overhead numeric calls of a CasADi function through its buffer interface (a few us per
    call instead of tens): fill the fixed input arrays ``self.args``, call :meth:`evaluate`; the
    outputs are views of fixed arrays, overwritten by the next call: ``self.flat`` (as vectors)
    and ``self.out`` (shaped, CasADi's column-major order)."""

    def __init__(self, fn: ca.Function) -> None:
        self._buf, self.evaluate = fn.buffer()
        self.args = [np.zeros(fn.nnz_in(i)) for i in range(fn.n_in())]
        self.flat = [np.zeros(fn.nnz_out(i)) for i in range(fn.n_out())]
        for i, a in enumerate(self.args):
            self._buf.set_arg(i, memoryview(a))
        for i, r in enumerate(self.flat):
            self._buf.set_res(i, memoryview(r))
        self.out = [r.reshape(fn.size_out(i), order="F") for i, r in enumerate(self.flat)]


class BufferedCall(BufferedFunction):
    """:class:`BufferedFunction` of a function of (q, v, p, gravity), with p and gravity fixed."""

    def __init__(self, fn: ca.Function, p: np.ndarray, gravity: float) -> None:
        super().__init__(fn)
        self.args[2][:] = p
        self.args[3][:] = gravity

    def call(self, q: np.ndarray, v: np.ndarray) -> None:
        self.args[0][:] = q
        self.args[1][:] = v
        self.evaluate()


class _Evaluator(BufferedCall):
    """:class:`BufferedCall` of :func:`step_function`, its outputs named (:class:`_State`)."""

    def __init__(self, fn: ca.Function, p: np.ndarray, gravity: float) -> None:
        super().__init__(fn, p, gravity)
        o, f = self.out, self.flat
        self._state = _State(f[0], o[1], f[2], o[3], o[4], f[5], f[6], o[7], o[8], o[9])

    def __call__(self, q: np.ndarray, v: np.ndarray) -> _State:
        self.call(q, v)
        return self._state


def _flight(
    evaluate_step: _Evaluator, q: np.ndarray, v: np.ndarray, step: float, reach: float
) -> tuple[np.ndarray, np.ndarray, float] | None:
    """One classical Runge-Kutta 4 step of the free flight, as long as ``step`` or, halving, at
    least 4 x ``reach`` / 2, such that no contact comes within ``reach`` seconds (at its normal
    velocity) of the ground at any stage of it; None when none qualifies (take contact steps).

    Contact steps resolve every touchdown; the flight steps only skip the free flight between
    them, where the contact step (a fraction of a contact period) is needlessly small.
    """
    h = step
    while h >= 2.0 * reach:
        ok = True
        ks = [(v, evaluate_step(q, v).free.copy())]
        for frac in (0.5, 0.5, 1.0):
            dq, dv = ks[-1]
            qq, vv = q + frac * h * dq, v + frac * h * dv
            s = evaluate_step(qq, vv)
            if np.any(s.gap <= reach * np.maximum(0.0, -s.rate)):
                ok = False
                break
            ks.append((vv, s.free.copy()))
        if ok:
            q1 = q + h / 6.0 * (ks[0][0] + 2 * ks[1][0] + 2 * ks[2][0] + ks[3][0])
            v1 = v + h / 6.0 * (ks[0][1] + 2 * ks[1][1] + 2 * ks[2][1] + ks[3][1])
            s = evaluate_step(q1, v1)
            if np.all(s.gap > reach * np.maximum(0.0, -s.rate)) and np.all(s.gap > 0.0):
                return q1, v1, h
        h *= 0.5
    return None


def _constraint_forces(s: _State, active: np.ndarray, k: float, b: float, d: float) -> np.ndarray:
    """MuJoCo's soft-constraint contact forces: f >= 0 complementary to (A + R) f - (a_ref - a0)
    >= 0, as the bound-constrained QP min f^T (A+R) f / 2 - (a_ref - a0)^T f, solved as an NNLS on
    the Cholesky factor of A + R (Lawson-Hanson)."""
    f = np.zeros(len(s.gap))
    idx = np.flatnonzero(active)
    if idx.size == 0:
        return f
    Jn = s.Jn[idx]
    A = Jn @ s.minv_jnt[:, idx]
    H = A + np.diag((1.0 - d) / d * np.diag(A))
    rhs = -(b * s.rate[idx] + k * s.gap[idx]) / d - Jn @ s.free
    if idx.size == 1:
        f[idx] = max(0.0, rhs[0] / H[0, 0])
        return f
    L = np.linalg.cholesky(0.5 * (H + H.T))
    f[idx] = nnls(L.T, np.linalg.solve(L, rhs))
    return f


@dataclass(frozen=True)
class _Run:
    """What the integration of one impact keeps fixed: the step function, the settings, the contact
    law's constants and the subtrees' contact incidence and gravity forces."""

    evaluate_step: _Evaluator
    settings: CompliantSettings
    penalty: bool
    zeta: float
    k: np.ndarray  # stiffness per contact
    dt: float  # contact step
    settle_steps: int
    settle_speed: float
    in_subtree: np.ndarray  # bodies x contacts
    gravity_force: np.ndarray  # on each subtree, d x bodies
    zeros: np.ndarray  # the force of no contact (n_c), shared by every step that has none
    space: Space = PLANAR


@dataclass(frozen=True)
class _Tally:
    """What the integration records per contact and accumulates, updated in place step by step
    (the arrays are reused: numpy's per-call overhead on these tiny arrays dominates the step)."""

    c: np.ndarray  # damping per contact, tuned at each touchdown (penalty)
    effective_mass: np.ndarray  # 1 / A_ii, updated at each contact's own touchdown
    untouched: np.ndarray  # contacts that have not touched yet
    prev_gap: np.ndarray  # gaps at the start of the last step
    touchdown: np.ndarray
    release: np.ndarray
    max_penetration: np.ndarray
    impulse: np.ndarray  # n_c
    impulse_vector: np.ndarray  # d x n_c
    joint_impulse: np.ndarray  # d x bodies
    times: list[float]
    forces: list[np.ndarray]


@dataclass(frozen=True)
class _End:
    """Where the integration stopped: the state, its normal velocities and kinetic energy, the time,
    the step counts and how it ended."""

    q: np.ndarray
    v: np.ndarray
    rate: np.ndarray
    kinetic: float
    t: float
    n_steps: int
    n_flight: int
    status: CompliantStatus


def _touchdown_state(
    tree: Tree,
    scene: Scene,
    settings: CompliantSettings,
    terrain: Terrain | Heightfield | None,
    base_x: float | None,
    v_minus: np.ndarray | None,
    space: Space = PLANAR,
) -> tuple[_Evaluator, np.ndarray, np.ndarray]:
    """The step function on the ground and the state (q, v) at the first touchdown
    (:func:`simulate_impact`'s arguments)."""
    evaluate_step, q = touchdown_evaluator(tree, scene, settings.gravity, terrain, base_x, space)
    layout = dof_layout(tree.topology(), space)
    if v_minus is None:
        v = pre_impact_velocity(tree.topology(), scene, space)
    else:
        v = np.array(v_minus, dtype=float).ravel()
        if v.shape != (layout.nv,):
            raise ModelError(f"v_minus: expected {layout.nv} generalized velocities, got {v.shape}")
    return evaluate_step, q, v


def landing_ground(
    scene: Scene, terrain: Terrain | Heightfield | None, base_x: float | None, space: Space
) -> tuple[Terrain | Heightfield, float, float]:
    """The ground (the scene's unless ``terrain`` is given; in space a heightfield,
    :func:`spatial_ground`) and the base origin's x and z at touchdown."""
    if space.joint_axis is not None:
        ground, x = scene_ground(scene, terrain, base_x)  # type: ignore[arg-type]
        return ground, x, 0.0
    return spatial_ground(scene, terrain), float(scene.base_x if base_x is None else base_x), float(scene.base_z)


def touchdown_evaluator(
    tree: Tree,
    scene: Scene,
    gravity: float,
    terrain: Terrain | Heightfield | None = None,
    base_x: float | None = None,
    space: Space = PLANAR,
) -> tuple[_Evaluator, np.ndarray]:
    """The step function of ``tree`` on its ground (the scene's unless ``terrain`` is given; in
    space a heightfield, :func:`spatial_ground`) and the configuration at the first touchdown.
    At that configuration (rotation coordinates 0 in space) the rates are the core's velocity. A
    planar tree with centres of mass off its rods evaluates with their offsets (PLANAR_OFFSET)."""
    space = values_space(tree, space)
    topology = tree.topology()
    ground, base_x, base_z = landing_ground(scene, terrain, base_x, space)
    evaluate_step = _Evaluator(compiled_step(topology, ground, space), design_vector(tree, space.body_values), gravity)
    q = touchdown_configuration(tree, ground, base_x, space=space, base_z=base_z)
    return evaluate_step, q


def _contact_parameters(
    s: _State, settings: CompliantSettings, zeta: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Stiffness k, damping c and effective mass 1 / A_ii of each contact at the first touchdown
    ``s``, and the fastest contact frequency omega_max (module docstring)."""
    nc = len(s.gap)
    A0 = s.Jn @ s.minv_jnt
    k = np.full(nc, settings.stiffness)
    effective_mass = 1.0 / np.diag(A0)  # updated at each contact's own touchdown
    if settings.law is ContactLaw.PENALTY:
        c = 2.0 * zeta * np.sqrt(k * effective_mass)
        omega_max = math.sqrt(settings.stiffness * float(np.max(np.linalg.eigvalsh(0.5 * (A0 + A0.T)))))
    else:
        c = np.full(nc, 2.0 * zeta * math.sqrt(settings.stiffness))
        omega_max = math.sqrt(settings.stiffness)
    return k, c, effective_mass, omega_max


def _setup(
    tree: Tree,
    scene: Scene,
    settings: CompliantSettings,
    evaluate_step: _Evaluator,
    s: _State,
    v: np.ndarray,
    zeta: float,
    space: Space = PLANAR,
) -> tuple[_Run, _Tally]:
    """The run's constants (step, settling test) and empty tallies, at the first touchdown ``s``
    with velocity ``v``."""
    k, c, effective_mass, omega_max = _contact_parameters(s, settings, zeta)
    nc = len(k)
    d = s.normal.shape[0]
    down = [0.0, -settings.gravity, 0.0][:d]
    dt = settings.timestep or 2.0 * math.pi / (omega_max * settings.steps_per_period)
    period = 2.0 * math.pi / omega_max
    run = _Run(
        evaluate_step=evaluate_step,
        settings=settings,
        penalty=settings.law is ContactLaw.PENALTY,
        zeta=zeta,
        k=k,
        dt=dt,
        settle_steps=max(1, int(math.ceil(period / dt))),
        settle_speed=settings.settle_fraction * max(abs(scene.speed), float(np.max(np.abs(v))), 1e-12),
        in_subtree=subtree_incidence(tree),
        gravity_force=np.outer(down, subtree_masses(tree)),
        zeros=np.zeros(nc),
        space=space,
    )
    tally = _Tally(
        c=c,
        effective_mass=effective_mass,
        untouched=np.ones(nc, dtype=bool),
        prev_gap=s.gap.copy(),
        touchdown=np.full(nc, np.nan),
        release=np.full(nc, np.nan),
        max_penetration=np.zeros(nc),
        impulse=np.zeros(nc),
        impulse_vector=np.zeros((d, nc)),
        joint_impulse=np.zeros((d, tree.n_bodies)),
        times=[],
        forces=[],
    )
    return run, tally


def _touch_down(s: _State, touching: np.ndarray, t: float, prev_t: float, run: _Run, tally: _Tally) -> bool:
    """Record the contacts that touch at ``s`` for the first time: touchdown time (linear
    interpolation of the crossing within the last step, ``prev_t`` to ``t``), effective mass and,
    penalty law, the damping tuned to e on it. True when some did."""
    new = touching & tally.untouched
    if not new.any():
        return False
    frac = -s.gap[new] / np.maximum(tally.prev_gap[new] - s.gap[new], 1e-300)
    tune_damping(s, new, t - (t - prev_t) * np.minimum(frac, 1.0), run, tally)
    return True


def tune_damping(s: _State, new: np.ndarray, touchdown: np.ndarray | float, run: _Run, tally: _Tally) -> None:
    """Record the ``new`` contacts' touchdown at ``touchdown`` (s), their effective mass at ``s``
    and, penalty law, the damping tuned to e on it (the effective mass the contact meets)."""
    tally.touchdown[new] = touchdown
    tally.untouched[new] = False
    tally.effective_mass[new] = 1.0 / np.einsum("cv,vc->c", s.Jn[new], s.minv_jnt[:, new])
    if run.penalty:
        tally.c[new] = 2.0 * run.zeta * np.sqrt(run.k[new] * tally.effective_mass[new])


def _normal_forces(s: _State, touching: np.ndarray, any_touching: bool, run: _Run, c: np.ndarray) -> np.ndarray:
    """The contact law's normal forces at ``s`` (damping ``c``); zero off the ground."""
    if not any_touching:
        return run.zeros
    if run.penalty:
        f = -run.k * s.gap - c * s.rate
        f[(f < 0.0) | ~touching] = 0.0
        return f
    return _constraint_forces(s, touching, run.settings.stiffness, c[0] if len(c) else 0.0, run.settings.impedance)


def _impact_over(
    s: _State, touching: np.ndarray, any_loaded: bool, untouched: np.ndarray, still: int, run: _Run
) -> tuple[CompliantStatus | None, int]:
    """After the first touchdown, whether the impact has ended at ``s``: ``SEPARATED`` when nothing
    pushes and no contact approaches the ground that is touching or has not touched yet (any
    contact, with ``follow_recontacts``); ``SETTLED`` when the loaded contacts have moved slower
    than the settling speed for ``settle_steps`` steps (``still``: so far); else None. With the
    updated ``still``."""
    if not any_loaded:
        approaching = s.rate < 0.0
        if run.settings.follow_recontacts:
            blocking = approaching
        else:
            blocking = approaching & (touching | untouched)
        if not blocking.any():
            return CompliantStatus.SEPARATED, still
        return None, 0
    if np.abs(s.rate[touching]).max() < run.settle_speed:
        still += 1
        return (CompliantStatus.SETTLED if still >= run.settle_steps else None), still
    return None, 0


def _loaded_acceleration(
    s: _State, f: np.ndarray, loaded: np.ndarray, t: float, run: _Run, tally: _Tally
) -> np.ndarray:
    """The acceleration under the contact forces ``f`` at ``s``; their impulses and the joint
    impulses over the step starting at ``t`` are added to the tally, the loaded contacts' release
    time moved to its end."""
    dt = run.dt
    a = s.free + s.minv_jnt @ f
    F = s.normal * f  # d x contacts
    # joint forces (parent onto child) at this state: Newton's law for each subtree
    momentum_rate = (s.subtree_jacobian @ a).reshape(-1, F.shape[0]).T + s.subtree_bias
    joint_force = momentum_rate - F @ run.in_subtree.T - run.gravity_force
    np.add(tally.joint_impulse, dt * joint_force, out=tally.joint_impulse)
    np.add(tally.impulse, dt * f, out=tally.impulse)
    np.add(tally.impulse_vector, dt * F, out=tally.impulse_vector)
    tally.release[loaded] = t + dt
    return a


def _record(settings: CompliantSettings, tally: _Tally, t: float, f: np.ndarray) -> None:
    """Keep a step's start time and forces when ``settings.record``."""
    if settings.record:
        tally.times.append(t)
        tally.forces.append(f)


def _check_finite(q: np.ndarray, v: np.ndarray, t: float, run: _Run) -> None:
    """Raise NumericalError when the state (q, v) at ``t`` is no longer finite."""
    if not (math.isfinite(v.sum()) and math.isfinite(q.sum())):
        raise NumericalError(
            f"the compliant integration diverged at t = {t:.3g} s (step {run.dt:.3g} s for stiffness "
            f"{run.settings.stiffness:.3g}): lower the step"
        )


def _integrate(run: _Run, tally: _Tally, s: _State, q: np.ndarray, v: np.ndarray) -> _End:
    """Integrate from the first touchdown (``s`` at (q, v)): semi-implicit Euler contact steps,
    Runge-Kutta flight steps between touchdowns, until the impact ends or ``max_time``."""
    settings, evaluate_step = run.settings, run.evaluate_step
    status = CompliantStatus.TIMEOUT
    still = 0
    t = prev_t = 0.0
    n_steps = n_flight = 0
    any_touched = False
    # The loop runs a few hundred to tens of thousands of times: flags are kept as Python bools and
    # arrays are reused, since numpy's per-call overhead on these tiny arrays dominates the step.
    while True:
        touching = s.gap < 0.0
        any_touching = bool(touching.any())
        if n_steps and any_touching and not any_touched or (any_touched and tally.untouched.any() and any_touching):
            any_touched = _touch_down(s, touching, t, prev_t, run, tally) or any_touched
        f = _normal_forces(s, touching, any_touching, run, tally.c)
        loaded = f > 0.0
        any_loaded = any_touching and bool(loaded.any())
        if any_touched:  # stop: nothing pushes and nothing approaches, or at rest
            ended, still = _impact_over(s, touching, any_loaded, tally.untouched, still, run)
            if ended is not None:
                status = ended
                break
        if t >= settings.max_time:
            break
        tally.prev_gap[:] = s.gap
        prev_t = t
        if settings.flight_step and not any_touching:
            flown = _flight(evaluate_step, q, v, settings.flight_step, 2.0 * run.dt)
            if flown is not None:
                q, v, h = flown
                t += h
                n_flight += 1
                _check_chart(q, run.space, t)
                _record(settings, tally, prev_t, run.zeros)
                s = evaluate_step(q, v)
                continue
            s = evaluate_step(q, v)  # the trial flight overwrote the evaluator's state
        a = _loaded_acceleration(s, f, loaded, t, run, tally) if any_loaded else s.free
        if any_touching:
            np.maximum(tally.max_penetration, -s.gap, out=tally.max_penetration)
        v = v + run.dt * a
        q = q + run.dt * v
        _record(settings, tally, t, f)
        t += run.dt
        n_steps += 1
        _check_finite(q, v, t, run)
        _check_chart(q, run.space, t)
        s = evaluate_step(q, v)
    return _End(q, v, s.rate.copy(), float(s.kinetic[0]), t, n_steps, n_flight, status)


def _result(
    run: _Run, tally: _Tally, end: _End, q0: np.ndarray, v0: np.ndarray, energy_before: float
) -> CompliantResult:
    """The :class:`CompliantResult` of a finished integration (``q0``, ``v0``: at the first
    touchdown, with kinetic energy ``energy_before``)."""
    settings, touchdown = run.settings, tally.touchdown
    internal, magnitude = joint_impulses(tally.joint_impulse)
    energy_after = end.kinetic
    return CompliantResult(
        external=tally.impulse,
        external_vector=tally.impulse_vector.T.copy(),
        internal=internal,
        internal_magnitude=magnitude,
        external_norm=float(np.linalg.norm(tally.impulse)),
        internal_norm=float(np.linalg.norm(magnitude)),
        touchdown_time=touchdown,
        release_time=tally.release,
        touchdown_order=touchdown_order(touchdown, run.dt),
        recontacting=tuple(int(i) for i in np.flatnonzero(np.isfinite(touchdown) & (end.rate < 0.0))),
        max_penetration=tally.max_penetration,
        time=np.array(tally.times),
        force=np.array(tally.forces).reshape(len(tally.forces), len(touchdown)),
        q_minus=q0,
        q_plus=end.q,
        v_minus=world_velocity(q0, v0, run.space),
        v_plus=world_velocity(end.q, end.v, run.space),
        energy_before=energy_before,
        energy_after=energy_after,
        energy_gain=energy_after > energy_before * (1.0 + 1e-9),
        stiffness=run.k,
        damping=tally.c,
        effective_mass=tally.effective_mass,
        damping_ratio=run.zeta,
        timestep=run.dt,
        n_steps=end.n_steps,
        n_flight_steps=end.n_flight,
        duration=end.t,
        status=end.status,
        law=settings.law,
        model=f"compliant ({settings.law.value}, semi-implicit Euler), {run.space.name}",
    )


def simulate_impact(
    tree: Tree,
    scene: Scene,
    settings: CompliantSettings = CompliantSettings(),
    terrain: Terrain | None = None,
    base_x: float | None = None,
    v_minus: np.ndarray | None = None,
    space: Space = PLANAR,
) -> CompliantResult:
    """Integrate the landing of ``tree`` through the impact with compliant contacts.

    Args:
        tree: the floating tree; its angles are the touchdown configuration.
        scene: speed (straight down, unless ``v_minus``), restitution (tunes the damping);
            ``scene.selection`` is not used: the geometry decides which contacts touch and when.
        settings: contact law, stiffness, step, gravity (:class:`CompliantSettings`).
        terrain: overrides ``scene.terrain``, the ground profile (default: the scene's).
        base_x: overrides ``scene.base_x``, the x of the base origin at touchdown (m) placing the
            tree over the terrain (default: the scene's).
        v_minus: generalized velocity at the first touchdown (base vx, vy, omega, joint rates;
            in space vx, vy, vz, wx, wy, wz, joint rates); default: the scene's approach
            (:func:`impulse_core.evaluate.pre_impact_velocity`).
        space: PLANAR, or SPATIAL: the ground is then ``scene.heightfield`` (or ``terrain``, a
            ``Heightfield``), the base placed at (``scene.base_x``, ``scene.base_z``); impulse
            vectors, joint impulses and momenta have three components; ``q_minus``/``q_plus``
            hold the base origin, its rotation coordinates (:func:`chart_rotation`) and the joint
            angles; ``v_minus``/``v_plus`` the core's velocities (world angular velocity).

    Raises:
        ModelError: friction (the rung is frictionless) or a restitution it cannot represent.
        NumericalError: the integration blew up (non-finite state).
    """
    if scene.friction > 0:
        raise ModelError("scene.friction: the compliant rung models frictionless contact only (friction: 0)")
    space = values_space(tree, space)  # a planar tree with centres of mass off its rods: their offsets too
    evaluate_step, q, v = _touchdown_state(tree, scene, settings, terrain, base_x, v_minus, space)
    zeta = (
        damping_ratio_for_restitution(scene.restitution) if settings.damping_ratio is None else settings.damping_ratio
    )
    s = evaluate_step(q, v)
    run, tally = _setup(tree, scene, settings, evaluate_step, s, v, zeta, space)
    q0, v0 = q.copy(), v.copy()
    energy_before = float(s.kinetic[0])
    end = _integrate(run, tally, s, q, v)
    return _result(run, tally, end, q0, v0, energy_before)


def relative_difference(pairs: list[tuple[Any, Any]]) -> float:
    """``MODEL_FORMAT.md``'s relative difference: max |a_i - b_i| / max |b_i| per pair of lists
    (a, b), the largest over the pairs (a pair whose reference is all zero is skipped)."""
    worst = 0.0
    for x, y in pairs:
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        scale = float(np.max(np.abs(y), initial=0.0))
        if scale > 0:
            worst = max(worst, float(np.max(np.abs(x - y))) / scale)
    return worst


def compliant_difference(a: CompliantResult, b: CompliantResult) -> float:
    """Relative difference of the external and internal impulses (:func:`relative_difference`)."""
    return relative_difference([(a.external, b.external), (a.internal_magnitude, b.internal_magnitude)])


#: :func:`simulate_to_tolerance`'s methods: adaptive Dormand-Prince steps, or doubled fixed steps.
ADAPTIVE, DOUBLING = "adaptive", "doubling"


def simulate_to_tolerance(
    tree: Tree,
    scene: Scene,
    settings: CompliantSettings,
    tolerance: float,
    max_doublings: int = 7,
    space: Space = PLANAR,
    method: str = ADAPTIVE,
) -> CompliantResult:
    """The compliant landing to ``tolerance`` (relative, :func:`compliant_difference`), with its
    error estimate. ``method`` :data:`ADAPTIVE` (default): Dormand-Prince 5(4) steps between
    located contact switches, the local tolerance refined until two runs agree
    (:func:`impulse_core.timedomain.adaptive.adaptive_to_tolerance`). :data:`DOUBLING`:
    :func:`simulate_impact` with the steps per contact period doubled from ``settings``' until
    two runs differ by at most ``tolerance`` (the method is first order, so that difference
    estimates the finer run's error); the finer run, with the estimate. Either way an unmet
    tolerance after ``max_doublings`` refinements: the estimate says so (the caller warns)."""
    if method == ADAPTIVE:
        from impulse_core.timedomain.adaptive import adaptive_to_tolerance  # it builds on this module

        return adaptive_to_tolerance(tree, scene, settings, tolerance, max_doublings, space)
    if method != DOUBLING:
        raise ModelError(f"compliant: unknown refinement method {method!r} (choices: {ADAPTIVE}, {DOUBLING})")
    n = settings.steps_per_period
    previous = simulate_impact(tree, scene, settings, space=space)
    error = math.inf
    for _ in range(max_doublings):
        n *= 2.0
        current = simulate_impact(tree, scene, replace(settings, steps_per_period=n), space=space)
        error = compliant_difference(current, previous)
        previous = current
        if error <= tolerance:
            break
    return replace(previous, steps_per_period=n, error_estimate=error, tolerance=tolerance)


__all__ = [
    "STEPS_PER_PERIOD_RANGE",
    "STIFFNESS_RANGE",
    "TOUCHDOWN_CLEARANCE",
    "CompliantResult",
    "CompliantSettings",
    "CompliantStatus",
    "ContactLaw",
    "clipped_restitution",
    "compiled_dynamics",
    "configured_design",
    "damping_ratio_for_restitution",
    "dynamics_function",
    "scene_ground",
    "spatial_ground",
    "touchdown_evaluator",
    "world_velocity",
    "chart_rates",
    "chart_rotation",
    "continued_rotation_vector",
    "simulate_impact",
    "simulate_to_tolerance",
    "compliant_difference",
    "relative_difference",
    "subtree_incidence",
    "subtree_masses",
    "touchdown_configuration",
    "touchdown_order",
]
