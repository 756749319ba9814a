"""Passwords out of storage URLs, apart from :mod:`optimizer.config.study_config` (which imports the
design space): every command's one-line error needs it (``optimizer.cli.status``), and
``study_config.redact_url`` is this function."""

from __future__ import annotations

import re


def redact_url(url: str) -> str:
    """A storage URL fit for logs, run folders and reports: any password replaced by ``***``."""
    return re.sub(r"(//[^/@:]*:)[^/@]*@", r"\1***@", url)


__all__ = ["redact_url"]
