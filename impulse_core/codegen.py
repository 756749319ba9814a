"""Compile a CasADi function to machine code once, cache it on disk, fall back to CasADi's
virtual machine where no C compiler is available.

The cache key hashes the function's serialized graph (which fixes the topology), the CasADi
version and the compiler command, so a stale library is never loaded.
"""

from __future__ import annotations

import hashlib
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from enum import Enum
from pathlib import Path

import casadi as ca

#: Compiler flags; -O3 without -ffast-math keeps IEEE semantics (results equal the VM's to rounding).
CFLAGS = ("-O3", "-fPIC", "-shared")


class Backend(Enum):
    """Which path evaluates a function."""

    COMPILED = "compiled C (cached)"
    VIRTUAL_MACHINE = "CasADi virtual machine"


@dataclass(frozen=True)
class Compiled:
    """A function ready to call, with the path that runs it."""

    function: ca.Function
    backend: Backend
    library: Path | None
    compiled_now: bool


def find_compiler() -> str | None:
    """The C compiler on PATH (cc, gcc or clang), or None."""
    for name in ("cc", "gcc", "clang"):
        path = shutil.which(name)
        if path:
            return path
    return None


def cache_key(f: ca.Function, compiler: str) -> str:
    """A hash of the function graph, the CasADi version and the compiler command."""
    h = hashlib.sha256()
    h.update(f.serialize().encode())
    h.update(ca.__version__.encode())
    h.update(" ".join((compiler, *CFLAGS)).encode())
    return h.hexdigest()[:20]


def compile_function(f: ca.Function, cache_dir: Path | None, compiler: str | None = None) -> Compiled:
    """``f`` as compiled C loaded from (or built into) ``cache_dir``; the VM function when
    ``cache_dir`` is None, no compiler exists or the build fails.

    Args:
        f: the function (SX graphs generate the leanest code).
        cache_dir: where compiled libraries live (created if missing); None: do not compile.
        compiler: the C compiler to use (default: :func:`find_compiler`).
    """
    compiler = compiler or find_compiler()
    if cache_dir is None or compiler is None:
        return Compiled(f, Backend.VIRTUAL_MACHINE, None, False)
    cache_dir = Path(cache_dir)
    name = f"{f.name()}_{cache_key(f, compiler)}"
    library = cache_dir / f"{name}.so"
    compiled_now = False
    if not library.exists():
        try:
            cache_dir.mkdir(parents=True, exist_ok=True)
            with tempfile.TemporaryDirectory(dir=cache_dir) as tmp:
                generator = ca.CodeGenerator(f"{name}.c", {"with_header": False})
                generator.add(f)
                source = Path(generator.generate(f"{tmp}/"))
                partial = Path(tmp) / f"{name}.so"
                subprocess.run(
                    [compiler, *CFLAGS, str(source), "-o", str(partial)],
                    check=True,
                    capture_output=True,
                )
                partial.replace(library)  # atomic: a reader never sees half a library
            compiled_now = True
        except (OSError, subprocess.CalledProcessError):
            return Compiled(f, Backend.VIRTUAL_MACHINE, None, False)
    return Compiled(ca.external(f.name(), str(library)), Backend.COMPILED, library, compiled_now)
