"""A whole landing drawn: the impulses over time, and the leg at each impact (matplotlib)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from impulse_core.evaluate import touchdown_geometry
from impulse_core.kinematics.spatial import PLANAR, dof_layout
from impulse_core.model.terrain import height
from impulse_core.model.tree import Scene, Tree
from impulse_core.timedomain.landing import LandingResult
from optimizer.errors import ConfigError
from optimizer.report.plot import _GROUND, _plot_path, _save
from optimizer.report.text import contact_names

#: Postures drawn at most (evenly chosen among the events, the first and last always).
MAX_POSTURES = 12


def posture(tree: Tree, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each rod's joint and tip (bodies x 2, world frame) at configuration q (base x, y, angle,
    then the joint angles)."""
    layout = dof_layout(tree.topology(), PLANAR)
    angles = [q[2]] + [b.angle if k is None else q[k] for b, k in zip(tree.bodies[1:], layout.body_dof[1:])]
    bodies = tuple(dataclasses.replace(b, angle=float(a)) for b, a in zip(tree.bodies, angles))
    g = touchdown_geometry(dataclasses.replace(tree, bodies=bodies))
    return g.origins + q[:2], g.tips + q[:2]


def plot_landing(tree: Tree, result: LandingResult, path: str | Path, title: str, scene: Scene) -> Path:
    """Two panels: every contact's normal impulse and each event's external_norm and
    internal_norm over time; the leg at the impacts (darker later) on the ground profile."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = _plot_path(path)
    fig, (ax_t, ax_leg) = plt.subplots(2, 1, figsize=(8, 9), gridspec_kw={"height_ratios": [1, 1.4]})
    times = np.array([e.time for e in result.events]) * 1e3
    for i, name in enumerate(contact_names(tree)):
        values = np.array([e.external[i] for e in result.events])
        shown = values > 0
        ax_t.plot(times[shown], values[shown], "o", ms=3, label=name)
    ax_t.plot(times, [e.external_norm for e in result.events], "k_", ms=8, label="external_norm")
    ax_t.plot(times, [e.internal_norm for e in result.events], "x", color="#27ae60", ms=4, label="internal_norm")
    ax_t.set_yscale("symlog", linthresh=1e-4)
    ax_t.set_xlabel("time after the first touchdown [ms]")
    ax_t.set_ylabel("impulse [N s]")
    ax_t.set_title(f"{title}: {len(result.events)} impacts over {1e3 * result.duration:g} ms")
    ax_t.legend(fontsize=7, ncol=2)
    _draw_postures(ax_leg, tree, result, scene)
    return _save(fig, path)


def _draw_postures(ax, tree: Tree, result: LandingResult, scene: Scene) -> None:  # type: ignore[no-untyped-def]
    """The leg at a few impacts (and at the end), the ground below."""
    t_traj, q_traj = result.trajectory
    picks = np.unique(np.linspace(0, len(result.events) - 1, min(MAX_POSTURES, len(result.events))).astype(int))
    moments = [(result.events[k].time, f"{1e3 * result.events[k].time:.1f} ms") for k in picks]
    moments.append((result.duration, f"end {1e3 * result.duration:g} ms"))
    xs = []
    for n, (t, label) in enumerate(moments):
        q = q_traj[min(int(np.searchsorted(t_traj, t)), len(q_traj) - 1)]
        origins, tips = posture(tree, q)
        shade = 0.25 + 0.75 * n / max(len(moments) - 1, 1)
        for o, tip in zip(origins, tips):
            ax.plot([o[0], tip[0]], [o[1], tip[1]], "-", color=(0.29, 0.43, 0.65, shade), lw=2)
        ax.annotate(label, origins[0], fontsize=6, alpha=shade)
        xs += [origins[:, 0], tips[:, 0]]
    x = np.concatenate(xs)
    ground_x = np.linspace(x.min() - 0.1, x.max() + 0.1, 200)
    ax.plot(ground_x, height(scene.terrain, ground_x), color=_GROUND, lw=1.5)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("the leg at the impacts (darker: later)")


#: Frames of an animation (evenly spaced in time) and its frame rate.
ANIMATION_FRAMES, ANIMATION_FPS = 100, 20


def animate_landing(tree: Tree, result: LandingResult, path: str | Path, scene: Scene) -> Path:
    """The landing as an animated GIF: the leg at ``ANIMATION_FRAMES`` evenly spaced times (the
    last step's posture before each), the ground, and the time and impacts so far."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation, PillowWriter

    path = Path(path)
    if path.suffix.lower() != ".gif":
        raise ConfigError(f"{path}: an animation is written as .gif (by its suffix)", path)
    t_traj, q_traj = result.trajectory
    times = np.linspace(0.0, result.duration, ANIMATION_FRAMES)
    frames = [q_traj[min(int(np.searchsorted(t_traj, t, side="right")) - 1, len(q_traj) - 1)] for t in times]
    points = np.vstack([np.vstack(posture(tree, q)) for q in frames])
    lo, hi = points.min(axis=0) - 0.05, points.max(axis=0) + 0.05
    fig, ax = plt.subplots(figsize=(6, 6 * (hi[1] - lo[1]) / max(hi[0] - lo[0], 1e-9) + 0.5))
    ground_x = np.linspace(lo[0], hi[0], 200)
    ax.plot(ground_x, height(scene.terrain, ground_x), color=_GROUND, lw=1.5)
    rods = [ax.plot([], [], "-", color="#4a6fa5", lw=2.5)[0] for _ in tree.bodies]
    label = ax.set_title("")
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(min(lo[1], -0.02), hi[1])
    ax.set_aspect("equal")
    event_times = np.array([e.time for e in result.events])

    def show(k: int) -> list:  # type: ignore[type-arg]
        origins, tips = posture(tree, frames[k])
        for rod, o, tip in zip(rods, origins, tips):
            rod.set_data([o[0], tip[0]], [o[1], tip[1]])
        label.set_text(f"t = {1e3 * times[k]:.1f} ms, {int(np.sum(event_times <= times[k]))} impacts")
        return [*rods, label]

    animation = FuncAnimation(fig, show, frames=len(frames), blit=False)
    try:
        animation.save(str(path), writer=PillowWriter(fps=ANIMATION_FPS))
    except OSError as e:
        raise ConfigError(f"{path}: cannot write the animation ({e.strerror or e})", path) from None
    finally:
        plt.close(fig)
    return path
