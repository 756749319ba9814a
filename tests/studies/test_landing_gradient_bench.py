"""``studies/landing_gradient/bench.py``: a rerun keeps the dated notes of its results page."""

from __future__ import annotations

import importlib.util
from pathlib import Path

BENCH = Path(__file__).resolve().parents[2] / "studies" / "landing_gradient" / "bench.py"


def test_a_rerun_keeps_the_dated_notes_and_drops_the_old_table(tmp_path: Path) -> None:
    spec = importlib.util.spec_from_file_location("landing_gradient_bench", BENCH)
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    page = tmp_path / "results.md"
    assert bench.kept_notes(page) == ""
    page.write_text("# Title\n\nThe header.\n\nRun 2026-11-27: one.\n\nRun 2026-11-28: two.\n\n| stale | table |\n")
    assert bench.kept_notes(page) == "Run 2026-11-27: one.\n\nRun 2026-11-28: two.\n\n"
