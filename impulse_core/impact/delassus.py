"""The impulse model as CasADi graphs: external impulses (paper eq. 11), post-impact velocities
and internal (joint reaction) impulses (paper eqs. 15-27, as an impulsive Newton-Euler pass).

Everything here is a pure function of a :class:`~impulse_core.model.tree.Topology` that returns
CasADi SX expressions of the design vector ``p``; :func:`impact_function` wraps them in one
named ``casadi.Function`` per topology. :func:`lean_impact_function` is the optimiser's and the
benchmark's hot path (a subset of the outputs by tree-structured algorithms, equal to rounding);
:func:`norms_gradient_function` adds the gradients of both norms, by the adjoint of the impact
equations (the factorizations are reused, not differentiated).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from enum import Enum

import casadi as ca

from impulse_core.kinematics import dynamics as dyn
from impulse_core.kinematics.displacement import PlacedSymbols, placed_gradient, placed_symbols
from impulse_core.kinematics.spatial import (
    GROUND_NORMAL,
    PLANAR,
    BodyValues,
    DofLayout,
    Kinematics,
    Space,
    contact_bodies,
    dof_layout,
    forward_kinematics,
    mass_columns,
    n_values,
    point_jacobian,
    unpack_values,
)
from impulse_core.model.tree import Topology

#: Ground tangent (world frame): the direction of the tangential (friction) impulse in the plane.
GROUND_TANGENT = ca.DM([1.0, 0.0, 0.0])
#: The second ground tangent of a spatial model (lateral, z).
LATERAL_TANGENT = ca.DM([0.0, 0.0, 1.0])


def ground_tangents(space: Space) -> tuple[ca.DM, ...]:
    """The tangent directions of the friction impulse: x in the plane; x, then z, in space."""
    return (GROUND_TANGENT,) if space.joint_axis is not None else (GROUND_TANGENT, LATERAL_TANGENT)


def _contact_jacobian(topology: Topology, p: ca.SX, space: Space):
    values = unpack_values(topology, p, space)
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
    lam, pivots, _ = _newton_law(A, -(1 + restitution) * (J @ v_minus))
    return lam, pivots


def _newton_law(A: ca.SX, rhs: ca.SX) -> tuple[ca.SX, ca.SX, dyn.LTDL]:
    """lambda = A^-1 rhs by a dense L^T D L factor of A (paper eq. 11); the relative pivots; the factor."""
    f = dyn.ltdl(A, dyn.dense_parent(A.shape[0]))
    return dyn.solve(f, rhs), dyn.relative_pivots(f, A), f


def internal_impulse(
    topology: Topology,
    kin,
    jac: dyn.BodyJacobians,
    values,
    delta_v: ca.SX,
    external: ca.SX,
    tangential: ca.SX | None = None,
    tangents: tuple[ca.DM, ...] = (GROUND_TANGENT,),
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
        if tangential is not None:  # all contacts' x components, then (in space) their z components
            for k, direction in enumerate(tangents):
                f_ext = f_ext + tangential[k * len(topology.active) + i] * direction
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


def _response_outputs(
    topology, kin, jac, values, J, M, M_inv_JT, v_minus, external, tangential=None, tangents=(GROUND_TANGENT,)
):
    """Outputs named ``RESPONSE_OUTPUTS``. ``M_inv_JT`` has one column per normal impulse, then,
    with ``tangential``, one per tangential impulse."""
    delta_v = M_inv_JT @ (external if tangential is None else ca.vertcat(external, tangential))
    v_plus = v_minus + delta_v
    F, T = internal_impulse(topology, kin, jac, values, delta_v, external, tangential, tangents)
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
    p = ca.SX.sym("p", n_values(topology, space))
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
    p = ca.SX.sym("p", n_values(topology, space))
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
    """Given normal and tangential impulses at the active contacts (x components; in space, x
    components then z components), everything that follows from them: the outputs of
    :func:`response_function` (``contact_velocity`` normal; ``internal`` includes the tangential
    impulses' share) plus ``tangent_velocity`` (the active contacts' tangential velocities after
    the impact, same layout, m/s). Built only for scenes with friction."""
    nv = dof_layout(topology, space).nv
    n = len(topology.active)
    p = ca.SX.sym("p", n_values(topology, space))
    v_minus = ca.SX.sym("v_minus", nv)
    lam = ca.SX.sym("external", n)
    tangents = ground_tangents(space)
    lam_t = ca.SX.sym("tangential", n * len(tangents))
    values, kin, layout, J, jac, M, f = _model(topology, space, p)
    Jt = ca.vertcat(*[_direction_jacobian(topology, kin, layout, space, t) for t in tangents])
    _, M_inv_JT = delassus_matrix(ca.vertcat(J, Jt), f)
    outs = _response_outputs(topology, kin, jac, values, J, M, M_inv_JT, v_minus, lam, lam_t, tangents)
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


@dataclass(frozen=True)
class _LeanGraph:
    """A lean graph's outputs and what the adjoint gradient (:func:`_adjoint_gradients`) reuses.

    Attributes:
        outputs: ``LEAN_OUTPUTS``.
        kin, layout, motions, inertias: the tree at touchdown (world frame).
        values: the bodies' design values (:func:`unpack_values`).
        delta_v: generalized velocity change (nv x 1).
        delassus: the L^T D L factor of the Delassus matrix A (paper eq. 11).
        solve_mass: tau -> M^-1 tau.
        contact_response: nu -> M^-1 J^T nu, the velocity change under normal impulses nu.
    """

    outputs: tuple[ca.SX, ...]
    kin: Kinematics
    layout: DofLayout
    motions: tuple[dyn.JointMotion, ...]
    inertias: tuple[dyn.SpatialInertia, ...]
    values: tuple[BodyValues, ...]
    delta_v: ca.SX
    delassus: dyn.LTDL
    solve_mass: Callable[[ca.SX], ca.SX]
    contact_response: Callable[[ca.SX], ca.SX]


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


def _normal_velocities(topology: Topology, kin: Kinematics, omega: tuple[ca.SX, ...], vel: tuple[ca.SX, ...]) -> ca.SX:
    """n^T (v_b + omega_b x (p_C - O_b)) at every active contact C (on body b): J x, given the
    body velocities (``dynamics.body_velocities``) of x."""
    bodies = contact_bodies(topology)
    rows = [
        GROUND_NORMAL.T @ (vel[bodies[c]] + ca.cross(omega[bodies[c]], kin.W_p_C[c] - kin.W_p_O[bodies[c]]))
        for c in topology.active
    ]
    return ca.vertcat(*rows) if rows else ca.SX(0, 1)


def _lean_graph_articulated(topology: Topology, space: Space, p: ca.SX, v_minus: ca.SX, e: ca.SX) -> _LeanGraph:
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
    values = unpack_values(topology, p, space)
    kin = forward_kinematics(topology, values, space)
    layout = dof_layout(topology, space)
    motions = dyn.joint_motions(kin, layout, space)
    inertias = dyn.lean_body_inertias(kin, values)
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

    def contact_forces(weights: ca.SX) -> dict[int, ca.SX]:
        forces: dict[int, ca.SX] = {}
        for i, c in enumerate(active):
            forces[bodies[c]] = forces.get(bodies[c], ca.SX.zeros(6, 1)) + weights[i] * unit_impulse(c)
        return forces

    def rates(r: dict[int, ca.SX]) -> ca.SX:
        return ca.vertcat(*[r[k] for k in range(layout.nv)])

    A = ca.SX(nc, nc)
    for j, c in enumerate(active):
        response, _ = dyn.impulse_response(art, {bodies[c]: unit_impulse(c)})
        for i in range(j + 1):
            A[i, j] = normal_velocity(active[i], response)
            A[j, i] = A[i, j]
    Jv = _normal_velocities(topology, kin, *dyn.body_velocities(topology.parents, kin, layout, motions, v_minus))
    lam, pivots, fA = _newton_law(A, -(1 + e) * Jv)
    dV, dv = dyn.impulse_response(art, contact_forces(lam))
    force = [inertias[b].momentum(dV[b][:3], dV[b][3:])[1] for b in range(topology.n_bodies)]
    return _LeanGraph(
        _lean_outputs(topology, bodies, n, force, lam, pivots),
        kin,
        layout,
        motions,
        inertias,
        values,
        rates(dv),
        fA,
        lambda tau: rates(dyn.impulse_response(art, {}, tau)[1]),
        lambda nu: rates(dyn.impulse_response(art, contact_forces(nu))[1]),
    )


def _lean_graph_composite(topology: Topology, space: Space, p: ca.SX, v_minus: ca.SX, e: ca.SX) -> _LeanGraph:
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
    values = unpack_values(topology, p, space)
    kin = forward_kinematics(topology, values, space)
    layout = dof_layout(topology, space)
    S = dyn.joint_motions(kin, layout, space)
    inertias = dyn.lean_body_inertias(kin, values)
    M = dyn.composite_mass_matrix(topology.parents, kin, layout, values, space, inertias)
    f = dyn.ltdl(M, layout.dof_parent, reciprocals=True)
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
    lam, pivots, fA = _newton_law(A, -(1 + e) * (J @ v_minus))
    dv = dyn.solve_l(f, DY @ lam)
    omega, vel = dyn.body_velocities(topology.parents, kin, layout, S, dv)
    force = [inertias[b].momentum(omega[b], vel[b])[1] for b in range(topology.n_bodies)]
    return _LeanGraph(
        _lean_outputs(topology, bodies, n, force, lam, pivots),
        kin,
        layout,
        S,
        inertias,
        values,
        dv,
        fA,
        lambda tau: dyn.solve(f, tau),
        lambda nu: dyn.solve_l(f, DY @ nu),
    )


class LeanAlgorithm(Enum):
    """How :func:`lean_impact_function` reaches the Delassus matrix and Delta v.

    COMPOSITE: mass matrix (RBDA alg. 6.2) and its sparse factor, O(n d^2) for depth d, few
    divisions. ARTICULATED: articulated-body inertias (RBDA alg. 7.3), O(n) per contact, one
    division per joint per pass. AUTO: COMPOSITE for trees no more than ``AUTO_DEPTH`` joints deep below the base.
    """

    AUTO = "auto"
    COMPOSITE = "composite"
    ARTICULATED = "articulated"


#: AUTO picks COMPOSITE up to this depth of joints below the base, ARTICULATED beyond (tuned on
#: the planar scaling series; in space the composite algorithm stays faster at the same joint
#: depth: case 3 with splayed toes 0.36 against 0.46 us per design, one core; 0.26 against 0.33, 4728 against 5457
#: SX instructions, after 2026-11-27's lean15).
AUTO_DEPTH = 5

_LEAN_GRAPHS = {LeanAlgorithm.COMPOSITE: _lean_graph_composite, LeanAlgorithm.ARTICULATED: _lean_graph_articulated}


def dof_depth(topology: Topology, space: Space = PLANAR) -> int:
    """The largest number of DOFs on one path from the root (base DOFs included)."""
    return max(len(s) for s in dof_layout(topology, space).body_support)


def _lean_graph(
    topology: Topology, space: Space, p: ca.SX, v_minus: ca.SX, e: ca.SX, algorithm: LeanAlgorithm = LeanAlgorithm.AUTO
) -> _LeanGraph:
    if algorithm is LeanAlgorithm.AUTO:
        deep = dof_depth(topology, space) - len(space.base_dofs) > AUTO_DEPTH
        algorithm = LeanAlgorithm.ARTICULATED if deep else LeanAlgorithm.COMPOSITE
    return _LEAN_GRAPHS[algorithm](topology, space, p, v_minus, e)


def lean_impact_function(
    topology: Topology, space: Space = PLANAR, algorithm: LeanAlgorithm = LeanAlgorithm.AUTO, rods: bool = False
) -> ca.Function:
    """The hot path of the optimiser and the benchmark: same inputs as :func:`impact_function`
    and the subset ``LEAN_OUTPUTS`` of its outputs (same names, same values to rounding), by the
    tree-structured algorithms of ``algorithm`` (:class:`LeanAlgorithm`), with common
    subexpression elimination. ``rods``: the variant for designs whose mass-property values are
    all zero (:func:`_rods_folded`; ``impact_lean_rods``)."""
    nv = dof_layout(topology, space).nv
    p = ca.SX.sym("p", n_values(topology, space))
    v_minus = ca.SX.sym("v_minus", nv)
    e = ca.SX.sym("restitution")
    outs = _rods_folded(topology, space, p, _lean_graph(topology, space, p, v_minus, e, algorithm).outputs, rods)
    return ca.Function(
        "impact_lean_rods" if rods else "impact_lean", [p, v_minus, e], outs, list(IMPACT_INPUTS),
        list(LEAN_OUTPUTS), LEAN_OPTIONS,
    )


def _rods_folded(topology: Topology, space: Space, p: ca.SX, outs, rods: bool) -> list[ca.SX]:
    """``outs`` with every body's mass-property values (:func:`impulse_core.kinematics.spatial.mass_columns`)
    replaced by the constant 0 when ``rods``: CasADi then drops the terms they multiply. Applied
    after differentiating, a gradient keeps its entries w.r.t. those values (exact at 0); the
    function is then only right for designs that have them all zero (its callers check)."""
    columns = mass_columns(topology, space) if rods else ()
    if not columns:
        return list(outs)
    return ca.substitute(list(outs), [p[k] for k in columns], [ca.SX(0.0)] * len(columns))


#: Outputs of :func:`scenario_impact_function`.
SCENARIO_IMPACT_OUTPUTS = LEAN_OUTPUTS + ("v_plus", "energy_after")


def scenario_impact_function(topology: Topology, space: Space = PLANAR) -> ca.Function:
    """``LEAN_OUTPUTS`` and the motion after the impact (``v_plus``; ``energy_after`` =
    sum over bodies of (omega . L + v . p) / 2 at v_plus): what the first-impact objectives of
    one landing need, on the lean graph (many landings of one design, batched)."""
    nv = dof_layout(topology, space).nv
    p = ca.SX.sym("p", n_values(topology, space))
    v_minus = ca.SX.sym("v_minus", nv)
    e = ca.SX.sym("restitution")
    g = _lean_graph(topology, space, p, v_minus, e)
    v_plus = v_minus + g.delta_v
    omega, vel = dyn.body_velocities(topology.parents, g.kin, g.layout, g.motions, v_plus)
    twice = ca.SX(0)
    for b in range(topology.n_bodies):
        L, P = g.inertias[b].momentum(omega[b], vel[b])
        twice = twice + omega[b].T @ L + vel[b].T @ P
    outs = [*g.outputs, v_plus, 0.5 * twice]
    return ca.Function("impact_scenario", [p, v_minus, e], outs, list(IMPACT_INPUTS), list(SCENARIO_IMPACT_OUTPUTS),
                       LEAN_OPTIONS)


def _adjoint_gradients(
    topology: Topology, space: Space, p: ca.SX, v_minus: ca.SX, e: ca.SX, g: _LeanGraph
) -> tuple[ca.SX, ca.SX]:
    """Gradients of ``external_norm`` and ``internal_norm`` w.r.t. ``p`` (n_values x 1 each) by
    the adjoint of the impact equations, not by differentiating through the factorizations.

    The forward model is M(p) dv = J(p)^T lambda and A lambda = -(1 + e) J(p) v_minus with
    A = J M^-1 J^T (paper eq. 11); a norm is g(p, lambda, dv) (the internal norm through the
    impulsive Newton-Euler pass, eqs. 15-27; the external norm |lambda|). With the seeds
    lambda_bar = dg/dlambda and dv_bar = dg/d(dv), the adjoint solves

        z = M^-1 dv_bar,   nu = A^-1 (lambda_bar + J z),   a = z - M^-1 J^T nu

    reuse the forward pass's factors of M and A, and then

        dg/dp = d/dp [ g + a^T (J^T lambda - M dv) - nu^T J (dv + (1 + e) v_minus) ]

    with lambda, dv, a and nu held fixed: derivatives of kinematics only (J x and a^T M dv, one
    forward velocity pass each; a^T M dv by :func:`dyn.kinetic_bilinear`, at the centres of mass
    without world-frame inertias, and the internal norm's momenta as m v_G): one reverse sweep
    per norm over a graph without the factorizations. In space the sweep stops at the placed
    tree (:func:`placed_symbols`), which rigid displacements of subtrees take to the design
    (:func:`placement_gradient`), not reverse mode through the 3 x 3 rotation products: spatial
    case 3's all-values gradient 18380 -> 15562 instructions; 15442 with the roll turned about
    the frame's x column. The plane's rotations are the cos and sin of absolute angles, cheaper
    through reverse mode (case 3: 3346 against 3704). A twist-level form of the sweep (the
    spatial momenta's and contact wrenches' displacement derivatives, after Carpentier and
    Mansard) was tried and costs more: 17573; so did only its a^T M dv term at the twist level
    (16010 against 15431) and a^T M dv as a^T (M dv) (16632 against 15562). Tried and dropped
    (2026-11-27, branch grad15): the graphs rebuilt with every sum's and product's operands in
    one order before CSE (15442 -> 14672, outputs bit for bit): no time gained (paired, 0.95-1.02
    on the SIMD and C loops), 0.25-0.3 s more to build each gradient.
    (Both brackets vanish at the solution: the first is the impulse balance, the second
    J v_plus + e J v_minus, the restitution law.)
    """
    nc, nv = len(topology.active), g.layout.nv
    if nc == 0:  # no impact: both norms are zero whatever the design
        return ca.SX.zeros(p.shape[0], 1), ca.SX.zeros(p.shape[0], 1)
    lam, pivots, dv = g.outputs[0], g.outputs[1], g.delta_v
    held = [ca.SX.sym(name, k) for name, k in (("lam", nc), ("dv", nv), ("a", nv), ("nu", nc), ("u", nv))]
    lam_h, dv_h, a_h, nu_h, u_h = held
    # in space the sweep stops at the placed tree; the plane's cos and sin are cheaper through reverse mode
    placed = placed_symbols(g.kin, p) if space.joint_axis is None else PlacedSymbols(g.kin, ca.SX(0, 1), ca.SX(0, 1))
    kin = placed.kin
    motions = dyn.joint_motions(kin, g.layout, space)

    def velocities(x: ca.SX, tree: Kinematics = kin, S: tuple = motions) -> tuple[tuple[ca.SX, ...], tuple[ca.SX, ...]]:
        return dyn.body_velocities(topology.parents, tree, g.layout, S, x)

    twists_dv, twists_a = velocities(dv_h), velocities(a_h)
    momenta = [v.mass * w for v, w in zip(g.values, dyn.com_velocities(kin, *twists_dv))]
    internal_norm = _lean_outputs(topology, contact_bodies(topology), GROUND_NORMAL, momenta, lam_h, pivots)[4]
    a_M_dv = dyn.kinetic_bilinear(kin, g.values, twists_a, twists_dv)
    psi = lam_h.T @ _normal_velocities(topology, kin, *twists_a) - a_M_dv
    psi = psi - nu_h.T @ _normal_velocities(topology, kin, *velocities(u_h))
    seeds = ca.substitute(ca.gradient(internal_norm, ca.vertcat(lam_h, dv_h)),
                          ca.vertcat(lam_h, dv_h, placed.symbols), ca.vertcat(lam, dv, placed.placed))

    def gradient(objective: ca.SX, lam_bar: ca.SX, dv_bar: ca.SX | None) -> ca.SX:
        nu_rhs, z = lam_bar, ca.SX.zeros(nv, 1)
        if dv_bar is not None:
            z = g.solve_mass(dv_bar)
            nu_rhs = nu_rhs + _normal_velocities(topology, g.kin, *velocities(z, g.kin, g.motions))
        nu = dyn.solve(g.delassus, nu_rhs)
        a = z - g.contact_response(nu)
        d = placed_gradient(topology, g.values, g.kin, placed, objective, p)
        return ca.substitute(
            d, ca.vertcat(*held, placed.symbols), ca.vertcat(lam, dv, a, nu, dv + (1 + e) * v_minus, placed.placed)
        )

    d_external = gradient(psi, lam / ca.norm_2(lam), None)
    d_internal = gradient(psi + internal_norm, seeds[:nc], seeds[nc:])
    return d_external, d_internal


def norms_gradient_function(
    topology: Topology,
    space: Space = PLANAR,
    algorithm: LeanAlgorithm = LeanAlgorithm.AUTO,
    adjoint: bool = True,
    rods: bool = False,
    columns: Sequence[int] | None = None,
) -> ca.Function:
    """``external_norm`` and ``internal_norm`` with their gradients w.r.t. every design value
    (``d_external_norm``, ``d_internal_norm``: 1 x n_values each), sharing the forward pass of
    :func:`lean_impact_function`.

    With ``adjoint`` (default) by the adjoint of the impact equations (:func:`_adjoint_gradients`:
    the factorizations are not differentiated); otherwise by CasADi's reverse-mode algorithmic
    differentiation of the whole graph (the independent check of the first). ``rods``: the
    variant for designs whose mass-property values are all zero (``norms_gradient_rods``,
    :func:`_rods_folded` after differentiating: every entry of the gradients kept). ``columns``:
    the gradients w.r.t. these entries of the design vector only (1 x len(columns) each, in
    that order; the full gradients' entries, ``norms_gradient_columns``): the reverse sweeps
    drop the partial derivatives into the other values (e.g. the values a search varies,
    :func:`optimizer.design_space.search_columns`: 30 of 193 for spatial case 3).
    """
    nv = dof_layout(topology, space).nv
    p = ca.SX.sym("p", n_values(topology, space))
    v_minus = ca.SX.sym("v_minus", nv)
    e = ca.SX.sym("restitution")
    g = _lean_graph(topology, space, p, v_minus, e, algorithm)
    norms = g.outputs[3:5]
    if adjoint:
        d_external, d_internal = _adjoint_gradients(topology, space, p, v_minus, e, g)
    else:
        d_external, d_internal = (ca.gradient(x, p) for x in norms)
    if columns is not None:
        d_external, d_internal = d_external[list(columns)], d_internal[list(columns)]
    return ca.Function(
        "norms_gradient" + ("" if columns is None else "_columns") + ("_rods" if rods else ""),
        [p, v_minus, e],
        _rods_folded(topology, space, p, [*norms, d_external.T, d_internal.T], rods),
        list(IMPACT_INPUTS),
        list(GRADIENT_OUTPUTS),
        LEAN_OPTIONS,
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
    p = ca.SX.sym("p", n_values(topology, space))
    v_minus = ca.SX.sym("v_minus", nv)
    values, kin, layout, J, jac, M, f = _model(topology, space, p)
    if tangent:
        J = ca.vertcat(J, *[_direction_jacobian(topology, kin, layout, space, t) for t in ground_tangents(space)])
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
    p = ca.SX.sym("p", n_values(topology, space))
    kin = forward_kinematics(topology, unpack_values(topology, p, space), space)
    cat = lambda xs: ca.horzcat(*xs) if xs else ca.SX(3, 0)
    return ca.Function(
        "geometry",
        [p],
        [cat(kin.W_p_O), cat(kin.W_p_T), cat(kin.W_p_G), cat(kin.W_p_C)],
        ["p"],
        ["origins", "tips", "coms", "contacts"],
    )


def mass_matrix_function(topology: Topology, space: Space = PLANAR) -> ca.Function:
    """``M(p)``, for checks against independent implementations."""
    p = ca.SX.sym("p", n_values(topology, space))
    values, kin, layout, J = _contact_jacobian(topology, p, space)
    jac = dyn.body_jacobians(kin, layout, values, space)
    return ca.Function("mass_matrix", [p], [dyn.mass_matrix(jac, values), J], ["p"], ["M", "contact_jacobian"])
