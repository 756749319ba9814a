"""The impulse model as CasADi graphs: external impulses (paper eq. 11), post-impact velocities
and internal (joint reaction) impulses (paper eqs. 15-27, as an impulsive Newton-Euler pass).

Everything here is a pure function of a :class:`~impulse_core.tree.Topology` that returns
CasADi SX expressions of the design vector ``p``; :func:`impact_function` wraps them in one
named ``casadi.Function`` per topology. :func:`lean_impact_function` is the optimiser's and the
benchmark's hot path (a subset of the outputs by tree-structured algorithms, equal to rounding);
:func:`norms_gradient_function` adds the gradients of both norms.
"""

from __future__ import annotations

from enum import Enum

import casadi as ca

from impulse_core import dynamics as dyn
from impulse_core.kinematics import (
    GROUND_NORMAL,
    PLANAR,
    Space,
    contact_bodies,
    dof_layout,
    forward_kinematics,
    point_jacobian,
    unpack_values,
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
    M = dyn.composite_mass_matrix(topology.parents, kin, layout, values, space)
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


#: Outputs of :func:`lean_impact_function`: what the optimiser and the benchmark need per design.
LEAN_OUTPUTS = ("external", "delassus_pivots", "internal_magnitude", "external_norm", "internal_norm")
#: Outputs of :func:`norms_gradient_function`.
GRADIENT_OUTPUTS = LEAN_OUTPUTS[3:] + ("d_external_norm", "d_internal_norm")
#: CasADi options of the hot-path functions: common subexpression elimination.
LEAN_OPTIONS = {"cse": True}


def _lean_outputs(
    topology: Topology, bodies: tuple[int, ...], n: ca.DM, force: list[ca.SX], lam: ca.SX, pivots: ca.SX
) -> tuple[ca.SX, ...]:
    """``LEAN_OUTPUTS`` from each body's momentum change ``force`` (consumed): subtract the contact
    impulses, sum over subtrees (the joint impulse behind each body), take magnitudes and norms."""
    for i, c in enumerate(topology.active):
        force[bodies[c]] = force[bodies[c]] - lam[i] * n
    for b in reversed(range(1, topology.n_bodies)):
        force[topology.parents[b]] = force[topology.parents[b]] + force[b]
    magnitude = ca.vertcat(*[ca.sqrt(force[b].T @ force[b]) for b in range(1, topology.n_bodies)])
    return (
        lam,
        pivots,
        magnitude,
        ca.norm_2(lam) if lam.shape[0] else ca.SX(0),
        ca.norm_2(magnitude) if magnitude.shape[0] else ca.SX(0),
    )


def _lean_graph_articulated(topology: Topology, space: Space, p: ca.SX, v_minus: ca.SX, e: ca.SX) -> tuple[ca.SX, ...]:
    """The outputs ``LEAN_OUTPUTS`` in O(n) per contact, by the articulated-body algorithm.

    1. Forward kinematics, trig once per absolute angle (:func:`forward_kinematics`).
    2. Articulated-body inertias, one backward pass (RBDA alg. 7.3; no mass matrix is formed).
    3. Delassus matrix (paper eq. 11) column by column: the velocity change at every contact
       under a unit normal impulse at contact j (:func:`dynamics.impulse_response`; the graph
       keeps only the passes along the paths to the contacts); upper triangle, mirrored.
    4. Newton's law A lambda = -(1 + e) J v_minus by a dense L^T D L of A; J v_minus from one
       forward velocity pass.
    5. Delta v of every body under lambda (one more response), momentum changes, and joint force
       impulses by one backward pass (subtree momentum change minus the external impulses on
       the subtree: the impulsive Newton-Euler pass of paper eqs. 15-27).
    """
    values = unpack_values(topology, p)
    kin = forward_kinematics(topology, values, space)
    layout = dof_layout(topology, space)
    inertias = dyn.body_inertias(kin, values)
    art = dyn.articulated_bodies(topology.parents, kin, layout, inertias, space)
    bodies = contact_bodies(topology)
    n = GROUND_NORMAL
    active = topology.active
    nc = len(active)

    def unit_impulse(c: int) -> ca.SX:  # a unit normal impulse at contact c, about O_b
        return ca.vertcat(ca.cross(kin.W_p_C[c] - kin.W_p_O[bodies[c]], n), n)

    def normal_velocity(c: int, V: tuple[ca.SX, ...]) -> ca.SX:
        V_b = V[bodies[c]]
        return n.T @ (V_b[3:] + ca.cross(V_b[:3], kin.W_p_C[c] - kin.W_p_O[bodies[c]]))

    A = ca.SX(nc, nc)
    for j, c in enumerate(active):
        response, _ = dyn.impulse_response(art, {bodies[c]: unit_impulse(c)})
        for i in range(j + 1):
            A[i, j] = normal_velocity(active[i], response)
            A[j, i] = A[i, j]
    V_minus = dyn.body_velocities(art, v_minus)
    Jv = ca.vertcat(*[normal_velocity(c, V_minus) for c in active]) if nc else ca.SX(0, 1)
    f = dyn.ltdl(A, dyn.dense_parent(nc))
    lam = dyn.solve(f, -(1 + e) * Jv)
    pivots = dyn.relative_pivots(f, A)
    forces: dict[int, ca.SX] = {}
    for i, c in enumerate(active):
        forces[bodies[c]] = forces.get(bodies[c], ca.SX.zeros(6, 1)) + lam[i] * unit_impulse(c)
    dV, _ = dyn.impulse_response(art, forces)
    force = [inertias[b].momentum(dV[b][:3], dV[b][3:])[1] for b in range(topology.n_bodies)]
    return _lean_outputs(topology, bodies, n, force, lam, pivots)


def _lean_graph_composite(topology: Topology, space: Space, p: ca.SX, v_minus: ca.SX, e: ca.SX) -> tuple[ca.SX, ...]:
    """The outputs ``LEAN_OUTPUTS`` through the mass matrix and its sparse factor.

    1. Forward kinematics, trig once per absolute angle (:func:`forward_kinematics`).
    2. Mass matrix by the composite-rigid-body algorithm (RBDA alg. 6.2) and its L^T D L factor
       with the tree's sparsity (RBDA alg. 6.3).
    3. Contact Jacobian rows n^T (v_k + omega_k x (p_C - o_k)) from the joint motions; Delassus
       matrix A = Y^T D^-1 Y with Y = L^-T J^T (sparse back substitution, upper triangle only),
       and Newton's law A lambda = -(1 + e) J v_minus (paper eq. 11) by a dense L^T D L of A.
    4. Delta v = L^-1 D^-1 Y lambda; body velocities by one forward pass, momentum changes, and
       joint force impulses by one backward pass (subtree momentum change minus the external
       impulses on the subtree: the impulsive Newton-Euler pass of paper eqs. 15-27).

    Cost O(n d^2) for depth d: the cheaper choice for shallow trees (few divisions).
    """
    values = unpack_values(topology, p)
    kin = forward_kinematics(topology, values, space)
    layout = dof_layout(topology, space)
    S = dyn.joint_motions(kin, layout, space)
    inertias = dyn.body_inertias(kin, values)
    M = dyn.composite_mass_matrix(topology.parents, kin, layout, values, space)
    f = dyn.ltdl(M, layout.dof_parent)
    bodies = contact_bodies(topology)
    n = GROUND_NORMAL
    nc = len(topology.active)
    J = ca.SX(nc, layout.nv)
    for r, c in enumerate(topology.active):
        for k in layout.body_support[bodies[c]]:
            J[r, k] = n.T @ S[k].velocity_at(kin.W_p_C[c])
    Y = dyn.solve_lt(f, J.T)
    DY = dyn.solve_d(f, Y)
    A = ca.SX(nc, nc)
    for i in range(nc):
        for j in range(i, nc):
            A[i, j] = Y[:, i].T @ DY[:, j]
            A[j, i] = A[i, j]
    lam, pivots = external_impulse(A, J, v_minus, e)
    dv = dyn.solve_l(f, DY @ lam)
    omega: list[ca.SX] = []
    vel: list[ca.SX] = []  # velocity of each body's joint origin
    n_base = len(space.base_dofs)
    for b in range(topology.n_bodies):
        parent = topology.parents[b]
        O_b = kin.W_p_O[b]
        if parent < 0:
            w, v = ca.SX.zeros(3, 1), ca.SX.zeros(3, 1)
            for k in range(n_base):
                w = w + S[k].omega * dv[k]
                v = v + S[k].velocity_at(O_b) * dv[k]
        else:
            w, v = omega[parent], vel[parent] + ca.cross(omega[parent], O_b - kin.W_p_O[parent])
            k = layout.body_dof[b]
            if k is not None:  # the joint turns about O_b: no velocity of O_b
                w = w + S[k].omega * dv[k]
        omega.append(w)
        vel.append(v)
    force = [inertias[b].momentum(omega[b], vel[b])[1] for b in range(topology.n_bodies)]
    return _lean_outputs(topology, bodies, n, force, lam, pivots)


class LeanAlgorithm(Enum):
    """How :func:`lean_impact_function` reaches the Delassus matrix and Delta v.

    COMPOSITE: mass matrix (RBDA alg. 6.2) and its sparse factor, O(n d^2) for depth d, few
    divisions. ARTICULATED: articulated-body inertias (RBDA alg. 7.3), O(n) per contact, one
    division per joint per pass. AUTO: COMPOSITE for trees no deeper than ``AUTO_DEPTH`` DOFs.
    """

    AUTO = "auto"
    COMPOSITE = "composite"
    ARTICULATED = "articulated"


#: AUTO picks COMPOSITE up to this DOF depth (base DOFs included), ARTICULATED beyond.
AUTO_DEPTH = 8

_LEAN_GRAPHS = {LeanAlgorithm.COMPOSITE: _lean_graph_composite, LeanAlgorithm.ARTICULATED: _lean_graph_articulated}


def dof_depth(topology: Topology, space: Space = PLANAR) -> int:
    """The largest number of DOFs on one path from the root (base DOFs included)."""
    return max(len(s) for s in dof_layout(topology, space).body_support)


def _lean_graph(
    topology: Topology, space: Space, p: ca.SX, v_minus: ca.SX, e: ca.SX, algorithm: LeanAlgorithm = LeanAlgorithm.AUTO
) -> tuple[ca.SX, ...]:
    if algorithm is LeanAlgorithm.AUTO:
        deep = dof_depth(topology, space) > AUTO_DEPTH
        algorithm = LeanAlgorithm.ARTICULATED if deep else LeanAlgorithm.COMPOSITE
    return _LEAN_GRAPHS[algorithm](topology, space, p, v_minus, e)


def lean_impact_function(
    topology: Topology, space: Space = PLANAR, algorithm: LeanAlgorithm = LeanAlgorithm.AUTO
) -> ca.Function:
    """The hot path of the optimiser and the benchmark: same inputs as :func:`impact_function`
    and the subset ``LEAN_OUTPUTS`` of its outputs (same names, same values to rounding), by the
    tree-structured algorithms of ``algorithm`` (:class:`LeanAlgorithm`), with common
    subexpression elimination."""
    nv = dof_layout(topology, space).nv
    p = ca.SX.sym("p", topology.n_values)
    v_minus = ca.SX.sym("v_minus", nv)
    e = ca.SX.sym("restitution")
    outs = _lean_graph(topology, space, p, v_minus, e, algorithm)
    return ca.Function("impact_lean", [p, v_minus, e], list(outs), list(IMPACT_INPUTS), list(LEAN_OUTPUTS), LEAN_OPTIONS)


def norms_gradient_function(
    topology: Topology, space: Space = PLANAR, algorithm: LeanAlgorithm = LeanAlgorithm.AUTO
) -> ca.Function:
    """``external_norm`` and ``internal_norm`` with their gradients w.r.t. every design value
    (``d_external_norm``, ``d_internal_norm``: 1 x n_values each), by reverse-mode algorithmic
    differentiation of :func:`_lean_graph` sharing its forward pass."""
    nv = dof_layout(topology, space).nv
    p = ca.SX.sym("p", topology.n_values)
    v_minus = ca.SX.sym("v_minus", nv)
    e = ca.SX.sym("restitution")
    outs = _lean_graph(topology, space, p, v_minus, e, algorithm)
    norms = ca.vertcat(outs[3], outs[4])
    G = ca.jacobian(norms, p)
    return ca.Function(
        "norms_gradient", [p, v_minus, e], [outs[3], outs[4], G[0, :], G[1, :]], list(IMPACT_INPUTS), list(GRADIENT_OUTPUTS), LEAN_OPTIONS
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
