"""Compiled C equals the virtual machine, is cached on disk, and falls back without a compiler."""

from __future__ import annotations

import numpy as np
import pytest

from impulse_core.codegen import Backend, batch_kernel, compile_function, find_compiler
from impulse_core.evaluate import approach_velocity, compiled_model
from impulse_core.tree import Body, Tree, design_vector


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
        np.testing.assert_allclose(np.array(first.function(p, v, 0.8)[k]), np.array(f(p, v, 0.8)[k]), rtol=1e-13, atol=1e-15)


def test_falls_back_to_vm(leg, tmp_path) -> None:
    f, p, v = leg
    assert compile_function(f, None).backend is Backend.VIRTUAL_MACHINE
    broken = compile_function(f, tmp_path, compiler="/nonexistent/cc")
    assert broken.backend is Backend.VIRTUAL_MACHINE
    np.testing.assert_array_equal(np.array(broken.function(p, v, 0.8)[0]), np.array(f(p, v, 0.8)[0]))


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
