"""A description's joint laws (stops, dampers, springs) on an imported leg's joints
(docs/MODEL_FORMAT.md, "Import").

The description counts a joint's coordinate q from its own zero (MJCF: q = ``ref`` at the pose the
links are placed in; URDF: 0); footopt counts its joint angle from the rods' geometry. An imported
rod's joint angle at q is ``zero + sign (q - ref)``: ``zero`` its angle at the placed pose (planar:
the in-plane angle between the rods; spatial: 0, ``rpy`` holds the rest), ``sign`` -1 for a planar
joint turning about -z. Limits, the spring's rest and ``--angle`` all go through that map; damping
and stiffness are per radian either way. Laws footopt has no key for are named in one warning.
"""

from __future__ import annotations

from collections.abc import Sequence

from impulse_core.errors import ModelError
from impulse_core.model.joints import FREE, JointLaw
from impulse_core.model.tree import Tree
from optimizer.imports.description import Description, Dynamics, Joint


def footopt_angle(zero: float, flipped: bool, dynamics: Dynamics, q: float) -> float:
    """footopt's joint angle when the description's coordinate is ``q`` (see the module docstring)."""
    return zero + (-1.0 if flipped else 1.0) * (q - dynamics.ref)


def imported_laws(
    desc: Description, joints: Sequence[Joint], flipped: Sequence[bool], zero: Tree, angles: dict[str, float]
) -> tuple[tuple[JointLaw, ...], tuple[str, ...]]:
    """Each body's joint law (the base's free) from ``joints`` (the chain's, root to ankle) and the
    warnings (at most one line: the laws left out), for the tree ``zero`` at the placed pose and
    the touchdown ``angles`` (joint name -> the description's q).

    Raises:
        ConfigError: naming the joint's field (limits not lower < upper, a negative damping) or
            ``--angle`` (a touchdown outside a joint's limits).
    """
    laws: list[JointLaw] = [FREE]
    left: dict[str, list[str]] = {}
    field = "limit" if desc.format == "URDF" else "range"
    for k, joint in enumerate(joints, start=1):
        d = joint.dynamics
        to = lambda q: footopt_angle(zero.bodies[k].angle, flipped[k], d, q)  # noqa: E731
        limits = None
        if d.limits is not None:
            lo, hi = d.limits
            if not lo < hi:
                raise desc.error(f"joint '{joint.name}'.{field}", f"lower {lo!r} must be below upper {hi!r} (rad); "
                                 "footopt's stops need lo < hi (--no-joint-laws leaves every law out)")
            q = angles.get(joint.name, d.ref)
            if not lo <= q <= hi:
                raise desc.error("--angle", f"joint '{joint.name}' at {q:.6g} rad lies outside its {field} "
                                 f"[{lo:.6g}, {hi:.6g}] rad: give a touchdown angle within it (--angle "
                                 f"{joint.name}=RAD) or pass --no-joint-laws")
            limits = tuple(sorted((to(lo), to(hi))))
        law = JointLaw(stiffness=d.stiffness, damping=d.damping, rest=to(d.springref) if d.stiffness else None,
                       limits=limits)
        try:
            law.validate(f"joint '{joint.name}'")
        except ModelError as e:
            where, _, message = str(e).partition(": ")
            raise desc.error(where, message) from None
        laws.append(law)
        for name, value in d.unsupported:
            left.setdefault(name, []).append(f"{joint.name} {value:.6g}")
    warnings = ()
    if left:
        warnings = ("Warning: not imported (footopt has no such joint law): "
                    + "; ".join(f"{name} ({', '.join(v)})" for name, v in left.items()) + ".",)
    return (tuple(laws) if any(law != FREE for law in laws) else ()), warnings


def laws_summary(
    fmt: str, names: Sequence[str], laws: Sequence[JointLaw], imported: bool, warnings: Sequence[str]
) -> list[str]:
    """The summary's lines on joint laws: each joint's, in footopt's angles, then the warnings."""
    if not imported:
        return ["Joint laws: left out (--no-joint-laws): the joints are free. Motors are not imported."]
    lines = ["Joint laws (angles as footopt counts them; motors are not imported"
             + ("; URDF has no joint springs" if fmt == "URDF" else "") + "):"]
    for name, law in zip(names, laws[1:] if laws else [FREE] * len(names), strict=True):
        parts = ([f"limits [{law.limits[0]:.6g}, {law.limits[1]:.6g}] rad"] if law.limits else []) + (
            [f"damping {law.damping:.6g} N m s/rad"] if law.damping else []) + (
            [f"stiffness {law.stiffness:.6g} N m/rad about {law.rest:.6g} rad"] if law.stiffness else [])
        lines.append(f"  {name}: " + (", ".join(parts) if parts else "free"))
    return lines + list(warnings)


__all__ = ["footopt_angle", "imported_laws", "laws_summary"]
