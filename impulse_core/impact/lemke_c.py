"""Lemke's method (:func:`impulse_core.impact.coulomb.lemke`) as C, through the compile cache;
with it :func:`~impulse_core.impact.coulomb.solve_unilateral`'s LCP (its matrix, scaling and
first pivoting path) and the landing's event-location root (:func:`impulse_core.timedomain.
landing._hermite_root`).

The same arithmetic as the numpy and Python-float code, operation for operation: the tableau
[I, -M, -cover, q], its scale and tolerance, the first pivot on argmin(q / cover), each pivot's
row divided by the pivot and the other rows less their factor times it (a product, then a
difference: the library is built without fused multiply-adds, as every compiled function of the
cache, :data:`impulse_core.compile.codegen.CFLAGS`), the ratio test's least ratio, its ties
within tol (1 + |least|) going to the artificial variable first, then to the lowest row; the
unilateral LCP's blocks (with -eye's signed zeros), D M D and D q / speed as numpy multiplies
them. So each returns the same numbers, bit for bit, at a few microseconds a call instead of
about a hundred for a landing's 12-row impact LCP (tests/impulse_core/test_lemke_c.py and
tests/impulse_core/test_landing_event_path.py check the equality). What numpy's own routines
do (the matrix-vector products, clips at 0) stays in numpy.

:func:`compiled_lemke` builds (or loads) the library; ``lemke``, ``solve_unilateral`` and
``cone_unilateral`` run on it when given it as their ``kernel`` (the numbers are the same either
way): a landing with ``step_code`` c does (:class:`impulse_core.timedomain.events.run._Landing`), and
locates its events with :func:`hermite_root`. Without a C compiler the Python code stays in place.
"""

from __future__ import annotations

import ctypes
import functools
import math
import threading

import numpy as np

from impulse_core.compile.cache import (
    CompileError, compiler_identity, default_root, entry_key, lookup, run_compilers, store,
)
from impulse_core.compile.codegen import CFLAGS, find_compiler

NAME = "footopt_lemke"
LIBRARY = "lemke.so"

SOURCE = r"""
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Gauss-Jordan pivot of the n x w tableau T on (row, col): coulomb._pivot's arithmetic. */
static void pivot(double *T, int *basis, int n, int w, int row, int col, double *pr, double *f) {
    double p = T[row * w + col];
    for (int j = 0; j < w; ++j) pr[j] = T[row * w + j] / p;
    for (int i = 0; i < n; ++i) f[i] = T[i * w + col];
    f[row] = 0.0;
    for (int i = 0; i < n; ++i) {
        double fi = f[i];
        double *Ti = T + i * w;
        for (int j = 0; j < w; ++j) Ti[j] -= fi * pr[j];
    }
    memcpy(T + row * w, pr, sizeof(double) * w);
    basis[row] = col;
}

/* coulomb.lemke (n > 0): 0 where M or q is not finite (no pivoting on NaN), 2 where q >= 0
   (z = 0), 1 and z (before the clip at 0), 0 on a secondary ray or out of pivots, -1 without
   memory. */
static int lemke_core(int n, const double *M, const double *q, const double *cover, int max_pivots,
                      double tol_unit, double *z) {
    for (int i = 0; i < n * n; ++i)
        if (!isfinite(M[i])) return 0;
    for (int i = 0; i < n; ++i)
        if (!isfinite(q[i])) return 0;
    int negative = 0;
    for (int i = 0; i < n; ++i) negative |= !(q[i] >= 0.0);
    if (!negative) return 2;
    int w = 2 * n + 2, art = 2 * n, status = 0;
    double *T = malloc(sizeof(double) * (n * w + w + 2 * n));
    int *basis = malloc(sizeof(int) * n);
    if (!T || !basis) { free(T); free(basis); return -1; }
    double *pr = T + n * w, *f = pr + w, *ratio = f + n;
    for (int i = 0; i < n; ++i) {
        double *Ti = T + i * w;
        for (int j = 0; j < n; ++j) Ti[j] = i == j ? 1.0 : 0.0;
        for (int j = 0; j < n; ++j) Ti[n + j] = -M[i * n + j];
        Ti[art] = -cover[i];
        Ti[art + 1] = q[i];
        basis[i] = i;
    }
    double scale = 1.0, big = -INFINITY;
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < w - 1; ++j) { double a = fabs(T[i * w + j]); if (a > big) big = a; }
    if (big > scale) scale = big;
    double tol = tol_unit * scale;
    int first = 0;
    double best = q[0] / cover[0];
    for (int i = 1; i < n; ++i) { double r = q[i] / cover[i]; if (r < best) { best = r; first = i; } }
    pivot(T, basis, n, w, first, art, pr, f);
    int entering = n + first;
    for (int k = 0; k < max_pivots; ++k) {
        int any = 0;
        double least = 0.0;
        for (int r = 0; r < n; ++r) {
            double c = T[r * w + entering];
            if (c > tol) {
                ratio[r] = T[r * w + w - 1] / c;
                if (!any || ratio[r] < least) least = ratio[r];
                any = 1;
            } else {
                ratio[r] = NAN;
            }
        }
        if (!any) break;  /* a secondary ray */
        double bound = least + tol * (1.0 + fabs(least));
        int row = -1, tie = -1;
        for (int r = 0; r < n; ++r) {
            if (T[r * w + entering] > tol && ratio[r] <= bound) {
                if (tie < 0) tie = r;
                if (basis[r] == art) { row = r; break; }
            }
        }
        if (row < 0) row = tie;
        if (row < 0) break;  /* no tie (NaN ratios): the Python code's ties[0] would fail alike */
        int leaving = basis[row];
        pivot(T, basis, n, w, row, entering, pr, f);
        if (leaving == art) {
            for (int j = 0; j < n; ++j) z[j] = 0.0;
            for (int r = 0; r < n; ++r) {
                int var = basis[r];
                if (var >= n && var < 2 * n) z[var - n] = T[r * w + w - 1];
            }
            status = 1;
            break;
        }
        entering = leaving < n ? leaving + n : leaving - n;
    }
    free(T);
    free(basis);
    return status;
}

/* lemke_core on data = [M (n x n, row-major), q, cover, z]. */
int footopt_lemke(int n, double *data, int max_pivots, double tol_unit) {
    return lemke_core(n, data, data + n * n, data + n * n + n, max_pivots, tol_unit, data + n * n + 2 * n);
}

/* coulomb.solve_unilateral's LCP (unilateral_lcp), its scaling (scaled_lemke's D and speed) and
   Lemke's method with the unit cover, on data = [W (k x k, row-major, k = n + m), u (k),
   restitution (n), mu (m), owner (m, as doubles), then out: z (N = n + 3 m, before the clip),
   d (N), speed]; returns lemke_core's status (the caller retries other covers in Python). */
int footopt_unilateral(int n, int m, double *data, int max_pivots, double tol_unit) {
    int k = n + m, N = n + 3 * m;
    const double *W = data, *u = W + k * k, *e = u + k, *mu = e + n, *owner = mu + m;
    double *z = (double *)owner + m, *d = z + N, *speed = d + N;
    double *M = malloc(sizeof(double) * (N * N + 2 * N));
    if (!M) return -1;
    double *q = M + N * N, *cover = q + N;
    const double tiny = 2.2250738585072014e-308;
    for (int i = 0; i < N * N; ++i) M[i] = 0.0;
#define MM(i, j) M[(i) * N + (j)]
#define WW(i, j) W[(i) * k + (j)]
    int t = n, s = n + m, b = n + 2 * m;  /* lambda_t+, lambda_t-, beta */
    for (int i = 0; i < n; ++i) {
        for (int j = 0; j < n; ++j) MM(i, j) = WW(i, j);
        for (int j = 0; j < m; ++j) { MM(i, t + j) = WW(i, n + j); MM(i, s + j) = -WW(i, n + j); }
    }
    for (int i = 0; i < m; ++i) {
        for (int j = 0; j < n; ++j) { MM(t + i, j) = WW(n + i, j); MM(s + i, j) = -WW(n + i, j); }
        for (int j = 0; j < m; ++j) {
            MM(t + i, t + j) = WW(n + i, n + j);
            MM(t + i, s + j) = -WW(n + i, n + j);
            MM(s + i, t + j) = -WW(n + i, n + j);
            MM(s + i, s + j) = WW(n + i, n + j);
            /* M[b, t] = M[b, s] = -eye(m): -0.0 off the diagonal */
            MM(b + i, t + j) = i == j ? -1.0 : -0.0;
            MM(b + i, s + j) = i == j ? -1.0 : -0.0;
        }
        MM(t + i, b + i) = 1.0;
        MM(s + i, b + i) = 1.0;
        MM(b + i, (int)owner[i]) = mu[i];
    }
#undef MM
#undef WW
    for (int i = 0; i < n; ++i) q[i] = (1.0 + e[i]) * u[i];
    for (int i = 0; i < m; ++i) { q[t + i] = u[n + i]; q[s + i] = -u[n + i]; q[b + i] = 0.0; }
    double top = 0.0;
    for (int i = 0; i < k; ++i) { double a = fabs(u[i]); if (a > top) top = a; }
    *speed = top > tiny ? top : tiny;  /* max(max |u|, tiny); a NaN u stops at lemke_core's check */
    for (int i = 0; i < n; ++i) {
        double a = fabs(W[i * k + i]);
        d[i] = 1.0 / sqrt(a < tiny ? tiny : a);  /* np.maximum(|W_ii|, tiny): NaN propagates */
    }
    for (int i = 0; i < m; ++i) {
        double st = d[(int)owner[i]];
        d[t + i] = st;
        d[s + i] = st;
        d[b + i] = 1.0 / st;
    }
    for (int i = 0; i < N; ++i) {
        for (int j = 0; j < N; ++j) M[i * N + j] = d[i] * M[i * N + j] * d[j];
        q[i] = d[i] * q[i] / *speed;
        cover[i] = 1.0;
    }
    int status = lemke_core(N, M, q, cover, max_pivots, tol_unit, z);
    free(M);
    return status;
}

/* landing._hermite_root (its arguments finite): the first of the ns samples s where the cubic
   Hermite fit falls below 0 (Horner's rule), then 40 bisections; NaN where none or the first. */
double footopt_hermite_root(double g0, double d0, double g1, double d1, const double *s, int ns) {
    double c3 = 2 * g0 + d0 - 2 * g1 + d1, c2 = -3 * g0 - 2 * d0 + 3 * g1 - d1, c1 = d0, c0 = g0;
    int first = 0;
    for (int i = 0; i < ns; ++i)
        if (((c3 * s[i] + c2) * s[i] + c1) * s[i] + c0 < 0) { first = i; break; }
    if (first == 0) return NAN;
    double a = s[first - 1], b = s[first];
    for (int k = 0; k < 40; ++k) {
        double m = 0.5 * (a + b);
        if (((c3 * m + c2) * m + c1) * m + c0 >= 0) a = m; else b = m;
    }
    return b;
}
"""


def _build(compiler: str, work) -> list[str]:
    (work / "lemke.c").write_text(SOURCE)
    run_compilers([compiler, *CFLAGS, str(work / "lemke.c"), "-o", str(work / LIBRARY)])
    return [LIBRARY, "lemke.c"]


@functools.cache
def kernel(cache_dir: str | None = None):
    """The library's functions (ctypes: ``footopt_lemke``, ``footopt_unilateral``,
    ``footopt_hermite_root``), built into (or loaded from) the compile cache (``cache_dir``,
    default :func:`~impulse_core.compile.cache.default_root`); None without a C compiler, when the
    build fails or the cache cannot be written."""
    compiler = find_compiler()
    if compiler is None:
        return None
    root = default_root() if cache_dir is None else cache_dir
    try:
        key = entry_key(SOURCE, compiler_identity(compiler), *CFLAGS)
        folder = lookup(root, NAME, key) or store(root, NAME, key, lambda work: _build(compiler, work))
    except (CompileError, OSError):  # no compiler, a failed build, an unwritable cache
        return None
    library = ctypes.CDLL(str(folder / LIBRARY))
    lemke, unilateral = library.footopt_lemke, library.footopt_unilateral
    lemke.argtypes = [ctypes.c_int, ctypes.c_void_p, ctypes.c_int, ctypes.c_double]
    unilateral.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.c_void_p, ctypes.c_int, ctypes.c_double]
    lemke.restype = unilateral.restype = ctypes.c_int
    hermite = library.footopt_hermite_root
    hermite.argtypes = [ctypes.c_double] * 4 + [ctypes.c_void_p, ctypes.c_int]
    hermite.restype = ctypes.c_double
    return lemke, unilateral, hermite


@functools.cache
def compiled_lemke(cache_dir: str | None = None) -> Lemke | None:
    """Lemke's method as C (:class:`Lemke` on :func:`kernel`'s functions), or None without a C
    compiler: the ``kernel`` of :func:`impulse_core.impact.coulomb.lemke` and its callers."""
    functions = kernel(cache_dir)
    return None if functions is None else Lemke(functions)


class Lemke:
    """The compiled Lemke's method on per-size work arrays (their addresses taken once: a call
    then costs a few copies and the C function's own time)."""

    def __init__(self, functions) -> None:
        self.fn, self.fn_unilateral, self.fn_root = functions
        self.local = threading.local()  # the work arrays, per thread (landings may run in threads)

    @property
    def work(self) -> dict[int, tuple[np.ndarray, int]]:
        """Per size, this thread's work array for :meth:`__call__` and its address."""
        try:
            return self.local.work
        except AttributeError:
            self.local.work = {}
            return self.local.work

    @property
    def work_unilateral(self) -> dict[tuple[int, int], tuple[np.ndarray, int]]:
        """Per (n, m), this thread's work array for :meth:`unilateral` and its address."""
        try:
            return self.local.work_unilateral
        except AttributeError:
            self.local.work_unilateral = {}
            return self.local.work_unilateral

    def unilateral(self, W: np.ndarray, u: np.ndarray, owner: np.ndarray, restitution: np.ndarray, mu: np.ndarray,
                   tol: float) -> np.ndarray | None:
        """:func:`impulse_core.impact.coulomb.scaled_lemke`'s z of :func:`~impulse_core.impact.coulomb.
        unilateral_lcp`'s LCP with solve_unilateral's scaling, where the unit covering vector finds it;
        None where not (the caller then takes the Python path, which retries other covers)."""
        n, m = len(restitution), len(owner)
        k, N = n + m, n + 3 * m
        work = self.work_unilateral.get((n, m))
        if work is None:
            data = np.zeros(k * k + k + n + 2 * m + 2 * N + 1)
            work = self.work_unilateral[(n, m)] = (data, data.ctypes.data)
        data, address = work
        kk = k * k
        data[:kk].reshape(k, k)[:] = W
        data[kk : kk + k] = u
        data[kk + k : kk + k + n] = restitution
        data[kk + k + n : kk + k + n + m] = mu
        data[kk + k + n + m : kk + k + n + 2 * m] = owner
        status = self.fn_unilateral(n, m, address, 50 * N + 50, tol)
        if status < 0:
            raise MemoryError("Lemke's method: no memory for the tableau")
        if status == 0:
            return None
        z0 = kk + k + n + 2 * m
        d, speed = data[z0 + N : z0 + 2 * N], data[z0 + 2 * N]
        z = np.maximum(data[z0 : z0 + N], 0.0) if status == 1 else np.zeros(N)
        return d * z * speed

    def __call__(self, M: np.ndarray, q: np.ndarray, cover: np.ndarray | None, max_pivots: int, tol: float
                 ) -> np.ndarray | None:
        """:func:`impulse_core.impact.coulomb.lemke`'s answer: z, or None (M or q not finite, a
        ray, out of pivots); M (n x n), q float arrays, n > 0, ``cover`` None: ones."""
        n = q.size
        work = self.work.get(n)
        if work is None:
            data = np.zeros(n * n + 3 * n)
            work = self.work[n] = (data, data.ctypes.data)
        data, address = work
        nn = n * n
        data[:nn].reshape(n, n)[:] = M
        data[nn : nn + n] = q
        data[nn + n : nn + 2 * n] = 1.0 if cover is None else cover
        status = self.fn(n, address, max_pivots, tol)
        if status == 1:
            return np.maximum(data[nn + 2 * n :], 0.0)
        if status == 2:
            return np.zeros(n)
        if status < 0:
            raise MemoryError("Lemke's method: no memory for the tableau")
        return None


def hermite_root(samples: np.ndarray):
    """:func:`impulse_core.timedomain.events.location._hermite_root` on ``samples`` as the compiled
    library's (the same arithmetic, the same root bit for bit), or None without a C compiler."""
    functions = kernel()
    if functions is None:
        return None
    fn, s = functions[2], np.ascontiguousarray(samples, dtype=float)
    address, ns, isfinite, nan = s.ctypes.data, len(s), math.isfinite, math.nan

    def root(g0: float, d0: float, g1: float, d1: float) -> float:
        if not (isfinite(d0) and isfinite(d1) and isfinite(g0) and isfinite(g1)):
            return nan
        return fn(g0, d0, g1, d1, address, ns)

    root.samples = s  # the samples' array stays alive with the function
    return root


__all__ = ["SOURCE", "Lemke", "compiled_lemke", "hermite_root", "kernel"]
