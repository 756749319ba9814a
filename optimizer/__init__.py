"""footopt's edge layer: model files, reports, plots and the ``footopt`` command line, over
:mod:`impulse_core`."""

from optimizer.config.model_file import (
    ModelFile,
    Reference,
    dump_model_file,
    format_model_file,
    load_model_file,
    load_yaml,
    parse_model,
)
from optimizer.errors import ConfigError
from optimizer.report.plot import plot_touchdown
from optimizer.report.text import contact_names, format_report, joint_names, result_record

__all__ = [
    "ConfigError",
    "ModelFile",
    "Reference",
    "contact_names",
    "dump_model_file",
    "format_model_file",
    "format_report",
    "joint_names",
    "load_model_file",
    "load_yaml",
    "parse_model",
    "plot_touchdown",
    "result_record",
]
