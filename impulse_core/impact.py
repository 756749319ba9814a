"""The impulse model as CasADi graphs: external impulses (paper eq. 11), post-impact velocities
and internal (joint reaction) impulses (paper eqs. 15-27, as an impulsive Newton-Euler pass).

Everything here is a pure function of a :class:`~impulse_core.tree.Topology` that returns
CasADi SX expressions of the design vector ``p``; :func:`impact_function` wraps them in one
named ``casadi.Function`` per topology.
"""

from __future__ import annotations

import casadi as ca

from impulse_core import dynamics as dyn
from impulse_core.kinematics import (
    GROUND_NORMAL,
    PLANAR,
    Space,
    dof_layout,
    forward_kinematics,
    point_jacobian,
    unpack_values,
    contact_bodies,
)
from impulse_core.tree import Topology


#: Ground tangent (world frame): the direction of the tangential (friction) impulse in the plane.
GROUND_TANGENT = ca.DM([1.0, 0.0, 0.0])


def _contact_jacobian(topology: Topology, p: ca.SX, space: Space):
    values = unpack_values(topology, p)
    kin = forward_kinematics(topology, values, space)
    layout = dof_layout(topology, space)
    return values, kin, layout, _direction_jacobian(topology, kin, layout, space, GROUND_NORMAL)


def _direction_jacobian(topology: Topology, kin, layout, space: Space, direction: ca.DM) -> ca.SX:
    """Jacobian of the active contacts' velocity along ``direction`` (world frame), one row each."""
    bodies = contact_bodies(topology)
    rows = []
    for c in topology.active:
        Jv, _ = point_jacobian(kin, layout, bodies[c], kin.W_p_C[c], space)
        rows.append(direction.T @ Jv)
    return ca.vertcat(*rows) if rows else ca.SX(0, layout.nv)


def delassus_matrix(J: ca.SX, f: dyn.LTDL) -> tuple[ca.SX, ca.SX]:
    """Delassus matrix A = J M^-1 J^T (paper eq. 11, A_ij = n_i^T J_ij n_j) and M^-1 J^T,
    from the L^T D L factor of M: with Y = L^-T J^T, A = Y^T D^-1 Y."""
    Y = dyn.solve_lt(f, J.T)
    DY = dyn.solve_d(f, Y)
    A = Y.T @ DY
    A = 0.5 * (A + A.T)
    return A, dyn.solve_l(f, DY)


def external_impulse(A: ca.SX, J: ca.SX, v_minus: ca.SX, restitution: ca.SX) -> tuple[ca.SX, ca.SX]:
    """Normal impulses of the coupled Newton law, paper eq. 11: A lambda = -(1 + e) J v_minus.

    Solved by a dense L^T D L factor of A (positive definite when the contact normals are
    independent). Returns (lambda, relative pivots D_k / A_kk); a pivot near zero means A has
    lost rank and lambda is not to be trusted (the caller checks).
    """
    n = A.shape[0]
    f = dyn.ltdl(A, dyn.dense_parent(n))
    rhs = -(1 + restitution) * (J @ v_minus)
    return dyn.solve(f, rhs), dyn.relative_pivots(f, A)


def internal_impulse(
    topology: Topology,
    kin,
    jac: dyn.BodyJacobians,
    values,
    delta_v: ca.SX,
    external: ca.SX,
    tangential: ca.SX | None = None,
) -> tuple[ca.SX, ca.SX]:
    """Impulse each joint transmits from parent to child: (force, torque about the joint), world
    frame, one column per non-base body (3 x (n_bodies - 1) each).

    Impulsive Newton-Euler backward pass (paper eqs. 15-27 in the world frame): the joint impulse
    into body k's subtree equals the subtree's momentum change minus the external impulses on it
    (normal ``external`` along the ground normal, plus ``tangential`` along the ground tangent
    when given). Momentum is accumulated as wrenches about the world origin, then shifted to each
    joint.
    """
    n = topology.n_bodies
    dP = [values[b].mass * (jac.Jv[b] @ delta_v) for b in range(n)]
    dL = [jac.W_I_G[b] @ (jac.Jw[b] @ delta_v) for b in range(n)]
    force = [dP[b] for b in range(n)]
    moment = [ca.cross(kin.W_p_G[b], dP[b]) + dL[b] for b in range(n)]  # about the world origin
    bodies = contact_bodies(topology)
    for i, c in enumerate(topology.active):
        b = bodies[c]
        f_ext = external[i] * GROUND_NORMAL
        if tangential is not None:
            f_ext = f_ext + tangential[i] * GROUND_TANGENT
        force[b] = force[b] - f_ext
        moment[b] = moment[b] - ca.cross(kin.W_p_C[c], f_ext)
    for b in reversed(range(1, n)):
        parent = topology.parents[b]
        force[parent] = force[parent] + force[b]
        moment[parent] = moment[parent] + moment[b]
    F = ca.horzcat(*force[1:]) if n > 1 else ca.SX(3, 0)
    T = ca.horzcat(*[moment[b] - ca.cross(kin.W_p_O[b], force[b]) for b in range(1, n)]) if n > 1 else ca.SX(3, 0)
    return F, T


#: Names of the compiled function's inputs and outputs.
IMPACT_INPUTS = ("p", "v_minus", "restitution")
RESPONSE_INPUTS = ("p", "v_minus", "external")
RESPONSE_OUTPUTS = (
    "v_plus",
    "internal",
    "internal_torque",
    "internal_magnitude",
    "external_norm",
    "internal_norm",
    "energy_before",
    "energy_after",
    "contact_velocity",
)
IMPACT_OUTPUTS = ("external", "delassus_pivots") + RESPONSE_OUTPUTS


def _model(topology: Topology, space: Space, p: ca.SX):
    """Kinematics, Jacobians, mass matrix and its factor of one topology."""
    values, kin, layout, J = _contact_jacobian(topology, p, space)
    jac = dyn.body_jacobians(kin, layout, values, space)
    M = dyn.mass_matrix(jac, values)
    f = dyn.ltdl(M, layout.dof_parent)
    return values, kin, layout, J, jac, M, f


def _response_outputs(topology, kin, jac, values, J, M, M_inv_JT, v_minus, external, tangential=None):
    """Outputs named ``RESPONSE_OUTPUTS``. ``M_inv_JT`` has one column per normal impulse, then,
    with ``tangential``, one per tangential impulse."""
    delta_v = M_inv_JT @ (external if tangential is None else ca.vertcat(external, tangential))
    v_plus = v_minus + delta_v
    F, T = internal_impulse(topology, kin, jac, values, delta_v, external, tangential)
    magnitude = ca.sqrt(ca.sum1(F**2)).T if F.shape[1] else ca.SX(0, 1)
    return (
        v_plus,
        F,
        T,
        magnitude,
        ca.norm_2(external) if external.shape[0] else ca.SX(0),
        ca.norm_2(magnitude) if magnitude.shape[0] else ca.SX(0),
        0.5 * v_minus.T @ M @ v_minus,
        0.5 * v_plus.T @ M @ v_plus,
        J @ v_plus,
    )


def impact_function(topology: Topology, space: Space = PLANAR) -> ca.Function:
    """The paper's model for one topology, as a named CasADi function.

    Inputs: ``p`` (design vector, ``tree.design_vector``), ``v_minus`` (generalized velocity
    before impact: base linear velocity of its origin and angular velocity in the world frame,
    then joint rates), ``restitution``.
    Outputs: ``external`` (normal impulse at each active contact, N s), ``delassus_pivots``,
    ``v_plus``, ``internal`` (3 x joints joint force impulses, N s), ``internal_torque``
    (3 x joints, about each joint, N m s), ``internal_magnitude``, ``external_norm``,
    ``internal_norm``, ``energy_before``, ``energy_after`` (J), ``contact_velocity``
    (normal velocity of each active contact after impact).
    """
    nv = dof_layout(topology, space).nv
    p = ca.SX.sym("p", topology.n_values)
    v_minus = ca.SX.sym("v_minus", nv)
    e = ca.SX.sym("restitution")
    values, kin, layout, J, jac, M, f = _model(topology, space, p)
    A, M_inv_JT = delassus_matrix(J, f)
    lam, pivots = external_impulse(A, J, v_minus, e)
    outs = _response_outputs(topology, kin, jac, values, J, M, M_inv_JT, v_minus, lam)
    return ca.Function("impact", [p, v_minus, e], [lam, pivots, *outs], list(IMPACT_INPUTS), list(IMPACT_OUTPUTS))


def response_function(topology: Topology, space: Space = PLANAR) -> ca.Function:
    """Given external impulses, everything that follows from them (same outputs as
    :func:`impact_function` after ``delassus_pivots``), plus the Delassus matrix and the
    contact Jacobian as ``delassus`` and ``contact_jacobian``: the path for contact sets whose
    impulse split the Newton law leaves open."""
    nv = dof_layout(topology, space).nv
    p = ca.SX.sym("p", topology.n_values)
    v_minus = ca.SX.sym("v_minus", nv)
    lam = ca.SX.sym("external", len(topology.active))
    values, kin, layout, J, jac, M, f = _model(topology, space, p)
    A, M_inv_JT = delassus_matrix(J, f)
    outs = _response_outputs(topology, kin, jac, values, J, M, M_inv_JT, v_minus, lam)
    return ca.Function(
        "response",
        [p, v_minus, lam],
        [*outs, A, J],
        list(RESPONSE_INPUTS),
        list(RESPONSE_OUTPUTS) + ["delassus", "contact_jacobian"],
    )


def friction_response_function(topology: Topology, space: Space = PLANAR) -> ca.Function:
    """Given normal and tangential (x direction) impulses at the active contacts, everything that
    follows from them: the outputs of :func:`response_function` (``contact_velocity`` normal;
    ``internal`` includes the tangential impulses' share) plus ``tangent_velocity`` (tangential
    velocity of each active contact after impact, m/s). Built only for scenes with friction."""
    nv = dof_layout(topology, space).nv
    n = len(topology.active)
    p = ca.SX.sym("p", topology.n_values)
    v_minus = ca.SX.sym("v_minus", nv)
    lam = ca.SX.sym("external", n)
    lam_t = ca.SX.sym("tangential", n)
    values, kin, layout, J, jac, M, f = _model(topology, space, p)
    Jt = _direction_jacobian(topology, kin, layout, space, GROUND_TANGENT)
    _, M_inv_JT = delassus_matrix(ca.vertcat(J, Jt), f)
    outs = _response_outputs(topology, kin, jac, values, J, M, M_inv_JT, v_minus, lam, lam_t)
    return ca.Function(
        "friction_response",
        [p, v_minus, lam, lam_t],
        [*outs, Jt @ outs[0]],
        ["p", "v_minus", "external", "tangential"],
        list(RESPONSE_OUTPUTS) + ["tangent_velocity"],
    )


def _mul_l(f: dyn.LTDL, v: ca.SX) -> ca.SX:
    """L v with the unit lower triangular factor of M = L^T D L (sparse: ancestors only)."""
    return ca.vertcat(*[v[k] + sum((f.L[(k, i)] * v[i] for i in f.ancestors(k)), ca.SX(0)) for k in range(v.shape[0])])


def metric_function(topology: Topology, space: Space = PLANAR, tangent: bool = False) -> ca.Function:
    """The contact problem in the kinetic-energy metric, for the rungs solved as least squares.

    With M = L^T D L (the tree's sparse factor) and u = D^1/2 L v, the kinetic energy is |u|^2 / 2
    and an impulse lambda on the contact rows changes u by E lambda, E = D^-1/2 L^-T J^T; the
    Delassus matrix is A = E^T E (paper eq. 11). Inputs ``p``, ``v_minus``. Outputs
    ``contact_jacobian`` J (rows: the active contacts' normals, then, with ``tangent``, their
    x tangents), ``delassus`` A, ``metric_factor`` E (nv x rows) and ``u_minus`` (D^1/2 L v_minus).
    """
    nv = dof_layout(topology, space).nv
    p = ca.SX.sym("p", topology.n_values)
    v_minus = ca.SX.sym("v_minus", nv)
    values, kin, layout, J, jac, M, f = _model(topology, space, p)
    if tangent:
        J = ca.vertcat(J, _direction_jacobian(topology, kin, layout, space, GROUND_TANGENT))
    sqrt_d = ca.vertcat(*[ca.sqrt(d) for d in f.D])
    E = dyn.solve_lt(f, J.T) / ca.repmat(sqrt_d, 1, J.shape[0])
    A = E.T @ E
    return ca.Function(
        "metric",
        [p, v_minus],
        [J, 0.5 * (A + A.T), E, sqrt_d * _mul_l(f, v_minus)],
        ["p", "v_minus"],
        ["contact_jacobian", "delassus", "metric_factor", "u_minus"],
    )


def geometry_function(topology: Topology, space: Space = PLANAR) -> ca.Function:
    """World positions at touchdown: ``origins``, ``tips``, ``coms`` (3 x bodies) and
    ``contacts`` (3 x declared contacts)."""
    p = ca.SX.sym("p", topology.n_values)
    kin = forward_kinematics(topology, unpack_values(topology, p), space)
    cat = lambda xs: ca.horzcat(*xs) if xs else ca.SX(3, 0)  # noqa: E731
    return ca.Function(
        "geometry",
        [p],
        [cat(kin.W_p_O), cat(kin.W_p_T), cat(kin.W_p_G), cat(kin.W_p_C)],
        ["p"],
        ["origins", "tips", "coms", "contacts"],
    )


def mass_matrix_function(topology: Topology, space: Space = PLANAR) -> ca.Function:
    """``M(p)``, for checks against independent implementations."""
    p = ca.SX.sym("p", topology.n_values)
    values, kin, layout, J = _contact_jacobian(topology, p, space)
    jac = dyn.body_jacobians(kin, layout, values, space)
    return ca.Function("mass_matrix", [p], [dyn.mass_matrix(jac, values), J], ["p"], ["M", "contact_jacobian"])
