"""Batches of designs (``impulse_core.compile.batch``): every row equals ``evaluate()`` where the batch says
Newton's law is its answer, and the flag says so exactly where ``evaluate()`` keeps Newton's law;
gradients equal the single-call function's; impulses scale with speed and with (1 + e); bad
input is refused naming the value."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from impulse_core.compile.batch import batch_evaluator
from impulse_core.compile.codegen import find_compiler
from impulse_core.impact.laws import ImpactModel
from impulse_core.errors import ModelError
from impulse_core.evaluate import approach_velocity, evaluate
from impulse_core.impact.delassus import norms_gradient_function
from impulse_core.model.tree import (
    BODY_VALUES,
    CONTACT_BOUNDS,
    VALUE_BOUNDS,
    Body,
    ContactSelection,
    JointKind,
    Scene,
    Tree,
    design_vector,
    with_values,
)

SCENE = Scene(speed=2.5, restitution=0.7, selection=ContactSelection.ALL)
PATHS = [pytest.param(True, marks=pytest.mark.skipif(find_compiler() is None, reason="no C compiler")), False]


def foot() -> Tree:
    """Thigh, shank, heel and three toes (one welded), five contacts, two of them on one rod."""
    return Tree(
        (
            Body("thigh", None, 0.7, 1.0, -1.2),
            Body("shank", 0, 0.7, 1.0, -0.6),
            Body("heel", 1, 0.15, 0.1, -0.8, contacts=(1.0,)),
            Body("toe1", 1, 0.3, 0.09, 1.5),
            Body("toe1_tip", 3, 0.15, 0.04, 0.3, contacts=(1.0,)),
            Body("toe2", 1, 0.25, 0.09, 1.2),
            Body("toe2_tip", 5, 0.15, 0.04, 0.5, contacts=(0.2, 1.0)),
            Body("toe3", 1, 0.2, 0.09, 1.0, joint=JointKind.FIXED),
            Body("toe3_tip", 7, 0.1, 0.04, 0.2, contacts=(1.0,)),
        )
    )


def _designs(seed: int, rows: int = 24) -> tuple[Tree, np.ndarray]:
    """``rows`` designs of :func:`foot`: angles +-0.1 rad, masses x exp(+-0.3), and the inner
    contact of toe 2 moved from its joint to 0.4 of the rod: Newton's law holds for the first
    rows and makes that contact pull for most of the last."""
    tree = foot()
    rng = np.random.default_rng(seed)
    n_body = len(BODY_VALUES)
    P = np.repeat(design_vector(tree)[None, :], rows, axis=0)
    P[:, BODY_VALUES.index("angle") : n_body * tree.n_bodies : n_body] += 0.1 * rng.standard_normal(
        (rows, tree.n_bodies)
    )
    P[:, BODY_VALUES.index("mass") : n_body * tree.n_bodies : n_body] *= np.exp(
        0.3 * rng.standard_normal((rows, tree.n_bodies))
    )
    P[:, n_body * tree.n_bodies + 2] = np.linspace(0.0, 0.4, rows)
    return tree, P


@pytest.mark.parametrize("seed, compiled", [
    pytest.param(0, True, marks=PATHS[0].marks, id="0-compiled"), pytest.param(0, False, id="0-vm"),
    pytest.param(1, True, marks=[*PATHS[0].marks, pytest.mark.slow], id="1-compiled"),
    pytest.param(1, False, id="1-vm"),
])  # seed 1 compiled to C (a second compile) with --slow
def test_rows_equal_evaluate_where_newton(compiled, seed, tmp_path) -> None:
    tree, P = _designs(seed)
    evaluator = batch_evaluator(tree.topology(), tmp_path if compiled else None, gradient=True)
    assert ("loop" in evaluator.path) == compiled
    out = evaluator(P, SCENE.speed, SCENE.restitution)
    grad = norms_gradient_function(tree.topology())
    v = approach_velocity(tree.topology(), SCENE.speed)
    for i, p in enumerate(P):
        result = evaluate(with_values(tree, p), SCENE)
        assert out.newton[i] == (result.model is ImpactModel.NEWTON and result.split_unique), i
        if not out.newton[i]:
            continue
        scale = max(1.0, float(np.abs(result.external).max()))
        np.testing.assert_allclose(
            out.external[i], result.external[list(result.active)], rtol=1e-11, atol=1e-12 * scale
        )
        np.testing.assert_allclose(out.internal_magnitude[i], result.internal_magnitude, rtol=1e-10, atol=1e-12 * scale)
        assert out.external_norm[i] == pytest.approx(result.external_norm, rel=1e-11)
        assert out.internal_norm[i] == pytest.approx(result.internal_norm, rel=1e-10)
        single = grad(p=p, v_minus=v, restitution=SCENE.restitution)
        for name in ("d_external_norm", "d_internal_norm"):
            ref = np.array(single[name]).ravel()
            np.testing.assert_allclose(getattr(out, name)[i], ref, rtol=1e-10, atol=1e-12 * np.abs(ref).max())
    assert out.newton.any() and not out.newton.all()  # both kinds of row were checked


@pytest.mark.parametrize("compiled", PATHS, ids=["compiled", "vm"])
def test_impulses_scale_with_speed_and_restitution(compiled, tmp_path) -> None:
    """External and joint impulses are linear in (1 + e) v (paper eq. 11 and the Newton-Euler
    pass); per-row speeds give what one call per speed gives."""
    tree, P = _designs(2)
    evaluator = batch_evaluator(tree.topology(), tmp_path if compiled else None)
    base = evaluator(P, 2.0, 0.5)
    same_product = evaluator(P, 3.0, 0.0)  # (1 + e) v = 3 in both
    faster = evaluator(P, 3.0, 0.5)
    rows = base.newton  # well-conditioned rows: rounding stays near 1e-16 relative
    assert rows.sum() >= 3
    for out, factor in ((faster, 1.5), (same_product, 1.0)):
        for name in ("external", "internal_magnitude", "external_norm", "internal_norm"):
            ref = factor * getattr(base, name)[rows]
            np.testing.assert_allclose(getattr(out, name)[rows], ref, rtol=1e-10, atol=1e-12 * np.abs(ref).max())
    speeds = np.where(np.arange(len(P)) % 2, 2.0, 3.0)
    mixed = evaluator(P, speeds, 0.5)
    np.testing.assert_array_equal(mixed.external[1::2], base.external[1::2])
    np.testing.assert_array_equal(mixed.external[::2], faster.external[::2])


@pytest.mark.parametrize(
    "change,message",
    [
        (lambda P: P[:, :-1], "p: must have"),
        (lambda P: _set(P, (1, 1), -1.0), "p[1]: body 0 mass"),
        (lambda P: _set(P, (2, 3), 1.5), "p[2]: body 0 at"),
        (lambda P: _set(P, (0, 2), np.nan), "p[0]: body 0 angle"),
        (lambda P: _set(P, (1, -1), 2.0), "p[1]: contact"),
    ],
)
def test_bad_designs_are_refused_naming_the_value(change, message) -> None:
    tree, P = _designs(3, rows=3)
    evaluator = batch_evaluator(tree.topology(), None)
    with pytest.raises(ModelError, match=message.replace("[", r"\[").replace("]", r"\]")):
        evaluator(change(P.copy()), 2.0, 0.5)


@pytest.mark.parametrize(
    "speed,restitution,message",
    [
        (0.0, 0.5, "speed: must be > 0"),
        (2.0, 1.5, "restitution: must be in"),
        ([1.0, 2.0], 0.5, "speed: must be one value or one per row"),
        ([1.0, np.inf, -1.0], 0.5, "speed: must be finite"),
        ([1.0, 2.0, -1.0], np.nan, "speed: must be > 0"),
        (2.0, [0.5, np.nan, 2.0], "restitution: must be finite"),
        (2.0, [0.5, 0.5], "restitution: must be one value or one per row"),
    ],
)
def test_bad_scene_values_are_refused(speed, restitution, message) -> None:
    tree, P = _designs(3, rows=3)
    with pytest.raises(ModelError, match=message.replace("[", r"\[")):
        batch_evaluator(tree.topology(), None)(P, speed, restitution)


@pytest.fixture(scope="module")
def compiled_foot(tmp_path_factory):
    """The compiled evaluator of :func:`foot` (its API driver, then the Python path on the same
    library for comparison)."""
    if find_compiler() is None:
        pytest.skip("no C compiler")
    tree = foot()
    fast = batch_evaluator(tree.topology(), tmp_path_factory.mktemp("batch_cache"))
    assert fast.run_api is not None
    return fast, replace(fast, run_api=None)


@pytest.mark.parametrize("rows", [1, 5, 203])
def test_api_driver_equals_the_python_path_bit_for_bit(compiled_foot, rows) -> None:
    """One C call (checks, approach, loop, flags) gives what the Python path gives on the same
    library, bit for bit: outputs, ``newton`` (both kinds of row) and ``failed`` (a row made
    not finite by a denormal mass), for shared and per-row speeds and restitutions."""
    fast, python = compiled_foot
    tree, P = _designs(4, rows=rows)
    if rows > 3:
        P[3, len(BODY_VALUES) * 4 + BODY_VALUES.index("mass")] = 1e-320
    rng = np.random.default_rng(rows)
    for speed, restitution in ((2.5, 0.7), (rng.uniform(1, 4, rows), 0.3), (1.5, rng.uniform(0, 1, rows))):
        a, b = fast(P, speed, restitution), python(P, speed, restitution)
        for name in ("external", "internal_magnitude", "external_norm", "internal_norm", "newton", "failed"):
            x, y = getattr(a, name), getattr(b, name)
            assert x.dtype == y.dtype and x.shape == y.shape, name
            assert x.tobytes() == y.tobytes(), name
    if rows == 203:
        assert a.newton.any() and not a.newton.all() and a.failed[3] and a.failed.sum() == 1


@pytest.mark.parametrize(
    "speed,restitution,message",
    [
        (0.0, 0.5, "speed: must be > 0"),
        (2.0, 1.5, "restitution: must be in"),
        (2.0, -0.0 - 1e-300, "restitution: must be in"),
        ([1.0, np.inf, -1.0], 0.5, "speed: must be finite"),
        ([1.0, 2.0, -1.0], np.nan, "speed: must be > 0"),
        (2.0, [0.5, np.nan, 2.0], "restitution: must be finite"),
        ([1.0, 2.0], 0.5, "speed: must be one value or one per row"),
    ],
)
def test_compiled_path_refuses_bad_scene_values_alike(compiled_foot, speed, restitution, message) -> None:
    tree, P = _designs(3, rows=3)
    with pytest.raises(ModelError, match=message):
        compiled_foot[0](P, speed, restitution)


def test_compiled_path_refuses_bad_designs_naming_the_value(compiled_foot) -> None:
    """The first bad value (row-major) is named, as on the virtual machine, also when the
    speed is bad too (the design is checked first)."""
    tree, P = _designs(3, rows=150)
    P[140, 2] = np.nan
    P[141, 1] = -1.0
    with pytest.raises(ModelError, match=r"p\[140\]: body 0 angle"):
        compiled_foot[0](P, -1.0, 0.5)
    P[140, 2] = 0.1
    with pytest.raises(ModelError, match=r"p\[141\]: body 0 mass"):
        compiled_foot[0](P, 2.0, 0.5)


def _set(P: np.ndarray, index: tuple[int, int], value: float) -> np.ndarray:
    P[index] = value
    return P


@pytest.mark.parametrize("name", [*BODY_VALUES, "contact"])
def test_value_bounds_are_what_validate_tree_enforces(name, tmp_path) -> None:
    """The batch check (in Python and in the compiled API driver) and ``validate_tree`` accept
    and refuse the same values at each bound (``VALUE_BOUNDS``): just inside, at the bound, just
    outside, infinities and NaN."""
    tree, P = _designs(6, rows=1)
    low, closed, high = VALUE_BOUNDS.get(name, CONTACT_BOUNDS)
    n_body = len(BODY_VALUES)
    col = n_body * tree.n_bodies if name == "contact" else n_body + BODY_VALUES.index(name)  # the shank's
    evaluator = batch_evaluator(tree.topology(), None)
    compiled = batch_evaluator(tree.topology(), tmp_path) if find_compiler() is not None else evaluator
    candidates = [v for v in (low, high) if np.isfinite(v)] + [np.nextafter(low, -np.inf), np.nan]
    candidates += [np.nextafter(low, np.inf), np.nextafter(high, -np.inf), np.inf, -np.inf]
    candidates += [np.nextafter(high, np.inf)] if np.isfinite(high) else []
    for value in candidates:
        row = P[0].copy()
        row[col] = value
        try:
            with_values(tree, row)
            tree_ok = True
        except ModelError:
            tree_ok = False
        for path in (evaluator, compiled):
            try:
                path(row, SCENE.speed, SCENE.restitution)
                batch_ok = True
            except ModelError:
                batch_ok = False
            assert batch_ok == tree_ok, (name, value, path.path)


def test_rows_that_are_not_finite_are_reported_and_never_newton() -> None:
    """A row whose outputs are not finite (here injected into the runner's outputs) is flagged
    ``failed`` and not ``newton``; the other rows are untouched."""
    from dataclasses import replace

    tree, P = _designs(0, rows=4)
    fast = batch_evaluator(tree.topology(), None)
    clean = fast(P, SCENE.speed, SCENE.restitution)

    def poisoned(*inputs: np.ndarray) -> list[np.ndarray]:
        outs = [o.copy() for o in fast.run_impact(*inputs)]
        outs[0][1, 0] = np.nan  # one external impulse of row 1
        outs[-1][0, 0] = np.inf  # and row 0's last output
        return outs

    out = replace(fast, run_impact=poisoned)(P, SCENE.speed, SCENE.restitution)
    assert clean.newton[0]  # so the flag below is tested on a row that was newton
    np.testing.assert_array_equal(out.failed, [True, True, False, False])
    assert not out.newton[out.failed].any()
    np.testing.assert_array_equal(out.newton[~out.failed], clean.newton[~out.failed])
    assert not clean.failed.any()
