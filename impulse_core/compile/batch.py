"""Many designs of one topology at once: the hot path (:func:`impulse_core.impact.delassus.lean_impact_function`)
compiled once per topology and run over a block of designs, for sweeps, robust-design studies and
searches that evaluate millions of designs.

Each row is one design of the same topology: the contacts of ``topology.active`` hit at once (as
``contacts: all``), the whole tree translating straight down, frictionless. The answer is
Newton's law (paper eq. 11) for that contact set; ``BatchResult.newton`` flags the rows where that
is also what :func:`impulse_core.evaluate.evaluate` answers (every impulse >= 0, the Delassus
matrix well conditioned). Evaluate the other rows one by one: there a contact would pull, and the
complementarity law lets it separate instead.

The path is the fastest one built: the SIMD loop (:func:`impulse_core.compile.codegen.simd_driver`), else
the C loop, else CasADi's ``map`` on its virtual machine (no cache directory, or no C compiler).
Compiled, one C call does the whole batch (:func:`impulse_core.compile.codegen.api_driver`: the
value checks, each row's approach velocity, the loop and the ``newton`` and ``failed`` flags, in
blocks of rows split over the cores); a check that fails there is raised by the same Python
checks as on the virtual machine, so the errors name the same value.
"""

from __future__ import annotations

import ctypes
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import casadi as ca
import numpy as np

from impulse_core.compile import codegen
from impulse_core.compile.codegen import Backend, api_kernel, batch_kernel, compile_function, simd_lanes
from impulse_core.errors import ModelError
from impulse_core.evaluate import approach_velocity
from impulse_core.impact.delassus import GRADIENT_OUTPUTS, LEAN_OUTPUTS, lean_impact_function, norms_gradient_function
from impulse_core.impact.laws import PIVOT_TOL
from impulse_core.kinematics.spatial import MASS_VALUES, PLANAR, Space, n_values
from impulse_core.model.tree import BODY_VALUES, CONTACT_BOUNDS, VALUE_BOUNDS, Topology

#: Where the API driver finds the external impulses and the Delassus pivots among the outputs.
_EXTERNAL, _PIVOTS = LEAN_OUTPUTS.index("external"), LEAN_OUTPUTS.index("delassus_pivots")
#: Rows -> one array per output (rows of designs in, rows out).
_Runner = Callable[[np.ndarray, np.ndarray, np.ndarray], list[np.ndarray]]


@dataclass(frozen=True)
class BatchResult:
    """The impact of every row (design) of a batch; N s, first axis the designs.

    Attributes:
        external: normal impulse at each active contact (n x contacts).
        internal_magnitude: force impulse through each joint, one per non-base body (n x joints).
        external_norm, internal_norm: their Euclidean norms (n).
        newton: True where Newton's law is also :func:`impulse_core.evaluate.evaluate`'s answer.
        failed: True where an output is not finite (the design's impact could not be resolved in
            float64); such rows are never ``newton``.
        d_external_norm, d_internal_norm: gradients w.r.t. the design vector (n x n_values),
            with ``gradient=True`` only.
    """

    external: np.ndarray
    internal_magnitude: np.ndarray
    external_norm: np.ndarray
    internal_norm: np.ndarray
    newton: np.ndarray
    failed: np.ndarray
    d_external_norm: np.ndarray | None = None
    d_internal_norm: np.ndarray | None = None


@dataclass(frozen=True)
class BatchEvaluator:
    """Evaluates batches of designs of one topology (made by :func:`batch_evaluator`).

    Attributes:
        topology: the tree's structure and the contacts that hit.
        space: the kinematic space.
        path: what runs: "SIMD loop (4 designs per step)", "C loop" or "CasADi virtual machine".
        run_impact, run_gradient: the compiled (or VM) batch functions, rows in and out.
        run_api: the compiled API driver (checks, loop and flags in one call), None on the VM.
        parallel: whether the compiled loops run on all cores.
        widths: values per row of each of ``LEAN_OUTPUTS``.
        rods: the functions' rods variant runs (mass-property values folded to 0): every row's
            must be 0 (the checks refuse others).
    """

    topology: Topology
    space: Space
    path: str
    run_impact: _Runner = field(repr=False)
    run_gradient: _Runner | None = field(repr=False)
    run_api: Callable[..., int] | None = field(default=None, repr=False)
    parallel: bool = True
    widths: tuple[int, ...] = field(default=(), repr=False)
    rods: bool = False
    _fixed: tuple = field(default=(), init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        """The arrays every compiled call passes: value bounds, the approach at unit speed."""
        lo, hi = codegen.api_bounds(*_bounds(self.topology, self.space.body_values, self.rods))
        arrays = (lo, hi, approach_velocity(self.topology, 1.0, self.space))
        object.__setattr__(self, "_fixed", (*arrays, *(a.ctypes.data for a in arrays)))

    def __call__(self, p: np.ndarray, speed: float | np.ndarray, restitution: float | np.ndarray) -> BatchResult:
        """The impact of every design.

        Args:
            p: design vectors, one per row (n x ``n_values(topology, space)``, layout of
                :func:`impulse_core.model.tree.design_vector`); a single vector is one row.
            speed: approach speed (m/s, > 0), one for all rows or one per row.
            restitution: Newton's coefficient in [0, 1], one for all rows or one per row.

        Raises:
            ModelError: naming the argument whose shape or values are wrong.
        """
        P = np.atleast_2d(np.asarray(p, dtype=float))
        n = P.shape[0]
        width = n_values(self.topology, self.space)
        if P.ndim != 2 or P.shape[1] != width:
            raise ModelError(f"p: must have {width} values per row, got shape {np.shape(p)}")
        if self.run_api is not None:
            done = self._compiled_call(P, speed, restitution)
            if done is not None:
                return done
        speeds, E = self._checked(P, speed, restitution)
        V = speeds[:, None] * self._fixed[2][None, :]
        out = dict(zip(LEAN_OUTPUTS, self.run_impact(P, V, E[:, None]), strict=True))
        external = out["external"]
        finite = np.ones(n, dtype=bool)
        for o in out.values():  # column by column: NumPy's row reductions are slow on narrow rows
            for j in range(o.shape[1]):
                finite &= np.isfinite(o[:, j])
        newton = finite & (_row_min(external, 0.0) >= 0) & (_row_min(out["delassus_pivots"], 1.0) >= PIVOT_TOL)
        failed = ~finite
        grads = {}
        if self.run_gradient is not None:
            grads = dict(zip(GRADIENT_OUTPUTS, self.run_gradient(P, V, E[:, None]), strict=True))
        return _batch_result(out, newton, failed, grads)

    def _checked(self, P: np.ndarray, speed, restitution) -> tuple[np.ndarray, np.ndarray]:
        """Speed and restitution per row, once every value is checked (ModelError naming the
        first bad one: ``p``, then speed, then restitution)."""
        n = P.shape[0]
        _check_values(self.topology, P, self.space.body_values, self.rods)
        speeds = _per_row("speed", speed, n)
        if not np.all(speeds > 0):
            raise ModelError("speed: must be > 0")
        E = _per_row("restitution", restitution, n)
        if not np.all((E >= 0) & (E <= 1)):
            raise ModelError("restitution: must be in [0, 1]")
        return speeds, E

    def _compiled_call(self, P: np.ndarray, speed, restitution) -> BatchResult | None:
        """The batch by one call of the compiled API driver; None when speed or restitution has
        neither one value nor one per row (the checks then raise)."""
        n = P.shape[0]
        P = np.ascontiguousarray(P)
        speeds = np.ascontiguousarray(speed, dtype=float).reshape(-1)
        E = np.ascontiguousarray(restitution, dtype=float).reshape(-1)
        if speeds.size not in (1, n) or E.size not in (1, n):
            return None
        outs = [np.empty((n, k)) for k in self.widths]
        newton, failed = np.empty(n, dtype=bool), np.empty(n, dtype=bool)
        low, high, unit = self._fixed[3:]
        bad = self.run_api(
            P.ctypes.data, speeds.ctypes.data, int(speeds.size > 1), E.ctypes.data, int(E.size > 1), unit, low, high,
            (ctypes.c_void_p * len(outs))(*(o.ctypes.data for o in outs)), n, _EXTERNAL, _PIVOTS, PIVOT_TOL,
            newton.ctypes.data, failed.ctypes.data, int(self.parallel),
        )
        if bad & ~codegen.API_FAILED:
            self._checked(P, speeds, E)  # raises, naming the value
            raise AssertionError(f"the compiled checks refused a batch that the Python checks accept ({bad})")
        if bad:
            raise FloatingPointError(f"{self.path}: the compiled function reported a failure")
        out = dict(zip(LEAN_OUTPUTS, outs, strict=True))
        grads = {}
        if self.run_gradient is not None:
            V = np.broadcast_to(speeds, (n,))[:, None] * self._fixed[2][None, :]
            grads = dict(zip(GRADIENT_OUTPUTS, self.run_gradient(P, V, np.broadcast_to(E, (n,))[:, None]), strict=True))
        return _batch_result(out, newton, failed, grads)


def _batch_result(out: dict[str, np.ndarray], newton: np.ndarray, failed: np.ndarray,
                  grads: dict[str, np.ndarray]) -> BatchResult:
    """The rows' outputs (``LEAN_OUTPUTS``, rows first) and flags as a :class:`BatchResult`."""
    return BatchResult(
        external=out["external"],
        internal_magnitude=out["internal_magnitude"],
        external_norm=out["external_norm"][:, 0],
        internal_norm=out["internal_norm"][:, 0],
        newton=newton,
        failed=failed,
        d_external_norm=grads.get("d_external_norm"),
        d_internal_norm=grads.get("d_internal_norm"),
    )


def batch_evaluator(
    topology: Topology,
    cache_dir: str | Path | None,
    *,
    gradient: bool = False,
    parallel: bool = True,
    space: Space = PLANAR,
    fallback: bool = False,
    rods: bool = False,
) -> BatchEvaluator:
    """Build (once per topology; compiled code is cached in ``cache_dir``) a batch evaluator.

    Args:
        topology: the structure; its ``active`` contacts are the ones that hit.
        cache_dir: where compiled C is cached (:func:`impulse_core.compile.codegen.compile_function`);
            None: CasADi's virtual machine.
        gradient: also compute the gradients of both norms (adjoint,
            :func:`impulse_core.impact.delassus.norms_gradient_function`).
        parallel: split the compiled loops over the cores (OpenMP; same results bit for bit).
        space: the kinematic space (planar).
        fallback: on a missing or failing C compiler, warn and run on the virtual machine
            instead of raising ``CompileError``.
        rods: the variant for designs whose mass-property values are all zero (a model where
            :func:`impulse_core.kinematics.spatial.rods_only`; its own compiled functions, the
            same outputs, faster); rows with another value there are refused.
    """
    lean = lean_impact_function(topology, space, rods=rods)
    impact, path, api = _runner(lean, cache_dir, parallel, fallback)
    grad = None
    if gradient:
        grad = _runner(norms_gradient_function(topology, space, rods=rods), cache_dir, parallel, fallback)[0]
    widths = tuple(lean.nnz_out(i) for i in range(lean.n_out()))
    return BatchEvaluator(topology, space, path, impact, grad, api, parallel, widths, rods)


def _runner(
    f: ca.Function, cache_dir: str | Path | None, parallel: bool, fallback: bool
) -> tuple[_Runner, str, Callable[..., int] | None]:
    """The fastest batch path of ``f``, its name and its API driver (None on the VM)."""
    directory = None if cache_dir is None else Path(cache_dir).expanduser()
    compiled = compile_function(f, directory, fallback=fallback)
    if compiled.backend is Backend.COMPILED:
        lanes = simd_lanes(compiled, f)
        kernel = batch_kernel(compiled, f, parallel=parallel, simd=lanes > 0)
        assert kernel is not None
        return kernel, f"SIMD loop ({lanes} designs per step)" if lanes else "C loop", api_kernel(compiled, f)

    def on_vm(P: np.ndarray, V: np.ndarray, E: np.ndarray) -> list[np.ndarray]:
        outs = f.map(P.shape[0])(P.T, V.T, E.T)
        return [np.array(o, dtype=float).T.reshape(P.shape[0], -1) for o in outs]

    return on_vm, Backend.VIRTUAL_MACHINE.value, None


def _bounds(
    topology: Topology, body_values: tuple[str, ...], rods: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each design value's (low, low included, high), in the design vector's order; with ``rods``
    the mass-property values' are [0, 0]."""
    names = [name for _ in range(topology.n_bodies) for name in body_values]
    names += ["contact"] * sum(topology.n_contacts)
    bounds = np.array(
        [(0.0, True, 0.0) if rods and name in MASS_VALUES else VALUE_BOUNDS.get(name, CONTACT_BOUNDS) for name in names],
        dtype=float,
    ).reshape(-1, 3)
    return np.ascontiguousarray(bounds[:, 0]), bounds[:, 1].astype(bool), np.ascontiguousarray(bounds[:, 2])


def _check_values(
    topology: Topology, P: np.ndarray, body_values: tuple[str, ...] = BODY_VALUES, rods: bool = False
) -> None:
    """Raise ModelError naming the first value of ``P`` that no tree may have (the checks of
    :func:`impulse_core.model.tree.validate_tree`): one pass for each column's extremes, the rows
    searched only when a column is out of bounds."""
    names = [(b, name) for b in range(topology.n_bodies) for name in body_values]
    names += [(c, "contact") for c in range(sum(topology.n_contacts))]
    low, closed, high = _bounds(topology, body_values, rods)

    def ok(x: np.ndarray) -> np.ndarray:
        return np.isfinite(x) & np.where(closed, x >= low, x > low) & (x <= high)

    if P.shape[0] == 0 or (ok(P.min(axis=0)) & ok(P.max(axis=0))).all():
        return
    row, col = (int(i) for i in np.argwhere(~ok(P))[0])
    k, name = names[col]
    where = f"contact {k}" if name == "contact" else f"body {k} {name}"
    lo, hi = ("[" if closed[col] else "(") + f"{low[col]:g}", f"{high[col]:g}]"
    raise ModelError(f"p[{row}]: {where} must be finite and in {lo}, {hi}, got {P[row, col]}")


def _row_min(a: np.ndarray, empty: float) -> np.ndarray:
    """Each row's minimum (``empty`` for rows of no columns), a column at a time."""
    out = np.full(a.shape[0], empty)
    for j in range(a.shape[1]):
        np.minimum(out, a[:, j], out=out)
    return out


def _per_row(name: str, value: float | np.ndarray, n: int) -> np.ndarray:
    """``value`` as one float per row (a scalar is broadcast)."""
    arr = np.asarray(value, dtype=float).ravel()
    if arr.size not in (1, n):
        raise ModelError(f"{name}: must be one value or one per row ({n}), got {arr.size}")
    if not np.all(np.isfinite(arr)):
        raise ModelError(f"{name}: must be finite")
    return np.broadcast_to(arr, (n,)).copy()


__all__ = ["BatchEvaluator", "BatchResult", "batch_evaluator"]
