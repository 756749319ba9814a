"""A whole landing drawn: the impulses over time, and the leg at each impact (matplotlib); in
space the leg in three views (side, front, top) as ``footopt evaluate --plot`` draws a spatial foot."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from impulse_core.evaluate import touchdown_geometry
from impulse_core.kinematics.spatial import PLANAR, Space, dof_layout
from impulse_core.model.tree import Scene, Tree
from impulse_core.timedomain.compliant import chart_rotation
from impulse_core.timedomain.landing import LandingResult
from optimizer.errors import ConfigError
from optimizer.report.plot import _GROUND, VIEWS, _plot_path, _save, ground_section
from optimizer.report.text import contact_names

#: Postures drawn at most (evenly chosen among the events, the first and last always).
MAX_POSTURES = 12


def posture(tree: Tree, q: np.ndarray, space: Space = PLANAR) -> tuple[np.ndarray, np.ndarray]:
    """Each rod's joint and tip (world frame: bodies x 2 in the plane, x 3 in space) at the
    landing's configuration q: in the plane base x, y, angle, then the joint angles; in space the
    base origin, its rotation vector phi about its touchdown orientation, then the joint angles."""
    planar = space.joint_axis is not None
    layout = dof_layout(tree.topology(), space)
    base = q[2] if planar else tree.bodies[0].angle
    angles = [base] + [b.angle if k is None else q[k] for b, k in zip(tree.bodies[1:], layout.body_dof[1:])]
    bodies = tuple(dataclasses.replace(b, angle=float(a)) for b, a in zip(tree.bodies, angles))
    g = touchdown_geometry(dataclasses.replace(tree, bodies=bodies), space)
    if planar:
        return g.origins + q[:2], g.tips + q[:2]
    R = chart_rotation(np.asarray(q[3:6], dtype=float))
    return g.origins @ R.T + q[:3], g.tips @ R.T + q[:3]


def plot_landing(tree: Tree, result: LandingResult, path: str | Path, title: str, scene: Scene,
                 space: Space = PLANAR) -> Path:
    """Every contact's normal impulse and each event's external_norm and internal_norm over time;
    below, the leg at the impacts (darker later) on the ground: one panel in the plane, the side,
    front and top views in space."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = _plot_path(path)
    if space.joint_axis is not None:
        fig, (ax_t, ax_leg) = plt.subplots(2, 1, figsize=(8, 9), gridspec_kw={"height_ratios": [1, 1.4]})
        legs = [(ax_leg, (0, 1))]
    else:
        fig = plt.figure(figsize=(14, 9))
        grid = fig.add_gridspec(2, 3, height_ratios=[1, 1.3])
        ax_t = fig.add_subplot(grid[0, :])
        legs = [(fig.add_subplot(grid[1, k]), (h, v)) for k, (_, h, v) in enumerate(VIEWS)]
    _draw_impulses(ax_t, tree, result, title)
    for (ax, view), (name, _, _) in zip(legs, VIEWS):
        _draw_postures(ax, tree, result, scene, space, view)
        ax.set_title("the leg at the impacts (darker: later)" if len(legs) == 1 else f"{name}, darker later", fontsize=9)
    return _save(fig, path)


def _draw_impulses(ax, tree: Tree, result: LandingResult, title: str) -> None:  # type: ignore[no-untyped-def]
    times = np.array([e.time for e in result.events]) * 1e3
    for i, name in enumerate(contact_names(tree)):
        values = np.array([e.external[i] for e in result.events])
        shown = values > 0
        ax.plot(times[shown], values[shown], "o", ms=3, label=name)
    ax.plot(times, [e.external_norm for e in result.events], "k_", ms=8, label="external_norm")
    ax.plot(times, [e.internal_norm for e in result.events], "x", color="#27ae60", ms=4, label="internal_norm")
    for k, (start, span) in enumerate(result.bridges):  # stalled events crossed by Moreau-Jean steps
        ax.axvspan(1e3 * start, 1e3 * (start + span), color="#f39c12", alpha=0.3,
                   label="Moreau-Jean bridge" if k == 0 else None)
    ax.set_yscale("symlog", linthresh=1e-4)
    ax.set_xlabel("time after the first touchdown [ms]")
    ax.set_ylabel("impulse [N s]")
    ax.set_title(f"{title}: {len(result.events)} impacts over {1e3 * result.duration:g} ms")
    ax.legend(fontsize=7, ncol=2)


def _configuration_at(result: LandingResult, t: float) -> np.ndarray:
    """The last recorded configuration at or before t."""
    t_traj, q_traj = result.trajectory
    return q_traj[min(max(int(np.searchsorted(t_traj, t, side="right")) - 1, 0), len(q_traj) - 1)]


_AXES = ("x", "y", "z")
#: A posture's time label is left out where another's lies within this fraction of the drawing's span.
LABEL_SPACING = 0.04


def posture_events(times: np.ndarray, count: int) -> np.ndarray:
    """Indices of at most ``count`` events to draw, spread over the landing's time rather than over
    the events' count: for each of ``count`` evenly spaced times from the first event to the last,
    the first event at or after it. A Zeno cascade (case 3: 440 bounces within 21 ms of 0.3 s)
    would otherwise take every pick but the first, all alike."""
    if not len(times):
        return np.zeros(0, int)
    targets = np.linspace(times[0], times[-1], min(count, len(times)))
    return np.unique(np.minimum(np.searchsorted(times, targets, side="left"), len(times) - 1))


def _draw_postures(ax, tree: Tree, result: LandingResult, scene: Scene, space: Space,  # type: ignore[no-untyped-def]
                   view: tuple[int, int]) -> None:
    """The leg at a few impacts (and at the end) seen along ``view`` (the world axes drawn
    across and up), the ground below."""
    h, v = view
    picks = posture_events(np.array([e.time for e in result.events]), MAX_POSTURES)
    moments = [(result.events[k].time, f"{1e3 * result.events[k].time:.1f} ms") for k in picks]
    moments.append((result.duration, f"end {1e3 * result.duration:g} ms"))
    drawn = [posture(tree, _configuration_at(result, t), space) for t, _ in moments]
    points = [p for pair in drawn for p in pair]
    span = float(np.ptp(np.vstack(points)[:, [h, v]], axis=0).max()) or 1.0
    labelled: list[np.ndarray] = []
    for n, ((origins, tips), (_, label)) in enumerate(zip(drawn, moments)):
        shade = 0.25 + 0.75 * n / max(len(moments) - 1, 1)
        for o, tip in zip(origins, tips):
            ax.plot([o[h], tip[h]], [o[v], tip[v]], "-", color=(0.29, 0.43, 0.65, shade), lw=2)
        at = origins[0, [h, v]]
        if all(np.max(np.abs(at - a)) > LABEL_SPACING * span for a in labelled):  # no label over another
            ax.annotate(label, at, fontsize=6, alpha=shade)
            labelled.append(at)
    if v == 1:
        across, ground = ground_section(np.vstack(points), scene, space, h)
        ax.plot(across, ground, color=_GROUND, lw=1.5)
    ax.set_aspect("equal")
    ax.set_xlabel(f"{_AXES[h]} [m]")
    ax.set_ylabel(f"{_AXES[v]} [m]")


#: Frames of an animation (evenly spaced in time) and its frame rate.
ANIMATION_FRAMES, ANIMATION_FPS = 100, 20


def animate_landing(tree: Tree, result: LandingResult, path: str | Path, scene: Scene, space: Space = PLANAR) -> Path:
    """The landing as an animated GIF: the leg at ``ANIMATION_FRAMES`` evenly spaced times (the
    last step's posture before each), the ground, and the time and impacts so far; in space the
    side, front and top views side by side."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation, PillowWriter

    path = Path(path)
    if path.suffix.lower() != ".gif":
        raise ConfigError(f"{path}: an animation is written as .gif (by its suffix)", path)
    times = np.linspace(0.0, result.duration, ANIMATION_FRAMES)
    frames = [posture(tree, _configuration_at(result, t), space) for t in times]
    points = np.vstack([np.vstack(f) for f in frames])
    lo, hi = points.min(axis=0) - 0.05, points.max(axis=0) + 0.05
    views = [(0, 1)] if space.joint_axis is not None else [(h, v) for _, h, v in VIEWS]
    fig, axes = plt.subplots(1, len(views), figsize=(6 * len(views), 6), squeeze=False)
    drawn = []
    for ax, (h, v) in zip(axes[0], views):
        if v == 1:
            ax.plot(*ground_section(points, scene, space, h), color=_GROUND, lw=1.5)
        drawn.append([ax.plot([], [], "-", color="#4a6fa5", lw=2.5)[0] for _ in tree.bodies])
        ax.set_xlim(lo[h], hi[h])
        ax.set_ylim(min(lo[v], -0.02) if v == 1 else lo[v], hi[v])
        ax.set_aspect("equal")
        ax.set_xlabel(f"{_AXES[h]} [m]")
        ax.set_ylabel(f"{_AXES[v]} [m]")
    label = fig.suptitle("")
    event_times = np.array([e.time for e in result.events])

    def show(k: int) -> list:  # type: ignore[type-arg]
        origins, tips = frames[k]
        for rods, (h, v) in zip(drawn, views):
            for rod, o, tip in zip(rods, origins, tips):
                rod.set_data([o[h], tip[h]], [o[v], tip[v]])
        label.set_text(f"t = {1e3 * times[k]:.1f} ms, {int(np.sum(event_times <= times[k]))} impacts")
        return [*(r for rods in drawn for r in rods), label]

    animation = FuncAnimation(fig, show, frames=len(frames), blit=False)
    try:
        animation.save(str(path), writer=PillowWriter(fps=ANIMATION_FPS))
    except OSError as e:
        raise ConfigError(f"{path}: cannot write the animation ({e.strerror or e})", path) from None
    finally:
        plt.close(fig)
    return path
