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


@pytest.mark.parametrize("toe_length", [0.05, 2.0])
def test_the_uncropped_drawing_holds_its_title_legend_and_labels(
    tmp_path: Path, leg_scene: Scene, toe_length: float, monkeypatch
) -> None:
    """The touchdown drawing is sized to its data, not cropped: whether the leg is tall or the
    foot wide, everything drawn lies inside the figure."""
    import optimizer.report.plot as plot
    from optimizer.design_space import FootDesign, Leg, Segment, foot_tree

    design = FootDesign(heel=(Segment(0.1, 0.05, -0.5),), toes=((Segment(toe_length, 0.1, 1.2),),))
    tree = foot_tree(Leg(), design)
    figures = []
    save = plot._save
    monkeypatch.setattr(plot, "_save", lambda fig, path, layout=True: figures.append(fig) or save(fig, path, layout))
    plot_touchdown(tree, touchdown_geometry(tree), evaluate(tree, leg_scene), tmp_path / "foot.png", "a long title " * 4)
    (fig,) = figures
    drawn = fig.get_tightbbox(fig.canvas.get_renderer())  # inches
    width, height = fig.get_size_inches()
    assert drawn.x0 >= 0 and drawn.y0 >= 0 and drawn.x1 <= width and drawn.y1 <= height
