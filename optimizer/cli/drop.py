"""``footopt drop``: a design dropped in MuJoCo, its impulses beside footopt's. Registered in
:data:`optimizer.cli.main.SUBCOMMANDS`. On flat ground the model dropped is ``footopt export``'s
MJCF with contact spheres and the ground added (``mujoco_bridge.exported_for_drop``), and with the
model's stops as stiff limits rebounding with their ``stop_restitution``, tuned for the drop's own
time step (``export.stop_parameters``; springs and dampers left out: they give no impulse). A
spatial model drops the same way, with friction (elliptic cones beside footopt's circular cone)
and on a ``scene.heightfield`` (each contact on the heightfield's tangent plane at its touchdown
point, ``mujoco_bridge.tangent_planes``; footopt's side the sequential rigid model ``auto`` picks).

MuJoCo's contacts are soft: the drop uses its direct contact parameters (``solref = (-k, -b)``,
a constant impedance; :mod:`optimizer.validation.mujoco_bridge`) with footopt's compliant rung's
law of the same stiffness, its time step and its impact window, so that the three columns are the
rigid answer (what ``footopt evaluate`` reports), the compliant rung and MuJoCo. The two soft
ones agree to MuJoCo's integration; both approach the rigid one as the stiffness grows.

Exit status: 0 shown; 2 a bad file or option, or MuJoCo not installed (one line on stderr).
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace

import numpy as np

from impulse_core.errors import FootoptError, NumericalError
from impulse_core.evaluate import pre_impact_velocity
from impulse_core.kinematics.spatial import PLANAR, SPATIAL, Space
from impulse_core.model.joints import JointLaw
from impulse_core.timedomain.compliant import STIFFNESS_RANGE, CompliantSettings, ContactLaw, simulate_impact
from optimizer.cli.status import EXIT_FAILURE, EXIT_OK, EXIT_USAGE, warn
from optimizer.cli.status import error as _error
from optimizer.report.text import contact_names, joint_names

#: MuJoCo contact stiffness footopt drops with by default (1/s^2, mass-normalised): stiff enough
#: for about 1 % from the rigid answer on the paper's feet (studies/fidelity/).
DEFAULT_STIFFNESS = 1e8
#: With friction a drop lasts this many compliant impact windows (sliding contacts stay longer).
FRICTION_WINDOW = 3


def add_drop(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "drop",
        help="drop a design in MuJoCo and print its impulses beside footopt's",
        description=(
            "Drop a model file's leg in MuJoCo with the scene's approach (speed or velocity, angular velocity), "
            "soft contacts of the given stiffness (with scene.friction: Coulomb friction on elliptic cones; on a "
            "spatial scene.heightfield: its tangent plane under each contact), and print each contact's normal "
            "(and tangential) impulse and each joint's impulse: footopt's answer (the model footopt evaluate "
            "picks), footopt's compliant rung with the same contact law, and MuJoCo's, with the contact settings "
            "used. The joints' stops are stiff limits rebounding with their "
            "stop_restitution at the drop's step. Needs the mujoco package (pip install mujoco)."
        ),
    )
    p.add_argument("model", metavar="MODEL.yaml", help="a model file (a design from a run folder's designs/)")
    p.add_argument("--stiffness", type=float, default=DEFAULT_STIFFNESS,
                   help=f"MuJoCo's contact stiffness, 1/s^2 (solref -k; default {DEFAULT_STIFFNESS:g})")
    p.add_argument("--json", action="store_true", help="one JSON object instead of the table")
    p.set_defaults(run=run_drop)


def run_drop(args: argparse.Namespace) -> int:
    """``footopt drop``."""
    from optimizer.config.model_file import load_model_file
    from optimizer.evaluation.model_choice import evaluate_landing

    try:
        import mujoco  # noqa: F401 - only to say clearly when it is missing
    except ImportError:
        _error("footopt drop", "needs MuJoCo: pip install mujoco")
        return EXIT_USAGE
    lo, hi = STIFFNESS_RANGE
    if not lo <= args.stiffness <= hi:
        _error("--stiffness", f"must be in [{lo:g}, {hi:g}] (1/s^2), got {args.stiffness}")
        return EXIT_USAGE
    try:
        model = load_model_file(args.model)
        if model.scene.duration is not None:
            warn(f"{args.model}: scene.duration is left out: the drop compares the first impact")
        scene = replace(model.scene, duration=None)  # the first impact
        rigid = evaluate_landing(model.tree, scene, "auto", space=model.space)
        record = drop_record(model.tree, scene, args.stiffness, rigid, model.space, model.joints)
    except NumericalError as e:
        _error(args.model, f"numerical failure: {e}")
        return EXIT_FAILURE
    except FootoptError as e:
        _error(args.model, str(e))
        return EXIT_USAGE
    print(json.dumps(record) if args.json else format_drop(args.model, record))
    return EXIT_OK


def stops_only(joints: tuple[JointLaw, ...]) -> tuple[JointLaw, ...]:
    """The joint laws' stops and their restitution, without springs and dampers (no impulse)."""
    return tuple(JointLaw(limits=law.limits, stop_restitution=law.stop_restitution) for law in joints)


def drop_record(tree, scene, stiffness: float, rigid, space: Space = PLANAR,  # type: ignore[no-untyped-def]
                joints: tuple[JointLaw, ...] = ()) -> dict:
    """The three answers and the settings, as JSON-able data; ``joints``: the model's joint laws,
    whose stops MuJoCo's model holds (:func:`stops_only`, tuned for the drop's step)."""
    from optimizer.results.export import stop_parameters, to_mjcf
    from optimizer.validation.mujoco_bridge import drop, drop_spatial

    settings = CompliantSettings(law=ContactLaw.CONSTRAINT, stiffness=stiffness, gravity=scene.gravity)
    frictional = scene.friction > 0  # the compliant rung is frictionless: no column then
    stops = stops_only(joints)
    soft = simulate_impact(tree, replace(scene, friction=0.0), settings, space=space)
    steps = int(round(soft.duration / soft.timestep)) * (FRICTION_WINDOW if frictional else 1)
    if space is SPATIAL:
        mj = drop_spatial(tree, scene, settings, steps, soft.timestep, joints=stops)
    else:
        exported = to_mjcf(tree, scene, joints=stops, stop_timestep=soft.timestep)  # footopt export's MJCF
        mj = drop(tree, scene, settings, steps, soft.timestep, v_minus=pre_impact_velocity(tree.topology(), scene),
                  exported=exported if scene.terrain.is_flat else None)
    b = float(np.mean(soft.damping))
    record = {
        "contacts": list(contact_names(tree)),
        "joints": list(joint_names(tree)),
        "external": {"footopt": _floats(rigid.external), "compliant": None if frictional else _floats(soft.external),
                     "mujoco": _floats(mj.external)},
        "internal": {"footopt": _floats(rigid.internal_magnitude),
                     "compliant": None if frictional else _floats(soft.internal_magnitude),
                     "mujoco": _floats(mj.internal_magnitude)},
        "settings": {"solref": [-stiffness, -b], "solimp_d": settings.impedance, "timestep": soft.timestep,
                     "steps": steps, "window": steps * soft.timestep, "gravity": scene.gravity,
                     "friction": scene.friction, "cone": "elliptic" if frictional else None,
                     "rigid_model": _model_name(rigid),
                     "condim": 3 if frictional else 1, "impratio": 1.0,
                     "mjcf": "footopt export's, with contact spheres and ground" if scene.terrain.is_flat
                     else "the bridge's (terrain)", "space": space.name,
                     "stops": {tree.bodies[i].name: [-k, -b] for i, law in enumerate(stops) if law.limits is not None
                               for k, b in [stop_parameters(law.stop_restitution, soft.timestep)]}
                     if scene.terrain.is_flat else {}},
    }
    if space is SPATIAL:
        uneven = scene.heightfield is not None and not scene.heightfield.is_flat
        record["settings"]["ground"] = ("the heightfield's tangent plane at each contact's touchdown point"
                                        if uneven else "flat")
        record["touchdown"] = {"point": _rows(mj.touchdown_point), "normal": _rows(mj.touchdown_normal)}
    if frictional:  # the ground's impulse on each contact along its ground tangents (flat: x, and z in space)
        ours = rigid.tangential if hasattr(rigid, "tangential") else rigid.result.tangential  # the sequential model's
        record["tangential"] = {"footopt": _rows(ours), "mujoco": _rows(mujoco_tangential(mj, space))}
    return record


def mujoco_tangential(mj, space: Space) -> np.ndarray:  # type: ignore[no-untyped-def]
    """MuJoCo's impulse on each contact along footopt's ground tangents (:func:`tangent_basis`) at
    the ground normal where it first touched (up where it never did): n_c in the plane, n_c x 2 in
    space."""
    from impulse_core.timedomain.events.point import tangent_basis

    d = mj.external_vector.shape[1]
    normal = np.zeros((len(mj.external), d))
    normal[:, 1] = 1.0
    if mj.touchdown_normal is not None:
        touched = ~np.isnan(mj.touchdown_normal[:, 0])
        normal[touched] = mj.touchdown_normal[touched, :d]
    along = np.einsum("kad,kd->ka", tangent_basis(normal), mj.external_vector)
    return along[:, 0] if space is PLANAR else along


def _model_name(result) -> str:  # type: ignore[no-untyped-def]
    model = getattr(result, "model", None) or getattr(result, "impact_model", "auto")
    return str(getattr(model, "value", model))


def _floats(x) -> list[float]:  # type: ignore[no-untyped-def]
    return [float(v) for v in np.asarray(x, dtype=float).ravel()]


def _rows(x) -> list:  # type: ignore[no-untyped-def]
    """Per contact: a number (plane) or a list (space: [x, z] tangents, 3D points; NaN as None)."""
    a = np.asarray(x, dtype=float)
    return [None if np.isnan(v) else float(v) for v in a] if a.ndim == 1 else \
        [[None if np.isnan(v) else float(v) for v in row] for row in a]


def format_drop(path: str, r: dict) -> str:
    """The table: one row per contact and per joint, the three answers side by side."""
    s = r["settings"]
    contact = ("frictionless (condim 1)" if not s["friction"]
               else f"friction {s['friction']:g} on elliptic cones (condim 3, impratio {s['impratio']:g})")
    lines = [f"{path} dropped in MuJoCo: solref ({s['solref'][0]:g}, {s['solref'][1]:.4g}), solimp d {s['solimp_d']:g}, "
             f"timestep {s['timestep']:.3g} s x {s['steps']} steps ({1e3 * s['window']:.3g} ms), {contact}",
             f"{'':<24}{'footopt (' + str(s['rigid_model']) + ')':>22}{'compliant':>14}{'MuJoCo':>14}"]
    if s.get("ground", "flat") != "flat":
        lines.insert(1, f"ground: {s['ground']} (footopt: {s['rigid_model']} on the heightfield)")
    if s.get("stops"):
        stops = ", ".join(f"{name} ({k:.4g}, {b:.4g})" for name, (k, b) in s["stops"].items())
        lines.insert(1, f"stops as limits, solreflimit {stops} (rebounding with each stop's restitution)")
    kinds = [("external", r["contacts"]), ("tangential", r["contacts"]), ("internal", r["joints"])]
    for kind, names in kinds:
        if kind not in r:
            continue
        lines.append(f"{kind} impulse (N s)" + ("  (compliant rung: frictionless, not shown)" if kind == "tangential" else ""))
        for k, name in enumerate(names):
            cells = [_cell(r[kind].get(who), k) for who in ("footopt", "compliant", "mujoco")]
            lines.append(f"  {name:<22}{cells[0]:>22}{cells[1]:>14}{cells[2]:>14}")
    return "\n".join(lines)


def _cell(values: list | None, k: int) -> str:
    if values is None:
        return "-"
    v = values[k]
    return "[" + ", ".join(f"{c:.4g}" for c in v) + "]" if isinstance(v, list) else f"{v:.6g}"


__all__ = ["DEFAULT_STIFFNESS", "add_drop", "drop_record", "format_drop", "run_drop", "stops_only"]
