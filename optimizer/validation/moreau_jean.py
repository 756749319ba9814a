"""An independent peer for the whole landing: Moreau-Jean time stepping of the same rigid law on
Pinocchio's dynamics (planar legs on flat ground). Needs `pin` (a test dependency).

footopt's ``landing()`` is event driven (each impact located and solved by the impact law, the
modes chosen between impacts). Moreau-Jean's scheme (Moreau 1988, Jean 1999; Acary & Brogliato,
*Numerical Methods for Nonsmooth Dynamical Systems*, 2008, ch. 10; Siconos's ``MoreauJeanOSI``)
takes fixed steps instead and solves, at every step, the contact law at the velocity level:

    M (v+ - v) = h f(q, v) + J^T P,      q+ = q (+) h v+,
    0 <= U_n+ + e U_n  _|_  P_n >= 0,    |P_t| <= mu P_n with U_t+ = 0 or P_t = -mu P_n sign(U_t+),

U = J v the rows' velocities (contact normals and tangents, the stops' joint rates), e Newton's
coefficient. Impacts and resting contact are the same law at the step's scale, and the scheme
converges at first order in h to the rigid landing, Zeno cascades included (Acary & Brogliato,
sec. 10.1). The rows and the law at a step:

- active: the rows whose gap the step would close, and those loaded in the step before while their
  gap stays within :data:`REST_GAP`;
- e is 0 where the approach is slower than the plastic speed (``MODEL_FORMAT.md``) and for a row
  active in the step before (a resting contact takes no new impact);
- nonsmooth Gauss-Seidel (Moreau's, as Siconos's ``NSGS``: each row's projection in turn) starts
  from the step before's impulses (a warm start): where both staying and leaving solve a resting
  contact's problem (its free normal acceleration turned away from the ground while friction holds
  it), it keeps the rest, as footopt's transition rule does;
- the positions take the velocity after (theta = 1), and a resting contact's gap (loaded, leaving
  slower than the plastic speed) is then set back to 0 by the least mass-weighted change of q, as
  Siconos's ``MoreauJeanDirectProjectionOSI`` does: it would otherwise drift by O(h^2) a step (by
  h^2 a / 2 with the midpoint rule: 1 um in 10 ms).

Nothing of footopt's dynamics, events or impact solvers is used: the mass matrix, the nonlinear
effects and the contact Jacobians are Pinocchio's (:mod:`.pinocchio_bridge`'s tree). Only the model
file's reading (the tree, its touchdown configuration and velocity, the joint laws' arrays) is
shared. :func:`moreau_jean_landing` returns what ``footopt evaluate --json`` reports of a landing
that a comparison uses: the final angles, base and velocity, each contact's total normal impulse,
the largest step impulse (an impact's, plus at most h times the resting forces).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from impulse_core.errors import ModelError
from impulse_core.evaluate import pre_impact_velocity
from impulse_core.kinematics.spatial import PLANAR
from impulse_core.model.joints import JointLaw
from impulse_core.model.tree import Scene, Tree
from impulse_core.timedomain.compliant import touchdown_configuration
from impulse_core.timedomain.events.point import joint_arrays
from impulse_core.timedomain.events.settings import PLASTIC_SPEED
from optimizer.validation.pinocchio_bridge import build, crba_mass_matrix, velocity_map

#: Nonsmooth Gauss-Seidel: sweeps at most, and the change of the impulses (relative) that ends them.
SWEEPS, SWEEP_TOL = 2000, 1e-13
#: A row loaded in the step before stays active while its predicted gap is below this (m): a resting
#: contact's gap moves about 0 (rounding, curvature), and without the margin it would
#: leave and touch again every few steps, each time an impact (restitution above the plastic speed
#: at h = 2e-5 s), so that an impact elsewhere met it in or out of the step by chance (random leg 6
#: of settled_posture.py: a toe's 12 N rest, out for the 4 steps before the plank's end struck, took
#: its share of that impact a step late, 3.5e-3 rad apart at any step). A rebound that rises less
#: than this (slower than sqrt(2 a REST_GAP), 0.6 mm/s at 20 m/s^2) is thus plastic: an approximation.
REST_GAP = 1e-8


@dataclass(frozen=True)
class MoreauJeanLanding:
    """A Moreau-Jean landing's figures, in footopt's coordinates and order (``MODEL_FORMAT.md``)."""

    step: float
    final_angles: np.ndarray  # base absolute angle, then the joint angles in file order
    final_base: np.ndarray  # x, y of the base origin
    final_velocity: np.ndarray  # footopt's generalized velocity
    total_external: np.ndarray  # per contact, the normal impulse over [0, T] (N s)
    peak_external_norm: float  # the largest |P_n| over the steps (N s)
    sweeps: int  # the most Gauss-Seidel sweeps a step took


@dataclass(frozen=True)
class _Leg:
    """The Pinocchio model and footopt's maps: our DOF k is Pinocchio's ``idx_v[k]`` (``idx_q[k]``)."""

    model: pin.Model
    frames: tuple[int, ...]
    permutation: np.ndarray  # v_ours = permutation @ blockdiag(R(theta), I) @ v_pin
    idx_q: np.ndarray  # per joint DOF of ours (after the 3 base DOFs), Pinocchio's q index


def _leg(tree: Tree, gravity: float) -> _Leg:
    """Pinocchio's model of ``tree`` with gravity along -y."""
    built = build(tree)
    model = built.model
    model.gravity.linear[:] = (0.0, -gravity, 0.0)
    theta0 = tree.bodies[0].angle
    permutation = built.T @ np.linalg.inv(velocity_map(theta0, model.nv))
    idx_v = np.argmax(np.abs(permutation[3:]), axis=1)
    idx_q = idx_v + 1  # the planar base: 4 q (x, y, cos, sin) for 3 v; revolute joints 1 and 1
    return _Leg(model, built.contact_frames, np.round(permutation), idx_q)


def _velocity_map(leg: _Leg, q: np.ndarray) -> np.ndarray:
    """T with v_ours = T v_pin at the configuration q (Pinocchio's)."""
    return leg.permutation @ velocity_map(math.atan2(q[3], q[2]), leg.model.nv)


def _to_pin(leg: _Leg, q_ours: np.ndarray, v_ours: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    q = np.zeros(leg.model.nq)
    q[:4] = q_ours[0], q_ours[1], math.cos(q_ours[2]), math.sin(q_ours[2])
    q[leg.idx_q] = q_ours[3:]
    return q, np.linalg.solve(_velocity_map(leg, q), v_ours)


def _rows(leg: _Leg, data: pin.Data, q: np.ndarray, lo: np.ndarray, hi: np.ndarray
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every contact's gap, normal and tangent Jacobian rows (world y and x, Pinocchio's v), and
    each joint DOF's margins to its stops (q - lo, hi - q; ours, inf where none)."""
    model = leg.model
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    gap = np.array([data.oMf[f].translation[1] for f in leg.frames])
    J = [pin.getFrameJacobian(model, data, f, pin.LOCAL_WORLD_ALIGNED) for f in leg.frames]
    angles = q[leg.idx_q]
    return gap, np.array([j[1] for j in J]), np.array([j[0] for j in J]), np.concatenate([angles - lo, hi - angles])


def _nsgs(W: np.ndarray, free: np.ndarray, target: np.ndarray, mu: float, kinds: np.ndarray, pair: np.ndarray,
          start: np.ndarray) -> tuple[np.ndarray, int]:
    """Nonsmooth Gauss-Seidel on U = W P + free from P = ``start``: per normal row (``kinds`` 0)
    0 <= U + target _|_ P >= 0 (``target`` e U before), per tangent row (1) |P| <= mu P_n of its
    normal (``pair``) with U = 0 inside; stops are normal rows. Returns P and the sweeps taken."""
    P = start.copy()
    for sweep in range(1, SWEEPS + 1):
        before = P.copy()
        for i in range(len(free)):
            u = free[i] + W[i] @ P
            if kinds[i] == 0:
                P[i] = max(0.0, P[i] - (u + target[i]) / W[i, i])
            else:
                bound = mu * P[pair[i]]
                P[i] = min(bound, max(-bound, P[i] - u / W[i, i]))
        scale = max(float(np.max(np.abs(P))), 1e-300)
        if float(np.max(np.abs(P - before))) <= SWEEP_TOL * scale:
            return P, sweep
    return P, SWEEPS


@dataclass(frozen=True)
class _StepRows:
    """A step's active rows: the contacts' normals, the stops (0..n-1 lower, n..2n-1 upper, per joint
    DOF), the contacts' tangents where there is friction; G stacks them in that order (Pinocchio's v),
    ``keys`` name them across steps."""

    contacts: np.ndarray
    stops: np.ndarray
    friction: np.ndarray
    G: np.ndarray
    keys: list

    @property
    def normals(self) -> int:
        return self.contacts.size + self.stops.size


def _step_rows(leg: _Leg, q: np.ndarray, v: np.ndarray, data: pin.Data, limits: tuple[np.ndarray, np.ndarray],
               kept: dict, step: float, mu: float) -> _StepRows:
    """The rows active over a step from (q, v): those whose gap the step would close, and those
    loaded in the step before (``kept``: its impulses by key) while within :data:`REST_GAP`."""
    lo, hi = limits
    gap, Jn, Jt, margin = _rows(leg, data, q, lo, hi)
    rate = np.concatenate([v[leg.idx_q - 1], -v[leg.idx_q - 1]])
    rests = np.array([kept.get(("n", i), 0.0) > 0 for i in range(len(gap))])
    held = np.array([kept.get(("s", i), 0.0) > 0 for i in range(margin.size)], dtype=bool)
    contacts = np.flatnonzero(gap + 0.5 * step * (Jn @ v) <= np.where(rests, REST_GAP, 0.0))
    stops = np.flatnonzero(margin + 0.5 * step * rate <= np.where(held, REST_GAP, 0.0))
    Js = np.zeros((stops.size, v.size))
    Js[np.arange(stops.size), leg.idx_q[stops % len(lo)] - 1] = np.where(stops < len(lo), 1.0, -1.0)
    friction = contacts if mu > 0 else np.zeros(0, int)
    keys = [("n", i) for i in contacts] + [("s", i) for i in stops] + [("t", i) for i in friction]
    return _StepRows(contacts, stops, friction, np.vstack([Jn[contacts], Js, Jt[friction]]), keys)


def _step_impulses(rows: _StepRows, M: np.ndarray, v: np.ndarray, free: np.ndarray, kept: dict,
                   restitution: np.ndarray, mu: float) -> tuple[np.ndarray, int]:
    """The law over ``rows`` from the velocity ``v`` before and ``free`` after the step's forces:
    Newton's ``restitution`` (per normal row) on a new approach faster than the plastic speed,
    Coulomb's cone; by nonsmooth Gauss-Seidel from the step before's impulses. Returns P, sweeps."""
    n, before = rows.normals, rows.G @ v
    resting = np.array([key in kept for key in rows.keys[:n]], dtype=bool)  # no new impact
    e = np.where((-before[:n] > PLASTIC_SPEED) & ~resting, restitution, 0.0)
    target = np.r_[e * np.minimum(before[:n], 0.0), np.zeros(rows.friction.size)]
    kinds = np.r_[np.zeros(n, int), np.ones(rows.friction.size, int)]
    pair = np.r_[np.zeros(n, int), np.arange(rows.friction.size)]
    W = rows.G @ np.linalg.solve(M, rows.G.T)
    start = np.array([kept.get(key, 0.0) for key in rows.keys])
    return _nsgs(W, rows.G @ free, target, mu, kinds, pair, start)


def _onto_resting(leg: _Leg, data: pin.Data, q: np.ndarray, limits: tuple[np.ndarray, np.ndarray],
                  resting: np.ndarray) -> np.ndarray:
    """q with the ``resting`` contacts' gaps set back to 0 by the least mass-weighted change
    (Siconos's ``MoreauJeanDirectProjectionOSI``)."""
    if not resting.size:
        return q
    gap, Jn = _rows(leg, data, q, *limits)[:2]
    M, A = crba_mass_matrix(leg.model, data, q), Jn[resting]
    multipliers = np.linalg.lstsq(A @ np.linalg.solve(M, A.T), -gap[resting], rcond=None)[0]
    return pin.integrate(leg.model, q, np.linalg.solve(M, A.T @ multipliers))


def moreau_jean_landing(tree: Tree, scene: Scene, laws: tuple[JointLaw, ...], step: float,
                        trace: list | None = None) -> MoreauJeanLanding:
    """The landing of a planar ``tree`` on flat ground from its touchdown (``scene``: approach,
    gravity, friction, restitution, duration; ``laws``: springs, dampers, stops and their
    restitution) by Moreau-Jean steps of length ``step`` (module docstring). ``trace``: a list
    that each step with rows appends (t, contacts, stops, P, U+) to (stops: 0..n-1 lower, n..
    upper, per joint DOF; P and U+ normal rows, then the contacts' tangent rows)."""
    if not scene.terrain.is_flat or scene.heightfield is not None:
        raise ModelError("scene.terrain: the Moreau-Jean peer lands on flat ground only")
    q0 = touchdown_configuration(tree, scene.terrain, scene.base_x)
    joints = joint_arrays(tree, laws, q0, PLANAR)
    limits = joints.lo[3:], joints.hi[3:]
    k, c, rest, e_stop = joints.stiffness[3:], joints.damping[3:], joints.rest[3:], joints.restitution[3:]
    leg = _leg(tree, scene.gravity)
    model, data, j = leg.model, leg.model.createData(), leg.idx_q
    q, v = _to_pin(leg, q0, pre_impact_velocity(tree.topology(), scene, PLANAR))
    theta = q0[2]  # the base angle, followed continuously (not wrapped)
    total, peak, most = np.zeros(len(leg.frames)), 0.0, 0
    kept: dict = {}  # the step before's impulses by row: where it rests, and the next solve's start
    for n in range(max(1, round(float(scene.duration) / step))):
        M = crba_mass_matrix(model, data, q)
        torque = np.zeros(model.nv)
        torque[j - 1] = -k * (q[j] - rest) - c * v[j - 1]
        free = v + step * np.linalg.solve(M, torque - pin.nle(model, data, q, v))
        rows = _step_rows(leg, q, v, data, limits, kept, step, scene.friction)
        resting = rows.contacts
        if rows.keys:
            restitution = np.r_[np.full(rows.contacts.size, scene.restitution), e_stop[rows.stops % k.size]]
            P, sweeps = _step_impulses(rows, M, v, free, kept, restitution, scene.friction)
            free = free + np.linalg.solve(M, rows.G.T @ P)
            after, most, kept = rows.G @ free, max(most, sweeps), dict(zip(rows.keys, P))
            if trace is not None:
                trace.append((n * step, rows.contacts, rows.stops, P, after))
            on = P[: rows.contacts.size]
            total[rows.contacts] += on
            peak = max(peak, float(np.linalg.norm(on)))
            resting = rows.contacts[(on > 0) & (after[: rows.contacts.size] <= PLASTIC_SPEED)]  # not a rebound
        else:
            kept = {}
        q_next = _onto_resting(leg, data, pin.integrate(model, q, step * free), limits, resting)
        theta += math.remainder(math.atan2(q_next[3], q_next[2]) - theta, 2 * math.pi)
        q, v = q_next, free
    angles = np.concatenate([[theta], q[j]])
    return MoreauJeanLanding(step, angles, q[:2].copy(), _velocity_map(leg, q) @ v, total, peak, most)
