"""``footopt``'s start-up: every command line pays for what ``optimizer.cli.main`` imports, so
the heavy modules load only where they are used (SciPy's rotations in a landing's re-chart, its
``linprog`` in the design space's lengths, the bench, the study files, the plots and the
searches). A fresh interpreter must not bring them in for the import, ``--help`` or
``evaluate`` of an impact model."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from importlib import metadata
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
#: Top-level packages kept off the command line's import path.
HEAVY_PACKAGES = ("scipy", "optuna", "matplotlib", "plotly", "cvxpy", "sqlalchemy", "pinocchio", "mujoco")
#: footopt's own modules that import the design space or more, kept off it too.
HEAVY_MODULES = ("optimizer.design_space", "optimizer.analysis.bench", "optimizer.config.study_config")


def _heavy_after(statement: str) -> list[str]:
    code = (
        "import json, sys\n"
        f"{statement}\n"
        f"print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in {HEAVY_PACKAGES!r} "
        f"or m in {HEAVY_MODULES!r})))\n"
    )
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=REPO, env=env, capture_output=True, text=True, check=True, timeout=300
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def _cli(args: list[str]) -> str:
    """``main(args)`` in the probe's interpreter, its output swallowed and its exit status checked."""
    return (
        "import contextlib, io\n"
        "from optimizer.cli.main import main\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        "    try:\n"
        f"        status = main({args!r})\n"
        "    except SystemExit as e:\n"
        "        status = e.code\n"
        "assert status == 0, status"
    )


def test_importing_the_cli_imports_nothing_heavy() -> None:
    assert _heavy_after("import optimizer.cli.main") == []


@pytest.mark.parametrize(
    "args",
    [
        ["--help"],
        ["evaluate", "--help"],
        ["evaluate", "--json", "configs/paper_case3.yaml", "configs/spatial_case3.yaml"],
    ],
    ids=["help", "evaluate help", "evaluate"],
)
def test_running_the_cli_imports_nothing_heavy(args: list[str]) -> None:
    assert _heavy_after(_cli(args)) == []


@pytest.mark.parametrize("module", ["optimizer.design_space", "optimizer.analysis.bench", "optimizer.config.study_config"])
def test_the_design_space_imports_no_heavy_package(module: str) -> None:
    """One step further out (``evaluate --landings``, ``optimize``, ``bench``): scipy's ``linprog``
    loads when the design space assigns lengths, not on import."""
    assert [m for m in _heavy_after(f"import {module}") if m not in HEAVY_MODULES] == []


def test_the_check_can_fail() -> None:
    """Control: the same probe sees a heavy module once something imports it."""
    assert "scipy.spatial.transform" in _heavy_after("import optimizer.cli.main\nimport scipy.spatial.transform")
    assert "optimizer.design_space" in _heavy_after("import optimizer.design_space")


def test_the_moved_names_are_importable_where_they_were() -> None:
    """``SCALING_SIZES`` and ``redact_url`` live in light modules; their old homes still export them."""
    from optimizer.analysis import bench, sizes
    from optimizer.config import redact, study_config

    assert bench.SCALING_SIZES is sizes.SCALING_SIZES == (5, 10, 20, 50, 100, 200)
    assert study_config.redact_url is redact.redact_url
    assert study_config.redact_url("postgresql://me:secret@host/db") == "postgresql://me:***@host/db"


def test_version_is_looked_up_when_asked() -> None:
    """``--version`` still prints the installed version (looked up only then)."""
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    out = subprocess.run(
        [sys.executable, "-m", "optimizer", "--version"], cwd=REPO, env=env, capture_output=True, text=True, timeout=120
    )
    try:
        expected = metadata.version("footopt")
    except metadata.PackageNotFoundError:
        expected = "(not installed)"
    assert (out.returncode, out.stdout, out.stderr) == (0, f"footopt {expected}\n", "")
