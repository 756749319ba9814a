"""Speed of one design's evaluation, measured next to Pinocchio in the same run (``footopt bench``).

What is timed is the optimiser's hot path, :func:`impulse_core.impact.delassus.lean_impact_function`
(external impulses, Delassus pivots, joint force impulse magnitudes and both norms; equal to
the full model's outputs to rounding, which :func:`speed_report` checks), and the gradient of both
norms w.r.t. the design values the optimiser's search varies
(:func:`impulse_core.impact.delassus.norms_gradient_function` with ``columns``
:func:`optimizer.design_space.search_columns` on a leg of the rods before the first rod named
``heel...`` or ``toe...``, :func:`gradient_columns`; every value for a tree that is no footopt design):
the adjoint of the impact equations,
beside CasADi's reverse mode through the whole graph as its peer; the adjoint's gradient w.r.t.
every design value is timed beside them (the figure before 2026-11-26).

Batched, four ways, one call from Python per batch: ``Function.map`` on CasADi's virtual
machine; ``Function.map`` over the compiled function (CasADi's C++ loop calls the C code per
design); the compiled C loop (:func:`impulse_core.compile.codegen.batch_kernel`: one C function walks
the designs, NumPy arrays in and out, nothing allocated per call); and the SIMD loop
(:func:`impulse_core.compile.codegen.simd_driver`: the same instructions on several designs at once,
one per vector lane). Compiled: the function
as C (``-O3``), compiled once per topology and cached on disk (:mod:`impulse_core.compile.codegen`); the
virtual machine where no compiler exists. Inputs are built before the clock starts (CasADi
matrices for the maps, one design per row for the C loop).

Timings are medians of repeated runs; quote ratios measured in one run (these machines are noisy).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import casadi as ca
import numpy as np

from impulse_core.compile.codegen import Backend, Compiled, batch_kernel, compile_function, has_openmp, simd_lanes
from impulse_core.evaluate import active_contacts, approach_velocity, compiled_model
from impulse_core.impact.delassus import LEAN_OUTPUTS, lean_impact_function, norms_gradient_function
from impulse_core.kinematics.spatial import PLANAR, Space, n_values, rods_only
from impulse_core.model.tree import Body, ContactSelection, Scene, Topology, Tree, design_vector
from optimizer.analysis.sizes import SCALING_SIZES
from optimizer.design_space import leg_rod_count, search_columns

#: Outputs compared between batched and single calls, and between the lean and the full model.
CHECKED_OUTPUTS = ("external", "internal_magnitude", "external_norm", "internal_norm")


@dataclass(frozen=True)
class SpeedReport:
    """Microseconds per design (or per call) for one model; ``ratio`` = best batched (any path,
    threads included) / Pinocchio (one thread), ``ratio_one_core`` the same without threads,
    ``gradient_ratio`` = gradient / evaluation, both batched on one core on ``gradient_path``
    (the SIMD loop where built, else the C loop, else CasADi's map): the adjoint gradient;
    ``gradient_ratio_autodiff`` the same for CasADi's reverse mode through the whole graph, its
    peer in the same run; ``gradient_ratio_c_loop`` and ``gradient_ratio_map`` the adjoint's on
    those paths. "The gradient" is w.r.t. the ``n_gradient_values`` design values the search
    varies (of ``n_values``), ``gradient_values`` says which and why (:func:`gradient_columns`);
    ``gradient_ratio_all`` and ``gradient_ratio_all_c_loop``: the
    adjoint's gradient w.r.t. every design value, same paths; ``gradient_equals_full``: the
    searched gradients equal the full ones' entries to 1e-12; ``rods``: the functions timed are
    the rods variants (every body's mass-property
    values zero, folded: ``rods=True`` of :func:`lean_impact_function`)."""

    model: str
    n_bodies: int
    n_dof: int
    n_contacts: int
    n_instructions: int
    n_instructions_full: int
    n_instructions_gradient: int | None
    n_instructions_gradient_autodiff: int | None
    n_instructions_gradient_all: int | None
    n_values: int
    n_gradient_values: int
    gradient_values: str
    build_ms: float
    compile_s: float | None
    backend: str
    simd_lanes: int
    us_per_design_single: float
    us_per_design_batched_vm: float
    us_per_design_batched_compiled: float | None
    us_per_design_batched_kernel: float | None
    us_per_design_batched_kernel_threads: float | None
    us_per_design_batched_simd: float | None
    us_per_design_batched_simd_threads: float | None
    openmp: bool
    us_per_design_batched_threads: float | None
    us_per_design_batched: float
    us_per_design_full_batched: float | None
    gradient_path: str
    us_per_design_gradient: float | None
    us_per_design_gradient_autodiff: float | None
    gradient_ratio: float | None
    gradient_ratio_autodiff: float | None
    gradient_ratio_c_loop: float | None
    gradient_ratio_map: float | None
    us_per_design_gradient_all: float | None
    gradient_ratio_all: float | None
    gradient_ratio_all_c_loop: float | None
    gradient_equals_autodiff: bool | None
    gradient_equals_full: bool | None
    pinocchio_us_per_call: float | None
    ratio: float | None
    ratio_one_core: float | None
    batch: int
    batched_equals_single: bool
    lean_equals_full: bool
    scaling: list[dict] = field(default_factory=list)
    rods: bool = False

    def as_dict(self) -> dict:
        return asdict(self)


def _median_us(fn: Callable[[], object], calls: int | None = None, repeats: int = 5, sample_s: float = 0.04) -> float:
    """Median over ``repeats`` of the time per call (microseconds); ``calls`` per sample, or as
    many as fill about ``sample_s`` seconds."""
    t0 = time.perf_counter()
    fn()  # warm up (first-call allocations, page faults), and size the samples
    first = time.perf_counter() - t0
    if calls is None:
        calls = max(1, int(sample_s / max(first, 1e-7)))
    samples = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(calls):
            fn()
        samples.append((time.perf_counter() - t0) / calls * 1e6)
    return float(np.median(samples))


def _best_us(fns: dict[str, Callable[[], object]], rounds: int = 3) -> dict[str, float]:
    """Microseconds per call of each of ``fns``, timed in turn ``rounds`` times: the smallest of
    the per-round medians (a shared machine only ever adds time, and interleaving puts the
    functions compared in a ratio under the same load)."""
    best = {k: math.inf for k in fns}
    for _ in range(rounds):
        for k, fn in fns.items():
            best[k] = min(best[k], _median_us(fn))
    return best


def _compile(f: ca.Function, cache_dir: Path | None) -> tuple[Compiled, float]:
    t0 = time.perf_counter()
    compiled = compile_function(f, cache_dir)
    return compiled, time.perf_counter() - t0


def _close(a: ca.DM, b: ca.DM, rtol: float) -> bool:
    a, b = np.array(a, dtype=float).ravel(), np.array(b, dtype=float).ravel()
    return bool(np.allclose(a, b, rtol=rtol, atol=rtol * max(1.0, float(np.abs(b).max(initial=0.0)))))


def speed_report(
    name: str,
    tree: Tree,
    scene: Scene,
    batch: int = 2000,
    seed: int = 0,
    cache_dir: Path | None = None,
    gradient: bool = True,
    threads: int = 2,
    pinocchio: bool = True,
    rounds: int = 5,
    space: Space = PLANAR,
) -> SpeedReport:
    """Time the hot path (external + internal impulses + norms) on ``tree``.

    Args:
        name: the model's name in the report.
        tree, scene: the model; the designs are its design vector jittered by 1 % (seeded).
        batch: designs per batched call.
        cache_dir: where compiled C is cached; None: the virtual machine only.
        gradient: also time the gradient of both norms (and report ``gradient_ratio``).
        threads: above 1, also time ``Function.map(..., "thread", threads)`` on the fastest path
            and the compiled C loop split by OpenMP (``OMP_NUM_THREADS``, default all cores).
        pinocchio: time ``pinocchio.impulseDynamics`` on the same model (if installed).
        rounds: every path is timed this many times, interleaved; the best round counts.
        space: the model's space (a spatial model: Pinocchio with a free-flyer base).
    """
    b = _Bench.of(tree, scene, batch, seed, space)
    same, lean_full, out_map = b.checked()
    fns: dict[str, Callable[[], object]] = {"vm": _mapped(b.lean, b.args, batch)}
    compiled = _compiled_paths(b, out_map, cache_dir, threads, fns) if cache_dir is not None else None
    same &= compiled.same if compiled is not None else True
    fast = compiled.fast if compiled is not None else b.lean
    if threads > 1:
        fns["threads"] = _mapped(fast, b.args, batch, threads)
    n_grad, grad_same = ({}, (None, None))
    if gradient:
        n_grad, grad_same, grad_twins = _gradient_paths(b, cache_dir if fast is not b.lean else None, fns)
        same &= grad_twins
        if fast is not b.lean:
            fns["full"] = _mapped(_compile(b.full, cache_dir)[0].function, b.args, batch)
    if pinocchio:
        try:
            fns["pinocchio"] = _pinocchio_call(tree, scene, b.active, space)
        except ImportError:
            pass
    return _report(name, b, _best_us(fns, rounds), compiled, n_grad, grad_same, same, lean_full)


@dataclass(frozen=True)
class _Bench:
    """What every timed path of :func:`speed_report` shares: the functions and the designs."""

    tree: Tree
    active: tuple[int, ...]
    lean: ca.Function
    full: ca.Function
    build_ms: float
    v: np.ndarray
    args: tuple  # (P, V, E) as DM, one design per column
    rows: tuple  # the same as NumPy rows
    idx: list[int]  # the columns checked against single calls
    batch: int
    topology: Topology
    space: Space
    rods: bool

    @classmethod
    def of(cls, tree: Tree, scene: Scene, batch: int, seed: int, space: Space) -> _Bench:
        active = active_contacts(tree, scene, space=space)
        topology = tree.topology(active)
        t0 = time.perf_counter()
        rods = rods_only(tree, space)
        lean = lean_impact_function(topology, space, rods=rods)
        build_ms = (time.perf_counter() - t0) * 1e3
        p = design_vector(tree, space.body_values)
        v = approach_velocity(topology, scene.speed, space)
        rng = np.random.default_rng(seed)
        P = ca.DM(p[:, None] * (1 + 0.01 * rng.standard_normal((p.size, batch))))
        args = (P, ca.DM(np.repeat(v[:, None], batch, axis=1)), ca.DM.ones(1, batch) * scene.restitution)
        idx = sorted({0, batch - 1, *(int(i) for i in rng.integers(0, batch, 3))})
        rows = tuple(np.ascontiguousarray(np.array(a).T) for a in args)
        full = compiled_model(topology, space).impact
        return cls(tree, active, lean, full, build_ms, v, args, rows, idx, batch, topology, space, rods)

    def checked(self) -> tuple[bool, bool, list]:
        """Correctness first: (batched == single calls to 1e-12, lean == the full model to 1e-9,
        the batched outputs)."""
        out_map = self.lean.map(self.batch)(*self.args)
        same, lean_full = True, True
        for i in self.idx:
            col = tuple(a[:, i] for a in self.args)
            one = self.lean(*col)
            ref = self.full.call(dict(zip(("p", "v_minus", "restitution"), col)))
            for k in CHECKED_OUTPUTS:
                j = LEAN_OUTPUTS.index(k)
                same &= _close(out_map[j][:, i], one[j], 1e-12)
                lean_full &= _close(one[j], ref[k], 1e-9)
        return bool(same), bool(lean_full), out_map


@dataclass(frozen=True)
class _CompiledPaths:
    backend: str
    compile_s: float | None
    fast: ca.Function
    same: bool
    openmp: bool
    lanes: int


def _compiled_paths(b: _Bench, out_map: list, cache_dir: Path, threads: int, fns: dict) -> _CompiledPaths:
    """Compile the lean function and add its batched paths to ``fns`` (checked against the map)."""
    compiled, compile_s = _compile(b.lean, cache_dir)
    if compiled.backend is not Backend.COMPILED:
        return _CompiledPaths(compiled.backend.value, None, b.lean, True, False, 0)
    backend = "compiled C, " + ("compiled in this run" if compiled.compiled_now else "loaded from the disk cache")
    fns["compiled"] = _mapped(compiled.function, b.args, b.batch)
    paths, outs, twins_same = _batch_paths("", compiled, b.lean, b.rows, threads)
    fns |= paths
    same = twins_same and all(
        _close(out[j][i], out_map[j][:, i], 1e-12)
        for out in outs.values()
        for i in b.idx
        for j in (LEAN_OUTPUTS.index(k) for k in CHECKED_OUTPUTS)
    )
    openmp = threads > 1 and has_openmp(compiled, b.lean)
    return _CompiledPaths(backend, compile_s, compiled.function, same, openmp, simd_lanes(compiled, b.lean))


def _gradient_paths(
    b: _Bench, cache_dir: Path | None, fns: dict
) -> tuple[dict[str, int], tuple[bool, bool], bool]:
    """Add the batched paths of the adjoint's and CasADi's reverse mode's gradients w.r.t. the
    searched values, and of the adjoint's w.r.t. every value, to ``fns``: (instructions, (the
    first two agree to 1e-8, the searched adjoint's entries equal the full one's to 1e-12),
    every batched path equals single calls)."""
    columns = _gradient_columns(b)
    grads = {
        "gradient": norms_gradient_function(b.topology, b.space, rods=b.rods, columns=columns),
        "gradient_autodiff": norms_gradient_function(
            b.topology, b.space, adjoint=False, rods=b.rods, columns=columns
        ),
        "gradient_all": norms_gradient_function(b.topology, b.space, rods=b.rods),
    }
    n_grad = {k: int(g.n_instructions()) for k, g in grads.items()}
    singles = {k: [g(*(x[:, i] for x in b.args)) for i in b.idx] for k, g in grads.items()}
    grad_same = (
        all(
            _close(x, y, 1e-8)
            for one, ref in zip(singles["gradient"], singles["gradient_autodiff"])
            for x, y in zip(one, ref)
        ),
        all(
            _close(x, y if k < 2 else y[columns], 1e-12)
            for one, ref in zip(singles["gradient"], singles["gradient_all"])
            for k, (x, y) in enumerate(zip(one, ref))
        ),
    )
    same = True
    for key, grad in grads.items():
        grad_compiled = None if cache_dir is None else _compile(grad, cache_dir)[0]
        fns[f"{key}_map"] = _mapped(grad if grad_compiled is None else grad_compiled.function, b.args, b.batch)
        if grad_compiled is not None:
            paths, outs, twins_same = _batch_paths(f"{key}_", grad_compiled, grad, b.rows, 1)
            fns |= paths
            same &= twins_same and all(
                _close(out[j][i], singles[key][n][j], 1e-10)
                for out in outs.values()
                for n, i in enumerate(b.idx)
                for j in range(grad.n_out())
            )
    return n_grad, grad_same, same


def gradient_columns(tree: Tree, topology: Topology, space: Space) -> tuple[list[int], str]:
    """The design values the timed gradient is taken w.r.t., and which they are in words: on a
    footopt design (:func:`foot_tree`'s layout, whatever its leg: the rods before the first one
    named ``heel...`` or ``toe...``, :func:`leg_rod_count`) those a search varies
    (:func:`search_columns`); on any other tree every value."""
    legs = leg_rod_count(tree)
    columns = None if legs is None else search_columns(topology, space, legs)
    if columns is None:
        return list(range(n_values(topology, space))), (
            "every value: not a footopt design (a chain of leg rods, then only rods named heel..., toe...)")
    names = ", ".join(b.name for b in tree.bodies[:legs])
    splay = " and the toe roots' rpy" if "yaw" in space.body_values else ""
    return list(columns), (f"the foot rods' lengths, masses and joint angles{splay}, below a leg of {legs} "
                           f"rod{'s' * (legs > 1)} ({names})")


def _gradient_columns(b: _Bench) -> list[int]:
    """:func:`gradient_columns` of the bench's tree."""
    return gradient_columns(b.tree, b.topology, b.space)[0]


def _report(
    name: str, b: _Bench, us: dict[str, float], compiled: _CompiledPaths | None, n_grad: dict[str, int],
    grad_same: tuple[bool | None, bool | None], same: bool, lean_full: bool,
) -> SpeedReport:
    """The report from the best round of each path (microseconds per batch, Pinocchio per call)."""
    per_design = {k: t / b.batch for k, t in us.items() if k != "pinocchio"}
    map_path = "compiled" if "compiled" in per_design else "vm"
    one_core_paths = ("vm", "compiled", "kernel", "simd")
    batched = min(
        per_design[k] for k in (*one_core_paths, "kernel_threads", "simd_threads", "threads") if k in per_design
    )
    one_core = min(per_design[k] for k in one_core_paths if k in per_design)
    # The gradient ratios: gradient and evaluation on the same one-core path.
    path = next((k for k in ("simd", "kernel") if k in per_design and f"gradient_{k}" in per_design), None)

    def gradient_ratio(key: str, on: str | None) -> float | None:
        timed = f"{key}_{on}" if on else f"{key}_map"
        return per_design[timed] / per_design[on or map_path] if timed in per_design else None

    pin_us = us.get("pinocchio")
    columns, which = gradient_columns(b.tree, b.topology, b.space)
    return SpeedReport(
        model=name,
        n_bodies=b.tree.n_bodies,
        n_dof=int(b.v.size),
        n_contacts=len(b.active),
        n_instructions=int(b.lean.n_instructions()),
        n_instructions_full=int(b.full.n_instructions()),
        n_instructions_gradient=n_grad.get("gradient"),
        n_instructions_gradient_autodiff=n_grad.get("gradient_autodiff"),
        n_instructions_gradient_all=n_grad.get("gradient_all"),
        n_values=n_values(b.topology, b.space),
        n_gradient_values=len(columns),
        gradient_values=which,
        build_ms=b.build_ms,
        compile_s=None if compiled is None else compiled.compile_s,
        backend=Backend.VIRTUAL_MACHINE.value if compiled is None else compiled.backend,
        simd_lanes=0 if compiled is None else compiled.lanes,
        us_per_design_single=_median_us(lambda: b.lean(*(a[:, 0] for a in b.args))),
        us_per_design_batched_vm=per_design["vm"],
        us_per_design_batched_compiled=per_design.get("compiled"),
        us_per_design_batched_kernel=per_design.get("kernel"),
        us_per_design_batched_kernel_threads=per_design.get("kernel_threads"),
        us_per_design_batched_simd=per_design.get("simd"),
        us_per_design_batched_simd_threads=per_design.get("simd_threads"),
        openmp=False if compiled is None else compiled.openmp,
        us_per_design_batched_threads=per_design.get("threads"),
        us_per_design_batched=batched,
        us_per_design_full_batched=per_design.get("full"),
        gradient_path=path or map_path,
        us_per_design_gradient=per_design.get(f"gradient_{path or 'map'}"),
        us_per_design_gradient_autodiff=per_design.get(f"gradient_autodiff_{path or 'map'}"),
        gradient_ratio=gradient_ratio("gradient", path),
        gradient_ratio_autodiff=gradient_ratio("gradient_autodiff", path),
        gradient_ratio_c_loop=gradient_ratio("gradient", "kernel"),
        gradient_ratio_map=gradient_ratio("gradient", None),
        us_per_design_gradient_all=per_design.get(f"gradient_all_{path or 'map'}"),
        gradient_ratio_all=gradient_ratio("gradient_all", path),
        gradient_ratio_all_c_loop=gradient_ratio("gradient_all", "kernel"),
        gradient_equals_autodiff=grad_same[0],
        gradient_equals_full=grad_same[1],
        pinocchio_us_per_call=pin_us,
        ratio=None if pin_us is None else batched / pin_us,
        ratio_one_core=None if pin_us is None else one_core / pin_us,
        batch=b.batch,
        batched_equals_single=bool(same),
        lean_equals_full=lean_full,
        rods=b.rods,
    )


def _batch_paths(
    prefix: str, compiled: Compiled, f: ca.Function, rows: Sequence[np.ndarray], threads: int
) -> tuple[dict[str, Callable[[], object]], dict[str, list[np.ndarray]], bool]:
    """The compiled batch drivers of ``f``, ready to time as ``prefix + "kernel"`` (the C loop)
    and ``prefix + "simd"`` (the SIMD loop, where built), with their OpenMP twins
    (``..._threads``) when ``threads`` > 1; each driver's outputs on ``rows``; and whether every
    twin equals its serial driver bit for bit."""
    fns: dict[str, Callable[[], object]] = {}
    outs: dict[str, list[np.ndarray]] = {}
    same = True
    for path, simd in (("kernel", False), ("simd", True)):
        kernel = batch_kernel(compiled, f, simd=simd)
        if kernel is None:
            continue
        outs[path] = kernel(*rows)
        fns[prefix + path] = _kernel_call(kernel, rows, outs[path])
        if threads > 1:
            twin = batch_kernel(compiled, f, parallel=True, simd=simd)
            out = twin(*rows)
            same &= all(np.array_equal(a, b) for a, b in zip(out, outs[path]))
            fns[prefix + path + "_threads"] = _kernel_call(twin, rows, out)
    return fns, outs, same


def _mapped(f: ca.Function, args: Sequence[ca.DM], batch: int, threads: int = 1) -> Callable[[], object]:
    """One call of ``f`` mapped over the batch (the loop runs in CasADi, not in Python)."""
    fmap = f.map(batch) if threads == 1 else f.map(batch, "thread", threads)
    return lambda: fmap(*args)


def _kernel_call(
    kernel: Callable[..., list[np.ndarray]], rows: Sequence[np.ndarray], out: list[np.ndarray]
) -> Callable[[], object]:
    """One call of a compiled batch driver over the batch, writing into ``out`` (no allocation)."""
    return lambda: kernel(*rows, out=out)


def _pinocchio_call(tree: Tree, scene: Scene, active: tuple[int, ...], space: Space = PLANAR) -> Callable[[], object]:
    """One call of ``pinocchio.impulseDynamics`` on the same model (raises ImportError without it)."""
    import pinocchio as pin

    from optimizer.validation.pinocchio_bridge import build, build_spatial

    ref = build(tree) if space is PLANAR else build_spatial(tree)
    data = ref.model.createData()
    J = ref.normal_jacobian(active)
    v = ref.to_pin_velocity(approach_velocity(tree.topology(active), scene.speed, space))
    q, model, e = ref.q, ref.model, scene.restitution
    return lambda: pin.impulseDynamics(model, data, q, v, J, e, 0.0)


def scaled_tree(n_bodies: int) -> Tree:
    """A foot of ``n_bodies`` rods for the scaling series: thigh, shank, and sqrt((n - 2) / 3)
    toes (rounded, at least one) of about equal numbers of segments, hinged at the ankle and
    fanned out, a contact at each toe's tip. Case 3 is the 9-body member with 3 two-link toes
    and a one-link heel; this family grows both toe count and toe length."""
    if n_bodies < 3:
        raise ValueError(f"n_bodies: must be >= 3, got {n_bodies}")
    n_toes = max(1, round(math.sqrt((n_bodies - 2) / 3)))
    segments = [(n_bodies - 2) // n_toes + (1 if t < (n_bodies - 2) % n_toes else 0) for t in range(n_toes)]
    bodies = [
        Body("thigh", None, 0.7, 1.0, -1.1156),
        Body("shank", 0, 0.7, 1.0, -0.6828),
    ]
    for t, n_seg in enumerate(segments):
        spread = 1.2 + 1.6 * t / max(1, n_toes - 1) if n_toes > 1 else 1.5
        for s in range(n_seg):
            parent = 1 if s == 0 else len(bodies) - 1
            bodies.append(
                Body(
                    f"toe{t}_{s}",
                    parent,
                    0.3 / n_seg,
                    0.2 / n_seg,
                    spread if s == 0 else 0.25 / n_seg,
                    contacts=(1.0,) if s == n_seg - 1 else (),
                )
            )
    return Tree(tuple(bodies))


#: The scene of the scaling series: every toe tip hits at once.
SCALING_SCENE = Scene(speed=3.43, restitution=0.8, selection=ContactSelection.ALL)


def scaling_series(
    sizes: Sequence[int] = SCALING_SIZES, batch: int = 500, cache_dir: Path | None = None, pinocchio: bool = True
) -> list[dict]:
    """Time per design against body count (:func:`scaled_tree`), evaluation only."""
    rows = []
    for n in sizes:
        tree = scaled_tree(n)
        r = speed_report(
            f"scaled_{n}",
            tree,
            SCALING_SCENE,
            batch=batch,
            cache_dir=cache_dir,
            gradient=False,
            threads=1,
            pinocchio=pinocchio,
            rounds=3,
        )
        rows.append(
            {
                "bodies": n,
                "dof": r.n_dof,
                "contacts": r.n_contacts,
                "instructions": r.n_instructions,
                "build_ms": r.build_ms,
                "compile_s": r.compile_s,
                "backend": r.backend,
                "us_per_design": r.us_per_design_batched,
                "us_per_design_c_loop": r.us_per_design_batched_kernel,
                "us_per_design_map": r.us_per_design_batched_compiled,
                "us_per_design_vm": r.us_per_design_batched_vm,
                "pinocchio_us_per_call": r.pinocchio_us_per_call,
                "batched_equals_single": r.batched_equals_single,
                "lean_equals_full": r.lean_equals_full,
            }
        )
    return rows


def growth_exponent(rows: Sequence[dict]) -> float | None:
    """Least-squares slope of log(us per design) against log(bodies): <= 2 is at most quadratic."""
    if len(rows) < 2:
        return None
    x = np.log([r["bodies"] for r in rows])
    y = np.log([r["us_per_design"] for r in rows])
    return float(np.polyfit(x, y, 1)[0])


def _fmt(x: float | None, unit: str = "", digits: int = 2) -> str:
    return "-" if x is None else f"{x:.{digits}f}{unit}"


def format_report(r: SpeedReport) -> str:
    """A short table for the terminal."""
    rows = [
        (
            "model",
            f"{r.model} ({r.n_bodies} bodies, {r.n_dof} DOF, {r.n_contacts} contacts)"
            + (", rods: mass properties folded to 0" if r.rods else ""),
        ),
        (
            "SX instructions: lean / full model / gradient (adjoint, reverse mode; adjoint, all values)",
            (
                f"{r.n_instructions} / {r.n_instructions_full} / "
                f"{r.n_instructions_gradient or '-'}, {r.n_instructions_gradient_autodiff or '-'}; "
                f"{r.n_instructions_gradient_all or '-'}"
            ),
        ),
        (
            "gradient w.r.t. the values a search varies (all: not a footopt design)",
            f"{r.n_gradient_values} of {r.n_values} design values",
        ),
        ("  which", r.gradient_values),
        ("build the graph (first use of the topology)", f"{r.build_ms:.1f} ms"),
        ("compile to C (or load from the cache)", _fmt(r.compile_s, " s")),
        ("path that ran", r.backend),
        ("one call per design (from Python)", _fmt(r.us_per_design_single, " us")),
        (f"batched (map over {r.batch}), VM", _fmt(r.us_per_design_batched_vm, " us/design")),
        (f"batched (map over {r.batch}), compiled C", _fmt(r.us_per_design_batched_compiled, " us/design")),
        (f"batched ({r.batch} designs), compiled C loop", _fmt(r.us_per_design_batched_kernel, " us/design")),
        (
            f"batched, SIMD loop ({r.simd_lanes} designs per step)",
            _fmt(r.us_per_design_batched_simd, " us/design", 3),
        ),
        ("batched, CasADi map on 2 threads", _fmt(r.us_per_design_batched_threads, " us/design")),
        (
            "batched, compiled C loop on OpenMP threads",
            _fmt(r.us_per_design_batched_kernel_threads, " us/design")
            + ("" if r.openmp else " (built without OpenMP)"),
        ),
        ("batched, SIMD loop on OpenMP threads", _fmt(r.us_per_design_batched_simd_threads, " us/design", 3)),
        ("batched, best", _fmt(r.us_per_design_batched, " us/design", 3)),
        ("full model (all outputs), batched compiled", _fmt(r.us_per_design_full_batched, " us/design")),
        (
            f"gradient of both norms (adjoint), batched, {r.gradient_path}",
            _fmt(r.us_per_design_gradient, " us/design", 3),
        ),
        (f"gradient / evaluation ({r.gradient_path})", _fmt(r.gradient_ratio)),
        (
            "gradient / evaluation (C loop; CasADi map)",
            f"{_fmt(r.gradient_ratio_c_loop)}; {_fmt(r.gradient_ratio_map)}",
        ),
        (
            f"gradient by reverse mode through the graph, {r.gradient_path}",
            _fmt(r.us_per_design_gradient_autodiff, " us/design", 3),
        ),
        (f"reverse-mode gradient / evaluation ({r.gradient_path})", _fmt(r.gradient_ratio_autodiff)),
        (
            f"gradient w.r.t. all {r.n_values} values (adjoint), batched, {r.gradient_path}",
            _fmt(r.us_per_design_gradient_all, " us/design", 3),
        ),
        (
            f"all-values gradient / evaluation ({r.gradient_path}; C loop)",
            f"{_fmt(r.gradient_ratio_all)}; {_fmt(r.gradient_ratio_all_c_loop)}",
        ),
        (
            "pinocchio.impulseDynamics (external only)",
            _fmt(r.pinocchio_us_per_call, " us/call")
            if r.pinocchio_us_per_call is not None
            else "not timed: Pinocchio is not installed (pip install pin)",
        ),
        ("ratio batched / pinocchio", _fmt(r.ratio, "", 3)),
        ("ratio batched on one core / pinocchio", _fmt(r.ratio_one_core, "", 3)),
        ("batched results equal single calls", "yes" if r.batched_equals_single else "NO"),
        ("lean outputs equal the full model's", "yes" if r.lean_equals_full else "NO"),
        (
            "adjoint gradients equal reverse mode's",
            "-" if r.gradient_equals_autodiff is None else "yes" if r.gradient_equals_autodiff else "NO",
        ),
        (
            "searched gradients equal the all-values gradients' entries",
            "-" if r.gradient_equals_full is None else "yes" if r.gradient_equals_full else "NO",
        ),
    ]
    width = max(len(k) for k, _ in rows)
    text = "\n".join(f"{k:<{width}}  {v}" for k, v in rows)
    if r.scaling:
        text += "\n\n" + format_scaling(r.scaling)
    return text


def format_scaling(rows: Sequence[dict]) -> str:
    """The scaling series as a table, with the fitted growth exponent."""
    head = (
        f"{'bodies':>6} {'DOF':>4} {'contacts':>8} {'instructions':>12} {'compile s':>9} {'us/design':>10} "
        f"{'C loop us':>10} {'pinocchio us':>12}"
    )
    lines = [head]
    for r in rows:
        lines.append(
            f"{r['bodies']:>6} {r['dof']:>4} {r['contacts']:>8} {r['instructions']:>12} "
            f"{_fmt(r['compile_s']):>9} {r['us_per_design']:>10.3f} {_fmt(r['us_per_design_c_loop'], '', 3):>10} "
            f"{_fmt(r['pinocchio_us_per_call']):>12}"
        )
    k = growth_exponent(rows)
    lines.append(f"time ~ bodies^{_fmt(k)} (least squares over the series)")
    return "\n".join(lines)
