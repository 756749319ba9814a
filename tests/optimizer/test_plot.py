"""Plots of a tree at touchdown."""

from __future__ import annotations

from pathlib import Path

import pytest

from impulse_core.evaluate import evaluate, touchdown_geometry
from impulse_core.model.tree import Scene, Tree
from optimizer.errors import ConfigError
from optimizer.report.plot import plot_touchdown


@pytest.mark.parametrize(("name", "magic"), [("leg.png", b"\x89PNG\r\n\x1a\n"), ("leg.svg", b"<?xml")])
def test_writes_the_file_its_suffix_names(
    tmp_path: Path, leg_tree: Tree, leg_scene: Scene, name: str, magic: bytes
) -> None:
    result = evaluate(leg_tree, leg_scene)
    path = plot_touchdown(leg_tree, touchdown_geometry(leg_tree), result, tmp_path / name, "leg")
    assert path == tmp_path / name
    data = path.read_bytes()
    assert data.startswith(magic) and len(data) > 1000


def test_labels_the_impulses(tmp_path: Path, leg_tree: Tree, leg_scene: Scene) -> None:
    result = evaluate(leg_tree, leg_scene)
    svg = plot_touchdown(leg_tree, touchdown_geometry(leg_tree), result, tmp_path / "leg.svg", "my leg").read_text()
    assert "my leg" in svg
    for value in (*result.external, *result.internal_magnitude):
        assert f"{value:.3g}" in svg


def test_refuses_other_suffixes(tmp_path: Path, leg_tree: Tree, leg_scene: Scene) -> None:
    result = evaluate(leg_tree, leg_scene)
    with pytest.raises(ConfigError, match=r"\.png or \.svg"):
        plot_touchdown(leg_tree, touchdown_geometry(leg_tree), result, tmp_path / "leg.jpg", "leg")
    assert not (tmp_path / "leg.jpg").exists()


def test_leaves_pyplot_alone(tmp_path: Path, leg_tree: Tree, leg_scene: Scene) -> None:
    import matplotlib.pyplot as plt

    before = plt.get_fignums()
    result = evaluate(leg_tree, leg_scene)
    plot_touchdown(leg_tree, touchdown_geometry(leg_tree), result, tmp_path / "leg.png", "leg")
    assert plt.get_fignums() == before


def test_coinciding_rods_share_one_label() -> None:
    """Case 3's three identical toes lie on top of each other: one label each place, not three
    printed over each other."""
    import numpy as np

    from optimizer.report.plot import _coinciding

    where = np.array([[0.0, 0.0], [1.0, 0.5], [1.0, 0.5], [1.0, 0.5 + 1e-12], [2.0, 0.0]])
    groups = _coinciding(["a", "t1", "t2", "t3", "b"], where, extent=2.0)
    assert [names for names, _ in groups] == [["a"], ["t1", "t2", "t3"], ["b"]]
