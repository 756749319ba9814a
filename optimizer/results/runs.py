"""Run directories: where a study's storage, resolved config, versions and Pareto front live.

A run directory holds (names fixed: outside checks read them):

- ``study.yaml``: the resolved study (every default explicit; ``search.trials`` as last run);
- ``study.journal``: the Optuna journal storage (unless the study names another storage);
- ``run.json``: versions, seed, storage, method, trial counts, wall time;
- ``pareto.csv``, ``pareto.json``: one row/entry per Pareto design: every objective, every
  constraint value, the design's values, and ``model_file``, the path of its model file
  relative to the run directory;
- ``designs/trial_<n>.yaml``: each Pareto design as a ``MODEL_FORMAT.md`` model file, and beside it
  ``trial_<n>.urdf`` and ``trial_<n>.xml`` (MJCF), the same design at its touchdown
  (:mod:`optimizer.results.export`);
- ``front.png``: the front in the first two objectives, over every evaluated design;
- ``scenarios.csv``, ``scenarios.png`` (a study with ``landings``): each front design on each
  landing, and its distribution of each objective (:mod:`optimizer.results.scenarios`);
- ``report.html``: the same front as a self-contained page: each Pareto design's values, leg
  drawing (``designs/trial_<n>.png``) and files a click away, the objectives table, the study.

footopt never removes a file it did not write: a directory holding anything else is refused
unless it is a run of the same study (then the run resumes) or ``force`` is given (then this
run's own files are replaced; other files stay).
"""

from __future__ import annotations

import csv
import io
import json
import platform
import signal
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, replace
from enum import Enum
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
import optuna

from impulse_core.evaluate import evaluate, touchdown_geometry
from impulse_core.kinematics.spatial import PLANAR
from optimizer.config.model_file import Reference, dump_model_file
from optimizer.config.study_config import StudyConfig, format_study, load_study, redact_url
from optimizer.design_space import (
    CONSTRAINT_FIELDS,
    DesignEvaluation,
    Objective,
    chain_names,
    foot_geometry,
    foot_support_margin,
    design_model,
    foot_space,
    foot_tree,
    landing_scene,
)
from optimizer.errors import ConfigError
from optimizer.results.export import ExportFormat, export_text
from optimizer.report.html import REPORT_FILE, ReportPoint, write_report
from optimizer.report.plot import PNG_COMPRESSION, plot_top_views, plot_touchdown, plot_views, preload_matplotlib
from optimizer.workers import cores, forked_pool
from optimizer.results.pareto import non_dominated
from optimizer.results.scenarios import SCENARIOS_FILE, SCENARIOS_PLOT, write_scenarios
from optimizer.search.outer import RecordedTrial, recorded_trials

STUDY_FILE, STORAGE_FILE, RUN_FILE = "study.yaml", "study.journal", "run.json"
CSV_FILE, JSON_FILE, PLOT_FILE, DESIGNS_DIR = "pareto.csv", "pareto.json", "front.png", "designs"
#: A spatial study's front designs seen from above (support polygons, centres of mass).
TOP_VIEW_FILE = "top_views.png"
#: Files footopt writes in a run directory (and may replace).
OWN_FILES = (STUDY_FILE, STORAGE_FILE, RUN_FILE, CSV_FILE, JSON_FILE, PLOT_FILE, REPORT_FILE, SCENARIOS_FILE,
             SCENARIOS_PLOT, TOP_VIEW_FILE)
#: The objective columns of every front file: the first impact's, and the whole landing's when
#: the study scores it (:func:`objective_columns`).
OBJECTIVE_COLUMNS = tuple(o.value for o in Objective if not o.landing)
LANDING_COLUMNS = tuple(o.value for o in Objective if o.landing)
#: The files of one Pareto design in ``designs/``: its model file, then its exports.
DRAWING_SUFFIX = ".png"  # each Pareto design's leg at touchdown, beside its files
DESIGN_SUFFIXES = (".yaml", *(f.suffix for f in ExportFormat), DRAWING_SUFFIX)
#: Seconds after which the journal's lock file counts as left behind by a killed run.
JOURNAL_LOCK_GRACE_S = 3


class RunState(Enum):
    """What :func:`prepare_run` found in the directory."""

    FRESH = "fresh"
    RESUME = "resume"


def storage_url(run_dir: Path, config: StudyConfig) -> str | optuna.storages.BaseStorage:
    """The study's storage: its URL, or the journal file in the run directory."""
    if config.storage is not None:
        return config.storage
    from optuna.storages import JournalStorage
    from optuna.storages.journal import JournalFileBackend, JournalFileSymlinkLock

    path = str(run_dir / STORAGE_FILE)
    # A killed run leaves its lock behind; a write holds it for milliseconds, so a lock older
    # than the grace period is stale (Optuna's default waits 30 s before breaking it).
    lock = _interrupt_safe(JournalFileSymlinkLock)(path, grace_period=JOURNAL_LOCK_GRACE_S)
    return JournalStorage(JournalFileBackend(path, lock_obj=lock))


def _interrupt_safe(lock_type: type) -> type:
    """``lock_type`` with Ctrl-C held back from acquire to release.

    Optuna's lock release is not atomic under Ctrl-C: an interrupt between its rename and unlink
    replaces the KeyboardInterrupt with a FileNotFoundError. While the lock is held (a journal
    write: milliseconds) a SIGINT is only recorded, and raised again right after release. Signal
    handlers belong to the main thread: elsewhere the lock is Optuna's own.
    """

    class InterruptSafeLock(lock_type):  # type: ignore[misc, valid-type]
        _handler: object = None  # the SIGINT handler to restore; None when not deferring
        _deferred = False

        def _defer(self, signum: int, frame: object) -> None:
            self._deferred = True

        def acquire(self) -> bool:
            handler = None
            if threading.current_thread() is threading.main_thread():
                self._deferred = False
                handler = signal.signal(signal.SIGINT, self._defer)
            try:
                got = super().acquire()  # may call release() to break a stale lock
            except BaseException:
                self._handler = handler
                self._restore()
                raise
            self._handler = handler
            return got

        def release(self) -> None:
            try:
                super().release()
            finally:
                self._restore()

        def _restore(self) -> None:
            handler, self._handler = self._handler, None
            if handler is not None:
                signal.signal(signal.SIGINT, handler)
                if self._deferred:
                    signal.raise_signal(signal.SIGINT)

    return InterruptSafeLock


def _own(path: Path) -> bool:
    return path.name in OWN_FILES or path.name == DESIGNS_DIR or path.name.startswith(f"{STORAGE_FILE}.")


def prepare_run(run_dir: Path, config: StudyConfig, force: bool = False) -> RunState:
    """Check (and create) the run directory for ``config``.

    Returns:
        FRESH for a new or empty directory (or with ``force``: this run's old files removed),
        RESUME when it holds a run of the same study (``search.trials`` may differ).

    Raises:
        ConfigError: the directory holds other files, or a run of a different study, and
            ``force`` is False; or it is not a directory.
    """
    if run_dir.exists() and not run_dir.is_dir():
        raise ConfigError("exists and is not a directory", run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    entries = sorted(run_dir.iterdir())
    if not entries:
        return RunState.FRESH
    if force:
        remove_own_files(run_dir, config)
        return RunState.FRESH
    previous_file = run_dir / STUDY_FILE
    if not previous_file.exists():
        names = ", ".join(p.name for p in entries[:3]) + (", ..." if len(entries) > 3 else "")
        raise ConfigError(
            f"not empty and not a footopt run ({names}); choose another --out, or pass --force to "
            "write this run's files there anyway",
            run_dir,
        )
    previous = load_study(previous_file)
    different = _differences(previous, config)
    if different:
        verb = "differs" if len(different) == 1 else "differ"
        raise ConfigError(
            f"holds a run of a different study ({', '.join(different)} {verb}); choose another --out, "
            "or pass --force to start this study over there",
            run_dir,
        )
    return RunState.RESUME


def _differences(a: StudyConfig, b: StudyConfig) -> list[str]:
    """Top-level fields in which two studies differ (``search.trials`` excepted)."""
    a = replace(a, search=replace(a.search, trials=0))
    b = replace(b, search=replace(b.search, trials=0))
    return [
        name
        for name in ("name", "seed", "storage", "scene", "leg", "space", "limits", "objectives", "search")
        if getattr(a, name) != getattr(b, name)
    ]


def remove_own_files(run_dir: Path, config: StudyConfig) -> None:
    """Remove what a previous run wrote (and its study, from an external storage)."""
    if config.storage is not None:
        try:
            optuna.delete_study(study_name=config.name, storage=config.storage)
        except KeyError:
            pass
    for p in run_dir.iterdir():
        if p.name == DESIGNS_DIR and p.is_dir():
            _remove_designs(p)
            if not any(p.iterdir()):
                p.rmdir()
        elif _own(p) and p.is_file():
            p.unlink()


def _remove_designs(designs: Path) -> None:
    """Remove the design files footopt wrote (``trial_*`` with a suffix of ``DESIGN_SUFFIXES``)."""
    for f in designs.glob("trial_*"):
        if f.suffix in DESIGN_SUFFIXES and f.is_file():
            f.unlink()


def write_study_file(run_dir: Path, config: StudyConfig) -> Path:
    path = run_dir / STUDY_FILE
    header = (
        "The resolved study of this run (every default explicit). Resume: footopt optimize this-file --out this-dir"
    )
    path.write_text(format_study(config, header), encoding="utf-8")
    return path


def versions() -> dict[str, str]:
    """Versions of what made a run."""
    out = {"python": platform.python_version()}
    for package in ("footopt", "optuna", "casadi", "numpy", "scipy"):
        try:
            out[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            out[package] = "not installed"
    return out


def write_run_file(run_dir: Path, config: StudyConfig, **extra: Any) -> Path:
    """``run.json``: versions, seed, storage and whatever the caller adds (counts, times)."""
    record = {
        "study": config.name,
        "seed": config.seed,
        "method": config.search.method.value,
        "sampler": config.search.sampler.value,
        "storage": redact_url(config.storage) if config.storage else STORAGE_FILE,
        "versions": versions(),
        "command": " ".join(redact_url(a) for a in sys.argv),  # a storage URL's password never lands here
        **extra,
    }
    path = run_dir / RUN_FILE
    path.write_text(json.dumps(record, indent=2) + "\n", encoding="utf-8")
    return path


# --------------------------------------------------------------------------------------------
# The front


@dataclass(frozen=True)
class FrontPoint:
    """One exported Pareto design.

    Attributes:
        trial: its Optuna trial number.
        method: outer or inner.
        evaluation: design, objectives, constraint values.
        model_file: its model file, relative to the run directory.
    """

    trial: int
    method: str
    evaluation: DesignEvaluation
    model_file: Path


def pareto_front(config: StudyConfig, trials: list[RecordedTrial]) -> list[RecordedTrial]:
    """The feasible trials that no other feasible trial dominates in the study's objectives
    (coinciding points once), ordered by the first objective."""
    feasible = [t for t in trials if t.evaluation.feasible]
    if not feasible:
        return []
    values = np.array([[t.evaluation.objectives.score(o) for o in config.objectives] for t in feasible])
    return [feasible[i] for i in non_dominated(values)]


def objective_columns(config: StudyConfig) -> tuple[str, ...]:
    """The objective columns of the study's front files."""
    return OBJECTIVE_COLUMNS + (LANDING_COLUMNS if config.whole_landing else ())


def export_front(run_dir: Path, config: StudyConfig, study: optuna.Study) -> list[FrontPoint]:
    """Write the front's files (CSV, JSON, model files, plot) and return its points."""
    trials = list(recorded_trials(study))
    front = pareto_front(config, trials)
    designs = run_dir / DESIGNS_DIR
    designs.mkdir(exist_ok=True)
    _remove_designs(designs)
    points, drawings = [], []
    scene = landing_scene(config.scene, config.limits)
    for t in front:
        rel = Path(DESIGNS_DIR) / f"trial_{t.number:05d}.yaml"
        design = t.evaluation.design
        tree, space = foot_tree(config.leg, design), foot_space(config.leg, design)
        result = evaluate(tree, scene, space=space)
        reference = Reference(
            source=f"footopt optimize, study '{config.name}', trial {t.number} ({t.method} search)",
            external=tuple(float(x) for x in result.external),
            internal=tuple(float(x) for x in result.internal_magnitude),
            external_norm=result.external_norm,
            internal_norm=result.internal_norm,
        )
        header = (
            f"Pareto design of study '{config.name}' (trial {t.number}, shape {t.evaluation.design.shape.label}).\n"
            "Lengths were chosen by footopt's linear program; with uniform rods the impulses do not depend on\n"
            "them, only on the angles and masses (and the touchdown constraints on the lengths)."
        )
        if config.whole_landing:
            header += (
                f"\nThe whole landing (scene.duration) at footopt evaluate --tolerance {config.search.landing_tolerance!r} "
                "gives the front's landing figures."
            )
        model = replace(design_model(config.leg, t.evaluation.design, config.scene, config.limits,
                                     config.space.joint_laws.stop_restitution), reference=reference)
        dump_model_file(model, run_dir / rel, header_comment=header)
        for fmt in ExportFormat:
            extra = {"space": space} if space is not PLANAR else {}
            text = export_text(tree, scene, fmt, name=rel.stem, joints=model.joints, **extra)
            (run_dir / rel).with_suffix(fmt.suffix).write_text(text, encoding="utf-8")
        title = f"trial {t.number} ({t.evaluation.design.shape.label})"
        drawing = run_dir / rel.with_suffix(DRAWING_SUFFIX)
        if space is not PLANAR:
            drawings.append((plot_views, (tree, touchdown_geometry(tree, space), result, drawing, title)))
        else:
            drawings.append((plot_touchdown, (tree, touchdown_geometry(tree), result, drawing, title, scene)))
        points.append(FrontPoint(t.number, t.method, t.evaluation, rel))
    with _drawn(drawings):
        _write_front_files(run_dir, config, trials, points)
    return points


@contextmanager
def _drawn(drawings: list[tuple[Callable, tuple]]) -> Iterator[None]:
    """Make every drawing (function, arguments): in forked workers (:mod:`optimizer.workers`)
    while the body runs, or here after it; any error a drawing raised is raised on leaving."""
    global _DRAWINGS
    if drawings:
        preload_matplotlib()  # once, before the workers fork
    _DRAWINGS = drawings  # the workers fork as the pool starts and find them here
    try:
        with forked_pool(min(cores(), len(drawings))) as pool:
            jobs = [pool.submit(_draw, i) for i in range(len(drawings))] if pool is not None else []
            yield
            for job in jobs:
                job.result()
    finally:
        _DRAWINGS = []
    if not jobs:
        for f, args in drawings:
            f(*args)


_DRAWINGS: list[tuple[Callable, tuple]] = []


def _draw(i: int) -> None:
    f, args = _DRAWINGS[i]
    f(*args)


def _write_front_files(
    run_dir: Path, config: StudyConfig, trials: list[RecordedTrial], points: list[FrontPoint]
) -> None:
    """The front's CSV, JSON, scenarios, top views, plot and page (or none of the last ones); the
    page shows the plots, so it comes last."""
    (run_dir / CSV_FILE).write_text(front_csv(config, points), encoding="utf-8")
    (run_dir / JSON_FILE).write_text(json.dumps(front_json(config, points), indent=2) + "\n", encoding="utf-8")
    if points and config.landings is not None:
        designs = [(p.model_file.stem, p.evaluation.design) for p in points]
        write_scenarios(run_dir, config, objective_columns(config), designs)
    if points and config.space.spatial:
        feet = [(f"trial {p.trial} ({p.evaluation.design.shape.label})", foot_tree(config.leg, p.evaluation.design))
                for p in points]
        plot_top_views(feet, run_dir / TOP_VIEW_FILE)
    else:
        (run_dir / TOP_VIEW_FILE).unlink(missing_ok=True)
    if points:
        plot_front(run_dir / PLOT_FILE, config, trials, points)
        write_front_report(run_dir, config, trials, points)
    else:  # no empty plot or page: the command says why nothing is shown
        (run_dir / PLOT_FILE).unlink(missing_ok=True)
        (run_dir / REPORT_FILE).unlink(missing_ok=True)


def write_front_report(run_dir: Path, config: StudyConfig, trials: list[RecordedTrial], points: list[FrontPoint]) -> Path:
    """``report.html``: the front's page (:mod:`optimizer.report.html`)."""
    names = [o.value for o in config.objectives]
    columns = objective_columns(config)
    front = {p.trial for p in points}

    def xy(t: RecordedTrial) -> tuple[float, float]:
        o = t.evaluation.objectives
        return (o.value(config.objectives[0]), o.value(config.objectives[1])) if len(names) > 1 else (
            float(t.number), o.value(config.objectives[0]))

    others = [xy(t) for t in trials if t.evaluation.feasible and t.number not in front]
    shown = []
    for p in points:
        ev = p.evaluation
        values = {n: ev.objectives.value(Objective(n)) for n in names + [c for c in columns if c not in names]}
        files = {"model file": p.model_file.as_posix()}
        files |= {f.name.upper(): p.model_file.with_suffix(f.suffix).as_posix() for f in ExportFormat}
        files["drawing"] = p.model_file.with_suffix(DRAWING_SUFFIX).as_posix()
        shown.append(ReportPoint(p.trial, ev.design.shape.label, values, design_values(config, ev), files))
    figures = [f for f in (PLOT_FILE, SCENARIOS_PLOT, TOP_VIEW_FILE) if (run_dir / f).exists()]
    return write_report(run_dir / REPORT_FILE, config.name, names, shown, others, format_study(config), figures)


def design_values(config: StudyConfig, evaluation: DesignEvaluation) -> dict[str, float]:
    """The design's values by name (``toe1_distal.mass``), plus its ankle height and foot length."""
    design = evaluation.design
    out: dict[str, float] = {}
    for names, chain in zip(chain_names(design.shape), design.chains, strict=True):
        for name, s in zip(names, chain, strict=True):
            out[f"{name}.length"] = s.length
            out[f"{name}.mass"] = s.mass
            out[f"{name}.joint_angle"] = s.joint_angle
            if config.whole_landing:
                out[f"{name}.stiffness"] = s.stiffness
                out[f"{name}.damping"] = s.damping
                if s.stop is not None:  # no stops: no column value
                    out[f"{name}.stop"] = s.stop
    geo = foot_geometry(config.leg, design)
    out["ankle_height"] = -geo.ground
    out["foot_length"] = float(geo.reaches.max())
    out["foot_mass"] = design.foot_mass
    if design.toe_yaws is not None:  # a splayed foot: each toe's yaw (rad) and its support margin (m)
        out.update({f"toe{i + 1}.yaw": float(y) for i, y in enumerate(design.toe_yaws)})
        out["support_margin"] = foot_support_margin(config.leg, design)
    return out


def _row(config: StudyConfig, p: FrontPoint) -> dict[str, Any]:
    ev = p.evaluation
    shape = ev.design.shape
    row: dict[str, Any] = {
        "trial": p.trial,
        "method": p.method,
        "shape": shape.label,
        "toes": shape.n_toes,
        "toe_segments": shape.toe_segments,
        "heel_segments": shape.heel_segments,
    }
    row.update({name: ev.objectives.value(Objective(name)) for name in objective_columns(config)})
    row["model_file"] = p.model_file.as_posix()
    row.update({f"constraint.{name}": v for name, v in ev.constraints.items()})
    row.update(design_values(config, ev))
    return row


def front_csv(config: StudyConfig, points: list[FrontPoint]) -> str:
    """``pareto.csv``: one row per Pareto design; design columns are the union over shapes
    (empty where a design has no such rod)."""
    rows = [_row(config, p) for p in points]
    columns: list[str] = ["trial", "method", "shape", "toes", "toe_segments", "heel_segments", *objective_columns(config)]
    columns += ["model_file"] + [f"constraint.{n}" for n in _constraint_names(config)]
    for row in rows:
        columns += [k for k in row if k not in columns]
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=columns, restval="", lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: (repr(v) if isinstance(v, float) else v) for k, v in row.items()})
    return buffer.getvalue()


def _constraint_names(config: StudyConfig) -> list[str]:
    """The constraint columns: every constraint value, ``support_margin`` only where the study
    constrains it."""
    from dataclasses import fields

    from optimizer.design_space import ConstraintValues, SupportConstraintValues

    kind = ConstraintValues if config.limits.support_margin is None else SupportConstraintValues
    return [f.name for f in fields(kind)]


def front_json(config: StudyConfig, points: list[FrontPoint]) -> dict[str, Any]:
    """``pareto.json``: the study's objectives and one entry per Pareto design."""
    entries = []
    for p in points:
        ev = p.evaluation
        shape = ev.design.shape
        entries.append(
            {
                "trial": p.trial,
                "method": p.method,
                "shape": {
                    "toes": shape.n_toes,
                    "toe_segments": shape.toe_segments,
                    "heel_segments": shape.heel_segments,
                },
                "objectives": {name: ev.objectives.value(Objective(name)) for name in objective_columns(config)},
                "constraints": dict(ev.constraints.items()),
                "design": design_values(config, ev),
                "model_file": p.model_file.as_posix(),
            }
        )
    return {"study": config.name, "objectives": [o.value for o in config.objectives], "designs": entries}


def plot_front(path: Path, config: StudyConfig, trials: list[RecordedTrial], points: list[FrontPoint]) -> Path:
    """The front in the first two objectives (or the one objective against the trial number),
    every evaluated design behind it, front points coloured by toe count."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.5, 5.5))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    objs = config.objectives
    two = len(objs) > 1

    def xy(ev: DesignEvaluation, number: int) -> tuple[float, float]:
        o = ev.objectives
        return (o.value(objs[0]), o.value(objs[1])) if two else (float(number), o.value(objs[0]))

    feasible = [xy(t.evaluation, t.number) for t in trials if t.evaluation.feasible]
    infeasible = [xy(t.evaluation, t.number) for t in trials if not t.evaluation.feasible]
    if infeasible:
        ax.scatter(*zip(*infeasible), s=8, marker="x", color="#dddddd", label="infeasible", zorder=1)
    if feasible:
        ax.scatter(*zip(*feasible), s=10, color="#999999", alpha=0.6, label="feasible", zorder=2)
    if points:
        toes = sorted({p.evaluation.design.shape.n_toes for p in points})
        cmap = __import__("matplotlib").colormaps["viridis"]
        for n in toes:
            sel = [xy(p.evaluation, p.trial) for p in points if p.evaluation.design.shape.n_toes == n]
            color = cmap((n - toes[0]) / max(1, toes[-1] - toes[0]))
            ax.scatter(*zip(*sel), s=42, color=color, edgecolor="black", zorder=3, label=f"Pareto, {n} toe(s)")
        if two and objs[0].sign > 0 and objs[1].sign > 0:  # the staircase of a minimised pair
            line = sorted(xy(p.evaluation, p.trial) for p in points)
            ax.plot(*zip(*line), color="black", lw=0.8, zorder=2.5, drawstyle="steps-post")
    everything = np.array(feasible + [xy(p.evaluation, p.trial) for p in points])
    if everything.size and np.all(everything > 0):  # impulses span decades: log axes then
        low, high = everything.min(axis=0), everything.max(axis=0)
        if two and high[0] > 20 * low[0]:
            ax.set_xscale("log")
        if high[1] > 20 * low[1]:
            ax.set_yscale("log")
    unit = {"energy_after": "J", "base_angular_velocity": "rad/s", "settled_at": "s", "energy_absorbed": "fraction"}
    label = lambda o: f"{o.value} ({unit.get(o.value, 'N s')})"
    ax.set_xlabel(label(objs[0]) if two else "trial")
    ax.set_ylabel(label(objs[1]) if two else label(objs[0]))
    ax.set_title(f"study '{config.name}': {plural(len(points), 'Pareto design')} of {len(trials)} evaluated")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="upper right")
    fig.tight_layout()
    fig.savefig(path, dpi=110, pil_kwargs={"compress_level": PNG_COMPRESSION})
    return path


def format_front(config: StudyConfig, points: list[FrontPoint]) -> str:
    """The front as a text table: shape, every objective, model file."""
    columns = objective_columns(config)
    header = f"{'trial':>6} {'shape':>7} " + " ".join(f"{c:>21}" for c in columns) + "  model_file"
    lines = [header]
    for p in points:
        o = p.evaluation.objectives
        values = " ".join(f"{o.value(Objective(c)):>21.6g}" for c in columns)
        lines.append(f"{p.trial:>6} {p.evaluation.design.shape.label:>7} {values}  {p.model_file.as_posix()}")
    aims = ", ".join(("maximising " if o.sign < 0 else "") + o.value for o in config.objectives)
    head = f"study '{config.name}': {plural(len(points), 'Pareto design')} (minimising {aims})"
    return head + "\n" + "\n".join(lines) + "\n"


def plural(n: int, noun: str) -> str:
    """``1 Pareto design``, ``2 Pareto designs``."""
    return f"{n} {noun}{'' if n == 1 else 's'}"


def infeasible_summary(study: optuna.Study) -> str:
    """Why a study has no feasible design: the constraints its designs missed, most often first."""
    trials = list(recorded_trials(study))
    shapes: dict[str, list[str]] = {}
    for key, why in study.user_attrs.items():
        if key.startswith("infeasible:"):
            shapes.setdefault(str(why), []).append(key.split(":", 1)[1])
    if not trials:
        why = [f"{reason} (shapes {', '.join(labels)})" for reason, labels in shapes.items()]
        return "no feasible design: " + ("; ".join(why) or "no design was evaluated")
    missed: dict[str, int] = {}
    for t in trials:
        for name, v in t.evaluation.constraints.violations():
            if v > 0:
                missed[name] = missed.get(name, 0) + 1
    failed = sum(t.evaluation.objectives is None for t in trials)
    parts = [
        f"{CONSTRAINT_FIELDS.get(n) or n + ' (physics)'} missed by {k} of {len(trials)}"
        for n, k in sorted(missed.items(), key=lambda nk: -nk[1])
    ]
    if failed:
        parts.append(f"{failed} of {len(trials)} impact solves failed numerically")
    return f"no feasible design among {plural(len(trials), 'evaluated design')}: " + "; ".join(parts or ["?"])


__all__ = [
    "CSV_FILE",
    "DESIGNS_DIR",
    "DESIGN_SUFFIXES",
    "JSON_FILE",
    "PLOT_FILE",
    "RUN_FILE",
    "STORAGE_FILE",
    "STUDY_FILE",
    "FrontPoint",
    "RunState",
    "design_values",
    "export_front",
    "format_front",
    "front_csv",
    "front_json",
    "infeasible_summary",
    "pareto_front",
    "plot_front",
    "plural",
    "prepare_run",
    "remove_own_files",
    "storage_url",
    "versions",
    "write_run_file",
    "write_study_file",
]
