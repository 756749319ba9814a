"""Load a study script (``studies/whole_landing/NAME.py``) as a module, as the tests of studies do."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

WHOLE_LANDING = Path(__file__).resolve().parents[2] / "studies" / "whole_landing"


def study_module(name: str) -> ModuleType:
    """``studies/whole_landing/<name>.py``, loaded once and kept under ``name`` in ``sys.modules``
    (its dataclasses look their module up there)."""
    spec = importlib.util.spec_from_file_location(name, WHOLE_LANDING / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault(name, module)
    spec.loader.exec_module(module)
    return sys.modules[name]
