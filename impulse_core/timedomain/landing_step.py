"""The landing's integrator steps (Runge-Kutta 4, ROS2 and Radau IIA) and projection as compiled
CasADi functions (plane and space).

:meth:`impulse_core.timedomain.events.run._Landing.rk4_step` (and ``implicit_step``, ROS2) builds
each stage's rows and solves them in numpy, which costs ~10 x the dynamics call. Here one SX graph
per integrator, topology, terrain and set of joints with stops holds the whole step for every
mode: every possible row is present (each contact's normal row, each stop's row, then each
contact's row of each tangent in turn) and the mode enters as numbers. A row is active
(``active`` = 1) or not (0): an inactive row is replaced by an identity row with a zero
right-hand side, so its multiplier is 0 and the active rows' system is the mode's
(:func:`impulse_core.timedomain.events.forces._accelerations`, and ROS2's ``_constrained_solve`` with
W = M + g h D + g^2 h^2 K for M) exactly. Its Delassus matrix and the mass matrix are solved by
Gaussian elimination without pivoting (``landing_derivatives._solve``): the mass matrix is
positive definite, the masked Delassus matrix block diagonal in the active and inactive rows, the
active block that of the numpy path.

The function also returns what the landing loop asks of the step's end point: the witnesses'
ingredients (gaps, normal velocities, slip, contact forces, stop forces in the mode), the linear
momentum at both ends and the step's momentum balance but for the weight (``balance``: the change
of momentum minus the step's impulses as vectors, ``vectors``: along the end's normals and
tangents, but on a sloped heightfield each stage's force along that stage's own normal and
tangents, since a contact sliding across a curved cell turns its normal within a step and the
end's directions would leave a residual of first order in the step; ``terms``: the momentum's
terms at both ends, the scale it rounds at), the normals and the kinetic energy (the divergence
check), so that a plain step costs one call; and the projection
that follows it (:func:`landing_projection_function`, the same masked rows: positions, then
velocities) where its placement is the mode's own. Redundant modes (least-norm forces and
corrections) and non-finite results (singular rows) are left to the numpy path.

In space (a heightfield's normals) each contact has two tangent rows (t_x, t_z,
:func:`landing.tangent_basis`), ``direction`` holds each sliding contact's mode direction d (two
numbers), and its friction's direction u is :func:`landing.slip_direction` of the slip at each
stage: s / |s| while s . d > 0 and |s| is above ``floor``, regularised below the step's ``core``
(:meth:`landing._Landing.steer`, computed in numpy before the step), else d; the SX is
:func:`landing_derivatives.slip_direction_expression`, the replay's. The slip and tangential
forces of the end are n_c x 2, the normals n_c x 3; the base's rotation-vector coordinates are
:func:`landing.landing_function`'s (q' = v), and a re-centred chart's design vector is set by
:meth:`CompiledStep.set_design`.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import casadi as ca
import numpy as np

from impulse_core.compile.cache import default_root
from impulse_core.compile.codegen import cached_function, compile_function
from impulse_core.kinematics.spatial import PLANAR, Space
from impulse_core.model.heightfield import Heightfield
from impulse_core.model.terrain import Terrain
from impulse_core.timedomain.compliant import BufferedFunction
from impulse_core.timedomain.events.point import _Joints, _any, momentum_terms
from impulse_core.timedomain.events.rows import _Mode, _mode_bytes
from impulse_core.timedomain.events.run import _Landing
from impulse_core.timedomain.events.settings import RADAU_A, RADAU_B, RADAU_TOL, ROS2_GAMMA
from impulse_core.timedomain.landing import AUTO_CODE, C_CODE, IMPLICIT, RADAU, RK4, VM_CODE, landing_function
from impulse_core.timedomain.landing_derivatives import (
    _factor,
    _solve,
    _substitute,
    slip_direction_expression,
    spatial_contact_rows,
)

STEP_INPUTS = ("q", "v", "h", "active", "direction", "stop", "core", "mu", "floor", "stiffness", "damping", "rest",
               "p", "gravity")
STEP_OUTPUTS = ("q1", "v1", "impulse", "momentum0", "momentum1", "gap0", "vn0", "gap", "vn", "slip", "fn", "ft",
                "stop_force", "normal", "kinetic", "balance", "vectors", "terms")
#: The Radau IIA step's further input and outputs (:func:`_radau`): its stages' Z before and after
#: its Newton iterations, and their corrections' sizes.
RADAU_INPUTS, RADAU_OUTPUTS = ("z0",), ("newton", "z")
#: Simplified Newton iterations unrolled in the compiled Radau IIA step (:func:`_radau`), a divisor of
#: landing.RADAU_ITERATIONS: random files 33096, 33053 and 32700 converge in 3 to 4, 4 to 6 and 6 to 12
#: (RADAU_TOL); a step not converged by then goes on from its Z in another call
#: (:meth:`landing._Landing.radau_once`). 33053's first 30 ms took 1.57 s at 6, 1.91 s at 4 (33491's
#: 3.4 s at either).
RADAU_UNROLLED = 6
#: CasADi options of the step and projection. Not common subexpression elimination: it makes
#: spatial case 3's step 11 % shorter (216861 -> 192431 instructions, ~15 % faster on the virtual
#: machine) but its graph's build 3.0 s instead of 0.2 s, more than a short landing takes.
OPTIONS: dict = {}


@dataclass(frozen=True)
class _Args:
    """The step's symbolic inputs other than (q, v, h)."""

    active: ca.SX  # per row (normal rows, stop rows, tangent rows: each tangent's in turn): 1 closed, 0 open
    direction: ca.SX  # per contact: its sliding friction's mode direction d (the plane: +-1; space: 2), or 0
    stop: ca.SX  # per stop row: the stop's side (-1 lower, +1 upper)
    core: ca.SX  # space, per contact: the step's regularisation (landing._Landing.steer)
    mu: ca.SX
    floor: ca.SX  # space: the slip speed below which a sliding contact keeps d
    stiffness: ca.SX
    damping: ca.SX
    rest: ca.SX
    p: ca.SX
    gravity: ca.SX


def _tangents_of(fn: ca.Function) -> int:
    """Tangents per contact of a landing function: 1 in the plane, 2 in space."""
    return fn.size1_out(1) - 1


def _point(fn: ca.Function, q: ca.SX, v: ca.SX, x: _Args) -> dict:
    """The dynamics at (q, v) in contact coordinates: normal rows and each tangent's rows (the
    plane: the normal turned by -90 degrees; space: t_x, t_z, :func:`landing.tangent_basis`;
    ``tangent``: each tangent's d x n_c directions), the slip per tangent, the joint laws' torques."""
    gap, normal, J, bias, M, force, kinetic, momentum, _, _ = fn(q, v, x.p, x.gravity)
    if _tangents_of(fn) == 1:
        nx, ny = normal[0, :].T, normal[1, :].T
        Jx, Jy, bx, by = J[0::2, :], J[1::2, :], bias[0::2], bias[1::2]
        rows = dict(Jn=ca.diag(nx) @ Jx + ca.diag(ny) @ Jy, Jt=[ca.diag(ny) @ Jx - ca.diag(nx) @ Jy],
                    bn=nx * bx + ny * by, bt=[ny * bx - nx * by])
        tangent = [ca.vertcat(ny.T, -nx.T)]
    else:
        _, tangents, rows = spatial_contact_rows(normal, J, bias)
        tangent = [ca.horzcat(*[t[a] for t in tangents]) for a in range(2)]
    return dict(
        gap=gap, normal=normal, tangent=tangent, M=M, slip=[Jt @ v for Jt in rows["Jt"]],
        f=force - x.stiffness * (q - x.rest) - x.damping * v, kinetic=kinetic, momentum=momentum[:, 0], **rows,
    )


def _directions(pt: dict, x: _Args) -> list[ca.SX]:
    """Per tangent, each contact's component of its sliding friction's direction u: the plane's
    mode direction; in space :func:`landing.slip_direction` of the slip at the point (it turns
    with the slip within the step), 0 where d is 0."""
    if len(pt["Jt"]) == 1:
        return [x.direction]
    u = [slip_direction_expression(ca.vertcat(pt["slip"][0][i], pt["slip"][1][i]), x.direction[2 * i : 2 * i + 2],
                                   x.core[i], x.floor) for i in range(pt["gap"].shape[0])]
    return [ca.vertcat(*[ui[a] for ui in u]) for a in range(2)]


def _masked_rows(pt: dict, x: _Args, stop_dofs: tuple[int, ...]) -> tuple[ca.SX, ca.SX, ca.SX, list[ca.SX]]:
    """The mode's rows at a point, inactive ones zeroed: (G, F, b, u per tangent); F's normal row
    of a sliding contact is n - mu u^T t (:func:`_directions`)."""
    E = _stop_rows(x.stop, stop_dofs, pt["M"].shape[0])
    Jn, Jt, u = pt["Jn"], pt["Jt"], _directions(pt, x)
    Fn = Jn - x.mu * sum(ca.diag(ua) @ Jta for ua, Jta in zip(u, Jt))
    G = ca.diag(x.active) @ ca.vertcat(Jn, E, *Jt)
    F = ca.diag(x.active) @ ca.vertcat(Fn, E, *Jt)
    b = x.active * ca.vertcat(pt["bn"], ca.SX.zeros(len(stop_dofs)), *pt["bt"])
    return G, F, b, u


def _masked_solver(W: ca.SX, G: ca.SX, F: ca.SX, active: ca.SX) -> Callable[[ca.SX, ca.SX], tuple[ca.SX, ca.SX]]:
    """(rhs, row_rhs) -> (x, lambda) with W x = rhs + F^T lambda and G x = row_rhs on the active
    rows (masked rows G, F: the others' lambda = 0; :func:`landing._constrained_solve`); W and
    the rows' matrix G W^-1 F^T are factored once for any number of right-hand sides."""
    w = _factor(W)
    winv_ft = _substitute(w, F.T)
    s = _factor(G @ winv_ft + ca.diag(1 - active))

    def solve(rhs: ca.SX, row_rhs: ca.SX) -> tuple[ca.SX, ca.SX]:
        x0 = _substitute(w, rhs)
        lam = _substitute(s, row_rhs - G @ x0)
        return x0 + winv_ft @ lam, lam

    return solve


def _row_forces(lam: ca.SX, u: list[ca.SX], x: _Args, nc: int, ns: int) -> tuple[ca.SX, list[ca.SX], ca.SX]:
    """(fn, ft per tangent, stop multipliers) of the rows' multipliers: a sliding contact's
    tangential force is -mu u fn (its tangent rows are inactive)."""
    fn, first = lam[:nc], nc + ns
    ft = [-x.mu * ua * fn + lam[first + k * nc : first + (k + 1) * nc] for k, ua in enumerate(u)]
    return fn, ft, lam[nc:first]


def _masked_forces(pt: dict, x: _Args, stop_dofs: tuple[int, ...]) -> tuple[ca.SX, ca.SX, list[ca.SX], ca.SX]:
    """(a, fn, ft per tangent, stop multipliers) of the mode: M a = f + F^T lambda, G a + b = 0 on
    the active rows."""
    G, F, b, u = _masked_rows(pt, x, stop_dofs)
    a, lam = _masked_solver(pt["M"], G, F, x.active)(pt["f"], -b)
    return (a, *_row_forces(lam, u, x, pt["Jn"].shape[0], len(stop_dofs)))


def _derivative(fn: ca.Function, q: ca.SX, v: ca.SX, x: _Args, stop_dofs: tuple[int, ...], pt: dict | None = None
                ) -> tuple[ca.SX, ca.SX, dict]:
    """(a, [fn; ft per tangent], the point) at (q, v) (``pt``: its point, if already built)."""
    pt = _point(fn, q, v, x) if pt is None else pt
    a, fn_, ft, _ = _masked_forces(pt, x, stop_dofs)
    return a, _stacked(fn_, ft), pt


def _stacked(fn: ca.SX, ft: list[ca.SX]) -> ca.SX:
    """[normal per contact; each tangent's per contact] (:func:`landing._stacked`)."""
    return ca.vertcat(fn, *ft)


def _rk4(fn: ca.Function, q: ca.SX, v: ca.SX, h: ca.SX, x: _Args, stop_dofs: tuple[int, ...], start: dict
         ) -> tuple[ca.SX, ca.SX, ca.SX, ca.SX]:
    """One classical RK4 step: (q1, v1, contact impulses [normal; each tangent's], their world
    vectors by stage: :func:`_force_vectors`) (:meth:`landing._Landing.rk4_step`; ``start``: the
    point at (q, v))."""
    a1, f1, p1 = _derivative(fn, q, v, x, stop_dofs, start)
    v2 = v + 0.5 * h * a1
    a2, f2, p2 = _derivative(fn, q + 0.5 * h * v, v2, x, stop_dofs)
    v3 = v + 0.5 * h * a2
    a3, f3, p3 = _derivative(fn, q + 0.5 * h * v2, v3, x, stop_dofs)
    v4 = v + h * a3
    a4, f4, p4 = _derivative(fn, q + h * v3, v4, x, stop_dofs)
    q1 = q + h / 6.0 * (v + 2 * v2 + 2 * v3 + v4)
    v1 = v + h / 6.0 * (a1 + 2 * a2 + 2 * a3 + a4)
    vectors = h / 6.0 * (_force_vectors(p1, f1) + 2 * _force_vectors(p2, f2) + 2 * _force_vectors(p3, f3)
                         + _force_vectors(p4, f4))
    return q1, v1, h / 6.0 * (f1 + 2 * f2 + 2 * f3 + f4), vectors


def _ros2(fn: ca.Function, q: ca.SX, v: ca.SX, h: ca.SX, x: _Args, stop_dofs: tuple[int, ...], start: dict
          ) -> tuple[ca.SX, ca.SX, ca.SX, ca.SX]:
    """One ROS2 step with the joint laws in its matrix W = M + g h D + g^2 h^2 K, the mode's rows
    those of the start (:meth:`landing._Landing.implicit_step`, whose docstring derives it); its
    impulses as :func:`_rk4`'s, the stages' forces along their own points' directions."""
    g = ROS2_GAMMA * h
    nc, ns = start["Jn"].shape[0], len(stop_dofs)
    G, F, b, u = _masked_rows(start, x, stop_dofs)
    solve = _masked_solver(start["M"] + ca.diag(g * x.damping + g * g * x.stiffness), G, F, x.active)
    k1v, nu1 = solve(start["f"] - g * x.stiffness * v, -b)
    k1q = v + g * k1v
    q2, v2 = q + h * k1q, v + h * k1v
    a2, f2, p2 = _derivative(fn, q2, v2, x, stop_dofs)
    rq, rv = v2 - 2.0 * k1q, a2 - 2.0 * k1v
    k2v, nu2 = solve(start["M"] @ rv - g * x.stiffness * rq, G @ rv)
    k2q = rq + g * k2v
    f1, f3 = (_stacked(*_row_forces(nu, u, x, nc, ns)[:2]) for nu in (nu1, nu2))
    vectors = 0.5 * h * (_force_vectors(start, f1 + f3) + _force_vectors(p2, f2))
    return q + 0.5 * h * (3.0 * k1q + k2q), v + 0.5 * h * (3.0 * k1v + k2v), 0.5 * h * (f1 + f2 + f3), vectors


def _radau(fn: ca.Function, q: ca.SX, v: ca.SX, h: ca.SX, x: _Args, stop_dofs: tuple[int, ...], start: dict,
           z0: ca.SX) -> tuple[ca.SX, ...]:
    """RADAU_UNROLLED simplified Newton iterations of the two-stage Radau IIA step from its stages'
    ``z0`` = [Z_1; Z_2] (each Z_i over (q, v); :meth:`landing._Landing.radau_newton`, whose
    docstring derives it): (q1, v1, impulses, their vectors by stage as :func:`_rk4`'s, each
    iteration's correction size max |dZ| / (RADAU_TOL (1 + |y|)), the stages' Z after them). The
    Newton matrix I - h A x J, J = [[0, I], [-C K, -C D]] (C the mode's constrained inverse mass at
    the start), is eliminated over the stages' q parts: (I + h A x C D + h^2 A^2 x C K) dv = r_v -
    h (A x C K) r_q, dq = r_q + h (A x I) dv, its matrix factored once."""
    nv = q.shape[0]
    G, F, _, _ = _masked_rows(start, x, stop_dofs)
    C = _masked_solver(start["M"], G, F, x.active)(ca.SX.eye(nv), ca.SX.zeros(G.shape[0], nv))[0]
    CK, CD = C @ ca.diag(x.stiffness), C @ ca.diag(x.damping)
    A, A2 = RADAU_A, RADAU_A @ RADAU_A
    newton = _factor(ca.vertcat(*[ca.horzcat(*[float(i == k) * ca.SX.eye(nv) + h * A[i, k] * CD + h * h * A2[i, k] * CK
                                               for k in range(2)]) for i in range(2)]))
    scale = RADAU_TOL * (1.0 + ca.fabs(ca.vertcat(q, v)))
    Z, sizes = [z0[: 2 * nv], z0[2 * nv :]], []
    for _ in range(RADAU_UNROLLED):
        stages = [(v + z[nv:], *_derivative(fn, q + z[:nv], v + z[nv:], x, stop_dofs)) for z in Z]
        r = [h * (A[i, 0] * ca.vertcat(stages[0][0], stages[0][1]) + A[i, 1] * ca.vertcat(stages[1][0], stages[1][1]))
             - Z[i] for i in range(2)]
        rhs = [r[i][nv:] - h * CK @ (A[i, 0] * r[0][:nv] + A[i, 1] * r[1][:nv]) for i in range(2)]
        dv = _substitute(newton, ca.vertcat(*rhs))
        dv = [dv[:nv], dv[nv:]]
        dZ = [ca.vertcat(r[i][:nv] + h * (A[i, 0] * dv[0] + A[i, 1] * dv[1]), dv[i]) for i in range(2)]
        Z = [Z[i] + dZ[i] for i in range(2)]
        sizes.append(ca.mmax(ca.vertcat(*[ca.fabs(d) / scale for d in dZ])))
    impulse = h * (RADAU_B[0] * stages[0][2] + RADAU_B[1] * stages[1][2])
    vectors = h * (RADAU_B[0] * _force_vectors(stages[0][3], stages[0][2])
                   + RADAU_B[1] * _force_vectors(stages[1][3], stages[1][2]))
    return q + Z[1][:nv], v + Z[1][nv:], impulse, vectors, ca.vertcat(*sizes), ca.vertcat(*Z)


def _force_vectors(pt: dict, forces: ca.SX) -> ca.SX:
    """Each contact's vector (d x n_c, world frame) of ``forces`` ([normal; each tangent's] per
    contact) along the point's normals and tangents (:func:`landing.contact_vectors`)."""
    nc = pt["gap"].shape[0]
    directions = [pt["normal"], *pt["tangent"]]
    return sum(d * ca.repmat(forces[k * nc : (k + 1) * nc].T, d.shape[0], 1) for k, d in enumerate(directions))


def _impulse_vector(pt: dict, impulse: ca.SX) -> ca.SX:
    """The contact impulses' sum (world frame) of ``impulse`` ([normal; each tangent's] per
    contact) along the normals and tangents at the point (:func:`landing.impulse_vector`)."""
    nc = pt["gap"].shape[0]
    directions = [pt["normal"], *pt["tangent"]]
    return sum(d @ impulse[k * nc : (k + 1) * nc] for k, d in enumerate(directions))


#: Each integrator's step (:data:`landing.RK4`, :data:`landing.IMPLICIT`, :data:`landing.RADAU`) and its
#: function's name.
_INTEGRATORS = {RK4: (_rk4, "landing_step"), IMPLICIT: (_ros2, "landing_implicit_step"),
                RADAU: (_radau, "landing_radau_step")}


@functools.lru_cache(maxsize=16)
def landing_step_function(topology, terrain: Terrain | Heightfield, stop_dofs: tuple[int, ...],
                          space: Space = PLANAR, method: str = RK4) -> ca.Function:
    """One step of the landing's integrator ``method`` (classical RK4, ROS2: ``implicit``, or Radau
    IIA: ``radau``, with its Newton iterations' :data:`RADAU_OUTPUTS`) in a mode given as numbers
    (module docstring), and its end point's figures (:data:`STEP_OUTPUTS`); ``stop_dofs``: the
    DOFs with stops; ``space``: the plane, PLANAR_OFFSET (centres of mass off the rods: the design
    vector's layout) or space (``terrain`` a heightfield)."""
    fn = landing_function(topology, terrain, space)
    nv, nc, ns, nt = fn.size1_in(0), fn.size1_out(0), len(stop_dofs), _tangents_of(fn)
    q, v, h = ca.SX.sym("q", nv), ca.SX.sym("v", nv), ca.SX.sym("h")
    x = _Args(
        ca.SX.sym("active", (1 + nt) * nc + ns), ca.SX.sym("direction", nt * nc), ca.SX.sym("stop", ns),
        ca.SX.sym("core", nc), ca.SX.sym("mu"), ca.SX.sym("floor"),
        ca.SX.sym("stiffness", nv), ca.SX.sym("damping", nv), ca.SX.sym("rest", nv),
        ca.SX.sym("p", fn.size1_in(2)), ca.SX.sym("gravity"),
    )
    integrate, name = _INTEGRATORS[method]
    extra = [ca.SX.sym("z0", 4 * nv)] if method == RADAU else []
    start = _point(fn, q, v, x)
    q1, v1, impulse, vectors, *newton = integrate(fn, q, v, h, x, stop_dofs, start, *extra)  # Radau: RADAU_OUTPUTS
    end = _point(fn, q1, v1, x)
    _, fn1, ft1, stop1 = _masked_forces(end, x, stop_dofs)
    if not isinstance(terrain, Heightfield) or terrain.is_flat:  # normals that turn only at events
        vectors, applied = _force_vectors(end, impulse), _impulse_vector(end, impulse)
    else:  # the normals turn under a sliding contact: each stage's force along its own
        applied = ca.sum2(vectors)
    outs = [q1, v1, impulse, start["momentum"], end["momentum"], start["gap"], start["Jn"] @ v, end["gap"],
            end["Jn"] @ v1, ca.horzcat(*end["slip"]), fn1, ca.horzcat(*ft1), stop1, end["normal"], end["kinetic"],
            end["momentum"] - start["momentum"] - applied, vectors,
            ca.vertcat(momentum_terms(start["M"], v, nt + 1), momentum_terms(end["M"], v1, nt + 1)), *newton]
    inputs = [q, v, h, x.active, x.direction, x.stop, x.core, x.mu, x.floor, x.stiffness, x.damping, x.rest, x.p,
              x.gravity, *extra]
    names = STEP_INPUTS + (RADAU_INPUTS if extra else ()), STEP_OUTPUTS + (RADAU_OUTPUTS if extra else ())
    return ca.Function(name, inputs, outs, list(names[0]), list(names[1]), OPTIONS)


def _masked_correction(M: ca.SX, G: ca.SX, active: ca.SX, residual: ca.SX) -> tuple[ca.SX, ca.SX]:
    """(M^-1 G^T lambda, lambda) with G M^-1 G^T lambda = residual on the active rows of G (the
    others: lambda = 0): the smallest kinetic-metric change that moves the rows by ``residual``."""
    G = ca.diag(active) @ G
    X = _solve(M, G.T)
    lam = _solve(G @ X + ca.diag(1 - active), active * residual)
    return X @ lam, lam


def _stop_rows(stop: ca.SX, stop_dofs: tuple[int, ...], nv: int) -> ca.SX:
    """Each stop's velocity row: -side e_j (its margin's rate)."""
    E = ca.SX.zeros(len(stop_dofs), nv)
    for r, j in enumerate(stop_dofs):
        E[r, j] = -stop[r]
    return E


@functools.lru_cache(maxsize=16)
def landing_projection_function(topology, terrain: Terrain | Heightfield, stop_dofs: tuple[int, ...],
                                space: Space = PLANAR) -> ca.Function:
    """:meth:`landing._Landing.project` for a mode given as numbers: the position correction dq
    (gaps of the ``place`` rows' contacts and their stops' margins to ``limit``, to zero), then
    the velocity projection onto the mode's rows (``active``, ``stop``: as the step's), both
    with the rows at (q, v) (q_new = q - dq); its impulses [normal, tangential] per contact."""
    fn = landing_function(topology, terrain, space)
    nv, nc, ns, nt = fn.size1_in(0), fn.size1_out(0), len(stop_dofs), _tangents_of(fn)
    q, v, p, gravity = ca.SX.sym("q", nv), ca.SX.sym("v", nv), ca.SX.sym("p", fn.size1_in(2)), ca.SX.sym("gravity")
    place, place_stop, limit = ca.SX.sym("place", nc + ns), ca.SX.sym("place_stop", ns), ca.SX.sym("limit", ns)
    active, stop = ca.SX.sym("active", (1 + nt) * nc + ns), ca.SX.sym("stop", ns)
    zeros = ca.SX.zeros(nv)
    x = _Args(active, ca.SX.zeros(nt * nc), stop, ca.SX.zeros(nc), ca.SX(0), ca.SX(0), zeros, zeros, zeros, p, gravity)
    pt = _point(fn, q, v, x)
    margin = ca.vertcat(*[-place_stop[r] * (q[j] - limit[r]) for r, j in enumerate(stop_dofs)]) if ns else ca.SX(0, 1)
    dq, _ = _masked_correction(pt["M"], ca.vertcat(pt["Jn"], _stop_rows(place_stop, stop_dofs, nv)), place,
                               ca.vertcat(pt["gap"], margin))
    # the linear momentum the correction would move at fixed v, given back through the base's
    # translation (:meth:`landing._Landing.momentum_kept`)
    dp = pt["momentum"] - fn(q - dq, v, p, gravity)[7][:, 0]
    kept = v + ca.vertcat(dp / pt["M"][0, 0], ca.SX.zeros(nv - dp.shape[0]))
    G = ca.vertcat(pt["Jn"], _stop_rows(stop, stop_dofs, nv), *pt["Jt"])
    dv, lam = _masked_correction(pt["M"], G, active, -(G @ kept))
    return ca.Function("landing_projection", [q, v, place, place_stop, limit, active, stop, p, gravity],
                       [dq, kept + dv, ca.vertcat(lam[:nc], lam[nc + ns :])],
                       ["q", "v", "place", "place_stop", "limit", "active", "stop", "p", "gravity"],
                       ["dq", "v1", "impulse"], OPTIONS)


@functools.lru_cache(maxsize=16)
def compiled_step_function(topology, terrain: Terrain | Heightfield, stop_dofs: tuple[int, ...],
                           space: Space = PLANAR, method: str = RK4) -> tuple[ca.Function, ca.Function]:
    """:func:`landing_step_function` and :func:`landing_projection_function` as C, built once
    into (or loaded from) the compile cache (:func:`impulse_core.compile.codegen.compile_function`);
    without a C compiler, a warning and the virtual machine's functions."""
    return tuple(compile_function(f, default_root(), fallback=True, drivers=False).function
                 for f in step_functions(topology, terrain, stop_dofs, space, method))


def step_functions(topology, terrain: Terrain | Heightfield, stop_dofs: tuple[int, ...], space: Space = PLANAR,
                   method: str = RK4) -> tuple[ca.Function, ca.Function]:
    """:func:`landing_step_function` and :func:`landing_projection_function` (the virtual machine's)."""
    return (landing_step_function(topology, terrain, stop_dofs, space, method),
            landing_projection_function(topology, terrain, stop_dofs, space))


def cached_step_function(topology, terrain: Terrain | Heightfield, stop_dofs: tuple[int, ...],
                         space: Space = PLANAR, method: str = RK4) -> tuple[ca.Function, ca.Function] | None:
    """:func:`compiled_step_function` if the compile cache already holds both libraries, else
    None (nothing is built: step code ``auto``)."""
    found = tuple(cached_function(f, default_root(), drivers=False)
                  for f in step_functions(topology, terrain, stop_dofs, space, method))
    return None if None in found else found


def compiled_landing_function(topology, terrain: Terrain | Heightfield, space: Space = PLANAR,
                              build: bool = True) -> ca.Function:
    """:func:`landing.landing_function` (the numpy path's dynamics at a point: every event asks it
    two or three times) as C through the compile cache, as the step is; the same arithmetic as
    the virtual machine's (no contraction into fused multiply-adds), so the same numbers. Not
    ``build``: C only if the cache already holds it, else the virtual machine's function."""
    if build:
        return _built_landing_function(topology, terrain, space)
    f = landing_function(topology, terrain, space)
    return cached_function(f, default_root(), drivers=False) or f


@functools.lru_cache(maxsize=16)
def _built_landing_function(topology, terrain: Terrain | Heightfield, space: Space) -> ca.Function:
    return compile_function(landing_function(topology, terrain, space), default_root(), fallback=True,
                            drivers=False).function


def landing_code(run: _Landing) -> tuple[ca.Function, ...]:
    """The functions that step code c compiles for a landing's run (its integrator's step and
    projection, the point's dynamics): what a build ahead of its landings makes
    (:func:`impulse_core.compile.codegen.background_build`, without drivers)."""
    return (*step_functions(run.topology, run.ground, stop_dofs(run.joints), run.space, run.method),
            landing_function(run.topology, run.ground, run.space))


def stop_dofs(joints: _Joints) -> tuple[int, ...]:
    """The DOFs with a stop on either side (each has a stop row in the step)."""
    return tuple(int(j) for j in np.flatnonzero(np.isfinite(joints.lo) | np.isfinite(joints.hi)))


#: A mode stepped this many times on the virtual machine gets its own function (:class:`ModeFunctions`):
#: building it costs ~50 general steps (f3037's ROS2 step: 12 ms; a step 254 us, 81 us in the mode).
SPECIALISE_AFTER = 32
#: At most this many modes' functions are kept (then they are built anew as asked).
SPECIALISED_MODES = 64


class ModeFunctions:
    """The evaluations of a :class:`BufferedFunction` per mode: its own, or on the virtual machine
    for a mode asked for :data:`SPECIALISE_AFTER` times, a copy with the mode's rows (``fixed``:
    the indices of the inputs that say which rows are active and each stop's side) as the
    constants they hold then. CasADi folds them as it builds the copy, so the inactive rows'
    products by 0 and 1 and the sums of their zeros drop out (f3037's ROS2 step: 22121
    instructions, 8073 with two sliding contacts); the rest are the same operations in the same
    order. The sliding directions stay inputs (in space they turn with the slip at every step).
    The copies read and write the function's own arrays."""

    def __init__(self, fn: BufferedFunction, f: ca.Function, fixed: tuple[int, ...], specialise: bool) -> None:
        self.fn, self.f, self.fixed, self.specialise = fn, f, fixed, specialise
        self._modes: dict[bytes, list] = {}  # per mode: [times asked, its evaluation or None]

    def evaluator(self, key: bytes) -> Callable[[], None]:
        """The evaluation for the mode whose rows are ``key`` (:func:`_rows_key`; its inputs
        already set in ``fn.args``)."""
        if not self.specialise:
            return self.fn.evaluate
        entry = self._modes.get(key)
        if entry is None:
            self._modes = self._modes if len(self._modes) < SPECIALISED_MODES else {}
            entry = self._modes[key] = [0, None]
        entry[0] += 1
        if entry[1] is None and entry[0] >= SPECIALISE_AFTER:
            entry[1] = self.bound(self.specialised())
        return self.fn.evaluate if entry[1] is None else entry[1][1]

    def specialised(self) -> ca.Function:
        """``f`` with the ``fixed`` inputs as the constants ``fn.args`` holds (they stay inputs, unused)."""
        f = self.f
        inputs = [ca.SX.sym(f.name_in(i), f.sparsity_in(i)) for i in range(f.n_in())]
        values = [ca.DM(self.fn.args[i]) if i in self.fixed else x for i, x in enumerate(inputs)]
        return ca.Function(f"{f.name()}_mode", inputs, f.call(values), f.name_in(), f.name_out(), OPTIONS)

    def bound(self, f: ca.Function) -> tuple:
        """(buffer, evaluate) of ``f`` on ``fn``'s input and output arrays (the buffer kept alive)."""
        buffer, evaluate = f.buffer()
        for i, a in enumerate(self.fn.args):
            buffer.set_arg(i, memoryview(a))
        for i, r in enumerate(self.fn.flat):
            buffer.set_res(i, memoryview(r))
        return buffer, evaluate


def _rows_key(numbers: tuple[np.ndarray, ...]) -> bytes:
    """A mode's rows (:meth:`CompiledStep.numbers`' active rows and stop sides) as bytes: what a
    mode's own functions fix (:class:`ModeFunctions`)."""
    return numbers[0].tobytes() + numbers[1].tobytes()


@dataclass
class StepEnd:
    """A compiled step's results (copies): the state after it, its contact impulses ([normal,
    tangential] per contact), and its ends' figures in the step's mode (d = 2 in the plane, 3 in
    space; d - 1 tangents per contact)."""

    q: np.ndarray
    v: np.ndarray
    impulse: np.ndarray
    momentum0: np.ndarray  # linear momentum at the start
    momentum1: np.ndarray  # and at the end
    gap0: np.ndarray  # gaps and normal velocities at the start
    vn0: np.ndarray
    gap: np.ndarray  # at the end: gaps, normal and tangential velocities, the mode's forces
    vn: np.ndarray
    slip: np.ndarray  # n_c x (d - 1)
    fn: np.ndarray
    ft: np.ndarray  # n_c x (d - 1)
    stop_force: np.ndarray  # per DOF (0 where no stop row)
    normal: np.ndarray  # n_c x d
    kinetic: float
    #: the momentum balance but for the weight: momentum1 - momentum0 - the step's impulses'
    #: vectors' sum (:meth:`landing._Landing.balanced_step`)
    balance: np.ndarray
    #: the step's impulses per contact as world vectors, d x n_c (a sloped heightfield: by stage)
    vectors: np.ndarray
    #: the linear momentum's terms summed in absolute value at the start (d) and at the end (d):
    #: the scale it rounds at (:func:`~impulse_core.timedomain.events.point.momentum_terms`)
    terms: np.ndarray
    #: Radau IIA: each unrolled Newton iteration's correction size (:func:`_radau`), and the stages' Z (2 x 2 n_v)
    newton: np.ndarray | None = None
    z: np.ndarray | None = None


class CompiledStep(BufferedFunction):
    """:func:`landing_step_function` with the design, gravity, friction and joint laws fixed:
    ``step(q, v, h, mode)`` -> :class:`StepEnd`, or None where the numpy path must answer (a
    redundant mode, or a non-finite result); ``compiled``: as C through the compile cache
    (:func:`impulse_core.compile.codegen.compile_function`; no compiler: the virtual machine);
    ``terrain``: the plane's profile or space's heightfield; ``floor``: the slip speed below which
    a sliding contact keeps its mode's direction (space, :func:`landing.slip_direction`);
    ``method``: the integrator (RK4, IMPLICIT: ROS2, or RADAU: Radau IIA)."""

    def __init__(self, topology, terrain: Terrain | Heightfield, p: np.ndarray, gravity: float, mu: float,
                 joints: _Joints, code: str = VM_CODE, space: Space = PLANAR, floor: float = 0.0,
                 method: str = RK4) -> None:
        self.stop_dofs = stop_dofs(joints)
        vm = step_functions(topology, terrain, self.stop_dofs, space, method)
        if code == C_CODE:
            step, projection = compiled_step_function(topology, terrain, self.stop_dofs, space, method)
        else:
            step, projection = (code == AUTO_CODE and cached_step_function(topology, terrain, self.stop_dofs, space,
                                                                           method)) or vm
        #: whether the functions run as C (no compiler: the virtual machine's, also with ``c``)
        self.compiled = step is not vm[0]
        compiled = self.compiled
        super().__init__(step)
        self.block, self.spans = self.contiguous()
        self.slices = [slice(a, b) for a, b in self.spans]
        self.projection = BufferedFunction(projection)
        #: per mode, the step's and the projection's evaluations (the inputs the mode's rows
        #: set: active, stop; place, place_stop, limit, active, stop)
        self.modes = ModeFunctions(self, step, (3, 5), not compiled)
        self.projection_modes = ModeFunctions(self.projection, projection, (2, 3, 4, 5, 6), not compiled)
        self.nc, self.nt = step.size1_out(10), step.size2_out(9)
        self.set_design(p)
        self.projection.args[8][:] = gravity
        self.dofs = list(self.stop_dofs)
        self.dof_index = np.array(self.dofs, dtype=int)
        self.lo, self.hi = joints.lo[self.dofs], joints.hi[self.dofs]
        self.lo_all, self.hi_all = joints.lo, joints.hi
        self.stopless = np.isneginf(joints.lo) & np.isposinf(joints.hi)  # DOFs that no stop row covers
        for name, value in (("mu", mu), ("floor", floor), ("stiffness", joints.stiffness),
                            ("damping", joints.damping), ("rest", joints.rest), ("gravity", gravity)):
            self.args[STEP_INPUTS.index(name)][:] = value
        self.mu, self.nv = mu, len(joints.stiffness)
        self._numbers: dict[bytes, tuple | None] = {}  # see numbers()

    def step(self, q: np.ndarray, v: np.ndarray, h: float, mode: _Mode, z0: np.ndarray | None = None
             ) -> StepEnd | None:
        """The step from (q, v) in ``mode`` (Radau IIA: its iterations from the stages' ``z0``, 2 x
        2 n_v; None: 0), or None where the numpy path answers."""
        numbers = self.numbers(mode)
        if numbers is None:
            return None
        a = self.args
        a[0][:], a[1][:], a[2][0] = q, v, h
        a[3][:], a[5][:], a[4][:] = numbers
        a[6][:] = mode.core
        if len(a) > len(STEP_INPUTS):
            a[len(STEP_INPUTS)][:] = 0.0 if z0 is None else z0.ravel()
        self.modes.evaluator(_rows_key(numbers))()
        block = self.block.copy()  # every output at once, as views of one copy
        o = [block[s] for s in self.slices]
        total = np.add.reduce  # ndarray.sum's reduction, without its wrapper
        if not np.isfinite(total(o[1]) + total(o[10]) + total(o[11])):  # singular rows: NaN or inf, which propagate
            return None
        stop_force = np.zeros(self.nv)
        stop_force[self.dof_index] = o[12]
        shape = (self.nc, self.nt)
        return StepEnd(o[0], o[1], o[2], o[3], o[4], o[5], o[6], o[7], o[8], o[9].reshape(shape, order="F"), o[10],
                       o[11].reshape(shape, order="F"), stop_force, o[13].reshape(self.out[13].shape, order="F").T,
                       float(o[14][0]), o[15], o[16].reshape(self.out[16].shape, order="F"), o[17],
                       *(o[18], o[19].reshape(2, -1)) if len(o) > 18 else ())

    def set_design(self, p: np.ndarray) -> None:
        """Evaluate with the design vector ``p`` from now on (space: a re-centred base's rotation
        coordinates change it, :meth:`landing._Landing.rechart`)."""
        self.args[STEP_INPUTS.index("p")][:] = p
        self.projection.args[7][:] = p

    def contiguous(self) -> tuple[np.ndarray, list[tuple[int, int]]]:
        """The step's outputs as consecutive slices of one array (one copy per step): the array,
        and each output's (start, end) in it."""
        ends = np.cumsum([0] + [len(r) for r in self.flat])
        block = np.zeros(ends[-1])
        spans = list(zip(ends[:-1].tolist(), ends[1:].tolist()))
        for i, (a, b) in enumerate(spans):
            self.flat[i] = block[a:b]
            self._buf.set_res(i, memoryview(self.flat[i]))
            self.out[i] = self.flat[i].reshape(self.out[i].shape, order="F")
        return block, spans

    def numbers(self, mode: _Mode) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """The mode as the functions' numbers (:meth:`active`, and each contact's sliding
        direction, 0 where open or sticking), kept per mode; None where the numpy path answers (a
        redundant mode, a stop on a DOF without stop rows)."""
        key = _mode_bytes(mode)
        numbers = self._numbers.get(key, False)
        if numbers is False:
            numpy = mode.redundant or np.any(mode.stop[self.stopless])
            sliding = (mode.slip * mode.closed[:, None]).ravel() if self.mu > 0 else np.zeros(mode.slip.size)
            numbers = None if numpy else (*self.active(mode), sliding)
            self._numbers = self._numbers if len(self._numbers) < 256 else {}
            self._numbers[key] = numbers
        return numbers

    def active(self, mode: _Mode) -> tuple[np.ndarray, np.ndarray]:
        """The mode's rows as numbers: per row (normal, stop, each tangent's) whether it is closed,
        and each stop row's side."""
        stops = mode.stop[self.dofs]
        stick = mode.closed & ~mode.sliding & (self.mu > 0)
        return np.concatenate([mode.closed, stops != 0] + [stick] * self.nt), stops

    def project(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """:meth:`landing._Landing.project` of (q, v) onto ``mode``'s rows, the placement's
        being the mode's own (no open contact below the ground, no free joint past a stop before
        or after the correction: the caller checks the first two); None where the numpy path
        must answer (a redundant mode, a joint carried past its stop, a non-finite result)."""
        numbers = self.numbers(mode)
        if numbers is None:
            return None
        a = self.projection.args
        a[0][:], a[1][:] = q, v
        a[5][:], a[6][:] = numbers[:2]
        a[2][:], a[3][:] = a[5][: len(a[2])], a[6]
        a[4][:] = np.where(a[6] > 0, self.hi, self.lo)
        self.projection_modes.evaluator(_rows_key(numbers))()
        dq, v1, impulse = (r.copy() for r in self.projection.flat)
        q1 = q - dq
        free = mode.stop == 0
        carried = _any(free & ((q1 > self.hi_all) | (q1 < self.lo_all)))
        total = np.add.reduce  # ndarray.sum's reduction, without its wrapper
        if carried or not np.isfinite(total(dq) + total(v1)):
            return None
        return q1, v1, impulse


__all__ = ["CompiledStep", "ModeFunctions", "StepEnd", "cached_step_function", "compiled_landing_function",
           "compiled_step_function", "landing_code", "landing_projection_function", "landing_step_function",
           "step_functions"]
