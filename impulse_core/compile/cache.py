"""A compile cache that can be trusted: one folder per entry, loaded only if it matches its key.

An entry is a folder ``<name>_<key[:20]>`` under the cache root holding the built files and a
``manifest.json`` with the full key and the SHA-256 of every file, written last. The key hashes
what defines the build (the generated source, the compiler's path and version, the flags), so a
change to any of them makes a new entry, and nothing is versioned by hand. A folder whose manifest
is missing, names another key, or whose files no longer hash to what was built (a library of a
matching name dropped in by someone else, a half-copied file) is never loaded: it is rebuilt.
Builds happen in a private temporary folder that is renamed into place, so two processes building
the same entry at once never see each other's half-written files.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import json
import os
import shutil
import signal
import subprocess
import tempfile
import time
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

from impulse_core.errors import FootoptError

MANIFEST = "manifest.json"
#: Where compiled libraries are cached unless ``FOOTOPT_CACHE_DIR`` says otherwise.
DEFAULT_ROOT = Path.home() / ".cache" / "footopt"


def default_root() -> Path:
    """The cache root: ``FOOTOPT_CACHE_DIR`` if set, else :data:`DEFAULT_ROOT`."""
    return Path(os.environ.get("FOOTOPT_CACHE_DIR", str(DEFAULT_ROOT))).expanduser()


class CompileError(FootoptError, RuntimeError):
    """A C compiler is missing or failed; the message says which and how to run without it."""


@functools.cache
def compiler_identity(compiler: str) -> str:
    """The compiler's resolved path and the first line of ``--version`` (part of every key)."""
    path = shutil.which(compiler) or compiler
    try:
        out = subprocess.run([path, "--version"], capture_output=True, text=True, timeout=30, check=False)
    except (OSError, subprocess.SubprocessError) as exc:
        raise CompileError(f"C compiler {compiler!r} cannot be run: {exc}") from exc
    lines = (out.stdout or out.stderr).splitlines()
    return f"{Path(path).resolve()} {lines[0] if lines else ''}"


def entry_key(*parts: str | bytes) -> str:
    """SHA-256 over ``parts`` (sources, compiler identity, flags), each length-prefixed."""
    h = hashlib.sha256()
    for part in parts:
        data = part.encode() if isinstance(part, str) else part
        h.update(len(data).to_bytes(8, "little"))
        h.update(data)
    return h.hexdigest()


def entry_folder(root: Path, name: str, key: str) -> Path:
    """Where the entry ``name`` with ``key`` lives."""
    return Path(root) / f"{name}_{key[:20]}"


def lookup(root: Path, name: str, key: str) -> Path | None:
    """The entry's folder if it exists and matches its key and its files' hashes; else None."""
    folder = entry_folder(root, name, key)
    try:
        manifest = json.loads((folder / MANIFEST).read_text())
        files = manifest["files"]
        if manifest["key"] != key or not files:
            return None
        if all(_digest(folder / f) == d for f, d in files.items()):
            return folder
    except (OSError, ValueError, KeyError, TypeError):
        pass
    return None


def store(root: Path, name: str, key: str, build: Callable[[Path], Iterable[str]]) -> Path:
    """Build the entry in a private folder with ``build(folder)`` (which returns the names of the
    files it made), record their hashes, and move it into place; returns the verified folder.

    Raises:
        CompileError: the build failed (its message is kept).
    """
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(dir=root, prefix=".build_"))
    try:
        files = {f: _digest(work / f) for f in build(work)}
        (work / MANIFEST).write_text(json.dumps({"key": key, "files": files}, indent=1))
        folder = entry_folder(root, name, key)
        if folder.exists() and lookup(root, name, key) is None:
            shutil.rmtree(folder, ignore_errors=True)  # a stale or foreign folder: replace it
        try:
            work.rename(folder)
        except OSError:
            pass  # another process stored the same entry first; verified below
    finally:
        shutil.rmtree(work, ignore_errors=True)
    found = lookup(root, name, key)
    if found is None:
        raise CompileError(f"cache entry {entry_folder(root, name, key)} does not verify after building it")
    return found


@contextlib.contextmanager
def claim(root: Path, name: str, key: str) -> Iterator[bool]:
    """Whether this process may build the entry (True), or another live process on this machine
    already does (False: its lock file ``.<folder>.lock`` names that process). A lock whose
    process has ended is taken over; the lock is removed on leaving. Builds in the background
    claim first, so that several workers of one study build each library once."""
    lock = Path(root) / f".{entry_folder(root, name, key).name}.lock"
    Path(root).mkdir(parents=True, exist_ok=True)
    for _ in range(2):
        try:
            fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            if _holder_alive(lock):
                yield False
                return
            lock.unlink(missing_ok=True)  # its process ended: take it over
            continue
        with os.fdopen(fd, "w") as f:
            f.write(str(os.getpid()))
        try:
            yield True
        finally:
            lock.unlink(missing_ok=True)
        return
    yield False


def _holder_alive(lock: Path) -> bool:
    """Whether the process a lock file names still runs (a lock without a number yet: while it is
    younger than a minute, its process is writing it)."""
    try:
        os.kill(int(lock.read_text().strip()), 0)
    except PermissionError:  # a process of another user
        return True
    except ValueError:
        try:
            return time.time() - lock.stat().st_mtime < 60.0
        except OSError:
            return False
    except OSError:
        return False
    return True


def run_compilers(*commands: list[str], niceness: int = 0, jobs: list | None = None) -> None:
    """Run compiler commands at once (one process each, ``niceness`` added to their scheduling
    niceness: builds needed later yield the cores to those needed first) and wait for all;
    CompileError with the first failing compiler's last lines. ``jobs``: a list the processes are
    appended to, each in a session of its own, so that whoever started a build in the background
    can stop it (:func:`stop_compilers`)."""
    nice = shutil.which("nice") if niceness > 0 else None  # a command, not preexec_fn: builds run in threads
    prefix = [nice, "-n", str(niceness)] if nice else []
    try:
        started = [
            subprocess.Popen([*prefix, *c], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             start_new_session=jobs is not None) for c in commands
        ]
    except OSError as exc:
        raise CompileError(f"C compiler cannot be run: {exc}") from exc
    if jobs is not None:
        jobs.extend(started)
    outputs = [job.communicate() for job in started]
    for command, job, (out, err) in zip(commands, started, outputs, strict=True):
        if job.returncode:
            tail = " | ".join((err or out or "").strip().splitlines()[-3:])
            raise CompileError(f"C compiler failed ({command[0]}, exit {job.returncode}): {tail}")


def stop_compilers(jobs: list[subprocess.Popen]) -> None:
    """Kill the compilers :func:`run_compilers` started with ``jobs`` that still run, with the
    processes they started (cc1, as: each job leads a session of its own)."""
    for job in jobs:
        if job.poll() is None:
            try:
                os.killpg(job.pid, signal.SIGKILL)
            except OSError:  # ended meanwhile
                pass


def _digest(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


__all__ = ["CompileError", "claim", "compiler_identity", "entry_folder", "entry_key", "lookup", "run_compilers",
           "stop_compilers", "store"]
