"""Dependency direction (STYLE.md): impulse_core needs casadi and numpy only. Importing any core
module in a fresh interpreter must not bring in YAML, optuna, scipy, matplotlib or cvxpy."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
CORE_MODULES = [
    "impulse_core",
    "impulse_core.model.tree",
    "impulse_core.model.rods",
    "impulse_core.kinematics.spatial",
    "impulse_core.kinematics.dynamics",
    "impulse_core.impact.delassus",
    "impulse_core.impact.nnls",
    "impulse_core.errors",
    "impulse_core.evaluate",
    "impulse_core.impact.laws",
    "impulse_core.compile.codegen",
    "impulse_core.compile.batch",
    "impulse_core.timedomain.landing",  # scipy's Rotation: imported in its re-chart only
]
FORBIDDEN = ["yaml", "optuna", "scipy", "matplotlib", "cvxpy"]


def _imported_after(statement: str) -> list[str]:
    code = (
        "import json, sys\n"
        f"{statement}\n"
        f"print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in {FORBIDDEN!r})))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("module", CORE_MODULES)
def test_core_module_imports_no_heavy_dependency(module):
    assert _imported_after(f"import {module}") == []


def test_evaluating_a_design_imports_no_heavy_dependency():
    """Not only the import: building and running a compiled model (every rung of the impact-model
    ladder, friction included) stays within casadi + numpy."""
    statement = (
        "from impulse_core.model.tree import Body, Tree, Scene\n"
        "from impulse_core.evaluate import evaluate\n"
        "t = Tree((Body('a', None, 1.0, 1.0, 0.0, contacts=(0.0, 0.5, 1.0)),))\n"
        "r = evaluate(t, Scene())\n"
        "assert r.external.sum() > 0\n"
        "from impulse_core.impact.laws import ImpactModel\n"
        "for m in ImpactModel:\n"
        "    assert evaluate(t, Scene(friction=0.5), m).model is m"
    )
    assert _imported_after(statement) == []


def test_the_check_can_fail():
    """Control: the same probe does see scipy when it is imported."""
    assert "scipy" in _imported_after("import scipy.optimize")
