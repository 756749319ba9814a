"""Speed of one design's evaluation, measured next to Pinocchio in the same run.

Timings are medians of repeated runs; ratios against a peer measured in the same process are
what to quote (these machines are noisy).
"""

from __future__ import annotations

import time
from pathlib import Path
from dataclasses import asdict, dataclass
from typing import Callable

import numpy as np

from impulse_core.codegen import Backend, compile_function
from impulse_core.evaluate import active_contacts, approach_velocity, compiled_model, evaluate
from impulse_core.tree import Scene, Tree, design_vector


@dataclass(frozen=True)
class SpeedReport:
    """Microseconds per design (or per call) for one model; ``ratio`` = batched / Pinocchio."""

    model: str
    n_dof: int
    n_contacts: int
    n_instructions: int
    build_ms: float
    us_per_design_single: float
    us_per_design_batched_vm: float
    us_per_design_batched_compiled: float | None
    us_per_design_batched: float
    backend: str
    us_per_design_evaluate: float
    pinocchio_us_per_call: float | None
    ratio: float | None
    batch: int
    batched_equals_single: bool

    def as_dict(self) -> dict:
        return asdict(self)


def _median_us(fn: Callable[[], object], calls: int, repeats: int = 5) -> float:
    """Median over ``repeats`` of the time per call of ``calls`` calls (microseconds)."""
    samples = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(calls):
            fn()
        samples.append((time.perf_counter() - t0) / calls * 1e6)
    return float(np.median(samples))


def speed_report(
    name: str, tree: Tree, scene: Scene, batch: int = 2000, seed: int = 0, cache_dir: Path | None = None
) -> SpeedReport:
    """Time the paper's model (external + internal impulses + norms) on ``tree``.

    Single: one Python call of the compiled function per design. Batched: ``Function.map`` over
    ``batch`` designs (the design values jittered by 1 % so that no result is reused).
    Compiled: the same function as C (``impulse_core.codegen``, cached in ``cache_dir``; skipped
    when None or without a compiler); ``us_per_design_batched`` is the faster batched path.
    Evaluate: the full ``impulse_core.evaluate`` path. Pinocchio: ``impulseDynamics`` per call
    on the same model (external impulses and post-impact velocity only).
    """
    active = active_contacts(tree, scene)
    topology = tree.topology(active)
    compiled_model.cache_clear()
    t0 = time.perf_counter()
    model = compiled_model(topology)
    build_ms = (time.perf_counter() - t0) * 1e3
    f = model.impact
    p = design_vector(tree)
    v = approach_velocity(topology, scene.speed)
    e = scene.restitution
    rng = np.random.default_rng(seed)
    P = p[:, None] * (1 + 0.01 * rng.standard_normal((p.size, batch)))
    single = _median_us(lambda: f(p, v, e), calls=2000)
    fmap = f.map(batch)
    V = np.repeat(v[:, None], batch, axis=1)
    E = np.full((1, batch), e)
    batched_vm = _median_us(lambda: fmap(P, V, E), calls=3) / batch
    compiled = compile_function(f, cache_dir)
    batched_c = None
    if compiled.backend is Backend.COMPILED:
        cmap = compiled.function.map(batch)
        batched_c = _median_us(lambda: cmap(P, V, E), calls=3) / batch
    batched = min(batched_vm, batched_c or np.inf)
    out_map = fmap(P, V, E)
    idx = rng.integers(0, batch, 5)
    names = ("external", "v_plus", "external_norm", "internal_norm")  # one column per design
    cols = {k: np.array(out_map[f.index_out(k)]) for k in names}
    same = all(
        np.allclose(cols[k][:, i], np.array(f(P[:, i], v, e)[f.index_out(k)]).ravel(), rtol=1e-12, atol=0)
        for i in idx
        for k in names
    )
    per_eval = _median_us(lambda: evaluate(tree, scene), calls=200)
    pin_us = None
    try:
        pin_us = _pinocchio_us(tree, scene, active)
    except ImportError:
        pass
    return SpeedReport(
        model=name,
        n_dof=int(v.size),
        n_contacts=len(active),
        n_instructions=int(f.n_instructions()),
        build_ms=build_ms,
        us_per_design_single=single,
        us_per_design_batched_vm=batched_vm,
        us_per_design_batched_compiled=batched_c,
        us_per_design_batched=batched,
        backend=compiled.backend.value,
        us_per_design_evaluate=per_eval,
        pinocchio_us_per_call=pin_us,
        ratio=None if pin_us is None else batched / pin_us,
        batch=batch,
        batched_equals_single=bool(same),
    )


def _pinocchio_us(tree: Tree, scene: Scene, active: tuple[int, ...]) -> float:
    import pinocchio as pin

    from optimizer.pinocchio_bridge import build

    ref = build(tree)
    data = ref.model.createData()
    J = ref.normal_jacobian(active)
    v = ref.to_pin_velocity(approach_velocity(tree.topology(active), scene.speed))
    q, model, e = ref.q, ref.model, scene.restitution
    return _median_us(lambda: pin.impulseDynamics(model, data, q, v, J, e, 0.0), calls=2000)


def format_report(r: SpeedReport) -> str:
    """A short table for the terminal."""
    rows = [
        ("model", f"{r.model} ({r.n_dof} DOF, {r.n_contacts} contacts, {r.n_instructions} SX instructions)"),
        ("build (first use of the topology)", f"{r.build_ms:.1f} ms"),
        ("footopt, one call per design", f"{r.us_per_design_single:.2f} us"),
        (f"footopt, batched (map over {r.batch}), VM", f"{r.us_per_design_batched_vm:.2f} us/design"),
        (
            f"footopt, batched (map over {r.batch}), compiled C",
            "no compiler" if r.us_per_design_batched_compiled is None else f"{r.us_per_design_batched_compiled:.2f} us/design",
        ),
        ("footopt evaluate() (full Python path)", f"{r.us_per_design_evaluate:.2f} us"),
        (
            "pinocchio.impulseDynamics (external only)",
            "not installed" if r.pinocchio_us_per_call is None else f"{r.pinocchio_us_per_call:.2f} us/call",
        ),
        ("ratio batched / pinocchio", "-" if r.ratio is None else f"{r.ratio:.2f}"),
        ("batched results equal single calls", "yes" if r.batched_equals_single else "NO"),
    ]
    width = max(len(k) for k, _ in rows)
    return "\n".join(f"{k:<{width}}  {v}" for k, v in rows)


