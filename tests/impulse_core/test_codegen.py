"""Compiled C equals the virtual machine, is cached on disk, and falls back without a compiler."""

from __future__ import annotations

import numpy as np
import pytest

from impulse_core.codegen import Backend, compile_function, find_compiler
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
