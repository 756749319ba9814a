"""``footopt export``: a model file as URDF or MJCF. Registered in :data:`optimizer.cli.main.SUBCOMMANDS`.

Exit status as the rest of ``footopt``: 0 written; 2 a bad model file, a bad option or an OUT that
exists (without ``--force``), one line on stderr naming the file or the option.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from impulse_core.errors import FootoptError
from optimizer.cli.status import EXIT_OK, EXIT_USAGE
from optimizer.cli.status import error as _error

_SUFFIXES = {".urdf": "urdf", ".xml": "mjcf", ".mjcf": "mjcf"}


def add_export(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "export",
        help="write a model file as URDF or MJCF (MuJoCo), at its touchdown",
        description=(
            "Write a model file's leg as a robot description: one link (URDF) or body (MJCF) per rod, named as "
            "the rod, with its mass, centre of mass and inertia; a joint per rod, named as the rod, revolute "
            "about z or fixed; a floating base (URDF: the root link, to be loaded with a free-flyer; MJCF: a "
            "freejoint); one frame per contact, <rod>_contact<k> (URDF: a massless link on a fixed joint; MJCF: "
            "a site). The zero configuration is the touchdown posture and pose (base origin above scene.base_x, "
            "its first contact on the ground); axes as footopt's: x forward, y up, z lateral (MJCF gravity along "
            "-y). A rod's inertia about its own axis, zero in the model, is written as 1e-9 kg m^2 (the file "
            "says so). A spatial file's scene.heightfield: the robot stands at its touchdown on it, and the MJCF "
            "holds it as a MuJoCo hfield (an uneven grid on a common step; the file states how far MuJoCo's "
            "triangles leave footopt's bilinear ground); URDF has no terrain. See MODEL_FORMAT.md, 'Export'."
        ),
    )
    p.add_argument("model", metavar="MODEL.yaml", help="a model file (MODEL_FORMAT.md)")
    p.add_argument("-o", "--out", metavar="OUT", required=True, help="the file to write ('-': standard output)")
    p.add_argument(
        "--format",
        choices=("urdf", "mjcf"),
        default=None,
        help="urdf or mjcf (default: from OUT's suffix, .urdf, or .xml / .mjcf for MJCF)",
    )
    p.add_argument("--stop-timestep", type=float, default=None, metavar="S",
                   help="MJCF: tune the stops' stiff limits for MuJoCo steps of S seconds, 1e-8 to 1 "
                        "(default: MuJoCo's "
                        "default step, 0.002; a longer step needs softer stops)")
    p.add_argument("--force", action="store_true", help="replace OUT if it exists")
    p.set_defaults(run=run_export)


def run_export(args: argparse.Namespace) -> int:
    """``footopt export``."""
    from optimizer.config.model_file import load_model_file
    from optimizer.results.export import STOP_TIMESTEP_RANGE, ExportFormat, export_text

    name = args.format or _SUFFIXES.get(Path(args.out).suffix.lower())
    if name is None:
        _error("--format", f"give urdf or mjcf (the suffix of {args.out} names neither)")
        return EXIT_USAGE
    step = args.stop_timestep
    lo, hi = STOP_TIMESTEP_RANGE
    if step is not None and not lo <= step <= hi:
        _error("--stop-timestep", f"must be a time step in [{lo:g}, {hi:g}] (s), got {step!r}")
        return EXIT_USAGE
    try:
        model = load_model_file(args.model)
        text = export_text(model.tree, model.scene, ExportFormat(name), Path(args.model).stem, model.joints,
                           model.space, **({} if step is None else {"stop_timestep": step}))
    except FootoptError as e:
        _error(args.model, str(e))
        return EXIT_USAGE
    if args.out == "-":
        print(text, end="")
        return EXIT_OK
    return _write(Path(args.out), text, args.force)


def _write(path: Path, text: str, force: bool) -> int:
    """Write ``text`` to ``path``, refusing to replace a file unless ``force``."""
    try:
        with path.open("w" if force else "x", encoding="utf-8") as f:
            f.write(text)
    except FileExistsError:
        _error(str(path), "already exists; not overwriting it (pass --force to replace it)")
        return EXIT_USAGE
    except OSError as e:
        _error(str(path), f"cannot write: {e.strerror or e}")
        return EXIT_USAGE
    return EXIT_OK


__all__ = ["add_export", "run_export"]
