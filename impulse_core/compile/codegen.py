"""Compile a CasADi function to machine code once and cache it on disk.

Beside CasADi's own C (one design per call) each library holds two batch drivers: a C loop over
designs (:func:`batch_driver`), and a SIMD loop (:func:`simd_driver`) that runs the same SX
instructions on several designs at once, one per vector lane, written by this module from the
function's instruction list.

Libraries live in the trusted cache of :mod:`impulse_core.compile.cache`: keyed by a hash of
the generated source, the compiler's path and version and the flags, and loaded only if the entry
matches its key and its files' hashes. A missing or failing compiler is a ``CompileError``
(or, on request, a visible warning and the virtual machine).
"""

from __future__ import annotations

import ctypes
import functools
import platform
import shutil
import tempfile
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum
from pathlib import Path

import casadi as ca
import numpy as np

from impulse_core.compile.cache import (
    CompileError,
    claim,
    compiler_identity,
    entry_key,
    lookup,
    run_compilers,
    store,
)

#: Compiler flags; -O3 without -ffast-math keeps IEEE semantics (results equal the VM's to rounding).
#: -fno-math-errno only drops errno updates, so sqrt becomes one instruction instead of a call
#: guarded by a branch; results are unchanged. No -march=native: a cache directory may be shared
#: by machines with different CPUs, and it gained nothing measurable here (studies/speed).
#: -ffp-contract=off: no fused multiply-adds where the CPU has them (aarch64 always does), so the
#: C loop and the SIMD loop round every operation as the VM does.
CFLAGS = ("-O3", "-fno-math-errno", "-ffp-contract=off", "-fPIC", "-shared")


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


#: File name of the compiled library inside its cache entry.
LIBRARY = "library.so"
#: Designs per SIMD step: one 256-bit vector of doubles (AVX2; two SSE2 registers without it).
SIMD_LANES = 4
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


#: C of the SIMD driver's vector type and its lane-wise functions (GCC/Clang vector extensions).
_SIMD_PRELUDE = r"""
#include <math.h>
#include <string.h>
#if defined(__AVX__)
#include <immintrin.h>
#endif
typedef double footopt_vd __attribute__((vector_size(8 * FOOTOPT_LANES)));
typedef long long footopt_vi __attribute__((vector_size(8 * FOOTOPT_LANES)));

static inline footopt_vd footopt_sqrt(footopt_vd x) {
  footopt_vd r;
  for (int l = 0; l < FOOTOPT_LANES; ++l) r[l] = sqrt(x[l]);
  return r;
}

/* 1 when every lane of a comparison's mask is set: one movemask with AVX (a loop over the lanes
   compiles to a dozen shuffles; spatial case 3's evaluation 3-5 % faster), else lane by lane. */
static inline int footopt_all(footopt_vi m) {
#if defined(__AVX__) && FOOTOPT_LANES == 4
  return _mm256_movemask_pd((__m256d)m) == 15;
#else
  int all = 1;
  for (int l = 0; l < FOOTOPT_LANES; ++l) all &= m[l] != 0;
  return all;
#endif
}

static inline footopt_vd footopt_fabs(footopt_vd x) { return (footopt_vd)((footopt_vi)x & 0x7fffffffffffffffLL); }

/* sin and cos of every lane, within 2 ulp of libm's (1 ulp for |x| <= 10; tests/impulse_core/
   test_codegen.py): x = q pi/2 + r with q = round(2 x / pi)
   (the 1.5 * 2^52 trick; its low bits are q mod 4), r by Cody-Waite in three parts of pi/2
   (exact products for |q| < 2^20), fdlibm's kernels __kernel_sin / __kernel_cos on
   [-pi/4, pi/4], then the quadrant. libm itself where any lane has |x| > 1e5 (or is not finite).
   Where every lane is +-0 (a model's rpy mostly are), sin x = x and cos x = 1 exactly, as libm's. */
static inline void footopt_sincos(footopt_vd x, footopt_vd* s_out, footopt_vd* c_out) {
  if (footopt_all(x == (footopt_vd){0})) {  /* +0 and -0 */
    *s_out = x;
    *c_out = (footopt_vd){0} + 1.0;
    return;
  }
  int all_small = footopt_all(footopt_fabs(x) <= 1e5 + (footopt_vd){0});  /* false for nan */
  if (!all_small) {
    for (int l = 0; l < FOOTOPT_LANES; ++l) {
      (*s_out)[l] = sin(x[l]);
      (*c_out)[l] = cos(x[l]);
    }
    return;
  }
  const double toint = 6755399441055744.0;
  footopt_vd t = x * 6.36619772367581382433e-01 + toint;
  footopt_vi qi = (footopt_vi)t;
  footopt_vd q = t - toint;
  footopt_vd r = x - q * 1.57079632673412561417e+00;
  r = r - q * 6.07710050630396597660e-11;
  r = r - q * 2.02226624879595063154e-21;
  footopt_vd z = r * r;
  footopt_vd ps = 8.33333333332248946124e-03 + z * (-1.98412698298579493134e-04 + z * (2.75573137070700676789e-06
                  + z * (-2.50507602534068634195e-08 + z * 1.58969099521155010221e-10)));
  footopt_vd s = r + z * r * (-1.66666666666666324348e-01 + z * ps);
  footopt_vd w = z * z;
  footopt_vd pc = z * (4.16666666666666019037e-02 + z * (-1.38888888888741095749e-03 + z * 2.48015872894767294178e-05))
                  + w * w * (-2.75573143513906633035e-07 + z * (2.08757232129817482790e-09 + z * -1.13596475577881948265e-11));
  footopt_vd hz = 0.5 * z;
  footopt_vd one_hz = 1.0 - hz;
  footopt_vd c = one_hz + (((1.0 - one_hz) - hz) + z * pc);
  footopt_vi swap = -(qi & 1);
  footopt_vi si = ((footopt_vi)s & ~swap) | ((footopt_vi)c & swap);
  footopt_vi ci = ((footopt_vi)c & ~swap) | ((footopt_vi)s & swap);
  *s_out = (footopt_vd)(si ^ ((qi & 2) << 62));
  *c_out = (footopt_vd)(ci ^ (((qi + 1) & 2) << 62));
}

static inline footopt_vd footopt_sin(footopt_vd x) { footopt_vd s, c; footopt_sincos(x, &s, &c); return s; }
static inline footopt_vd footopt_cos(footopt_vd x) { footopt_vd s, c; footopt_sincos(x, &s, &c); return c; }

/* Lane l reads design kk[l] (row-major: design k's input at p + k * nnz). */
static inline footopt_vd footopt_load(const casadi_real* p, casadi_int nnz, const casadi_int* kk) {
  footopt_vd r;
  for (int l = 0; l < FOOTOPT_LANES; ++l) r[l] = p[kk[l] * nnz];
  return r;
}

/* Lane l's value to the step's staging buffer (design l's outputs one after another, stride n). */
static inline void footopt_stage(casadi_real* p, casadi_int n, footopt_vd x) {
  for (int l = 0; l < FOOTOPT_LANES; ++l) p[l * n] = x[l];
}
"""

_SIMD_BINARY = {ca.OP_ADD: "+", ca.OP_SUB: "-", ca.OP_MUL: "*", ca.OP_DIV: "/"}
_SIMD_UNARY = {
    ca.OP_NEG: "-{a}",
    ca.OP_SQ: "{a} * {a}",
    ca.OP_TWICE: "{a} + {a}",
    ca.OP_INV: "1.0 / {a}",
    ca.OP_FABS: "footopt_fabs({a})",
    ca.OP_SQRT: "footopt_sqrt({a})",
    ca.OP_SIN: "footopt_sin({a})",
    ca.OP_COS: "footopt_cos({a})",
}


def simd_driver(f: ca.Function, lanes: int = SIMD_LANES) -> str | None:
    """C source of ``<name>_simd(in, out, n)`` and ``<name>_simd_parallel``: the batch drivers'
    contract (:func:`batch_driver`), but each step runs ``f``'s SX instructions once on ``lanes``
    designs, one per vector lane (the last step repeats the last design in its spare lanes and
    stores only the real ones). A step's outputs go to a staging buffer on the stack and then to
    each design's rows, one contiguous copy per output (the gradient's 388 values per design of
    spatial case 3, stored in place lane by lane, cost 5-11 % of its time at 2000 designs). The
    inputs a step reads are all loaded at its start, in memory order (:func:`_input_loads`), not
    where each is first used: the lanes' rows are read in one sweep (spatial case 3, 2000 designs:
    the all-values gradient faster in seven of eight paired runs, by 12 % at the median; the
    evaluation alike within the noise).
    Arithmetic, sqrt and fabs are IEEE operations lane by lane, so they round as the scalar code does; sin and cos come from a vector kernel within 1 ulp of
    libm's for |x| <= 10 (2 ulp up to 1e5; libm itself beyond), one call for the sin and cos of
    one value, and none where every lane's value is zero (sin and cos exact, as libm's).
    ``<name>_simd_lanes()`` returns ``lanes``. None when ``f`` is not an SX function
    or uses an operation outside +, -, *, /, 1/x, negation, square, fabs, sqrt, sin and cos."""
    if not f.is_a("SXFunction"):
        return None
    pairs = _sincos_pairs(f)
    staged = np.cumsum([0] + [f.nnz_out(i) for i in range(f.n_out())]).tolist()
    loads, read = _input_loads(f)
    body = []
    for k in range(f.n_instructions()):
        op, i, o = f.instruction_id(k), f.instruction_input(k), f.instruction_output(k)
        if k in pairs:  # sin and cos of one value: one reduction and both polynomials, once
            first, pair = pairs[k]
            if first:
                body.append(f"  footopt_sincos(w{i[0]}, &s{pair}, &c{pair});")
            body.append(f"  w{o[0]} = {'s' if op == ca.OP_SIN else 'c'}{pair};")
        elif op == ca.OP_INPUT:
            body.append(f"  w{o[0]} = inputs[{loads[k]}];")
        elif op == ca.OP_OUTPUT:
            body.append(f"  footopt_stage(staged + {staged[o[0]] + o[1]}, {staged[-1]}, w{i[0]});")
        elif op == ca.OP_CONST:
            body.append(f"  w{o[0]} = zero + {float(f.instruction_constant(k)).hex()};")
        elif op in _SIMD_BINARY:
            body.append(f"  w{o[0]} = w{i[0]} {_SIMD_BINARY[op]} w{i[1]};")
        elif op in _SIMD_UNARY:
            body.append(f"  w{o[0]} = " + _SIMD_UNARY[op].format(a=f"w{i[0]}") + ";")
        else:
            return None
    name, n_w = f.name(), max(f.sz_w(), 1)
    names = [f"w{j}" for j in range(n_w)] + [f"{sc}{p}" for p in range(len(pairs) // 2) for sc in "sc"]
    declarations = ["  footopt_vd " + ", ".join(names[start : start + 12]) + ";" for start in range(0, len(names), 12)]
    return (
        "\n".join(
            [
                f"#define FOOTOPT_LANES {lanes}",
                _SIMD_PRELUDE,
                f"static void {name}_simd_step(const casadi_real** in, casadi_real** out, casadi_int k0, casadi_int n) {{",
                "  casadi_int kk[FOOTOPT_LANES];",
                "  int l, valid = n - k0 < FOOTOPT_LANES ? (int)(n - k0) : FOOTOPT_LANES;",
                "  footopt_vd zero = {0};",
                f"  casadi_real staged[FOOTOPT_LANES * {max(staged[-1], 1)}];",
                "  for (l = 0; l < FOOTOPT_LANES; ++l) kk[l] = l < valid ? k0 + l : n - 1;",
                f"  footopt_vd inputs[{max(len(read), 1)}];",
                *(f"  inputs[{n}] = footopt_load(in[{i}] + {j}, {f.nnz_in(i)}, kk);" for n, (i, j) in enumerate(read)),
                *declarations,
                *body,
                *_unstaged(f, staged),
                "}",
                f"CASADI_SYMBOL_EXPORT int {name}_simd(const casadi_real** in, casadi_real** out, casadi_int n) {{",
                "  casadi_int k0;",
                f"  for (k0 = 0; k0 < n; k0 += FOOTOPT_LANES) {name}_simd_step(in, out, k0, n);",
                "  return 0;",
                "}",
                f"CASADI_SYMBOL_EXPORT int {name}_simd_parallel(const casadi_real** in, casadi_real** out, casadi_int n) {{",
                "  casadi_int k0;",
                "  #pragma omp parallel for if(n >= 64)",
                f"  for (k0 = 0; k0 < n; k0 += FOOTOPT_LANES) {name}_simd_step(in, out, k0, n);",
                "  return 0;",
                "}",
                f"CASADI_SYMBOL_EXPORT int {name}_simd_lanes(void) {{ return {lanes}; }}",
            ]
        )
        + "\n"
    )


def _input_loads(f: ca.Function) -> tuple[dict[int, int], list[tuple[int, int]]]:
    """What the SIMD step loads at its start: each INPUT instruction of ``f`` -> its place, and
    the (input, nonzero) read at each place, ordered by input, then nonzero (memory order within
    each design's rows)."""
    reads = {
        k: (int(f.instruction_input(k)[0]), int(f.instruction_input(k)[1]))
        for k in range(f.n_instructions())
        if f.instruction_id(k) == ca.OP_INPUT
    }
    order = sorted(set(reads.values()))
    place = {value: n for n, value in enumerate(order)}
    return {k: place[value] for k, value in reads.items()}, order


def _unstaged(f: ca.Function, staged: list[int]) -> list[str]:
    """C that copies each real design's outputs from the SIMD step's staging buffer (offsets
    ``staged``) to its rows: one contiguous copy per output, not a scattered store per value."""
    return [
        "  for (l = 0; l < valid; ++l) {",
        *(
            f"    memcpy(out[{i}] + kk[l] * {f.nnz_out(i)}, staged + l * {staged[-1]} + {staged[i]}, "
            f"{f.nnz_out(i)} * sizeof(casadi_real));"
            for i in range(f.n_out())
            if f.nnz_out(i)
        ),
        "  }",
    ]


#: Rows per block of :func:`api_driver` (a multiple of the SIMD lanes): its speeds and
#: restitutions are expanded into a block-sized buffer on the stack.
API_BLOCK = 64

#: Bits of the value :func:`api_driver` returns.
API_BAD_P, API_SPEED_NOT_FINITE, API_SPEED_NOT_POSITIVE, API_E_NOT_FINITE, API_E_OUT_OF_RANGE, API_FAILED = (
    1 << k for k in range(6)
)


def api_driver(f: ca.Function, simd: bool) -> str:
    """C source of ``<name>_api``: the batched API's whole call in one pass over the designs, for
    a function of ``(p, v_minus, restitution)`` (restitution one value per design). In blocks of
    ``API_BLOCK`` designs (split over threads by OpenMP when asked): every value of ``p`` checked
    against its column's closed bounds ``lo`` <= x <= ``hi`` (finite; an open or infinite bound is
    passed as the nearest double inside it, :func:`api_bounds`), each design's
    speed (finite, > 0) and restitution (finite, in [0, 1]) checked, ``v_minus`` = speed x
    ``unit_v`` (the product numpy forms, so the same bits), the SIMD (or C) loop on the block,
    then per design ``failed`` (an output not finite) and ``newton`` (finite, every output
    ``ext`` >= 0 and every output ``piv`` >= ``pivot_tol``). Returns the ``API_*`` bits of what
    was wrong (0: all checks held); the caller raises the error the bits name."""
    name = f.name()
    n_out = f.n_out()
    n_p, n_v = f.nnz_in(0), f.nnz_in(1)
    nnz_out = ", ".join(str(f.nnz_out(i)) for i in range(n_out))
    kernel = f"{name}_simd" if simd else f"{name}_batch"
    # x * 0 is 0 for every finite x and NaN for an infinite or NaN one: their sum is 0 exactly
    # when every output of the row is finite.
    finite_terms = "\n".join(
        f"    zero += res[{i}][r * {f.nnz_out(i)} + {j}] * 0;" for i in range(n_out) for j in range(f.nnz_out(i))
    )
    return f"""
static int {name}_api_block(const casadi_real* P, const casadi_real* speed, casadi_int speed_step,
    const casadi_real* E, casadi_int e_step, const casadi_real* unit_v, const casadi_real* lo,
    const casadi_real* hi, casadi_real** out, casadi_int k0, casadi_int m,
    casadi_int ext, casadi_int piv, casadi_real pivot_tol, unsigned char* newton, unsigned char* failed) {{
  static const casadi_int nnz_out[{max(n_out, 1)}] = {{{nnz_out}}};
  casadi_real v[{API_BLOCK * max(n_v, 1)}], e[{API_BLOCK}];
  const casadi_real* in[3];
  casadi_real* res[{max(n_out, 1)}];
  casadi_int r, j, i;
  int bad = 0, ok_p = 1;
  for (r = 0; r < m; ++r) {{
    const casadi_real* p = P + (k0 + r) * {n_p};
    casadi_real s = speed[(k0 + r) * speed_step], x = E[(k0 + r) * e_step];
    for (j = 0; j < {n_p}; ++j) ok_p &= (p[j] >= lo[j]) & (p[j] <= hi[j]);
    if (!(s - s == 0)) bad |= {API_SPEED_NOT_FINITE}; else if (!(s > 0)) bad |= {API_SPEED_NOT_POSITIVE};
    if (!(x - x == 0)) bad |= {API_E_NOT_FINITE}; else if (!(x >= 0 && x <= 1)) bad |= {API_E_OUT_OF_RANGE};
    for (j = 0; j < {n_v}; ++j) v[r * {n_v} + j] = s * unit_v[j];
    e[r] = x;
  }}
  if (!ok_p) bad |= {API_BAD_P};
  in[0] = P + k0 * {n_p};
  in[1] = v;
  in[2] = e;
  for (i = 0; i < {n_out}; ++i) res[i] = out[i] + k0 * nnz_out[i];
  if ({kernel}(in, res, m)) bad |= {API_FAILED};
  for (r = 0; r < m; ++r) {{
    casadi_real zero = 0;
    int positive = 1;
{finite_terms}
    for (j = 0; j < nnz_out[ext]; ++j) positive &= res[ext][r * nnz_out[ext] + j] >= 0;
    for (j = 0; j < nnz_out[piv]; ++j) positive &= res[piv][r * nnz_out[piv] + j] >= pivot_tol;
    failed[k0 + r] = !(zero == 0);
    newton[k0 + r] = (zero == 0) & positive;
  }}
  return bad;
}}
CASADI_SYMBOL_EXPORT int {name}_api(const casadi_real* P, const casadi_real* speed, casadi_int speed_step,
    const casadi_real* E, casadi_int e_step, const casadi_real* unit_v, const casadi_real* lo,
    const casadi_real* hi, casadi_real** out, casadi_int n,
    casadi_int ext, casadi_int piv, casadi_real pivot_tol, unsigned char* newton, unsigned char* failed,
    int parallel) {{
  casadi_int k0;
  int bad = 0;
  #pragma omp parallel for reduction(|:bad) if(parallel && n >= {2 * API_BLOCK})
  for (k0 = 0; k0 < n; k0 += {API_BLOCK}) {{
    casadi_int m = n - k0 < {API_BLOCK} ? n - k0 : {API_BLOCK};
    bad |= {name}_api_block(P, speed, speed_step, E, e_step, unit_v, lo, hi, out, k0, m, ext, piv,
                            pivot_tol, newton, failed);
  }}
  return bad;
}}
"""


def api_bounds(low: np.ndarray, closed: np.ndarray, high: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bounds (low, low included, high; a value must also be finite) as the closed bounds
    ``lo <= x <= hi`` that :func:`api_driver` tests, which hold for exactly the same doubles:
    an open low bound becomes the next double above it, infinite bounds the largest finite
    doubles (NaN fails both comparisons)."""
    big = np.finfo(float).max
    lo = np.where(closed, low, np.nextafter(low, np.inf))
    return np.ascontiguousarray(np.clip(lo, -big, big)), np.ascontiguousarray(np.clip(high, -big, big))


def _sincos_pairs(f: ca.Function) -> dict[int, tuple[bool, int]]:
    """The SIN and COS instructions of ``f`` that take the same value (the same work slot, not
    written in between), as instruction -> (first of its pair, pair number)."""
    version = [0] * max(f.sz_w(), 1)
    seen: dict[tuple[int, int], list[int]] = {}
    for k in range(f.n_instructions()):
        op = f.instruction_id(k)
        if op in (ca.OP_SIN, ca.OP_COS):
            slot = f.instruction_input(k)[0]
            seen.setdefault((slot, version[slot]), []).append(k)
        if op != ca.OP_OUTPUT:
            for slot in f.instruction_output(k)[:1]:
                version[slot] += 1
    pairs: dict[int, tuple[bool, int]] = {}
    for ks in seen.values():
        ops = {f.instruction_id(k) for k in ks}
        if len(ks) == 2 and ops == {ca.OP_SIN, ca.OP_COS}:
            n = len(pairs) // 2
            pairs[ks[0]], pairs[ks[1]] = (True, n), (False, n)
    return pairs


def simd_flags() -> tuple[str, ...]:
    """Instruction-set flags for the SIMD driver: ``-mavx2`` on an x86-64 CPU that has AVX2 (a
    4-lane vector is then one register), none otherwise (the compiler splits the vectors into
    what the baseline has, SSE2 pairs on x86-64). No -mfma: a fused multiply-add would round
    differently from the scalar code. Part of the cache key, so a library built for one CPU is
    never loaded on another that lacks the instructions."""
    if platform.machine().lower() not in ("x86_64", "amd64"):
        return ()
    try:
        cpuinfo = Path("/proc/cpuinfo").read_text()
    except OSError:
        return ()
    flags = next((line.split(":", 1)[1].split() for line in cpuinfo.splitlines() if line.startswith("flags")), [])
    return ("-mavx2",) if "avx2" in flags else ()


def find_compiler() -> str | None:
    """The C compiler on PATH (cc, gcc or clang), or None."""
    for name in ("cc", "gcc", "clang"):
        path = shutil.which(name)
        if path:
            return path
    return None


def compile_function(
    f: ca.Function, cache_dir: Path | None, compiler: str | None = None, *, fallback: bool = False,
    drivers: bool = True,
) -> Compiled:
    """``f`` as compiled C, loaded from (or built into) the trusted cache in ``cache_dir``
    (:mod:`impulse_core.compile.cache`: keyed by the generated source, the compiler and its flags).

    Args:
        f: the function (SX graphs generate the leanest code).
        cache_dir: where compiled libraries live (created if missing); None: do not compile, run
            on CasADi's virtual machine.
        compiler: the C compiler to use (default: :func:`find_compiler`).
        fallback: on a missing or failing compiler, warn (``RuntimeWarning``) and return the
            virtual-machine function instead of raising.
        drivers: with the loops over designs (:func:`generated_source`); without them a library
            serves one call at a time and builds faster (a landing's step: 12 s against 15 s).

    Raises:
        CompileError: no C compiler, or the build failed (unless ``fallback``).
    """
    if cache_dir is None:
        return Compiled(f, Backend.VIRTUAL_MACHINE, None, False)
    try:
        return _compiled(f, Path(cache_dir), compiler or find_compiler(), drivers)
    except CompileError as exc:
        if not fallback:
            raise
        warnings.warn(f"{exc}; {f.name()} runs on CasADi's virtual machine (slower)", RuntimeWarning, stacklevel=2)
        return Compiled(f, Backend.VIRTUAL_MACHINE, None, False)


def _compiled(f: ca.Function, cache_dir: Path, compiler: str | None, drivers: bool = True) -> Compiled:
    """The cached library of ``f``, built first if the cache has no entry matching its key."""
    if compiler is None:
        raise CompileError("no C compiler found (cc, gcc or clang): install one, or pass no cache directory")
    source, key = source_key(f, compiler, drivers)
    folder = lookup(cache_dir, f.name(), key)
    compiled_now = folder is None
    if folder is None:
        folder = store(cache_dir, f.name(), key, lambda work: _build(compiler, source, simd_flags(), work))
    library = folder / LIBRARY
    return Compiled(_external(f.name(), library), Backend.COMPILED, library, compiled_now)


@functools.lru_cache(maxsize=32)
def source_key(f: ca.Function, compiler: str, drivers: bool = True) -> tuple[str, str]:
    """``f``'s library source (:func:`generated_source`) and its cache key (the source, the
    compiler's identity, the flags), generated once per function."""
    source = generated_source(f, drivers)
    return source, entry_key(source, compiler_identity(compiler), *CFLAGS, *simd_flags(), OPENMP_FLAG)


@functools.lru_cache(maxsize=64)
def _external(name: str, library: Path) -> ca.Function:
    """A verified library's function, loaded once."""
    return ca.external(name, str(library))


def cached_function(f: ca.Function, cache_dir: Path, drivers: bool = True) -> ca.Function | None:
    """``f`` as C if the cache in ``cache_dir`` already holds its library (built by
    :func:`compile_function` or :func:`background_build` with the same ``drivers``), else None
    (also without a C compiler); nothing is built."""
    compiler = find_compiler()
    if compiler is None:
        return None
    try:
        folder = _found(Path(cache_dir), f.name(), source_key(f, compiler, drivers)[1])
    except LookupError:
        return None
    return _external(f.name(), folder / LIBRARY)


@functools.lru_cache(maxsize=64)
def _found(cache_dir: Path, name: str, key: str) -> Path:
    """The verified entry's folder, verified once (LookupError, not cached, while it is missing)."""
    folder = lookup(cache_dir, name, key)
    if folder is None:
        raise LookupError(name)
    return folder


def background_build(
    f: ca.Function, cache_dir: Path, drivers: bool = True, niceness: int = 0, jobs: list | None = None
) -> Callable[[], Path] | None:
    """``f``'s source generated now, and a call that compiles it into the cache and returns the
    entry's folder (:func:`impulse_core.compile.cache.store`; it calls no CasADi, so it may run in
    a thread, and its compiler runs at ``niceness``; ``jobs`` receives the compiler's process, to
    stop it); None without a compiler or when the cache already holds it."""
    compiler = find_compiler()
    if compiler is None:
        return None
    source, key = source_key(f, compiler, drivers)
    if lookup(Path(cache_dir), f.name(), key) is not None:
        return None
    arch = simd_flags()
    return functools.partial(_claimed_store, Path(cache_dir), f.name(), key,
                             lambda work: _build(compiler, source, arch, work, niceness, jobs))


def _claimed_store(root: Path, name: str, key: str, build: Callable[[Path], list[str]]) -> Path | None:
    """:func:`store` unless another process builds the entry (:func:`impulse_core.compile.cache.claim`:
    None) or has stored it meanwhile."""
    with claim(root, name, key) as mine:
        if not mine:
            return None
        return lookup(root, name, key) or store(root, name, key, build)


def generated_source(f: ca.Function, drivers: bool = True) -> str:
    """The C of one library: CasADi's code for ``f``, then (``drivers``) the C loop and the SIMD
    loop over designs."""
    with tempfile.TemporaryDirectory() as tmp:
        generator = ca.CodeGenerator(f"{f.name()}.c", {"with_header": False})
        generator.add(f)
        source = Path(generator.generate(f"{tmp}/")).read_text()
    if not drivers:
        return source
    simd = simd_driver(f)
    lanes = simd or f"CASADI_SYMBOL_EXPORT int {f.name()}_simd_lanes(void) {{ return 0; }}\n"
    api = api_driver(f, simd is not None) if _api_signature(f) else ""
    return source + batch_driver(f) + lanes + api


def _api_signature(f: ca.Function) -> bool:
    """Whether ``f`` takes ``(p, v_minus, restitution)`` with one restitution per design (what
    :func:`api_driver` serves)."""
    return f.n_in() == 3 and f.nnz_in(2) == 1 and f.n_out() > 0


def _build(compiler: str, source: str, arch: tuple[str, ...], work: Path, niceness: int = 0,
           jobs: list | None = None) -> list[str]:
    """Compile ``source`` into ``work``/LIBRARY: with OpenMP and the SIMD flags, else without
    OpenMP (the parallel loops then run serially); returns the files to record."""
    (work / "source.c").write_text(source)
    command = [compiler, *CFLAGS, *arch, str(work / "source.c"), "-o", str(work / LIBRARY)]
    try:
        run_compilers([*command[:-3], OPENMP_FLAG, *command[-3:]], niceness=niceness, jobs=jobs)
    except CompileError:
        run_compilers(command, niceness=niceness, jobs=jobs)
    return [LIBRARY, "source.c"]


def batch_kernel(
    compiled: Compiled, f: ca.Function, parallel: bool = False, simd: bool = False
) -> Callable[..., list[np.ndarray]] | None:
    """The compiled batch driver of ``f`` (:func:`batch_driver`) as a Python callable, or None on
    the virtual-machine path.

    The callable takes one array per input, shape (n_designs, nnz_in(i)) in C order (one design
    per row), and returns one array per output, shape (n_designs, nnz_out(i)); pass ``out=`` (a
    list of such arrays) to reuse buffers. Raises ``FloatingPointError`` if the C code reports a
    failure. With ``parallel``, the loop is split over OpenMP threads (``OMP_NUM_THREADS``; all
    cores by default) when the library was built with OpenMP (:func:`has_openmp`). With ``simd``,
    the SIMD driver (:func:`simd_driver`), or None if the library has none (:func:`simd_lanes`).
    """
    if compiled.backend is not Backend.COMPILED or compiled.library is None:
        return None
    if simd and not simd_lanes(compiled, f):
        return None
    lib = ctypes.CDLL(str(compiled.library))
    driver = "simd" if simd else "batch"
    fn = getattr(lib, f"{f.name()}_{driver}_parallel" if parallel else f"{f.name()}_{driver}")
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


def api_kernel(compiled: Compiled, f: ca.Function) -> Callable[..., int] | None:
    """The compiled library's :func:`api_driver` as a ctypes function (arguments as its C
    signature, arrays by address), or None (virtual machine, another signature, no driver)."""
    if compiled.backend is not Backend.COMPILED or compiled.library is None or not _api_signature(f):
        return None
    fn = getattr(ctypes.CDLL(str(compiled.library)), f"{f.name()}_api", None)
    if fn is None:
        return None
    address, count = ctypes.c_void_p, ctypes.c_longlong
    fn.restype = ctypes.c_int
    fn.argtypes = [address, address, count, address, count, address, address, address, address,
                   count, count, count, ctypes.c_double, address, address, ctypes.c_int]
    return fn


def has_openmp(compiled: Compiled, f: ca.Function) -> bool:
    """Whether the compiled library's parallel batch loop was built with OpenMP."""
    if compiled.backend is not Backend.COMPILED or compiled.library is None:
        return False
    return bool(getattr(ctypes.CDLL(str(compiled.library)), f"{f.name()}_openmp")())


def simd_lanes(compiled: Compiled, f: ca.Function) -> int:
    """Designs per step of the compiled library's SIMD driver; 0 if it has none."""
    if compiled.backend is not Backend.COMPILED or compiled.library is None:
        return 0
    return int(getattr(ctypes.CDLL(str(compiled.library)), f"{f.name()}_simd_lanes")())
