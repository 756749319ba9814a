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
from impulse_core.model.joints import FREE
from impulse_core.model.tree import Body
from impulse_core.timedomain.landing import landing
from impulse_core.timedomain.landing_derivatives import sequence_signature, taped_run
from optimizer.config.model_file import load_model_file
from optimizer.config.study_config import load_study
from optimizer.design_space import STUDY_LANDING, FootShape, Leg, LegChain, leg_chain, yaw_rpy
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


#: A spatial leg: its base rolled, pitched and yawed, its second rod about a tilted axis.
SPATIAL_LEG = LegChain((Body("a", None, 0.3, 1.0, -1.2, rpy=(0.2, -0.1, 0.3)),
                        Body("b", 0, 0.3, 1.0, 0.4, axis=(1.0, 0.0, 0.3))), (FREE, FREE), SPATIAL)


@pytest.mark.parametrize("leg, yaw", [(Leg(thigh_angle=-1.8, knee_angle=0.0), 0.3),
                                      (Leg(thigh_angle=-1.0, knee_angle=-0.2), -0.5),
                                      (Leg(thigh_angle=-0.6, knee_angle=0.0), 0.0), (SPATIAL_LEG, 0.3),
                                      (SPATIAL_LEG, -0.4)])
def test_rpy_rates_are_the_derivative_of_yaw_rpy(leg, yaw):
    leg = leg_chain(leg)
    fd = (np.array(yaw_rpy(leg, yaw + 1e-6)) - np.array(yaw_rpy(leg, yaw - 1e-6))) / 2e-6
    assert np.max(np.abs(rpy_rates(leg, yaw) - fd)) <= 1e-8


@pytest.fixture(scope="module")
def nlp(tmp_path_factory):
    path = tmp_path_factory.mktemp("landing_inner_spatial") / "spatial.yaml"
    path.write_text(SPATIAL_LANDING_YAML, encoding="utf-8")
    return build_landing_nlp(load_study(path), FootShape(1, 1))


@pytest.mark.slow  # by default the same check over 2 landings: test_landing_inner_spatial_robust's gradients test
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
    """One objective (one anchor solve), 3 ms, IPOPT cut to 1 iteration: each recorded design's
    model file, landed again at the study's tolerance, gives the objective its row records."""
    import optimizer.search.landing_inner as landing_inner
    from optimizer.cli.main import main

    monkeypatch.setitem(landing_inner.LANDING_IPOPT, "ipopt.max_iter", 1)
    path = tmp_path / "spatial.yaml"
    path.write_text(SPATIAL_LANDING_YAML.replace("[peak_external_norm, energy_absorbed]", "[energy_absorbed]")
                    .replace("duration: 0.004", "duration: 0.003"), encoding="utf-8")
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


#: Two or three toes splayed (symmetric, or per toe with independent toes), a support margin.
def _margin_yaml(toes: str, splay: str, margin: float) -> str:
    return SPATIAL_LANDING_YAML.replace("toes: [1, 1]", f"toes: [{toes}]").replace(
        "splay: [0.1, 0.4]\n  splay_mode: per_toe", splay
    ).replace("constraints: {min_link_mass: 0.02}", f"constraints: {{min_link_mass: 0.02, support_margin: {margin}}}")


MARGIN_STUDIES = {
    "symmetric": (_margin_yaml("3, 3", "splay: [0.1, 0.6]", 0.01), FootShape(3, 1)),
    "per_toe": (_margin_yaml("2, 2", "splay: [-0.5, 0.5]\n  splay_mode: per_toe\n  toe_symmetry: independent", 0.01),
                FootShape(2, 1)),
}


def _edge_terms(config, design) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The realised design's edge terms, numerically (the evaluation's geometry): per edge of the
    NLP's contact order (heel, then toes by decreasing yaw) s = d x (c - P) and |d|^2; and the
    corners and the centre of mass on the ground."""
    from impulse_core.evaluate import touchdown_geometry
    from optimizer.design_space import foot_tree

    tree = foot_tree(config.leg, design)
    geometry = touchdown_geometry(tree, SPATIAL)
    masses = np.array([b.mass for b in tree.bodies])
    c = (masses @ geometry.coms / masses.sum())[[0, 2]]
    n_toes = len(design.toes)
    corners = geometry.contacts[[0, *range(n_toes, 0, -1)]][:, [0, 2]]
    d = np.roll(corners, -1, axis=0) - corners
    w = c - corners
    return d[:, 0] * w[:, 1] - d[:, 1] * w[:, 0], np.sum(d**2, axis=1), corners, c


def _margin_rows(nlp, x):
    """The support margin's rows of the NLP at x (the last edges rows of ``geometric``), in m^2:
    s - (b + TIGHTEN) sqrt(|d|^2 + MARGIN_EPS^2)."""
    from optimizer.search.landing_inner import MARGIN_UNIT

    n_edges = nlp.shape.n_toes + 1
    return np.asarray(nlp.geometric(x)).ravel()[-n_edges:] * MARGIN_UNIT**2


def _quadratic_rows(nlp, x):
    """The quadratic form's rows (``margin_form="quadratic"``: the last 2 x edges rows), in m:
    cross products s, then s^2 - (b + TIGHTEN)^2 |d|^2."""
    from optimizer.search.landing_inner import MARGIN_UNIT

    n_edges = nlp.shape.n_toes + 1
    g = np.asarray(nlp.geometric(x)).ravel()
    return g[-2 * n_edges : -n_edges] * MARGIN_UNIT**2, g[-n_edges:] * MARGIN_UNIT**4


@pytest.fixture(scope="module", params=sorted(MARGIN_STUDIES))
def margin_nlp(request, tmp_path_factory):
    text, shape = MARGIN_STUDIES[request.param]
    path = tmp_path_factory.mktemp("landing_margin") / "margin.yaml"
    path.write_text(text, encoding="utf-8")
    return build_landing_nlp(load_study(path), shape)


def test_the_support_margin_rows_are_the_realised_designs_edge_terms(margin_nlp):
    """At random level points (yaws random in their range): the rows (the default distance form
    and the quadratic one) are the design's edge terms; where the contact order is the hull's,
    min s / |d| is the study's support margin (to 1e-9)."""
    from optimizer.design_space import foot_support_margin
    from optimizer.search.compiled import MARGIN_EPS, TIGHTEN

    nlp, config = margin_nlp, margin_nlp.config
    without = build_landing_nlp(config, nlp.shape, margin_rows=False)
    quadratic = build_landing_nlp(config, nlp.shape, margin_form="quadratic")
    order = max(len(nlp.yaws) - 1, 0)  # per-toe yaws kept in order
    n_edges = nlp.shape.n_toes + 1
    assert nlp.geometric.size1_out(0) == without.geometric.size1_out(0) + order + n_edges
    assert quadratic.geometric.size1_out(0) == without.geometric.size1_out(0) + order + 2 * n_edges
    rng = np.random.default_rng(5)
    b, hull_order, inside = config.limits.support_margin, 0, 0
    for _ in range(12):
        x = start_landing(nlp, rng)
        assert x is not None
        design = nlp.design(x)
        s, dd, corners, c = _edge_terms(config, design)
        rows = _margin_rows(nlp, x)
        assert np.max(np.abs(rows - (s - (b + TIGHTEN) * np.sqrt(dd + MARGIN_EPS**2)))) <= 1e-14
        cross, squared = _quadratic_rows(quadratic, x)
        assert np.max(np.abs(cross - s)) <= 1e-14
        assert np.max(np.abs(squared - (s**2 - (b + TIGHTEN) ** 2 * dd))) <= 1e-16
        margin = foot_support_margin(config.leg, design)
        d, e = np.roll(corners, -1, axis=0) - corners, np.roll(corners, -2, axis=0) - corners
        if np.min(d[:, 0] * e[:, 1] - d[:, 1] * e[:, 0]) > 0:  # convex, counter-clockwise: the hull's order
            hull_order += 1
            edge_margin = float(np.min(s / np.sqrt(dd)))
            if margin >= 0:
                inside += 1
                assert edge_margin == pytest.approx(margin, abs=1e-9)
            else:  # outside: some edge's line is crossed, by no more than the hull's distance
                assert margin - 1e-12 <= edge_margin < 0
    assert hull_order >= 6 and inside >= 3


def test_the_support_margin_rows_gradient_agrees_with_central_differences(margin_nlp):
    """d rows / dx (CasADi's, exact) against central differences of the realised design's edge
    terms (numeric), along random directions and along each variable."""
    import casadi as ca

    from optimizer.search.compiled import MARGIN_EPS, TIGHTEN
    from optimizer.search.landing_inner import MARGIN_UNIT

    nlp, config = margin_nlp, margin_nlp.config
    n_edges = nlp.shape.n_toes + 1
    xs = ca.SX.sym("x", nlp.n_x)
    J = ca.Function("J", [xs], [ca.jacobian(nlp.geometric(xs)[-n_edges:], xs)])
    b = config.limits.support_margin + TIGHTEN

    def rows(x):  # the NLP's rows, in its unit
        s, dd, _, _ = _edge_terms(config, nlp.design(x))
        return (s - b * np.sqrt(dd + MARGIN_EPS**2)) / MARGIN_UNIT**2

    rng = np.random.default_rng(7)
    for _ in range(3):
        x = start_landing(nlp, rng)
        G = np.asarray(J(x))
        assert np.any(G[:, -len(nlp.yaws):])  # the splay moves the edges
        for u in [rng.standard_normal(nlp.n_x), *np.eye(nlp.n_x)]:
            eps = 1e-6
            fd = (rows(x + eps * u) - rows(x - eps * u)) / (2 * eps)
            assert np.max(np.abs(fd - G @ u)) <= 1e-7 * max(1.0, np.max(np.abs(G @ u))), (u, fd, G @ u)


#: Two identical toes, symmetric splay in [0.1, 0.6] rad, a 3 cm support margin, one objective.
SWEEP_MARGIN_YAML = _margin_yaml("2, 2", "splay: [0.1, 0.6]", 0.03).replace(
    "[peak_external_norm, energy_absorbed]", "[peak_external_norm]"
)


def test_a_landing_sweep_with_margin_rows_records_only_designs_within_the_margin(tmp_path, monkeypatch):
    """The landing NLP's objective swapped for the splay (cheap: no landing per iterate; its
    minimum narrows the support polygon): without the rows IPOPT's optimum leaves the margin, with
    them the NLP's solution meets its rows and the margin, and every design the sweep records
    (realised and landed by the study's evaluation) meets the margin."""
    import math

    import optimizer.search.landing_inner as landing_inner
    from optimizer.design_space import foot_support_margin
    from optimizer.search.landing_inner import _Landed, landing_sweep, realise_landing, solve_landing

    monkeypatch.setattr(_Landed, "values", lambda self, x: np.array([x[-1]]))
    monkeypatch.setattr(_Landed, "gradient", lambda self, x: np.eye(len(x))[-1:])
    path = tmp_path / "margin.yaml"
    path.write_text(SWEEP_MARGIN_YAML, encoding="utf-8")
    config, shape = load_study(path), FootShape(2, 1)
    b = config.limits.support_margin
    nlp, free = build_landing_nlp(config, shape), build_landing_nlp(config, shape, margin_rows=False)
    assert nlp.yaws == ("splay",)
    x0 = start_landing(nlp, np.random.default_rng(config.seed))  # the sweep's own first start
    unconstrained = solve_landing(free, (1.0, 0.0), math.inf, x0)
    assert unconstrained.x[-1] == pytest.approx(0.1, abs=1e-6)  # the splay at its lower bound
    assert np.all(unconstrained.x >= free.lbx) and np.all(unconstrained.x <= free.ubx)  # not IPOPT's relaxed bound
    assert foot_support_margin(config.leg, free.design(unconstrained.x)) < b
    assert realise_landing(free, unconstrained.x) is None  # the evaluation drops it

    solutions = []

    def recording(*args, **kwargs):
        solutions.append(solve_landing(*args, **kwargs))
        return solutions[-1]

    monkeypatch.setattr(landing_inner, "solve_landing", recording)
    records = list(landing_sweep(nlp, np.random.default_rng(config.seed)))
    assert len(solutions) == 1 and solutions[0].success
    # the rows (m^2) to IPOPT's tolerance, within TIGHTEN's room (TIGHTEN |d| ~ 1e-8 m^2)
    assert np.min(_margin_rows(nlp, solutions[0].x)) >= -1e-9
    assert solutions[0].x[-1] > 0.1 + 1e-3  # the margin, not the bound, stops the splay
    assert foot_support_margin(config.leg, nlp.design(solutions[0].x)) >= b
    assert len(records) == 1 and all(foot_support_margin(config.leg, r.design) >= b for r in records)


def test_from_a_start_outside_the_hull_the_distance_rows_reach_the_margin_where_the_quadratic_stall(
    tmp_path, monkeypatch
):
    """The sweep test's NLP (the objective swapped for the splay) with a 4 cm margin, as
    ``studies/splayed_toes/landing_margin.yaml``, from its seed-3 first start (the centre of mass
    8.8 mm outside the hull): with the distance rows IPOPT ends at the margin; with the quadratic
    rows (whose gradient loses its s term near an edge) it ends outside the margin after its 60
    iterations."""
    import math

    from optimizer.design_space import foot_support_margin
    from optimizer.search.landing_inner import solve_landing

    monkeypatch.setattr(_Landed, "values", lambda self, x: np.array([x[-1]]))
    monkeypatch.setattr(_Landed, "gradient", lambda self, x: np.eye(len(x))[-1:])
    path = tmp_path / "margin.yaml"
    path.write_text(SWEEP_MARGIN_YAML.replace("support_margin: 0.03", "support_margin: 0.04"), encoding="utf-8")
    config = load_study(path)
    shape, b = FootShape(2, 1), config.limits.support_margin
    nlp, quadratic = build_landing_nlp(config, shape), build_landing_nlp(config, shape, margin_form="quadratic")
    x0 = start_landing(nlp, np.random.default_rng(3))
    assert foot_support_margin(config.leg, nlp.design(x0)) < -5e-3
    new, old = (solve_landing(n, (1.0, 0.0), math.inf, x0) for n in (nlp, quadratic))
    assert new.success and foot_support_margin(config.leg, nlp.design(new.x)) >= b
    assert not old.success and foot_support_margin(config.leg, quadratic.design(old.x)) < b
