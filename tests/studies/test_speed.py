"""``studies/whole_landing/speed.py``: a rerun replaces the table above the notes and keeps every note
from the first section heading on (where the cost lies, the reruns' ratios, the dated reruns)."""

from __future__ import annotations

from pathlib import Path

from tests.studies.scripts import study_module


def test_a_rerun_keeps_the_notes_from_the_first_heading_on(tmp_path: Path) -> None:
    speed = study_module("speed")
    page = tmp_path / "speed.md"
    notes = "## Where the cost lies\n\nthe events.\n\n## Reruns, oldest first\n\nRerun 2026-11-28: 1.6 x.\n"
    page.write_text("# Title\n\n| stale | table |\n|---|---|\nRerun is not a heading here.\n\n" + notes)
    kept = speed.kept_notes(page)
    assert kept == "\n" + notes
    assert "stale" not in kept and "not a heading" not in kept


def test_a_page_without_notes_keeps_nothing(tmp_path: Path) -> None:
    speed = study_module("speed")
    page = tmp_path / "speed.md"
    assert speed.kept_notes(page) == ""
    page.write_text("# Title\n\n| a | b |\n")
    assert speed.kept_notes(page) == ""
