"""Which values the impulses depend on: exact derivatives of a design's objectives with respect
to every value of its tree (CasADi's algorithmic differentiation of the core's impact model).

For a foot of uniform rods landing straight down, the derivatives with respect to every rod
length are zero (to rounding): the impulses depend on the angles and the masses only; lengths
act through the touchdown geometry (the constraints). The mass derivatives are also given
budget-neutral: moving mass into one foot rod out of all foot rods equally, so the foot mass is
unchanged.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import casadi as ca
import numpy as np

from impulse_core.evaluate import approach_velocity, compiled_model
from impulse_core.kinematics.spatial import PLANAR, Space, values_space
from impulse_core.model.tree import ContactSelection, Scene, Topology, design_vector, value_names
from optimizer.design_space import FootDesign, Leg, foot_tree, segment_names

#: Objectives differentiated, in this order.
QUANTITIES = ("external_norm", "internal_norm", "energy_after", "base_angular_velocity")


@dataclass(frozen=True)
class Sensitivity:
    """Exact first derivatives of a design's objectives (Newton's law, paper eq. 11).

    Attributes:
        names: the tree's value names (``toe1_distal.length``, ``heel.mass``, ...; see
            ``impulse_core.model.tree.value_names``).
        values: the values.
        derivatives: d quantity / d value, one row per entry of ``QUANTITIES``.
        budget_neutral_mass: per foot rod, d quantity / d mass when that rod gains the mass
            every foot rod loses equally (rows as ``derivatives``; columns: foot rods in tree
            order, named by ``foot_rods``).
        foot_rods: body names of the foot rods.
    """

    names: tuple[str, ...]
    values: np.ndarray
    derivatives: np.ndarray
    budget_neutral_mass: np.ndarray
    foot_rods: tuple[str, ...]

    def of(self, quantity: str) -> dict[str, float]:
        """Derivatives of one quantity by value name."""
        row = self.derivatives[QUANTITIES.index(quantity)]
        return dict(zip(self.names, (float(x) for x in row), strict=True))


@functools.lru_cache(maxsize=64)
def _jacobian_function(topology: Topology, space: Space = PLANAR) -> ca.Function:
    """(p, v_minus, restitution) -> (quantities, d quantities / d p) for one topology (``space``:
    the plane, or PLANAR_OFFSET where a centre of mass is off its rod)."""
    impact = compiled_model(topology, space).impact
    p = ca.SX.sym("p", impact.size1_in(0))
    v = ca.SX.sym("v_minus", impact.size1_in(1))
    e = ca.SX.sym("restitution")
    out = impact(p=p, v_minus=v, restitution=e)
    omega = out["v_plus"][2]
    q = ca.vertcat(out["external_norm"], out["internal_norm"], out["energy_after"], ca.sqrt(omega**2))
    return ca.Function("sensitivity", [p, v, e], [q, ca.jacobian(q, p)], ["p", "v_minus", "restitution"], ["q", "dq_dp"])


def sensitivities(leg: Leg, design: FootDesign, scene: Scene) -> Sensitivity:
    """Exact derivatives of the objectives of ``design`` with every contact hitting."""
    tree = foot_tree(leg, design)
    topology, space = tree.topology(), values_space(tree, PLANAR)  # a leg's centres of mass off its rods too
    fn = _jacobian_function(topology, space)
    p = design_vector(tree, space.body_values)
    v = approach_velocity(topology, scene.speed)
    out = fn(p=p, v_minus=v, restitution=scene.restitution)
    d = np.array(out["dq_dp"])
    names = value_names(tree, space.body_values)
    rods = segment_names(design.shape)
    mass_cols = [names.index(f"{r}.mass") for r in rods]
    dm = d[:, mass_cols]
    neutral = dm - dm.mean(axis=1, keepdims=True)
    return Sensitivity(names, p, d, neutral, rods)


def all_contacts(scene: Scene) -> Scene:
    """``scene`` with every declared contact hitting (the derivatives' setting)."""
    return Scene(scene.speed, scene.restitution, scene.friction, ContactSelection.ALL, scene.contact_tolerance)


__all__ = ["QUANTITIES", "Sensitivity", "all_contacts", "sensitivities"]
