"""Identical sibling subtrees (twins: identical toes on one parent) and the symmetry of their
motion: the exact landing keeps twins' states identical, since their equations of motion and
contact laws map onto each other, and :func:`twin_groups` and :func:`symmetrized` let the landing
hold them so against rounding (:meth:`_Landing.modes_after`; after every step too, where
:func:`mode_alike`: :meth:`_Landing.held_alike`)."""

from __future__ import annotations

from dataclasses import fields

import numpy as np

from impulse_core.kinematics.spatial import DofLayout
from impulse_core.model.rods import children as body_children
from impulse_core.model.tree import Tree
from impulse_core.timedomain.events.point import _Joints


def twin_groups(tree: Tree, joints: _Joints, layout: DofLayout) -> tuple[np.ndarray, ...]:
    """The DOFs of each group of twins: sibling subtrees (one parent) whose bodies are equal in
    everything but their names, body by body in the same order, with equal joint laws (stiffness,
    damping, rest angle, stops, stop restitution) at their DOFs. Each group is a k x m array: k
    twins, each one's m DOFs in the same order (its subtree's bodies in the tree's order). Twins
    inside twins form groups of their own. Empty where the tree has none."""
    return tuple(dofs for dofs, _ in _twins(tree, joints, layout))


def twin_contacts(tree: Tree, joints: _Joints, layout: DofLayout) -> tuple[np.ndarray, ...]:
    """The declared contacts of each group of :func:`twin_groups` (in its order): a k x c array, k
    twins, each one's c contacts in the same order (its subtree's bodies in the tree's order, each
    body's contacts in its order); k x 0 where the twins have none."""
    return tuple(contacts for _, contacts in _twins(tree, joints, layout))


def _twins(tree: Tree, joints: _Joints, layout: DofLayout) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each group of twins' (DOFs, contacts) (:func:`twin_groups`, :func:`twin_contacts`)."""
    children = body_children(tree)
    body_dof = layout.body_dof
    own = [f.name for f in fields(tree.bodies[0]) if f.name not in ("name", "parent")]
    declared: dict[int, list[int]] = {}
    for c, (b, _) in enumerate(tree.contacts):
        declared.setdefault(b, []).append(c)

    def law(i: int) -> tuple:
        k = body_dof[i]
        if k is None:
            return ()
        return tuple(float(a[k]) for a in (joints.stiffness, joints.damping, joints.rest, joints.lo, joints.hi,
                                           joints.restitution))

    signature: dict[int, tuple] = {}
    dofs: dict[int, list[int]] = {}
    contacts: dict[int, list[int]] = {}
    for i in range(len(tree.bodies) - 1, 0, -1):  # children after their parents: every child done first
        body = tree.bodies[i]
        signature[i] = (tuple(getattr(body, name) for name in own), law(i),
                        tuple(signature[c] for c in children[i]))
        dofs[i] = ([] if body_dof[i] is None else [body_dof[i]]) + [d for c in children[i] for d in dofs[c]]
        contacts[i] = declared.get(i, []) + [k for c in children[i] for k in contacts[c]]
    groups = []
    for parent in range(len(tree.bodies)):
        alike: dict[tuple, list[int]] = {}
        for c in children[parent]:
            alike.setdefault(signature[c], []).append(c)
        for members in alike.values():
            if len(members) > 1 and dofs[members[0]]:
                groups.append((np.array([dofs[c] for c in members], dtype=int),
                               np.array([contacts[c] for c in members], dtype=int).reshape(len(members), -1)))
    return groups


def symmetrized(x: np.ndarray, groups: tuple[np.ndarray, ...]) -> np.ndarray:
    """``x`` (per DOF, or per DOF and column) with each group's twins given their mean where they
    differ (``x`` itself, not a copy, where every group's twins are equal to the bit)."""
    out = x
    for g in groups:
        values = x[g]  # k x m (x ...)
        if (values == values[0]).all():
            continue
        if out is x:
            out = x.copy()
        out[g] = values.mean(axis=0)
    return out


def mode_alike(stop: np.ndarray, closed: np.ndarray, slip: np.ndarray, groups: tuple[np.ndarray, ...],
               contacts: tuple[np.ndarray, ...]) -> bool:
    """Whether a mode (its ``stop`` per DOF, ``closed`` and ``slip`` per contact) treats each group's
    twins alike (``groups``: :func:`twin_groups`, ``contacts``: :func:`twin_contacts`): their stops,
    and their contacts' rows and slips, equal twin by twin."""
    for g, c in zip(groups, contacts):
        if not (stop[g] == stop[g[0]]).all():
            return False
        if c.size and not ((closed[c] == closed[c[0]]).all() and (slip[c] == slip[c[0]]).all()):
            return False
    return True
