"""The inner whole-landing search's shapes swept in forked workers (:mod:`optimizer.workers`), their
designs streamed back as each is found and handed out shape by shape in the serial order.

A shape's sweep (:func:`optimizer.search.landing_inner.landing_sweep`: IPOPT solves that land the
design at every iterate) takes minutes, so each worker sweeps one shape at a time and sends every
feasible design to the parent as soon as it is realised. The parent records the designs of the
shape it is at as they come, and keeps those of later shapes until their turn: the trials are
recorded in the order one process records them, whatever the number of workers (every shape's
sweep depends on the study's seed and the shape only). Leaving on an error or a Ctrl-C, the designs
received and not yet recorded are given to ``keep`` first (recorded without marking their shape
done: a resumed run sweeps that shape again and skips them), so nothing a worker finished is lost.
"""

from __future__ import annotations

import multiprocessing
import queue
from collections.abc import Callable, Iterator
from concurrent.futures import Future
from contextlib import contextmanager

from optimizer.config.study_config import StudyConfig
from optimizer.design_space import DesignEvaluation, FootShape
from optimizer.workers import cores, forked_pool

#: How long (s) the parent waits for a design before it looks at the workers' futures again.
POLL = 0.2

#: Records the designs a shape's sweep found so far (its first ones, in order) without marking it done.
Keep = Callable[[FootShape, list[DesignEvaluation]], None]


def shape_designs(config: StudyConfig, shape: FootShape) -> Iterator[DesignEvaluation]:
    """One shape's sweep: its feasible designs in order, each as it is found."""
    from optimizer.search.inner import shape_seed
    from optimizer.search.landing_inner import build_landing_nlp, landing_sweep

    return landing_sweep(build_landing_nlp(config, shape), shape_seed(config.seed, shape))


class _Serial:
    """Every shape swept here, when it is asked for."""

    def __init__(self, config: StudyConfig) -> None:
        self.config = config

    def designs(self, shape: FootShape) -> Iterator[DesignEvaluation]:
        return shape_designs(self.config, shape)


class _Streamed:
    """The shapes' sweeps running in workers (``futures``: each returns its number of designs),
    their designs arriving on ``inbox`` as (shape's index, design)."""

    def __init__(self, shapes: list[FootShape], futures: list[Future], inbox: multiprocessing.Queue) -> None:
        self.shapes, self.futures, self.inbox = shapes, futures, inbox
        self.received: list[list[DesignEvaluation]] = [[] for _ in shapes]
        self.handed = [0] * len(shapes)

    def designs(self, shape: FootShape) -> Iterator[DesignEvaluation]:
        """``shape``'s designs in order, each as soon as its worker sent it; a worker's error is raised here."""
        k = self.shapes.index(shape)
        while True:
            got = self.received[k]
            while self.handed[k] < len(got):
                self.handed[k] += 1
                yield got[self.handed[k] - 1]
            future = self.futures[k]
            if future.done() and len(got) >= future.result():
                return
            self.receive(POLL)

    def receive(self, timeout: float | None) -> bool:
        """Take one design from the inbox (waiting up to ``timeout``, None: not at all); False if there was none."""
        try:
            k, design = self.inbox.get(timeout=timeout) if timeout is not None else self.inbox.get_nowait()
        except queue.Empty:
            return False
        self.received[k].append(design)
        return True

    def unrecorded(self) -> Iterator[tuple[FootShape, list[DesignEvaluation]]]:
        """Each shape with designs received beyond those handed out: the shape and all its designs so far."""
        while self.receive(None):
            pass
        for k, shape in enumerate(self.shapes):
            if len(self.received[k]) > self.handed[k]:
                yield shape, self.received[k]


#: A worker's inbox to the parent (set at its start, by the fork).
_WORKER: dict = {}


def _start(inbox: multiprocessing.Queue) -> None:
    _WORKER["inbox"] = inbox


def _sweep_in_worker(config: StudyConfig, k: int, shape: FootShape) -> int:
    """Sweep shape ``k`` in a worker, sending each design to the parent; the number of designs."""
    n = 0
    for n, design in enumerate(shape_designs(config, shape), 1):
        _WORKER["inbox"].put((k, design))
    return n


@contextmanager
def landing_sweeps(config: StudyConfig, shapes: list[FootShape], workers: int | None,
                   keep: Keep) -> Iterator[_Serial | _Streamed]:
    """The sweeps of ``shapes``: ``designs(shape)`` of the object given is that shape's designs,
    asked for in the order of ``shapes``. With more than one worker (and shape), swept in forked
    workers (default :func:`optimizer.workers.cores`), else here; leaving on an error, the
    designs received and not yet handed out go to ``keep``."""
    n = min(cores() if workers is None else workers, len(shapes))
    if n <= 1 or "fork" not in multiprocessing.get_all_start_methods():
        yield _Serial(config)
        return
    inbox = multiprocessing.get_context("fork").Queue()
    with forked_pool(n, _start, (inbox,)) as pool:
        assert pool is not None
        futures = [pool.submit(_sweep_in_worker, config, k, shape) for k, shape in enumerate(shapes)]
        sweeps = _Streamed(shapes, futures, inbox)
        try:
            yield sweeps
        except BaseException:
            for shape, designs in sweeps.unrecorded():
                keep(shape, designs)
            raise


__all__ = ["Keep", "POLL", "landing_sweeps", "shape_designs"]
