"""The inner search: per foot shape, IPOPT with exact derivatives over the shape's continuous
values, and an epsilon-constraint sweep for a front.

The NLP of a kind of foot (:mod:`optimizer.search.compiled`) is compiled to C once and cached on
disk when the study's solves repay the build (else it runs on CasADi's virtual machine);
identical toes are one merged chain and the toe count is a parameter, so one NLP serves every
toe count. Its parameters are the objective weights and the toe count, and its first constraint
row's upper bound is the epsilon of a solve: every front point is a re-solve, warm-started from
the last (:data:`optimizer.search.compiled.WARM_OPTIONS`).

Variables (per distinct rod; identical toes share theirs): joint angle, mass, length; and the
ankle height h above the ground.

    min_x   w1 f1(x) + w2 f2(x)
    s.t.    f2(x) <= eps
            sum_{i in chain} L_i (-sin phi_i) = h            every tip on the ground line
            m_i / rho_max <= L_i <= m_i / rho_min           mass per length
            F_min <= reach_toe(x) <= F_max                  foot length
            height(joint) >= c_min                          clearance (chain joints, ankle, knee, hip)
            sum m = M  (or <= M)                            foot mass
            lambda_c >= 0,  E_after <= E_before             physical impact
            joint limits, m_i >= m_min                      bounds

Objectives that are maxima or absolute values (``max_internal``, ``base_angular_velocity``) get
an epigraph variable. A solution is realised once (:func:`realise`): its masses rescaled to the
budget exactly, its own lengths (or, when they miss a limit by rounding, lengths re-chosen by
:func:`assign_lengths`), its objectives and impact constraints from the compiled ``foot_values``,
its geometric constraints from :func:`constraint_values`; it is kept only if every constraint
holds there: the NLP's own tolerances never decide what is exported.

Splayed toes (``design_space.space: spatial``; :func:`optimizer.search.compiled._splayed_values`).
In space identical toes at different yaws take different impulses, so no toe is merged: the NLP
is the whole tree's (Newton's law in space, eq. 11, straight down), one NLP per toe count (a
kind per shape; the toe-count parameter is unused). Identical toes share their angles and masses
(independent toes have their own); every toe has lengths of its own (in space the impulses do
depend on the lengths once the base turns about an axis other than a toe's joint axes, and a
toe's reach, cos(yaw) times its run in its plane, differs from toe to toe, as the outer search's
linear program has it). The yaw variables are as ``design_space`` asks: one ``splay`` s (toes
spread from -s to +s; none for one toe) or one yaw per toe, in order (psi_1 <= ... <= psi_n: any
foot is one such after relabelling its toes); a fixed range [x, x] is a constant. Extra rows:

            F_min <= cos(psi_i) reach_i(x) - heel <= F_max   every toe's forward reach
            s_e >= b sqrt(|d_e|^2 + eps^2)                  support margin b, per hull edge e

(:func:`optimizer.search.compiled._support_rows`: the centre of mass's projection left of every
edge of the contacts in a fixed order, heel then toes by decreasing yaw; sound in any order,
exact but for b eps^2 / (2 |d_e|^2) when that order is the hull's). ``base_angular_velocity``
is the norm of the base's angular velocity, by an epigraph u^2 >= |omega|^2. A one-toe shape
with a positive support margin is infeasible before any solve (one toe and the heel span no
area). The leg may be spatial (a
``leg: {file}`` whose joint axes are not all parallel): each toe root's ``rpy`` is then
:func:`optimizer.design_space.yaw_rpy` on the leg's last rod's frame at touchdown, symbolic in the
yaws, and the leg's rods keep their own axes, frames and mass properties, as in the outer search's
model files (:func:`optimizer.design_space.foot_tree`). The realised design is
evaluated as the outer search evaluates splayed feet (:func:`evaluate_design`: the core's
``evaluate`` in space, the support margin of its model file).

Over ``landings:`` (level first impacts) a splayed foot's NLP maps the whole tree's impact over
the scenarios, as the plane's does (:func:`optimizer.search.compiled._splayed_scenario_impacts`):
each scenario's approach is [velocity_x, -speed, velocity_z] and [roll_rate, 0,
angular_velocity] (world frame) with its restitution, what the outer search writes into the
scenario's model file, and each objective is its statistic over the scenarios; the realised
design is scored by the outer search's evaluation over the landings. A roll or a pitch (which
contacts hit) and friction are refused when the study is read (naming ``landings.<name>`` or
``scene.friction``): the outer search takes them. Whole landings over landings (in the plane and
in space): :mod:`optimizer.search.landing_inner`.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass, replace

import numpy as np
import optuna

from optimizer.config.study_config import StudyConfig, check_inner_whole_landings
from optimizer.design_space import (
    CONSTRAINT_FIELDS,
    DesignEvaluation,
    FootDesign,
    FootShape,
    MassMode,
    Objectives,
    Segment,
    SplaySpace,
    ToeSymmetry,
    assign_lengths,
    constraint_values,
    evaluate_design,
)
from optimizer.search.compiled import (
    VALUE_OUTPUTS,
    CompiledNlp,
    FootKind,
    NlpCache,
    foot_kind,
    load_nlp,
    toe_yaws,
    vm_nlp,
)
from optimizer.interrupts import check_interrupt, interruptible
from optimizer.search.landing_workers import landing_sweeps
from optimizer.workers import cores, forked_pool
from optimizer.search.outer import evaluate_design_over_landings, objective_values, record_attrs

#: Weights of the two anchors: each objective first, the other as a tie-break.
ANCHOR_WEIGHTS = ((1.0, 1e-4), (1e-4, 1.0))


@dataclass(frozen=True)
class Solution:
    """One NLP solve: IPOPT's point, multipliers, status, weighted objective and f2."""

    x: np.ndarray
    lam_x: np.ndarray
    lam_g: np.ndarray
    success: bool
    f: float
    f2: float


@dataclass(frozen=True)
class ShapeNlp:
    """A shape's view of its kind's compiled NLP: the toe count that the parameter takes and how
    the distinct chains expand to the design's chains."""

    shape: FootShape
    compiled: CompiledNlp
    identical: bool
    splay: SplaySpace | None = None

    @property
    def multiplicity(self) -> tuple[int, ...]:
        return (1, *([self.shape.n_toes] if self.identical else [1] * self.shape.n_toes))

    def unpack(self, x: np.ndarray) -> tuple[tuple[tuple[float, ...], ...], ...]:
        """(joint angles, masses) per distinct chain and lengths per chain of the kind's
        ``length_sizes`` (:meth:`expand_lengths` makes them the design's) from the NLP's x."""
        c = self.compiled
        n, n_L = c.n_rods, c.n_lengths
        blocks = ((x[:n], c.kind.sizes), (x[n : 2 * n], c.kind.sizes), (x[2 * n : 2 * n + n_L], c.kind.length_sizes))
        out = []
        for block, sizes in blocks:
            chains, i = [], 0
            for k in sizes:
                chains.append(tuple(float(v) for v in block[i : i + k]))
                i += k
            out.append(tuple(chains))
        return tuple(out)

    def expand(self, per_chain: tuple) -> tuple:
        """Distinct chains (heel, toe[, toe...]) to the design's chains (heel, every toe)."""
        return (per_chain[0], *([per_chain[1]] * self.shape.n_toes if self.identical else per_chain[1:]))

    def expand_lengths(self, lengths: tuple) -> tuple:
        """The NLP's lengths (:meth:`unpack`) to the design's chains: a splayed foot has every
        chain's already."""
        return tuple(lengths) if self.compiled.kind.spatial else self.expand(lengths)

    def toe_yaws(self, x: np.ndarray) -> tuple[float, ...] | None:
        """Every toe's yaw at the NLP's x (None: a planar foot)."""
        c = self.compiled
        if not c.kind.spatial:
            return None
        assert self.splay is not None
        i = 2 * c.n_rods + c.n_lengths + 1
        return tuple(float(v) for v in toe_yaws(self.splay, self.shape.n_toes, x[i : i + c.kind.yaws]))


def build_nlp(config: StudyConfig, shape: FootShape, cache: NlpCache | None = None) -> ShapeNlp:
    """The NLP of ``shape``: its kind's compiled NLP (from ``cache``, or a new one)."""
    cache = NlpCache(config, []) if cache is None else cache
    return ShapeNlp(shape, cache[foot_kind(config, shape)], config.space.toe_symmetry is ToeSymmetry.IDENTICAL,
                    config.space.splay)


def start_point(config: StudyConfig, nlp: ShapeNlp, rng: np.random.Generator) -> np.ndarray | None:
    """A random start: angles uniform in their limits, mass shares uniform, yaws uniform in
    their range (per toe: in order), lengths and ankle height from the linear program (so the
    start is level), epigraph variables at 1."""
    lim, c = config.limits, nlp.compiled
    n, n_L, n_yaw = c.n_rods, c.n_lengths, c.kind.yaws
    a = rng.uniform(c.lbx[:n], c.ubx[:n])
    shares = rng.uniform(0.05, 1.0, n)
    mult = np.concatenate([[nlp.multiplicity[k]] * s for k, s in enumerate(c.kind.sizes)])
    used = lim.foot_mass if lim.mass_mode is MassMode.EQUAL else lim.foot_mass * 0.9
    free = used - np.sum(mult) * lim.min_link_mass
    m = lim.min_link_mass + free * shares / np.sum(mult * shares)
    at = 2 * n + n_L + 1
    psi = np.sort(rng.uniform(c.lbx[at : at + n_yaw], c.ubx[at : at + n_yaw]))
    x = np.concatenate([a, m, np.ones(n_L), [0.0], psi])
    angles, masses, _ = nlp.unpack(x)
    assignment = assign_lengths(config.leg, nlp.shape, nlp.expand(angles), nlp.expand(masses), lim,
                                toe_yaws=nlp.toe_yaws(x))
    if assignment is None:
        return None
    lengths = assignment.lengths[: len(c.kind.length_sizes)]
    L = np.concatenate([np.array(ch) for ch in lengths])
    return np.concatenate([a, m, L, [assignment.ankle_height], psi, np.ones(c.n_x - at - n_yaw)])


def solve(
    nlp: ShapeNlp,
    weights: tuple[float, float],
    eps: float,
    x0: np.ndarray,
    warm: Solution | None = None,
) -> Solution:
    """One IPOPT solve from ``x0`` (warm-started with ``warm``'s multipliers, on the compiled
    NLP's warm solver, when given)."""
    c = nlp.compiled
    ubg = c.ubg.copy()
    ubg[0] = eps
    args = dict(x0=x0, p=[*weights, nlp.shape.n_toes], lbx=c.lbx, ubx=c.ubx, lbg=c.lbg, ubg=ubg)
    solver = c.solver
    if warm is not None:
        args.update(lam_x0=warm.lam_x, lam_g0=warm.lam_g)
        solver = c.warm_solver or solver
    try:
        sol = solver(**args)
    except RuntimeError:  # CasADi reports a KeyboardInterrupt raised inside IPOPT as an error
        check_interrupt()
        raise
    check_interrupt()
    success = bool(solver.stats()["success"])
    return Solution(
        np.array(sol["x"]).ravel(),
        np.array(sol["lam_x"]).ravel(),
        np.array(sol["lam_g"]).ravel(),
        success,
        float(sol["f"]),
        float(sol["g"][0]),
    )


def realise(config: StudyConfig, nlp: ShapeNlp, x: np.ndarray) -> DesignEvaluation | None:
    """The design of an NLP point (see the module docstring); None when it is not feasible."""
    lim = config.limits
    angles, masses, lengths = nlp.unpack(x)
    yaws = nlp.toe_yaws(x)
    if lim.mass_mode is MassMode.EQUAL:
        mult = nlp.multiplicity
        total = sum(mult[c] * sum(ms) for c, ms in enumerate(masses))
        n_all = sum(mult[c] * len(ms) for c, ms in enumerate(masses))
        free = total - n_all * lim.min_link_mass
        target = lim.foot_mass - n_all * lim.min_link_mass
        masses = tuple(tuple(lim.min_link_mass + (v - lim.min_link_mass) * target / free for v in ms) for ms in masses)
    evaluation = _evaluate(config, nlp, angles, masses, lengths, yaws)
    if evaluation is not None and evaluation.feasible:
        return evaluation
    assignment = assign_lengths(config.leg, nlp.shape, nlp.expand(angles), nlp.expand(masses), lim, toe_yaws=yaws)
    if assignment is None:
        return None
    evaluation = _evaluate(config, nlp, angles, masses, assignment.lengths[: len(lengths)], yaws)
    return evaluation if evaluation is not None and evaluation.feasible else None


def _evaluate(config: StudyConfig, nlp: ShapeNlp, angles, masses, lengths, yaws=None) -> DesignEvaluation | None:
    """Objectives and constraint values of a design given per distinct chain (lengths as
    :meth:`ShapeNlp.unpack` gives them; ``yaws``: a splayed foot's toe yaws): the impact from
    the compiled ``foot_values``, the geometry from :func:`constraint_values`. With landings, the
    statistics as the outer search scores them (every scenario by the model ``auto`` picks), not
    the NLP's own values; a splayed foot as the outer search evaluates it (:func:`evaluate_design`,
    the core's ``evaluate`` in space, with its support margin), not by the NLP's values."""
    chains = [
        tuple(Segment(L, m, a) for a, m, L in zip(ac, mc, lc, strict=True))
        for ac, mc, lc in zip(nlp.expand(angles), nlp.expand(masses), nlp.expand_lengths(lengths), strict=True)
    ]
    design = FootDesign(heel=chains[0], toes=tuple(chains[1:]), toe_yaws=yaws)
    if config.landings is not None:
        return evaluate_design_over_landings(config, design)
    if design.spatial:
        return evaluate_design(config.leg, design, config.scene, config.limits)
    c = nlp.compiled
    angles_masses = np.array([v for block in (angles, masses) for ch in block for v in ch], dtype=float)
    out = dict(zip(VALUE_OUTPUTS, (float(v) for v in c.values(angles_masses, nlp.shape.n_toes)), strict=True))
    if not all(math.isfinite(v) for v in out.values()):
        return None
    values = replace(
        constraint_values(config.leg, design, config.limits),
        pulling=-out["min_external"],
        energy_gain=out["energy_after"] - out["energy_before"],
    )
    objectives = Objectives(**{k: out[k] for k in VALUE_OUTPUTS[:5]})
    return DesignEvaluation(design, objectives, values)


def _best(config: StudyConfig, nlp: ShapeNlp, solutions: list[Solution]) -> tuple[Solution, DesignEvaluation] | None:
    """The successful solve of least objective whose realised design is feasible."""
    for s in sorted((s for s in solutions if s.success), key=lambda s: s.f):
        evaluation = realise(config, nlp, s.x)
        if evaluation is not None:
            return s, evaluation
    return None


def anchors(config: StudyConfig, nlp: ShapeNlp, rng: np.random.Generator) -> list[tuple[Solution, DesignEvaluation]]:
    """Each objective's minimum (the other as a tie-break): the best of ``search.starts``
    random starts, and of a start from the other anchor's best point (the two minima often
    share a basin that one random start misses)."""
    starts = [x0 for x0 in (start_point(config, nlp, rng) for _ in range(config.search.starts)) if x0 is not None]
    weights = ANCHOR_WEIGHTS if len(config.objectives) > 1 else ((1.0, 0.0),)
    solutions = {w: [solve(nlp, w, math.inf, x0) for x0 in starts] for w in weights}
    for w, other in zip(weights, weights[::-1]):
        if w != other:
            best = min((s for s in solutions[other] if s.success), key=lambda s: s.f, default=None)
            if best is not None:
                solutions[w].append(solve(nlp, w, math.inf, best.x))
    return [b for w in weights if (b := _best(config, nlp, solutions[w])) is not None]


def planned_solves(config: StudyConfig) -> int:
    """The most solves one shape's sweep makes (:func:`anchors`, then :func:`epsilon_sweep`, each
    of whose front points may be solved twice)."""
    if len(config.objectives) < 2:
        return config.search.starts
    return len(ANCHOR_WEIGHTS) * (config.search.starts + 1) + 2 * config.search.front_points


def epsilon_sweep(config: StudyConfig, nlp: ShapeNlp, rng: np.random.Generator) -> Iterator[DesignEvaluation]:
    """A front of one shape: the anchors (:func:`anchors`), then ``search.inner.front_points``
    epsilon-constraint solves between them, each warm-started from the previous one (or, when
    that fails, started from the second anchor). Yields every feasible design, in a fixed order."""
    found = anchors(config, nlp, rng)
    for _, evaluation in found:
        yield evaluation
    if len(found) < 2 or config.search.front_points == 0:
        return
    (first, _), (second, _) = found
    if not first.f2 > second.f2:  # one design is best in both: there is no front between
        return
    previous = first
    for eps in np.linspace(first.f2, second.f2, config.search.front_points + 2)[1:-1]:
        s = solve(nlp, ANCHOR_WEIGHTS[0], float(eps), previous.x, previous)
        evaluation = realise(config, nlp, s.x) if s.success else None
        if evaluation is None:  # the front may jump basins: try from the other end
            s = solve(nlp, ANCHOR_WEIGHTS[0], float(eps), second.x)
            evaluation = realise(config, nlp, s.x) if s.success else None
        if evaluation is not None:
            yield evaluation
            previous = s


# --------------------------------------------------------------------------------------------
# Recording into a study

#: User attributes of an inner trial: its shape's label and its place in the shape's sweep.
ATTR_SHAPE, ATTR_INDEX = "inner_shape", "inner_index"


def shape_done_key(shape: FootShape) -> str:
    """The study user attribute that marks a shape's sweep as recorded."""
    return f"inner_done:{shape.label}"


def shape_seed(seed: int, shape: FootShape) -> np.random.Generator:
    """The random starts of one shape: a function of the study's seed and the shape only."""
    return np.random.default_rng([seed, shape.n_toes, shape.toe_segments, shape.heel_segments])


def recorded_indices(study: optuna.Study, shape: FootShape) -> set[int]:
    """Places in ``shape``'s sweep already recorded (by a run killed before marking it done)."""
    trials = study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.COMPLETE,))
    return {int(t.user_attrs[ATTR_INDEX]) for t in trials if t.user_attrs.get(ATTR_SHAPE) == shape.label}


def run_inner(
    study: optuna.Study,
    config: StudyConfig,
    progress: Callable[[int, int], None] | None = None,
    workers: int | None = None,
) -> int:
    """Sweep every shape of the design space not yet recorded in ``study``; record each feasible
    design as a COMPLETE trial (user attributes as the outer search's, ``method: inner``, and its
    shape and place in the sweep), then mark the shape done. The sweep is deterministic, so a
    resumed shape skips the places already recorded: no shape is swept twice once done, and no
    design is recorded twice after a kill.

    Shapes are swept by ``workers`` processes (default :func:`optimizer.workers.cores`); the
    trials are recorded here, in the serial order (a whole-landing shape's designs as each is
    found: :mod:`optimizer.search.landing_workers`).

    Returns:
        The number of shapes swept now.

    Raises:
        ConfigError: whole landings over landings the NLP cannot score (the study file's
            validation says so first, :func:`check_inner_whole_landings`).
    """
    if config.landings is not None and config.whole_landing:
        check_inner_whole_landings(config, config.landings)
    shapes = config.space.shapes()
    sp = config.space
    distributions = {
        "toes": optuna.distributions.IntDistribution(*sp.toes),
        "toe_segments": optuna.distributions.IntDistribution(*sp.toe_segments),
        "heel_segments": optuna.distributions.IntDistribution(*sp.heel_segments),
    }
    done = sum(1 for s in shapes if study.user_attrs.get(shape_done_key(s)))
    todo = [s for s in shapes if not study.user_attrs.get(shape_done_key(s)) and _why_infeasible(config, s) is None]
    # One kind after another, smallest first: its search runs while the larger ones compile.
    kinds = sorted(dict.fromkeys(foot_kind(config, s) for s in todo),
                   key=lambda k: (sum(k.sizes), k.sizes, k.splayed_toes))
    # A whole-landing study compiles nothing: its NLP lands each iterate (optimizer.search.landing_inner).
    solves = {k: planned_solves(config) * sum(foot_kind(config, s) == k for s in todo) for k in kinds}
    swept, cache = 0, (None if config.whole_landing else NlpCache(config, kinds, solves=solves))
    order = {k: i for i, k in enumerate(kinds)}
    todo.sort(key=lambda s: order[foot_kind(config, s)])
    if config.whole_landing:
        def keep(shape: FootShape, designs: list[DesignEvaluation]) -> None:
            _record_shape(study, config, shape, designs, None, distributions)

        sweeps = landing_sweeps(config, todo, workers, keep)
    else:
        sweeps = _sweeps(config, todo, cache, workers)
    with interruptible(), sweeps as results:
        for shape in sorted(shapes, key=lambda s: order.get(foot_kind(config, s), -1)):
            if study.user_attrs.get(shape_done_key(shape)):
                continue
            why = _why_infeasible(config, shape)
            if why is None:
                if config.whole_landing:  # each design recorded as it is found (a solve can take minutes)
                    _record_shape(study, config, shape, results.designs(shape), NO_LANDING, distributions)
                else:
                    _record_shape(study, config, shape, *next(results), distributions)
            else:  # no design of it is feasible
                study.set_user_attr(infeasible_key(shape), why)
            study.set_user_attr(shape_done_key(shape), True)
            done, swept = done + 1, swept + 1
            if progress is not None:
                progress(done, len(shapes))
    return swept


#: A shape's sweep: its feasible designs in order, and why there are none (else None).
Sweep = tuple[list[DesignEvaluation], "str | None"]


def sweep_shape(config: StudyConfig, nlp: ShapeNlp) -> Sweep:
    """The designs of one shape's epsilon sweep, and, when there are none, why (:func:`_diagnose`)."""
    designs = list(epsilon_sweep(config, nlp, shape_seed(config.seed, nlp.shape)))
    return designs, None if designs else _diagnose(config, nlp, nlp.shape)


@contextmanager
def _sweeps(
    config: StudyConfig, shapes: list[FootShape], cache: NlpCache, workers: int | None
) -> Iterator[Iterator[Sweep]]:
    """The sweeps of ``shapes``, in their order. With more than one worker (and shape), each
    kind's shapes are handed to forked worker processes (:mod:`optimizer.workers`) as soon as its
    library is built (each loads it from the cache), while the next kinds compile; a kind on the
    virtual machine at once (its NLP is built here, once, and the workers inherit it by the
    fork). The results are the ones a serial sweep gives (every shape's sweep depends on the
    study's seed and the shape only)."""
    kinds = dict.fromkeys(foot_kind(config, s) for s in shapes)
    on_vm = {k: cache[k] for k in kinds if not cache.building(k) and cache.library(k) is None}
    with forked_pool(min(cores() if workers is None else workers, len(shapes)), _inherit, (on_vm,)) as pool:
        if pool is None:
            yield (sweep_shape(config, build_nlp(config, s, cache)) for s in shapes)
        else:
            yield _pooled(config, shapes, cache, pool)


def _pooled(
    config: StudyConfig, shapes: list[FootShape], cache: NlpCache, pool: ProcessPoolExecutor
) -> Iterator[Sweep]:
    pending: deque[Future] = deque()
    submitted: set = set()
    for shape in shapes:
        kind = foot_kind(config, shape)
        if kind not in submitted:  # hand out every shape of this kind once it is built
            submitted.add(kind)
            folder = cache.library(kind)
            for s in shapes:
                if foot_kind(config, s) == kind:
                    pending.append(pool.submit(_sweep_in_worker, config, s, folder))
        while pending and pending[0].done():
            yield pending.popleft().result()
    while pending:
        yield pending.popleft().result()


#: A worker's NLPs, by library folder (or by kind, on the virtual machine).
_WORKER_NLPS: dict = {}


def _inherit(on_vm: dict[FootKind, CompiledNlp]) -> None:
    """A worker's start: the kinds on the virtual machine that the parent built."""
    _WORKER_NLPS.update(on_vm)


def _sweep_in_worker(config: StudyConfig, shape: FootShape, folder) -> Sweep:
    """One shape's sweep in a worker: its kind's library from ``folder``, or the kind on the
    virtual machine (``folder`` None)."""
    kind: FootKind = foot_kind(config, shape)
    key = kind if folder is None else folder
    if key not in _WORKER_NLPS:
        _WORKER_NLPS[key] = vm_nlp(config, kind) if folder is None else load_nlp(kind, folder)
    nlp = ShapeNlp(shape, _WORKER_NLPS[key], config.space.toe_symmetry is ToeSymmetry.IDENTICAL, config.space.splay)
    return sweep_shape(config, nlp)


def _record_shape(
    study: optuna.Study, config: StudyConfig, shape: FootShape, designs: Iterable[DesignEvaluation],
    diagnosis: str | None, distributions: dict,
) -> None:
    """Add each design of one shape's sweep not yet recorded as a COMPLETE trial (``designs``
    may be a generator: each is recorded as it comes); ``diagnosis``: why there is none, recorded
    when there is none."""
    have = recorded_indices(study, shape)
    params = {"toes": shape.n_toes, "toe_segments": shape.toe_segments, "heel_segments": shape.heel_segments}
    i = -1
    for i, evaluation in enumerate(designs):
        if i in have:
            continue
        trial = optuna.trial.create_trial(
            params=params,
            distributions=distributions,
            values=objective_values(config, evaluation.objectives),
            user_attrs={**record_attrs(evaluation, "inner"), ATTR_SHAPE: shape.label, ATTR_INDEX: i},
            constraints=dict(evaluation.constraints.violations()),
        )
        study.add_trial(trial)
    if i < 0 and diagnosis is not None:  # nothing feasible: say what stood in the way
        study.set_user_attr(infeasible_key(shape), diagnosis)


#: Why a shape has no feasible design, as the study files' fields say it (see ``infeasible_key``).
NO_LANDING = "IPOPT found no feasible design that lands"
NO_MASS = "constraints.min_link_mass x its rods exceeds constraints.foot_mass"
NO_AREA = "constraints.support_margin > 0: one toe and the heel span no area"
NO_POSTURE = (
    "no level touchdown posture meets constraints.foot_length, constraints.min_clearance, "
    "constraints.joint_angles and constraints.mass_per_length together"
)


def _why_infeasible(config: StudyConfig, shape: FootShape) -> str | None:
    """Why no design of ``shape`` can be feasible, before any solve (None: it may be)."""
    lim = config.limits
    if shape.n_links * lim.min_link_mass > lim.foot_mass:
        return NO_MASS
    if config.space.spatial and shape.n_toes < 2 and (lim.support_margin or 0.0) > 0:
        return NO_AREA
    return None


def _diagnose(config: StudyConfig, nlp: ShapeNlp, shape: FootShape, tries: int = 8) -> str:
    """Why no design of ``shape`` was found: no level posture at all, or the constraints that
    every random level start (of ``tries``) misses, by their study-file fields."""
    rng = shape_seed(config.seed, shape)
    starts = [x for x in (start_point(config, nlp, rng) for _ in range(tries)) if x is not None]
    if not starts:
        return NO_POSTURE
    missed: set[str] | None = None
    for x in starts:
        angles, masses, lengths = nlp.unpack(x)
        ev = _evaluate(config, nlp, angles, masses, lengths, nlp.toe_yaws(x))
        names = {k for k, v in ev.constraints.violations() if v > 0} if ev is not None else set()
        missed = names if missed is None else missed & names
    fields = sorted(CONSTRAINT_FIELDS.get(k) or f"{k} (physics)" for k in missed or ())
    return f"every level posture tried misses {', '.join(fields)}" if fields else "IPOPT found no feasible design"


def infeasible_key(shape: FootShape) -> str:
    """The study user attribute that says why ``shape`` has no feasible design."""
    return f"infeasible:{shape.label}"


__all__ = [
    "NO_MASS",
    "NO_POSTURE",
    "ShapeNlp",
    "Solution",
    "anchors",
    "build_nlp",
    "epsilon_sweep",
    "infeasible_key",
    "planned_solves",
    "realise",
    "run_inner",
    "shape_done_key",
    "solve",
    "start_point",
    "sweep_shape",
]
