"""Forked worker pools (:mod:`optimizer.workers`): results in the order asked whatever order the
workers finish in, and an error (a Ctrl-C among them) stops the workers at once."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest

from optimizer.workers import forked_pool, mapped


def _slow_square(x: float) -> float:
    time.sleep(0.2 * (3 - x))  # the first items finish last
    return x * x


def _sleep_then_mark(folder: str) -> None:
    Path(folder, f"{os.getpid()}.started").touch()
    time.sleep(15.0)
    Path(folder, f"{os.getpid()}.finished").touch()


_LATER: list[str] = []


def _later() -> list[str]:
    return list(_LATER)


def test_the_workers_fork_as_the_pool_opens():
    """Not at the first job: what this process does after opening the pool (here a list filled;
    in a search, a background compiler's thread started) does not reach the workers."""
    with forked_pool(2) as pool:
        if pool is None:
            pytest.skip("no fork on this platform")
        _LATER.append("after the fork")
        try:
            assert pool.submit(_later).result() == []
        finally:
            _LATER.clear()


def test_mapped_keeps_the_order_asked_and_tells_progress_in_it():
    told: list[tuple[int, int]] = []
    with forked_pool(3) as pool:
        if pool is None:
            pytest.skip("no fork on this platform")
        assert mapped(pool, _slow_square, [0, 1, 2, 3], lambda d, n: told.append((d, n))) == [0, 1, 4, 9]
    assert told == [(1, 4), (2, 4), (3, 4), (4, 4)]
    assert mapped(None, _slow_square, [3, 2]) == [9, 4]


def test_an_error_inside_a_forked_pool_stops_its_workers_at_once(tmp_path: Path):
    """A Ctrl-C while the workers run (a whole landing can take minutes): leaving the pool does
    not wait for them to finish their jobs."""
    with pytest.raises(KeyboardInterrupt):
        with forked_pool(2) as pool:
            if pool is None:
                pytest.skip("no fork on this platform")
            futures = [pool.submit(_sleep_then_mark, str(tmp_path)) for _ in range(2)]
            deadline = time.time() + 30
            while len(list(tmp_path.glob("*.started"))) < 2 and time.time() < deadline:
                time.sleep(0.05)
            raise KeyboardInterrupt
    assert len(list(tmp_path.glob("*.started"))) == 2
    assert not list(tmp_path.glob("*.finished"))  # left without awaiting them (it would have taken 15 s)
    assert all(f.done() for f in futures)
