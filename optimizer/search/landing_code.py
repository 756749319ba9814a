"""C for a study's whole landings, built in the background while they run.

A study lands many designs of few topologies. Its landings take step code ``auto``
(:data:`optimizer.design_space.STUDY_LANDING`): the integrator's step and projection and the
dynamics at a point run as C where the compile cache already holds them, else on CasADi's
virtual machine. A search that plans :data:`COMPILE_LANDINGS` or more landings per shape builds
each topology's C (:func:`impulse_core.timedomain.landing_step.landing_code`) from its first
landing on, one library at a time, in a thread whose compiler runs at :data:`NICENESS` (it takes
a core the search leaves idle, and yields one it needs); the landings switch to C as each is
stored. The C is the virtual machine's arithmetic without fused multiply-adds, so a landing gives
the same numbers on either code (bit for bit in the plane; in space the virtual machine's
per-mode copies, :class:`~impulse_core.timedomain.landing_step.ModeFunctions`, round a few last
bits differently: the simplifications CasADi makes as it folds a mode's constants, such as
(x * y) / y into x, need not round as the general function does; 1e-13 relative on random file
60006, bit for bit on three other spatial files). Planar study landings run 1.2-1.8 x faster
as C, spatial ones about 2.7 x; a build takes 5-20 s in the plane and up to minutes in space.
"""

from __future__ import annotations

import queue
import subprocess
import threading
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from impulse_core.compile.cache import default_root, stop_compilers
from impulse_core.compile.codegen import background_build
from impulse_core.errors import FootoptError
from impulse_core.kinematics.spatial import Space
from impulse_core.model.joints import JointLaw
from impulse_core.model.tree import Scene, Tree
from impulse_core.timedomain.events.run import _Landing
from impulse_core.timedomain.landing import VM_CODE, LandingSettings

#: A search that plans at least this many landings per shape builds their C: a planar shape's
#: three libraries take 8-18 s of CPU and save 20-40 % of each 1.5-2.4 s landing after them
#: (landing_study's designs), so they pay back after about this many.
COMPILE_LANDINGS = 24
#: The background compiler's niceness.
NICENESS = 10


class LandingBuilds:
    """The background builds of one search (:mod:`module docstring <optimizer.search.landing_code>`).
    ``planned``: the landings the search plans per shape (fewer than :data:`COMPILE_LANDINGS`:
    nothing is built). Use as a context manager, or call :meth:`stop`: it stops a running compiler
    (the cache never holds half a build) and ends the thread."""

    def __init__(self, planned: float, root: Path | None = None, niceness: int = NICENESS) -> None:
        self.active = planned >= COMPILE_LANDINGS
        self.root, self.niceness = root or default_root(), niceness
        self.started: list[str] = []  #: the names of the functions whose builds were started, in order
        self._seen: set = set()
        self._jobs: list[subprocess.Popen] = []
        self._queue: queue.Queue[Callable[[], Path] | None] = queue.Queue()
        self._thread: threading.Thread | None = None

    def prepare(self, tree: Tree, scene: Scene, laws: tuple[JointLaw, ...], settings: LandingSettings,
                space: Space) -> None:
        """Queue the builds of this landing's C that the cache lacks (none if inactive or stopped)."""
        if not self.active:
            return
        from impulse_core.timedomain.landing_step import landing_code  # it builds on the landing module

        try:
            with np.errstate(all="ignore"):
                run = _Landing(tree, scene, laws, replace(settings, step_code=VM_CODE), space)
        except (FootoptError, ArithmeticError, ValueError, np.linalg.LinAlgError):  # its landing fails alike
            return
        for f in landing_code(run):
            if f in self._seen:
                continue
            self._seen.add(f)
            build = background_build(f, self.root, drivers=False, niceness=self.niceness, jobs=self._jobs)
            if build is not None:
                self.started.append(f.name())
                self._queue.put(build)
                self._start()

    def _start(self) -> None:
        if self._thread is None:
            self._thread = threading.Thread(target=self._work, name="footopt-landing-builds", daemon=True)
            self._thread.start()

    def _work(self) -> None:
        while (build := self._queue.get()) is not None:
            try:
                build()
            except Exception:  # noqa: BLE001 - any failed build (CompileError, OSError): that code stays on the VM
                pass
            finally:
                self._queue.task_done()
        self._queue.task_done()

    def stop(self) -> None:
        """Stop building: no queued build starts, a running compiler is killed; returns when the
        thread has ended. Builds already stored stay in the cache."""
        self.active = False
        if self._thread is None:
            return
        while True:  # drop the queued builds
            try:
                self._queue.get_nowait()
            except queue.Empty:
                break
            self._queue.task_done()
        self._queue.put(None)
        while self._thread.is_alive():
            stop_compilers(self._jobs)
            self._thread.join(0.05)
        self._thread = None

    def wait(self) -> None:
        """Wait until every queued build has ended (stored, or failed)."""
        self._queue.join()

    def __enter__(self) -> LandingBuilds:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


__all__ = ["COMPILE_LANDINGS", "NICENESS", "LandingBuilds"]
