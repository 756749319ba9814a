"""The inner whole-landing search's shapes in forked workers (optimizer.search.landing_workers): the
trials one process records, in its order; a Ctrl-C keeps the designs a worker finished."""

from __future__ import annotations

import os
import signal
import threading
import time

import optuna
import pytest

import optimizer.search.landing_inner as landing_inner
import optimizer.search.landing_workers as landing_workers
from optimizer.config.study_config import load_study
from optimizer.search.inner import ATTR_SHAPE, run_inner, shape_done_key
from optimizer.search.outer import open_study
from tests.optimizer.test_landing_study import TINY_LANDING_YAML

#: Two shapes (one toe, two toes), one start, no front points, IPOPT cut to one iteration per solve.
TWO_SHAPES = (TINY_LANDING_YAML.replace("duration: 0.02", "duration: 0.003")
              .replace("search: {method: outer, trials: 6, startup_trials: 6, landing_tolerance: 1.0e-2}",
                       "search: {method: inner, inner: {starts: 1, front_points: 0}, landing_tolerance: 1.0e-2}"))


@pytest.fixture
def config(tmp_path, monkeypatch):
    monkeypatch.setitem(landing_inner.LANDING_IPOPT, "ipopt.max_iter", 1)
    path = tmp_path / "two_shapes.yaml"
    path.write_text(TWO_SHAPES, encoding="utf-8")
    config = load_study(path)
    assert len(config.space.shapes()) == 2
    return config


def _trials(study: optuna.Study) -> list:
    return [(t.params, t.values, t.user_attrs) for t in study.trials]


class _Late:
    """A worker's inbox whose designs reach the parent 0.3 s after the worker sent them (after its
    sweep's future is done): the parent must wait for every design its future counts."""

    def __init__(self, inbox) -> None:
        self.inbox = inbox

    def put(self, item) -> None:
        threading.Timer(0.3, self.inbox.put, (item,)).start()


def test_two_workers_record_what_one_process_records(config, monkeypatch):
    """The same trials in the same order, with two workers whose designs arrive late."""
    runs = []
    for workers in (1, 2):
        study = open_study(config, optuna.storages.InMemoryStorage())
        assert run_inner(study, config, workers=workers) == 2
        runs.append(_trials(study))
        monkeypatch.setattr(landing_workers, "_start", lambda inbox: landing_workers._WORKER.update(inbox=_Late(inbox)))
    assert {t[2][ATTR_SHAPE] for t in runs[0]} == {s.label for s in config.space.shapes()}  # designs of both
    assert runs[1] == runs[0]


def test_a_ctrl_c_keeps_the_designs_a_worker_finished(config, tmp_path, monkeypatch):
    """The first shape's worker waits until the second shape's worker has swept it, then sends the
    parent a SIGINT: the parent, waiting for the first shape's designs, records the second's
    (without marking it done) before it stops; the resumed run then records what an
    uninterrupted run does."""
    first, second = sorted(config.space.shapes(), key=lambda s: s.n_toes)
    flag = tmp_path / "second_done"
    real = landing_workers.shape_designs

    def designs(config, shape):
        if shape == second:
            yield from real(config, shape)
            flag.write_text("done")
            return
        while not flag.exists():
            time.sleep(0.05)
        os.kill(os.getppid(), signal.SIGINT)
        time.sleep(60)  # the parent stops this worker
        yield from ()

    monkeypatch.setattr(landing_workers, "shape_designs", designs)
    study = open_study(config, optuna.storages.InMemoryStorage())
    with pytest.raises(KeyboardInterrupt):
        run_inner(study, config, workers=2)
    kept = _trials(study)
    assert kept and {t[2][ATTR_SHAPE] for t in kept} == {second.label}
    assert not study.user_attrs.get(shape_done_key(second)) and not study.user_attrs.get(shape_done_key(first))

    monkeypatch.setattr(landing_workers, "shape_designs", real)
    assert run_inner(study, config, workers=1) == 2
    whole = open_study(config, optuna.storages.InMemoryStorage())
    run_inner(whole, config, workers=1)
    key = sorted  # the same trials; the kept ones first
    assert key(map(repr, _trials(study))) == key(map(repr, _trials(whole)))
    assert len(study.trials) == len(whole.trials)
