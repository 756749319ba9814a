"""Exact derivatives of the whole landing's objectives along its event sequence ("replay").

:func:`landing_gradient` runs the numeric landing (:mod:`impulse_core.timedomain.landing`) at the
reported step h with a tape that records every committed operation, then replays the same
computation operation by operation with CasADi functions symbolic in the design values theta and
the friction coefficient (built once per mode and cached for every design of the same
structure), carrying the forward sensitivities dz/dtheta of every quantity z (and dz/ds, s the
scene's values: see below) by the chain rule with each operation's exact Jacobian (CasADi's
algorithmic differentiation):

* each step of the run's integrator (classical RK4, or ROS2 where the run is implicit) in its
  segment's mode (the same closed rows, slip directions and stops: M a = f + F^T lambda,
  G a + b = 0), with the contact-force quadrature;
* each projection after a step or an event (positions, then velocities; its impulses counted),
  with the rows it used;
* each event time implicitly: the witness w that crossed (a gap, a stop margin, a normal force,
  a cone margin, a slip) reaches, along the event's step of length tau from the state x_k, the
  value c it had at the located tau*. One Newton correction
  ``tau = tau* - (w(x_k, theta, tau*) - c) / w_tau`` gives the time (tau* to rounding) and the
  implicit function theorem's derivative ``dtau/dtheta = -(w_x dx_k/dtheta + w_theta) / w_tau``:
  carried through the event's step, that is the saltation term;
* each impact by the law in its reported modes (as :mod:`impulse_core.impact.mode_derivatives`):
  the active rows fixed, the impulse solves the linear equations of that mode (a pushing row
  meets Newton's restitution, a separating row has no impulse, a sticking contact no slip, a
  sliding one its impulse on the cone's edge against the reported slip); each row's restitution
  is the number the run used (the plastic rules are decisions of the sequence), an input whose
  Jacobian carries the restitutions' derivatives;
* the step count fixed: regular steps keep their taped length (h, or h / 2^j where the momentum
  balance or, in space, a slow turning slip split it: :meth:`~events.stepping._Landing.slip_length`),
  an event step is tau(theta), and the
  last step ends at T, so its length T - t(theta) moves with the event times. The derivative is
  that of the discretisation itself: central differences of the numeric landing at the same h
  agree with it while the sequence does not change (``tests/impulse_core/test_landing_derivatives.py``).
  A split is a decision of the run (a threshold on the slip's speed): where a change of theta
  moves one by a step, the numeric objective jumps by the two discretisations' difference (the
  two-rod leg of ``test_landing_derivatives_spatial``, a slip slowing to its stop: central
  differences at +-1e-5 of the friction, each run splitting on its own, are 3e-4 of the derivative
  off, 2.9e-5 at +-1e-6, a jump of ~1e-10), and the derivative is that of the branch with the
  run's splits; central differences along it hold them (:func:`taped_run`'s ``halvings``: 4.6e-7).

In space (``space=SPATIAL``; ``tests/impulse_core/test_landing_derivatives_spatial.py``) the
replay is the same, with what the plane's single tangent hides:

* a sliding contact's force is n - mu u^T t along u = :func:`~landing.slip_direction` of its
  slip s at each stage, the direction d its mode carries and the step's regularisation core
  (:meth:`~landing._Landing.steer`: h mu f_n w at the step's start). u, d and core are functions
  of the state and theta like the rest: each step computes its core, after a regular step d
  follows the slip (:meth:`~landing._Landing.follow_slip`), and a mode an event chooses starts
  each sliding contact with the d it carried (the mode persisted), its slip s / |s| (it slid on
  through the event) or, for a contact starting to slide, the fixed point d = a_t(d) / |a_t(d)|
  of the circular cone's law at the acceleration level (its slip acceleration a_t in the mode);
  the replay carries d with its sensitivities and checks it against the run's at every step;
* a sliding impact's tangential impulse lies on the cone's edge against the slip after it,
  lambda_t = -mu lambda_n w / |w| (w the two tangent rows' velocities after): nonlinear in
  lambda, so the impact is one Newton step on its mode's equations from the run's lambda*, whose
  value is lambda* to rounding and whose derivative is the implicit function theorem's. An impact
  where the cone's solver fell back to its polyhedral answer (the run's ``inexact``) does not meet
  those equations and is refused (NumericalError), as is a slip direction the replay does not
  reproduce (two contacts at one point made to slide alike, a contact put on the cone's edge);
* both integrators are replayed (a spatial landing takes RK4 unless ``auto`` finds the joint laws
  too stiff for it, as in the plane; the run's compiled RK4 step equals its numpy path to
  rounding, and the replay repeats that arithmetic), so the derivative is that of the run the
  tool reports.

Forward rather than adjoint sensitivities: every operation's Jacobian w.r.t. (x, theta) is one
call, the sweep is a product of small dense matrices, and peaks at intermediate events need no
second pass.

Outputs (:class:`LandingGradient`): ``peak_external_norm``, ``peak_internal_norm``,
``peak_max_internal`` (the event, and joint, attaining the maximum is differentiated: where
several tie within 1e-9 relative this is the gradient of one of them, an element of the Clarke
subdifferential, and ``ties`` says so), ``energy_absorbed``, ``total_external`` (per contact)
and ``final_angles``; w.r.t. theta in ``jacobian`` and w.r.t. the scene's values in
``scene_jacobian``. ``settled_at`` is not differentiable (a threshold crossing of |v| with
linear interpolation, constant where the landing never settles): it is not offered.

theta (:func:`design_names`): the tree's design vector (:func:`~impulse_core.model.tree.design_vector`:
lengths, masses, angles, ..., and ``com_y`` where a centre of mass is off its rod; in space
SPATIAL's values per body, rpy angles, axes, radii, offsets and tensors among them), then per
revolute joint its law's stiffness, damping, rest, limits[0], limits[1]. In space
``final_angles`` are the base's rotation coordinates (3, about its touchdown orientation, which
its design values set), then each joint's angle. A joint whose ``rest`` is None rests at its touchdown angle, so the
derivative w.r.t. its angle carries it and the rest entry's is 0; a joint without stops has 0
derivatives for its limit entries (their values are reported as 0). The touchdown height
follows the lowest contact (where several are lowest, the first: a one-sided derivative; on a
foot whose tips a search keeps level, the sides differ by a combination of the level-tip
constraints' gradients, which the constraints' multipliers absorb).

The scene's values s (:func:`scene_names`, :func:`scene_theta`; the derivatives in
:attr:`LandingGradient.scene_jacobian`, laid out as ``jacobian``): ``friction`` (mu), ``speed``,
``restitution``, then per revolute joint its law's ``stop_restitution`` (a study's foot joints
share one: its derivative is the sum of theirs; 0 for a joint that hits no stop), along the same
event sequence:

* mu is a symbol of every operation, as theta is: the force -mu u f_n of a sliding contact, the
  sliding impact's cone edge, the step's regularisation core in space, the cone-margin witness
  (the time a contact starts to slip; the force is continuous there, so that time moves the
  objectives only through the steps' lengths). Whether mu > 0 (which rows exist) is built in, so
  one structure serves every positive friction.
* the speed sets the approach velocity v0 (:func:`~impulse_core.evaluate.pre_impact_velocity`:
  the base origin's [velocity_x, -speed(, velocity_z)] and the angular velocity along the base's
  DOFs, linear in the speed): the sensitivities start with dv0/dspeed, and the energy touchdown
  brings (``energy_absorbed``'s denominator) is the kinetic energy at v0 and the springs' at q0. The tolerances it
  scales (the slip floor, 1e-9 max(1, speed) m/s) are thresholds of decisions, not differentiated.
* a row's restitution is the scene's at a contact and its joint's ``stop_restitution`` at a stop,
  0 where the plastic rules zeroed it (approaching slower than
  :data:`~landing.PLASTIC_SPEED`, or a rebound shorter than the shortest bounce: the tape says
  which rows): there its derivative is 0.

Not sound for the scene's values where a decision sits on its threshold: a row at the plastic
rules' (approach speed 1e-4 m/s, bounce time), a restitution of 0 (a row whose free
acceleration pulls it away rests after a plastic impact but leaves after any e > 0: the
derivative is that of the plastic run; where every such row is pushed back, the plastic rule
keeps zeroing it for small e and the derivative is the one from above), and friction at 0 (a
frictionless scene has no friction rows: its friction column is NaN, not a derivative).

Sound where: the event sequence is locally constant, i.e. away from grazing touchdowns, ties of
event times, and ties inside the impact law (a row on the edge between two modes). Redundant
rows (a singular row matrix, where the force split is not unique) are refused with a
NumericalError. A change of the sequence under a change of theta is a kink or jump of the
numeric objective: the derivative returned is that of the reported branch. Eventful landings
(hundreds of impacts, chattering contacts, a slip-stop event followed 1e-10 s later by another
at a tolerance threshold) change their sequence under perturbations of 1e-8 relative, mostly by
such micro-events that barely move the objectives; there the derivative describes the reported
branch only (``studies/landing_gradient/results.md``).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import casadi as ca
import numpy as np

from impulse_core.errors import ModelError, NumericalError
from impulse_core.evaluate import pre_impact_velocity
from impulse_core.impact.coulomb import LEMKE_TOL
from impulse_core.kinematics.spatial import PLANAR, Space, dof_layout, values_space
from impulse_core.model.joints import FREE, JointLaw
from impulse_core.model.tree import Scene, Tree, design_vector, value_names
from impulse_core.timedomain.compliant import TOUCHDOWN_CLEARANCE, ground_expression, spatial_ground, subtree_incidence
from impulse_core.timedomain.events.rows import _Mode, _Rows
from impulse_core.timedomain.events.run import _Landing
from impulse_core.timedomain.events.settings import RECHART, ROS2_GAMMA, balance_share
from impulse_core.timedomain.events.twins import symmetrized
from impulse_core.timedomain.landing import (
    IMPLICIT, RADAU, RK4, LandingResult, LandingSettings, landing, landing_function,
)

#: Events whose peak values lie within this relative distance of the maximum tie.
TIE = 1e-9
#: Per revolute joint, the law values theta carries after the design vector.
LAW_VALUES = ("stiffness", "damping", "rest", "limits[0]", "limits[1]")
#: The scalar objectives, in the order of :attr:`LandingGradient.values`.
SCALARS = ("peak_external_norm", "peak_internal_norm", "peak_max_internal", "energy_absorbed")
#: The scene's values differentiated (:attr:`LandingGradient.scene_jacobian`), before each revolute
#: joint's stop restitution (:func:`scene_names`).
SCENE_VALUES = ("friction", "speed", "restitution")


@dataclass(frozen=True)
class LandingGradient:
    """Objectives of one landing and their exact derivatives along its event sequence.

    Attributes:
        values: objective name -> value (floats; ``total_external`` and ``final_angles`` arrays),
            from the replay (equal to ``result``'s to rounding).
        jacobian: objective name -> derivative w.r.t. theta (a vector for the scalars, one row
            per entry for the arrays).
        theta: the design values differentiated (:func:`design_names` order).
        names: their names.
        scene_jacobian: objective name -> derivative w.r.t. the landing's conditions
            ``scene_theta`` (as ``jacobian``; the friction column NaN in a frictionless scene).
        scene_theta: the scene's friction, speed and restitution, then each revolute joint's
            stop restitution (:func:`scene_theta`).
        scene_names: their names (:func:`scene_names`).
        sequence: the event sequence and step counts the derivative holds along
            (:func:`sequence_signature`).
        peak_events: objective -> (event index, joint index or -1) whose value is the peak.
        ties: objective -> event indices tying the peak (more than one: a subgradient).
        result: the numeric landing at the reported step (the run replayed).
        timings: s spent in the taped run (and the landing before it, without ``step``) and in
            the sensitivity sweep (with building any operation not yet built).
    """

    values: dict
    jacobian: dict
    theta: np.ndarray
    names: tuple[str, ...]
    sequence: tuple
    peak_events: dict
    ties: dict
    result: LandingResult
    timings: dict
    scene_jacobian: dict
    scene_theta: np.ndarray
    scene_names: tuple[str, ...]


def _joint_dofs(tree: Tree, space: Space = PLANAR) -> list[tuple[int, int]]:
    layout = dof_layout(tree.topology(), space)
    return [(b, layout.body_dof[b]) for b in range(1, tree.n_bodies) if layout.body_dof[b] is not None]


def body_values(tree: Tree, space: Space = PLANAR) -> tuple[str, ...]:
    """The design vector's values per body: the plane's, with ``com_y`` where a centre of mass
    is off its rod (PLANAR_OFFSET); in space SPATIAL's (rpy, axis, radius, offsets, tensor)."""
    return values_space(tree, space).body_values


def design_names(tree: Tree, space: Space = PLANAR) -> tuple[str, ...]:
    """Names of theta's entries: the design vector's, then each revolute joint's law values."""
    laws = [f"{tree.bodies[b].name}.{name}" for b, _ in _joint_dofs(tree, space) for name in LAW_VALUES]
    return value_names(tree, body_values(tree, space)) + tuple(laws)


def design_theta(tree: Tree, laws: tuple[JointLaw, ...], space: Space = PLANAR) -> np.ndarray:
    """theta of ``tree`` and its joint laws (a rest of None: the touchdown angle; no stops: 0)."""
    laws = laws or (FREE,) * tree.n_bodies
    extra = []
    for b, _ in _joint_dofs(tree, space):
        law = laws[b]
        lo, hi = law.limits if law.limits is not None else (0.0, 0.0)
        extra += [law.stiffness, law.damping, tree.bodies[b].angle if law.rest is None else law.rest, lo, hi]
    return np.concatenate([design_vector(tree, body_values(tree, space)), np.array(extra, dtype=float)])


def scene_names(tree: Tree, space: Space = PLANAR) -> tuple[str, ...]:
    """Names of the landing's conditions differentiated: :data:`SCENE_VALUES`, then per revolute
    joint its law's ``stop_restitution`` (``<body>.stop_restitution``)."""
    return SCENE_VALUES + tuple(f"{tree.bodies[b].name}.stop_restitution" for b, _ in _joint_dofs(tree, space))


def scene_theta(tree: Tree, scene: Scene, laws: tuple[JointLaw, ...], space: Space = PLANAR) -> np.ndarray:
    """The values of :func:`scene_names`: the scene's friction, speed and restitution, each joint
    law's stop restitution."""
    laws = laws or (FREE,) * tree.n_bodies
    stops = [laws[b].stop_restitution for b, _ in _joint_dofs(tree, space)]
    return np.array([scene.friction, scene.speed, scene.restitution, *stops], dtype=float)


def apply_theta(tree: Tree, laws: tuple[JointLaw, ...], theta: np.ndarray, space: Space = PLANAR
                ) -> tuple[Tree, tuple[JointLaw, ...]]:
    """The tree and joint laws with the values of ``theta`` (:func:`design_theta`'s layout; a rest
    of None stays None, following the angle; a joint without stops keeps none)."""
    from dataclasses import replace

    from impulse_core.model.tree import with_values

    theta = np.asarray(theta, dtype=float)
    values = body_values(tree, space)
    n_p = len(design_vector(tree, values))
    new_tree = with_values(tree, theta[:n_p], values)
    out = list(laws or (FREE,) * tree.n_bodies)
    for i, (b, _) in enumerate(_joint_dofs(tree, space)):
        k, c, rest, lo, hi = theta[n_p + len(LAW_VALUES) * i : n_p + len(LAW_VALUES) * (i + 1)]
        law = out[b]
        out[b] = replace(law, stiffness=float(k), damping=float(c), rest=None if law.rest is None else float(rest),
                         limits=None if law.limits is None else (float(lo), float(hi)))
    return new_tree, tuple(out)


class _Op:
    """One operation of the replay, differentiable two ways. ``op(*args)`` returns its outputs
    (flat numpy vectors) and ``jac[i][j]`` = d output i / d input j (dense), from one CasADi call;
    :meth:`along` returns the outputs and their derivatives along m given directions (forward
    mode: m sweeps, no Jacobian formed). Built once per mode (symbolic in theta), so every design
    of one structure reuses it; each form is built on its first use."""

    def __init__(self, name: str, inputs: list, outputs: list, wrt: list | None = None) -> None:
        """``wrt``: per input, the symbols its Jacobian is taken w.r.t. (default the input itself;
        a leading part of it leaves the rest undifferentiated, as the slip floor of theta)."""
        self.name, self.inputs, self.outputs = name, inputs, [ca.vec(o) for o in outputs]
        self.wrt = wrt or inputs
        self.n_out, self.n_in = len(self.outputs), len(inputs)
        self.base = ca.Function(name, inputs, self.outputs)
        self.shapes = [(o.shape[0], i.shape[0]) for o in self.outputs for i in self.wrt]
        self._jacobians: ca.Function | None = None
        self._forward: dict[int, ca.Function] = {}

    @property
    def f(self) -> ca.Function:
        """The outputs, then one Jacobian of every output w.r.t. every input (shared work) in blocks."""
        if self._jacobians is None:
            J = ca.jacobian(ca.vertcat(*self.outputs), ca.vertcat(*self.wrt))
            rows = np.cumsum([0] + [o.shape[0] for o in self.outputs])
            cols = np.cumsum([0] + [i.shape[0] for i in self.wrt])
            jacs = [J[int(rows[a]) : int(rows[a + 1]), int(cols[b]) : int(cols[b + 1])]
                    for a in range(self.n_out) for b in range(self.n_in)]
            self._jacobians = ca.Function(self.name, self.inputs, self.outputs + jacs)
        return self._jacobians

    def __call__(self, *args) -> tuple[list[np.ndarray], list[list[np.ndarray]]]:
        res = self.f(*args)
        outs = [np.asarray(r, dtype=float).reshape(-1) for r in res[: self.n_out]]
        jacs = [np.asarray(r, dtype=float).reshape(shape) for r, shape in zip(res[self.n_out :], self.shapes)]
        return outs, [jacs[i * self.n_in : (i + 1) * self.n_in] for i in range(self.n_out)]

    def along(self, args: list, seeds: list[np.ndarray]) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """The outputs at ``args`` and their derivatives along ``seeds`` (per input, an n_in x m
        matrix of its directions; theta's slip floor row 0): each output's n_out x m."""
        m = seeds[0].shape[1]
        if m not in self._forward:  # one function of (inputs, seeds): the outputs, then their sweeps
            seed = [ca.SX.sym(f"seed{j}", i.shape[0], m) for j, i in enumerate(self.inputs)]
            swept = self.base.forward(m)(*self.inputs, *self.outputs, *seed)
            swept = swept if isinstance(swept, (list, tuple)) else [swept]
            self._forward[m] = ca.Function(f"{self.name}_along", [*self.inputs, *seed], [*self.outputs, *swept])
        res = self._forward[m](*args, *seeds)
        return ([np.asarray(o, dtype=float).reshape(-1) for o in res[: self.n_out]],
                [np.asarray(r, dtype=float).reshape(o.shape[0], m) for r, o in zip(res[self.n_out :], self.outputs)])


def _mode_key(mode: _Mode) -> tuple:
    """A mode's discrete part: closed contacts, the plane's slip signs (space: which contacts slide;
    the direction is a continuous quantity carried by the replay), stops."""
    slip = mode.side if mode.slip.shape[1] == 1 else mode.sliding
    return (tuple(int(x) for x in mode.closed), tuple(int(x) for x in slip), tuple(int(x) for x in mode.stop))


def _moving(mode: _Mode, frictional: bool) -> np.ndarray:
    """Per contact: closed and sliding with friction (its force turns with the slip in space)."""
    return mode.closed & mode.sliding if frictional else np.zeros(len(mode.closed), bool)


class _Symbolic:
    """The landing's operations as CasADi functions of (x = [q; v], theta, ...), built once per
    mode or impact and cached. Their theta is the design values' followed by the friction
    coefficient mu (:attr:`mu`, symbolic like them; whether it is positive, which decides the
    rows, is built in: :attr:`frictional`) and the run's slip floor (:attr:`floor`, not
    differentiated). In space the operations of a mode with sliding
    contacts also take d, the slip directions the mode carries (n_c x 2 flattened,
    :attr:`_Mode.slip`), and a step returns its regularisation core (:meth:`_Landing.steer`)."""

    def __init__(self, run: _Landing, laws: tuple[JointLaw, ...]) -> None:
        self.run = run
        tree = run.tree
        self.tree, self.nv, self.nc = tree, run.nv, run.nc
        self.space, self.planar, self.dims = run.space, run.planar, run.dims
        self.nt = run.dims - 1  # tangents per contact
        self.values = run.space.body_values  # the plane's, PLANAR_OFFSET's or SPATIAL's
        self.ground = run.scene.terrain if run.planar else spatial_ground(run.scene)
        self.fn = landing_function(run.topology, self.ground, run.space)
        self.n_p = len(design_vector(tree, self.values))
        self.dofs = _joint_dofs(tree, run.space)
        self.n_theta = self.n_p + len(LAW_VALUES) * len(self.dofs)
        self.laws = laws or (FREE,) * tree.n_bodies
        self.frictional, self.gravity = run.mu > 0, run.scene.gravity
        self.S = subtree_incidence(tree)
        self.cache: dict = {}
        self.x = ca.SX.sym("x", 2 * self.nv)
        # the design values, mu, then the slip floor (below this slip speed a sliding contact keeps
        # its direction d: the run's speed_tol, a threshold, so not differentiated: :meth:`op`)
        self.th = ca.SX.sym("theta", self.n_theta + 2)
        self.mu, self.floor = self.th[self.n_theta], self.th[self.n_theta + 1]
        self.differentiated = self.th[: self.n_theta + 1]
        self.d = ca.SX.sym("d", self.nt * self.nc)  # space: the carried slip directions

    # ---- pieces of theta

    def angle(self, th: ca.SX, b: int) -> ca.SX:
        return th[len(self.values) * b + self.values.index("angle")]

    def law_arrays(self, th: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX, list, list]:
        """Per DOF: stiffness, damping, rest (SX vectors; base entries 0), lo, hi (lists: an SX
        entry where a stop exists, else None)."""
        k, c, rest = ca.SX.zeros(self.nv), ca.SX.zeros(self.nv), ca.SX.zeros(self.nv)
        lo, hi = [None] * self.nv, [None] * self.nv
        for i, (b, j) in enumerate(self.dofs):
            base = self.n_p + len(LAW_VALUES) * i
            k[j], c[j] = th[base], th[base + 1]
            rest[j] = self.angle(th, b) if self.laws[b].rest is None else th[base + 2]
            if self.laws[b].limits is not None:
                lo[j], hi[j] = th[base + 3], th[base + 4]
        return k, c, rest, lo, hi

    # ---- the landing's numerics, symbolically

    def point(self, q: ca.SX, v: ca.SX, th: ca.SX) -> dict:
        """The dynamics at (q, v): gap, per contact its normal and tangents (lists of d-vectors),
        Jn (n_c x nv), Jt and bt (one per tangent: n_c x nv, n_c), bn, slip (per contact, its
        tangential velocities), M, f (springs and dampers included), kinetic, momentum, com."""
        o = self.fn(q, v, th[: self.n_p], self.gravity)
        gap, N, Jc, bias, M, force, kinetic, momentum, com, C = o
        k, c, rest, _, _ = self.law_arrays(th)
        pt = dict(M=M, f=force - k * (q - rest) - c * v, kinetic=kinetic, momentum=momentum, com=com)
        if self.planar:
            pairs = [_gap(self.run.scene.terrain, C[0, i], C[1, i]) for i in range(self.nc)]
            gap = ca.vertcat(*[g for g, _, _ in pairs])
            nx, ny = ca.vertcat(*[a for _, a, _ in pairs]), ca.vertcat(*[b for _, _, b in pairs])
            Jx, Jy = Jc[0::2, :], Jc[1::2, :]
            bx, by = bias[0::2], bias[1::2]
            Jn = ca.diag(nx) @ Jx + ca.diag(ny) @ Jy if self.nc else ca.SX(0, self.nv)
            Jt = ca.diag(ny) @ Jx - ca.diag(nx) @ Jy if self.nc else ca.SX(0, self.nv)
            normals = [ca.vertcat(nx[i], ny[i]) for i in range(self.nc)]
            tangents = [[ca.vertcat(ny[i], -nx[i])] for i in range(self.nc)]
            pt.update(gap=gap, Jn=Jn, Jt=[Jt], bn=nx * bx + ny * by, bt=[ny * bx - nx * by])
        else:
            normals, tangents, rows = spatial_contact_rows(N, Jc, bias)
            pt.update(gap=gap, **rows)
        pt.update(normal=normals, tangent=tangents,
                  slip=[ca.vertcat(*[pt["Jt"][a][i, :] @ v for a in range(self.nt)]) for i in range(self.nc)])
        return pt

    def directions(self, pt: dict, mode: _Mode, d: ca.SX, core) -> list:
        """Per contact, the unit direction its sliding friction opposes (a list of n_t entries), or
        None: the plane's +-1; in space :func:`landing.slip_direction` of the slip at ``pt``, the
        carried direction ``d`` and the step's ``core``."""
        moving = _moving(mode, self.frictional)
        out: list = [None] * self.nc
        for i in np.flatnonzero(moving):
            if self.planar:
                out[i] = [float(mode.side[i])]
                continue
            u = slip_direction_expression(pt["slip"][i], d[self.nt * i : self.nt * (i + 1)], core[i], self.floor)
            out[i] = [u[a] for a in range(self.nt)]
        return out

    def rows(self, pt: dict, contacts, sliding: np.ndarray, stops, u: list) -> tuple[ca.SX, ca.SX, ca.SX, _Rows]:
        """G, F, b of :func:`landing._rows` symbolically (``sliding`` per contact, ``u`` its
        direction), and the rows' bookkeeping (numeric)."""
        contacts = np.asarray(contacts, int)
        dofs = np.flatnonzero(stops)
        mu = self.mu
        sliding = sliding[contacts] if self.frictional else np.zeros(len(contacts), bool)
        sticking = contacts[~sliding] if self.frictional else contacts[:0]
        G_stop = np.zeros((len(dofs), self.nv))
        G_stop[np.arange(len(dofs)), dofs] = -stops[dofs]
        Jn, Jt = pt["Jn"], pt["Jt"]
        sel = lambda A, idx: ca.vertcat(*[A[int(i), :] for i in idx]) if len(idx) else ca.SX(0, self.nv)  # noqa: E731
        selv = lambda a, idx: ca.vertcat(*[a[int(i)] for i in idx]) if len(idx) else ca.SX(0, 1)  # noqa: E731
        Fn = [Jn[int(i), :] - mu * sum(u[i][a] * Jt[a][int(i), :] for a in range(self.nt))
              if s and u[i] is not None else Jn[int(i), :]
              for i, s in zip(contacts, sliding)]
        Fn = ca.vertcat(*Fn) if len(contacts) else ca.SX(0, self.nv)
        tangent_rows = ca.vertcat(*[sel(Jt[a], sticking) for a in range(self.nt)])
        G = ca.vertcat(sel(Jn, contacts), ca.SX(ca.DM(G_stop)), tangent_rows)
        F = ca.vertcat(Fn, ca.SX(ca.DM(G_stop)), tangent_rows)
        b = ca.vertcat(selv(pt["bn"], contacts), ca.SX.zeros(len(dofs)),
                       *[selv(pt["bt"][a], sticking) for a in range(self.nt)])
        info = _Rows(
            np.zeros((0, 0)), np.zeros((0, 0)), np.zeros(0),
            np.concatenate([contacts, -np.ones(len(dofs), int)]),
            np.concatenate([-np.ones(len(contacts), int), dofs]),
            np.searchsorted(contacts, sticking), np.full(len(sticking), np.nan),  # mu: symbolic (self.mu)
        )
        return G, F, b, info

    def mode_rows(self, pt: dict, mode: _Mode, u: list):
        return self.rows(pt, np.flatnonzero(mode.closed), mode.sliding, mode.stop, u)

    def accelerations(self, pt: dict, mode: _Mode, d: ca.SX, core) -> tuple[ca.SX, ca.SX, ca.SX, _Rows]:
        """(a, lambda, [fn; ft] per contact, rows) of the mode at the point."""
        u = self.directions(pt, mode, d, core)
        G, F, b, info = self.mode_rows(pt, mode, u)
        X = _solve(pt["M"], ca.horzcat(pt["f"], F.T))
        a0, minv_ft = X[:, 0], X[:, 1:]
        if G.shape[0] == 0:
            lam = ca.SX(0, 1)
            a = a0
        else:
            lam = _solve(G @ minv_ft, -(G @ a0 + b))
            a = a0 + minv_ft @ lam
        return a, lam, self.contact_forces(info, lam, u, self.mu), info

    def contact_forces(self, info: _Rows, lam: ca.SX, u: list, mu: ca.SX | float) -> ca.SX:
        """[fn; ft (first tangent of every contact, then the second's)] of the rows' multipliers;
        a contact with a direction in ``u`` has -mu u fn."""
        fn = [ca.SX(0)] * self.nc
        ft = [[ca.SX(0)] * self.nc for _ in range(self.nt)]
        for r, c in enumerate(info.contact):
            if c >= 0:
                fn[c] = lam[r]
                if u[c] is not None:
                    for a in range(self.nt):
                        ft[a][c] = -mu * u[c][a] * lam[r]
        m = len(info.owner)
        for k, r in enumerate(info.owner):
            for a in range(self.nt):
                ft[a][int(info.contact[r])] = lam[info.n + a * m + k]
        return ca.vertcat(*fn, *[f for row in ft for f in row]) if self.nc else ca.SX(0, 1)

    def derivative(self, q, v, th, mode, d, core):
        pt = self.point(q, v, th)
        a, _, forces, _ = self.accelerations(pt, mode, d, core)
        return a, forces

    def rk4(self, q, v, th, mode, h, d, core):
        a1, f1 = self.derivative(q, v, th, mode, d, core)
        a2, f2 = self.derivative(q + 0.5 * h * v, v + 0.5 * h * a1, th, mode, d, core)
        v2 = v + 0.5 * h * a1
        a3, f3 = self.derivative(q + 0.5 * h * v2, v + 0.5 * h * a2, th, mode, d, core)
        v3 = v + 0.5 * h * a2
        a4, f4 = self.derivative(q + h * v3, v + h * a3, th, mode, d, core)
        v4 = v + h * a3
        q1 = q + h / 6.0 * (v + 2 * v2 + 2 * v3 + v4)
        v1 = v + h / 6.0 * (a1 + 2 * a2 + 2 * a3 + a4)
        return q1, v1, h / 6.0 * (f1 + 2 * f2 + 2 * f3 + f4)

    def ros2(self, q, v, th, mode, h, d, core):
        """:meth:`landing._Landing.implicit_step` symbolically (ROS2 with the joint laws in its
        matrix)."""
        g = ROS2_GAMMA * h
        k, c, _, _, _ = self.law_arrays(th)
        pt = self.point(q, v, th)
        u = self.directions(pt, mode, d, core)
        G, F, b, info = self.mode_rows(pt, mode, u)
        W = pt["M"] + ca.diag(g * c + g * g * k)

        def constrained(rhs, row_rhs):
            X = _solve(W, ca.horzcat(rhs, F.T))
            x0, winv_ft = X[:, 0], X[:, 1:]
            if G.shape[0] == 0:
                return x0, ca.SX(0, 1)
            nu = _solve(G @ winv_ft, row_rhs - G @ x0)
            return x0 + winv_ft @ nu, nu

        k1v, nu1 = constrained(pt["f"] - g * k * v, -b)
        k1q = v + g * k1v
        q2, v2 = q + h * k1q, v + h * k1v
        a2, f2 = self.derivative(q2, v2, th, mode, d, core)
        rq, rv = v2 - 2.0 * k1q, a2 - 2.0 * k1v
        k2v, nu2 = constrained(pt["M"] @ rv - g * k * rq, G @ rv)
        k2q = rq + g * k2v
        f1 = self.contact_forces(info, nu1, u, self.mu)
        f3 = self.contact_forces(info, nu2, u, self.mu)
        return q + 0.5 * h * (3.0 * k1q + k2q), v + 0.5 * h * (3.0 * k1v + k2v), 0.5 * h * (f1 + f2 + f3)

    def steer(self, q, v, th, mode, h, d) -> ca.SX:
        """:meth:`landing._Landing.steer`: per contact the core h mu f_n w of a sliding one (its
        normal force with the exact direction at the step's start, w the trace of its tangential
        inverse mass), 0 elsewhere and in the plane."""
        core = ca.SX.zeros(self.nc)
        moving = np.flatnonzero(_moving(mode, self.frictional))
        if self.planar or not len(moving):
            return core
        pt = self.point(q, v, th)
        _, _, forces, _ = self.accelerations(pt, mode, d, ca.SX.zeros(self.nc))
        for i in moving:
            rows = ca.vertcat(*[pt["Jt"][a][int(i), :] for a in range(self.nt)])
            w = ca.trace(rows @ _solve(pt["M"], rows.T))
            core[int(i)] = h * self.mu * ca.fmax(forces[int(i)], 0.0) * w
        return core

    def integrate(self, q, v, th, mode, h, method, d):
        """One step of the run's integrator (``rk4`` or ``implicit``): (q, v, impulses, core)."""
        core = self.steer(q, v, th, mode, h, d)
        step = self.ros2 if method == IMPLICIT else self.rk4
        return (*step(q, v, th, mode, h, d, core), core)

    def split(self, x):
        return x[: self.nv], x[self.nv :]

    def inputs(self, *args) -> list:
        """An operation's inputs: ``args``, then the carried slip directions in space."""
        return [*args] if self.planar else [*args, self.d]

    # ---- cached functions

    def op(self, name: str, inputs: list, outputs: list) -> _Op:
        """An operation whose Jacobian w.r.t. theta leaves out the slip floor."""
        return _Op(name, inputs, outputs, [self.differentiated if i is self.th else i for i in inputs])

    def step(self, mode: _Mode, method: str) -> _Op:
        """(x, theta, h[, d]) -> (x after one step of the mode by the run's integrator, contact
        impulses [fn; ft][, the step's core])."""
        key = ("step", method, _mode_key(mode))
        if key not in self.cache:
            h = ca.SX.sym("h")
            q, v = self.split(self.x)
            q1, v1, imp, core = self.integrate(q, v, self.th, mode, h, method, self.d)
            outs = [ca.vertcat(q1, v1), imp] + ([] if self.planar else [core])
            self.cache[key] = self.op("step", self.inputs(self.x, self.th, h), outs)
        return self.cache[key]

    def follow(self, mode: _Mode) -> _Op:
        """(x, theta, d, core) -> d after :meth:`landing._Landing.follow_slip` at x (space)."""
        key = ("follow", _mode_key(mode))
        if key not in self.cache:
            core = ca.SX.sym("core", self.nc)
            q, v = self.split(self.x)
            u = self.directions(self.point(q, v, self.th), mode, self.d, core)
            d = ca.vertcat(*[self.d[self.nt * i : self.nt * (i + 1)] if u[i] is None else ca.vertcat(*u[i])
                             for i in range(self.nc)])
            self.cache[key] = self.op("follow", [self.x, self.th, self.d, core], [d])
        return self.cache[key]

    def new_directions(self, mode: _Mode, kinds: tuple) -> _Op:
        """(x, theta, d) -> the slip directions a mode chosen at an event starts with (space):
        per contact ``kinds`` is "keep" (its direction carried), "slip" (its slip s / |s| at x:
        the contact slid on through the event) or "start" (it starts sliding: the direction of its
        slip acceleration in the mode, the fixed point d = a_t(d) / |a_t(d)| of the circular cone's
        law; one Newton step from the run's d, whose derivative is the implicit function
        theorem's)."""
        key = ("directions", _mode_key(mode), kinds)
        if key not in self.cache:
            q, v = self.split(self.x)
            pt = self.point(q, v, self.th)
            start = [i for i, k in enumerate(kinds) if k == "start"]
            parts = []
            for i, k in enumerate(kinds):
                di = self.d[self.nt * i : self.nt * (i + 1)]
                parts.append(pt["slip"][i] / _norm(pt["slip"][i]) if k == "slip" else di)
            d = ca.vertcat(*parts)
            if start:
                a, _, _, _ = self.accelerations(pt, mode, d, ca.SX.zeros(self.nc))
                residual = []
                for i in start:
                    at = ca.vertcat(*[pt["Jt"][j][i, :] @ a + pt["bt"][j][i] for j in range(self.nt)])
                    residual.append(d[self.nt * i : self.nt * (i + 1)] - at / _norm(at))
                R = ca.vertcat(*residual)
                idx = [self.nt * i + j for i in start for j in range(self.nt)]
                z = ca.vertcat(*[d[j] for j in idx])
                step = _solve(ca.jacobian(R, z), R)
                for n, j in enumerate(idx):
                    d[j] = d[j] - step[n]
            self.cache[key] = self.op("directions", [self.x, self.th, self.d], [d])
        return self.cache[key]

    def project(self, mode: _Mode, lifted: tuple, beyond: tuple = ()) -> _Op:
        """(x, theta) -> (x projected onto the mode's rows, the projection's impulses); ``lifted``:
        open contacts below the ground at the input, whose gaps are zeroed too."""
        key = ("project", _mode_key(mode), lifted, beyond)
        if key not in self.cache:
            q, v = self.split(self.x)
            th = self.th
            pt = self.point(q, v, th)
            place = mode.copy()
            place.closed[list(lifted)] = True
            if beyond:  # free joints past a stop, put back onto it
                place.stop = np.where(place.stop == 0, np.array(beyond, int), place.stop)
            dq = self.position_correction(pt, q, th, place)
            # the momentum the correction would move, given back through the base's translation
            # (:meth:`landing._Landing.momentum_kept`)
            dp = pt["momentum"][:, 0] - self.point(q - dq, v, th)["momentum"][:, 0]
            v = v + ca.vertcat(dp / pt["M"][0, 0], ca.SX.zeros(self.nv - dp.shape[0]))
            none = [None] * self.nc
            G, _, _, info = self.rows(pt, np.flatnonzero(mode.closed), mode.sliding, mode.stop, none)
            if G.shape[0] == 0:
                out = [ca.vertcat(q - dq, v), ca.SX.zeros(self.dims * self.nc)]
            else:
                minv_gt = _solve(pt["M"], G.T)
                impulse = -_solve(G @ minv_gt, G @ v)
                imp = self.contact_forces(info, impulse, none, 0.0)
                out = [ca.vertcat(q - dq, v + minv_gt @ impulse), imp]
            self.cache[key] = self.op("project", [self.x, self.th], out)
        return self.cache[key]

    def position_correction(self, pt, q, th, place: _Mode):
        G, _, _, info = self.rows(pt, np.flatnonzero(place.closed), place.sliding, place.stop, [None] * self.nc)
        n = info.n
        if n == 0:
            return ca.SX.zeros(self.nv)
        _, _, _, lo, hi = self.law_arrays(th)
        residual = []
        for r in range(n):
            c, d = int(info.contact[r]), int(info.dof[r])
            if c >= 0:
                residual.append(pt["gap"][c])
            else:
                side = int(place.stop[d])
                residual.append(-side * (q[d] - (hi[d] if side > 0 else lo[d])))
        Gn = G[:n, :]
        minv_gt = _solve(pt["M"], Gn.T)
        return minv_gt @ _solve(Gn @ minv_gt, ca.vertcat(*residual))

    def witness(self, q, v, th, mode: _Mode, index: int, ft_sign: float, d, core) -> ca.SX:
        """The raw (unscaled) witness ``index`` of :meth:`_Landing.witness_and_rate`."""
        nc, nv = self.nc, self.nv
        pt = self.point(q, v, th)
        group, i = (index // nc, index % nc) if index < 4 * nc else (4 + (index - 4 * nc) // nv, (index - 4 * nc) % nv)
        if group == 0:
            return pt["gap"][i]
        if group in (4, 5):
            _, _, _, lo, hi = self.law_arrays(th)
            return q[i] - lo[i] if group == 4 else hi[i] - q[i]
        if group == 3:  # the slip along the mode's direction
            if self.planar:
                return float(mode.side[i]) * pt["slip"][i][0]
            return ca.dot(d[self.nt * i : self.nt * (i + 1)], pt["slip"][i])
        _, lam, forces, info = self.accelerations(pt, mode, d, core)
        if group == 1:
            return forces[i]
        if group == 2:  # the cone's margin
            ft = [forces[nc * (1 + a) + i] for a in range(self.nt)]
            return self.mu * forces[i] - (ft_sign * ft[0] if self.planar else _norm(ca.vertcat(*ft)))
        r = int(np.flatnonzero(info.dof == i)[0])  # group 6: the stop's force
        return lam[r]

    def event_witness(self, mode: _Mode, index: int, ft_sign: float, method: str) -> _Op:
        """(x, theta, tau[, d]) -> the witness ``index`` after a step of tau from x."""
        key = ("witness", method, _mode_key(mode), index, ft_sign)
        if key not in self.cache:
            tau = ca.SX.sym("tau")
            q, v = self.split(self.x)
            q1, v1, _, core = self.integrate(q, v, self.th, mode, tau, method, self.d)
            w = self.witness(q1, v1, self.th, mode, index, ft_sign, self.d, core)
            self.cache[key] = self.op("witness", self.inputs(self.x, self.th, tau), [w])
        return self.cache[key]

    def impact(self, rows: _Rows, e: np.ndarray, modes: tuple) -> _Op:
        """(x, theta, e[, lambda*]) -> (v after, fn, ft, joint impulses d x joints) of the impact
        over ``rows`` in the law's modes ``modes`` (:func:`_impact_modes`), e the rows'
        restitutions. In the plane the mode's equations are linear; in space a sliding contact's
        impulse lies on the circular cone's edge against its slip after the impact,
        lambda_t = -mu lambda_n w / |w| (w = the tangent rows' velocities after), so the impulse
        is one Newton step on the mode's equations from the run's lambda* (a solution: the value is
        lambda* to rounding, the derivative the implicit function theorem's)."""
        n, m = rows.n, len(rows.owner)
        pushing, tangent = modes
        key = ("impact", tuple(rows.contact), tuple(rows.dof), modes)
        if key not in self.cache:
            q, v = self.split(self.x)
            th = self.th
            e = ca.SX.sym("restitution", n)
            pt = self.point(q, v, th)
            stops = np.zeros(self.nv, int)
            for r, dof in enumerate(rows.dof):
                if dof >= 0:
                    stops[dof] = int(np.rint(-rows.G[r, dof]))
            none = [None] * self.nc
            G, _, _, _ = self.rows(pt, rows.contact[rows.contact >= 0], np.zeros(self.nc, bool), stops, none)
            minv_gt = _solve(pt["M"], G.T)
            W = G @ minv_gt
            u = G @ v
            inputs = [self.x, th, e]
            if self.planar:
                K, r = [], []
                for i in range(n):
                    if pushing[i]:
                        K.append(W[i, :])
                        r.append(-(1.0 + e[i]) * u[i])
                    else:
                        K.append(_unit(n + m, i))
                        r.append(0)
                for k, mode in enumerate(tangent):
                    i = int(rows.owner[k])
                    if mode == 2:
                        K.append(W[n + k, :])
                        r.append(-u[n + k])
                    else:
                        K.append(_unit(n + m, n + k) + self.mu * float(mode) * _unit(n + m, i))
                        r.append(0)
                lam = _solve(ca.vcat(K), ca.vcat(r)) if n + m else ca.SX(0, 1)
            else:
                star = ca.SX.sym("lambda", n + self.nt * m)
                inputs.append(star)
                after = W @ star + u
                R = [after[i] + e[i] * u[i] if pushing[i] else star[i] for i in range(n)]
                tangential = [[] for _ in range(self.nt)]
                for k, mode in enumerate(tangent):
                    i = int(rows.owner[k])
                    at = [n + a * m + k for a in range(self.nt)]
                    w = ca.vertcat(*[after[j] for j in at])
                    for a, j in enumerate(at):
                        if mode == 0:
                            tangential[a].append(star[j])
                        elif mode == 2:
                            tangential[a].append(w[a])
                        else:  # sliding: on the cone's edge against the slip after
                            tangential[a].append(star[j] + self.mu * star[i] * w[a] / _norm(w))
                R = ca.vertcat(*R, *[x for rows_a in tangential for x in rows_a])
                lam = star - _solve(ca.jacobian(R, star), R) if n + m else ca.SX(0, 1)
            v_plus = v + minv_gt @ lam
            forces = self.contact_forces(rows, lam, none, self.mu)
            fn = forces[: self.nc]
            ft = [forces[self.nc * (1 + a) : self.nc * (2 + a)] for a in range(self.nt)]
            after = self.point(q, v_plus, th)["momentum"]
            S = ca.DM(self.S)
            F = [ca.vertcat(*[pt["normal"][c][k] * fn[c]
                              + sum(pt["tangent"][c][a][k] * ft[a][c] for a in range(self.nt))
                              for c in range(self.nc)]) for k in range(self.dims)]
            joint = after - pt["momentum"] - ca.vertcat(*[(S @ Fk).T for Fk in F])
            # the joint impulses as vectors (x, y[, z] rows): their norms are taken where a peak is
            # differentiated, since sqrt at a zero joint impulse would put 0 * inf = NaN in reverse mode
            outs = [v_plus, fn, ca.vertcat(*ft), joint[:, 1:]] + ([] if self.planar else [lam])
            self.cache[key] = self.op("impact", inputs, outs)
        return self.cache[key]

    def touchdown(self, lowest: int, lowest_x: float) -> _Op:
        """theta -> (q0, com height at q0, total mass); the contact ``lowest`` (at x = ``lowest_x``
        at theta*) sets the touchdown height."""
        key = ("touchdown", lowest)
        if key not in self.cache:
            th = self.th
            run = self.run
            q = ca.SX.zeros(self.nv)
            layout = dof_layout(run.topology, run.space)
            q[0] = float(run.q0[0])
            if self.planar:
                q[2] = self.angle(th, 0)
            else:  # the base's orientation is its design values' (rotation coordinates 0), z the scene's
                q[2] = float(run.q0[2])
            for b in range(1, self.tree.n_bodies):
                if layout.body_dof[b] is not None:
                    q[layout.body_dof[b]] = self.angle(th, b)
            v = ca.SX.zeros(self.nv)  # the posture's points and centre of mass need no velocity
            C = self.fn(q, v, th[: self.n_p], self.gravity)[9]
            x, y = C[0, lowest], C[1, lowest]
            if self.planar:
                ground = _terrain_height(run.scene.terrain, x, lowest_x)
            else:  # the heightfield's height under the contact: y - gap / n_y
                gap, normal = ground_expression(self.ground, C[:, lowest])
                ground = y - gap / normal[1]
            q[1] = TOUCHDOWN_CLEARANCE - (y - ground)
            pt = self.point(q, v, th)
            mass = sum(th[len(self.values) * b + self.values.index("mass")] for b in range(self.tree.n_bodies))
            self.cache[key] = self.op("touchdown", [th], [q, pt["com"], mass])
        return self.cache[key]

    def final(self) -> _Op:
        """(x, theta) -> (kinetic + spring energy, com height, final angles: the plane's base
        angle, in space the base's rotation coordinates; then each joint's)."""
        key = ("final",)
        if key not in self.cache:
            q, v = self.split(self.x)
            th = self.th
            pt = self.point(q, v, th)
            k, _, rest, _, _ = self.law_arrays(th)
            energy = pt["kinetic"] + 0.5 * ca.sum1(k * (q - rest) ** 2)
            layout = dof_layout(self.run.topology, self.space)
            base = [q[2]] if self.planar else [q[3], q[4], q[5]]
            angles = base + [self.angle(th, b) if layout.body_dof[b] is None else q[layout.body_dof[b]]
                             for b in range(1, self.tree.n_bodies)]
            self.cache[key] = self.op("final", [self.x, th], [energy, pt["com"], ca.vertcat(*angles)])
        return self.cache[key]


def _norm(x: ca.SX) -> ca.SX:
    """|x|, finite with finite derivatives at 0 (a branch not taken must not put NaN in if_else)."""
    return ca.sqrt(ca.fmax(ca.dot(x, x), 1e-300))


def slip_direction_expression(s: ca.SX, d: ca.SX, core, floor) -> ca.SX:
    """:func:`landing.slip_direction` of one contact: its slip ``s`` (2-vector), the mode's
    direction ``d``, the step's ``core`` and the resting threshold ``floor``."""
    speed = _norm(s)
    along = ca.logic_and(ca.dot(s, d) > 0, speed > floor)
    lifted = s + ca.fmax(core - speed, 0.0) * d
    return ca.if_else(along, lifted / _norm(lifted), d)


def spatial_contact_rows(N: ca.SX, Jc: ca.SX, bias: ca.SX) -> tuple[list, list, dict]:
    """Contact coordinates in space of :func:`landing.landing_function`'s ``normal`` (3 x n_c),
    ``contact_jacobian`` and ``contact_bias``: per contact its normal and tangents
    (:func:`_tangents`), and the rows ``Jn`` (n_c x nv), ``bn``, ``Jt`` and ``bt`` (one per tangent)."""
    nc, nv = N.shape[1], Jc.shape[1]
    normals = [N[:, i] for i in range(nc)]
    tangents = [_tangents(n) for n in normals]
    J = [Jc[3 * i : 3 * i + 3, :] for i in range(nc)]
    bb = [bias[3 * i : 3 * i + 3] for i in range(nc)]

    def rows(vecs: list) -> ca.SX:
        return ca.vertcat(*[a.T @ m for a, m in zip(vecs, J)]) if nc else ca.SX(0, nv)

    def values(vecs: list) -> ca.SX:
        return ca.vertcat(*[ca.dot(a, x) for a, x in zip(vecs, bb)]) if nc else ca.SX(0, 1)

    along = [[t[a] for t in tangents] for a in range(2)]
    return normals, tangents, dict(Jn=rows(normals), bn=values(normals), Jt=[rows(t) for t in along],
                                   bt=[values(t) for t in along])


def _tangents(n: ca.SX) -> list:
    """:func:`landing.tangent_basis` of one spatial normal: t_x (x's projection on the tangent
    plane, made unit) and t_z = t_x x n."""
    t_x = ca.DM([1.0, 0.0, 0.0]) - n[0] * n
    t_x = t_x / ca.norm_2(t_x)
    return [t_x, ca.cross(t_x, n)]


def _gap(terrain, px: ca.SX, py: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
    """The signed gap and ground normal of :func:`impulse_core.model.terrain.gap_expression`, with
    finite derivatives everywhere: that one's distance sqrt(dx^2 + dy^2) has a 0/0 derivative on
    the ground (d = 0), which CasADi's if_else carries into every branch. Here a piece's distance
    is linear (n . (p - a)) where the nearest point is inside it, radial only at a breakpoint."""
    xs, ys = terrain.x, terrain.y
    if len(xs) == 1:
        return py - ys[0], ca.SX(0.0), ca.SX(1.0)
    from impulse_core.model.terrain import _segment_normals, slope_normal

    n_pts = len(xs)
    seg = _segment_normals(terrain)
    pieces = [((xs[0], ys[0]), (-1.0, 0.0), math.inf, (0.0, 1.0))]
    pieces += [((xs[i], ys[i]), (xs[i + 1] - xs[i], ys[i + 1] - ys[i]), 1.0, tuple(seg[i])) for i in range(n_pts - 1)]
    pieces += [((xs[-1], ys[-1]), (1.0, 0.0), math.inf, (0.0, 1.0))]
    vertex = slope_normal(terrain, np.asarray(xs))
    h = ys[0]
    for i in range(n_pts - 1):
        slope = (ys[i + 1] - ys[i]) / (xs[i + 1] - xs[i])
        h = h + slope * (ca.fmin(ca.fmax(px, xs[i]), xs[i + 1]) - xs[i])
    sign = ca.if_else(py - h >= 0, 1.0, -1.0)
    best = None
    for k, ((ax, ay), (dx, dy), upper, (nx, ny)) in enumerate(pieces):
        t = ((px - ax) * dx + (py - ay) * dy) / (dx * dx + dy * dy)
        t = ca.fmax(t, 0.0) if math.isinf(upper) else ca.fmin(ca.fmax(t, 0.0), upper)
        cx, cy = ax + t * dx, ay + t * dy
        d2 = (px - cx) ** 2 + (py - cy) ** 2
        end = 0 if k == 0 else (n_pts - 1 if k == len(pieces) - 1 else None)
        if end is None:
            vnx = ca.if_else(t <= 0.0, vertex[k - 1][0], vertex[k][0])
            vny = ca.if_else(t <= 0.0, vertex[k - 1][1], vertex[k][1])
            interior = ca.logic_and(t > 0.0, t < upper)
        else:
            vnx, vny = vertex[end][0], vertex[end][1]
            interior = t > 0.0
        safe = ca.sqrt(ca.fmax(d2, 1e-24))
        radial = d2 > 1e-24
        g = ca.if_else(interior, nx * (px - ax) + ny * (py - ay), sign * safe)
        kx = ca.if_else(interior, nx, ca.if_else(radial, sign * (px - cx) / safe, vnx))
        ky = ca.if_else(interior, ny, ca.if_else(radial, sign * (py - cy) / safe, vny))
        if best is None:
            best = (d2, g, kx, ky)
        else:
            closer = d2 < best[0]
            best = tuple(ca.if_else(closer, new, old) for new, old in zip((d2, g, kx, ky), best))
    return best[1], best[2], best[3]


def _solve(A: ca.SX, B: ca.SX) -> ca.SX:
    """A^-1 B by Gaussian elimination without pivoting. CasADi's SX ``solve`` is a Gram-Schmidt
    QR whose square roots put 0 * inf = NaN in the derivatives where an entry is numerically zero;
    the matrices here (the mass matrix, the rows' Delassus matrices, the impact's mode matrix)
    have nonzero pivots in their natural order."""
    return _substitute(_factor(A), B)


def _factor(A: ca.SX) -> tuple[ca.SX, list[ca.SX]]:
    """:func:`_solve`'s elimination of A alone: (U, each column's multipliers), for
    :func:`_substitute` with any number of right-hand sides (the same operations as one solve)."""
    A, multipliers = ca.SX(A), []
    for k in range(A.shape[0] - 1):
        L = A[k + 1 :, k] / A[k, k]
        A[k + 1 :, k:] = A[k + 1 :, k:] - L @ A[k, k:]
        multipliers.append(L)
    return A, multipliers


def _substitute(factors: tuple[ca.SX, list[ca.SX]], B: ca.SX) -> ca.SX:
    """A^-1 B from A's :func:`_factor`: the elimination applied to B, then back substitution."""
    U, multipliers = factors
    n = U.shape[0]
    if n == 0:
        return ca.SX(0, B.shape[1])
    B = ca.SX(B)
    for k, L in enumerate(multipliers):
        B[k + 1 :, :] = B[k + 1 :, :] - L @ B[k, :]
    X = ca.SX.zeros(n, B.shape[1])
    for k in reversed(range(n)):
        rest = U[k, k + 1 :] @ X[k + 1 :, :] if k + 1 < n else 0
        X[k, :] = (B[k, :] - rest) / U[k, k]
    return X


_SYMBOLIC: dict = {}


def _symbolic(run: _Landing, laws: tuple[JointLaw, ...]) -> _Symbolic:
    """The symbolic operations of a run, shared by every run whose structure is the same (the
    design values, the friction coefficient and the slip floor are symbols; which rests follow the
    angle and which joints have stops, the ground, whether there is friction, gravity and the
    base's touchdown x and z are built in; the approach velocity is not in the graphs): a search
    that lands many designs of one topology, or one design in many scenarios, builds each mode's
    functions, and CasADi their derivatives, once."""
    laws = laws or (FREE,) * run.tree.n_bodies
    scene = run.scene
    key = (run.topology, run.space, scene.terrain, scene.heightfield, run.mu > 0, scene.gravity,
           scene.base_x, scene.base_z, tuple(law.rest is None for law in laws),
           tuple(law.limits is None for law in laws))
    if key not in _SYMBOLIC:
        if len(_SYMBOLIC) >= 16:
            _SYMBOLIC.pop(next(iter(_SYMBOLIC)))
        _SYMBOLIC[key] = _Symbolic(run, laws)
    return _SYMBOLIC[key]


def _unit(size: int, k: int) -> ca.SX:
    row = ca.SX.zeros(1, size)
    row[k] = 1
    return row


def _terrain_height(terrain, x: ca.SX, x_num: float) -> ca.SX:
    """The ground's height at x on the segment holding ``x_num`` (linear there; flat beyond)."""
    pts = np.asarray(terrain.points, dtype=float)
    if len(pts) == 1 or x_num <= pts[0, 0]:
        return ca.SX(float(pts[0, 1]))
    if x_num >= pts[-1, 0]:
        return ca.SX(float(pts[-1, 1]))
    i = int(np.searchsorted(pts[:, 0], x_num, side="right")) - 1
    (x0, y0), (x1, y1) = pts[i], pts[i + 1]
    return y0 + (y1 - y0) / (x1 - x0) * (x - x0)


def sequence_signature(tape: list, run: _Landing) -> tuple:
    """The discrete decisions of a taped run: per operation its kind and mode (steps: the mode and
    whether it is the last, shortened one; event steps: the mode and the witness that crossed;
    impacts: the rows, which restitutions the plastic rules zeroed, and the law's modes).
    Projections' rows follow from the modes; the open contacts they lift (left below the ground
    by rounding, with no first-order effect) are not included."""
    return tuple(s for s in (_signature(entry, run) for entry in tape) if s is not None)


def _signature(entry: tuple, run: _Landing) -> tuple | None:
    kind = entry[0]
    if kind == "step":
        return ("step", _mode_key(entry[3]), bool(entry[5]))
    if kind == "event_step":
        _, q, v, mode, tau, watch = entry
        return ("event", _mode_key(mode), _crossing(run, q, v, mode, tau, watch))
    if kind == "vertex_step":  # a resting contact passed a terrain breakpoint (not replayed: landing_gradient)
        _, q, v, mode, tau, crossed = entry
        return ("vertex", _mode_key(mode), tuple(int(c) for c in np.flatnonzero(crossed)))
    if kind == "impact":
        _, q, v, rows, e, sol, _ = entry
        return ("impact", tuple(int(c) for c in rows.contact), tuple(int(d) for d in rows.dof),
                tuple(float(z) == 0 for z in e), _impact_modes(rows, sol, _approach_speed(rows, v)))
    return None


def _approach_speed(rows: _Rows, v: np.ndarray) -> float:
    return max(float(np.max(np.abs(rows.G @ v), initial=0.0)), np.finfo(float).tiny)


def _impact_modes(rows: _Rows, sol, speed: float) -> tuple:
    n = rows.n
    impulse_tol = LEMKE_TOL * 1e3 * max(float(np.max(np.abs(sol.normal), initial=0.0)), np.finfo(float).tiny)
    pushing = sol.normal > impulse_tol
    tangent = []
    m = len(rows.owner)
    tangents = (len(sol.velocity) - n) // m if m else 1
    for k in range(m):
        i = int(rows.owner[k])
        w = sol.velocity[n + k :: m] if tangents > 1 else sol.velocity[n + k : n + k + 1]
        if not pushing[i]:
            tangent.append(0)
        elif np.linalg.norm(w) <= 1e-9 * speed:
            tangent.append(2)
        else:  # sliding: the plane's slip sign; in space 1 (the slip's direction is continuous)
            tangent.append(int(np.sign(w[0])) if tangents == 1 else 1)
    return tuple(int(x) for x in pushing), tuple(tangent)


def _crossing(run: _Landing, q, v, mode: _Mode, tau: float, watch: np.ndarray) -> tuple[int, float]:
    """The watched witness that crossed at the located tau (the smallest scaled value there), and
    the sign of its contact's tangential force (for a cone margin)."""
    q1, v1, _ = run.step(q, v, mode, tau)
    w = run.witness(q1, v1, mode)
    idx = np.flatnonzero(watch)
    i = int(idx[np.argmin(w[idx])])
    sign = 1.0
    if run.planar and run.nc <= i < 4 * run.nc and (i // run.nc) == 2:
        _, forces = run.derivative(q1, v1, mode)
        sign = float(np.sign(forces[run.nc + i % run.nc])) or 1.0
    return i, sign


def replayed_landing(tree: Tree, scene: Scene, laws: tuple[JointLaw, ...], settings: LandingSettings,
                     space: Space = PLANAR) -> LandingResult:
    """The landing whose run the derivatives replay (its step and momentum-balance share):
    :func:`landing`'s, or where that landing went on with Radau IIA (``auto`` on a stiff landing:
    its steps are not replayed), the same landing on RK4 (as ``auto`` went on before Radau IIA
    was one of its integrators)."""
    result = landing(tree, scene, laws, settings, space)
    if result.integrator != RADAU:
        return result
    return landing(tree, scene, laws, replace(settings, integrator=RK4), space)


def replayed_step(tree: Tree, scene: Scene, laws: tuple[JointLaw, ...], settings: LandingSettings,
                  space: Space = PLANAR) -> float:
    """The step of :func:`replayed_landing`."""
    return replayed_landing(tree, scene, laws, settings, space).step


def taped_run(tree: Tree, scene: Scene, laws: tuple[JointLaw, ...], step: float,
              settings: LandingSettings = LandingSettings(), space: Space = PLANAR, share: float | None = None,
              halvings: list[int] | None = None) -> tuple[LandingResult, list, _Landing]:
    """One numeric landing at the fixed Runge-Kutta ``step`` (in ``space``) with its tape; its steps keep
    the momentum balance within ``share`` of its budget (None: the share :func:`landing` gives its
    first run at ``settings.tolerance``, :func:`balance_share`; a landing's own: its ``share``).
    ``halvings``: another run's slow-slip splits (its ``run.slip_halvings``), taken instead of this
    run's own as far as they reach (the branch whose derivative that run's replay gives: central
    differences along it, module docstring)."""
    run = _Landing(tree, scene, laws, settings, space)
    run.given_halvings = halvings
    if run.method == RADAU:
        raise ModelError("integrator: the derivatives replay RK4 and ROS2 steps, not Radau IIA's (radau)")
    run.tape = []
    result = run.run(step, share=balance_share(settings.tolerance) if share is None else share)
    tape, run.tape = run.tape, None  # the run may be kept (a cached structure): not its tape
    return result, tape, run


def landing_gradient(
    tree: Tree,
    scene: Scene,
    laws: tuple[JointLaw, ...] = (),
    settings: LandingSettings = LandingSettings(),
    step: float | None = None,
    space: Space = PLANAR,
    directions: np.ndarray | None = None,
    share: float | None = None,
) -> LandingGradient:
    """The landing's objectives and their exact derivatives w.r.t. theta and the scene's values
    (module docstring) along the event sequence of the run at ``step`` (None: the step
    :func:`landing` reports at ``settings``, which costs that landing first), in the plane or in
    ``space``. With ``directions`` D (rows: theta's, then the scene's values; k columns) only the
    derivatives along D's columns are carried (forward mode, k sweeps per operation: cheaper than
    every column where k is small, as for a search's few variables): ``jacobian`` is then
    d/dz at theta + D z (k entries per output) and ``scene_jacobian`` is empty. ``share``: the
    momentum balance's share of the run (:func:`taped_run`; with ``step`` None, the landing's).

    Raises:
        ModelError: as :func:`landing`.
        NumericalError: as :func:`landing`; or redundant rows in some mode, or (space) an impact
            off the circular cone's exact law or a slip direction the replay does not reproduce
            (not differentiable), or a Moreau-Jean bridge across stalled events (:meth:`_Landing.bridge`).
    """
    t0 = time.perf_counter()
    theta = design_theta(tree, laws, space)
    conditions = scene_theta(tree, scene, laws, space)
    if step is None:
        replayed = replayed_landing(tree, scene, laws, settings, space)
        step, share = replayed.step, replayed.share
    result, tape, run = taped_run(tree, scene, laws, step, settings, space, share)
    t1 = time.perf_counter()
    sym = _symbolic(run, laws)
    nc, nv, n_theta, dims = sym.nc, sym.nv, sym.n_theta, sym.dims
    # the operations' parameters: theta, mu, the slip floor; the sensitivities' columns: theta, then the
    # scene's values (:func:`scene_names`: mu first, so an operation's parameter columns lead)
    p = np.append(theta, [run.mu, run.speed_tol])
    n = n_theta + len(conditions) if directions is None else directions.shape[1]
    ahead = _Sweep(n, None if directions is None else directions[: n_theta + 1])
    speed_col, restitution_col = n_theta + SCENE_VALUES.index("speed"), n_theta + SCENE_VALUES.index("restitution")
    stop_col = {j: n_theta + len(SCENE_VALUES) + i for i, (_, j) in enumerate(sym.dofs)}

    # touchdown: the lowest contact (the first where several tie) sets the height
    geometry = run.point(np.array([run.q0[0], 0.0, *run.q0[2:]]), np.zeros(nv)).contacts
    if run.planar:
        from impulse_core.model.terrain import vertical_clearance

        clearance = vertical_clearance(scene.terrain, geometry)
    else:
        from impulse_core.model.heightfield import vertical_clearance as clearance_above

        clearance = clearance_above(sym.ground, geometry)
    lowest = int(np.argmin(clearance))
    v0 = pre_impact_velocity(run.topology, scene, run.space)
    dv0 = pre_impact_velocity(run.topology, Scene(speed=1.0), run.space)  # d v0 / d speed (v0 is linear in it)
    (q0, height0, mass), (dq0, d_height0, d_mass) = ahead(sym.touchdown(lowest, float(geometry[lowest, 0])), [p])
    # forward sensitivities: each quantity z carries dz/d(theta, scene values), or along the
    # directions (rows: its entries)
    x = np.concatenate([q0, v0])
    S = np.vstack([dq0, np.zeros((nv, n))])
    if directions is None:
        S[nv:, speed_col] = dv0
    else:
        S[nv:] = np.outer(dv0, directions[speed_col])
    # energy_absorbed's energy brought at touchdown: kinetic at v0 and the springs' at q0
    (e_touch, _, _), (d_e_touch, _, _) = ahead(sym.final(), [x, p], [S, None])
    totals, S_totals = np.zeros(dims * nc), np.zeros((dims * nc, n))
    # space: the slip directions the mode carries, and the last step's core (:meth:`_Landing.steer`)
    nd = sym.nt * nc
    d, S_d = np.zeros(nd), np.zeros((nd, n))
    core, S_core = np.zeros(nc), np.zeros((nc, n))
    t, dt = 0.0, np.zeros(n)
    T = float(scene.duration)
    events = []  # per impact: (fn, d fn, joint impulses, their derivative)
    signature = []
    checked: set = set()
    previous = None

    for entry in tape:
        kind = entry[0]
        if kind == "rechart":
            raise NumericalError(f"the base turned more than {RECHART:g} rad: its rotation coordinates were "
                                 "re-centred, which the derivatives' replay does not follow")
        if kind == "vertex_step":
            where = "a grid line of scene.heightfield" if run.grid is not None else "a breakpoint of scene.terrain"
            raise NumericalError(f"a resting contact passed {where} (an event where the ground's normal jumps), "
                                 "which the derivatives' replay does not follow")
        if kind == "unspun":
            raise NumericalError("a rod of radius 0 spun about its own axis, a motion that moves no mass, whose "
                                 "velocity the landing holds at 0 (MODEL_FORMAT: radius): the replay does not follow")
        if kind == "bridge":
            raise NumericalError("events stalled where no mode held and the landing crossed them by Moreau-Jean "
                                 "steps (a start of slip the modes do not resolve), which the derivatives' replay "
                                 "does not follow")
        if kind == "crease_project":
            raise NumericalError("a projection carried a resting contact across a grid line of scene.heightfield "
                                 "(onto the next cell's rows), which the derivatives' replay does not follow")
        item = _signature(entry, run)
        if item is not None:
            signature.append(item)
        if kind in ("step", "event_step"):
            _, q, v, mode = entry[:4]
            if _mode_key(mode) not in checked:
                _check_rows(run, q, v, mode)
                checked.add(_mode_key(mode))
            if not run.planar:
                _check_directions(mode, d, run.mu > 0)
            extra, extra_seeds = ([], []) if run.planar else ([d], [S_d])
            if kind == "step":
                _, q, v, mode, h, final = entry
                h, dh = (T - t, -dt) if final else (h, np.zeros(n))
            else:
                _, q, v, mode, tau, watch = entry
                index, sign = item[2]
                op = sym.event_witness(mode, index, sign, run.method)
                c = float(op.base(np.concatenate([q, v]), p, tau, *extra))
                (w,), Jw = op(x, p, tau, *extra)
                rate = float(Jw[0][2][0, 0])
                if rate == 0 or not math.isfinite(rate):
                    raise NumericalError("an event's witness does not cross (a graze): no derivative of its time")
                # the event time: where the witness reaches its value at the located tau (one
                # Newton correction; its derivative is the implicit function theorem's)
                h = tau - float(w[0] - c) / rate
                dh = -ahead.jacobians(Jw[0], [S, None, np.zeros((1, n)), *extra_seeds])[0] / rate
            outs, d_outs = ahead(sym.step(mode, run.method), [x, p, h, *extra], [S, None, dh[None, :], *extra_seeds])
            S_totals = S_totals + d_outs[1]
            if not run.planar:
                core, S_core = outs[2], d_outs[2]
            S = d_outs[0]
            x, totals, t, dt = outs[0], totals + outs[1], t + h, dt + dh
        elif kind == "impact":
            _, q, v, rows, e, sol, plastic = entry
            star = [] if run.planar else [np.concatenate([sol.normal, sol.tangential])]
            # each row's restitution: the scene's (a contact) or its joint's stop restitution, 0
            # where the plastic rules zeroed it (a decision of the sequence)
            de = np.zeros((rows.n, n))
            for r in np.flatnonzero(~plastic):
                col = restitution_col if rows.contact[r] >= 0 else stop_col[int(rows.dof[r])]
                de[r] = directions[col] if directions is not None else np.arange(n) == col
            star_seeds = [np.zeros((len(star[0]), n))] if star else []  # the run's impulse: a point of evaluation
            outs, d_out = ahead(sym.impact(rows, e, item[4]), [x, p, e, *star], [S, None, de, *star_seeds])
            v_plus, fn, ft, joint = outs[:4]
            if star:  # the run's impulse meets the mode's equations at the run's own state (not its polyhedral answer)
                lam = np.asarray(sym.impact(rows, e, item[4]).base(np.concatenate([q, v]), p, e, star[0])[4]).ravel()
                if np.max(np.abs(lam - star[0]), initial=0.0) > 1e-6 * max(np.max(np.abs(star[0])), 1e-300):
                    raise NumericalError("an impact off the circular cone's exact law (its polyhedral answer): "
                                         "no derivative")
            x = np.concatenate([x[:nv], v_plus])
            S = np.vstack([S[:nv], d_out[0]])
            totals = totals + np.concatenate([fn, ft])
            S_totals = S_totals + np.vstack([d_out[1], d_out[2]])
            events.append((fn, d_out[1], joint, d_out[3]))
        elif kind == "twins":  # identical toes set to their mean: a rounding's correction, the sensitivities
            # kept (a design direction may part the twins)
            groups = entry[1]
            x = np.concatenate([symmetrized(x[:nv], groups), symmetrized(x[nv:], groups)])
        elif kind == "project":
            _, q, v, mode = entry
            if not run.planar and previous != "step":  # an event chose this mode: its slip directions
                d, S_d = _event_directions(sym, ahead, run.point(q, v).slip, mode, x, p, d, S, S_d)
            place, _ = run.placement(run.point(q, v), q, mode)
            lifted = tuple(int(i) for i in np.flatnonzero(place.closed & ~mode.closed))
            put_back = np.where(mode.stop == 0, place.stop, 0)
            beyond = tuple(int(b) for b in put_back) if np.any(put_back) else ()
            (x1, imp), (S, d_imp) = ahead(sym.project(mode, lifted, beyond), [x, p], [S, None])
            S_totals = S_totals + d_imp
            x, totals = x1, totals + imp
            if not run.planar and previous == "step" and np.any(_moving(mode, run.mu > 0)):
                (d,), (S_d,) = ahead(sym.follow(mode), [x, p, d, core], [S, None, S_d, S_core])
        previous = kind
    (energy, com, angles), (d_energy, d_com, d_angles) = ahead(sym.final(), [x, p], [S, None])
    fall = height0[0] - com[0]  # the centre of mass's drop over the landing
    brought = e_touch[0] + float(mass[0]) * scene.gravity * fall
    d_brought = d_e_touch[0] + scene.gravity * (d_mass[0] * fall + float(mass[0]) * (d_height0[0] - d_com[0]))
    absorbed = 1.0 - energy[0] / brought
    d_absorbed = -(d_energy[0] * brought - energy[0] * d_brought) / brought**2

    # peaks: the event (and joint) attaining the maximum in the numeric run
    ext = np.array([ev.external_norm for ev in result.events])
    inr = np.array([ev.internal_norm for ev in result.events])
    mx = np.array([float(ev.internal_magnitude.max()) if ev.internal_magnitude.size else 0.0 for ev in result.events])
    ties, chosen = {}, {}
    for name, vals in (("peak_external_norm", ext), ("peak_internal_norm", inr), ("peak_max_internal", mx)):
        i = int(np.argmax(vals))
        ties[name] = tuple(int(k) for k in np.flatnonzero(vals >= vals[i] * (1 - TIE)))
        chosen[name] = i

    def norm_and_derivative(z: np.ndarray, dz: np.ndarray) -> tuple[float, np.ndarray]:
        size = float(np.linalg.norm(z))
        return size, (z @ dz) / size if size > 0 else np.zeros(n)

    fn, d_fn, _, _ = events[chosen["peak_external_norm"]]
    peak_ext = norm_and_derivative(fn, d_fn)
    _, _, joint, d_joint = events[chosen["peak_internal_norm"]]
    peak_int = norm_and_derivative(joint, d_joint)
    _, _, joint, d_joint = events[chosen["peak_max_internal"]]
    magnitudes = result.events[chosen["peak_max_internal"]].internal_magnitude
    j = int(np.argmax(magnitudes)) if magnitudes.size else -1
    peak_max = (norm_and_derivative(joint[dims * j : dims * (j + 1)], d_joint[dims * j : dims * (j + 1)]) if j >= 0
                else (0.0, np.zeros(n)))
    peak_events = {"peak_external_norm": (chosen["peak_external_norm"], -1),
                   "peak_internal_norm": (chosen["peak_internal_norm"], -1),
                   "peak_max_internal": (chosen["peak_max_internal"], j)}
    out = np.concatenate([[peak_ext[0], peak_int[0], peak_max[0], absorbed], totals[:nc], angles])
    jac = np.vstack([peak_ext[1], peak_int[1], peak_max[1], d_absorbed, S_totals[:nc], d_angles])
    if run.mu == 0:  # frictionless: the rows friction would add are not there (module docstring)
        friction_col = n_theta + SCENE_VALUES.index("friction")
        jac[:, friction_col if directions is None else directions[friction_col] != 0] = np.nan
    t2 = time.perf_counter()
    values, jacobian, scene_jacobian = {}, {}, {}
    rows_of = {name: k for k, name in enumerate(SCALARS)}
    rows_of["total_external"] = slice(4, 4 + nc)
    rows_of["final_angles"] = slice(4 + nc, len(out))
    for name, k in rows_of.items():
        value = out[k]
        values[name] = float(value) if isinstance(k, int) else value.copy()
        split = n_theta if directions is None else n  # along directions: no scene columns apart
        jacobian[name], scene_jacobian[name] = jac[k, :split].copy(), jac[k, split:].copy()
    return LandingGradient(
        values=values, jacobian=jacobian, theta=theta, names=design_names(tree, space), sequence=tuple(signature),
        peak_events=peak_events, ties=ties, result=result,
        timings={"run": t1 - t0, "sensitivities": t2 - t1},
        scene_jacobian=scene_jacobian, scene_theta=conditions, scene_names=scene_names(tree, space),
    )


class _Sweep:
    """How the replay carries sensitivities through an operation: ``sweep(op, args, seeds)``
    returns the outputs and their derivatives from the seeds (per input, its entries'
    sensitivities; theta's None: the sweep's own). With ``P`` None every column of theta, mu and
    the scene's values is carried (n of them; theta's and mu's lead) by the operations'
    Jacobians; with ``P`` (theta's and mu's rows of the directions, n columns) only the
    directions, by forward mode."""

    def __init__(self, n: int, P: np.ndarray | None) -> None:
        self.n = n
        self.P = None if P is None else np.vstack([P, np.zeros((1, n))])  # the slip floor: not moved

    def __call__(self, op: _Op, args: list, seeds: list | None = None) -> tuple[list[np.ndarray], list[np.ndarray]]:
        seeds = seeds or [None]
        if self.P is None:
            outs, J = op(*args)
            return outs, [self.jacobians(Jo, seeds) for Jo in J]
        return op.along(args, [self.P if seed is None else seed for seed in seeds])

    def jacobians(self, J: list[np.ndarray], seeds: list) -> np.ndarray:
        """An output's derivative from its Jacobians w.r.t. the inputs and their ``seeds``, in order."""
        out = np.zeros((J[0].shape[0], self.n))
        for Jj, seed in zip(J, seeds, strict=True):
            if seed is not None:
                out += Jj @ seed
            elif self.P is None:  # theta's and mu's columns lead
                out[:, : Jj.shape[1]] += Jj
            else:
                out += Jj @ self.P[: Jj.shape[1]]
        return out


def _check_directions(mode: _Mode, d: np.ndarray, frictional: bool) -> None:
    """The carried slip directions are the run's (space): else the replay has missed a rule."""
    moving = _moving(mode, frictional)
    gap = np.abs(mode.slip[moving] - d.reshape(mode.slip.shape)[moving])
    # a missed rule differs at O(1); an ill-conditioned event time (a slow touchdown) moves the
    # replayed state, and with it d, by more than rounding
    if np.max(gap, initial=0.0) > 1e-5:
        raise NumericalError(f"a sliding contact's direction differs from the run's by {np.max(gap):.1e}: not replayed")


def _event_directions(sym: _Symbolic, ahead: _Sweep, slip: np.ndarray, mode: _Mode, x: np.ndarray, p: np.ndarray,
                      d: np.ndarray, S: np.ndarray, S_d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The slip directions (and their derivatives) of a mode that an event chose (space): each
    sliding contact's is the one it carried (the mode persisted), its slip's s / |s| at the event
    (``slip``, the run's at x), or the fixed point of a contact starting to slide
    (:meth:`_Symbolic.new_directions`); the others take the run's (no effect)."""
    target = mode.slip.reshape(-1)
    moving = _moving(mode, sym.frictional)
    nt = sym.nt
    d_in, S_in = d.copy(), S_d.copy()
    kinds = []
    for i in range(sym.nc):
        at = slice(nt * i, nt * (i + 1))
        speed = float(np.linalg.norm(slip[i]))
        if moving[i] and np.max(np.abs(d[at] - target[at])) <= 1e-9:
            kinds.append("keep")
            continue
        if moving[i] and speed > 0 and np.max(np.abs(slip[i] / speed - target[at])) <= 1e-9:
            kinds.append("slip")
        else:
            kinds.append("start" if moving[i] else "keep")
        d_in[at], S_in[at] = target[at], 0.0
    if not np.any(moving):
        return d_in, S_in
    (d_out,), (S_out,) = ahead(sym.new_directions(mode, tuple(kinds)), [x, p, d_in], [S, None, S_in])
    if np.max(np.abs(d_out - target)) > 1e-6:
        raise NumericalError("a contact starting to slide in space whose direction is not the circular cone's "
                             f"(off by {np.max(np.abs(d_out - target)):.1e}): no derivative")
    return d_out, S_out


def _check_rows(run: _Landing, q: np.ndarray, v: np.ndarray, mode: _Mode) -> None:
    """Refuse a mode whose rows are redundant (the force split is not unique: no derivative)."""
    from impulse_core.timedomain.events.rows import _mode_rows

    pt = run.point(q, v)
    rows = _mode_rows(pt, mode, run.mu)
    if rows.G.shape[0]:
        W = rows.G @ np.linalg.solve(pt.M, rows.F.T)
        if np.linalg.cond(W) > 1e12:
            raise NumericalError("redundant constraint rows in a landing mode: the force split is not unique, "
                                 "so it has no derivative")


__all__ = ["LAW_VALUES", "apply_theta", "body_values", "SCALARS", "SCENE_VALUES", "LandingGradient", "design_names",
           "design_theta", "landing_gradient", "scene_names", "scene_theta",
           "sequence_signature", "taped_run"]
