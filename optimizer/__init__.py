"""footopt's edge layer: model files, reports, plots and the ``footopt`` command line, over
:mod:`impulse_core`.

The names below are loaded on first use (PEP 562), so ``footopt`` starts without plotting or the
landing code and a Ctrl-C while it starts is an interrupt, not a traceback
(:mod:`optimizer.cli.entry`).
"""

from __future__ import annotations

import importlib
from typing import Any

_HOME = {
    "ConfigError": "optimizer.errors",
    "ModelFile": "optimizer.config.model_file",
    "Reference": "optimizer.config.model_file",
    "contact_names": "optimizer.report.text",
    "dump_model_file": "optimizer.config.model_file",
    "format_model_file": "optimizer.config.model_file",
    "format_report": "optimizer.report.text",
    "joint_names": "optimizer.report.text",
    "load_model_file": "optimizer.config.model_file",
    "load_yaml": "optimizer.config.model_file",
    "parse_model": "optimizer.config.model_file",
    "plot_touchdown": "optimizer.report.plot",
    "result_record": "optimizer.report.text",
}


def __getattr__(name: str) -> Any:
    if name not in _HOME:
        raise AttributeError(f"module 'optimizer' has no attribute {name!r}")
    value = getattr(importlib.import_module(_HOME[name]), name)
    globals()[name] = value
    return value


__all__ = sorted(_HOME)
