"""Many workers on one study: ``footopt optimize --workers N`` on the run's journal file, and on a
real PostgreSQL server started here (several machines share such a storage): every trial asked
is told, none is duplicated, and the front is the one a single process computes from the same
trials. The server comes from the system's PostgreSQL (Debian's, installed by .ci/run)."""

from __future__ import annotations

import glob
import json
import os
import shutil
import socket
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import optuna
import pytest
from optuna.trial import TrialState

from optimizer.cli.main import main
from optimizer.config.study_config import load_study
from optimizer.results.pareto import non_dominated
from optimizer.results.runs import storage_url
from optimizer.search.outer import evaluate_designs, open_study, read_trial, run_outer
from tests.optimizer.conftest import TINY_OUTER_YAML

PASSWORD = "s3cret-pw"


def _check_study(run: Path, config_storage: str | None, target: int, workers: int) -> None:
    """No trial lost (every one told), none duplicated (numbers and values unique), at most
    workers - 1 beyond the target; the run's front = the front of the same trials recomputed."""
    config = load_study(run / "study.yaml")
    storage = config_storage or storage_url(run, config)
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    trials = open_study(config, storage).get_trials(deepcopy=False)
    assert all(t.state in (TrialState.COMPLETE, TrialState.FAIL) for t in trials)  # nothing left RUNNING
    assert target <= len(trials) <= target + workers - 1
    assert len({t.number for t in trials}) == len(trials)
    assert len({tuple(sorted(t.params.items())) for t in trials}) == len(trials)
    recorded = [r for r in map(read_trial, trials) if r is not None]
    again = evaluate_designs(config, [r.evaluation.design for r in recorded])  # one process, same designs
    feasible = [(r.number, e) for r, e in zip(recorded, again, strict=True) if e.feasible]
    values = np.array([[e.objectives.value(o) for o in config.objectives] for _, e in feasible])
    expected = sorted(feasible[i][0] for i in non_dominated(values))
    front = json.loads((run / "pareto.json").read_text(encoding="utf-8"))
    assert sorted(d["trial"] for d in front["designs"]) == expected


def test_two_workers_share_the_journal_file(tmp_path: Path, capsys):
    study = tmp_path / "w.yaml"
    study.write_text(TINY_OUTER_YAML.replace("trials: 12", "trials: 16"), encoding="utf-8")
    assert main(["optimize", str(study), "--out", str(tmp_path / "run"), "--workers", "2", "--quiet"]) == 0
    _check_study(tmp_path / "run", None, 16, 2)


@pytest.mark.parametrize("burst_after", [1, 2, 3, 4])
def test_a_worker_counts_finished_and_in_flight_trials_in_one_read(tmp_path: Path, burst_after: int):
    """Another worker tells its 8 trials at once, just after this worker's ``burst_after``-th read
    of the storage: whichever read that is, this worker asks for at most the 2 the target of 10
    lacks, plus 1 (workers - 1). Two reads for the finished and in-flight counts would see the 8
    in neither state and ask for 5 more."""
    study_file = tmp_path / "w.yaml"
    study_file.write_text(TINY_OUTER_YAML, encoding="utf-8")
    config = load_study(study_file)
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = open_study(config, optuna.storages.InMemoryStorage())
    others = [study.ask() for _ in range(8)]
    reads = []

    def get_trials(*args, **kwargs):
        found = optuna.Study.get_trials(study, *args, **kwargs)
        reads.append(1)
        while len(reads) == burst_after and others:
            study.tell(others.pop(), state=TrialState.FAIL)
        return found

    study.get_trials = get_trials
    ran = run_outer(study, config, 10, None, workers=2)
    assert not others and 2 <= ran <= 3 and len(optuna.Study.get_trials(study)) == 8 + ran


def test_workers_need_the_outer_search(tmp_path: Path, capsys):
    from tests.optimizer.conftest import TINY_STUDY_YAML

    study = tmp_path / "inner.yaml"
    study.write_text(TINY_STUDY_YAML, encoding="utf-8")
    assert main(["optimize", str(study), "--out", str(tmp_path / "run"), "--workers", "2"]) == 2
    assert "--workers: the inner search runs in one process" in capsys.readouterr().err


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def postgres() -> str:
    """A PostgreSQL server of the system's binaries in a fresh folder, on a free port; its URL."""
    pytest.importorskip("psycopg", reason="psycopg is a dependency of footopt[postgres] and the tests")
    found = sorted(glob.glob("/usr/lib/postgresql/*/bin/initdb")) or [shutil.which("initdb") or ""]
    initdb = Path(found[-1])
    if not initdb.is_file():
        pytest.skip("no PostgreSQL server binaries here (apt-get install postgresql; .ci/run does)")
    as_postgres = ["runuser", "-u", "postgres", "--"] if os.geteuid() == 0 else []  # initdb refuses root
    folder = Path(tempfile.mkdtemp(prefix="footopt-pg-"))
    data = folder / "data"
    if as_postgres:
        shutil.chown(folder, "postgres")
        folder.chmod(0o755)
    port = _free_port()
    run = lambda *cmd: subprocess.run([*as_postgres, *map(str, cmd)], check=True, capture_output=True, timeout=120)
    run(initdb, "-D", data, "-A", "trust", "-U", "postgres", "--no-sync")
    run(initdb.parent / "pg_ctl", "-D", data, "-w", "-l", folder / "log", "-o",
        f"-p {port} -k {folder} -c listen_addresses=127.0.0.1 -c fsync=off", "start")
    try:
        run(initdb.parent / "createdb", "-h", "127.0.0.1", "-p", port, "-U", "postgres", "footopt")
        yield f"postgresql://postgres:{PASSWORD}@127.0.0.1:{port}/footopt"
    finally:
        run(initdb.parent / "pg_ctl", "-D", data, "-m", "immediate", "stop")
        shutil.rmtree(folder, ignore_errors=True)


def test_four_workers_on_postgresql(postgres: str, tmp_path: Path, capsys):
    """4 workers on a real PostgreSQL storage: nothing lost or duplicated, the same front as one
    process on the same trials; the storage's password is nowhere in the output or the run folder."""
    study = tmp_path / "pg.yaml"
    study.write_text(TINY_OUTER_YAML, encoding="utf-8")  # 12 trials
    run = tmp_path / "run"
    assert main(["optimize", str(study), "--out", str(run), "--workers", "4", "--storage", postgres]) == 0
    out, err = capsys.readouterr()
    assert PASSWORD not in out + err
    for f in run.rglob("*"):
        if f.is_file():
            assert PASSWORD.encode() not in f.read_bytes(), f
    _check_study(run, postgres, 12, 4)

