"""The inner search over whole landings in a spatial design space (optimizer.search.landing_inner
with ``design_space.space: spatial``): the toe's yaw is a variable whose derivative reaches the
NLP exactly (through its root rod's rpy), the NLP's gradient agrees with central differences of
the numeric spatial landing, and a tiny study runs, its front re-evaluating to the landing it
recorded."""

from __future__ import annotations

import csv
from dataclasses import replace

import numpy as np
import pytest

from impulse_core.kinematics.spatial import SPATIAL
from impulse_core.timedomain.landing import landing
from impulse_core.timedomain.landing_derivatives import sequence_signature, taped_run
from optimizer.config.model_file import load_model_file
from optimizer.config.study_config import load_study
from optimizer.design_space import STUDY_LANDING, FootShape, yaw_rpy
from optimizer.search.landing_inner import _Landed, build_landing_nlp, rpy_rates, start_landing
from tests.optimizer.test_landing_inner import _tangent
from tests.optimizer.test_landing_study import TINY_LANDING_YAML

#: One toe splayed by its own yaw in [0.1, 0.4] rad; the landing short, its tolerance loose.
SPATIAL_LANDING_YAML = (
    TINY_LANDING_YAML.replace("duration: 0.02", "duration: 0.004")
    .replace("toes: [1, 2]", "toes: [1, 1]\n  space: spatial\n  splay: [0.1, 0.4]\n  splay_mode: per_toe")
    .replace("search: {method: outer, trials: 6, startup_trials: 6, landing_tolerance: 1.0e-2}",
             "search: {method: inner, inner: {starts: 1, front_points: 0}, landing_tolerance: 1.0e-2}")
)


@pytest.mark.parametrize("shank, yaw", [(-1.8, 0.3), (-1.2, -0.5), (-0.6, 0.0)])
def test_rpy_rates_are_the_derivative_of_yaw_rpy(shank, yaw):
    fd = (np.array(yaw_rpy(shank, yaw + 1e-6)) - np.array(yaw_rpy(shank, yaw - 1e-6))) / 2e-6
    assert np.max(np.abs(rpy_rates(shank, yaw) - fd)) <= 1e-8


@pytest.fixture(scope="module")
def nlp(tmp_path_factory):
    path = tmp_path_factory.mktemp("landing_inner_spatial") / "spatial.yaml"
    path.write_text(SPATIAL_LANDING_YAML, encoding="utf-8")
    return build_landing_nlp(load_study(path), FootShape(1, 1))


def test_the_spatial_nlp_gradient_agrees_with_central_differences(nlp):
    """Along a level direction (all variables) and along the toe's yaw alone, the event sequence
    unchanged at both ends."""
    assert nlp.yaws == ("toe1.yaw",) and nlp.space is SPATIAL
    x0 = start_landing(nlp, np.random.default_rng(0))
    landed = _Landed(nlp)
    tree, laws, scene = landed.model(x0)
    assert tree.bodies[3].rpy != (0.0, 0.0, 0.0)  # the toe is turned out of the plane
    nlp.step = landing(tree, scene, laws, replace(STUDY_LANDING, tolerance=1e-2), SPATIAL).step
    G = landed.gradient(x0)
    assert np.all(np.isfinite(G)) and np.max(np.abs(G[:, -1])) > 1e-3 * np.max(np.abs(G))  # the yaw matters

    def sequence(x):
        t, l, s = landed.model(x)
        _, tape, run = taped_run(t, s, l, nlp.step, space=SPATIAL)
        return sequence_signature(tape, run)

    seq0 = sequence(x0)
    yaw = np.zeros(nlp.n_x)
    yaw[-1] = 1.0
    for u in (_tangent(nlp, x0, np.random.default_rng(3)), yaw):
        eps = 1e-6
        assert sequence(x0 + eps * u) == seq0 and sequence(x0 - eps * u) == seq0
        fd = (_Landed(nlp).values(x0 + eps * u) - _Landed(nlp).values(x0 - eps * u)) / (2 * eps)
        assert np.all(np.abs(fd - G @ u) <= 1e-4 * np.maximum(np.abs(G @ u), 1e-3)), (fd, G @ u)


def test_a_spatial_inner_landing_study_runs_and_its_front_re_evaluates(nlp, tmp_path, monkeypatch):
    """One objective (one anchor solve), IPOPT cut to 2 iterations: each recorded design's model
    file, landed again at the study's tolerance, gives the objective its row records."""
    import optimizer.search.landing_inner as landing_inner
    from optimizer.cli.main import main

    monkeypatch.setitem(landing_inner.LANDING_IPOPT, "ipopt.max_iter", 2)
    path = tmp_path / "spatial.yaml"
    path.write_text(SPATIAL_LANDING_YAML.replace("[peak_external_norm, energy_absorbed]", "[energy_absorbed]"),
                    encoding="utf-8")
    assert main(["optimize", str(path), "--out", str(tmp_path / "run"), "--quiet"]) == 0
    rows = list(csv.DictReader((tmp_path / "run" / "pareto.csv").open()))
    assert rows and all(r["method"] == "inner" for r in rows)
    for row in rows:
        assert 0.1 <= float(row["toe1.yaw"]) <= 0.4
        m = load_model_file(tmp_path / "run" / row["model_file"])
        assert m.space is SPATIAL
        r = landing(m.tree, m.scene, m.joints, replace(STUDY_LANDING, tolerance=1e-2), m.space)
        for key in ("energy_absorbed", "peak_external_norm"):
            assert getattr(r, key) == pytest.approx(float(row[key]), rel=1e-9), key
