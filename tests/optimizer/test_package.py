"""The package as a user gets it: a wheel built from the repository, installed outside it, runs
the README's commands on the files it ships (``footopt init``, the default study)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from optimizer.cli.init import STARTERS
from optimizer.cli.main import main

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> tuple[Path, dict[str, str]]:
    """The wheel, built without network (--no-isolation) and installed into its own folder;
    the environment that puts that folder first on the path."""
    root = tmp_path_factory.mktemp("wheel")
    subprocess.run([sys.executable, "-m", "build", "--wheel", "--no-isolation", "-o", str(root / "dist"), str(REPO)],
                   check=True, capture_output=True, cwd=root)
    wheel = next((root / "dist").glob("footopt-*.whl"))
    site = root / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-index", "--target",
                    str(site), str(wheel)], check=True, capture_output=True)
    env = {**os.environ, "PYTHONPATH": str(site), "MPLBACKEND": "Agg"}
    return site, env


def _run(site: Path, env: dict[str, str], cwd: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([str(site / "bin" / "footopt"), *args], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=600)


def test_the_installed_wheel_runs_the_readme_commands_outside_the_repo(installed, tmp_path):
    site, env = installed
    where = subprocess.run([sys.executable, "-c", "import optimizer; print(optimizer.__file__)"], cwd=tmp_path,
                           env=env, capture_output=True, text=True, check=True).stdout
    assert Path(where.strip()).is_relative_to(site)  # the wheel's copy, not the repository's
    done = _run(site, env, tmp_path, "init", "starter")
    assert done.returncode == 0, done.stderr
    assert sorted(p.name for p in (tmp_path / "starter").iterdir()) == sorted(STARTERS)
    done = _run(site, env, tmp_path, "optimize", "--out", "quick", "--quiet")  # the shipped default study
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "quick" / "pareto.csv").read_text(encoding="utf-8").count("\n") >= 2
    done = _run(site, env, tmp_path, "evaluate", "--json", "starter/paper_case3.yaml")
    assert done.returncode == 0 and '"external_norm"' in done.stdout, done.stderr
    assert (REPO / "LICENSE").read_text(encoding="utf-8").startswith("MIT License")


def test_init_refuses_to_overwrite_without_force(tmp_path, capsys):
    assert main(["init", str(tmp_path)]) == 0
    mine = tmp_path / STARTERS[0]
    mine.write_text("# my study\n", encoding="utf-8")
    assert main(["init", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert str(mine) in err and "--force" in err and "\n" == err[-1] and err.count("\n") == 1
    assert mine.read_text(encoding="utf-8") == "# my study\n"  # nothing written
    assert main(["init", str(tmp_path), "--force"]) == 0
    assert mine.read_text(encoding="utf-8") == (REPO / "configs" / STARTERS[0]).read_text(encoding="utf-8")
