"""The speed-accuracy trade of the impact-model ladder, measured on one scene.

Every rung that runs on the scene is timed and compared with the finest model:

* the rigid rungs of ``impulse_core.evaluate`` (every ``ImpactModel`` it offers: the paper's
  decoupled eq. 14, Newton's eq. 11, the LCP, friction), which assume flat ground;
* the sequential rigid model (``impulse_core.timedomain.sequential``: an LCP impact at each touchdown, free
  flight between), the stiff limit of the compliant rung on any terrain;
* the compliant rung (``impulse_core.timedomain.compliant``) with each contact law at several stiffnesses
  and steps per contact period;
* optionally MuJoCo with the constraint law's contact softness, as a peer (its time includes the
  Python loop that reads its contact forces).

The reference ("finest model") is the compliant penalty law at the largest stiffness and the
most steps; errors are also given against the rigid limit (the sequential model). An error is
the largest deviation over the contacts (external) or joints (internal) divided by the
reference's largest entry, so that tiny entries do not dominate; the ``differs`` column names
every single quantity that is off by more than 1 % of itself (and 0.1 % of the largest).

mujoco and matplotlib are imported lazily.
"""

from __future__ import annotations

import csv
import math
import statistics
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from impulse_core.evaluate import evaluate
from impulse_core.model.terrain import FLAT, Terrain
from impulse_core.model.tree import Scene, Tree
from impulse_core.timedomain.compliant import CompliantSettings, ContactLaw, scene_ground, simulate_impact
from impulse_core.timedomain.sequential import SequentialSettings, sequential_impacts

#: A quantity "differs" when it is off by more than this fraction of itself ...
DIFFERS_RELATIVE = 0.01
#: ... and by more than this fraction of the largest entry of its kind.
DIFFERS_FLOOR = 1e-3

PENALTY_STIFFNESS = (1e5, 1e6, 1e7, 1e8)  # N/m
CONSTRAINT_STIFFNESS = (1e6, 1e7, 1e8, 1e9)  # 1/s^2
STEPS_PER_PERIOD = (30, 120, 480)


@dataclass(frozen=True)
class Measurement:
    """One rung (at one setting) on the scene.

    Attributes:
        rung: ``decoupled``, ``newton``, ``lcp``, ``friction`` (rigid, flat ground),
            ``sequential`` (rigid, terrain), ``compliant-penalty``, ``compliant-constraint``,
            ``mujoco``.
        label: a readable name with the setting.
        stiffness: N/m (penalty) or 1/s^2 (constraint, MuJoCo); NaN for rigid rungs.
        steps_per_period: integration steps per fastest contact period; NaN for rigid rungs.
        seconds: median CPU time of one evaluation (s), after a warm-up call.
        external: normal impulse per declared contact (N s).
        internal: joint impulse magnitude per non-base body (N s).
        energy_before, energy_after: kinetic energy (J).
        touchdown_order: contacts by touchdown time (rigid flat rungs: the active contacts).
        n_steps: integration steps (0 for rigid rungs).
        note: what the reader must know (the model's own words, status, failures).
    """

    rung: str
    label: str
    stiffness: float
    steps_per_period: float
    seconds: float
    external: np.ndarray
    internal: np.ndarray
    energy_before: float
    energy_after: float
    touchdown_order: tuple[int, ...]
    n_steps: int
    note: str


@dataclass(frozen=True)
class AccuracyRow:
    """A measurement and its errors.

    Attributes:
        measurement: the run.
        external_error, internal_error: against the reference (finest model), relative to the
            reference's largest entry.
        external_error_rigid, internal_error_rigid: the same against the rigid limit.
        energy_error: (energy after - reference's) / energy before.
        speed_ratio: seconds / the Newton rung's seconds (or the fastest rigid rung's).
        differs: the single quantities off by more than 1 % (against the reference).
    """

    measurement: Measurement
    external_error: float
    internal_error: float
    external_error_rigid: float
    internal_error_rigid: float
    energy_error: float
    speed_ratio: float
    differs: str


@dataclass(frozen=True)
class AccuracyReport:
    """The measured ladder on one scene."""

    scene: str
    reference: str
    rigid_limit: str
    contact_names: tuple[str, ...]
    joint_names: tuple[str, ...]
    rows: tuple[AccuracyRow, ...]

    def row(self, label: str) -> AccuracyRow:
        return next(r for r in self.rows if r.measurement.label == label)


def _time(fn: Callable[[], object], repeats: int, budget: float) -> tuple[object, float]:
    """(result, median seconds per call): one warm-up call (compilation), then up to ``repeats``
    timed calls, fewer once ``budget`` seconds are spent. Times are the process's CPU time
    (``time.process_time``): on a shared machine other processes do not inflate them; every
    evaluation here runs on one thread."""
    result = fn()
    samples: list[float] = []
    while len(samples) < repeats:
        t0 = time.process_time()
        result = fn()
        samples.append(time.process_time() - t0)
        if sum(samples) > budget:
            break
    return result, statistics.median(samples)


def _rigid_models() -> list[tuple[str, object]]:
    """The rungs ``evaluate`` offers: (name, model argument) pairs."""
    try:
        from impulse_core.impact.laws import ImpactModel
    except ImportError:  # an evaluate without the ladder: Newton only
        return [("newton", None)]
    return [(m.value, m) for m in ImpactModel]


def _names(tree: Tree) -> tuple[tuple[str, ...], tuple[str, ...]]:
    contacts = []
    for b in tree.bodies:
        for k in range(len(b.contacts)):
            contacts.append(b.name if len(b.contacts) == 1 else f"{b.name}[{k}]")
    return tuple(contacts), tuple(b.name for b in tree.bodies[1:])


def measure(
    tree: Tree,
    scene: Scene,
    terrain: Terrain | None = None,
    base_x: float | None = None,
    penalty_stiffness: Sequence[float] = PENALTY_STIFFNESS,
    constraint_stiffness: Sequence[float] = CONSTRAINT_STIFFNESS,
    steps_per_period: Sequence[float] = STEPS_PER_PERIOD,
    include_mujoco: bool = False,
    repeats: int = 5,
    budget: float = 1.0,
) -> list[Measurement]:
    """Run and time every rung on the scene (module docstring). ``terrain`` and ``base_x``
    default to the scene's own, else flat ground and 0."""
    terrain, base_x = scene_ground(scene, terrain, base_x)
    out: list[Measurement] = []
    nan = math.nan
    # the rigid rungs refuse a terrain that is not flat; here their flat-ground answer is the point
    flat_scene = replace(scene, terrain=FLAT, base_x=0.0)
    for name, model in _rigid_models():
        try:
            if model is None:
                r, seconds = _time(lambda: evaluate(tree, flat_scene), repeats, budget)
            else:
                r, seconds = _time(lambda m=model: evaluate(tree, flat_scene, model=m), repeats, budget)
        except Exception as e:  # a rung that does not apply to this scene: recorded, not hidden
            out.append(
                Measurement(
                    name,
                    name,
                    nan,
                    nan,
                    nan,
                    np.full(len(tree.contacts), nan),
                    np.full(tree.n_bodies - 1, nan),
                    nan,
                    nan,
                    (),
                    0,
                    f"failed: {e}",
                )
            )
            continue
        note = getattr(r, "reason", "") or str(getattr(r, "model", ""))
        if not terrain.is_flat:
            note = "flat ground: ignores scene.terrain; " + note
        out.append(
            Measurement(
                name,
                name,
                nan,
                nan,
                seconds,
                np.asarray(r.external, dtype=float),
                np.asarray(r.internal_magnitude, dtype=float),
                r.energy_before,
                r.energy_after,
                tuple(r.active),
                0,
                note,
            )
        )
    seq, seconds = _time(
        lambda: sequential_impacts(tree, scene, SequentialSettings(), terrain, base_x), repeats, budget
    )
    out.append(
        Measurement(
            "sequential",
            "sequential",
            nan,
            nan,
            seconds,
            seq.external,
            seq.internal_magnitude,
            seq.energy_before,
            seq.energy_after,
            seq.touchdown_order,
            0,
            f"{len(seq.events)} impact(s) at t = " + ", ".join(f"{e.time * 1e3:.3f} ms" for e in seq.events),
        )
    )
    for law, stiffnesses in ((ContactLaw.PENALTY, penalty_stiffness), (ContactLaw.CONSTRAINT, constraint_stiffness)):
        unit = "N/m" if law is ContactLaw.PENALTY else "1/s^2"
        for n in steps_per_period:
            for k in stiffnesses:
                st = CompliantSettings(law=law, stiffness=k, steps_per_period=n, record=False)
                c, seconds = _time(lambda st=st: simulate_impact(tree, scene, st, terrain, base_x), repeats, budget)
                rung = f"compliant-{law.value}"
                out.append(
                    Measurement(
                        rung,
                        f"{rung} k={k:.0e} {unit}, {n:g} steps",
                        k,
                        n,
                        seconds,
                        c.external,
                        c.internal_magnitude,
                        c.energy_before,
                        c.energy_after,
                        c.touchdown_order,
                        c.n_steps + c.n_flight_steps,
                        f"{c.status.value}; dt = {c.timestep:.2e} s; duration {c.duration * 1e3:.3f} ms; "
                        f"{c.n_steps} contact + {c.n_flight_steps} flight steps"
                        + ("; ENERGY GAIN" if c.energy_gain else "")
                        + (f"; recontacting {c.recontacting}" if c.recontacting else ""),
                    )
                )
                if include_mujoco and law is ContactLaw.CONSTRAINT:
                    from optimizer.validation.mujoco_bridge import drop

                    steps = int(round(c.duration / c.timestep))
                    mj, seconds = _time(
                        lambda st=st, c=c, steps=steps: drop(tree, scene, st, steps, c.timestep, terrain, base_x),
                        repeats,
                        budget,
                    )
                    out.append(
                        Measurement(
                            "mujoco",
                            f"mujoco k={k:.0e} 1/s^2, {n:g} steps",
                            k,
                            n,
                            seconds,
                            mj.external,
                            mj.internal_magnitude,
                            c.energy_before,
                            math.nan,
                            tuple(int(i) for i in np.argsort(mj.touchdown_time) if np.isfinite(mj.touchdown_time[i])),
                            mj.n_steps,
                            "MuJoCo, the constraint law's softness and step (also in free flight); "
                            "time includes the Python loop",
                        )
                    )
    return out


def _error(x: np.ndarray, ref: np.ndarray) -> float:
    scale = float(np.max(np.abs(ref))) if ref.size else 0.0
    if not ref.size:
        return 0.0
    return float(np.max(np.abs(x - ref)) / (scale if scale > 0 else 1.0))


def _differs(m: Measurement, ref: Measurement, contacts: tuple[str, ...], joints: tuple[str, ...]) -> str:
    notes = []
    for kind, values, refs, names in (
        ("external", m.external, ref.external, contacts),
        ("internal", m.internal, ref.internal, joints),
    ):
        floor = DIFFERS_FLOOR * (float(np.max(np.abs(refs))) if refs.size else 0.0)
        for name, x, r in zip(names, values, refs):
            if not np.isfinite(x):
                notes.append(f"{kind} {name} n/a")
            elif abs(x - r) > max(DIFFERS_RELATIVE * abs(r), floor):
                notes.append(f"{kind} {name} " + (f"{(x / r - 1) * 100:+.1f} %" if r else f"{x:+.3g} (ref 0)"))
    if m.touchdown_order and ref.touchdown_order and m.touchdown_order != ref.touchdown_order:
        notes.append(f"touchdown order {m.touchdown_order} (ref {ref.touchdown_order})")
    if np.isfinite(m.energy_after) and m.energy_after > m.energy_before * (1 + 1e-9):
        notes.append("energy gain")
    return "; ".join(notes)


def accuracy_report(scene_name: str, tree: Tree, measurements: Sequence[Measurement]) -> AccuracyReport:
    """Errors of every measurement against the finest model and the rigid limit."""
    contacts, joints = _names(tree)
    finest = [m for m in measurements if m.rung == "compliant-penalty"]
    if not finest:
        finest = [m for m in measurements if m.rung.startswith("compliant")]
    reference = max(finest, key=lambda m: (m.stiffness, m.steps_per_period))
    rigid = next(m for m in measurements if m.rung == "sequential")
    base = [m for m in measurements if m.rung == "newton" and np.isfinite(m.seconds)]
    rigid_times = [m.seconds for m in measurements if m.n_steps == 0 and np.isfinite(m.seconds)]
    unit = base[0].seconds if base else min(rigid_times)
    rows = []
    for m in measurements:
        rows.append(
            AccuracyRow(
                measurement=m,
                external_error=_error(m.external, reference.external),
                internal_error=_error(m.internal, reference.internal),
                external_error_rigid=_error(m.external, rigid.external),
                internal_error_rigid=_error(m.internal, rigid.internal),
                energy_error=(m.energy_after - reference.energy_after) / reference.energy_before,
                speed_ratio=m.seconds / unit,
                differs=_differs(m, reference, contacts, joints),
            )
        )
    return AccuracyReport(scene_name, reference.label, rigid.label, contacts, joints, tuple(rows))


def measure_accuracy(
    scene_name: str,
    tree: Tree,
    scene: Scene,
    terrain: Terrain | None = None,
    base_x: float | None = None,
    **kwargs,
) -> AccuracyReport:
    """Measure every rung on the scene (:func:`measure`, same keyword arguments) and compare."""
    return accuracy_report(scene_name, tree, measure(tree, scene, terrain, base_x, **kwargs))


# --------------------------------------------------------------------------------------------
# Output


CSV_FIELDS = (
    "scene",
    "rung",
    "label",
    "stiffness",
    "steps_per_period",
    "seconds",
    "speed_ratio",
    "external_error",
    "internal_error",
    "external_error_rigid",
    "internal_error_rigid",
    "energy_before",
    "energy_after",
    "energy_error",
    "n_steps",
    "touchdown_order",
    "differs",
    "note",
)


def write_csv(report: AccuracyReport, path: str | Path) -> Path:
    """One line per measurement: settings, time, errors, then every impulse (N s)."""
    path = Path(path)
    extra = [f"external_{n}" for n in report.contact_names] + [f"internal_{n}" for n in report.joint_names]
    with path.open("w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow([*CSV_FIELDS, *extra])
        for r in report.rows:
            m = r.measurement
            w.writerow(
                [
                    report.scene,
                    m.rung,
                    m.label,
                    f"{m.stiffness:.6g}",
                    f"{m.steps_per_period:.6g}",
                    f"{m.seconds:.6g}",
                    f"{r.speed_ratio:.6g}",
                    f"{r.external_error:.4e}",
                    f"{r.internal_error:.4e}",
                    f"{r.external_error_rigid:.4e}",
                    f"{r.internal_error_rigid:.4e}",
                    f"{m.energy_before:.10g}",
                    f"{m.energy_after:.10g}",
                    f"{r.energy_error:.4e}",
                    m.n_steps,
                    " ".join(str(i) for i in m.touchdown_order),
                    r.differs,
                    m.note,
                    *[f"{x:.8g}" for x in (*m.external, *m.internal)],
                ]
            )
    return path


_STYLE = {
    "decoupled": ("s", "tab:gray"),
    "newton": ("D", "tab:blue"),
    "lcp": ("^", "tab:cyan"),
    "friction": ("v", "tab:purple"),
    "sequential": ("*", "black"),
    "compliant-penalty": ("o", "tab:orange"),
    "compliant-constraint": ("o", "tab:green"),
    "mujoco": ("x", "tab:red"),
}


def plot(report: AccuracyReport, path: str | Path) -> Path:
    """Error vs time per evaluation (log-log): against the finest model (top) and the rigid limit
    (bottom), external (left) and internal (right) impulses; the compliant settings of one step
    count are joined across stiffness (labelled at the largest step count). A model compared with
    itself (error 0) is left out."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.ticker import NullFormatter

    floor = 1e-6  # errors below this (the rigid rungs that equal the limit to rounding) are drawn here
    fig = Figure(figsize=(11, 8.2))
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, 2)
    max_steps = max(
        (r.measurement.steps_per_period for r in report.rows if np.isfinite(r.measurement.steps_per_period)),
        default=1.0,
    )
    panels = (
        ("external_error", f"external impulses vs finest ({report.reference})"),
        ("internal_error", "internal (joint) impulses vs finest"),
        ("external_error_rigid", f"external impulses vs rigid limit ({report.rigid_limit})"),
        ("internal_error_rigid", "internal (joint) impulses vs rigid limit"),
    )
    for ax, (attr, title) in zip(axes.ravel(), panels):
        groups: dict[tuple[str, float], list[AccuracyRow]] = {}
        for r in report.rows:
            if np.isfinite(r.measurement.seconds) and getattr(r, attr) > 0:
                groups.setdefault((r.measurement.rung, r.measurement.steps_per_period), []).append(r)
        for (rung, n), rows in sorted(groups.items(), key=lambda kv: (kv[0][0], np.nan_to_num(kv[0][1]))):
            marker, color = _STYLE.get(rung, ("o", "tab:brown"))
            xs = [r.measurement.seconds for r in rows]
            ys = [max(getattr(r, attr), floor) for r in rows]
            compliant = np.isfinite(n)
            label = f"{rung}, {n:g} steps/period" if compliant else rung
            alpha = (
                0.3 + 0.7 * math.log(n / min(n, 15.0) + 1.0) / math.log(max_steps / 15.0 + 1.0) if compliant else 1.0
            )
            ax.plot(
                xs,
                ys,
                marker=marker,
                color=color,
                alpha=min(alpha, 1.0),
                label=label,
                linestyle="-" if compliant else "none",
                markersize=6,
            )
            if compliant and n == max_steps:
                for r, x, y in zip(rows, xs, ys):
                    ax.annotate(
                        f"{r.measurement.stiffness:.0e}", (x, y), fontsize=6, xytext=(3, 3), textcoords="offset points"
                    )
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.yaxis.set_minor_formatter(NullFormatter())
        ax.set_xlabel("time per evaluation (s)")
        ax.set_ylabel(f"error (relative to the largest entry; < {floor:g} drawn at {floor:g})", fontsize=7)
        ax.set_title(title, fontsize=8)
        ax.axhline(0.01, color="0.6", lw=0.8, ls=":")
        ax.grid(True, which="major", alpha=0.3)
    axes[0, 1].legend(fontsize=6, loc="best", ncol=2)
    fig.suptitle(f"{report.scene}: speed and accuracy of the impact-model ladder (labels: stiffness)", fontsize=10)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=120)
    return path


def format_table(report: AccuracyReport, rungs: Sequence[str] | None = None, steps: float | None = None) -> str:
    """A Markdown table: rung, setting, time ratio, errors; optionally only some rungs or one
    step count for the compliant rows."""
    lines = [
        "| rung / setting | time / Newton | ext. err vs finest | int. err vs finest "
        "| ext. err vs rigid limit | int. err vs rigid limit | differs (vs finest) |",
        "|---|---:|---:|---:|---:|---:|---|",
    ]
    for r in report.rows:
        m = r.measurement
        if rungs is not None and m.rung not in rungs:
            continue
        if steps is not None and np.isfinite(m.steps_per_period) and m.steps_per_period != steps:
            continue
        differs = r.differs if len(r.differs) < 90 else r.differs[:87] + "..."
        lines.append(
            f"| {m.label} | {r.speed_ratio:,.0f} | {r.external_error:.1e} | {r.internal_error:.1e} | "
            f"{r.external_error_rigid:.1e} | {r.internal_error_rigid:.1e} | {differs} |"
        )
    return "\n".join(lines)


__all__ = [
    "AccuracyReport",
    "AccuracyRow",
    "Measurement",
    "accuracy_report",
    "format_table",
    "measure",
    "measure_accuracy",
    "plot",
    "write_csv",
]
