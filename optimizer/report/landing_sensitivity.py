"""``footopt evaluate --sensitivity``: which value of a model file moves its whole landing's
objectives, and by how much.

The derivatives are :func:`~impulse_core.timedomain.landing_derivatives.landing_gradient`'s,
taken at the step (and settings) of the landing the command reports: exact for that run, along
its event sequence (they hold while a change of a value keeps the sequence: the same impacts in
the same modes, the same step counts). The design values (the tree's lengths, masses, angles,
..., each revolute joint's stiffness, damping, rest and limits) and the scene's (friction, speed,
restitution, each joint's stop restitution) are reported together, each with its derivative and
its elasticity x / f df/dx (the relative change of f per relative change of x).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from impulse_core.errors import NumericalError
from impulse_core.model.joints import FREE
from impulse_core.timedomain.landing import LandingResult, LandingSettings
from impulse_core.timedomain.landing_derivatives import SCALARS, TIE, LandingGradient, landing_gradient
from optimizer.config.model_file import ModelFile
from optimizer.evaluation.model_choice import TimeDomainResult

#: Values listed per objective in the text report (the JSON has them all).
SHOWN_VALUES = 12
#: The objectives' units (``energy_absorbed`` is a fraction).
OBJECTIVE_UNITS = {
    "peak_external_norm": "N s",
    "peak_internal_norm": "N s",
    "peak_max_internal": "N s",
    "energy_absorbed": "1",
}
#: Each value's unit by the last part of its name (``1``: a ratio or a fraction of a length).
VALUE_UNITS = {
    "length": "m", "mass": "kg", "angle": "rad", "at": "1", "com": "1", "gyration": "1",
    "roll": "rad", "pitch": "rad", "yaw": "rad", "axis_x": "1", "axis_y": "1", "axis_z": "1", "radius": "m",
    "com_y": "m", "com_z": "m", "ixx": "kg m^2", "iyy": "kg m^2", "izz": "kg m^2", "ixy": "kg m^2",
    "ixz": "kg m^2", "iyz": "kg m^2", "stiffness": "N m/rad", "damping": "N m s/rad", "rest": "rad",
    "limits[0]": "rad", "limits[1]": "rad", "friction": "1", "speed": "m/s", "restitution": "1",
    "stop_restitution": "1",
}
#: The one line the text report and the help give for what the derivatives are and cost.
ALONG = ("exact derivatives of this run (its step and tolerance) along its event sequence: they hold while "
         "a change of a value keeps the same impacts in the same modes; they cost about 4-11 landings")


def value_unit(name: str) -> str:
    """The unit of a value named as in ``LandingGradient.names`` or ``scene_names``."""
    last = name.rsplit(".", 1)[-1]
    return "1" if last.startswith("contacts[") else VALUE_UNITS.get(last, "")


def landing_sensitivity(model: ModelFile, result: TimeDomainResult) -> LandingGradient:
    """The exact derivatives of the reported whole landing ``result`` of ``model``: at its step,
    with its settings.

    Raises:
        NumericalError: the derivatives are refused (a graze, redundant rows, an impact off the
            circular cone's exact law, ...), or the run replayed at the reported step is not the
            reported one.
    """
    r = result.result
    if not isinstance(r, LandingResult):
        raise TypeError("landing_sensitivity: not a whole landing")
    settings = result.settings if isinstance(result.settings, LandingSettings) else LandingSettings()
    g = landing_gradient(model.tree, model.scene, model.joints, settings, step=r.step, space=model.space,
                         share=r.share)
    same = len(g.result.events) == len(r.events) and g.result.n_steps == r.n_steps and all(
        math.isclose(g.values[k], getattr(r, k), rel_tol=1e-9, abs_tol=1e-300) for k in SCALARS)
    if not same:
        raise NumericalError(f"the run replayed at the reported step {r.step:.3g} s is not the reported landing")
    return g


def unset_values(model: ModelFile, g: LandingGradient) -> tuple[str, ...]:
    """Entries of ``g`` the file does not set, whose derivative is 0 by construction: the limits
    and stop restitution of a joint without stops, the rest of a joint resting at its touchdown
    angle."""
    laws = model.joints or (FREE,) * model.tree.n_bodies
    out = []
    for body, law in zip(model.tree.bodies, laws, strict=True):
        if law.limits is None:
            out += [f"{body.name}.limits[0]", f"{body.name}.limits[1]", f"{body.name}.stop_restitution"]
        if law.rest is None:
            out.append(f"{body.name}.rest")
    present = set(g.names) | set(g.scene_names)
    return tuple(n for n in out if n in present)


def lowest_contacts(model: ModelFile, tol: float = 1e-9) -> tuple[int, ...]:
    """The contacts lowest at touchdown (within ``tol`` m of the smallest clearance above the
    ground, as :func:`~impulse_core.timedomain.compliant.touchdown_configuration` places the
    tree). Where there are several, the derivatives follow the first: the touchdown height has a
    kink there, and a value that moves one of them has a one-sided derivative."""
    from impulse_core.evaluate import touchdown_geometry
    from impulse_core.kinematics.spatial import PLANAR

    scene = model.scene
    C = touchdown_geometry(model.tree, model.space).contacts
    if model.space is PLANAR:
        from impulse_core.model.terrain import vertical_clearance

        clearance = vertical_clearance(scene.terrain, C + np.array([scene.base_x, 0.0]))
    else:
        from impulse_core.model.heightfield import vertical_clearance as clearance_above
        from impulse_core.timedomain.compliant import spatial_ground

        clearance = clearance_above(spatial_ground(scene), C + np.array([scene.base_x, 0.0, scene.base_z]))
    return tuple(int(i) for i in np.flatnonzero(clearance <= clearance.min() + tol))


def elasticity(x: float, f: float, d: float) -> float | None:
    """d ln f / d ln x = x / f df/dx, or None where x or f is 0 or d is not a number."""
    if x == 0.0 or f == 0.0 or not math.isfinite(d):
        return None
    return x / f * d


def _columns(g: LandingGradient, objective: str) -> tuple[list[str], np.ndarray, np.ndarray]:
    names = list(g.names) + list(g.scene_names)
    values = np.concatenate([g.theta, g.scene_theta])
    derivative = np.concatenate([g.jacobian[objective], g.scene_jacobian[objective]], axis=-1)
    return names, values, derivative  # a scalar's: one entry per value; an array's: one row per component


def _json_number(x: float) -> float | None:
    return float(x) + 0.0 if math.isfinite(x) else None


def sensitivity_record(model: ModelFile, g: LandingGradient) -> dict[str, Any]:
    """The ``sensitivity`` object of ``footopt evaluate --json --sensitivity`` (MODEL_FORMAT.md,
    "What footopt evaluate --json prints")."""
    from optimizer.report.text import contact_names

    names, values, _ = _columns(g, SCALARS[0])
    contacts, lowest = contact_names(model.tree), lowest_contacts(model)
    derivatives: dict[str, dict[str, Any]] = {}
    elasticities: dict[str, dict[str, float | None]] = {}
    for objective in g.jacobian:
        _, _, d = _columns(g, objective)
        if d.ndim == 1:
            derivatives[objective] = {n: _json_number(x) for n, x in zip(names, d, strict=True)}
            f = float(g.values[objective])
            elasticities[objective] = {n: None if (e := elasticity(float(x), f, float(dx))) is None else e + 0.0
                                       for n, x, dx in zip(names, values, d, strict=True)}
        else:  # total_external (per contact), final_angles: one list per value, an entry per component
            derivatives[objective] = {n: [_json_number(x) for x in d[:, i]] for i, n in enumerate(names)}
    return {
        "along": "event sequence",
        "step": float(g.result.step),
        "events": len(g.result.events),
        "design": list(g.names),
        "scene": list(g.scene_names),
        "unset": list(unset_values(model, g)),
        "values": {n: float(x) + 0.0 for n, x in zip(names, values, strict=True)},
        "objectives": {k: (float(v) + 0.0 if np.ndim(v) == 0 else [float(x) + 0.0 for x in v])
                       for k, v in g.values.items()},
        "derivatives": derivatives,
        "elasticities": elasticities,
        "ties": {k: [int(i) for i in v] for k, v in g.ties.items() if len(v) > 1},
        "lowest_contacts": [contacts[i] for i in lowest] if len(lowest) > 1 else [],
    }


def effect(name: str, x: float, f: float, d: float) -> float | None:
    """The text report's measure of a value's weight: the % change of f for +1 % of x (the
    elasticity), or for an angle (unit rad), whose zero is a choice of frame, for +1 degree
    (100 d pi / 180 / f); None where f (or, not an angle, x) is 0 or d is not a number."""
    if value_unit(name) == "rad":
        return None if f == 0.0 or not math.isfinite(d) else 100.0 * d * math.pi / 180.0 / f
    return elasticity(x, f, d)


def _sorted_rows(names: list[str], values: np.ndarray, d: np.ndarray, f: float
                 ) -> list[tuple[str, float, float, float | None]]:
    """(name, value, derivative, :func:`effect`), by |effect| (largest first; values without one
    after, by |derivative|)."""
    rows = [(n, float(x), float(dx), effect(n, float(x), f, float(dx)))
            for n, x, dx in zip(names, values, d, strict=True)]
    return sorted(rows, key=lambda r: (r[3] is None, -abs(r[3] or 0.0), -abs(r[2]) if math.isfinite(r[2]) else 0.0))


def format_sensitivity(model: ModelFile, g: LandingGradient, shown: int = SHOWN_VALUES) -> list[str]:
    """The text report's sensitivity tables: per scalar objective its values by |effect|, the
    first ``shown`` of them, and what the derivatives are (and, where the peak is a tie, what that
    means)."""
    from optimizer.report.text import _table, contact_names

    unset = set(unset_values(model, g))
    lines = ["", f"Sensitivity: {ALONG}.",
             f"({len(g.result.events)} impacts, step {g.result.step:.3g} s; effect: the % change of f for +1 % of x "
             "(the elasticity (x / f) df/dx), or for +1 degree of an angle (its zero is a choice of frame), '-' where "
             "f or x is 0; values the file does not set are not listed)"]
    for objective in SCALARS:
        names, values, d = _columns(g, objective)
        f, unit = float(g.values[objective]), OBJECTIVE_UNITS[objective]
        rows = [r for r in _sorted_rows(names, values, d, f) if r[0] not in unset]
        listed = rows[:shown]
        hidden = rows[shown:]
        zero = sum(1 for r in hidden if r[2] == 0.0)
        table = [[n, f"{x:.6g}", value_unit(n), "-" if not math.isfinite(dx) else f"{dx:.4g}",
                  "-" if e is None else f"{e:+.4f}"] for n, x, dx, e in listed]
        per = "per unit of x" if unit == "1" else f"{unit} per unit of x"
        lines += ["", f"{objective} = {f:.6g} " + ("(a fraction)" if unit == "1" else unit),
                  *("  " + s for s in _table(["value", "x", "unit of x", f"df/dx [{per}]",
                                              "effect [% of f]"], table))]
        if hidden:
            lines.append(f"  ... {len(hidden)} more values ({zero} with derivative 0): "
                         "footopt evaluate --json --sensitivity lists them all")
        ties = g.ties.get(objective, ())
        if len(ties) > 1:
            lines.append(f"  note: {len(ties)} events tie for the peak (within {TIE:g} relative: events "
                         f"{', '.join(str(i) for i in ties)}): these are the derivatives of one of them, an element "
                         "of the Clarke subdifferential (a subgradient), not a gradient")
    lowest = lowest_contacts(model)
    if len(lowest) > 1:
        contacts = contact_names(model.tree)
        which = ", ".join(contacts[i] for i in lowest)
        lines.append(f"note: {len(lowest)} contacts are lowest at touchdown ({which}): "
                     f"the touchdown height follows the first, so a value that moves one of them has a one-sided "
                     "derivative (the height has a kink there)")
    if any(np.isnan(g.scene_jacobian[k]).any() for k in SCALARS):
        lines.append("note: friction is 0: the frictionless run has no friction rows, so its derivative w.r.t. "
                     "friction is not defined ('-')")
    return lines


__all__ = ["ALONG", "OBJECTIVE_UNITS", "SHOWN_VALUES", "effect", "elasticity", "format_sensitivity", "landing_sensitivity",
           "sensitivity_record", "unset_values", "value_unit"]
