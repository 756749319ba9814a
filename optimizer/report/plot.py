"""Drawings of a tree at touchdown with its impulses, and of a speed report (matplotlib, no
display needed)."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from impulse_core.evaluate import Geometry, ImpactResult, touchdown_geometry
from impulse_core.kinematics.spatial import SPATIAL, Space
from impulse_core.model import heightfield
from impulse_core.model.support import convex_hull, support_margin
from impulse_core.model.terrain import FLAT, height, slope_normal, vertical_clearance
from impulse_core.model.tree import Scene, Tree
from impulse_core.timedomain.compliant import spatial_ground, touchdown_configuration
from optimizer.errors import ConfigError

if TYPE_CHECKING:
    from optimizer.analysis.bench import SpeedReport

#: File types ``plot_touchdown`` writes, by suffix.
PLOT_SUFFIXES = (".png", ".svg")

_ROD, _JOINT, _CONTACT, _EXTERNAL, _INTERNAL, _GROUND = "#4a6fa5", "#333333", "#c0392b", "#c0392b", "#27ae60", "#777777"


def _coinciding(names: list[str], where: np.ndarray, extent: float) -> list[tuple[list[str], np.ndarray]]:
    """Labels grouped by position: rods drawn on top of each other (identical planar toes) share
    one label instead of printing their names over each other."""
    groups: dict[tuple[float, float], tuple[list[str], np.ndarray]] = {}
    for name, w in zip(names, where, strict=True):
        key = (round(w[0] / extent, 6), round(w[1] / extent, 6))
        groups.setdefault(key, ([], w))[0].append(name)
    return list(groups.values())


def _plot_path(path: str | Path) -> Path:
    """``path`` as a Path, refused (ConfigError) unless it ends in one of ``PLOT_SUFFIXES``."""
    path = Path(path)
    if path.suffix.lower() not in PLOT_SUFFIXES:
        raise ConfigError(f"{path}: a plot is written as {' or '.join(PLOT_SUFFIXES)} (by its suffix)", path)
    return path


#: zlib level of the PNGs written: 1 encodes about 3 x faster than matplotlib's 6, for files
#: about 10 % larger.
PNG_COMPRESSION = 1


def preload_matplotlib() -> None:
    """Import what the drawings need and draw a tiny figure of their kinds of artists (before
    forking workers that draw, so each inherits the fonts, text caches and PNG writer instead of
    loading them on its first drawing: about 0.09 s CPU each)."""
    import io

    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(1, 1), dpi=20)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    ax.plot([0, 1], [0, 1])
    ax.annotate("0", (0.5, 0.5), fontsize=8)
    ax.fill_between([0, 1], [0, 0], [1, 1], facecolor="none", hatch="///")
    ax.legend(handles=ax.lines, labels=["0"], fontsize=8)
    fig.suptitle("0", fontsize=10)
    fig.savefig(io.BytesIO(), format="png", pil_kwargs={"compress_level": PNG_COMPRESSION})


def _save(fig, path: Path, layout: bool = True) -> Path:
    """Lay out ``fig`` and write it to ``path`` cropped to its tight box (ConfigError if it
    cannot be written); ``layout`` False: as laid out already, uncropped (one drawing pass, not
    the crop's two)."""
    if layout:
        fig.tight_layout()
    png = {"pil_kwargs": {"compress_level": PNG_COMPRESSION}} if path.suffix.lower() == ".png" else {}
    try:
        fig.savefig(path, dpi=150, **({"bbox_inches": "tight"} if layout else {}), **png)
    except OSError as e:
        raise ConfigError(f"{path}: cannot write the plot: {e.strerror or e}", path) from None
    return path


def plot_touchdown(
    tree: Tree, geometry: Geometry, result: ImpactResult, path: str | Path, title: str, scene: Scene | None = None
) -> Path:
    """Draw the tree at touchdown and its impulses, and write the figure to ``path``.

    Rods are thick lines from joint to tip, joints circles, centres of mass small crosses, the
    ground a hatched line at ``geometry.ground_height``. Contacts are dots (filled when they
    hit). External impulses are arrows along the ground normal at the contacts; joint impulses
    (parent onto child, force part) arrows at the joints; both drawn to one scale and labelled
    in N s.

    Args:
        tree: the design.
        geometry: its touchdown geometry (``impulse_core.evaluate.touchdown_geometry``).
        result: its impact (``impulse_core.evaluate.evaluate``), or any result with the same
            fields (``optimizer.evaluation.model_choice.TimeDomainResult``).
        path: the file to write, PNG or SVG by its suffix (overwritten if it exists).
        title: first line of the title; the norms are added below it.
        scene: when it has a ``terrain`` (not the default flat ground), the tree is placed over it
            as at touchdown (base origin at ``scene.base_x``, lowered until the first contact
            touches), the ground is the terrain profile, and external impulses point along its
            normal below each contact.

    Returns:
        The path written.

    Raises:
        ConfigError: an unsupported suffix, or the file cannot be written.
    """
    # Imported here: the command line only pays for matplotlib when asked for a plot. The
    # Figure API with the Agg canvas needs no display and leaves pyplot's global state alone.
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    path = _plot_path(path)

    fig = Figure(figsize=(10, 6.5))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    origins, tips, coms, contacts = geometry.origins, geometry.tips, geometry.coms, geometry.contacts
    terrain = None if scene is None or scene.terrain == FLAT else scene.terrain
    if terrain is not None:  # world frame: base origin at base_x, first contact on the terrain
        shift = np.array([scene.base_x, 0.0]) - origins[0]
        shift[1] -= float(np.min(vertical_clearance(terrain, contacts + shift)))
        origins, tips, coms, contacts = (a + shift for a in (origins, tips, coms, contacts))
    points = [origins, tips, coms, contacts]

    for o, t in zip(origins, tips, strict=True):
        ax.plot([o[0], t[0]], [o[1], t[1]], color=_ROD, lw=6, solid_capstyle="round", alpha=0.85, zorder=2)
    extent0 = float(max(np.ptp(np.vstack(points), axis=0).max(), 1e-3))
    for names, where in _coinciding([b.name for b in tree.bodies], (coms + tips) / 2, extent0):
        label = names[0] if len(names) == 1 else f"{names[0]} (x{len(names)}, coinciding)"
        ax.annotate(label, where, fontsize=8, color=_ROD, xytext=(4, 4), textcoords="offset points")
    ax.plot(coms[:, 0], coms[:, 1], "x", color="black", ms=5, zorder=4)
    ax.plot(origins[0, 0], origins[0, 1], "s", mfc="white", mec=_JOINT, ms=8, zorder=4)
    if len(origins) > 1:
        ax.plot(origins[1:, 0], origins[1:, 1], "o", mfc="white", mec=_JOINT, ms=8, mew=1.5, zorder=4)

    active = np.zeros(len(contacts), dtype=bool)
    active[list(result.active)] = True
    if active.any():
        ax.plot(contacts[active, 0], contacts[active, 1], "o", color=_CONTACT, ms=7, zorder=5)
    if (~active).any():
        ax.plot(contacts[~active, 0], contacts[~active, 1], "o", mfc="white", mec=_CONTACT, ms=7, zorder=5)

    span = np.vstack(points)
    extent = float(max(np.ptp(span[:, 0]), np.ptp(span[:, 1]), 1e-3))
    largest = max(float(np.max(np.abs(result.external), initial=0.0)), result.max_internal)
    scale = 0.35 * extent / largest if largest > 0 else 0.0  # m per N s

    labelled: set[tuple[float, float, str]] = set()

    def arrow(start: np.ndarray, vector: np.ndarray, color: str, label: float) -> None:
        end = start + scale * vector
        points.append(end[None, :])
        key = (round(end[0] / extent, 6), round(end[1] / extent, 6), f"{label:.3g}")
        if key in labelled:  # coinciding rods (identical toes): one arrow, one label
            return
        labelled.add(key)
        ax.annotate(
            "",
            xy=end,
            xytext=start,
            zorder=6,
            arrowprops=dict(arrowstyle="-|>", color=color, lw=2, shrinkA=0, shrinkB=0),
        )
        ax.annotate(f"{label:.3g}", end, fontsize=8, color=color, xytext=(3, 3), textcoords="offset points", zorder=7)

    for i in result.active:
        normal = np.array([0.0, 1.0]) if terrain is None else slope_normal(terrain, contacts[i, 0])
        arrow(contacts[i], normal * result.external[i], _EXTERNAL, result.external[i])
    for j in range(len(tree.bodies) - 1):
        arrow(origins[j + 1], np.asarray(result.internal[j, :2], dtype=float), _INTERNAL, result.internal_magnitude[j])

    all_points = np.vstack(points)
    lo, hi = all_points.min(axis=0), all_points.max(axis=0)
    margin = 0.08 * extent
    x0, x1 = lo[0] - margin, hi[0] + margin
    if terrain is None:
        gx = np.array([x0, x1])
        gy = np.full(2, geometry.ground_height)
    else:
        gx = np.concatenate([[x0], [x for x in terrain.x if x0 < x < x1], [x1]])
        gy = height(terrain, gx)
    ax.plot(gx, gy, color=_GROUND, lw=1.5, zorder=1)
    ax.fill_between(gx, gy - 0.04 * extent, gy, facecolor="none", edgecolor=_GROUND, hatch="///", lw=0)
    ylim = (min(lo[1], float(gy.min()) - 0.04 * extent) - margin, max(hi[1], float(gy.max())) + margin)
    ax.set_xlim(x0, x1)
    ax.set_ylim(*ylim)
    ax.set_aspect("equal", adjustable="box")
    _fit_figure(fig, (x1 - x0) / (ylim[1] - ylim[0]))
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    fig.suptitle(
        f"{title}\n|external| = {result.external_norm:.4g} N s, |internal| = {result.internal_norm:.4g} N s, "
        f"largest joint {result.max_internal:.4g} N s",
        fontsize=10,
        x=0.01,
        ha="left",
    )
    handles = [
        Line2D([], [], color=_ROD, lw=6, label="rod"),
        Line2D([], [], ls="", marker="o", mfc="white", mec=_JOINT, label="joint (square: base origin)"),
        Line2D([], [], ls="", marker="x", color="black", label="centre of mass"),
        Line2D([], [], ls="", marker="o", color=_CONTACT, label="contact that hits (hollow: does not)"),
        Line2D([], [], color=_EXTERNAL, lw=2, label="external impulse [N s]"),
        Line2D([], [], color=_INTERNAL, lw=2, label="joint impulse, parent on child [N s]"),
        Line2D([], [], color=_GROUND, lw=1.5, label="ground"),
    ]
    ax.legend(handles=handles, fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0)
    return _save(fig, path, layout=False)


#: The touchdown drawing's frame (inches): the axes' height and widest width, the margins left
#: (tick labels), right (the legend), below (x label) and above (the title's two lines).
_AXES_HEIGHT, _AXES_WIDEST, _LEFT, _RIGHT, _BOTTOM, _TOP = 5.5, 9.0, 0.9, 3.0, 0.6, 0.75
#: Narrowest figure: the title's second line fits.
_FIGURE_NARROWEST = 6.8


def _fit_figure(fig, aspect: float) -> None:
    """Size ``fig`` to its one axes of equal scales spanning ``aspect`` (width / height of the
    data), its legend to the right: the figure is written uncropped in one drawing pass, with no
    more blank than the title's width needs."""
    width = min(max(_AXES_HEIGHT * aspect, 0.1), _AXES_WIDEST)
    height = width / aspect if _AXES_HEIGHT * aspect > _AXES_WIDEST else _AXES_HEIGHT
    W, H = max(_LEFT + width + _RIGHT, _FIGURE_NARROWEST), _BOTTOM + height + _TOP
    fig.set_size_inches(W, H)
    fig.subplots_adjust(left=_LEFT / W, right=(_LEFT + width) / W, bottom=_BOTTOM / H, top=1 - _TOP / H)


def plot_speed(report: SpeedReport, path: str | Path) -> Path:
    """Draw a speed report (``footopt bench --plot``) and write it to ``path`` (PNG or SVG).

    Left: microseconds per design of every path timed on the report's model, beside
    ``pinocchio.impulseDynamics`` per call. Right, when the report has a scaling series:
    microseconds per design against body count, log-log, with a quadratic slope for reference.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    path = _plot_path(path)
    bars = [
        ("CasADi VM, map", report.us_per_design_batched_vm),
        ("compiled, CasADi map", report.us_per_design_batched_compiled),
        ("compiled, C loop", report.us_per_design_batched_kernel),
        (f"compiled, SIMD ({report.simd_lanes} lanes)", report.us_per_design_batched_simd),
        ("C loop, 2 threads", report.us_per_design_batched_kernel_threads),
        ("SIMD, 2 threads", report.us_per_design_batched_simd_threads),
        (
            f"gradient, {report.n_gradient_values} values, adjoint ({report.gradient_path})",
            report.us_per_design_gradient,
        ),
        (
            f"gradient, {report.n_gradient_values} values, reverse mode ({report.gradient_path})",
            report.us_per_design_gradient_autodiff,
        ),
        (
            f"gradient, all {report.n_values} values, adjoint ({report.gradient_path})",
            report.us_per_design_gradient_all,
        ),
        ("pinocchio.impulseDynamics (per call)", report.pinocchio_us_per_call),
    ]
    bars = [(label, us) for label, us in bars if us is not None]
    fig = Figure(figsize=(13, 5.5) if report.scaling else (7, 5.5))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 2 if report.scaling else 1, 1)
    colors = [
        "#c0392b" if label.startswith("pinocchio") else "#27ae60" if "gradient" in label else _ROD for label, _ in bars
    ]
    ax.barh(range(len(bars)), [us for _, us in bars], color=colors)
    ax.set_yticks(range(len(bars)), [label for label, _ in bars], fontsize=8)
    ax.invert_yaxis()
    ax.set_xscale("log")
    ax.set_xlim(right=max(us for _, us in bars) * 3)  # room for the last bar's label inside the axes
    for k, (_, us) in enumerate(bars):
        ax.annotate(f"{us:.3g}", (us, k), xytext=(3, 0), textcoords="offset points", va="center", fontsize=8)
    ax.set_xlabel("microseconds per design (batched) or per call")
    ax.set_title(
        f"{report.model}: {report.n_bodies} bodies, {report.n_dof} DOF, {report.n_contacts} contacts", fontsize=10
    )
    if report.scaling:
        ax2 = fig.add_subplot(1, 2, 2)
        bodies = np.array([r["bodies"] for r in report.scaling], dtype=float)
        series = [
            ("best one-core path", "us_per_design", "o-", _ROD),
            ("compiled, C loop", "us_per_design_c_loop", "s--", "#8e44ad"),
            ("CasADi VM, map", "us_per_design_vm", "^:", _GROUND),
            ("pinocchio.impulseDynamics", "pinocchio_us_per_call", "d-", "#c0392b"),
        ]
        for label, key, style, color in series:
            ys = [r.get(key) for r in report.scaling]
            if all(y is not None for y in ys):
                ax2.plot(bodies, ys, style, color=color, label=label)
        first = report.scaling[0]["us_per_design"]
        ax2.plot(
            bodies, first * (bodies / bodies[0]) ** 2, color="#999999", lw=1, label="quadratic growth, for reference"
        )
        ax2.set_xscale("log")
        ax2.set_yscale("log")
        ax2.set_xticks(bodies, [f"{b:.0f}" for b in bodies])
        ax2.minorticks_off()
        ax2.set_xlabel("bodies")
        ax2.set_ylabel("microseconds per design (per call for Pinocchio)")
        ax2.set_title("scaling series (more toes, more segments)", fontsize=10)
        ax2.grid(True, which="both", alpha=0.3)
        ax2.legend(fontsize=8)
    return _save(fig, path)


__all__ = ["PLOT_SUFFIXES", "plot_speed", "plot_top_views", "plot_touchdown", "plot_views"]


#: The three views of a spatial foot: (title, horizontal world axis, vertical world axis).
VIEWS = (("side (x forward, y up)", 0, 1), ("front (z lateral, y up)", 2, 1), ("top (x forward, z lateral)", 0, 2))


def ground_section(points: np.ndarray, scene: Scene, space: Space, h: int) -> tuple[np.ndarray, np.ndarray]:
    """The ground's height along world axis ``h`` (x or z) under ``points`` (in space through
    their mean position across: the scene's heightfield, or its flat ground)."""
    across = np.linspace(points[:, h].min() - 0.1, points[:, h].max() + 0.1, 200)
    if space.joint_axis is not None:
        return across, height(scene.terrain, across)
    other = np.full_like(across, points[:, 2 if h == 0 else 0].mean())
    x, z = (across, other) if h == 0 else (other, across)
    return across, heightfield.height(spatial_ground(scene), x, z)


def _placed_on(tree: Tree, geometry: Geometry, scene: Scene) -> tuple[Geometry, np.ndarray]:
    """The touchdown geometry where the scene's heightfield puts it (base at ``base_x``,
    ``base_z``, lowered onto the ground) and the ground's upward normal at each contact."""
    hf = scene.heightfield
    shift = touchdown_configuration(tree, hf, scene.base_x, space=SPATIAL, base_z=scene.base_z)[:3]
    placed = dataclasses.replace(geometry, origins=geometry.origins + shift, tips=geometry.tips + shift,
                                 coms=geometry.coms + shift, contacts=geometry.contacts + shift)
    return placed, heightfield.normal(hf, placed.contacts[:, 0], placed.contacts[:, 2])


def plot_views(tree: Tree, geometry: Geometry, result: ImpactResult, path: str | Path, title: str,
               scene: Scene | None = None) -> Path:
    """A spatial tree at touchdown in three views (side, front, top): rods, joints, contacts
    (filled when they hit) and the external impulses as arrows along the ground normal (drawn in
    the side and front views; seen from above, the top view marks them with their value). On a
    heightfield (``scene.heightfield``) the tree stands where the scene lands it and the side and
    front views draw the ground's section through the contacts.

    Raises:
        ConfigError: an unsupported suffix, or the file cannot be written.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    path = _plot_path(path)
    uneven = scene is not None and scene.heightfield is not None
    normals = np.tile([0.0, 1.0, 0.0], (len(geometry.contacts), 1))
    if uneven:
        geometry, normals = _placed_on(tree, geometry, scene)
    fig = Figure(figsize=(14, 5))
    FigureCanvasAgg(fig)
    points = np.vstack([geometry.origins, geometry.tips, geometry.contacts])
    extent = float(max(np.ptp(points, axis=0).max(), 1e-3))
    largest = float(np.max(np.abs(result.external), initial=0.0))
    scale = 0.3 * extent / largest if largest > 0 else 0.0
    active = np.zeros(len(geometry.contacts), dtype=bool)
    active[list(result.active)] = True
    for k, (name, h, v) in enumerate(VIEWS):
        ax = fig.add_subplot(1, 3, k + 1)
        for o, t in zip(geometry.origins, geometry.tips, strict=True):
            ax.plot([o[h], t[h]], [o[v], t[v]], color=_ROD, lw=5, solid_capstyle="round", alpha=0.85)
        ax.plot(geometry.origins[:, h], geometry.origins[:, v], "o", mfc="white", mec=_JOINT, ms=6)
        c = geometry.contacts
        ax.plot(c[active, h], c[active, v], "o", color=_CONTACT, ms=6)
        ax.plot(c[~active, h], c[~active, v], "o", mfc="white", mec=_CONTACT, ms=6)
        for i in np.flatnonzero(active):
            if v == 1:  # the normal's upward part lies in this view
                tip = c[i] + scale * result.external[i] * normals[i]
                ax.annotate("", xy=(tip[h], tip[v]), xytext=(c[i, h], c[i, v]),
                            arrowprops=dict(arrowstyle="-|>", color=_EXTERNAL, lw=2, shrinkA=0, shrinkB=0))
            ax.annotate(f"{result.external[i]:.3g}", (c[i, h], c[i, v]), fontsize=8, color=_EXTERNAL,
                        xytext=(3, -10), textcoords="offset points")
        if v == 1 and uneven:
            ax.plot(*ground_section(c, scene, SPATIAL, h), color=_GROUND, lw=1)
        elif v == 1:
            ax.axhline(geometry.ground_height, color=_GROUND, lw=1)
        ax.set_title(name, fontsize=9)
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
    fig.suptitle(f"{title}\nexternal_norm {result.external_norm:.4f} N s, internal_norm {result.internal_norm:.4f} N s"
                 " (external impulses in red, N s)")
    return _save(fig, path)


def plot_top_views(feet: list[tuple[str, Tree]], path: str | Path, space: Space = SPATIAL) -> Path:
    """Each foot seen from above (x forward, z lateral), one panel per foot: its rods, its
    contacts, the support polygon (the convex hull of the contacts on the ground) and the whole
    tree's centre of mass projected on the ground, with the support margin
    (:mod:`impulse_core.model.support`: > 0 inside) in the panel's title.

    Raises:
        ConfigError: an unsupported suffix, or the file cannot be written.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    path = _plot_path(path)
    n = max(len(feet), 1)
    cols = min(n, 4)
    rows = (n + cols - 1) // cols
    fig = Figure(figsize=(4.2 * cols, 4.2 * rows))
    FigureCanvasAgg(fig)
    for k, (title, tree) in enumerate(feet):
        g = touchdown_geometry(tree, space)
        masses = np.array([b.mass for b in tree.bodies])
        com = masses @ g.coms / masses.sum()
        ground = g.contacts[:, [0, 2]]
        margin = support_margin(ground, com[[0, 2]])
        ax = fig.add_subplot(rows, cols, k + 1)
        hull = convex_hull(ground)
        if len(hull) >= 3:
            ax.fill(hull[:, 0], hull[:, 1], color=_CONTACT, alpha=0.15, lw=0)
        closed = np.vstack([hull, hull[:1]])
        ax.plot(closed[:, 0], closed[:, 1], "--", color=_CONTACT, lw=1, label="support polygon")
        for o, t in zip(g.origins, g.tips, strict=True):
            ax.plot([o[0], t[0]], [o[2], t[2]], color=_ROD, lw=4, solid_capstyle="round", alpha=0.85)
        ax.plot(g.contacts[:, 0], g.contacts[:, 2], "o", color=_CONTACT, ms=6, label="contacts")
        ax.plot(com[0], com[2], "x", color=_EXTERNAL, ms=10, mew=2, label="centre of mass")
        ax.set_title(f"{title}\nsupport margin {round(1e3 * margin, 1) + 0.0:+.1f} mm", fontsize=9)
        ax.set_xlabel("x forward [m]")
        ax.set_ylabel("z lateral [m]")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
        if k == 0:
            ax.legend(fontsize=7, loc="best")
    fig.suptitle("top views (from above): rods, contacts, support polygon, centre of mass on the ground")
    fig.tight_layout()
    return _save(fig, path)
