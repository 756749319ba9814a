"""What ``footopt evaluate`` prints: a readable text report and a JSON record per model file.

One code path writes what every model shares (contacts and their impulses, joints, norms,
velocities, energy, reference values); a rigid ``ImpactResult`` adds its friction columns and
warnings, a time-domain result (``optimizer.evaluation.model_choice.TimeDomainResult``: sequential or compliant)
its touchdown table and, compliant, how the integration ended.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from impulse_core.evaluate import ImpactResult, touchdown_geometry
from impulse_core.model.support import support_margin
from impulse_core.impact.laws import ImpactModel
from impulse_core.kinematics.spatial import PLANAR, Space, dof_layout
from impulse_core.model.terrain import FLAT
from impulse_core.model.tree import ContactSelection, Scene, Tree
from impulse_core.timedomain.compliant import CompliantResult, CompliantStatus, ContactLaw
from impulse_core.timedomain.landing import BALANCE_CHECK, LandingResult, halving_stalled, stall_start
from impulse_core.timedomain.sequential import SequentialResult
from optimizer.config.model_file import ModelFile
from optimizer.evaluation.model_choice import TimeDomainResult

#: What the reports read: one rigid impact, or a sequential or compliant landing.
Result = ImpactResult | TimeDomainResult

#: Kinetic energy may grow by this fraction (rounding) before the report calls it a gain.
ENERGY_GAIN_TOL = 1e-9


def contact_names(tree: Tree) -> tuple[str, ...]:
    """Names of the declared contacts in declaration order: body name and index on the body,
    e.g. ``heel[0]``."""
    return tuple(f"{tree.bodies[b].name}[{k}]" for b, k in tree.contacts)


def joint_names(tree: Tree) -> tuple[str, ...]:
    """One name per joint: its child body's name (every non-base body, file order)."""
    return tuple(b.name for b in tree.bodies[1:])


def velocity_names(tree: Tree, space: Space = PLANAR) -> tuple[tuple[str, str], ...]:
    """(name, unit) of each generalized velocity: the base's vx, vy, omega (spatial: vx, vy, vz,
    wx, wy, wz, world frame), then the rate of each revolute joint (named by its child body) in
    file order."""
    layout = dof_layout(tree.topology(), space)
    n_base = len(space.base_dofs)
    base: tuple[tuple[str, str], ...] = (("base vx", "m/s"), ("base vy", "m/s"), ("base omega", "rad/s"))
    if space is not PLANAR:
        base = tuple((f"base v{a}", "m/s") for a in "xyz") + tuple((f"base w{a}", "rad/s") for a in "xyz")
    joints = tuple((f"{tree.bodies[layout.dof_body[k]].name} rate", "rad/s") for k in range(n_base, layout.nv))
    return base + joints


def is_finite(result: Result) -> bool:
    """True when every number of the result is finite (a solve that failed is not)."""
    arrays = [result.external, result.internal, result.internal_magnitude, result.v_plus]
    if isinstance(result, ImpactResult):
        arrays.append(result.internal_torque)
    scalars = (result.external_norm, result.internal_norm, result.energy_before, result.energy_after)
    return all(np.all(np.isfinite(a)) for a in arrays) and all(math.isfinite(x) for x in scalars)


def energy_gained(result: Result) -> bool:
    """True when the kinetic energy after the impact exceeds the energy before."""
    return result.energy_after > result.energy_before * (1.0 + ENERGY_GAIN_TOL)


def rung(result: Result) -> tuple[str, str]:
    """The model that ran: its name (``newton``, ``sequential``, ...) and a one-line description."""
    if isinstance(result, ImpactResult):
        return result.model.value, result.model.description
    return result.impact_model, result.description


def warnings(model: ModelFile, result: Result) -> tuple[str, ...]:
    """Things about this impact a reader must know, one sentence each."""
    out = list(
        _rigid_warnings(model, result) if isinstance(result, ImpactResult) else _time_domain_warnings(model, result)
    )
    if energy_gained(result):
        out.append(
            f"energy gained: the kinetic energy grows from {result.energy_before:.6g} J to "
            f"{result.energy_after:.6g} J under the {rung(result)[0]} model"
        )
    return tuple(out)


def _rigid_warnings(model: ModelFile, result: ImpactResult) -> list[str]:
    names = contact_names(model.tree)
    out = list(result.notes)
    if result.model is ImpactModel.DECOUPLED:
        out.append(
            "decoupled (paper eq. 14) approximates Newton's law (eq. 11) with no error bound: it equals eq. 11 "
            "only when every impulse is equal (docs/ERRATA.md); run newton or lcp for the model's answer"
        )
    if not result.split_unique:
        active = ", ".join(names[i] for i in result.active)
        shown = (
            "no non-negative split meets the restitution law, so the smallest-norm split is shown"
            if result.pulling
            else "the smallest-norm split inside the friction cones is shown"
            if result.model is ImpactModel.FRICTION_RELAXED
            else "the smallest-norm split the friction law allows is shown (the solver's own where the law's "
            "answer lies outside the cone's inscribed 16-gon)"
            if result.model is ImpactModel.FRICTION
            else "the smallest-norm non-negative split is shown"
        )
        out.append(
            f"contacts {active} are redundant: the post-impact velocity is unique, the split of the "
            f"impulse is not; {shown}"
        )
    if result.pulling:
        pulling = ", ".join(names[i] for i in result.pulling)
        law = "the decoupled approximation (eq. 14)" if result.model is ImpactModel.DECOUPLED else "Newton's law"
        out.append(f"{law} makes contacts {pulling} pull on the ground (negative impulse)")
    if result.model is ImpactModel.FRICTION_RELAXED:
        out.append(
            "friction-relaxed is Anitescu's convex relaxation, not Coulomb's law: a sliding contact leaves the "
            "ground faster than restitution by mu |slip velocity|, so its normal impulse is biased high (run friction "
            "for the exact law)"
        )
    if result.separating and result.model in (ImpactModel.LCP, ImpactModel.FRICTION, ImpactModel.FRICTION_RELAXED):
        separating = ", ".join(names[i] for i in result.separating)
        out.append(f"contacts {separating} separate from the ground with zero impulse")
    hop = _friction_hop(model, result)
    if hop:
        worst = max(hop.values())
        out.append(
            f"contacts {', '.join(names[i] for i in hop)} slide and leave the ground up to {worst:.3g} m/s faster than "
            f"restitution while carrying impulse (the convex friction law's relaxation): read their normal "
            f"impulses as upper estimates"
        )
    return out


def _gain_warning(r: LandingResult) -> str:
    """The landing's impacts that raised the kinetic energy, the largest gain named."""
    gains = r.gaining_events
    top = max(gains, key=lambda e: e.energy_after - e.energy_before)
    return (
        f"{len(gains)} impact{'s' if len(gains) != 1 else ''} of the landing raised the kinetic energy, the most at "
        f"t = {top.time:.6g} s, from {top.energy_before:.6g} J to {top.energy_after:.6g} J: Newton's restitution "
        "with Coulomb friction can, where a contact sticks or reverses its slip at a restitution near 1 (Kane's "
        "paradox); the law is the contract's, the energy is not conserved by it"
    )


def _time_domain_warnings(model: ModelFile, result: TimeDomainResult) -> list[str]:
    names = contact_names(model.tree)
    out = []
    never = [names[i] for i in range(len(names)) if i not in set(result.active)]
    if never:
        out.append(f"contacts {', '.join(never)} never touch the ground during the landing")
    r = result.result
    if isinstance(r, LandingResult) and r.runs_apart:
        out.append(_runs_apart_warning(r))
    elif isinstance(r, LandingResult) and not r.converged and halving_stalled(r.halving):
        out.append(_stalled_warning(r))
    elif isinstance(r, LandingResult) and not r.converged:
        out.append(
            f"the landing did not converge to its tolerance: error estimate {r.error_estimate:.3g} > "
            f"{r.tolerance:g} at a Runge-Kutta step of {r.step:.3g} s (the contacts may chatter; the answer is "
            "the finest run)"
        )
    if isinstance(r, LandingResult) and not r.momentum_balance <= BALANCE_CHECK:
        out.append(
            f"the landing's momentum balance closes only to {r.momentum_balance:.2g} of its momentum (above "
            f"{BALANCE_CHECK:g}): its total impulses miss part of what moved the model (position corrections that "
            "move momentum with no impulse, as a contact chattering in a heightfield's crease, are one known cause)"
        )
    if isinstance(r, LandingResult) and r.energy_gained:
        out.append(_gain_warning(r))
    if isinstance(r, LandingResult) and r.non_unique:
        shown = "the smallest-norm non-negative split" if model.scene.friction == 0 else "the smallest-norm split the friction law allows"
        out.append(
            f"{r.non_unique} impact{'s' if r.non_unique != 1 else ''} of the landing had redundant rows: the velocities "
            f"after are unique, the split of the impulse is not; {shown} is shown"
        )
    if isinstance(r, LandingResult) and r.bridges:
        at = ", ".join(f"{t:.6g} s" for t, _ in r.bridges)
        out.append(
            f"events stalled where no contact mode held (a start of slip the modes do not resolve, or Painleve's "
            f"paradox that a jam did not end) at t = {at}: the "
            f"landing crossed {sum(span for _, span in r.bridges):.3g} s there by Moreau-Jean time steps (first order, "
            "within the error estimate; no derivatives along this landing)"
        )
    if isinstance(r, LandingResult) and r.inexact:
        out.append(
            f"{r.inexact} impacts or contact-mode choices of the landing did not meet the exact circular-cone friction "
            "law and used its 16-gon answer (friction up to 1.9% short of the cone's, slip direction up to 11.25 "
            "degrees off)"
        )
    if isinstance(r, CompliantResult) and r.error_estimate is None:
        out.append(
            "fixed steps (--steps-per-period): the time-discretisation error is not estimated (first order in the "
            "step; 1.5e-3 to 5e-3 relative at 120 steps per contact period in studies/fidelity/README.md); "
            "--tolerance refines the steps until it is met"
        )
    elif isinstance(r, CompliantResult) and not r.error_estimate <= r.tolerance:
        out.append(
            f"the compliant rung did not meet its tolerance: error estimate {r.error_estimate:.3g} > {r.tolerance:g} "
            f"at {r.steps_per_period:.4g} steps per contact period ({r.integrator}; the finest run is reported)"
        )
    if isinstance(r, CompliantResult):
        if r.recontacting:
            out.append(
                f"contacts {', '.join(names[i] for i in r.recontacting)} head back to the ground after releasing: "
                "a secondary impact follows that is not included"
            )
        if r.status is CompliantStatus.TIMEOUT:
            out.append(f"the integration stopped at its time limit ({r.duration:.3g} s) with a contact still loaded")
    if isinstance(r, SequentialResult) and r.end >= result.settings.max_time * (1 - 1e-12):
        out.append(f"the sequential run stopped at its time limit ({r.end:.3g} s) with a contact still resting or "
                   "approaching the ground: its impulses are counted up to then")
    return out


def _runs_apart_warning(r: LandingResult) -> str:
    """Why the step halving of a whole landing stopped unmet (:func:`runs_apart`): its runs'
    final angles did not approach each other while their impulses agreed; each comparison's
    figures."""
    last = r.halving[-2:]
    angles = ", then ".join(f"{a:.3g} (steps {hc:.3g} and {hf:.3g} s)" for hc, hf, _, _, a in last)
    peaks = " and ".join(f"{p:.2g}" for _, _, p, _, _ in last)
    totals = " and ".join(f"{t:.2g}" for _, _, _, t, _ in last)
    return (
        f"the landing's final angles did not converge, and the step halving stopped: successive runs ended "
        f"{angles} apart (relative; tolerance {r.tolerance:g}), not approaching each other as the step shrinks, "
        f"while their peak impulses differed by {peaks} and their total impulses by {totals}. The motion after "
        "the impacts (a tumbling flight, say) amplifies any small difference beyond what a shorter step removes. "
        "The answer is the finest run: its impulses hold to those differences; its final angles, base position "
        "and velocity are one possible outcome, not a converged one"
    )


def _stalled_warning(r: LandingResult) -> str:
    """Why the step halving of a whole landing stopped unmet (:func:`stall_start`): the runs'
    differences from the comparison it measured the stall from, none of them below half of it."""
    since = r.halving[stall_start(r.halving):]
    shown = ", then ".join(f"{max(c[2:]):.2g} (steps {c[0]:.3g} and {c[1]:.3g} s)" for c in since)
    return (
        f"the landing did not converge to its tolerance {r.tolerance:g}, and the step halving stopped: successive "
        f"runs differed by {shown} (relative), not halving as the step shrank {since[0][1] / since[-1][1]:.3g}-fold, "
        "each halving costing twice the one before (which contact takes a load, or lands first, changes with the "
        f"step). The answer is the finest run, uncertain to about {r.error_estimate:.2g}"
    )


def _friction_hop(model: ModelFile, result: ImpactResult) -> dict[int, float]:
    """Contacts (declared index) that carry impulse under the friction rung yet leave faster than
    Newton's restitution asks, and by how much (m/s); empty for every other rung."""
    if result.model is not ImpactModel.FRICTION_RELAXED:
        return {}
    scene = model.scene
    scale = max(float(np.max(result.external, initial=0.0)), 1e-300)
    out = {}
    for i, v_n in zip(result.active, result.contact_velocity, strict=True):
        excess = float(v_n - scene.restitution * scene.speed)
        if result.external[i] > 1e-9 * scale and excess > 1e-9 * scene.speed:
            out[i] = excess
    return out


def result_record(model: ModelFile, result: Result, file: str) -> dict[str, Any]:
    """The JSON object ``footopt evaluate --json`` prints for one file (plain Python types).

    Keys of the contract (``MODEL_FORMAT.md``): ``external``, ``internal``, ``external_norm``,
    ``internal_norm``, ``model`` (what ran: decoupled, newton, lcp, friction, sequential or
    compliant), ``warnings`` (a list, empty when there is nothing to say). Extras for every model:
    ``file``, ``model_description`` (the law, in words), ``impact_model`` (= ``model``),
    ``impact_reason`` (why), ``scene`` (with ``terrain`` as [x, y] points and ``base_x``),
    ``contacts``, ``active`` (per contact: it hit, or touched down), ``joints``, ``joint_kinds``,
    ``internal_vector``, ``max_internal``, ``max_internal_joint``, ``velocities``, ``v_minus``,
    ``v_plus``, ``energy_before``, ``energy_after``, ``energy_gained``, ``reference``.
    Rigid rungs add ``tangential`` (friction impulse per contact, x), ``separating``,
    ``internal_torque``, ``split_unique``, ``pulling``. Sequential adds ``tangential`` (summed over
    its impacts) and ``modes`` (each contact's at its last impact; null without friction). Sequential and compliant add
    ``touchdown_time`` (s after the first touchdown, per contact; null if it never touches) and
    ``touchdown_order`` (contact names); compliant also ``status``, ``recontacting``, ``law``,
    ``stiffness`` (N/m for the penalty law, 1/s^2 for the constraint law) and ``timestep`` (s).
    """
    tree, ref = model.tree, model.reference
    names = contact_names(tree)
    joints = joint_names(tree)
    active = set(result.active)
    mags = result.internal_magnitude
    name, description = rung(result)
    planar = model.space is PLANAR
    dims = 2 if planar else 3
    record: dict[str, Any] = {
        "file": file,
        "model": name,
        "model_description": description,
        "impact_model": name,
        "impact_reason": result.reason,
        "scene": _scene_record(model.scene, model.space),
        "contacts": list(names),
        "active": [i in active for i in range(len(names))],
        "external": _floats(result.external),
        "joints": list(joints),
        "joint_kinds": [b.joint.value for b in tree.bodies[1:]],
        "internal": _floats(mags),
        "internal_vector": [_floats(row[:dims]) for row in result.internal],
        "external_norm": _f(result.external_norm),
        "internal_norm": _f(result.internal_norm),
        "max_internal": _f(result.max_internal),
        "max_internal_joint": joints[int(np.argmax(mags))] if mags.size else None,
        "velocities": [name for name, _ in velocity_names(tree, model.space)],
        "v_minus": _floats(result.v_minus),
        "v_plus": _floats(result.v_plus),
        "energy_before": _f(result.energy_before),
        "energy_after": _f(result.energy_after),
        "energy_gained": energy_gained(result),
        "warnings": list(warnings(model, result)),
    }
    if not planar:
        record["support_margin"] = _f(foot_support_margin(model))
    if isinstance(result, ImpactResult):
        record |= {
            "tangential": _tangential(result.tangential),
            "modes": None if result.modes is None else [m.value for m in result.modes],
            "separating": [names[i] for i in result.separating],
            "internal_torque": (
                [] if not len(joints)
                else _floats(result.internal_torque[:, 2]) if planar
                else [_floats(row) for row in result.internal_torque]
            ),
            "split_unique": bool(result.split_unique),
            "pulling": [names[i] for i in result.pulling],
        }
    else:
        record |= {
            "touchdown_time": [None if math.isnan(t) else _f(t) for t in result.touchdown_time],
            "touchdown_order": [names[i] for i in result.touchdown_order],
        }
        r = result.result
        if isinstance(r, LandingResult):
            record |= _landing_record(r)
        if isinstance(r, SequentialResult) and r.tangential is not None:
            record |= {
                "tangential": _tangential(r.tangential),
                "modes": None if r.modes is None else [m.value for m in r.modes],
            }
        if isinstance(r, CompliantResult):
            record |= {
                "status": r.status.value,
                "recontacting": [names[i] for i in r.recontacting],
                "law": r.law.value,
                "stiffness": _f(result.settings.stiffness),
                "timestep": _f(r.timestep),
                "steps_per_period": None if r.steps_per_period is None else _f(r.steps_per_period),
                "integrator": r.integrator,
                "error_estimate": None if r.error_estimate is None or not math.isfinite(r.error_estimate)
                else _f(r.error_estimate),
                "tolerance": None if r.tolerance is None else _f(r.tolerance),
            }
    record["reference"] = (
        None
        if ref is None
        else {
            "source": ref.source,
            "external": None if ref.external is None else [_opt(v) for v in ref.external],
            "internal": None if ref.internal is None else [_opt(v) for v in ref.internal],
            "external_norm": _opt(ref.external_norm),
            "internal_norm": _opt(ref.internal_norm),
            "note": ref.note,
        }
    )
    return record


def _landing_record(r: LandingResult) -> dict[str, Any]:
    """The contract's ``events`` and ``landing`` keys (``MODEL_FORMAT.md``), with ``tangential``
    and ``modes``-free first-impact keys, and the accuracy (``error_estimate``, ``tolerance``,
    ``integrator``)."""
    events = [
        {
            "t": _f(e.time),
            "kind": e.kind,
            "external": _floats(e.external),
            "tangential": _tangential(e.tangential),
            "internal": _floats(e.internal_magnitude),
            "stop": _floats(e.stop),
            **({"jam": True} if e.jam else {}),  # an impulsive jam (Painleve's paradox), only where one is
        }
        for e in r.events
    ]
    settled = None if r.settled_at is None else _f(r.settled_at)
    return {
        "tangential": _tangential(r.tangential),
        "events": events,
        "landing": {
            "peak_external_norm": _f(r.peak_external_norm),
            "peak_internal_norm": _f(r.peak_internal_norm),
            "peak_max_internal": _f(r.peak_max_internal),
            "total_external": _floats(r.total_external),
            "settled_at": settled,
            "final_angles": _floats(r.final_angles),
            "final_base": _floats(r.final_base),
            "final_velocity": _floats(r.v_final),
            "energy_absorbed": _f(r.energy_absorbed),
            "duration": _f(r.duration),
            "step": _f(r.step),
        },
        "error_estimate": None if r.error_estimate is None or not math.isfinite(r.error_estimate) else _f(r.error_estimate),
        "tolerance": _f(r.tolerance) if r.tolerance is not None else None,
        "integrator": r.integrator,
    }


def _cell(x: Any) -> str:
    """A table cell: a number, or [x, z] for a spatial tangential value."""
    a = np.asarray(x, dtype=float)
    return _num(float(a)) if a.ndim == 0 else "[" + ", ".join(_num(float(v)).strip() for v in a) + "]"


def foot_support_margin(model: ModelFile) -> float:
    """A spatial model's support margin at touchdown (m, ``impulse_core.model.support``): the
    whole tree's centre of mass over the declared contacts' convex hull, on the ground (x, z)."""
    geometry = touchdown_geometry(model.tree, model.space)
    masses = np.array([b.mass for b in model.tree.bodies])
    com = masses @ geometry.coms / masses.sum()
    return support_margin(geometry.contacts[:, [0, 2]], com[[0, 2]])


def _vec(xs: tuple[float, ...]) -> str:
    return "[" + ", ".join(f"{x:g}" for x in xs) + "]"


def _scene_record(scene: Scene, space: Space = PLANAR) -> dict[str, Any]:
    planar = space is PLANAR
    return {
        "speed": _f(scene.speed),
        "velocity": _floats(scene.velocity[:2] if planar else scene.velocity),
        "angular_velocity": _f(scene.angular_velocity) if planar else _floats(scene.angular_velocity_3d),
        "restitution": _f(scene.restitution),
        "friction": _f(scene.friction),
        "contacts": scene.selection.value,
        "contact_tolerance": _f(scene.contact_tolerance),
        "terrain": [[_f(x), _f(y)] for x, y in scene.terrain.points],
        "base_x": _f(scene.base_x),
        "gravity": _f(scene.gravity),
        "duration": None if scene.duration is None else _f(scene.duration),
    } | ({} if planar else {
        "base_z": _f(scene.base_z),
        "heightfield": None if scene.heightfield is None else {
            "x": _floats(scene.heightfield.x),
            "z": _floats(scene.heightfield.z),
            "heights": [_floats(row) for row in scene.heightfield.heights],
        },
    })


def format_report(model: ModelFile, result: Result, file: str) -> str:
    """A plain-text report of one evaluation: contacts, (time-domain models) touchdowns, joints,
    norms, velocities, energy, warnings, with the file's reference values beside ours where it
    gives them."""
    lines = _header_lines(model, result, file) + _external_lines(model, result)
    if not isinstance(result, ImpactResult):
        lines += _touchdown_lines(model, result)
    if joint_names(model.tree):
        lines += _internal_lines(model, result)
    lines += _norm_lines(model, result) + _velocity_lines(model, result)
    if not isinstance(result, ImpactResult) and isinstance(result.result, LandingResult):
        lines += _landing_lines(model, result.result)
    lines += [f"warning: {w}" for w in warnings(model, result)]
    return "\n".join(lines) + "\n"


def _header_lines(model: ModelFile, result: Result, file: str) -> list[str]:
    """What ran and why, the scene, the ground, the tree."""
    tree, scene, ref = model.tree, model.scene, model.reference
    rigid = isinstance(result, ImpactResult)
    name, description = rung(result)
    selection = (
        "the geometry decides (touchdowns below)"
        if not rigid
        else "all declared contacts hit"
        if scene.selection is ContactSelection.ALL
        else f"lowest (contacts within {scene.contact_tolerance:g} m of the lowest hit)"
    )
    approach = (
        ""
        if scene.straight_down
        else f", {scene.velocity_x:g} m/s along x, turning {scene.angular_velocity:g} rad/s"
        if not scene.out_of_plane
        else f", velocity {_vec(scene.velocity)} m/s, angular velocity {_vec(scene.angular_velocity_3d)} rad/s"
    )
    lines = [
        f"== {file} ==",
        f"model:   {name}: {description}",
        f"why:     {result.reason}",
        f"scene:   speed {scene.speed:g} m/s down{approach}, restitution e = {scene.restitution:g}, "
        f"friction {scene.friction:g}, contacts: {selection}",
    ]
    if scene.heightfield is not None:
        hf = scene.heightfield
        lines.append(
            f"ground:  heightfield {len(hf.x)} x {len(hf.z)} points, x in [{hf.x[0]:g}, {hf.x[-1]:g}] m, "
            f"z in [{hf.z[0]:g}, {hf.z[-1]:g}] m, heights {hf.level:g} to "
            f"{max(v for row in hf.heights for v in row):g} m; base origin at x = {scene.base_x:g} m, "
            f"z = {scene.base_z:g} m"
        )
    elif scene.terrain != FLAT or scene.base_x != 0.0 or scene.base_z != 0.0:
        points = ", ".join(f"[{x:g}, {y:g}]" for x, y in scene.terrain.points)
        where = f"x = {scene.base_x:g} m" + (f", z = {scene.base_z:g} m" if scene.base_z != 0.0 else "")
        lines.append(f"ground:  terrain [{points}] (m), base origin at {where}")
    verb = "hit" if rigid else "touch down"
    if model.space is not PLANAR:
        margin = 1e3 * foot_support_margin(model)
        lines.append(f"support: margin {margin:+.1f} mm (the centre of mass inside the contacts' hull on the ground; < 0: outside)")
    n_declared = len(contact_names(tree))
    lines.append(
        f"tree:    {_count(tree.n_bodies, 'body', 'bodies')}, {len(set(result.active))} of {n_declared} declared "
        f"contacts {verb}"
    )
    if ref is not None and (ref.source or ref.note):
        lines.append("reference: " + "; ".join(s for s in (ref.source, ref.note) if s))
    return lines


def _external_lines(model: ModelFile, result: Result) -> list[str]:
    """The contacts' impulses (and with friction their tangential impulses and slip)."""
    names, ref, active = contact_names(model.tree), model.reference, set(result.active)
    rigid = isinstance(result, ImpactResult)
    show_ref = ref is not None and ref.external is not None
    friction = rigid and result.tangent_velocity is not None
    slip = dict(zip(result.active, result.tangent_velocity, strict=True)) if friction else {}
    headers = ["contact", "touches", "impulse [N s]"] + (["tangential [N s]", "slip after [m/s]"] if friction else [])
    headers += ["reference [N s]", "diff"] if show_ref else []
    rows = []
    for i, cname in enumerate(names):
        row = [cname, "yes" if i in active else "no", _num(result.external[i])]
        row += [_cell(result.tangential[i]), _cell(slip[i]) if i in slip else "-"] if friction else []
        if show_ref:
            assert ref is not None and ref.external is not None
            row += _ref_cells(result.external[i], ref.external[i])
        rows.append(row)
    along = "along +x" if model.space is PLANAR else "[x, z]"
    if not model.scene.ground_is_flat:  # the first instant on uneven ground: each contact's own tangents
        along = "along the ground's tangent" if model.space is PLANAR else "[t_x, t_z] of the ground"
    kind = f"normal and tangential {along}" if friction else "normal" if rigid else "along the local ground normal"
    return ["", f"External impulses ({kind}, on the contacts)"] + _table(headers, rows)


def _touchdown_lines(model: ModelFile, result: TimeDomainResult) -> list[str]:
    """When each contact touched down (time-domain models), and the integration's summary."""
    names = contact_names(model.tree)
    order = {c: k + 1 for k, c in enumerate(result.touchdown_order)}
    rows = [
        [cname, "-" if math.isnan(t) else f"{1e3 * t:.3f}", str(order[i]) if i in order else "-"]
        for i, (cname, t) in enumerate(zip(names, result.touchdown_time, strict=True))
    ]
    lines = ["", "Touchdowns (time after the first one)"] + _table(["contact", "touchdown [ms]", "order"], rows)
    r = result.result
    if isinstance(r, CompliantResult):
        unit = "N/m" if r.law is ContactLaw.PENALTY else "1/s^2"
        lines.append(
            f"integration: {r.status.value} after {1e3 * r.duration:.3f} ms, {r.n_steps} {r.integrator} contact "
            f"steps of {'' if r.integrator == 'euler' else 'on average '}{r.timestep:.3g} s and {r.n_flight_steps} "
            f"flight steps; stiffness {result.settings.stiffness:g} {unit}"
        )
    return lines


def _internal_lines(model: ModelFile, result: Result) -> list[str]:
    """The joints' impulses (components and magnitude), beside the reference's."""
    tree, ref, joints = model.tree, model.reference, joint_names(model.tree)
    show_ref = ref is not None and ref.internal is not None
    dims = 2 if model.space is PLANAR else 3
    headers = ["joint (child)", "kind"] + [f"{a} [N s]" for a in "xyz"[:dims]] + ["|impulse| [N s]"]
    headers += ["reference [N s]", "diff"] if show_ref else []
    rows = []
    for j, jname in enumerate(joints):
        components = [_num(x) for x in result.internal[j, :dims]]
        row = [jname, tree.bodies[j + 1].joint.value, *components, _num(result.internal_magnitude[j])]
        if show_ref:
            assert ref is not None and ref.internal is not None
            row += _ref_cells(result.internal_magnitude[j], ref.internal[j])
        rows.append(row)
    return ["", "Internal impulses (through each joint, parent onto child)"] + _table(headers, rows)


def _norm_lines(model: ModelFile, result: Result) -> list[str]:
    """Both norms (beside the reference's) and the largest joint impulse."""
    ref, joints = model.reference, joint_names(model.tree)
    headers = ["norm", "ours [N s]"] + (["reference [N s]", "diff"] if ref is not None else [])
    rows = []
    for key in ("external_norm", "internal_norm"):
        ours = getattr(result, key)
        rows.append([key, _num(ours)] + (_ref_cells(ours, getattr(ref, key)) if ref is not None else []))
    lines = [""] + _table(headers, rows)
    if joints:
        j = int(np.argmax(result.internal_magnitude))
        lines.append(f"largest joint impulse: {result.max_internal:.4f} N s, through the joint of {joints[j]}")
    return lines


def _velocity_lines(model: ModelFile, result: Result) -> list[str]:
    """The generalized velocities before and after, and the kinetic energy."""
    rows = [
        [f"{vname} [{unit}]", _num(before), _num(after)]
        for (vname, unit), before, after in zip(
            velocity_names(model.tree, model.space), result.v_minus, result.v_plus, strict=True
        )
    ]
    before, after = result.energy_before, result.energy_after
    change = (
        f"lost {100 * (before - after) / before:.1f}%"
        if after <= before
        else f"energy gained: +{100 * (after - before) / before:.1f}%"
    )
    return ["", "Velocities"] + _table(["velocity", "before", "after"], rows) + [
        "",
        f"kinetic energy [J]: before {before:.4f}, after {after:.4f} ({change})",
    ]


#: Events listed in the text report of a landing (the JSON has them all).
SHOWN_EVENTS = 12


def _landing_lines(model: ModelFile, r: LandingResult) -> list[str]:
    """The whole landing in the text report (the tables above are its first impact)."""
    names, tree = contact_names(model.tree), model.tree
    rows = [
        [f"{1e3 * e.time:.3f}", e.kind + (" (jam)" if e.jam else ""), _num(e.external_norm), _num(e.internal_norm)]
        + [_num(x) for x in e.external]
        for e in r.events[:SHOWN_EVENTS]
    ]
    headers = ["t [ms]", "kind", "external_norm", "internal_norm"] + [f"{n} [N s]" for n in names]
    more = len(r.events) - SHOWN_EVENTS
    settled = "not within the landing" if r.settled_at is None else f"at {1e3 * r.settled_at:.3f} ms"
    base = [f"{tree.bodies[0].name} (absolute)"] if r.space == "planar" else [
        f"{tree.bodies[0].name} turn {axis}" for axis in ("x", "y", "z")]
    angle_names = base + [b.name for b in tree.bodies[1:]]
    estimate = "not estimated" if r.error_estimate is None else f"{r.error_estimate:.2g}"
    return [
        "",
        f"Whole landing over {1e3 * r.duration:g} ms: {len(r.events)} impacts (the tables above are the first)",
        *_table(headers, rows),
        *([f"... {more} more events (footopt evaluate --json lists them all)"] if more > 0 else []),
        f"peak external_norm {r.peak_external_norm:.4f} N s, peak internal_norm {r.peak_internal_norm:.4f} N s, "
        f"largest joint impulse {r.peak_max_internal:.4f} N s",
        "total normal impulse over the landing [N s]: "
        + ", ".join(f"{n} {_num(x)}" for n, x in zip(names, r.total_external, strict=True)),
        f"settled (every velocity below 1e-3) {settled}; energy absorbed {100 * r.energy_absorbed:.1f}% of "
        "the touchdown kinetic and spring energy plus gravity's work",
        "final angles [rad]: " + ", ".join(f"{n} {a:.4f}" for n, a in zip(angle_names, r.final_angles, strict=True)),
        "final base origin [m]: " + ", ".join(f"{n} {x:.4f}" for n, x in zip("xyz", r.final_base)),
        f"accuracy: error estimate {estimate} (tolerance {r.tolerance:g}), "
        + {"rk4": "Runge-Kutta 4", "radau": "Radau IIA (order 3)"}.get(r.integrator, "implicit (ROS2, order 2)")
        + f" step {r.step:.3g} s"
        + f", steps {STEP_CODE_NAMES.get(r.step_code, r.step_code)}",
        *([("integrator: Radau IIA from the first step" if r.integrator == "radau" else
            "integrator: Runge-Kutta 4 at its stable step") + ", since the implicit run auto chose first gave way: "
           f"{r.integrator_switch}"] if r.integrator_switch else []),
    ]


#: How the text report names the code a landing's steps ran on (:attr:`LandingResult.step_code`).
STEP_CODE_NAMES = {"c": "as C from the compile cache", "vm": "on CasADi's virtual machine", "numpy": "in numpy"}


def _table(headers: list[str], rows: list[list[str]]) -> list[str]:
    """Aligned plain-text columns: the first column left-aligned, the others right-aligned."""
    widths = [max(len(r[c]) for r in [headers, *rows]) for c in range(len(headers))]

    def line(cells: list[str]) -> str:
        parts = [cells[0].ljust(widths[0])] + [cell.rjust(w) for cell, w in zip(cells[1:], widths[1:], strict=True)]
        return "  ".join(parts).rstrip()

    return [line(headers)] + [line(r) for r in rows]


def _ref_cells(ours: float, ref: float | None) -> list[str]:
    if ref is None:
        return ["-", ""]
    diff = f"{100 * (ours - ref) / abs(ref):+.1f}%" if ref != 0 else ""
    return [_num(ref), diff]


def _count(n: int, one: str, many: str) -> str:
    return f"{n} {one if n == 1 else many}"


def _num(x: float) -> str:
    return f"{round(float(x), 4) + 0.0:.4f}"  # no "-0.0000"


def _f(x: float) -> float:
    return float(x) + 0.0  # a plain float, and -0.0 written as 0.0


def _floats(a: Any) -> list[float]:
    return [_f(x) for x in np.asarray(a, dtype=float).ravel()]


def _tangential(a: Any) -> list[float] | list[list[float]]:
    """Tangential impulses per contact: a number along +x in the plane, [t_x, t_z] in space."""
    a = np.asarray(a, dtype=float)
    return [_floats(row) for row in a] if a.ndim == 2 else _floats(a)


def _opt(x: float | None) -> float | None:
    return None if x is None else _f(x)


__all__ = [
    "Result",
    "contact_names",
    "energy_gained",
    "format_report",
    "is_finite",
    "joint_names",
    "result_record",
    "rung",
    "velocity_names",
    "warnings",
]
