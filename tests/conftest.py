"""Shared fixtures: seeded random planar trees, contact-set conditioning, a run report.

``tests/`` is a package (``tests/__init__.py``) so that test modules import their helpers as
``tests.conftest``, ``tests.planar_numpy`` and ``tests.pinocchio_reference`` without clashing with
same-named test files elsewhere (e.g. ``tests/impulse_core`` vs the real ``impulse_core``).
``tests/`` itself is appended to ``sys.path`` (last, so that ``tests/impulse_core`` never shadows
the real ``impulse_core``) so that a plain ``import pinocchio_reference`` works from any test
directory; the repository root goes first so that the packages import without installation.
"""

from __future__ import annotations

import json
import math
import sys
import zlib
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest

TESTS = Path(__file__).resolve().parent
if str(TESTS.parent) not in sys.path:
    sys.path.insert(0, str(TESTS.parent))
if str(TESTS) not in sys.path:
    sys.path.append(str(TESTS))

from impulse_core.model.tree import (  # noqa: E402
    UNIFORM_COM,
    UNIFORM_GYRATION,
    Body,
    JointKind,
    Tree,
)
from tests import planar_numpy as pn  # noqa: E402


# --------------------------------------------------------------------------------------------
# Random trees
# --------------------------------------------------------------------------------------------
def log_uniform(rng: np.random.Generator, low: float, high: float, size=None):
    return np.exp(rng.uniform(np.log(low), np.log(high), size))


def random_tree(
    rng: np.random.Generator,
    n_bodies: int,
    *,
    p_fixed: float = 0.25,
    mass_ratio: float = 20.0,
    length_range: tuple[float, float] = (0.05, 1.0),
    p_contact: float = 0.6,
    max_contacts_per_body: int = 1,
    uniform: bool = False,
    chain: bool = False,
) -> Tree:
    """A random floating planar tree of rods.

    Args:
        rng: the (seeded) generator; the tree is a deterministic function of its state.
        n_bodies: number of rods (>= 1); body 0 is the floating base.
        p_fixed: probability that a non-base body is welded (fixed joint) to its parent.
        mass_ratio: masses are log-uniform in [1, mass_ratio] kg (so max/min <= mass_ratio).
        length_range: lengths are log-uniform in this range (m).
        p_contact: probability that a body carries contacts (at least one body always does).
        max_contacts_per_body: each body with contacts gets 1..this many, at random fractions.
        uniform: uniform rods (com 0.5, gyration 1/sqrt(12)) instead of random com/gyration.
        chain: each body hangs from the previous one (a serial chain) instead of a random parent.
    """
    lengths = log_uniform(rng, *length_range, n_bodies)
    masses = log_uniform(rng, 1.0, max(mass_ratio, 1.0 + 1e-12), n_bodies)
    has_contacts = rng.random(n_bodies) < p_contact
    if not has_contacts.any():
        has_contacts[rng.integers(n_bodies)] = True
    bodies = []
    for i in range(n_bodies):
        parent = None if i == 0 else (i - 1 if chain else int(rng.integers(0, i)))
        joint = JointKind.FIXED if (i > 0 and rng.random() < p_fixed) else JointKind.REVOLUTE
        n_c = int(rng.integers(1, max_contacts_per_body + 1)) if has_contacts[i] else 0
        bodies.append(
            Body(
                name=f"b{i}",
                parent=parent,
                length=float(lengths[i]),
                mass=float(masses[i]),
                angle=float(rng.uniform(-math.pi, math.pi)),
                at=float(rng.uniform(0.0, 1.0)),
                joint=joint,
                contacts=tuple(float(c) for c in rng.uniform(0.0, 1.0, n_c)),
                com=UNIFORM_COM if uniform else float(rng.uniform(0.0, 1.0)),
                gyration=UNIFORM_GYRATION if uniform else float(rng.uniform(0.05, 0.6)),
            )
        )
    return Tree(tuple(bodies))


def redraw_values(
    rng: np.random.Generator,
    tree: Tree,
    *,
    mass_ratio: float = 20.0,
    length_range: tuple[float, float] = (0.05, 1.0),
    uniform: bool = False,
) -> Tree:
    """The same topology (parents, joints, contact counts) with fresh random values: lets a test
    reuse one compiled CasADi function for many designs."""
    n = tree.n_bodies
    bodies = []
    for i, b in enumerate(tree.bodies):
        bodies.append(
            Body(
                name=b.name,
                parent=b.parent,
                joint=b.joint,
                length=float(log_uniform(rng, *length_range)),
                mass=float(log_uniform(rng, 1.0, max(mass_ratio, 1.0 + 1e-12))),
                angle=float(rng.uniform(-math.pi, math.pi)),
                at=float(rng.uniform(0.0, 1.0)),
                contacts=tuple(float(c) for c in rng.uniform(0.0, 1.0, len(b.contacts))),
                com=UNIFORM_COM if uniform else float(rng.uniform(0.0, 1.0)),
                gyration=UNIFORM_GYRATION if uniform else float(rng.uniform(0.05, 0.6)),
            )
        )
    assert len(bodies) == n
    return Tree(tuple(bodies))


def contact_independence(tree: Tree, active: tuple[int, ...] | None = None) -> tuple[bool, float]:
    """Whether the active contacts' normals are independent, and the condition number of the
    column-normalised normal Jacobian (rows: contacts; columns scaled to unit norm so that the
    answer does not depend on the units of the DOFs). Computed with the numpy model, not the core.
    """
    pl = pn.place(tree)
    J = pn.normal_jacobian(tree, pl, active)
    scale = np.linalg.norm(J, axis=0)
    scale[scale == 0] = 1.0
    s = np.linalg.svd(J / scale, compute_uv=False)
    if s.size < J.shape[0] or s.min() <= 1e-12 * s.max():
        return False, math.inf
    return True, float(s.max() / s.min())


def delassus_condition(tree: Tree, active: tuple[int, ...] | None = None) -> float:
    """Condition number of the Jacobi-scaled Delassus matrix D^-1/2 A D^-1/2, A = J M^-1 J^T
    (numpy model). This, not the normalised Jacobian's condition, bounds the digits an impulse
    solve keeps: a contact a few millimetres from a light body's joint has a well-normalised
    Jacobian row but is nearly dependent on its neighbours in the metric of M^-1."""
    pl = pn.place(tree)
    J = pn.normal_jacobian(tree, pl, active)
    A = J @ np.linalg.solve(pn.mass_matrix(tree, pl), J.T)
    d = 1.0 / np.sqrt(np.diag(A))
    return float(np.linalg.cond(A * d[:, None] * d[None, :]))


def mirrored(tree: Tree) -> Tree:
    """The mirror image about the vertical line through the base origin (every angle negated,
    the base's measured from the -x axis: theta -> pi - theta)."""
    bodies = [
        Body(
            name=b.name,
            parent=b.parent,
            length=b.length,
            mass=b.mass,
            angle=(math.pi - b.angle) if b.parent is None else -b.angle,
            at=b.at,
            joint=b.joint,
            contacts=b.contacts,
            com=b.com,
            gyration=b.gyration,
        )
        for b in tree.bodies
    ]
    return Tree(tuple(bodies))


def relative_error(a, b, scale=None) -> float:
    """||a - b|| / scale (default ||b||, or 1 where b is zero)."""
    a = np.asarray(a, dtype=float).ravel()
    b = np.asarray(b, dtype=float).ravel()
    if scale is None:
        scale = np.linalg.norm(b)
    return float(np.linalg.norm(a - b) / (scale if scale > 0 else 1.0))


# --------------------------------------------------------------------------------------------
# Fixtures
# --------------------------------------------------------------------------------------------
@pytest.fixture
def rng(request) -> np.random.Generator:
    """A generator seeded from the test's node id: reproducible and different per test."""
    return np.random.default_rng(zlib.crc32(request.node.nodeid.encode()))


def leg_with_heel_and_toe(uniform: bool = True) -> Tree:
    """Thigh (base), knee, shank; at the ankle the heel rod (contact at its tip) and a two-link toe
    chain (contact at the last tip): the structure of the paper's case 2 (ERRATA.md). Lengths,
    masses and angles are illustrative (the paper's Table 4 is lost), not the paper's design."""
    com = UNIFORM_COM if uniform else 0.4
    gyr = UNIFORM_GYRATION if uniform else 0.35
    return Tree(
        (
            Body("thigh", None, 0.7, 1.0, -1.4, com=com, gyration=gyr),
            Body("shank", 0, 0.7, 1.0, -0.3, com=com, gyration=gyr),
            Body("heel", 1, 0.1, 0.1, -1.14, contacts=(1.0,), com=com, gyration=gyr),
            Body("toe1", 1, 0.3, 0.25, 1.4, com=com, gyration=gyr),
            Body("toe2", 3, 0.15, 0.15, -0.4, contacts=(1.0,), com=com, gyration=gyr),
        )
    )


@pytest.fixture
def leg() -> Tree:
    return leg_with_heel_and_toe()


# --------------------------------------------------------------------------------------------
# Slow cases: a test's further parametrizations (``@pytest.mark.slow``), run with ``--slow``
# --------------------------------------------------------------------------------------------
def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--slow", action="store_true",
                     help="also run the cases marked slow (a test's further parametrizations)")


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "slow: a further case of a test whose first runs by default; run with --slow")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Without ``--slow`` the cases marked slow are skipped (each test keeps a case by default)."""
    if config.getoption("--slow"):
        return
    skip = pytest.mark.skip(reason="slow case: run with --slow")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)


# --------------------------------------------------------------------------------------------
# Report: tests record what they measured; it is printed at the end of the run.
# --------------------------------------------------------------------------------------------
REPORT: dict[str, list[str]] = defaultdict(list)


def report(section: str, line: str) -> None:
    """Record a line for the end-of-run summary (counts, worst errors, flagged cases)."""
    REPORT[section].append(line)


def pytest_sessionfinish(session, exitstatus):
    """An xdist worker hands its report lines to the controller (printed there)."""
    workeroutput = getattr(session.config, "workeroutput", None)
    if workeroutput is not None:
        workeroutput["footopt_report"] = json.dumps(REPORT)


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node, error):
    """The controller gathers each xdist worker's report lines as the worker ends."""
    for section, lines in json.loads(getattr(node, "workeroutput", {}).get("footopt_report", "{}")).items():
        REPORT[section].extend(lines)


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    if not REPORT:
        return
    terminalreporter.section("impulse_core measurements")
    for section, lines in REPORT.items():
        terminalreporter.write_line(f"[{section}]")
        for line in lines:
            terminalreporter.write_line(f"  {line}")


__all__ = [
    "contact_independence",
    "delassus_condition",
    "leg_with_heel_and_toe",
    "log_uniform",
    "mirrored",
    "random_tree",
    "redraw_values",
    "relative_error",
    "report",
]
