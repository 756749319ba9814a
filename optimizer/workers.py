"""Forked worker processes for the work of one run that splits into independent pieces (the
inner search's shapes, the front's drawings, whole landings of a batch of designs or of a design's
scenarios): as many as the cores this process may run on, or
``FOOTOPT_WORKERS`` (1: everything in this process). Workers leave Ctrl-C to the parent; results
come back in the order asked, so a run's files do not depend on the number of workers."""

from __future__ import annotations

import multiprocessing
import os
import signal
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager
from typing import Any, TypeVar

T = TypeVar("T")

#: Overrides the number of worker processes (an integer >= 1).
WORKERS_ENV = "FOOTOPT_WORKERS"


def cores() -> int:
    """Worker processes to use: ``FOOTOPT_WORKERS``, else the cores this process may run on."""
    value = os.environ.get(WORKERS_ENV, "").strip()
    if value:
        return max(1, int(value))
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


@contextmanager
def forked_pool(
    workers: int, setup: Callable[..., None] | None = None, setup_args: tuple = ()
) -> Iterator[ProcessPoolExecutor | None]:
    """A pool of ``workers`` forked processes (they inherit what this process has imported and
    set up), or None when ``workers`` <= 1 or the platform cannot fork. Each worker first calls
    ``setup(*setup_args)``: the arguments reach it by the fork, not pickled (objects that cannot
    be pickled, such as CasADi functions, pass). On leaving, queued jobs are cancelled and running
    ones awaited; leaving on an error (a Ctrl-C among them) stops the workers at once instead (a
    whole landing can run for minutes, and its result would be thrown away)."""
    if workers <= 1 or "fork" not in multiprocessing.get_all_start_methods():
        yield None
        return
    context = multiprocessing.get_context("fork")
    pool = ProcessPoolExecutor(workers, mp_context=context, initializer=_start, initargs=(setup, setup_args))
    try:
        # fork every worker now (a fork context's first job starts them all): a thread this process
        # starts later (a search's background compiler in CasADi's code) could hold a lock at the
        # fork that the child would then wait on forever
        pool.submit(int).result()
        yield pool
    except BaseException:
        for process in list((getattr(pool, "_processes", None) or {}).values()):  # no public handle on them
            process.terminate()
        raise
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def mapped(pool: ProcessPoolExecutor | None, function: Callable[[Any], T], items: Iterable[Any],
           progress: Callable[[int, int], None] | None = None) -> list[T]:
    """``[function(x) for x in items]``, in ``pool``'s workers (here when ``pool`` is None), in
    the order of ``items`` whatever order they finish in; ``progress(done, of)`` after each, in
    that order. ``function`` and the items are pickled: a module-level function (or a partial of
    one) and plain data."""
    items = list(items)
    futures = None if pool is None else [pool.submit(function, x) for x in items]
    results: list[T] = []
    try:
        for i, x in enumerate(items):
            results.append(function(x) if futures is None else futures[i].result())
            if progress is not None:
                progress(len(results), len(items))
        return results
    finally:
        for future in futures or ():
            future.cancel()


def _start(setup: Callable[..., None] | None, args: tuple) -> None:
    """A worker's start: leave Ctrl-C to the parent, then ``setup(*args)``."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if setup is not None:
        setup(*args)


__all__ = ["WORKERS_ENV", "cores", "forked_pool", "mapped"]
