"""Design derivatives of the placed tree by rigid displacements of subtrees.

A value that places body b (its joint ``angle``, its ``rpy`` and ``axis``, its ``at`` on the
parent) moves b's whole subtree rigidly; a rod's ``length`` moves its children's subtrees and
its own points along its axis. So an objective that depends on the design through the placed
tree (:class:`~impulse_core.kinematics.spatial.Kinematics`) has, w.r.t. such a value, the
derivative twist . wrench: the twist of that move against the wrench the objective's adjoints
exert on the subtree (each point's adjoint as a force at the point, each direction's and
rotation column's as a torque). The wrenches are summed over subtrees in one backward pass,
the duality of motion and force behind Carpentier and Mansard's analytical derivatives of the
recursive Newton-Euler algorithm (RSS 2018). O(n) 3-vector products per objective, where
reverse mode through the forward kinematics differentiates every 3 x 3 rotation product
(:func:`placed_symbols`, :func:`placed_gradient`, :func:`placement_gradient`).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from impulse_core.kinematics.spatial import BodyValues, Kinematics, axis_rotation, rpy_rotation
from impulse_core.model.tree import Topology

_FIELDS = ("W_R_B", "W_p_O", "W_p_G", "W_p_T", "W_p_C", "joint_axis")


@dataclass(frozen=True)
class PlacedSymbols:
    """Free symbols standing for the entries of the placed tree that depend on the design.

    Attributes:
        kin: the placed tree with those symbols (its constant entries kept: the plane's zeros
            and ones).
        symbols: the symbols, stacked.
        placed: the placed tree's expressions they stand for, in the same order.
    """

    kin: Kinematics
    symbols: ca.SX
    placed: ca.SX

    def adjoint(self, objective: ca.SX) -> Kinematics:
        """The gradient of ``objective`` w.r.t. each quantity of ``kin``, shaped as ``kin``
        (zero at its constant entries, None where the quantity is None)."""
        bar = ca.gradient(objective, self.symbols)
        index = {self.symbols[k].name(): k for k in range(self.symbols.shape[0])}

        def shaped(x: ca.SX | None) -> ca.SX | None:
            if x is None:
                return None
            out = ca.SX.zeros(*x.shape)
            for i in range(x.shape[0]):
                for j in range(x.shape[1]):
                    if x[i, j].is_symbolic():
                        out[i, j] = bar[index[x[i, j].name()]]
            return out

        return Kinematics(*(tuple(shaped(x) for x in getattr(self.kin, f)) for f in _FIELDS))


def placed_symbols(kin: Kinematics, p: ca.SX) -> PlacedSymbols:
    """:class:`PlacedSymbols` for ``kin``: a fresh symbol for each entry of its quantities (a
    rotation, a point, an axis) that depends on ``p``."""
    symbols: list[ca.SX] = []
    placed: list[ca.SX] = []

    def free(x: ca.SX | None) -> ca.SX | None:
        if x is None:
            return None
        out = ca.SX(x)
        for i in range(x.shape[0]):
            for j in range(x.shape[1]):
                if ca.depends_on(x[i, j], p):
                    out[i, j] = ca.SX.sym(f"k_{len(symbols)}")
                    symbols.append(out[i, j])
                    placed.append(x[i, j])
        return out

    fields = (tuple(free(x) for x in getattr(kin, f)) for f in _FIELDS)
    return PlacedSymbols(Kinematics(*fields), ca.vertcat(*symbols), ca.vertcat(*placed))


@dataclass(frozen=True)
class PlacementAdjoint:
    """An objective's gradient w.r.t. the placed tree, as :func:`placement_gradient` takes it.

    Attributes:
        force, torque: per body, the wrench (torque about the world origin) whose pairing with
            a rigid displacement of the body's subtree (a twist about the origin) is the
            objective's rate of change.
        axis: per body, the adjoint of its joint axis turned alone (its origin and the subtree
            held); zero for the base.
        com, tip: per body, the adjoints of its centre of mass and tip moved alone.
        contact: per declared contact, the adjoint of its point moved alone.
    """

    force: tuple[ca.SX, ...]
    torque: tuple[ca.SX, ...]
    axis: tuple[ca.SX, ...]
    com: tuple[ca.SX, ...]
    tip: tuple[ca.SX, ...]
    contact: tuple[ca.SX, ...]


def placement_gradient(topology: Topology, values: tuple[BodyValues, ...], kin: Kinematics,
                       adjoint: PlacementAdjoint, p: ca.SX) -> ca.SX:
    """The gradient w.r.t. ``p`` (n_values x 1) of an objective whose gradient w.r.t. the placed
    tree ``kin`` is ``adjoint``, through the placement only: add the objective's own gradient
    w.r.t. ``p`` (mass properties, which place nothing)."""
    pairs: list[tuple[ca.SX | float, ca.SX]] = []
    for b, v in enumerate(values):
        torque = adjoint.torque[b] - ca.cross(kin.W_p_O[b], adjoint.force[b])
        pairs += _turning_derivatives(topology, values, kin, adjoint.axis[b], b, torque)
        pairs += _sliding_derivatives(topology, values, kin, adjoint, b)
    pairs = [(x, d) for x, d in pairs if not isinstance(x, float)]
    if not pairs:
        return ca.SX.zeros(p.shape[0], 1)
    return ca.jacobian(ca.vertcat(*[x for x, _ in pairs]), p).T @ ca.vertcat(*[d for _, d in pairs])


def placed_gradient(topology: Topology, values: tuple[BodyValues, ...], kin: Kinematics, placed: PlacedSymbols,
                    objective: ca.SX, p: ca.SX) -> ca.SX:
    """The gradient w.r.t. ``p`` of ``objective``, built on ``placed.kin`` (the placed tree
    ``kin`` as :func:`placed_symbols`): its own gradient w.r.t. ``p`` plus, through the placed
    tree, :func:`placement_gradient`; in terms of ``placed.symbols`` (substitute
    ``placed.placed`` for them)."""
    d = ca.gradient(objective, p)
    if not placed.symbols.shape[0]:
        return d
    bar = placed.adjoint(objective)
    return d + placement_gradient(topology, values, kin, kinematics_adjoint(topology, kin, bar), p)


def _body_contacts(topology: Topology, b: int) -> list[int]:
    """The declared contacts on body ``b`` (indices into ``W_p_C``)."""
    return [c for c, (body, _) in enumerate(topology.declared_contacts) if body == b]


def _subtree_sums(topology: Topology, own: list[ca.SX]) -> tuple[ca.SX, ...]:
    """Per body, the sum of ``own`` over its subtree (one backward pass)."""
    total = list(own)
    for b in reversed(range(1, topology.n_bodies)):
        total[topology.parents[b]] = total[topology.parents[b]] + total[b]
    return tuple(total)


def kinematics_adjoint(topology: Topology, kin: Kinematics, bar: Kinematics) -> PlacementAdjoint:
    """:class:`PlacementAdjoint` from the gradient ``bar`` w.r.t. each quantity of the placed tree
    (:meth:`PlacedSymbols.adjoint`): a point's adjoint is a force at the point, a direction's
    (joint axis, rotation column) a torque d x d_bar."""
    force: list[ca.SX] = []
    torque: list[ca.SX] = []
    for b in range(topology.n_bodies):
        points = [(kin.W_p_O[b], bar.W_p_O[b]), (kin.W_p_G[b], bar.W_p_G[b]), (kin.W_p_T[b], bar.W_p_T[b])]
        points += [(kin.W_p_C[c], bar.W_p_C[c]) for c in _body_contacts(topology, b)]
        directions = [(kin.W_R_B[b][:, j], bar.W_R_B[b][:, j]) for j in range(3)]
        if kin.joint_axis[b] is not None:
            directions.append((kin.joint_axis[b], bar.joint_axis[b]))
        force.append(sum((x_bar for _, x_bar in points), ca.SX.zeros(3, 1)))
        torque.append(sum((ca.cross(x, x_bar) for x, x_bar in points + directions), ca.SX.zeros(3, 1)))
    axis = tuple(ca.SX.zeros(3, 1) if x is None else x for x in bar.joint_axis)
    return PlacementAdjoint(_subtree_sums(topology, force), _subtree_sums(topology, torque), axis,
                            tuple(bar.W_p_G), tuple(bar.W_p_T), tuple(bar.W_p_C))


def _turning_derivatives(topology: Topology, values: tuple[BodyValues, ...], kin: Kinematics, a_bar: ca.SX,
                         b: int, torque: ca.SX) -> list[tuple[ca.SX | float, ca.SX]]:
    """(value, derivative) for the values that turn body b's subtree about its joint origin O_b:
    ``angle`` about the joint axis a, ``rpy`` about the parent's frame turned as URDF's
    Rz(yaw) Ry(pitch) Rx(roll) (roll about R_parent Rz Ry e_x, the x column of the frame the
    forward kinematics forms, since Rx e_x = e_x), ``axis`` (normalised: only its direction
    counts), which turns the body by R(k, angle)'s differential, while a itself turns with the
    axis alone. ``torque``: the subtree's, about O_b; ``a_bar``: the adjoint of the axis turned
    alone."""
    v, parent = values[b], topology.parents[b]
    R_parent = kin.W_R_B[parent] if parent >= 0 else ca.DM.eye(3)
    frame = R_parent @ rpy_rotation(v.rpy)
    k = ca.vertcat(*v.axis)
    a = frame @ (k / ca.norm_2(k)) if kin.joint_axis[b] is None else kin.joint_axis[b]
    roll, pitch, yaw = v.rpy
    R_yaw = axis_rotation((0.0, 0.0, 1.0), yaw)
    pairs = [
        (v.angle, a.T @ torque),
        (roll, frame[:, 0].T @ torque),
        (pitch, (R_parent @ R_yaw[:, 1]).T @ torque),
        (yaw, R_parent[:, 2].T @ torque),
    ]
    if all(isinstance(x, float) for x in v.axis):
        return pairs
    body = torque - ca.cross(a, a_bar)  # what turns with the body, not with the axis
    w = ca.sin(v.angle) * body + (1 - ca.cos(v.angle)) * ca.cross(body, a) + a_bar
    d_axis = frame.T @ (w - a * (a.T @ w)) / ca.norm_2(k)
    return pairs + [(x, d_axis[j]) for j, x in enumerate(v.axis)]


def _sliding_derivatives(topology: Topology, values: tuple[BodyValues, ...], kin: Kinematics,
                         adjoint: PlacementAdjoint, b: int) -> list[tuple[ca.SX | float, ca.SX]]:
    """(value, derivative) for the values that move points of body b along its axes: ``at``
    (b's subtree along the parent's x), ``length`` (b's own points and its children's
    subtrees along b's x), ``com``, ``com_offset`` and the contact fractions."""
    v, parent = values[b], topology.parents[b]
    x_axis = kin.W_R_B[b][:, 0]
    contacts = _body_contacts(topology, b)
    along = v.com * adjoint.com[b] + adjoint.tip[b]
    along += sum((f * adjoint.contact[c] for f, c in zip(v.contacts, contacts)), ca.SX.zeros(3, 1))
    d_length = x_axis.T @ along
    for child in (c for c in range(topology.n_bodies) if topology.parents[c] == b):
        d_length += values[child].at * (x_axis.T @ adjoint.force[child])
    pairs = [(v.length, d_length), (v.com, v.length * (x_axis.T @ adjoint.com[b]))]
    pairs += [(f, v.length * (x_axis.T @ adjoint.contact[c])) for f, c in zip(v.contacts, contacts)]
    pairs += [(x, kin.W_R_B[b][:, j + 1].T @ adjoint.com[b]) for j, x in enumerate(v.com_offset)]
    if parent >= 0:
        pairs.append((v.at, values[parent].length * (kin.W_R_B[parent][:, 0].T @ adjoint.force[b])))
    return pairs

