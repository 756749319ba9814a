"""The inner search: per foot shape, IPOPT (through CasADi's ``nlpsol``) with exact derivatives
over the shape's continuous values, and an epsilon-constraint sweep for a front.

One NLP is built per (study, shape) and reused: its parameters are the objective weights and the
epsilon bound, so every anchor and every front point is a re-solve, warm-started from the last.

Variables (per distinct rod; identical toes share theirs): joint angle, mass, length; and the
ankle height h above the ground. The impact is the core's compiled CasADi function of the tree's
design vector, inlined into the NLP, so gradients, Jacobians and the Hessian are exact.

    min_x   w1 f1(x) + w2 f2(x)
    s.t.    f2(x) <= eps
            sum_{i in chain} L_i (-sin phi_i) = h            every tip on the ground line
            m_i / rho_max <= L_i <= m_i / rho_min           mass per length
            F_min <= reach_toe(x) <= F_max                  foot length
            height(joint) >= c_min                          clearance (chain joints, ankle, knee, hip)
            sum m = M  (or <= M)                            foot mass
            lambda_c >= 0,  E_after <= E_before             physical impact
            joint limits, m_i >= m_min                      bounds

Objectives that are maxima or absolute values (``max_internal``, ``base_angular_velocity``) get
an epigraph variable. Each solution is re-evaluated by :func:`evaluate_design` after its lengths
are re-chosen by :func:`assign_lengths` (impulses do not depend on them) and kept only if it is
feasible there: the NLP's own tolerances never decide what is exported.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import casadi as ca
import numpy as np
import optuna

from impulse_core.evaluate import approach_velocity, compiled_model
from impulse_core.model.tree import design_vector
from optimizer.design_space import (
    LENGTH_FLOOR,
    DesignEvaluation,
    FootDesign,
    FootShape,
    MassMode,
    Objective,
    Segment,
    ToeSymmetry,
    assign_lengths,
    evaluate_design,
    foot_geometry,
    foot_tree,
    with_lengths,
)
from optimizer.search.outer import objective_values, record_attrs
from optimizer.config.study_config import StudyConfig

#: Inequalities of the NLP are tightened by this (in their own units) so that the re-evaluated
#: design meets them with room for rounding.
TIGHTEN = 1e-7

IPOPT_OPTIONS = {
    "ipopt.print_level": 0,
    "print_time": False,
    "ipopt.sb": "yes",
    "ipopt.tol": 1e-8,
    "ipopt.constr_viol_tol": 1e-9,
    "ipopt.bound_relax_factor": 0.0,
    "ipopt.max_iter": 300,
    "ipopt.mu_strategy": "adaptive",
}


@dataclass(frozen=True)
class ShapeNlp:
    """The NLP of one shape: the solver and how to read its variables.

    Attributes:
        shape: the foot shape.
        solver: ``nlpsol`` (IPOPT) with parameters ``[w1, w2]``; the first constraint row is
            f2, whose upper bound is the epsilon of a solve.
        n_rods: distinct rods (heel rods, then the toe rods of each distinct toe).
        chain_sizes: rods per distinct chain (heel first).
        multiplicity: how many toes share each distinct chain (1 for the heel).
        lbx, ubx, lbg, ubg: bounds.
        objective_expressions: f1, f2 as functions of x (for reading values).
    """

    shape: FootShape
    solver: ca.Function
    n_rods: int
    chain_sizes: tuple[int, ...]
    multiplicity: tuple[int, ...]
    n_x: int
    lbx: np.ndarray
    ubx: np.ndarray
    lbg: np.ndarray
    ubg: np.ndarray
    objectives: ca.Function

    def unpack(self, x: np.ndarray) -> tuple[tuple[tuple[float, ...], ...], tuple[tuple[float, ...], ...]]:
        """(joint angles, masses) per distinct chain from the NLP's x."""
        n = self.n_rods
        a, m = x[:n], x[n : 2 * n]
        out_a, out_m, i = [], [], 0
        for k in self.chain_sizes:
            out_a.append(tuple(float(v) for v in a[i : i + k]))
            out_m.append(tuple(float(v) for v in m[i : i + k]))
            i += k
        return tuple(out_a), tuple(out_m)


def _expand(shape: FootShape, identical: bool, per_chain: tuple) -> tuple:
    """Distinct chains (heel, toe[, toe...]) to the design's chains (heel, every toe)."""
    return (per_chain[0], *([per_chain[1]] * shape.n_toes if identical else per_chain[1:]))


def build_nlp(config: StudyConfig, shape: FootShape) -> ShapeNlp:
    """The NLP of ``shape`` for ``config`` (see the module docstring)."""
    leg, lim = config.leg, config.limits
    identical = config.space.toe_symmetry is ToeSymmetry.IDENTICAL
    sizes = (shape.heel_segments, *([shape.toe_segments] * (1 if identical else shape.n_toes)))
    mult = (1, *([shape.n_toes] if identical else [1] * shape.n_toes))
    n = sum(sizes)
    starts = np.cumsum((0, *sizes[:-1]))
    a = ca.SX.sym("joint_angle", n)
    m = ca.SX.sym("mass", n)
    L = ca.SX.sym("length", n)
    h = ca.SX.sym("ankle_height")
    params = ca.SX.sym("weights", 2)  # w1, w2

    # The tree's design vector with the foot's values substituted (layout: tree.design_vector).
    template = FootDesign(
        heel=tuple(Segment(0.1, 0.1, 0.0) for _ in range(shape.heel_segments)),
        toes=tuple(tuple(Segment(0.1, 0.1, 0.0) for _ in range(shape.toe_segments)) for _ in range(shape.n_toes)),
    )
    tree = foot_tree(leg, template)
    p = ca.SX(ca.DM(design_vector(tree)))
    distinct = [list(range(s, s + k)) for s, k in zip(starts, sizes, strict=True)]
    chains = _expand(shape, identical, tuple(distinct))
    body = 2
    width = 6  # BODY_VALUES per body: length, mass, angle, at, com, gyration
    for chain in chains:
        for i in chain:
            p[width * body + 0] = L[i]
            p[width * body + 1] = m[i]
            p[width * body + 2] = a[i]
            body += 1
    topology = tree.topology()
    model = compiled_model(topology)
    v_minus = approach_velocity(topology, config.scene.speed)
    out = model.impact(p=p, v_minus=ca.DM(v_minus), restitution=config.scene.restitution)

    # Absolute angles per distinct chain.
    phi = []
    for chain in distinct:
        acc = leg.shank_angle
        for i in chain:
            acc = acc + a[i]
            phi.append((i, acc))
    phi_of = dict(phi)
    drop = {i: -ca.sin(phi_of[i]) for i in range(n)}
    run = {i: ca.cos(phi_of[i]) for i in range(n)}

    extra = []  # epigraph variables
    g, lbg, ubg = [], [], []

    def add(expr: ca.SX, lo: float, hi: float) -> None:
        g.append(expr)
        lbg.append(lo)
        ubg.append(hi)

    def objective_expr(o: Objective) -> ca.SX:
        if o is Objective.EXTERNAL_NORM:
            return out["external_norm"]
        if o is Objective.INTERNAL_NORM:
            return out["internal_norm"]
        if o is Objective.ENERGY_AFTER:
            return out["energy_after"]
        s = ca.SX.sym(f"epigraph_{o.value}")
        extra.append(s)
        if o is Objective.MAX_INTERNAL:
            mag = out["internal_magnitude"]
            for j in range(mag.shape[0]):
                add(s - mag[j], 0.0, math.inf)
        else:  # base angular velocity: |omega| <= s
            omega = out["v_plus"][2]
            add(s - omega, 0.0, math.inf)
            add(s + omega, 0.0, math.inf)
        return s

    primary = config.objectives[:2]
    f1 = objective_expr(primary[0])
    f2 = objective_expr(primary[1]) if len(primary) > 1 else ca.SX(0)
    add(f2, -math.inf, math.inf)  # the epsilon row: its upper bound is set per solve

    for chain in distinct:
        add(sum(L[i] * drop[i] for i in chain) - h, 0.0, 0.0)
    lo_rho, hi_rho = lim.mass_per_length
    for i in range(n):
        add(m[i] - hi_rho * L[i], -math.inf, -TIGHTEN * hi_rho)
        add(lo_rho * L[i] - m[i], -math.inf, -TIGHTEN)
    heel_run = sum(L[i] * run[i] for i in distinct[0])
    lo_f, hi_f = lim.foot_length
    for chain in distinct[1:]:
        add(sum(L[i] * run[i] for i in chain) - heel_run, lo_f + TIGHTEN, hi_f - TIGHTEN)
    for chain in distinct:
        for j in range(len(chain) - 1):
            add(h - sum(L[i] * drop[i] for i in chain[: j + 1]), lim.min_clearance + TIGHTEN, math.inf)
    leg_y = foot_geometry(leg, template).leg_points[:, 1]
    for y in (0.0, *leg_y):
        add(h + float(y), lim.min_clearance + TIGHTEN, math.inf)
    total = sum(mult[c] * m[i] for c, chain in enumerate(distinct) for i in chain)
    if lim.mass_mode is MassMode.EQUAL:
        add(total, lim.foot_mass, lim.foot_mass)
    else:
        add(total, -math.inf, lim.foot_mass)
    lam = out["external"]
    for c in range(lam.shape[0]):
        add(lam[c], TIGHTEN, math.inf)
    add(out["energy_after"] - out["energy_before"], -math.inf, -TIGHTEN)

    x = ca.vertcat(a, m, L, h, *extra)
    limits = lim.joint_limits(shape)[: len(distinct)]
    a_lo, a_hi = [], []
    for chain, bounds in zip(distinct, limits, strict=True):
        for j in range(len(chain)):
            a_lo.append(bounds[j][0])
            a_hi.append(bounds[j][1])
    lbx = np.concatenate([a_lo, [lim.min_link_mass * (1 + 1e-6)] * n, [LENGTH_FLOOR] * n, [0.0], [0.0] * len(extra)])
    ubx = np.concatenate([a_hi, [lim.foot_mass] * n, [math.inf] * n, [math.inf], [math.inf] * len(extra)])
    objective = params[0] * f1 + params[1] * f2
    nlp = {"x": x, "p": params, "f": objective, "g": ca.vertcat(*g)}
    solver = ca.nlpsol(f"foot_{shape.label}", "ipopt", nlp, IPOPT_OPTIONS)
    objectives = ca.Function("objectives", [x], [f1, f2])
    return ShapeNlp(
        shape=shape,
        solver=solver,
        n_rods=n,
        chain_sizes=tuple(sizes),
        multiplicity=tuple(mult),
        n_x=int(x.shape[0]),
        lbx=lbx,
        ubx=ubx,
        lbg=np.array(lbg),
        ubg=np.array(ubg),
        objectives=objectives,
    )


@dataclass(frozen=True)
class Solution:
    """One NLP solve: IPOPT's point and status, and the re-evaluated design (None if the point
    could not be turned into a feasible design)."""

    x: np.ndarray
    lam_x: np.ndarray
    lam_g: np.ndarray
    success: bool
    evaluation: DesignEvaluation | None


def start_point(config: StudyConfig, nlp: ShapeNlp, rng: np.random.Generator) -> np.ndarray | None:
    """A random start: angles uniform in their limits, mass shares uniform, lengths and ankle
    height from the linear program (so the start is level), epigraph variables at 1."""
    lim = config.limits
    a = rng.uniform(nlp.lbx[: nlp.n_rods], nlp.ubx[: nlp.n_rods])
    shares = rng.uniform(0.05, 1.0, nlp.n_rods)
    mult = np.concatenate([[nlp.multiplicity[c]] * k for c, k in enumerate(nlp.chain_sizes)])
    used = lim.foot_mass if lim.mass_mode is MassMode.EQUAL else lim.foot_mass * 0.9
    free = used - np.sum(mult) * lim.min_link_mass
    m = lim.min_link_mass + free * shares / np.sum(mult * shares)
    angles, masses = nlp.unpack(np.concatenate([a, m]))
    identical = config.space.toe_symmetry is ToeSymmetry.IDENTICAL
    assignment = assign_lengths(
        config.leg, nlp.shape, _expand(nlp.shape, identical, angles), _expand(nlp.shape, identical, masses), lim
    )
    if assignment is None:
        return None
    lengths = assignment.lengths[: len(nlp.chain_sizes)] if identical else assignment.lengths
    L = np.concatenate([np.array(c) for c in lengths])
    n_extra = nlp.n_x - 3 * nlp.n_rods - 1
    return np.concatenate([a, m, L, [assignment.ankle_height], np.ones(n_extra)])


def solve(
    config: StudyConfig,
    nlp: ShapeNlp,
    weights: tuple[float, float],
    eps: float,
    x0: np.ndarray,
    lam_x0: np.ndarray | None = None,
    lam_g0: np.ndarray | None = None,
) -> Solution:
    """One IPOPT solve from ``x0`` (warm-started with the multipliers when given)."""
    ubg = nlp.ubg.copy()
    ubg[0] = eps
    args = dict(x0=x0, p=list(weights), lbx=nlp.lbx, ubx=nlp.ubx, lbg=nlp.lbg, ubg=ubg)
    if lam_x0 is not None and lam_g0 is not None:
        args.update(lam_x0=lam_x0, lam_g0=lam_g0)
    sol = nlp.solver(**args)
    success = bool(nlp.solver.stats()["success"])
    x = np.array(sol["x"]).ravel()
    return Solution(x, np.array(sol["lam_x"]).ravel(), np.array(sol["lam_g"]).ravel(), success, realise(config, nlp, x))


def realise(config: StudyConfig, nlp: ShapeNlp, x: np.ndarray) -> DesignEvaluation | None:
    """The design of an NLP point: its angles and masses (masses rescaled to the budget
    exactly), lengths re-chosen by the linear program, evaluated by the core; None when it is
    not feasible there."""
    identical = config.space.toe_symmetry is ToeSymmetry.IDENTICAL
    angles, masses = nlp.unpack(x)
    lim = config.limits
    if lim.mass_mode is MassMode.EQUAL:
        total = sum(nlp.multiplicity[c] * sum(ms) for c, ms in enumerate(masses))
        n_all = sum(nlp.multiplicity[c] * len(ms) for c, ms in enumerate(masses))
        free = total - n_all * lim.min_link_mass
        target = lim.foot_mass - n_all * lim.min_link_mass
        masses = tuple(tuple(lim.min_link_mass + (v - lim.min_link_mass) * target / free for v in ms) for ms in masses)
    angles_all = _expand(nlp.shape, identical, angles)
    masses_all = _expand(nlp.shape, identical, masses)
    assignment = assign_lengths(config.leg, nlp.shape, angles_all, masses_all, lim)
    if assignment is None:
        return None
    unit = FootDesign(
        heel=tuple(Segment(1.0, mm, aa) for aa, mm in zip(angles_all[0], masses_all[0], strict=True)),
        toes=tuple(
            tuple(Segment(1.0, mm, aa) for aa, mm in zip(ac, mc, strict=True))
            for ac, mc in zip(angles_all[1:], masses_all[1:], strict=True)
        ),
    )
    evaluation = evaluate_design(config.leg, with_lengths(unit, assignment), config.scene, lim)
    return evaluation if evaluation.feasible else None


def epsilon_sweep(
    config: StudyConfig,
    nlp: ShapeNlp,
    rng: np.random.Generator,
    on_solution: Callable[[DesignEvaluation], None] | None = None,
) -> Iterator[DesignEvaluation]:
    """A front of one shape: the two anchors (best of ``search.starts`` random starts each),
    then ``search.inner.front_points`` epsilon-constraint solves between them, each warm-started
    from the previous one. Yields every feasible design found."""
    search = config.search
    two = len(config.objectives) > 1
    anchors: list[Solution] = []
    for weights in ((1.0, 1e-4), (1e-4, 1.0)) if two else ((1.0, 0.0),):
        best: Solution | None = None
        for _ in range(search.starts):
            x0 = start_point(config, nlp, rng)
            if x0 is None:
                continue
            s = solve(config, nlp, weights, math.inf, x0)
            if s.evaluation is None:
                continue
            yield s.evaluation
            if best is None or _weighted(config, s, weights) < _weighted(config, best, weights):
                best = s
        if best is not None:
            anchors.append(best)
    if not two or len(anchors) < 2 or search.front_points == 0:
        return
    f2_lo = float(nlp.objectives(anchors[1].x)[1])
    f2_hi = float(nlp.objectives(anchors[0].x)[1])
    if not f2_hi > f2_lo:
        return
    previous = anchors[0]
    for eps in np.linspace(f2_hi, f2_lo, search.front_points + 2)[1:-1]:
        s = solve(config, nlp, (1.0, 1e-4), float(eps), previous.x, previous.lam_x, previous.lam_g)
        if not (s.success and s.evaluation is not None):  # the front may jump basins: try from the other end
            s = solve(config, nlp, (1.0, 1e-4), float(eps), anchors[1].x)
        if s.success and s.evaluation is not None:
            yield s.evaluation
            previous = s


def _weighted(config: StudyConfig, s: Solution, weights: tuple[float, float]) -> float:
    assert s.evaluation is not None and s.evaluation.objectives is not None
    o = s.evaluation.objectives
    values = [o.value(obj) for obj in config.objectives[:2]]
    return float(sum(w * v for w, v in zip(weights, values)))


# --------------------------------------------------------------------------------------------
# Recording into a study


def shape_done_key(shape: FootShape) -> str:
    """The study user attribute that marks a shape's sweep as recorded."""
    return f"inner_done:{shape.label}"


def shape_seed(seed: int, shape: FootShape) -> np.random.Generator:
    """The random starts of one shape: a function of the study's seed and the shape only."""
    return np.random.default_rng([seed, shape.n_toes, shape.toe_segments, shape.heel_segments])


def run_inner(
    study: optuna.Study,
    config: StudyConfig,
    progress: Callable[[int, int], None] | None = None,
) -> int:
    """Sweep every shape of the design space not yet recorded in ``study``; record each feasible
    design as a COMPLETE trial (user attributes as the outer search's, ``method: inner``).
    A shape's trials are added together when its sweep ends, then the shape is marked done, so
    an interrupted run resumes at the first unfinished shape.

    Returns:
        The number of shapes swept now.
    """
    shapes = config.space.shapes()
    sp = config.space
    distributions = {
        "toes": optuna.distributions.IntDistribution(*sp.toes),
        "toe_segments": optuna.distributions.IntDistribution(*sp.toe_segments),
        "heel_segments": optuna.distributions.IntDistribution(*sp.heel_segments),
    }
    done = sum(1 for s in shapes if study.user_attrs.get(shape_done_key(s)))
    swept = 0
    for shape in shapes:
        if study.user_attrs.get(shape_done_key(shape)):
            continue
        nlp = build_nlp(config, shape)
        params = {"toes": shape.n_toes, "toe_segments": shape.toe_segments, "heel_segments": shape.heel_segments}
        trials = [
            optuna.trial.create_trial(
                params=params,
                distributions=distributions,
                values=objective_values(config, evaluation.objectives),
                user_attrs=record_attrs(evaluation, "inner"),
                constraints=dict(evaluation.constraints.violations()),
            )
            for evaluation in epsilon_sweep(config, nlp, shape_seed(config.seed, shape))
            if evaluation.objectives is not None
        ]
        study.add_trials(trials)
        study.set_user_attr(shape_done_key(shape), True)
        done, swept = done + 1, swept + 1
        if progress is not None:
            progress(done, len(shapes))
    return swept


__all__ = [
    "ShapeNlp",
    "Solution",
    "build_nlp",
    "epsilon_sweep",
    "realise",
    "run_inner",
    "shape_done_key",
    "solve",
    "start_point",
]
