"""``studies/whole_landing/moreau_jean_check.py``: its table's order column and summary."""

from __future__ import annotations

from tests.studies.scripts import study_module


def _row(name: str, coarse: float, fine: float) -> dict:
    gap = {"totals": 1e-4, "base": 1e-5, "seconds": 3.0}
    return {"name": name, "friction": 0.5, "restitution": 0.2, "events": 9, "settled_at": None,
            "gaps": [{**gap, "step": 4e-5, "angles": coarse}, {**gap, "step": 2e-5, "angles": fine}]}


def test_the_table_reads_the_order_and_counts_the_legs_within_the_check():
    check = study_module("moreau_jean_check")
    text = check.table([_row("leg 0", 4e-4, 2e-4), _row("leg 1", 5e-2, 5e-2)], 4e-5)
    lines = text.splitlines()
    assert "| leg 0 | 0.5 | 0.20 | 9 | - | 4.0e-04 | 2.0e-04 | 1.0 |" in lines[6]
    assert "| 5.0e-02 | 5.0e-02 | 0.0 |" in lines[7]
    assert lines[-1] == "Worst angle gap at h / 2: 5.0e-02 rad; 1 of 2 legs within 0.002 rad."
