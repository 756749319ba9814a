"""Fixtures for the optimizer tests: a small leg as a model file, and the same leg built by hand."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from impulse_core.model.tree import Body, ContactSelection, Scene, Tree

#: A three-body leg landing on both ends of its foot at once.
LEG_YAML = """\
# a three-body leg landing on both ends of its foot
scene:
  speed: 2.0
  restitution: 0.5
  contacts: all
model:
  bodies:
    - name: thigh
      length: 0.5
      mass: 2.0
      angle: -1.3
    - name: shank
      parent: thigh
      length: 0.5
      mass: 1.0
      angle: 0.5
    - name: foot
      parent: shank
      length: 0.25
      mass: 0.3
      angle: 1.2
      contacts: [0.0, 1.0]
"""

#: The leg with a heel and a toe on separate bodies; only the lowest contact hits.
FOOT_YAML = """\
scene: {speed: 3.43, restitution: 0.8}
model:
  bodies:
    - {name: thigh, length: 0.7, mass: 1.0, angle: -1.2}
    - {name: shank, parent: thigh, length: 0.7, mass: 1.0, angle: 0.6}
    - {name: heel, parent: shank, length: 0.15, mass: 0.1, angle: 2.0, contacts: [1.0]}
    - {name: toe, parent: shank, length: 0.2, mass: 0.1, angle: -0.5, contacts: [1.0]}
reference:
  source: a made-up table
  external: [null, 0.9]
  internal: [0.25, null, 0.8]
  external_norm: 0.9
"""

#: A plank lying flat on three contacts: redundant contacts (one rigid body, three normals).
PLANK_YAML = """\
scene: {speed: 1.0, restitution: 0.5, contacts: all}
model:
  bodies:
    - {name: plank, length: 1.0, mass: 1.0, angle: 0.0, contacts: [0.0, 0.5, 1.0]}
"""

#: A welded toe with two nearly coincident contacts: Newton's law asks one to pull.
PULLING_YAML = """\
scene: {speed: 3.43, restitution: 0.8, contacts: all}
model:
  bodies:
    - {name: thigh, length: 0.7, mass: 1.0, angle: -1.2}
    - {name: shank, parent: thigh, length: 0.7, mass: 1.0, angle: 0.6}
    - {name: heel, parent: shank, length: 0.15, mass: 0.1, angle: 2.0, contacts: [1.0]}
    - {name: toe, parent: shank, length: 0.2, mass: 0.1, angle: -1.0, joint: fixed, contacts: [1.0, 0.5]}
"""


@pytest.fixture
def write(tmp_path: Path) -> Callable[..., Path]:
    """Write text to a file under tmp_path and return its path: ``write(text, "name.yaml")``."""

    def _write(text: str, name: str = "model.yaml") -> Path:
        path = tmp_path / name
        path.write_text(text, encoding="utf-8")
        return path

    return _write


@pytest.fixture
def leg_file(write: Callable[..., Path]) -> Path:
    return write(LEG_YAML, "leg.yaml")


@pytest.fixture
def foot_file(write: Callable[..., Path]) -> Path:
    return write(FOOT_YAML, "foot.yaml")


@pytest.fixture
def leg_tree() -> Tree:
    """``LEG_YAML``'s tree, built by hand."""
    return Tree(
        (
            Body("thigh", None, length=0.5, mass=2.0, angle=-1.3),
            Body("shank", 0, length=0.5, mass=1.0, angle=0.5),
            Body("foot", 1, length=0.25, mass=0.3, angle=1.2, contacts=(0.0, 1.0)),
        )
    )


@pytest.fixture
def leg_scene() -> Scene:
    """``LEG_YAML``'s scene, built by hand."""
    return Scene(speed=2.0, restitution=0.5, selection=ContactSelection.ALL)


# --------------------------------------------------------------------------------------------
# Studies (footopt optimize)

#: A tiny study: 1-2 toes of one rod, the inner (IPOPT) search; runs in about a second.
TINY_STUDY_YAML = """\
name: tiny
seed: 3
design_space: {toes: [1, 2], toe_segments: [1, 1]}
constraints: {min_link_mass: 0.02}
objectives: [external_norm, internal_norm]
search: {method: inner, trials: 12, startup_trials: 5, inner: {front_points: 3, starts: 2}}
"""

#: The same design space searched by Optuna (outer), few trials.
TINY_OUTER_YAML = TINY_STUDY_YAML.replace("method: inner", "method: outer")


@pytest.fixture
def tiny_study(write: Callable[..., Path]) -> Path:
    return write(TINY_STUDY_YAML, "tiny.yaml")


@pytest.fixture
def tiny_outer_study(write: Callable[..., Path]) -> Path:
    return write(TINY_OUTER_YAML, "tiny_outer.yaml")


@pytest.fixture
def taped_once(monkeypatch: pytest.MonkeyPatch) -> Callable:
    """``taped_run`` run once per argument set in the test, the whole-landing NLP's landed values
    included: a central difference's landings, its event sequences and its statistics read the
    same runs (a taped run is a function of its arguments)."""
    import optimizer.search.landing_inner as landing_inner
    from impulse_core.kinematics.spatial import PLANAR
    from impulse_core.timedomain.landing import LandingSettings
    from impulse_core.timedomain.landing_derivatives import taped_run

    runs: dict = {}

    def once(tree, scene, laws, step, settings=LandingSettings(), space=PLANAR):
        key = (tree, scene, laws, step, settings, space)
        if key not in runs:
            runs[key] = taped_run(tree, scene, laws, step, settings, space)
        return runs[key]

    monkeypatch.setattr(landing_inner, "taped_run", once)
    return once


@pytest.fixture
def quick_timings(monkeypatch: pytest.MonkeyPatch) -> None:
    """``footopt bench``'s timings (:func:`optimizer.analysis.bench._median_us`) cut to one call
    after the warm-up: its tests check what it computes and reports, not its times (the default:
    five samples of about 0.04 s each, per path and round)."""
    import optimizer.analysis.bench as bench

    timed = bench._median_us
    monkeypatch.setattr(bench, "_median_us", lambda fn, calls=None, repeats=5, sample_s=0.04: timed(fn, 1, 1))


@contextmanager
def drawings_unsaved() -> Iterator[None]:
    """A run folder's drawings built (every figure made) but not rendered: ``_save`` (plot's,
    and landing_plot's copy) closes the figure and touches its file. For the study runs whose
    checks are the recorded designs: the rendering costs seconds and is not the point (the
    drawings themselves: test_plot, test_optimize_splay's run folder, test_spatial_cli)."""
    import matplotlib.pyplot as plt

    import optimizer.report.landing_plot as landing_plot
    import optimizer.report.plot as plot

    def unsaved(fig, path: Path, layout: bool = True) -> Path:
        plt.close(fig)
        Path(path).touch()
        return Path(path)

    with pytest.MonkeyPatch.context() as m:
        m.setattr(plot, "_save", unsaved)
        m.setattr(landing_plot, "_save", unsaved)
        yield


@pytest.fixture
def unsaved_drawings() -> Iterator[None]:
    """:func:`drawings_unsaved` for one test."""
    with drawings_unsaved():
        yield
