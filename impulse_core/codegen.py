"""Compile a CasADi function to machine code once, cache it on disk, fall back to CasADi's
virtual machine where no C compiler is available.

The cache key hashes the function's serialized graph (which fixes the topology), the CasADi
version and the compiler command, so a stale library is never loaded.
"""

from __future__ import annotations

import ctypes
import hashlib
import shutil
import subprocess
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum
from pathlib import Path

import casadi as ca
import numpy as np

#: Compiler flags; -O3 without -ffast-math keeps IEEE semantics (results equal the VM's to rounding).
#: -fno-math-errno only drops errno updates, so sqrt becomes one instruction instead of a call
#: guarded by a branch; results are unchanged. No -march=native: a cache directory may be shared
#: by machines with different CPUs, and it gained nothing measurable here (studies/speed).
CFLAGS = ("-O3", "-fno-math-errno", "-fPIC", "-shared")


class Backend(Enum):
    """Which path evaluates a function."""

    COMPILED = "compiled C (cached)"
    VIRTUAL_MACHINE = "CasADi virtual machine"


@dataclass(frozen=True)
class Compiled:
    """A function ready to call, with the path that runs it."""

    function: ca.Function
    backend: Backend
    library: Path | None
    compiled_now: bool


#: Version of what this module adds to CasADi's generated code (the batch driver); in the cache key.
GENERATOR_VERSION = "batch-driver-2"
#: Tried first, for the driver's parallel loop; the build retries without it if the compiler lacks it.
OPENMP_FLAG = "-fopenmp"


def batch_driver(f: ca.Function) -> str:
    """C source of ``<name>_batch(in, out, n)``: ``f`` on ``n`` designs stored one after another
    (input i of design k at ``in[i] + k * nnz_in(i)``, likewise the outputs), one C loop, no
    allocation: the batched path with no Python and no CasADi call machinery per design.
    ``<name>_batch_parallel`` is the same loop split over threads by OpenMP (serial when compiled
    without it; ``<name>_openmp()`` says which); designs are independent, so results are the same
    bit for bit. Both return the number of designs whose evaluation reported a failure."""
    name = f.name()
    n_in, n_out = f.n_in(), f.n_out()

    def loop(suffix: str, pragma: str) -> list[str]:
        return [
            f"CASADI_SYMBOL_EXPORT int {name}_{suffix}(const casadi_real** in, casadi_real** out, casadi_int n) {{",
            "  casadi_int k;",
            "  int failed = 0;",
            *([pragma] if pragma else []),
            "  for (k = 0; k < n; ++k) {",
            f"    const casadi_real* arg[{max(f.sz_arg(), 1)}] = {{0}};",
            f"    casadi_real* res[{max(f.sz_res(), 1)}] = {{0}};",
            f"    casadi_int iw[{f.sz_iw() + 1}];",
            f"    casadi_real w[{f.sz_w() + 1}];",
            *(f"    arg[{i}] = in[{i}] + k * {f.nnz_in(i)};" for i in range(n_in)),
            *(f"    res[{i}] = out[{i}] + k * {f.nnz_out(i)};" for i in range(n_out)),
            f"    if ({name}(arg, res, iw, w, 0)) failed += 1;",
            "  }",
            "  return failed;",
            "}",
        ]

    lines = [
        *loop("batch", ""),
        *loop("batch_parallel", "  #pragma omp parallel for reduction(+:failed) if(n >= 64)"),
        f"CASADI_SYMBOL_EXPORT int {name}_openmp(void) {{",
        "#ifdef _OPENMP",
        "  return 1;",
        "#else",
        "  return 0;",
        "#endif",
        "}",
    ]
    return "\n".join(lines) + "\n"


def find_compiler() -> str | None:
    """The C compiler on PATH (cc, gcc or clang), or None."""
    for name in ("cc", "gcc", "clang"):
        path = shutil.which(name)
        if path:
            return path
    return None


def cache_key(f: ca.Function, compiler: str) -> str:
    """A hash of the function graph, the CasADi version and the compiler command."""
    h = hashlib.sha256()
    h.update(f.serialize().encode())
    h.update(ca.__version__.encode())
    h.update(" ".join((compiler, *CFLAGS, OPENMP_FLAG, GENERATOR_VERSION)).encode())
    return h.hexdigest()[:20]


def compile_function(f: ca.Function, cache_dir: Path | None, compiler: str | None = None) -> Compiled:
    """``f`` as compiled C loaded from (or built into) ``cache_dir``; the VM function when
    ``cache_dir`` is None, no compiler exists or the build fails.

    Args:
        f: the function (SX graphs generate the leanest code).
        cache_dir: where compiled libraries live (created if missing); None: do not compile.
        compiler: the C compiler to use (default: :func:`find_compiler`).
    """
    compiler = compiler or find_compiler()
    if cache_dir is None or compiler is None:
        return Compiled(f, Backend.VIRTUAL_MACHINE, None, False)
    cache_dir = Path(cache_dir)
    name = f"{f.name()}_{cache_key(f, compiler)}"
    library = cache_dir / f"{name}.so"
    compiled_now = False
    if not library.exists():
        try:
            cache_dir.mkdir(parents=True, exist_ok=True)
            with tempfile.TemporaryDirectory(dir=cache_dir) as tmp:
                generator = ca.CodeGenerator(f"{name}.c", {"with_header": False})
                generator.add(f)
                source = Path(generator.generate(f"{tmp}/"))
                with source.open("a") as out:
                    out.write(batch_driver(f))
                partial = Path(tmp) / f"{name}.so"
                try:
                    subprocess.run(
                        [compiler, *CFLAGS, OPENMP_FLAG, str(source), "-o", str(partial)],
                        check=True,
                        capture_output=True,
                    )
                except subprocess.CalledProcessError:  # no OpenMP: the parallel loop runs serially
                    subprocess.run(
                        [compiler, *CFLAGS, str(source), "-o", str(partial)], check=True, capture_output=True
                    )
                partial.replace(library)  # atomic: a reader never sees half a library
            compiled_now = True
        except (OSError, subprocess.CalledProcessError):
            return Compiled(f, Backend.VIRTUAL_MACHINE, None, False)
    return Compiled(ca.external(f.name(), str(library)), Backend.COMPILED, library, compiled_now)


def batch_kernel(compiled: Compiled, f: ca.Function, parallel: bool = False) -> Callable[..., list[np.ndarray]] | None:
    """The compiled batch driver of ``f`` (:func:`batch_driver`) as a Python callable, or None on
    the virtual-machine path.

    The callable takes one array per input, shape (n_designs, nnz_in(i)) in C order (one design
    per row), and returns one array per output, shape (n_designs, nnz_out(i)); pass ``out=`` (a
    list of such arrays) to reuse buffers. Raises ``FloatingPointError`` if the C code reports a
    failure. With ``parallel``, the loop is split over OpenMP threads (``OMP_NUM_THREADS``; all
    cores by default) when the library was built with OpenMP (:func:`has_openmp`).
    """
    if compiled.backend is not Backend.COMPILED or compiled.library is None:
        return None
    lib = ctypes.CDLL(str(compiled.library))
    fn = getattr(lib, f"{f.name()}_batch_parallel" if parallel else f"{f.name()}_batch")
    fn.restype = ctypes.c_int
    n_in, n_out = f.n_in(), f.n_out()
    nnz_in = [f.nnz_in(i) for i in range(n_in)]
    nnz_out = [f.nnz_out(i) for i in range(n_out)]
    ptr = ctypes.POINTER(ctypes.c_double)
    fn.argtypes = [ctypes.POINTER(ptr), ctypes.POINTER(ptr), ctypes.c_longlong]

    def run(*inputs: np.ndarray, out: list[np.ndarray] | None = None) -> list[np.ndarray]:
        arrays = [np.ascontiguousarray(x, dtype=float).reshape(-1, nnz_in[i]) for i, x in enumerate(inputs)]
        n = arrays[0].shape[0]
        if any(a.shape[0] != n for a in arrays) or len(arrays) != n_in:
            raise ValueError(f"{f.name()}_batch: expected {n_in} inputs with {n} rows each")
        if out is None:
            out = [np.empty((n, k)) for k in nnz_out]
        ins = (ptr * n_in)(*(a.ctypes.data_as(ptr) for a in arrays))
        outs = (ptr * n_out)(*(o.ctypes.data_as(ptr) for o in out))
        if fn(ins, outs, n):
            raise FloatingPointError(f"{f.name()}_batch: the compiled function reported a failure")
        return out

    return run


def has_openmp(compiled: Compiled, f: ca.Function) -> bool:
    """Whether the compiled library's parallel batch loop was built with OpenMP."""
    if compiled.backend is not Backend.COMPILED or compiled.library is None:
        return False
    return bool(getattr(ctypes.CDLL(str(compiled.library)), f"{f.name()}_openmp")())
