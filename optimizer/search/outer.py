"""The outer search: Optuna over the foot's shape and values, every trial kept in a storage.

One trial = one foot: Optuna suggests the shape (toe count, rods per toe and heel), every joint
angle (within its limits) and a mass share per rod; the masses follow from the budget, the
lengths from the linear program of :func:`optimizer.design_space.assign_lengths`. The trial
records its design, all objectives and all constraint values as user attributes, and its
constraint violations with ``trial.set_constraint`` (Optuna 5; TPE and NSGA-II read them).

Trials are asked for in batches (ask/tell) and a batch's designs are evaluated together: the
impact of each kind of foot by its compiled values (:mod:`optimizer.search.compiled`, the same
merged model as the inner search's, one batched C loop per kind), each design once.

Determinism: the sampler is rebuilt before every ask with a seed made from the study's seed and
the trial's place (trials finished before its batch plus its place in the batch), so that a
study run in one go, or interrupted and resumed, asks the same questions and gets the same
answers.
"""

from __future__ import annotations

import functools
import math
import warnings
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from contextlib import AbstractContextManager, nullcontext
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import optuna
from optuna.trial import FrozenTrial, TrialState

from impulse_core.compile.codegen import batch_kernel, compile_function
from optimizer.config.study_config import SamplerKind, SearchSettings, StudyConfig
from optimizer.design_space import (
    DesignEvaluation,
    FootDesign,
    FootLimits,
    FootShape,
    MassMode,
    Objectives,
    Segment,
    FAILED,
    JOINT_FAMILIES,
    NOT_FINITE,
    SplayMode,
    ToeSymmetry,
    constraint_record,
    constraint_values,
    design_from,
    design_model,
    evaluate_design,
    evaluate_design_landing,
    study_landing,
    symmetric_yaws,
)
from optimizer.evaluation.robust import statistics_over_landings_many
from optimizer.interrupts import check_interrupt, interruptible
from optimizer.search.compiled import VALUE_OUTPUTS, FootKind, cache_dir, foot_kind, values_function
from optimizer.search.landing_code import LandingBuilds
from optimizer.workers import cores, forked_pool, mapped

#: User attributes every recorded trial carries.
ATTR_DESIGN, ATTR_OBJECTIVES, ATTR_CONSTRAINTS, ATTR_METHOD = "design", "objectives", "constraints", "method"
#: Set on a trial found RUNNING when a study resumes (its process was killed).
ATTR_INTERRUPTED = "interrupted"
#: Set on a FAIL trial whose design failed: why, in one line (:attr:`DesignEvaluation.failure`).
ATTR_FAILURE = "failure"


# --------------------------------------------------------------------------------------------
# Records: designs and results as plain data in the storage


def design_record(design: FootDesign) -> dict[str, Any]:
    """The design as JSON-able data: ``{"heel": [[L, m, angle], ...], "toes": [[[...]]]}``; a
    rod with a joint law adds ``stiffness, damping, stop`` (stop null: none)."""

    def rod(s: Segment) -> list[float | None]:
        values: list[float | None] = [float(s.length), float(s.mass), float(s.joint_angle)]
        if s.stiffness or s.damping or s.stop is not None:
            values += [float(s.stiffness), float(s.damping), None if s.stop is None else float(s.stop)]
        return values

    record: dict[str, Any] = {"heel": [rod(s) for s in design.heel], "toes": [[rod(s) for s in t] for t in design.toes]}
    if design.toe_yaws is not None:  # a splayed foot: each toe's yaw about the vertical (rad)
        record["toe_yaws"] = [float(y) for y in design.toe_yaws]
    return record


def design_from_record(record: dict[str, Any]) -> FootDesign:
    """Inverse of :func:`design_record`."""

    def rod(values: list[Any]) -> Segment:
        L, m, a, *law = values
        k, c, stop = law or (0.0, 0.0, None)
        return Segment(float(L), float(m), float(a), float(k), float(c), None if stop is None else float(stop))

    def chain(c: list[list[Any]]) -> tuple[Segment, ...]:
        return tuple(rod(v) for v in c)

    yaws = record.get("toe_yaws")
    return FootDesign(heel=chain(record["heel"]), toes=tuple(chain(t) for t in record["toes"]),
                      toe_yaws=None if yaws is None else tuple(float(y) for y in yaws))


@dataclass(frozen=True)
class RecordedTrial:
    """A finished trial as read back from the storage.

    Attributes:
        number: Optuna's trial number.
        method: ``outer`` or ``inner``.
        evaluation: the design, its objectives and its constraint values.
    """

    number: int
    method: str
    evaluation: DesignEvaluation


def read_trial(trial: FrozenTrial) -> RecordedTrial | None:
    """The recorded evaluation of a COMPLETE trial (None for other states or foreign trials)."""
    attrs = trial.user_attrs
    if trial.state is not TrialState.COMPLETE or ATTR_DESIGN not in attrs:
        return None
    objectives = Objectives(**attrs[ATTR_OBJECTIVES])
    constraints = constraint_record(attrs[ATTR_CONSTRAINTS])
    evaluation = DesignEvaluation(design_from_record(attrs[ATTR_DESIGN]), objectives, constraints)
    return RecordedTrial(trial.number, str(attrs.get(ATTR_METHOD, "outer")), evaluation)


def record_attrs(evaluation: DesignEvaluation, method: str) -> dict[str, Any]:
    """User attributes of a trial that evaluated ``evaluation``."""
    assert evaluation.objectives is not None
    return {
        ATTR_METHOD: method,
        ATTR_DESIGN: design_record(evaluation.design),
        ATTR_OBJECTIVES: dict(evaluation.objectives.items()),
        ATTR_CONSTRAINTS: dict(evaluation.constraints.items()),
    }


# --------------------------------------------------------------------------------------------
# From a trial's suggestions to a design


def suggest_shape(trial: optuna.Trial, config: StudyConfig) -> FootShape:
    sp = config.space
    return FootShape(
        n_toes=trial.suggest_int("toes", *sp.toes),
        toe_segments=trial.suggest_int("toe_segments", *sp.toe_segments),
        heel_segments=trial.suggest_int("heel_segments", *sp.heel_segments),
    )


def masses_from_shares(
    shape: FootShape, shares: tuple[tuple[float, ...], ...], limits: FootLimits, used: float
) -> tuple[tuple[float, ...], ...]:
    """Rod masses from non-negative shares (per chain, heel first): each rod gets the minimum
    link mass plus its share of what the foot mass ``used`` leaves; budget and minimum hold by
    construction (equal shares when every share is 0). A shape whose rods cannot all weigh the
    minimum within ``used`` gets the minimum everywhere: its ``foot_mass`` constraint then says by
    how much the budget is exceeded (rather than a negative mass)."""
    n = shape.n_links
    free = used - n * limits.min_link_mass
    if free < 0:
        return tuple(tuple(limits.min_link_mass for _ in c) for c in shares)
    total = sum(sum(c) for c in shares)
    if total <= 0:
        return tuple(tuple(used / n for _ in c) for c in shares)
    return tuple(tuple(limits.min_link_mass + free * w / total for w in c) for c in shares)


def suggest_design(trial: optuna.Trial, config: StudyConfig) -> FootDesign:
    """The foot a trial's suggestions make (see the module docstring)."""
    shape = suggest_shape(trial, config)
    limits = config.limits
    identical = config.space.toe_symmetry is ToeSymmetry.IDENTICAL
    chain_limits = limits.joint_limits(shape)

    def chain(prefix: str, k: int, bounds: tuple[tuple[float, float], ...]) -> tuple[tuple[float, ...], tuple[float, ...]]:
        angles = tuple(trial.suggest_float(f"{prefix}.joint_angle[{j}]", *bounds[j]) for j in range(k))
        shares = tuple(trial.suggest_float(f"{prefix}.mass_share[{j}]", 0.0, 1.0) for j in range(k))
        return angles, shares

    heel = chain("heel", shape.heel_segments, chain_limits[0])
    if identical:
        toe = chain("toe", shape.toe_segments, chain_limits[1])
        toes = [toe] * shape.n_toes
    else:
        toes = [chain(f"toe{i + 1}", shape.toe_segments, chain_limits[1 + i]) for i in range(shape.n_toes)]
    angles = (heel[0], *(t[0] for t in toes))
    shares = (heel[1], *(t[1] for t in toes))
    n_min = shape.n_links * limits.min_link_mass
    if limits.mass_mode is MassMode.AT_MOST:
        used = n_min + trial.suggest_float("foot_mass_fraction", 0.0, 1.0) * max(limits.foot_mass - n_min, 0.0)
    else:
        used = limits.foot_mass
    masses = masses_from_shares(shape, shares, limits, used)
    yaws = suggest_yaws(trial, config, shape) if config.space.spatial else None
    if not config.whole_landing:
        return design_from(config.leg, angles, masses, limits, toe_yaws=yaws)
    reach = trial.suggest_float("foot_reach", *limits.foot_length)
    design = design_from(config.leg, angles, masses, limits, reach, toe_yaws=yaws)
    return with_joint_laws(design, suggest_joint_laws(trial, config))


def suggest_yaws(trial: optuna.Trial, config: StudyConfig, shape: FootShape) -> tuple[float, ...]:
    """A spatial foot's toe yaws: one ``splay`` spread symmetrically, or ``toe<i>.yaw`` per toe
    (a fixed range [x, x] is not asked for)."""
    splay = config.space.splay
    assert splay is not None
    lo, hi = splay.splay

    def value(name: str) -> float:
        return lo if lo == hi else trial.suggest_float(name, lo, hi)

    if splay.mode is SplayMode.SYMMETRIC:
        return symmetric_yaws(shape.n_toes, value("splay")) if shape.n_toes > 1 else (0.0,)
    return tuple(value(f"toe{i + 1}.yaw") for i in range(shape.n_toes))


@dataclass(frozen=True)
class FamilyLaw:
    """One joint family's spring (N m/rad), damper (N m s/rad) and stop travel (rad; None: none)."""

    stiffness: float = 0.0
    damping: float = 0.0
    stop: float | None = None


def suggest_joint_laws(trial: optuna.Trial, config: StudyConfig) -> dict[str, FamilyLaw]:
    """One spring, damper and stop travel per joint family (``design_space.joint_laws``); a
    fixed range [x, x] is not asked for."""
    space = config.space.joint_laws

    def value(name: str, key: str) -> float | None:
        r = getattr(getattr(space, name), key)
        if r is None:
            return None
        return r[0] if r[0] == r[1] else trial.suggest_float(f"joint_laws.{name}.{key}", *r)

    out = {}
    for name in JOINT_FAMILIES:
        k, c, stop = (value(name, key) for key in ("stiffness", "damping", "stop"))
        out[name] = FamilyLaw(k or 0.0, c or 0.0, stop)
    return out


def with_joint_laws(design: FootDesign, laws: dict[str, FamilyLaw]) -> FootDesign:
    """``design`` with each rod's joint law from its family's."""

    def chain(c: tuple[Segment, ...], root: str, inner: str) -> tuple[Segment, ...]:
        return tuple(
            replace(s, stiffness=t.stiffness, damping=t.damping, stop=t.stop)
            for j, s in enumerate(c)
            for t in (laws[root if j == 0 else inner],)
        )

    return replace(design, heel=chain(design.heel, "heel_root", "heel_inner"),
                   toes=tuple(chain(t, "toe_root", "toe_inner") for t in design.toes))


def objective_values(config: StudyConfig, objectives: Objectives) -> list[float]:
    """What the sampler minimises: each objective's score (``energy_absorbed`` negated)."""
    return [objectives.score(o) for o in config.objectives]


# --------------------------------------------------------------------------------------------
# Studies


def make_sampler(search: SearchSettings, seed: int) -> optuna.samplers.BaseSampler:
    """A fresh sampler: TPE (Optuna's multi-objective default) or NSGA-II."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
        if search.sampler is SamplerKind.NSGA2:
            return optuna.samplers.NSGAIISampler(population_size=search.population, seed=seed)
        return optuna.samplers.TPESampler(
            n_startup_trials=search.startup_trials, seed=seed, multivariate=True, group=True, constant_liar=False
        )


def trial_seed(seed: int, finished: int) -> int:
    """The sampler's seed for the trial after ``finished`` finished trials."""
    return (seed * 1_000_003 + finished) % (2**32)


def open_study(config: StudyConfig, storage: str | optuna.storages.BaseStorage) -> optuna.Study:
    """Create the study in ``storage``, or load it when it is there (same name)."""
    return optuna.create_study(
        storage=storage,
        study_name=config.name,
        directions=["minimize"] * len(config.objectives),
        sampler=make_sampler(config.search, config.seed),
        load_if_exists=True,
    )


def mark_interrupted(study: optuna.Study) -> int:
    """Mark the trials left RUNNING by a killed process FAIL (``interrupted``); returns how
    many. Only for a study that one process runs at a time."""
    n = 0
    storage = study._storage
    for t in study.get_trials(deepcopy=False, states=(TrialState.RUNNING,)):
        storage.set_trial_user_attr(t._trial_id, ATTR_INTERRUPTED, True)
        storage.set_trial_state_values(t._trial_id, TrialState.FAIL)
        n += 1
    return n


def finished_trials(study: optuna.Study) -> int:
    """Trials that count toward the target: complete, or failed by the numerics (not the ones
    an interruption left behind)."""
    return trial_counts(study)[0]


def trial_counts(study: optuna.Study) -> tuple[int, int]:
    """(finished, in flight) from one read of the storage: a trial another worker tells between
    two reads would be counted in neither, and the workers would ask for it again."""
    trials = study.get_trials(deepcopy=False, states=(TrialState.COMPLETE, TrialState.FAIL, TrialState.RUNNING))
    running = sum(1 for t in trials if t.state == TrialState.RUNNING)
    finished = sum(1 for t in trials if t.state != TrialState.RUNNING and not t.user_attrs.get(ATTR_INTERRUPTED))
    return finished, running


#: Trials asked for at once and evaluated together.
OUTER_BATCH = 8


def run_outer(
    study: optuna.Study,
    config: StudyConfig,
    trials: int,
    progress: Callable[[int, int], None] | None = None,
    workers: int = 1,
) -> int:
    """Run trials until ``trials`` have finished (resuming counts what is there): ask for up to
    ``OUTER_BATCH`` at once, evaluate their designs together (:func:`evaluate_designs`), tell each.

    One process (``workers`` 1) reseeds the sampler before each ask from the study's seed and the
    trial's place, so a study run in one go or resumed asks the same questions. One of several
    processes sharing the storage (``workers`` > 1, see :func:`run_worker`) reseeds from the
    batch's first trial number instead (unique, so no two workers draw the same values), asks no
    more than the trials not yet finished or in flight, shared out between the workers (at most
    ``workers - 1`` trials beyond ``trials`` when they ask at the same moment), and leaves the
    trials of the others alone.

    Args:
        study: from :func:`open_study`.
        config: the study.
        trials: target number of finished trials.
        progress: called as ``progress(done, target)`` after each batch (done: by every process).
        workers: processes sharing the study.

    Returns:
        The number of trials run by this process.
    """
    if workers == 1:
        mark_interrupted(study)
    with landing_builds(config, trials) as builds, landing_pool(config, workers) as pool:
        return _run_batches(study, config, trials, progress, workers, builds, pool)


def landing_pool(config: StudyConfig, workers: int) -> AbstractContextManager[ProcessPoolExecutor | None]:
    """Worker processes that land a batch's designs at once (:func:`evaluate_designs`): a whole-
    landing search's, the cores shared out between the study's ``workers`` processes (none for a
    first-impact search, whose batch is one compiled call)."""
    if not config.whole_landing:
        return nullcontext(None)
    return forked_pool(min(OUTER_BATCH, max(1, cores() // workers)))


def landing_builds(config: StudyConfig, trials: int) -> LandingBuilds:
    """The background builds of a search's landings' C (:mod:`optimizer.search.landing_code`):
    active when it plans enough whole landings per shape (``trials`` designs over its shapes, times
    its scenarios)."""
    per_design = 0 if not config.whole_landing else config.landings.count if config.landings else 1
    return LandingBuilds(trials * per_design / max(1, len(config.space.shapes())))


def _run_batches(
    study: optuna.Study, config: StudyConfig, trials: int, progress: Callable[[int, int], None] | None,
    workers: int, builds: LandingBuilds, pool: ProcessPoolExecutor | None = None,
) -> int:
    """:func:`run_outer`'s loop of batches."""
    done, ran = finished_trials(study), 0
    while done < trials:
        size = min(OUTER_BATCH, trials - done)
        if workers > 1:
            done, flying = trial_counts(study)
            remaining = trials - done - flying
            if remaining <= 0:  # the other workers are finishing the last ones
                break
            size = min(OUTER_BATCH, max(1, remaining // workers))
        asked = ask_batch(study, config, size, done, workers)
        try:
            evaluations = evaluate_designs(config, [suggest_design(t, config) for t in asked], builds, pool)
            check_interrupt()  # a Ctrl-C that CasADi caught while the batch's graph was built
        except BaseException:
            for trial in asked:
                study._storage.set_trial_user_attr(trial._trial_id, ATTR_INTERRUPTED, True)
                study.tell(trial, state=TrialState.FAIL)
            raise
        for trial, evaluation in zip(asked, evaluations, strict=True):
            tell(study, config, trial, evaluation)
        ran += len(asked)
        done = done + len(asked) if workers == 1 else finished_trials(study)
        if progress is not None:
            progress(done, trials)
    return ran


def ask_batch(study: optuna.Study, config: StudyConfig, size: int, done: int, workers: int) -> list[optuna.Trial]:
    """Ask for ``size`` trials with the sampler seeded as :func:`run_outer` says."""
    asked = []
    for j in range(size):
        if workers == 1:
            study.sampler = make_sampler(config.search, trial_seed(config.seed, done + j))
        asked.append(study.ask())
    if workers > 1:  # suggestions are drawn after the asks: seed them by a number no other worker has
        study.sampler = make_sampler(config.search, trial_seed(config.seed, asked[0].number))
    return asked


def run_worker(config: StudyConfig, run_dir: str, trials: int, workers: int) -> int:
    """One extra worker process of ``footopt optimize --workers``: opens the run's study (its
    storage) and runs :func:`run_outer` in it; a Ctrl-C stops it quietly (its trials are marked)."""
    import logging
    from pathlib import Path

    from optimizer.results.runs import storage_url  # here: the run folder module imports this one

    optuna.logging.set_verbosity(logging.WARNING)
    try:
        with interruptible():
            return run_outer(open_study(config, storage_url(Path(run_dir), config)), config, trials, None, workers)
    except KeyboardInterrupt:
        return 0


def tell(study: optuna.Study, config: StudyConfig, trial: optuna.Trial, evaluation: DesignEvaluation) -> FrozenTrial:
    """Record a trial's evaluation: COMPLETE with its values, design, objectives and constraint
    values (and violations for the sampler), or FAIL when the impact solve failed numerically
    (the constraint values are still recorded)."""
    if evaluation.objectives is None:
        trial.set_user_attr(ATTR_CONSTRAINTS, dict(evaluation.constraints.items()))
        trial.set_user_attr(ATTR_FAILURE, evaluation.failure or FAILED)
        return study.tell(trial, state=TrialState.FAIL)
    for key, value in record_attrs(evaluation, "outer").items():
        trial.set_user_attr(key, value)
    for name, violation in evaluation.constraints.violations():
        trial.set_constraint(name, violation)
    return study.tell(trial, objective_values(config, evaluation.objectives))


def evaluate_designs(
    config: StudyConfig, designs: list[FootDesign], builds: LandingBuilds | None = None,
    pool: ProcessPoolExecutor | None = None,
) -> list[DesignEvaluation]:
    """Every design's objectives and constraint values: the impact of each kind of foot
    (:func:`optimizer.search.compiled.foot_kind`) from its compiled ``VALUE_OUTPUTS`` function,
    one batched C loop per kind, cached on disk; the geometry from :func:`constraint_values`.
    A whole-landing study lands each design in full instead (:func:`evaluate_design_landing`), and
    a study with friction or a spatial design space (splayed toes) solves each design's impact by the
    core's ``evaluate`` (:func:`evaluate_design`; the exact Coulomb law with friction). Whole
    landings run in ``pool``'s workers when given (:func:`landing_pool`; the same evaluations)."""
    if builds is not None:
        prepare_landings(builds, config, designs)
    if config.landings is not None:
        return evaluate_designs_over_landings(config, designs, pool)
    if config.whole_landing:
        return mapped(pool, functools.partial(_landed, config), designs)
    if config.space.spatial or config.scene.friction > 0:  # spatial feet, the exact Coulomb law: one by one
        return [evaluate_design(config.leg, d, config.scene, config.limits) for d in designs]
    out: list[DesignEvaluation | None] = [None] * len(designs)
    groups: dict[FootKind, list[int]] = {}
    for i, design in enumerate(designs):
        groups.setdefault(foot_kind(config, design.shape), []).append(i)
    for kind, rows in groups.items():
        run = _values_runner(config, kind)
        k = 1 + kind.distinct_toes
        chains = [designs[i].chains[:k] for i in rows]
        rods = [[s for c in d for s in c] for d in chains]
        angles_masses = np.array([[s.joint_angle for s in r] + [s.mass for s in r] for r in rods])
        n_toes = np.array([[float(designs[i].shape.n_toes)] for i in rows])
        with np.errstate(all="ignore"):
            values = np.hstack(run(angles_masses, n_toes))
        for i, row in zip(rows, values, strict=True):
            out[i] = _evaluation(config, designs[i], dict(zip(VALUE_OUTPUTS, (float(v) for v in row), strict=True)))
    return [e for e in out if e is not None]


def _landed(config: StudyConfig, design: FootDesign) -> DesignEvaluation:
    """One design of a whole-landing study, landed (:func:`evaluate_design_landing`)."""
    e, tol = config.space.joint_laws.stop_restitution, config.search.landing_tolerance
    return evaluate_design_landing(config.leg, design, config.scene, config.limits, e, tol)


def prepare_landings(builds: LandingBuilds, config: StudyConfig, designs: list[FootDesign]) -> None:
    """Start the background builds of the designs' whole landings' C (:class:`LandingBuilds`; over
    ``landings``, the nominal scene's)."""
    if not builds.active:
        return
    e, settings = config.space.joint_laws.stop_restitution, study_landing(config.search.landing_tolerance)
    for design in designs:
        m = design_model(config.leg, design, config.scene, config.limits, e)
        builds.prepare(m.tree, m.scene, m.joints, settings, m.space)


def evaluate_design_over_landings(config: StudyConfig, design: FootDesign) -> DesignEvaluation:
    """A design's statistics over the study's landings (each scenario as ``footopt evaluate`` on
    its overridden model file); no objectives when a scenario fails."""
    return evaluate_designs_over_landings(config, [design])[0]


def evaluate_designs_over_landings(config: StudyConfig, designs: list[FootDesign],
                                   pool: ProcessPoolExecutor | None = None) -> list[DesignEvaluation]:
    """:func:`evaluate_design_over_landings` of a batch of designs: designs x scenarios in one
    compiled call per shape and contact set, the whole landings in ``pool``'s workers."""
    assert config.landings is not None
    e = config.space.joint_laws.stop_restitution
    models = [design_model(config.leg, d, config.scene, config.limits, e) for d in designs]
    found = statistics_over_landings_many(models, config.landings, config.statistic_of,
                                          study_landing(config.search.landing_tolerance), pool)
    return [DesignEvaluation(d, s, constraint_values(config.leg, d, config.limits),
                             "" if s is not None else "a landing of the study's landings failed")
            for d, s in zip(designs, found, strict=True)]


def _evaluation(config: StudyConfig, design: FootDesign, values: dict[str, float]) -> DesignEvaluation:
    """A design's evaluation from its compiled ``VALUE_OUTPUTS`` (None objectives if not finite)."""
    geometric = constraint_values(config.leg, design, config.limits)
    if not all(math.isfinite(v) for v in values.values()):
        return DesignEvaluation(design, None, geometric, NOT_FINITE)
    constraints = replace(
        geometric, pulling=-values["min_external"], energy_gain=values["energy_after"] - values["energy_before"]
    )
    return DesignEvaluation(design, Objectives(**{k: values[k] for k in VALUE_OUTPUTS[:5]}), constraints)


@functools.lru_cache(maxsize=64)
def _values_runner(config: StudyConfig, kind: FootKind) -> Callable[..., list[np.ndarray]]:
    """The batched C loop of a kind's values (CasADi's map on its virtual machine without a compiler)."""
    f = values_function(config, kind)
    compiled = compile_function(f, cache_dir(), fallback=True)
    kernel = batch_kernel(compiled, f)
    if kernel is not None:
        return kernel

    def on_vm(*inputs: np.ndarray) -> list[np.ndarray]:
        outs = f.map(inputs[0].shape[0])(*(x.T for x in inputs))
        return [np.array(o, dtype=float).T.reshape(inputs[0].shape[0], -1) for o in outs]

    return on_vm


def recorded_trials(study: optuna.Study) -> Iterator[RecordedTrial]:
    """Every complete trial with a recorded design, in trial order."""
    for t in study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,)):
        r = read_trial(t)
        if r is not None:
            yield r


def failed_designs(study: optuna.Study) -> list[tuple[int, str]]:
    """The trials whose designs failed (FAIL, not interrupted), in trial order, each with why
    (:data:`ATTR_FAILURE`; studies recorded before it say only that they failed)."""
    return [(t.number, str(t.user_attrs.get(ATTR_FAILURE, FAILED)))
            for t in study.get_trials(deepcopy=False, states=(TrialState.FAIL,))
            if not t.user_attrs.get(ATTR_INTERRUPTED)]


def is_finite_values(values: list[float]) -> bool:
    return all(math.isfinite(v) for v in values)


__all__ = [
    "ATTR_FAILURE",
    "RecordedTrial",
    "failed_designs",
    "design_from_record",
    "design_record",
    "evaluate_designs",
    "finished_trials",
    "make_sampler",
    "mark_interrupted",
    "masses_from_shares",
    "open_study",
    "read_trial",
    "record_attrs",
    "recorded_trials",
    "run_outer",
    "run_worker",
    "suggest_design",
    "tell",
    "trial_counts",
    "trial_seed",
]
