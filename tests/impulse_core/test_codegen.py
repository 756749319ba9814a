"""Compiled C equals the virtual machine, is cached on disk, and falls back without a compiler;
the SIMD driver equals the C loop, its sin and cos are within 1-2 ulp of libm's."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from impulse_core.compile.cache import CompileError
from impulse_core.compile.codegen import Backend, batch_kernel, compile_function, find_compiler, simd_driver, simd_lanes
from impulse_core.evaluate import approach_velocity, compiled_model
from impulse_core.model.tree import Body, Tree, design_vector


needs_compiler_here = pytest.mark.skipif(find_compiler() is None, reason="no C compiler on this machine")


@pytest.fixture(scope="module")
def leg():
    tree = Tree(
        (
            Body("thigh", None, 0.7, 1.0, -1.2),
            Body("shank", 0, 0.7, 1.0, 0.6),
            Body("heel", 1, 0.15, 0.1, 2.0, contacts=(1.0,)),
            Body("toe", 1, 0.3, 0.4, 0.9, contacts=(1.0,)),
        )
    )
    topology = tree.topology()
    return compiled_model(topology).impact, design_vector(tree), approach_velocity(topology, 3.43)


@pytest.mark.skipif(find_compiler() is None, reason="no C compiler on this machine")
def test_compiled_equals_vm_and_is_cached(leg, tmp_path) -> None:
    f, p, v = leg
    first = compile_function(f, tmp_path)
    assert first.backend is Backend.COMPILED and first.compiled_now and first.library.exists()
    again = compile_function(f, tmp_path)
    assert again.backend is Backend.COMPILED and not again.compiled_now and again.library == first.library
    for k in range(f.n_out()):
        np.testing.assert_allclose(
            np.array(first.function(p, v, 0.8)[k]), np.array(f(p, v, 0.8)[k]), rtol=1e-13, atol=1e-15
        )


def test_no_cache_dir_runs_on_the_vm(leg) -> None:
    f, p, v = leg
    assert compile_function(f, None).backend is Backend.VIRTUAL_MACHINE


@pytest.mark.parametrize("compiler", ["/nonexistent/cc", "false"])
def test_a_failing_compiler_is_an_error_or_on_request_a_warning_and_the_vm(leg, tmp_path, compiler) -> None:
    f, p, v = leg
    with pytest.raises(CompileError, match="compiler"):
        compile_function(f, tmp_path, compiler=compiler)
    with pytest.warns(RuntimeWarning, match="virtual machine"):
        broken = compile_function(f, tmp_path, compiler=compiler, fallback=True)
    assert broken.backend is Backend.VIRTUAL_MACHINE
    np.testing.assert_array_equal(np.array(broken.function(p, v, 0.8)[0]), np.array(f(p, v, 0.8)[0]))


@needs_compiler_here
def test_a_tampered_or_foreign_library_is_never_loaded(leg, tmp_path) -> None:
    """A library whose bytes changed, or a folder of the right name without our manifest, is
    rebuilt, never loaded."""
    f, p, v = leg
    first = compile_function(f, tmp_path)
    tampered = first.library.with_suffix(".tmp")  # a new file, not the one this process mapped
    tampered.write_bytes(first.library.read_bytes() + b"\0")
    tampered.replace(first.library)
    again = compile_function(f, tmp_path)
    assert again.compiled_now and again.library == first.library
    (again.library.parent / "manifest.json").unlink()  # a foreign folder: no manifest of ours
    third = compile_function(f, tmp_path)
    assert third.compiled_now
    np.testing.assert_allclose(np.array(third.function(p, v, 0.8)[0]), np.array(f(p, v, 0.8)[0]), rtol=1e-13)


@needs_compiler_here
def test_the_key_follows_the_generated_source(leg, tmp_path) -> None:
    """Two functions of one name with different graphs get different entries; the same graph
    the same entry."""
    x = ca.SX.sym("x")
    a = compile_function(ca.Function("same_name", [x], [2 * x]), tmp_path)
    b = compile_function(ca.Function("same_name", [x], [3 * x]), tmp_path)
    again = compile_function(ca.Function("same_name", [x], [2 * x]), tmp_path)
    assert a.library != b.library and again.library == a.library and not again.compiled_now
    assert float(b.function(1.0)) == 3.0 and float(again.function(1.0)) == 2.0


@pytest.mark.skipif(find_compiler() is None, reason="no C compiler on this machine")
def test_batch_kernel_equals_single_calls(leg, tmp_path) -> None:
    """The compiled C loop over designs (one design per row) gives each design's single-call
    outputs, bit for bit; the VM path has no kernel."""
    f, p, v = leg
    compiled = compile_function(f, tmp_path)
    kernel = batch_kernel(compiled, f)
    rng = np.random.default_rng(3)
    P = p[None, :] * (1 + 0.01 * rng.standard_normal((5, p.size)))
    E = np.full((5, 1), 0.8)
    out = kernel(P, np.repeat(v[None, :], 5, axis=0), E)
    for i in range(5):
        single = compiled.function(P[i], v, 0.8)
        for k in range(f.n_out()):
            np.testing.assert_array_equal(out[k][i], np.array(single[k]).ravel(order="F"))
    parallel = batch_kernel(compiled, f, parallel=True)
    many = np.repeat(P, 40, axis=0)  # enough rows for the OpenMP loop to split
    serial = kernel(many, np.repeat(v[None, :], 200, axis=0), np.full((200, 1), 0.8))
    split = parallel(many, np.repeat(v[None, :], 200, axis=0), np.full((200, 1), 0.8))
    for a, b in zip(serial, split):
        np.testing.assert_array_equal(a, b)
    assert batch_kernel(compile_function(f, None), f) is None


needs_compiler = pytest.mark.skipif(find_compiler() is None, reason="no C compiler on this machine")


@needs_compiler
@pytest.mark.parametrize("n", [1, 3, 4, 7, 64])
def test_simd_kernel_equals_c_loop(leg, tmp_path, n) -> None:
    """The SIMD driver gives the C loop's outputs (arithmetic bit for bit; sin and cos within an
    ulp, so within 1e-13 of the outputs' size: some outputs, the joint torques, are zero up to
    rounding), whatever the number of designs (the last step is partly empty); its OpenMP twin
    gives the same bits."""
    f, p, v = leg
    compiled = compile_function(f, tmp_path)
    assert simd_lanes(compiled, f) >= 2
    rng = np.random.default_rng(n)
    P = p[None, :] * (1 + 0.05 * rng.standard_normal((n, p.size)))
    args = (P, np.repeat(v[None, :], n, axis=0), np.full((n, 1), 0.8))
    loop = batch_kernel(compiled, f)(*args)
    simd = batch_kernel(compiled, f, simd=True)(*args)
    scale = max(np.abs(a).max() for a in loop)
    for a, b in zip(loop, simd):
        np.testing.assert_allclose(b, a, rtol=0, atol=1e-13 * scale)
    split = batch_kernel(compiled, f, simd=True, parallel=True)(*args)
    for a, b in zip(simd, split):
        np.testing.assert_array_equal(a, b)


@needs_compiler
def test_simd_sin_cos_within_ulps_of_libm(tmp_path) -> None:
    """The vector sin and cos against numpy's (libm): at most 1 ulp apart for the angles of a
    model (|x| <= 10), 2 ulp up to 1e5; libm's own answer beyond, and for inf and nan."""
    x = ca.SX.sym("x")
    f = ca.Function("trig", [x], [ca.sin(x), ca.cos(x)])  # one value: sin and cos paired
    kernel = batch_kernel(compile_function(f, tmp_path), f, simd=True)
    g = ca.Function("trig_apart", [x], [ca.sin(x), ca.cos(0.5 * x)])  # two values: each on its own
    apart = batch_kernel(compile_function(g, tmp_path), g, simd=True)
    rng = np.random.default_rng(0)
    for bound, ulps in ((10.0, 1), (1e5, 2)):
        X = np.concatenate([rng.uniform(-bound, bound, 200_000), np.arange(-8, 9) * np.pi / 4])
        s, c = kernel(X[:, None])
        s2, c2 = apart(X[:, None])
        for got, ref in ((s, np.sin(X)), (c, np.cos(X)), (s2, np.sin(X)), (c2, np.cos(0.5 * X))):
            assert np.all(np.abs(got.ravel() - ref) <= ulps * np.spacing(np.abs(ref))), bound
    X = np.array([1e5 + 1, 1e6, 1e300, np.inf, -np.inf, np.nan])
    s, c = kernel(X[:, None])
    with np.errstate(invalid="ignore"):
        np.testing.assert_array_equal(s.ravel(), np.sin(X))
        np.testing.assert_array_equal(c.ravel(), np.cos(X))


@needs_compiler
def test_simd_sin_cos_of_zero_lanes_are_exact(tmp_path) -> None:
    """A step whose lanes are all +0 or -0 (rpy values at 0) gives sin x = x (its sign kept) and
    cos x = 1, as libm; a step with one lane off zero takes the kernel, and equals libm there
    (steps of four: designs 0-3 and 12-13 all zero, the last step's spare lanes repeat design 13)."""
    x = ca.SX.sym("x")
    f = ca.Function("trig_zero", [x], [ca.sin(x), ca.cos(x)])
    kernel = batch_kernel(compile_function(f, tmp_path), f, simd=True)
    X = np.array([0.0, -0.0, 0.0, -0.0, 0.0, 0.0, 0.0, 1e-300, -0.0, 0.0, 0.5, 0.0, -0.0, 0.0])
    s, c = kernel(X[:, None])
    np.testing.assert_array_equal(s.ravel(), np.sin(X))
    zero_steps = [0, 1, 2, 3, 12, 13]
    np.testing.assert_array_equal(np.signbit(s.ravel()[zero_steps]), np.signbit(X[zero_steps]))
    np.testing.assert_array_equal(c.ravel(), np.cos(X))


@needs_compiler
def test_simd_driver_only_for_the_operations_it_knows(tmp_path) -> None:
    """A function with an operation the SIMD driver does not write (exp) compiles without it:
    the C loop works, the SIMD kernel is None; so is it on the VM path."""
    x = ca.SX.sym("x")
    f = ca.Function("grow", [x], [ca.exp(x) + ca.sin(x)])
    assert simd_driver(f) is None
    compiled = compile_function(f, tmp_path)
    assert compiled.backend is Backend.COMPILED and simd_lanes(compiled, f) == 0
    assert batch_kernel(compiled, f, simd=True) is None
    np.testing.assert_allclose(batch_kernel(compiled, f)(np.array([[0.5]]))[0], [[np.exp(0.5) + np.sin(0.5)]])
    assert batch_kernel(compile_function(f, None), f, simd=True) is None


@needs_compiler
@pytest.mark.parametrize("n", [1, 5, 8])
def test_simd_step_loads_its_inputs_first_in_memory_order(tmp_path, n) -> None:
    """The SIMD step loads every input value it reads once, at its start, by input then nonzero
    (values read out of that order, some never read), and each instruction gets its own value:
    the outputs equal the C loop's bit for bit (no sin or cos), partly empty steps included."""
    x, y = ca.SX.sym("x", 5), ca.SX.sym("y", 3)
    f = ca.Function("scrambled", [x, y], [ca.vertcat(y[2] * x[4] - x[0], x[3] / y[0] + x[4] * x[4]), x[0] - y[2]])
    source = simd_driver(f)
    loads = [line.strip() for line in source.splitlines() if "= footopt_load(" in line]
    assert loads == [
        f"inputs[{k}] = footopt_load(in[{i}] + {j}, {f.nnz_in(i)}, kk);"
        for k, (i, j) in enumerate([(0, 0), (0, 3), (0, 4), (1, 0), (1, 2)])
    ]
    body = source[source.index("_simd_step(") :]
    assert body.index("footopt_load(in[1] + 2") < body.index(" w0 =")
    rng = np.random.default_rng(n)
    args = (rng.uniform(0.5, 2.0, (n, 5)), rng.uniform(0.5, 2.0, (n, 3)))
    compiled = compile_function(f, tmp_path)
    for a, b in zip(batch_kernel(compiled, f)(*args), batch_kernel(compiled, f, simd=True)(*args)):
        np.testing.assert_array_equal(b, a)


def test_a_claim_lets_one_process_build_an_entry(tmp_path):
    """:func:`claim`: the first claim holds the entry's lock until it leaves, a second is refused
    meanwhile and granted after; a lock whose process has ended is taken over, and a lock whose
    process still runs (this one, written by hand) refuses."""
    import os
    import subprocess

    from impulse_core.compile.cache import claim

    key = "ab" * 32
    with claim(tmp_path, "f", key) as first:
        assert first
        with claim(tmp_path, "f", key) as second:
            assert not second
    with claim(tmp_path, "f", key) as again:
        assert again
    ended = subprocess.Popen(["true"])
    ended.wait()
    lock = tmp_path / f".f_{key[:20]}.lock"
    lock.write_text(str(ended.pid))
    with claim(tmp_path, "f", key) as taken:
        assert taken
    assert not lock.exists()
    lock.write_text(str(os.getpid()))
    with claim(tmp_path, "f", key) as held:
        assert not held
