"""An independent peer for the whole landing: Moreau-Jean time stepping of the same rigid law on
Pinocchio's dynamics (planar or spatial legs on flat ground). Needs `pin` (a test dependency).

footopt's ``landing()`` is event driven (each impact located and solved by the impact law, the
modes chosen between impacts). Moreau-Jean's scheme (Moreau 1988, Jean 1999; Acary & Brogliato,
*Numerical Methods for Nonsmooth Dynamical Systems*, 2008, ch. 10; Siconos's ``MoreauJeanOSI``)
takes fixed steps instead and solves, at every step, the contact law at the velocity level:

    M (v+ - v) = h f(q, v) + J^T P,      q+ = q (+) h v+,
    0 <= U_n+ + e U_n  _|_  P_n >= 0,    |P_t| <= mu P_n with U_t+ = 0 or P_t = -mu P_n sign(U_t+),

U = J v the rows' velocities (contact normals and tangents, the stops' joint rates), e Newton's
coefficient; in space P_t and U_t are 2-vectors (world x and z), the cone circular (isotropic
Coulomb, ``MODEL_FORMAT.md``) and a sliding P_t = -mu P_n U_t+ / |U_t+|. Impacts and resting
contact are the same law at the step's scale, and the scheme converges at first order in h to the
rigid landing, Zeno cascades included (Acary & Brogliato, sec. 10.1). The rows and the law at a
step:

- active: the rows whose gap the step would close, and those loaded in the step before while their
  gap stays within :data:`REST_GAP`;
- e is 0 where the approach is slower than the plastic speed (``MODEL_FORMAT.md``) and for a row
  active in the step before (a resting contact takes no new impact);
- nonsmooth Gauss-Seidel (Moreau's, as Siconos's ``NSGS``: each row's projection in turn; in space
  each contact's normal and two tangents as one block, solved exactly as a single contact with the
  others' impulses fixed, :func:`_cone_contact`, as Siconos's ``FrictionContact3D`` NSGS with an
  exact one-contact solver) starts
  from the step before's impulses (a warm start): where both staying and leaving solve a resting
  contact's problem (its free normal acceleration turned away from the ground while friction holds
  it), it keeps the rest, as footopt's transition rule does;
- the positions take the velocity after (theta = 1; in space the free-flyer base by Pinocchio's
  Lie-group ``integrate``), and a resting contact's gap (loaded, leaving
  slower than the plastic speed) is then set back to 0 by the least mass-weighted change of q, as
  Siconos's ``MoreauJeanDirectProjectionOSI`` does: it would otherwise drift by O(h^2) a step (by
  h^2 a / 2 with the midpoint rule: 1 um in 10 ms).

Nothing of footopt's dynamics, events or impact solvers is used: the mass matrix, the nonlinear
effects and the contact Jacobians are Pinocchio's (:mod:`.pinocchio_bridge`'s tree). Only the model
file's reading (the tree, its touchdown configuration and velocity, the joint laws' arrays) is
shared. :func:`moreau_jean_landing` returns what ``footopt evaluate --json`` reports of a landing
that a comparison uses: the final angles, base and velocity, each contact's total normal and
tangential impulses, the largest step impulse (an impact's, plus at most h times the resting forces).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from impulse_core.errors import ModelError
from impulse_core.evaluate import pre_impact_velocity
from impulse_core.kinematics.spatial import PLANAR, SPATIAL, Space, dof_layout
from impulse_core.model.joints import JointLaw
from impulse_core.model.rods import body_rotation
from impulse_core.model.tree import Scene, Tree
from impulse_core.timedomain.compliant import chart_rotation, continued_rotation_vector, touchdown_configuration
from impulse_core.timedomain.events.point import joint_arrays
from impulse_core.timedomain.events.settings import PLASTIC_SPEED
from optimizer.validation.pinocchio_bridge import (
    build, build_spatial, crba_mass_matrix, spatial_velocity_map, velocity_map,
)

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
    final_angles: np.ndarray  # base absolute angle (space: its rotation vector since touchdown), joint angles
    final_base: np.ndarray  # x, y (space: x, y, z) of the base origin
    final_velocity: np.ndarray  # footopt's generalized velocity (space: the base's in the world frame)
    total_external: np.ndarray  # per contact, the normal impulse over [0, T] (N s)
    total_tangential: np.ndarray  # per contact, the tangential impulse over [0, T] (along x; space: x, z)
    peak_external_norm: float  # the largest |P_n| over the steps (N s)
    sweeps: int  # the most Gauss-Seidel sweeps a step took


@dataclass(frozen=True)
class _Leg:
    """The Pinocchio model and footopt's maps: our joint DOF k is Pinocchio's ``idx_v[k]``
    (``idx_q[k]``). Planar: a planar base joint (x, y, cos, sin; 3 v); spatial: a free flyer
    (x, y, z, quaternion; 6 v, in the base frame)."""

    model: pin.Model
    frames: tuple[int, ...]
    space: Space
    permutation: np.ndarray  # v_ours = permutation @ blockdiag(base's rotation, I) @ v_pin
    idx_v: np.ndarray  # per joint DOF of ours (after the base's), Pinocchio's v index
    rotation0: np.ndarray  # the base's orientation at touchdown (world from base)

    @property
    def spatial(self) -> bool:
        return self.space is SPATIAL

    @property
    def idx_q(self) -> np.ndarray:
        """Pinocchio's q index of each joint DOF: the base has one q more than v (cos and sin; a
        quaternion), revolute joints one each."""
        return self.idx_v + 1

    @property
    def n_base(self) -> int:
        return len(self.space.base_dofs)


def _leg(tree: Tree, gravity: float, space: Space) -> _Leg:
    """Pinocchio's model of ``tree`` in ``space`` with gravity along -y."""
    built = (build_spatial if space is SPATIAL else build)(tree)
    model = built.model
    model.gravity.linear[:] = (0.0, -gravity, 0.0)
    rotation0 = body_rotation(tree.bodies[0])
    if space is SPATIAL:
        permutation = built.T @ np.linalg.inv(spatial_velocity_map(rotation0, model.nv))
    else:
        permutation = built.T @ np.linalg.inv(velocity_map(tree.bodies[0].angle, model.nv))
    idx_v = np.argmax(np.abs(permutation[len(space.base_dofs):]), axis=1)
    return _Leg(model, built.contact_frames, space, np.round(permutation), idx_v, rotation0)


def _base_rotation(q: np.ndarray) -> np.ndarray:
    """The free flyer's orientation (world from base) at Pinocchio's q (quaternion x, y, z, w)."""
    return pin.Quaternion(q[6], q[3], q[4], q[5]).normalized().toRotationMatrix()


def _velocity_map(leg: _Leg, q: np.ndarray) -> np.ndarray:
    """T with v_ours = T v_pin at the configuration q (Pinocchio's)."""
    if leg.spatial:
        return leg.permutation @ spatial_velocity_map(_base_rotation(q), leg.model.nv)
    return leg.permutation @ velocity_map(math.atan2(q[3], q[2]), leg.model.nv)


def _to_pin(leg: _Leg, q_ours: np.ndarray, v_ours: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pinocchio's (q, v) of footopt's (space: q's rotation coordinates phi turn the base from its
    touchdown orientation, Exp(phi) R0)."""
    q = np.zeros(leg.model.nq)
    if leg.spatial:
        q[:3] = q_ours[:3]
        q[3:7] = pin.Quaternion(np.asarray(chart_rotation(q_ours[3:6])) @ leg.rotation0).coeffs()
    else:
        q[:4] = q_ours[0], q_ours[1], math.cos(q_ours[2]), math.sin(q_ours[2])
    q[leg.idx_q] = q_ours[leg.n_base:]
    return q, np.linalg.solve(_velocity_map(leg, q), v_ours)


def _rows(leg: _Leg, data: pin.Data, q: np.ndarray, lo: np.ndarray, hi: np.ndarray
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every contact's gap, normal and tangent Jacobian rows (world y; the tangents x, and z in
    space: n_c x (1 or 2) x nv; Pinocchio's v), and each joint DOF's margins to its stops (q - lo,
    hi - q; ours, inf where none)."""
    model = leg.model
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    gap = np.array([data.oMf[f].translation[1] for f in leg.frames])
    J = [pin.getFrameJacobian(model, data, f, pin.LOCAL_WORLD_ALIGNED) for f in leg.frames]
    tangents = [0, 2] if leg.spatial else [0]
    angles = q[leg.idx_q]
    return (gap, np.array([j[1] for j in J]), np.array([j[tangents] for j in J]),
            np.concatenate([angles - lo, hi - angles]))


def _nsgs(W: np.ndarray, free: np.ndarray, target: np.ndarray, mu: float, kinds: np.ndarray, pair: np.ndarray,
          start: np.ndarray) -> tuple[np.ndarray, int]:
    """Nonsmooth Gauss-Seidel on U = W P + free from P = ``start``: per normal row (``kinds`` 0)
    0 <= U + target _|_ P >= 0 (``target`` e U before), per tangent row (1) |P| <= mu P_n of its
    normal (``pair``) with U = 0 inside; stops are normal rows. A spatial contact's normal row (2)
    takes its tangents' rows (3, ``pair``: their normal) into one block, the circular cone's law
    solved for the three (:func:`_cone_contact`), its update under-relaxed by :data:`RELAXATION`
    after :data:`RELAX_AFTER` sweeps (the same fixed point). Returns P and the sweeps taken."""
    P = start.copy()
    blocks = {}
    for i in np.flatnonzero(kinds == 2):
        ix = np.r_[i, np.flatnonzero((kinds == 3) & (pair == i))]
        A, others = W[np.ix_(ix, ix)], W[ix].copy()
        others[:, ix] = 0.0
        blocks[i] = ix, A, np.linalg.inv(A), others
    for sweep in range(1, SWEEPS + 1):
        before = P.copy()
        relax = 1.0 if sweep <= RELAX_AFTER else RELAXATION
        for i in range(len(free)):
            kind = kinds[i]
            if kind == 0:
                u = free[i] + W[i] @ P
                P[i] = max(0.0, P[i] - (u + target[i]) / W[i, i])
            elif kind == 1:
                u = free[i] + W[i] @ P
                bound = mu * P[pair[i]]
                P[i] = min(bound, max(-bound, P[i] - u / W[i, i]))
            elif kind == 2:
                ix, A, inverse, others = blocks[i]
                r = P[ix]
                b = free[ix] + others @ P  # the contact's velocity without its own impulse (not W P - A r:
                # a fast slip's rounding there, 1e-16 of 1.6 m/s, moved a 6e-4 m/s normal's answer by 4e-13
                # each sweep, above SWEEP_TOL, for 2000 sweeps)
                b[0] += target[i]
                P[ix] = r + relax * (_cone_contact(A, inverse, b, mu, r) - r)
        scale = max(float(np.max(np.abs(P))), 1e-300)
        if float(np.max(np.abs(P - before))) <= SWEEP_TOL * scale:
            return P, sweep
    return P, SWEEPS


#: the spatial contacts' Gauss-Seidel updates after this many sweeps move by this share of the way
#: to the one-contact answer (Siconos's NSGS relaxation): spatial leg 1 at 2e-5 s, 0.12-0.3 s, with
#: two to four contacts sliding, cycled for 2000 sweeps a step at 1
RELAX_AFTER, RELAXATION = 50, 0.5


#: the one-contact solver's Newton steps on the slip direction at most, the step (rad) that ends
#: them, and the directions its fallback scans
NEWTON_STEPS, NEWTON_TOL, SCAN = 60, 1e-14, 720


def _cone_contact(A: np.ndarray, inverse: np.ndarray, b: np.ndarray, mu: float, guess: np.ndarray) -> np.ndarray:
    """One contact's circular-cone Coulomb law, exactly: r = (r_n, r_t) with u = A r + b (A the
    contact's 3x3 Delassus block, ``inverse`` its inverse, b the velocity without its impulse,
    the normal's restitution target included), 0 <= u_n _|_ r_n >= 0, |r_t| <= mu r_n, u_t = 0
    inside the cone, r_t = -mu r_n u_t / |u_t| on its edge. Tried in turn: separating (b_n >= 0),
    sticking (r = -A^-1 b inside the cone), sliding (:func:`_sliding`, from ``guess``'s direction,
    the impulse before, then from the sticking answer's)."""
    if b[0] >= 0.0:
        return np.zeros(3)
    r = -(inverse @ b)
    if r[0] > 0.0 and math.hypot(r[1], r[2]) <= mu * r[0]:
        return r
    slip = _slow_slip(inverse, r, mu)
    if slip is not None:
        return slip
    starts = [math.atan2(x[2], x[1]) for x in (guess, r) if math.hypot(x[1], x[2]) > 0.0]
    return _sliding(A, b, mu, starts or [0.0])


def _slow_slip(inverse: np.ndarray, stick: np.ndarray, mu: float) -> np.ndarray | None:
    """:func:`_cone_contact`'s slide continued from the sticking answer ``stick`` (outside the
    cone): r = stick - s A^-1 (0, d) (the impulse that slip speed s along -d leaves, u_n = 0), on
    the cone's edge along d (r_t = mu r_n d); Newton's method on (s, the angle of d) from s = 0
    and d along stick's r_t. Its answers with s >= 0 are the law's (s < 0: u_t along +d, not
    one); None where it ends elsewhere. A slow slip's answer is next to the start (for the angle
    alone, a root of u_t x d with u_t against d within a narrow window of directions)."""
    if math.hypot(stick[1], stick[2]) == 0.0:
        return None
    theta, s = math.atan2(stick[2], stick[1]), 0.0
    scale = float(np.abs(stick).max())
    for _ in range(NEWTON_STEPS):
        c, si = math.cos(theta), math.sin(theta)
        w = -(inverse[:, 1] * c + inverse[:, 2] * si)
        dw = inverse[:, 1] * si - inverse[:, 2] * c
        r = stick + s * w
        F = np.array([r[1] - mu * r[0] * c, r[2] - mu * r[0] * si])
        if float(np.abs(F).max()) <= 1e-15 * scale:
            break
        J = np.array([[w[1] - mu * w[0] * c, s * (dw[1] - mu * dw[0] * c) + mu * r[0] * si],
                      [w[2] - mu * w[0] * si, s * (dw[2] - mu * dw[0] * si) - mu * r[0] * c]])
        try:
            ds, dtheta = np.linalg.solve(J, -F)
        except np.linalg.LinAlgError:
            return None
        s, theta = s + ds, theta + dtheta
    else:
        return None
    if s < 0.0 or r[0] < 0.0:
        return None
    return np.array([r[0], mu * r[0] * c, mu * r[0] * si])


def _sliding(A: np.ndarray, b: np.ndarray, mu: float, starts: list[float]) -> np.ndarray:
    """The sliding answer of :func:`_cone_contact`: r_t = mu r_n d, d = (cos, sin) of an angle,
    r_n from u_n = 0, and u_t(d) anti-parallel to d: Newton's method on g = u_t x d from each of
    ``starts`` in turn; where each ends elsewhere (u_t along +d, or r_n <= 0), the roots of g
    bracketed on a scan of :data:`SCAN` directions, refined by bisection, the nearest to the first
    start with u_t against d (a slow slip's root lies within a narrow window of directions with
    u_t against d: the scan's neighbours need not have it)."""
    (a00, a01, a02), (a10, a11, a12), (a20, a21, a22) = A.tolist()
    b0, b1, b2 = b.tolist()

    def at(t: float) -> tuple[float, float, float, float, float]:
        c, s = math.cos(t), math.sin(t)
        den = a00 + mu * (a01 * c + a02 * s)
        rn = -b0 / den
        e1, e2 = a10 + mu * (a11 * c + a12 * s), a20 + mu * (a21 * c + a22 * s)
        u1, u2 = rn * e1 + b1, rn * e2 + b2
        drn = -rn * mu * (a02 * c - a01 * s) / den
        dg = (drn * e1 + rn * mu * (a12 * c - a11 * s)) * s + u1 * c - (drn * e2 + rn * mu * (a22 * c - a21 * s)) * c \
            + u2 * s
        return rn, u1 * s - u2 * c, dg, u1 * c + u2 * s, den

    tol = 1e-9 * (abs(b0) + abs(b1) + abs(b2))
    for theta in starts:
        for _ in range(NEWTON_STEPS):
            rn, g, dg, along, den = at(theta)
            if dg == 0.0:
                break
            theta -= g / dg
            if abs(g / dg) <= NEWTON_TOL:
                break
        rn, g, dg, along, den = at(theta)
        if den > 0.0 and rn >= 0.0 and along <= tol and abs(g) <= tol:
            break
    else:
        theta = _scanned_root(at, starts[0], tol)
        rn = at(theta)[0]
    return np.array([rn, mu * rn * math.cos(theta), mu * rn * math.sin(theta)])


def _scanned_root(at, near: float, tol: float) -> float:  # type: ignore[no-untyped-def]
    """:func:`_sliding`'s fallback: the roots of g between two of :data:`SCAN` directions with
    r_n >= 0 at both, by bisection; the nearest to ``near`` with u_t against d (within ``tol``)."""
    cell = 2.0 * math.pi / SCAN
    angles = near - math.pi + cell * np.arange(SCAN + 2)  # a turn and a cell: a root at the ends is inside one
    values = [at(float(t)) for t in angles]
    ok = [v[4] > 0.0 and v[0] >= 0.0 for v in values]
    brackets = [k for k in range(SCAN + 1) if ok[k] and ok[k + 1] and values[k][1] * values[k + 1][1] <= 0.0]
    for k in sorted(brackets, key=lambda k: abs(angles[k] - near)):
        lo, hi, g_lo = float(angles[k]), float(angles[k + 1]), values[k][1]
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            g = at(mid)[1]
            if (g <= 0.0) == (g_lo <= 0.0):
                lo, g_lo = mid, g
            else:
                hi = mid
        if at(0.5 * (lo + hi))[3] <= tol:
            return 0.5 * (lo + hi)
    raise FloatingPointError("the circular cone's one-contact law has no sliding answer")


@dataclass(frozen=True)
class _StepRows:
    """A step's active rows: the contacts' normals, the stops (0..n-1 lower, n..2n-1 upper, per joint
    DOF), the contacts' tangents where there is friction (``tangents`` each: 1 in the plane, x; 2 in
    space, x and z); G stacks them in that order (Pinocchio's v), ``keys`` name them across steps."""

    contacts: np.ndarray
    stops: np.ndarray
    friction: np.ndarray
    G: np.ndarray
    keys: list
    tangents: int

    @property
    def normals(self) -> int:
        return self.contacts.size + self.stops.size


def _step_rows(leg: _Leg, q: np.ndarray, v: np.ndarray, data: pin.Data, limits: tuple[np.ndarray, np.ndarray],
               kept: dict, step: float, mu: float) -> _StepRows:
    """The rows active over a step from (q, v): those whose gap the step would close, and those
    loaded in the step before (``kept``: its impulses by key) while within :data:`REST_GAP`."""
    lo, hi = limits
    gap, Jn, Jt, margin = _rows(leg, data, q, lo, hi)
    rate = np.concatenate([v[leg.idx_v], -v[leg.idx_v]])
    rests = np.array([kept.get(("n", i), 0.0) > 0 for i in range(len(gap))])
    held = np.array([kept.get(("s", i), 0.0) > 0 for i in range(margin.size)], dtype=bool)
    contacts = np.flatnonzero(gap + 0.5 * step * (Jn @ v) <= np.where(rests, REST_GAP, 0.0))
    stops = np.flatnonzero(margin + 0.5 * step * rate <= np.where(held, REST_GAP, 0.0))
    Js = np.zeros((stops.size, v.size))
    Js[np.arange(stops.size), leg.idx_v[stops % len(lo)]] = np.where(stops < len(lo), 1.0, -1.0)
    friction = contacts if mu > 0 else np.zeros(0, int)
    tangents = Jt.shape[1]
    keys = [("n", i) for i in contacts] + [("s", i) for i in stops] + [("t", i, a) for i in friction
                                                                       for a in range(tangents)]
    G = np.vstack([Jn[contacts], Js, Jt[friction].reshape(-1, v.size)])
    return _StepRows(contacts, stops, friction, G, keys, tangents)


def _step_impulses(rows: _StepRows, M: np.ndarray, v: np.ndarray, free: np.ndarray, kept: dict,
                   restitution: np.ndarray, mu: float) -> tuple[np.ndarray, int]:
    """The law over ``rows`` from the velocity ``v`` before and ``free`` after the step's forces:
    Newton's ``restitution`` (per normal row) on a new approach faster than the plastic speed,
    Coulomb's cone; by nonsmooth Gauss-Seidel from the step before's impulses. Returns P, sweeps."""
    n, before = rows.normals, rows.G @ v
    nt = rows.friction.size * rows.tangents
    resting = np.array([key in kept for key in rows.keys[:n]], dtype=bool)  # no new impact
    e = np.where((-before[:n] > PLASTIC_SPEED) & ~resting, restitution, 0.0)
    target = np.r_[e * np.minimum(before[:n], 0.0), np.zeros(nt)]
    kinds = np.r_[np.zeros(n, int), np.ones(nt, int)]
    pair = np.r_[np.zeros(n, int), np.repeat(np.arange(rows.friction.size), rows.tangents)]  # friction = contacts
    if rows.tangents == 2:  # space: each contact's three rows one block
        kinds[: rows.friction.size], kinds[n:] = 2, 3
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
                        trace: list | None = None, space: Space = PLANAR) -> MoreauJeanLanding:
    """The landing of ``tree`` (planar, or spatial with ``space=SPATIAL``) on flat ground from its
    touchdown (``scene``: approach, gravity, friction, restitution, duration; ``laws``: springs,
    dampers, stops and their restitution) by Moreau-Jean steps of length ``step`` (module
    docstring). ``trace``: a list that each step with rows appends (t, contacts, stops, P, U+) to
    (stops: 0..n-1 lower, n.. upper, per joint DOF; P and U+ normal rows, then the contacts'
    tangent rows: x, or x and z per contact in space)."""
    if not scene.terrain.is_flat or scene.heightfield is not None:
        raise ModelError("scene.terrain: the Moreau-Jean peer lands on flat ground only")
    spatial = space is SPATIAL
    q0 = touchdown_configuration(tree, scene.terrain, scene.base_x, space=space,
                                 base_z=float(scene.base_z) if spatial else 0.0)
    leg = _leg(tree, scene.gravity, space)
    nb = leg.n_base
    joints = joint_arrays(tree, laws, q0, space)
    limits = joints.lo[nb:], joints.hi[nb:]
    k, c, rest, e_stop = joints.stiffness[nb:], joints.damping[nb:], joints.rest[nb:], joints.restitution[nb:]
    model, data, j, jv = leg.model, leg.model.createData(), leg.idx_q, leg.idx_v
    q, v = _to_pin(leg, q0, pre_impact_velocity(tree.topology(), scene, space))
    theta = q0[2]  # the base angle, followed continuously (not wrapped)
    turn = np.zeros(3)  # space: the base's rotation vector since touchdown, followed continuously
    total, peak, most = np.zeros(len(leg.frames)), 0.0, 0
    tangential = np.zeros((len(leg.frames), 2 if spatial else 1))
    kept: dict = {}  # the step before's impulses by row: where it rests, and the next solve's start
    for n in range(max(1, round(float(scene.duration) / step))):
        M = crba_mass_matrix(model, data, q)
        torque = np.zeros(model.nv)
        torque[jv] = -k * (q[j] - rest) - c * v[jv]
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
            tangential[rows.friction] += P[rows.normals:].reshape(-1, rows.tangents)
            peak = max(peak, float(np.linalg.norm(on)))
            resting = rows.contacts[(on > 0) & (after[: rows.contacts.size] <= PLASTIC_SPEED)]  # not a rebound
        else:
            kept = {}
        q_next = _onto_resting(leg, data, pin.integrate(model, q, step * free), limits, resting)
        if spatial:
            if n % TURN_EVERY == 0:
                turn = _turn(leg, q_next, turn)
        else:
            theta += math.remainder(math.atan2(q_next[3], q_next[2]) - theta, 2 * math.pi)
        q, v = q_next, free
    base = list(_turn(leg, q, turn)) if spatial else [theta]
    layout = dof_layout(tree.topology(), space)
    angles = np.array(base + [b.angle if d is None else q[j[d - nb]] for b, d in zip(tree.bodies[1:],
                                                                                   layout.body_dof[1:])])
    return MoreauJeanLanding(step, angles, q[: 3 if spatial else 2].copy(), _velocity_map(leg, q) @ v, total,
                             tangential if spatial else tangential[:, 0], peak, most)


#: space: the steps between two readings of the base's rotation vector (each continues the one
#: before; a base turning by pi within them, 1000 rad/s at 3e-3 s, would be read a turn off)
TURN_EVERY = 64


def _turn(leg: _Leg, q: np.ndarray, previous: np.ndarray) -> np.ndarray:
    """The base's rotation vector since touchdown at Pinocchio's q, R R0^T (world frame, as
    footopt's phi), the representative nearest ``previous``."""
    return continued_rotation_vector(_base_rotation(q) @ leg.rotation0.T, previous)
