"""The speed-accuracy measurement: every rung is run, timed and compared; CSV and PNG are written."""

from __future__ import annotations

import csv

import numpy as np
import pytest
from fidelity_scenes import PAPER_SCENE, UNEVEN, case2

from optimizer.analysis.accuracy import format_table, measure_accuracy, plot, write_csv

SMALL = dict(
    penalty_stiffness=(1e6, 1e7), constraint_stiffness=(1e7,), steps_per_period=(30, 60), repeats=1, budget=0.05
)


@pytest.fixture(scope="module")
def flat_report():
    return measure_accuracy("case2", case2(), PAPER_SCENE, **SMALL)


@pytest.fixture(scope="module")
def uneven_report():
    return measure_accuracy("uneven", case2(), PAPER_SCENE, UNEVEN, **SMALL)


def test_every_rung_is_measured(flat_report):
    rungs = {r.measurement.rung for r in flat_report.rows}
    assert {"newton", "sequential", "compliant-penalty", "compliant-constraint"} <= rungs
    assert len([r for r in flat_report.rows if r.measurement.rung.startswith("compliant")]) == 2 * 2 + 2
    assert all(np.isfinite(r.measurement.seconds) and r.measurement.seconds > 0 for r in flat_report.rows)
    newton = next(r for r in flat_report.rows if r.measurement.rung == "newton")
    assert newton.speed_ratio == 1.0


def test_errors_against_the_finest_and_the_rigid_limit(flat_report):
    ref = flat_report.row(flat_report.reference)
    assert ref.external_error == 0.0 and ref.internal_error == 0.0 and ref.differs == ""
    assert flat_report.reference == "compliant-penalty k=1e+07 N/m, 60 steps"
    newton = next(r for r in flat_report.rows if r.measurement.rung == "newton")
    assert newton.external_error_rigid < 1e-9  # flat, simultaneous, all pushing: sequential = eq. 11
    soft = flat_report.row("compliant-penalty k=1e+06 N/m, 30 steps")
    assert soft.external_error > 1e-3 and soft.external_error_rigid > 1e-3


def test_flat_ground_rungs_on_uneven_terrain_are_flagged(uneven_report):
    newton = next(r for r in uneven_report.rows if r.measurement.rung == "newton")
    assert newton.measurement.note.startswith("flat ground")
    assert "touchdown order" in newton.differs
    seq = uneven_report.row("sequential")
    assert seq.measurement.touchdown_order == (1, 0) and "2 impact(s)" in seq.measurement.note


def test_csv_table_and_plot(flat_report, tmp_path):
    path = write_csv(flat_report, tmp_path / "case2.csv")
    with path.open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == len(flat_report.rows)
    assert {"external_heel", "external_toe_distal", "internal_shank", "seconds", "differs"} <= set(rows[0])
    assert float(rows[0]["external_heel"]) == pytest.approx(flat_report.rows[0].measurement.external[0])
    png = plot(flat_report, tmp_path / "case2.png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000
    table = format_table(flat_report)
    assert table.count("\n") == len(flat_report.rows) + 1
