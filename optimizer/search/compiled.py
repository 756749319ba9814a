"""The inner search's NLP of one kind of foot, compiled to C once and cached on disk.

Identical toes are one merged chain. n identical toes hit at once by Newton's law move alike
(the law's solution is unique, so it keeps the symmetry), so the impact of the tree equals the
impact of the tree with one toe whose rods carry n times the mass (and, at the same radius of
gyration, n times the inertia); each real toe takes 1/n of the merged toe's impulses. The
objectives follow exactly:

    external_norm^2 = sum_heel lambda^2 + sum_toe Lambda^2 / n
    internal_norm^2 = sum_(shank, heel) |F|^2 + sum_toe |F|^2 / n,   max_internal likewise

and the toe count is a parameter of the NLP: one library serves every toe count. Independent
toes keep one chain per toe (multiplicity 1). Splayed (spatial) toes are never merged: one NLP per
toe count, on the whole spatial tree (:func:`_splayed_values`, :func:`_splayed_impact`,
:func:`_support_rows`; the inner search's module docstring); over landings its impact is one
mapped call over the scenarios, as in the plane (:func:`_splayed_scenario_impacts`).

A library holds CasADi's generated NLP functions (objective, constraints, their exact gradient,
Jacobian and the Hessian of the Lagrangian, :meth:`casadi.Function.generate_dependencies`) and a
``foot_values`` function (every objective and the impact's constraint values at a point). It is
keyed by a hash of everything that defines the graph: the study's leg, scene, limits and
objectives, the kind of foot, the source of the modules that build it, the CasADi version, the
compiler and its flags. A warm study loads it without building any symbolic model.

Compiling pays only for enough solves: a kind that is not cached yet and will see fewer than
:data:`COMPILE_SOLVES` solves (splayed toes over landings: :data:`COMPILE_SCENARIO_SOLVES` solves
x scenarios) runs on CasADi's virtual machine instead (no library is built).
"""

from __future__ import annotations

import functools
import hashlib
import math
import tempfile
import warnings
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np

import impulse_core
from impulse_core.compile.cache import CompileError, compiler_identity, entry_key, lookup, run_compilers, store
from impulse_core.compile.cache import default_root as cache_dir
from impulse_core.compile.codegen import find_compiler
from impulse_core.evaluate import approach_velocity, compiled_geometry, compiled_model
from impulse_core.kinematics.spatial import PLANAR, SPATIAL, values_space
from impulse_core.model.tree import Topology, design_vector
from optimizer.config.study_config import StudyConfig
from optimizer.design_space import (
    LENGTH_FLOOR,
    FootDesign,
    FootShape,
    MassMode,
    Objective,
    Segment,
    SplayMode,
    SplaySpace,
    ToeSymmetry,
    foot_geometry,
    foot_tree,
    leg_chain,
    symmetric_yaws,
    yaw_rpy,
)
from optimizer.evaluation.statistics import Statistic, StatisticKind

#: Inequalities of the NLP are tightened by this (in their own units) so that the realised
#: design meets them with room for rounding.
TIGHTEN = 1e-7
#: Compiler flags of the NLP libraries: the Hessian's code is one long straight-line function that
#: -O1 compiles about 5 x slower than -O0 (7 s against 1.5 s for a three-rod toe) and runs no
#: faster within a study (IPOPT's own work dominates); no -ffast-math.
NLP_CFLAGS = ("-O0", "-fPIC", "-shared")
#: Outputs of ``foot_values``.
VALUE_OUTPUTS = (
    "external_norm",
    "internal_norm",
    "max_internal",
    "base_angular_velocity",
    "energy_after",
    "energy_before",
    "min_external",
)


@dataclass(frozen=True)
class FootKind:
    """What one compiled NLP covers: the rods of the heel and of each toe, and how many
    distinct toe chains (1 for identical toes, whatever their number). A splayed (spatial) foot
    is one NLP per toe count (``splayed_toes``: its toe chains, each at its own yaw; 0: planar),
    with ``yaws`` yaw variables (see the inner search's module docstring)."""

    heel_segments: int
    toe_segments: int
    distinct_toes: int
    splayed_toes: int = 0
    yaws: int = 0

    @property
    def name(self) -> str:
        """A C identifier (shape labels such as ``3x1+h2`` are not)."""
        splay = f"_s{self.splayed_toes}_y{self.yaws}" if self.spatial else ""
        return f"foot_h{self.heel_segments}_t{self.toe_segments}_k{self.distinct_toes}{splay}"

    @property
    def spatial(self) -> bool:
        return self.splayed_toes > 0

    @property
    def sizes(self) -> tuple[int, ...]:
        """Rods per distinct chain (its angles and masses), heel first."""
        return (self.heel_segments, *([self.toe_segments] * self.distinct_toes))

    @property
    def length_sizes(self) -> tuple[int, ...]:
        """Rods per chain whose lengths are variables, heel first: the distinct chains in the
        plane; every chain of a splayed foot (a toe's reach depends on its yaw, so identical
        toes share angles and masses but level their tips with lengths of their own)."""
        return (self.heel_segments, *([self.toe_segments] * self.splayed_toes)) if self.spatial else self.sizes

    @property
    def chain_of(self) -> tuple[int, ...]:
        """The distinct chain (of :attr:`sizes`) of each chain of :attr:`length_sizes`."""
        if not self.spatial:
            return tuple(range(len(self.sizes)))
        return (0, *((1 if self.distinct_toes == 1 else i + 1) for i in range(self.splayed_toes)))


def yaw_count(splay: SplaySpace, n_toes: int) -> int:
    """The NLP's yaw variables: one splay (symmetric, two toes or more) or one yaw per toe; none
    when the range is fixed ([x, x]), as :func:`optimizer.search.outer.suggest_yaws` asks."""
    lo, hi = splay.splay
    if lo == hi or (splay.mode is SplayMode.SYMMETRIC and n_toes == 1):
        return 0
    return 1 if splay.mode is SplayMode.SYMMETRIC else n_toes


def toe_yaws(splay: SplaySpace, n_toes: int, values: Sequence) -> tuple:
    """Every toe's yaw from the NLP's yaw variables ``values`` (floats or CasADi symbols; empty
    when :func:`yaw_count` is 0), as :func:`optimizer.search.outer.suggest_yaws` spreads them."""
    lo = splay.splay[0]
    if splay.mode is SplayMode.SYMMETRIC:
        return symmetric_yaws(n_toes, values[0] if len(values) else lo)
    return tuple(values) if len(values) else (lo,) * n_toes


def foot_kind(config: StudyConfig, shape: FootShape) -> FootKind:
    identical = config.space.toe_symmetry is ToeSymmetry.IDENTICAL
    distinct = 1 if identical else shape.n_toes
    if not config.space.spatial:
        return FootKind(shape.heel_segments, shape.toe_segments, distinct)
    splay = config.space.splay
    assert splay is not None
    return FootKind(shape.heel_segments, shape.toe_segments, distinct, shape.n_toes, yaw_count(splay, shape.n_toes))


@dataclass(frozen=True)
class CompiledNlp:
    """One kind's NLP, ready to solve.

    Attributes:
        kind: the foot kind.
        solver: IPOPT on the compiled functions; parameters ``[w1, w2, n_toes]``; constraint row
            0 is the second objective f2 (its upper bound is a solve's epsilon).
        values: ``(x, n_toes)`` -> ``VALUE_OUTPUTS`` (compiled).
        lbx, ubx, lbg, ubg: bounds (the same for every toe count).
        warm_solver: the same NLP, IPOPT started from the given primal and dual point
            (:data:`WARM_OPTIONS`), for a solve near a known optimum; None: ``solver``.
    """

    kind: FootKind
    solver: ca.Function
    values: ca.Function
    lbx: np.ndarray
    ubx: np.ndarray
    lbg: np.ndarray
    ubg: np.ndarray
    warm_solver: ca.Function | None = None

    @property
    def n_rods(self) -> int:
        return sum(self.kind.sizes)

    @property
    def n_lengths(self) -> int:
        return sum(self.kind.length_sizes)

    @property
    def n_x(self) -> int:
        return int(self.lbx.size)


def _source_hash() -> str:
    """Hash of the source of every module that shapes the NLP graph."""
    h = hashlib.sha256()
    roots = [Path(impulse_core.__file__).parent]
    files = sorted(p for r in roots for p in r.rglob("*.py"))
    here = Path(__file__).parent.parent
    files += [Path(__file__), here / "design_space.py"]
    for f in files:
        h.update(f.read_bytes())
    return h.hexdigest()


def nlp_key(config: StudyConfig, kind: FootKind, compiler: str) -> str:
    """The cache key of a kind's library (see the module docstring): it hashes what the generated
    source is made from (generating the source to hash it would cost what the cache saves)."""
    return entry_key(
        repr(config.leg),
        repr(config.limits),
        repr((config.scene.speed, config.scene.restitution)),
        repr(tuple(o.value for o in config.objectives)),
        repr((config.landings, tuple(config.statistic_of(o) for o in config.objectives))),
        repr(kind),
        *((repr(config.space.splay),) if kind.spatial else ()),
        _source_hash(),
        ca.__version__,
        compiler_identity(compiler),
        *NLP_CFLAGS,
    )


#: Solves of one kind below which an uncached kind of an SX NLP runs on CasADi's virtual machine
#: rather than being compiled: the toe-count study measured (CPU) gcc at 0.5 / 0.8 / 1.2 s for
#: its one-, two- and three-rod toes' libraries, and the virtual machine's extra cost at 0.9 /
#: 1.7 / 2.9 ms per solve (IPOPT's own work dominates either way), so a build repays itself after
#: 400-560 solves. A planar MX NLP (a study with landings) is always compiled.
COMPILE_SOLVES = 500
#: Solves x scenarios below which an uncached spatial MX NLP (splayed toes over landings) runs on
#: the virtual machine: on two one-rod splayed toes, gcc took 13-17 s and the virtual machine
#: 0.20 s more per solve over 5 scenarios (28 iterations) and 1.3 s more over 20 (36 iterations),
#: so a build repays itself after about 300 scenario-solves.
COMPILE_SCENARIO_SOLVES = 300

#: Niceness added per place in the build order (the first kind's build runs at the search's own).
NICENESS_STEP = 5

IPOPT_OPTIONS = {
    "ipopt.print_level": 0,
    "print_time": False,
    "ipopt.sb": "yes",
    "ipopt.tol": 1e-8,
    "ipopt.constr_viol_tol": 1e-9,
    "ipopt.bound_relax_factor": 0.0,
    "ipopt.max_iter": 300,
    "ipopt.mu_strategy": "adaptive",
}
#: A warm-started solve's options on top of ``IPOPT_OPTIONS``: IPOPT takes the given multipliers
#: (else it ignores them) and a small barrier, pushing the start little off its bounds. On the
#: toe-count study's epsilon sweeps: 1455 -> 941 iterations, the same designs to 1e-9.
WARM_OPTIONS = {
    "ipopt.warm_start_init_point": "yes",
    "ipopt.mu_init": 1e-4,
    "ipopt.warm_start_bound_push": 1e-6,
    "ipopt.warm_start_mult_bound_push": 1e-6,
}


class NlpCache:
    """The NLPs of a study's kinds of foot. Made with the kinds it will need: the libraries that
    are not cached yet are generated at once and compiled in background threads (one compiler
    process per library); ``cache[kind]`` waits for that kind's only, so the search of one kind
    runs while the others compile. Libraries live in the trusted cache
    (:mod:`impulse_core.compile.cache`). Without a C compiler, or when a build fails, that kind's
    NLP runs on CasADi's virtual machine, and a ``RuntimeWarning`` says so.

    ``solves``: the solves planned per kind; an uncached kind of an SX NLP with fewer than
    :data:`COMPILE_SOLVES` runs on the virtual machine, silently (None: every kind is compiled)."""

    def __init__(
        self,
        config: StudyConfig,
        kinds: list[FootKind],
        directory: Path | None = None,
        solves: dict[FootKind, int] | None = None,
    ) -> None:
        self._config, self._ready, self._solves = config, {}, solves
        self._folders: dict[FootKind, Path | None] = {}
        self._vm: dict[FootKind, _Graph] = {}
        self._compiler = find_compiler()
        self._root = directory or cache_dir()
        self._pool = ThreadPoolExecutor(max_workers=max(1, len(kinds)))
        # In the order the search needs them: each later build yields the cores to the earlier.
        self._builds = {k: self._start(k, NICENESS_STEP * i) for i, k in enumerate(kinds)}

    def _key(self, kind: FootKind) -> str:
        return nlp_key(self._config, kind, self._compiler)

    def building(self, kind: FootKind) -> bool:
        """Whether the kind's library is being compiled (:meth:`library` would wait for it)."""
        return self._builds.get(kind) is not None

    def compiles(self, kind: FootKind) -> bool:
        """Whether the kind, when not cached, is compiled (else it runs on the virtual machine):
        in the plane always with landings (an MX NLP), in space with landings when ``solves``
        plans :data:`COMPILE_SCENARIO_SOLVES` or more solves x scenarios, without landings when
        it plans :data:`COMPILE_SOLVES` or more."""
        planned = math.inf if self._solves is None else self._solves.get(kind, 0)
        landings = self._config.landings
        if landings is None:
            return planned >= COMPILE_SOLVES
        return not kind.spatial or planned * landings.count >= COMPILE_SCENARIO_SOLVES

    def _start(self, kind: FootKind, niceness: int = 0) -> tuple[_Graph, Future] | None:
        """Generate the kind's C and start compiling it, unless it is cached, cannot be compiled,
        or is not worth it (:meth:`compiles`)."""
        if (
            self._compiler is None
            or not self.compiles(kind)
            or lookup(self._root, kind.name, self._key(kind)) is not None
        ):
            return None
        graph = _graph(self._config, kind)
        build = functools.partial(_build, _sources(graph, kind), graph, self._compiler, niceness)
        return graph, self._pool.submit(store, self._root, kind.name, self._key(kind), build)

    def __getitem__(self, kind: FootKind) -> CompiledNlp:
        if kind not in self._ready:
            folder = self.library(kind)
            if folder is None:
                self._ready[kind] = vm_nlp(self._config, kind, self._vm.pop(kind, None))
            else:
                self._ready[kind] = load_nlp(kind, folder)
        return self._ready[kind]

    def library(self, kind: FootKind) -> Path | None:
        """The cache folder of the kind's compiled NLP (waiting for its build; another process
        loads it with :func:`load_nlp`), or None when the kind runs on CasADi's virtual machine
        (no C compiler, or its build failed: a ``RuntimeWarning`` says so)."""
        if kind in self._folders:
            return self._folders[kind]
        folder, graph = None, None
        if self._compiler is None:
            warnings.warn(
                "no C compiler found (cc, gcc or clang): the inner search runs on CasADi's virtual machine (slower)",
                RuntimeWarning,
                stacklevel=3,
            )
        else:
            started = self._builds.pop(kind, None) or self._start(kind)
            if started is None:
                folder = lookup(self._root, kind.name, self._key(kind))
                started = self._start(kind) if folder is None else None
            if started is not None:
                graph, future = started
                try:
                    folder = future.result()
                except CompileError as exc:
                    warnings.warn(
                        f"{exc}; {kind.name} runs on CasADi's virtual machine (slower)", RuntimeWarning, stacklevel=3
                    )
        if graph is not None:  # generated for a build that failed: the virtual machine reuses it
            self._vm[kind] = graph
        self._folders[kind] = folder
        return folder


def load_nlp(kind: FootKind, folder: Path) -> CompiledNlp:
    """The kind's NLP from its cache folder (:meth:`NlpCache.library`)."""
    bounds = np.load(folder / "bounds.npz")
    solver, warm = (ca.nlpsol(kind.name, "ipopt", str(folder / "nlp.so"), o) for o in _options())
    values = ca.external("foot_values", str(folder / "values.so"))
    return CompiledNlp(kind, solver, values, *(bounds[b] for b in ("lbx", "ubx", "lbg", "ubg")), warm)


def _options() -> tuple[dict, dict]:
    """IPOPT's options of a cold and of a warm-started solve."""
    return IPOPT_OPTIONS, {**IPOPT_OPTIONS, **WARM_OPTIONS}


def vm_nlp(config: StudyConfig, kind: FootKind, graph: _Graph | None = None) -> CompiledNlp:
    """The kind's NLP on CasADi's virtual machine (from ``graph`` when it is already built)."""
    graph = graph or _graph(config, kind)
    solver, warm = (ca.nlpsol(kind.name, "ipopt", graph.nlp, o) for o in _options())
    return CompiledNlp(kind, solver, graph.values, graph.lbx, graph.ubx, graph.lbg, graph.ubg, warm)


def _sources(graph: _Graph, kind: FootKind) -> dict[str, str]:
    """A kind's C: the NLP's functions (``nlp.c``) and ``foot_values`` (``values.c``)."""
    solver = ca.nlpsol(kind.name, "ipopt", graph.nlp, IPOPT_OPTIONS)
    dependencies = [solver.oracle(), *map(solver.get_function, solver.get_function())]
    sources = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, functions in (("nlp", dependencies), ("values", [graph.values])):
            generator = ca.CodeGenerator(f"{name}.c", {"with_header": False})
            for f in functions:
                generator.add(f)
            sources[name] = Path(generator.generate(f"{tmp}/")).read_text()
    return sources


def _build(sources: dict[str, str], graph: _Graph, compiler: str, niceness: int, work: Path) -> list[str]:
    """Compile a kind's sources into ``work`` (both at once, at ``niceness``) beside its bounds;
    the files made."""
    commands = []
    for name, text in sources.items():
        (work / f"{name}.c").write_text(text)
        commands.append([compiler, *NLP_CFLAGS, str(work / f"{name}.c"), "-o", str(work / f"{name}.so")])
    run_compilers(*commands, niceness=niceness)
    np.savez(work / "bounds.npz", lbx=graph.lbx, ubx=graph.ubx, lbg=graph.lbg, ubg=graph.ubg)
    return ["nlp.so", "values.so", "bounds.npz"]


@dataclass(frozen=True)
class _Graph:
    nlp: dict
    values: ca.Function
    lbx: np.ndarray
    ubx: np.ndarray
    lbg: np.ndarray
    ubg: np.ndarray


def _graph(config: StudyConfig, kind: FootKind) -> _Graph:
    """The symbolic NLP of a kind (see the inner search's module docstring for its rows). With
    ``landings``, each objective is its statistic over the scenarios (:func:`_statistic`), the
    impact is one mapped call over the scenarios, and the NLP is an MX graph (its derivatives
    are maps too, so the library grows with the impact, not with the scenario count)."""
    lim = config.limits
    sizes = kind.sizes
    n = sum(sizes)
    starts = np.cumsum((0, *sizes[:-1]))
    distinct = [list(range(s, s + k)) for s, k in zip(starts, sizes, strict=True)]
    sym = ca.SX if config.landings is None else ca.MX
    a, m = sym.sym("joint_angle", n), sym.sym("mass", n)
    L, h = sym.sym("length", sum(kind.length_sizes)), sym.sym("ankle_height")
    psi = sym.sym("yaw", kind.yaws)
    params = sym.sym("params", 3)  # w1, w2, toe count
    n_toes = params[2] if kind.distinct_toes == 1 else sym(1)
    mult = [sym(1)] + [n_toes] * kind.distinct_toes
    if kind.spatial:  # every toe its own chain: each counts once
        splay = config.space.splay
        assert splay is not None
        yaws = toe_yaws(splay, kind.splayed_toes, [psi[j] for j in range(kind.yaws)])
        if config.landings is None:
            p_tree, masses, topology = _splayed_values(config, kind, a, m, L, yaws)
            impact = _splayed_impact(config, topology, p_tree)
        else:  # the tree's values as one call, its impact mapped over the scenarios
            tree, topology = _splayed_tree_function(config, kind)
            p_tree, body_masses = tree(a, m, L, psi)
            masses = [body_masses[b] for b in range(body_masses.numel())]
            impact = _splayed_scenario_impacts(config, topology, p_tree)
    elif config.landings is None:
        impact = _merged_impact(config, kind, a, m, mult)
    else:
        impact = _scenario_impacts(config, kind, a, m, L, n_toes)

    extra: list = []
    g, lbg, ubg = [], [], []

    def add(expr, lo: float, hi: float) -> None:
        g.append(expr)
        lbg.extend([lo] * expr.numel())
        ubg.extend([hi] * expr.numel())

    def variable(name: str, size: int = 1):
        extra.append(sym.sym(name, size))
        return extra[-1]

    def objective(o: Objective):
        per_scenario = _per_scenario(o, impact, variable, add)
        return per_scenario if config.landings is None else _statistic(config.statistic_of(o), per_scenario, variable, add)

    primary = config.objectives[:2]
    f1 = objective(primary[0])
    f2 = objective(primary[1]) if len(primary) > 1 else sym(0)
    g.insert(0, f2)  # the epsilon row comes first
    lbg.insert(0, -math.inf)
    ubg.insert(0, math.inf)
    if kind.spatial:  # every chain of the tree: identical toes repeat their angles and masses
        chains = [distinct[c] for c in kind.chain_of]
        starts_L = np.cumsum((0, *kind.length_sizes[:-1]))
        lengths = [list(range(s, s + k)) for s, k in zip(starts_L, kind.length_sizes, strict=True)]
        turns = [1.0, *(ca.cos(y) for y in yaws)]
        _geometric_rows(config, chains, a, m, L, h, [sym(1)] * len(chains), add, lengths, turns)
        for j in range(kind.yaws - 1):  # per-toe yaws in order: a relabelling of the toes (docstring)
            add(psi[j + 1] - psi[j], 0.0, math.inf)
        if lim.support_margin is not None:
            _support_rows(config, kind, topology, p_tree, masses, add)
    else:
        _geometric_rows(config, distinct, a, m, L, h, mult, add)
    add(ca.vec(impact["external"]), TIGHTEN, math.inf)
    # No energy row: Newton's law gives E_after - E_before = (1 - e) sum(lambda_c v-_c) / 2 <= 0
    # once every lambda >= 0 and every contact approaches (v-_c < 0); the realised design is
    # evaluated by the model ``auto`` picks, which checks both.

    x = ca.vertcat(a, m, L, h, psi, *extra)
    a_lo, a_hi = [], []
    for chain, bounds in zip(distinct, _chain_limits(config, kind), strict=True):
        a_lo += [bounds[j][0] for j in range(len(chain))]
        a_hi += [bounds[j][1] for j in range(len(chain))]
    k = sum(e.numel() for e in extra)
    n_L = L.numel()
    yaw_lo, yaw_hi = config.space.splay.splay if kind.spatial else (0.0, 0.0)
    lbx = np.concatenate([a_lo, [lim.min_link_mass * (1 + 1e-6)] * n, [LENGTH_FLOOR] * n_L, [0.0],
                          [yaw_lo] * kind.yaws, [0.0] * k])
    ubx = np.concatenate([a_hi, [lim.foot_mass] * n, [math.inf] * n_L, [math.inf], [yaw_hi] * kind.yaws,
                          [math.inf] * k])
    nlp = {"x": x, "p": params, "f": params[0] * f1 + params[1] * f2, "g": ca.vertcat(*g)}
    if kind.spatial and config.landings is not None:  # the nominal scene's, on SX symbols of their own
        values = _splayed_values_function(config, kind)
    elif kind.spatial:  # the values of the NLP's design variables (the evaluation is evaluate_design's)
        values = _values(impact, ca.vertcat(a, m, L, h, psi), params[2], "foot_values", "design")
    elif config.landings is None:
        values = _values(impact, ca.vertcat(a, m), params[2], "foot_values")
    else:  # the nominal scene's values, on SX symbols of their own
        values = values_function(config, kind, "foot_values")
    return _Graph(nlp, values, lbx, ubx, np.array(lbg), np.array(ubg))


def _per_scenario(o: Objective, impact: dict, variable, add):
    """Objective ``o`` per scenario (1 x S; S = 1 without landings). ``max_internal`` and
    ``base_angular_velocity`` get one epigraph variable per scenario."""
    if o in (Objective.EXTERNAL_NORM, Objective.INTERNAL_NORM, Objective.ENERGY_AFTER):
        return impact[o.value]
    omega = impact["omega"]  # 1 x S in the plane, 3 x S in space
    u = variable(f"epigraph_{o.value}", omega.shape[1])
    if o is Objective.MAX_INTERNAL:
        for j in range(impact["scaled_magnitude"].shape[0]):
            add(u - impact["scaled_magnitude"][j, :].T, 0.0, math.inf)
    elif omega.shape[0] == 1:  # base angular velocity: |omega| <= u
        add(u - omega.T, 0.0, math.inf)
        add(u + omega.T, 0.0, math.inf)
    else:  # in space |omega| <= u as u^2 - |omega|^2 >= 0 (u >= 0 by its bound): smooth at omega = 0
        add(u**2 - ca.sum1(omega**2).T, 0.0, math.inf)
    return u.T


def _statistic(statistic: Statistic, u, variable, add):
    """The statistic of ``u`` (1 x S), as :mod:`optimizer.evaluation.statistics` defines it, in a
    form IPOPT's exact derivatives serve: ``mean`` and ``std`` as written (smooth while the values
    differ); ``max`` by an epigraph variable t >= u_s; ``cvar:q`` by Rockafellar and Uryasev's
    reformulation, t + sum z_s / ((1 - q) S) with z_s >= u_s - t, z_s >= 0 (exact at the NLP's
    optimum over t and z, and an upper bound elsewhere, so an epsilon row on it is exact too).
    ``max`` and ``cvar`` are nondecreasing in every u_s, so per-scenario epigraph variables stay
    tight; ``quantile`` (neither smooth nor convex) is refused when the study is read."""
    size = u.numel()
    mean = ca.sum2(u) / size
    if statistic.kind is StatisticKind.MEAN:
        return mean
    if statistic.kind is StatisticKind.STD:
        return ca.sqrt(ca.sum2((u - mean) ** 2) / size)
    t = variable(f"{statistic.kind.value}_level")
    if statistic.kind is StatisticKind.MAX:
        add(t - u.T, 0.0, math.inf)
        return t
    if statistic.kind is StatisticKind.CVAR:
        z = variable("cvar_excess", size)
        add(z - u.T + t, 0.0, math.inf)
        return t + ca.sum1(z) / ((1.0 - float(statistic.q)) * size)
    raise ValueError(f"the inner search takes no {statistic.text} statistic")


def _values(
    impact: dict[str, ca.SX], angles_masses: ca.SX, n_toes: ca.SX, name: str, input_name: str = "angles_masses"
) -> ca.Function:
    """``(angles and masses, toe count)`` -> ``VALUE_OUTPUTS`` (a splayed foot: its NLP's design
    variables, ``input_name`` ``design``, in place of the angles and masses)."""
    lam = impact["per_toe_external"]
    outs = [impact[k] for k in VALUE_OUTPUTS[:6]] + [ca.mmin(lam) if lam.shape[0] else ca.SX(0)]
    return ca.Function(name, [angles_masses, n_toes], outs, [input_name, "n_toes"], list(VALUE_OUTPUTS))


def values_function(config: StudyConfig, kind: FootKind, name: str | None = None) -> ca.Function:
    """The kind's ``VALUE_OUTPUTS`` alone (the outer search's evaluation), named after the kind."""
    n = sum(kind.sizes)
    a, m, n_toes = ca.SX.sym("joint_angle", n), ca.SX.sym("mass", n), ca.SX.sym("n_toes")
    mult = [ca.SX(1)] + [n_toes if kind.distinct_toes == 1 else ca.SX(1)] * kind.distinct_toes
    return _values(_merged_impact(config, kind, a, m, mult), ca.vertcat(a, m), n_toes, name or f"values_{kind.name}")


#: Per-scenario outputs of :func:`_scenario_function` (rows x scenarios once mapped).
SCENARIO_OUTPUTS = ("external", "scaled_magnitude", "omega", "external_norm", "internal_norm", "energy_after")


def scenario_approach(config: StudyConfig, spatial: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Each scenario's base velocity before the impact and restitution (1 x S): in the plane
    [vx, vy, omega] columns (3 x S), as :func:`optimizer.evaluation.batched.scenario_inputs` sets
    them; in space (``spatial``) [vx, vy, vz, wx, wy, wz] columns (6 x S, world frame), as
    :func:`optimizer.evaluation.scenarios.overrides` writes ``scene.velocity`` [velocity_x,
    -speed, velocity_z] and ``scene.angular_velocity`` [roll_rate, 0, angular_velocity]."""
    assert config.landings is not None
    s, draws = config.scene, config.landings.draw()
    column = dict(zip(config.landings.names, draws.T, strict=True))
    ones = np.ones(len(draws))
    vx, vy = column.get("velocity_x", 0.0) * ones, -column.get("speed", s.speed) * ones
    wz = column.get("angular_velocity", 0.0) * ones
    if spatial:
        base = np.vstack([vx, vy, column.get("velocity_z", 0.0) * ones, column.get("roll_rate", 0.0) * ones,
                          0.0 * ones, wz])
    else:
        base = np.vstack([vx, vy, wz])
    return base, (column.get("restitution", s.restitution) * ones)[None, :]


def _scenario_function(config: StudyConfig, kind: FootKind) -> ca.Function:
    """``(angles, masses, lengths, toe count, base velocity, restitution)`` -> ``SCENARIO_OUTPUTS``
    of one landing of the merged foot."""
    n = sum(kind.sizes)
    a, m, L = ca.SX.sym("joint_angle", n), ca.SX.sym("mass", n), ca.SX.sym("length", n)
    n_toes = ca.SX.sym("n_toes")
    base, e = ca.SX.sym("base_velocity", 3), ca.SX.sym("restitution")
    mult = [ca.SX(1)] + [n_toes if kind.distinct_toes == 1 else ca.SX(1)] * kind.distinct_toes
    impact = _merged_impact(config, kind, a, m, mult, (base, e), L)
    outs = [impact[k] for k in SCENARIO_OUTPUTS]
    names = ["a", "m", "L", "n_toes", "base", "e"]
    return ca.Function("scenario", [a, m, L, n_toes, base, e], outs, names, list(SCENARIO_OUTPUTS))


def _scenario_impacts(config: StudyConfig, kind: FootKind, a, m, L, n_toes) -> dict:
    """``SCENARIO_OUTPUTS`` over the study's landings: one mapped call (rows x S, symbolic in
    the NLP's variables)."""
    base, e = scenario_approach(config)
    mapped = _scenario_function(config, kind).map(base.shape[1])
    return dict(zip(SCENARIO_OUTPUTS, mapped(a, m, L, n_toes, ca.DM(base), ca.DM(e)), strict=True))


def _chain_limits(config: StudyConfig, kind: FootKind) -> tuple:
    shape = FootShape(kind.distinct_toes, kind.toe_segments, kind.heel_segments)
    return config.limits.joint_limits(shape)


def _merged_impact(config: StudyConfig, kind: FootKind, a, m, mult, approach=None, lengths=None) -> dict[str, ca.SX]:
    """The impact of the merged tree (each distinct toe's rods carry ``mult`` times their mass)
    and the real foot's objectives (see the module docstring). ``approach``: (base velocity
    [vx, vy, omega], restitution), symbolic; None: the study's scene, straight down.
    ``lengths``: the rods' lengths (a turning approach's contact speeds depend on them); None:
    fixed ones, which a straight-down approach does not see."""
    template = FootDesign(
        heel=tuple(Segment(0.1, 0.1, 0.0) for _ in range(kind.heel_segments)),
        toes=tuple(tuple(Segment(0.1, 0.1, 0.0) for _ in range(kind.toe_segments)) for _ in range(kind.distinct_toes)),
    )
    tree = foot_tree(config.leg, template)
    space = values_space(tree, PLANAR)  # a leg with centres of mass off its rods: their offsets too
    p = ca.SX(ca.DM(design_vector(tree, space.body_values)))
    width = len(space.body_values)
    legs = len(leg_chain(config.leg).rods)
    body, body_mult = legs, [ca.SX(1)] * (legs - 1)  # the leg's joint impulses are counted once
    for c, k in enumerate(kind.sizes):
        for _ in range(k):
            i = body - legs
            # The impulses of a straight-down approach do not depend on the rods' lengths (rods
            # scale with their length: com and radius of gyration are fractions of it), so that
            # impact sees fixed ones and its derivatives skip the lengths (tested against
            # evaluate() on real lengths); a turning approach's contact speeds need them.
            if lengths is not None:
                p[width * body] = lengths[i]
            p[width * body + 1] = mult[c] * m[i]
            p[width * body + 2] = a[i]
            body_mult.append(mult[c])
            body += 1
    topology = tree.topology()
    if approach is None:
        v_minus, e = ca.DM(approach_velocity(topology, config.scene.speed)), config.scene.restitution
    else:
        base, e = approach
        v_minus = ca.vertcat(base, ca.SX(len(approach_velocity(topology, 0.0)) - base.numel(), 1))
    out = compiled_model(topology, space).impact(p=p, v_minus=v_minus, restitution=e)
    lam, mag = out["external"], out["internal_magnitude"]
    contact_mult = ca.vertcat(*mult)
    joint_mult = ca.vertcat(*body_mult)
    return {
        "external": lam,
        "per_toe_external": lam / contact_mult,
        "external_norm": ca.sqrt(ca.sum1(lam**2 / contact_mult)),
        "internal_norm": ca.sqrt(ca.sum1(mag**2 / joint_mult)),
        "scaled_magnitude": mag / joint_mult,
        "max_internal": ca.mmax(mag / joint_mult),
        "omega": out["v_plus"][2],
        "base_angular_velocity": ca.fabs(out["v_plus"][2]),
        "energy_after": out["energy_after"],
        "energy_before": out["energy_before"],
    }


def _splayed_values(
    config: StudyConfig, kind: FootKind, a: ca.SX, m: ca.SX, L: ca.SX, yaws: Sequence
) -> tuple[ca.SX, list, Topology]:
    """The splayed foot's tree as the core's design vector (SPATIAL layout), symbolic in the
    NLP's angles, masses and lengths (every chain its own lengths) and the toes' yaws (each toe
    root's ``rpy`` on the leg's last rod, :func:`optimizer.design_space.yaw_rpy`: a planar or a
    spatial leg, whose rods keep their own values: axes, ``rpy``, mass properties); with every
    body's mass and the topology."""
    n_toes = kind.splayed_toes
    rod = Segment(0.1, 0.1, 0.0)
    template = FootDesign(heel=(rod,) * kind.heel_segments, toes=((rod,) * kind.toe_segments,) * n_toes,
                          toe_yaws=(0.1,) * n_toes)
    tree = foot_tree(config.leg, template)
    names = SPATIAL.body_values
    width, col = len(names), {k: names.index(k) for k in ("length", "mass", "angle", "roll", "pitch", "yaw")}
    p = ca.SX(ca.DM(design_vector(tree, names)))
    masses = [ca.SX(b.mass) for b in tree.bodies]
    starts = np.cumsum((0, *kind.sizes[:-1]))
    chain = leg_chain(config.leg)
    body, k = len(chain.rods), 0
    for c, d in enumerate(kind.chain_of):
        for j in range(kind.length_sizes[c]):
            i = int(starts[d]) + j
            p[width * body + col["length"]], p[width * body + col["mass"]] = L[k], m[i]
            p[width * body + col["angle"]] = a[i]
            masses[body] = m[i]
            if c > 0 and j == 0:  # a toe root: its yaw about the vertical
                rpy = yaw_rpy(chain, yaws[c - 1])
                for key, value in zip(("roll", "pitch", "yaw"), rpy, strict=True):
                    p[width * body + col[key]] = value
            body, k = body + 1, k + 1
    return p, masses, tree.topology()


def _splayed_impact(config: StudyConfig, topology: Topology, p: ca.SX, approach=None) -> dict[str, ca.SX]:
    """The splayed foot's impact (Newton's law, eq. 11, in space) and its objectives as
    :func:`optimizer.design_space.objectives` reads them: no toe merged, the base's turn the norm
    of its angular velocity (``omega``: 3 x 1). ``approach``: (base velocity [vx, vy, vz, wx, wy,
    wz], restitution), symbolic, the joints at rest; None: the study's scene, straight down."""
    if approach is None:
        v_minus, e = ca.DM(approach_velocity(topology, config.scene.speed, SPATIAL)), config.scene.restitution
    else:
        base, e = approach
        v_minus = ca.vertcat(base, ca.SX(len(approach_velocity(topology, 0.0, SPATIAL)) - base.numel(), 1))
    out = compiled_model(topology, SPATIAL).impact(p=p, v_minus=v_minus, restitution=e)
    lam, mag, omega = out["external"], out["internal_magnitude"], out["v_plus"][3:6]
    return {
        "external": lam,
        "per_toe_external": lam,
        "external_norm": ca.norm_2(lam),
        "internal_norm": ca.norm_2(mag),
        "scaled_magnitude": mag,
        "max_internal": ca.mmax(mag),
        "omega": omega,
        "base_angular_velocity": ca.norm_2(omega),
        "energy_after": out["energy_after"],
        "energy_before": out["energy_before"],
    }


def _splayed_tree_function(config: StudyConfig, kind: FootKind) -> tuple[ca.Function, Topology]:
    """``(angles, masses, lengths, yaw variables)`` -> (the design vector, every body's mass) of
    :func:`_splayed_values`, on SX symbols of its own (an MX NLP calls it), and the topology."""
    n = sum(kind.sizes)
    a, m = ca.SX.sym("joint_angle", n), ca.SX.sym("mass", n)
    L, psi = ca.SX.sym("length", sum(kind.length_sizes)), ca.SX.sym("yaw", kind.yaws)
    splay = config.space.splay
    assert splay is not None
    yaws = toe_yaws(splay, kind.splayed_toes, [psi[j] for j in range(kind.yaws)])
    p, masses, topology = _splayed_values(config, kind, a, m, L, yaws)
    f = ca.Function("splayed_tree", [a, m, L, psi], [p, ca.vertcat(*masses)], ["a", "m", "L", "yaw"], ["p", "masses"])
    return f, topology


def _splayed_scenario_impacts(config: StudyConfig, topology: Topology, p) -> dict:
    """``SCENARIO_OUTPUTS`` of the splayed foot (design vector ``p``, symbolic) over the study's
    landings: one mapped call of one landing's impact (rows x S; ``omega`` 3 x S)."""
    base, e = scenario_approach(config, spatial=True)
    q = ca.SX.sym("p", p.numel())
    approach = (ca.SX.sym("base_velocity", 6), ca.SX.sym("restitution"))
    impact = _splayed_impact(config, topology, q, approach)
    f = ca.Function("splayed_scenario", [q, *approach], [impact[k] for k in SCENARIO_OUTPUTS], ["p", "base", "e"],
                    list(SCENARIO_OUTPUTS))
    return dict(zip(SCENARIO_OUTPUTS, f.map(base.shape[1])(p, ca.DM(base), ca.DM(e)), strict=True))


def _splayed_values_function(config: StudyConfig, kind: FootKind) -> ca.Function:
    """The splayed foot's nominal ``VALUE_OUTPUTS`` in the NLP's design variables (angles,
    masses, lengths, ankle height, yaws), on SX symbols of their own (an NLP over landings)."""
    f, topology = _splayed_tree_function(config, kind)
    design = ca.SX.sym("design", 2 * sum(kind.sizes) + sum(kind.length_sizes) + 1 + kind.yaws)
    n, n_L = sum(kind.sizes), sum(kind.length_sizes)
    p, _ = f(design[:n], design[n : 2 * n], design[2 * n : 2 * n + n_L], design[2 * n + n_L + 1 :])
    return _values(_splayed_impact(config, topology, p), design, ca.SX.sym("n_toes"), "foot_values", "design")


def support_edges(kind: FootKind, topology: Topology, p: ca.SX, masses: list) -> tuple[ca.SX, ca.SX]:
    """The splayed foot's support polygon in the NLP's fixed contact order (heel, then the toes
    by decreasing yaw: counter-clockwise seen in (x, z) when the yaws are ordered): for each edge
    (P, Q), d = Q - P, the cross product s = d x (c - P) with c the whole tree's centre of mass
    projected on the ground (|d| times c's signed distance to the edge's line, > 0 inside), and
    |d|^2. Symbolic in the design vector ``p`` and the bodies' ``masses`` (two toes or more)."""
    geometry = compiled_geometry(topology, SPATIAL)(p=p)
    coms, contacts = geometry["coms"], geometry["contacts"]
    total = sum(masses[1:], masses[0])
    com = sum((masses[b] * coms[:, b] for b in range(1, len(masses))), masses[0] * coms[:, 0]) / total
    c = ca.vertcat(com[0], com[2])
    order = [0, *range(kind.splayed_toes, 0, -1)]
    return polygon_edges([ca.vertcat(contacts[0, i], contacts[2, i]) for i in order], c)


def polygon_edges(corners: Sequence, c) -> tuple:
    """Per edge (P, Q) of the closed polygon ``corners`` (each 2 x 1, SX or DM), d = Q - P: the
    cross product s = d x (c - P) (|d| times c's signed distance to the edge's line, > 0 left of
    it) and |d|^2, each stacked in a column."""
    cross, squared = [], []
    for P, Q in zip(corners, [*corners[1:], corners[0]], strict=True):
        d, w = Q - P, c - P
        cross.append(d[0] * w[1] - d[1] * w[0])
        squared.append(ca.sumsqr(d))
    return ca.vertcat(*cross), ca.vertcat(*squared)


#: The support margin rows' smoothing length (m): the distance row asks s >= b sqrt(|d|^2 + eps^2)
#: (:func:`_support_rows`), 1e-4 of the landing NLP's unit; conservative by b (sqrt(1 + eps^2 /
#: |d|^2) - 1) ~ b eps^2 / (2 |d|^2) in the distance to an edge's line (1e-7 m for b = 4 cm and a
#: 4 cm edge).
MARGIN_EPS = 1e-5
#: The support margin rows' forms (:func:`_support_rows`): ``distance`` (the default) and
#: ``quadratic`` (the earlier one, for comparison).
MARGIN_FORMS = ("distance", "quadratic")


def _support_rows(
    config: StudyConfig, kind: FootKind, topology: Topology, p: ca.SX, masses: list, add: Callable,
    unit: float = 1.0, form: str = "distance",
) -> None:
    """The support margin (``constraints.support_margin``, b): the centre of mass's ground
    projection at least b inside the contacts' hull, smoothly, per edge of :func:`support_edges`
    (s = |d| times the distance to the edge's line, > 0 inside):

        s - b sqrt(|d|^2 + eps^2) >= 0       (``form="distance"``, the default; eps :data:`MARGIN_EPS`)
        s >= 0  and  s^2 >= b^2 |d|^2        (``form="quadratic"``, two rows per edge)
        s >= 0                               (b <= 0, either form)

    Sound for any order: a point at least b left of every edge's line of a closed polygon is at
    least b inside its vertices' hull (the edges wind around it), so a realised design meets the
    true margin; both forms ask s >= b |d|, the distance form a little more, so both are sound.
    The quadratic form is exact where the order is the hull's (identical toes: their tips on a
    circle about the ankle, the heel behind) and on a degenerate edge (d = 0: nothing asked), but
    its gradient, 2 s grad(s) - b^2 grad(|d|^2), loses its s term where s is small: from a start
    near or outside an edge it pulls weakly (``studies/splayed_toes/results.md``, section 6). The
    distance form's gradient, grad(s) - b grad(|d|^2) / (2 sqrt(|d|^2 + eps^2)), keeps grad(s) at
    any s: near and outside an edge it pulls as |d| times the signed distance does. It is
    conservative by b (sqrt(1 + eps^2/|d|^2) - 1) ~ b eps^2 / (2 |d|^2) in the distance to an
    edge's line (at most b eps in s), and it refuses an edge shorter than about
    b eps / sqrt(h^2 - b^2) (h: c's distance to its line): two contacts within ~1e-5 m of each
    other (per-toe yaws that meet on identical toes), where the quadratic form asks nothing; with
    two toes their true margin is <= 0 anyway (two coincident tips and the heel span no area). A
    bound b <= 0 is met by keeping c inside (conservative: the true margin may go to b). One toe
    and the heel span no area: no rows (the realised design's margin decides). ``unit``: the
    rows' length unit (m; s in unit^2, the quadratic row in unit^4), their scale for the solver;
    the rows' feasible set does not depend on it."""
    if form not in MARGIN_FORMS:  # before the toe count: a wrong form fails on every shape
        raise ValueError(f"support margin rows: form {form!r} is not one of {MARGIN_FORMS}")
    if kind.splayed_toes < 2:
        return
    cross, squared = support_edges(kind, topology, p, masses)
    for row in margin_rows(cross, squared, float(config.limits.support_margin), unit, form):
        add(row, 0.0, math.inf)


def margin_rows(cross, squared, margin: float, unit: float = 1.0, form: str = "distance") -> list:
    """The support margin's rows of :func:`_support_rows` (each asked >= 0), in ``unit``, from
    the edge terms s and |d|^2 (m^2, SX or DM) and the bound ``margin`` (m; TIGHTEN added)."""
    if form not in MARGIN_FORMS:
        raise ValueError(f"support margin rows: form {form!r} is not one of {MARGIN_FORMS}")
    cross, squared = cross / unit**2, squared / unit**2
    b = (margin + TIGHTEN) / unit
    if margin <= 0:
        return [cross]
    if form == "distance":
        return [cross - b * ca.sqrt(squared + (MARGIN_EPS / unit) ** 2)]
    return [cross, cross**2 - b**2 * squared]


def _geometric_rows(config: StudyConfig, distinct, a, m, L, h, mult, add, lengths=None, turns=None) -> None:
    """Rows of the NLP that only the geometry and the masses set (level tips, mass per length,
    foot length, clearance, foot mass). ``distinct``: each chain's rods (indices of ``a`` and
    ``m``); ``lengths``: each chain's indices of ``L`` (None: those of ``distinct``); ``turns``:
    each chain's forward run per metre of its run in its plane (a splayed toe's cos(yaw); None:
    1), as :func:`optimizer.design_space.assign_lengths` has them."""
    leg, lim = config.leg, config.limits
    lengths = distinct if lengths is None else lengths
    turns = [1.0] * len(distinct) if turns is None else turns
    phi = []
    for chain in distinct:
        acc, angles = leg_chain(leg).foot_angle, []
        for i in chain:
            acc = acc + a[i]
            angles.append(acc)
        phi.append(angles)
    rods = [list(zip(chain, ls, angles, strict=True)) for chain, ls, angles in zip(distinct, lengths, phi, strict=True)]
    for chain in rods:
        add(sum(L[k] * -ca.sin(v) for _, k, v in chain) - h, 0.0, 0.0)
    lo_rho, hi_rho = lim.mass_per_length
    for chain in rods:
        for i, k, _ in chain:
            add(m[i] - hi_rho * L[k], -math.inf, -TIGHTEN * hi_rho)
            add(lo_rho * L[k] - m[i], -math.inf, -TIGHTEN)
    heel_run = turns[0] * sum(L[k] * ca.cos(v) for _, k, v in rods[0])
    lo_f, hi_f = lim.foot_length
    for chain, turn in zip(rods[1:], turns[1:], strict=True):
        add(turn * sum(L[k] * ca.cos(v) for _, k, v in chain) - heel_run, lo_f + TIGHTEN, hi_f - TIGHTEN)
    for chain in rods:
        for j in range(len(chain) - 1):
            add(h - sum(L[k] * -ca.sin(v) for _, k, v in chain[: j + 1]), lim.min_clearance + TIGHTEN, math.inf)
    rod = (Segment(0.1, 0.1, 0.0),)
    leg_y = foot_geometry(leg, FootDesign(heel=rod, toes=(rod,))).leg_points[:, 1]
    for y in (0.0, *leg_y):
        add(h + float(y), lim.min_clearance + TIGHTEN, math.inf)
    total = sum(mult[c] * m[i] for c, chain in enumerate(distinct) for i in chain)
    if lim.mass_mode is MassMode.EQUAL:
        add(total, lim.foot_mass, lim.foot_mass)
    else:
        add(total, -math.inf, lim.foot_mass)


__all__ = [
    "COMPILE_SCENARIO_SOLVES",
    "COMPILE_SOLVES",
    "IPOPT_OPTIONS",
    "MARGIN_EPS",
    "MARGIN_FORMS",
    "TIGHTEN",
    "VALUE_OUTPUTS",
    "WARM_OPTIONS",
    "CompiledNlp",
    "FootKind",
    "NlpCache",
    "foot_kind",
    "load_nlp",
    "margin_rows",
    "polygon_edges",
    "support_edges",
    "toe_yaws",
    "values_function",
    "yaw_count",
    "vm_nlp",
]
