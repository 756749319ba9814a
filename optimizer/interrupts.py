"""Ctrl-C during a search: CasADi may swallow the KeyboardInterrupt a SIGINT raises.

A KeyboardInterrupt raised inside a Python callback that CasADi's wrapper calls (a NumPy
conversion while a graph is built, IPOPT's iteration) can be caught there and lost, and the
search then runs on to its end. Within :func:`interruptible` a SIGINT also sets a flag, which
:func:`check_interrupt` turns back into the KeyboardInterrupt after each batch or solve, and any
error raised once it is set is the interrupt: a C extension may replace the KeyboardInterrupt by
an error of its own (NumPy's comparison of structured arrays, inside Optuna's TPE sampler, by
``TypeError: Cannot compare structured arrays``, which ended a Ctrl-C'd study as an internal error).
A block (in the main thread) that ends without an error after a SIGINT that no caller answered
(:func:`interrupt_handled`) ends with the KeyboardInterrupt: Python drops
one raised inside a weakref callback or a ``__del__`` (a worker pool's, collected as an inner
search ended: the search finished and the Ctrl-C was lost).
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

from optimizer.errors import interrupted

_INTERRUPTED = threading.Event()


def _on_sigint(signum: int, frame: object) -> None:
    _INTERRUPTED.set()
    raise KeyboardInterrupt


def check_interrupt() -> None:
    """Raise KeyboardInterrupt when a Ctrl-C came within :func:`interruptible`, even one that
    something caught on its way (it stays raised until the outermost block ends)."""
    if _INTERRUPTED.is_set():
        raise KeyboardInterrupt


def interrupt_handled() -> None:
    """Forget the Ctrl-C that the caller caught and answered (it reports the interrupt itself):
    the blocks it runs in end without raising it again."""
    _INTERRUPTED.clear()


@contextmanager
def interruptible() -> Iterator[None]:
    """Within: a SIGINT sets the flag :func:`check_interrupt` reads and raises KeyboardInterrupt,
    and an error a C extension raised because of it is the KeyboardInterrupt, as is the block's
    end after one that was swallowed. Nests (the outermost block installs the handler); outside
    the main thread it only converts errors."""
    main = threading.current_thread() is threading.main_thread()
    outermost = main and signal.getsignal(signal.SIGINT) is not _on_sigint
    if outermost:
        _INTERRUPTED.clear()
        previous = signal.signal(signal.SIGINT, _on_sigint)
    try:
        yield
    except Exception as e:  # the KeyboardInterrupt surfaced inside a C call, as another error
        if _INTERRUPTED.is_set() or interrupted(e):
            raise KeyboardInterrupt from e
        raise
    else:
        if main and _INTERRUPTED.is_set():  # a Ctrl-C that something swallowed is still one
            raise KeyboardInterrupt
    finally:
        if outermost:
            signal.signal(signal.SIGINT, previous)
            _INTERRUPTED.clear()


__all__ = ["check_interrupt", "interrupt_handled", "interruptible"]
