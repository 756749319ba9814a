"""``footopt import``: the leg above the ankle from a URDF or MJCF file, as a model file.
Registered in :data:`optimizer.cli.main.SUBCOMMANDS`; the work is in :mod:`optimizer.imports`.

Exit status as the rest of ``footopt``: 0 written; 2 a bad description, link or option, or an OUT
that exists (without ``--force``), one line on stderr naming the option, link or joint.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from impulse_core.errors import FootoptError
from optimizer.cli.export import _write
from optimizer.cli.status import EXIT_OK, EXIT_USAGE
from optimizer.cli.status import error as _error


def add_import(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "import",
        help="the leg above the ankle from a URDF or MJCF file, as a model file",
        description=(
            "Read a robot description (URDF, or MJCF compiled by MuJoCo) and write the leg from --root (the "
            "floating base) down to --ankle as a footopt model file: one rod per link, fixed joints merged into "
            "their parent, each revolute joint as in the description, a contact at the ankle (or at --foot). "
            "Planar when every joint axis of the chain is parallel, else spatial. Each rod carries its link's "
            "mass, centre of mass and inertia (the file's comments and this command's output say where "
            "anything is approximated), and each joint's stops, damper and spring "
            "(--no-joint-laws: none). See MODEL_FORMAT.md, 'Import'."
        ),
    )
    p.add_argument("description", metavar="ROBOT", help="a URDF (.urdf) or MJCF (.xml) file")
    p.add_argument("--root", required=True, metavar="LINK", help="the first link of the leg (the floating base)")
    p.add_argument("--ankle", required=True, metavar="LINK", help="the link where a foot attaches (the chain's end)")
    p.add_argument("--foot", metavar="NAME", default=None,
                   help="the contact point: a link welded to the ankle, or an MJCF site or geom on it "
                   "(default: the ankle link's origin)")
    p.add_argument("--space", choices=("auto", "planar", "spatial"), default="auto",
                   help="auto (default): planar when every joint axis is parallel, else spatial")
    p.add_argument("--angle", action="append", default=[], metavar="JOINT=RAD",
                   help="the touchdown posture: this joint's angle in rad, as the description counts it "
                   "(repeat for several joints; default: every joint at 0)")
    p.add_argument("--com-on-rods", action="store_true",
                   help="planar: move each centre of mass onto its rod (the inertia taken about that point): the former "
                   "approximation, for comparison; default: carried exactly (com_offset)")
    p.add_argument("--no-joint-laws", dest="joint_laws", action="store_false",
                   help="leave out the joints' stops, dampers and springs (default: imported, as footopt's "
                   "limits, damping, stiffness and rest; laws it has no key for are named in a warning)")
    p.add_argument("-o", "--out", metavar="OUT", required=True, help="the model file to write ('-': standard output)")
    p.add_argument("--force", action="store_true", help="replace OUT if it exists")
    p.set_defaults(run=run_import)


def run_import(args: argparse.Namespace) -> int:
    """``footopt import``."""
    from optimizer.config.model_file import format_model_file
    from optimizer.imports.read import read_description
    from optimizer.imports.leg import import_leg

    if args.out != "-" and Path(args.out).exists() and not args.force:
        _error(args.out, "already exists; not overwriting it (pass --force to replace it)")
        return EXIT_USAGE
    angles = _angles(args.angle)
    if angles is None:
        return EXIT_USAGE
    try:
        leg = import_leg(read_description(Path(args.description)), args.root, args.ankle, args.foot, args.space, angles,
                         args.joint_laws, args.com_on_rods)
    except FootoptError as e:
        _error(str(getattr(e, "source", None) or args.description), str(e))
        return EXIT_USAGE
    summary = leg.summary()
    text = format_model_file(leg.model, header_comment=summary)
    if args.out == "-":
        for line in leg.warnings:
            print(f"footopt import: {line}", file=sys.stderr)
        print(text, end="")
        return EXIT_OK
    status = _write(Path(args.out), text, args.force)
    if status == EXIT_OK:
        print(summary)
        print(f"wrote {args.out}")
    return status


def _angles(given: list[str]) -> dict[str, float] | None:
    """``--angle JOINT=RAD`` options as a mapping (None after printing the error of a bad one)."""
    out: dict[str, float] = {}
    for text in given:
        name, sep, value = text.partition("=")
        try:
            angle = float(value)
        except ValueError:
            angle = math.nan
        if not sep or not name or not math.isfinite(angle):
            _error("--angle", f"expected JOINT=RAD with a finite angle, got {text!r}")
            return None
        out[name.strip()] = angle
    return out


__all__ = ["add_import", "run_import"]
