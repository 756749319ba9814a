"""The inner search over whole-landing objectives: IPOPT per foot shape on the exact landing
gradient (:func:`impulse_core.timedomain.landing_derivatives.landing_gradient`), and an
epsilon-constraint sweep for a front, as :mod:`optimizer.search.inner` does for the first impact.

Variables per shape: per distinct rod its joint angle, mass and length, the ankle height (as the
first-impact NLP: identical toes share theirs), each joint family's searched law values
(stiffness, damping, stop travel; a fixed range [x, x] is a constant), and for a spatial design
space (splayed toes, ``design_space.splay``) the splay: one symmetric ``splay`` or each toe's
``yaw`` (a fixed range is a constant). A toe's yaw turns its root rod's ``rpy``
(:func:`optimizer.design_space.yaw_rpy`), whose derivative is exact (:func:`rpy_rates`); the
landing and its gradient are then spatial (``space=SPATIAL``). Constraints: the same
geometric rows (:func:`optimizer.search.compiled._geometric_rows`: level tips, mass per length,
foot length, clearance, foot mass), symbolic with exact derivatives. Splayed toes reach forward
by cos(yaw) of their run in their plane: each toe's forward reach has its lower bound as a row
of its own, while the plane's row keeps the in-plane run below the upper bound (stricter than
the forward reach's: sound, a little conservative). The support margin (``constraints.
support_margin``, two toes or more) is rows too, those of the first-impact NLP
(:func:`optimizer.search.compiled._support_rows`: per edge of the contacts in a fixed order, heel
then toes by decreasing yaw, s - b sqrt(|d|^2 + eps^2) >= 0), on the whole spatial tree of the
NLP's point (:func:`landing_tree_values`: identical toes repeat their chain's angles, masses and
lengths, as :meth:`LandingNlp.design` does), with exact derivatives, in units of
:data:`MARGIN_UNIT`; per-toe yaws are then kept in order (a relabelling of the toes), so the
fixed order follows the yaws (the rows are exact where it is the hull's, but for
:data:`optimizer.search.compiled.MARGIN_EPS`'s b eps^2 / (2 |d|^2), sound elsewhere).
The realised design's evaluation still checks the margin, as every constraint.
Objectives (at most two, each a landing objective but ``settled_at``, which has no derivative): a CasADi callback that lands
the design numerically at a fixed Runge-Kutta step, and its Jacobian callback, the exact gradient
along that landing's own event sequence, chained from the tree's values to the NLP's. IPOPT uses
a limited-memory Hessian.

A change of event sequence between iterates: every evaluation lands the design afresh, so the
gradient at an iterate is always that of its own sequence (re-derived whenever the sequence
differs from the last one), and IPOPT's filter line search accepts a trial point only on the
objective that the numeric landing measures there (and the constraint violation): a step across
a change of sequence (a kink or a jump of the objective) is accepted only if the numeric landing
says it improved, else the step is cut back. A landing that fails numerically returns NaN, which
IPOPT treats as an evaluation error and cuts the step. The step length is fixed within one solve
(the one ``landing()`` reports at the start point, at the study's tolerance), so the objective
is one function of the design during a solve; every design found is then realised and evaluated
by the study's own landing (:func:`optimizer.design_space.evaluate_design_landing`, its step
refined to the tolerance): that evaluation, not the NLP's, decides what is recorded.

Over ``landings:`` (in the plane or in space) the NLP scores what the outer search's evaluation
computes (:func:`optimizer.search.outer.evaluate_design_over_landings`): each scenario's scene is
built as it builds it (the design's model file with the scenario's overrides,
:func:`scenario_scenes`; ``speed``, ``velocity_x``, ``angular_velocity``, ``restitution`` and
``friction``, and in space ``velocity_z`` and ``roll_rate``, are the scene's constants, the same
for every design: in space the approach [velocity_x, -speed, velocity_z] and [roll_rate, 0,
angular_velocity], world frame) and landed at its own step (the one ``landing()`` reports at the
start point with the evaluation's settings, :func:`landing_settings`), a spatial landing for a
spatial design space, the support margin's rows as without landings. The callback returns
every scenario's objectives and the Jacobian callback each one's exact gradient along its own
event sequence (S landings and S gradients per iterate). Each objective is its statistic over the
scenarios as the first-impact NLP writes it (:func:`optimizer.search.compiled._statistic`):
``mean`` and ``std`` as written (CasADi's chain rule through the callbacks), ``max`` by an
epigraph variable t with one row t >= u_s per scenario (no kink for IPOPT: the active scenario's
gradient enters through its row's multiplier), ``cvar:q`` in Rockafellar and Uryasev's form
(a level and one excess per scenario). The extra variables start tight at each start point and
are dropped from the solution. A maximised objective (``energy_absorbed``) takes ``mean`` or
``std`` only (the epigraph of a maximised ``max`` would not be tight), a quantile is refused, and
so are a pitch, a roll or a step (the tree, or a ground placed by the design), when the study is
read (naming the field). A scenario that fails numerically
makes the iterate's values NaN, as the nominal landing does.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field, replace

import casadi as ca
import numpy as np

from impulse_core.errors import NumericalError
from impulse_core.kinematics.spatial import PLANAR, SPATIAL
from impulse_core.model.tree import Scene
from impulse_core.timedomain.landing import LandingSettings
from impulse_core.timedomain.landing_derivatives import (
    LAW_VALUES,
    _joint_dofs,
    body_values,
    design_names,
    landing_gradient,
    replayed_step,
    scene_names,
    taped_run,
)
from optimizer.config.study_config import StudyConfig
from optimizer.design_space import (
    JOINT_FAMILIES,
    LENGTH_FLOOR,
    DesignEvaluation,
    FootDesign,
    FootShape,
    LegChain,
    MassMode,
    Objective,
    Segment,
    SplayMode,
    ToeSymmetry,
    assign_lengths,
    design_model,
    evaluate_design_landing,
    foot_joint_laws,
    foot_tree,
    leg_chain,
    landing_scene,
    study_landing,
    symmetric_yaws,
    with_lengths,
    yaw_rpy,
)
from optimizer.evaluation.scenarios import model_data, overrides, scenario_model
from optimizer.evaluation.statistics import StatisticKind
from optimizer.search.compiled import (
    TIGHTEN,
    FootKind,
    _chain_limits,
    _geometric_rows,
    _splayed_values,
    _statistic,
    _support_rows,
    foot_kind,
    toe_yaws,
)

#: IPOPT's options for a landing solve: limited-memory Hessian (only first derivatives exist).
LANDING_IPOPT = {
    "ipopt.hessian_approximation": "limited-memory",
    "ipopt.print_level": 0,
    "ipopt.max_iter": 60,
    "ipopt.tol": 1e-6,
    "ipopt.acceptable_tol": 1e-4,
    "print_time": False,
}
#: The support margin rows' length unit (m): s ~ |d| x distance is 1e-3 m^2 (the quadratic form's
#: row 1e-6 m^4), below IPOPT's default constraint tolerance (1e-4) unscaled; in 0.1 m, O(0.1-1).
MARGIN_UNIT = 0.1
#: The law values a family may search, in the NLP's order.
LAW_KEYS = ("stiffness", "damping", "stop")


@dataclass
class LandingNlp:
    """One shape's landing NLP.

    Attributes:
        config, shape: the study and the foot shape.
        identical: identical toes share their rods' values.
        laws: the searched law variables, (family, key) in x's order after the ankle height.
        yaws: the searched splay variables after them (``splay``, or ``toe<i>.yaw``; none in the
            plane or where the range is fixed).
        lbx, ubx, lbg, ubg: bounds; constraint row 0 is f2 (its upper bound: a solve's epsilon).
        step: the Runge-Kutta step of the current solve (set by :func:`solve_landing`).
        steps: over ``landings``, each scenario's step of the current solve (``step`` unused).
        scenes: the scenes of the landings scored (:func:`scenario_scenes`, set on first use).
        sequences: the distinct event sequences the gradient was derived along (a count of
            re-derivations, for the record).
    """

    config: StudyConfig
    shape: FootShape
    identical: bool
    laws: tuple[tuple[str, str], ...]
    lbx: np.ndarray
    ubx: np.ndarray
    lbg: np.ndarray
    ubg: np.ndarray
    geometric: ca.Function
    yaws: tuple[str, ...] = ()
    step: float = 0.0
    sequences: set = field(default_factory=set)
    evaluations: int = 0
    gradients: int = 0
    steps: tuple[float, ...] = ()
    scenes: tuple = ()

    @property
    def sizes(self) -> tuple[int, ...]:
        return foot_kind(self.config, self.shape).sizes

    @property
    def n_rods(self) -> int:
        return sum(self.sizes)

    @property
    def n_x(self) -> int:
        return 3 * self.n_rods + 1 + len(self.laws) + len(self.yaws)

    @property
    def spatial(self) -> bool:
        return self.config.space.spatial

    @property
    def space(self):
        return SPATIAL if self.spatial else PLANAR

    def toe_yaws(self, x: np.ndarray) -> tuple[tuple[float, ...] | None, np.ndarray]:
        """Each toe's yaw at x (None: the planar foot) and its derivative w.r.t. the splay
        variables (toes x yaw variables)."""
        n_toes = self.shape.n_toes
        if not self.spatial:
            return None, np.zeros((n_toes, 0))
        splay = self.config.space.splay
        lo = splay.splay[0]
        values = {name: float(x[3 * self.n_rods + 1 + len(self.laws) + k]) for k, name in enumerate(self.yaws)}
        d = np.zeros((n_toes, len(self.yaws)))
        if splay.mode is SplayMode.SYMMETRIC:
            yaws = symmetric_yaws(n_toes, values.get("splay", lo))
            if self.yaws and n_toes > 1:  # toe i at -s + 2 s i / (n - 1)
                d[:, 0] = -1.0 + 2.0 * np.arange(n_toes) / (n_toes - 1)
            return yaws, d
        yaws = tuple(values.get(f"toe{i + 1}.yaw", lo) for i in range(n_toes))
        for k, name in enumerate(self.yaws):
            d[int(name[3:].split(".")[0]) - 1, k] = 1.0
        return yaws, d

    def design(self, x: np.ndarray) -> FootDesign:
        """The foot of an NLP point."""
        n = self.n_rods
        a, m, L = x[:n], x[n : 2 * n], x[2 * n : 3 * n]
        family = self.family_laws(x)
        chains, i = [], 0
        for c, k in enumerate(self.sizes):
            root, inner = ("heel_root", "heel_inner") if c == 0 else ("toe_root", "toe_inner")
            chain = []
            for j in range(k):
                law = family[root if j == 0 else inner]
                chain.append(Segment(float(L[i]), float(m[i]), float(a[i]), law["stiffness"], law["damping"], law["stop"]))
                i += 1
            chains.append(tuple(chain))
        toes = (chains[1],) * self.shape.n_toes if self.identical else tuple(chains[1:])
        return FootDesign(heel=chains[0], toes=toes, toe_yaws=self.toe_yaws(x)[0])

    def family_laws(self, x: np.ndarray) -> dict[str, dict]:
        """Each family's law values at x (searched ones from x, fixed ones their value)."""
        space = self.config.space.joint_laws
        searched = {key: x[3 * self.n_rods + 1 + k] for k, key in enumerate(self.laws)}
        out = {}
        for name in JOINT_FAMILIES:
            vals = {}
            for key in LAW_KEYS:
                r = getattr(getattr(space, name), key)
                vals[key] = None if r is None else float(searched.get((name, key), r[0]))
            vals["stiffness"] = vals["stiffness"] or 0.0
            vals["damping"] = vals["damping"] or 0.0
            out[name] = vals
        return out

    def rod_index(self) -> list[tuple[int, int, str, str]]:
        """Per foot body of the tree (the leg's rods excluded, tree order): (its body index, the
        distinct rod it takes its values from, its family's root or inner name)."""
        out, body = [], len(leg_chain(self.config.leg).rods)
        starts = np.cumsum((0, *self.sizes[:-1]))
        chains = [0] + ([1] * self.shape.n_toes if self.identical else list(range(1, 1 + self.shape.n_toes)))
        for c in chains:
            root, inner = ("heel_root", "heel_inner") if c == 0 else ("toe_root", "toe_inner")
            for j in range(self.sizes[c]):
                out.append((body, int(starts[c]) + j, root if j == 0 else inner))
                body += 1
        return out

    def chain_rule(self, x: np.ndarray, tree, names: tuple[str, ...], d_theta: np.ndarray) -> np.ndarray:
        """d/dx from d/dtheta (rows: objectives) for the tree of x."""
        n = self.n_rods
        values = body_values(tree, self.space)  # the plane's (com_y off the rods), or SPATIAL's
        width = len(values)
        dofs = _joint_dofs(tree, self.space)
        n_p = len(names) - len(LAW_VALUES) * len(dofs)
        law_at = {b: n_p + len(LAW_VALUES) * i for i, (b, _) in enumerate(dofs)}
        family = self.family_laws(x)
        out = np.zeros((d_theta.shape[0], self.n_x))
        searched = {key: 3 * n + 1 + k for k, key in enumerate(self.laws)}
        for body, rod, fam in self.rod_index():
            col = lambda name: width * body + values.index(name)  # noqa: E731
            out[:, rod] += d_theta[:, col("angle")]
            out[:, n + rod] += d_theta[:, col("mass")]
            out[:, 2 * n + rod] += d_theta[:, col("length")]
            base = law_at[body]
            lo, hi = d_theta[:, base + 3], d_theta[:, base + 4]
            if family[fam]["stop"] is not None:  # limits = angle -+ stop
                out[:, rod] += lo + hi
                if (fam, "stop") in searched:
                    out[:, searched[(fam, "stop")]] += hi - lo
            for key, k in (("stiffness", 0), ("damping", 1)):
                if (fam, key) in searched:
                    out[:, searched[(fam, key)]] += d_theta[:, base + k]
        if self.yaws:  # each toe root's rpy turns with its yaw
            yaws, d_yaws = self.toe_yaws(x)
            roots = [body for body, rod, fam in self.rod_index() if fam == "toe_root"]
            rpy = [values.index(k) for k in ("roll", "pitch", "yaw")]
            first = 3 * n + 1 + len(self.laws)
            for i, body in enumerate(roots):
                d_rpy = d_theta[:, [width * body + j for j in rpy]] @ rpy_rates(leg_chain(self.config.leg), yaws[i])
                out[:, first : first + len(self.yaws)] += np.outer(d_rpy, d_yaws[i])
        return out


def rpy_rates(leg: LegChain, yaw: float) -> np.ndarray:
    """d(roll, pitch, yaw)/d psi of :func:`optimizer.design_space.yaw_rpy` (a toe root turned by
    psi about the world's vertical): R(psi) = W_R_L^T Ry(psi) Rz(phi) turns about
    a = W_R_L^T e_y (in the plane Rz(-phi) e_y = (sin phi, cos phi, 0)) at unit rate, and the rpy
    rates of an angular velocity w in the parent's frame solve w = c' e_z + b' Rz(c) e_y +
    a' Rz(c) Ry(b) e_x (R = Rz(c) Ry(b) Rx(a))."""
    _, b, c = yaw_rpy(leg, yaw)
    axis = leg.ankle_rotation.T @ np.array([0.0, 1.0, 0.0])
    cb, sb, cc, sc = math.cos(b), math.sin(b), math.cos(c), math.sin(c)
    E = np.array([[cc * cb, -sc, 0.0], [sc * cb, cc, 0.0], [-sb, 0.0, 1.0]])  # columns: the roll, pitch, yaw axes
    return np.linalg.solve(E, axis)


def build_landing_nlp(
    config: StudyConfig, shape: FootShape, margin_rows: bool = True, margin_form: str = "distance"
) -> LandingNlp:
    """The landing NLP of ``shape`` (see the module docstring). ``margin_rows=False`` leaves the
    support margin's rows out (the realised design's evaluation alone checks it; for comparison);
    ``margin_form``: the rows' form (:func:`optimizer.search.compiled._support_rows`)."""
    lim = config.limits
    kind = foot_kind(config, shape)
    sizes = kind.sizes
    n = sum(sizes)
    starts = np.cumsum((0, *sizes[:-1]))
    distinct = [list(range(s, s + k)) for s, k in zip(starts, sizes, strict=True)]
    space = config.space.joint_laws
    laws, lo_law, hi_law = [], [], []
    for name in JOINT_FAMILIES:
        if name.endswith("inner") and (shape.heel_segments if name.startswith("heel") else shape.toe_segments) < 2:
            continue
        for key in LAW_KEYS:
            r = getattr(getattr(space, name), key)
            if r is not None and r[0] != r[1]:
                laws.append((name, key))
                lo_law.append(r[0])
                hi_law.append(r[1])
    yaws, lo_yaw, hi_yaw = [], [], []
    splay = config.space.splay
    if splay is not None and splay.splay[0] != splay.splay[1]:
        if splay.mode is SplayMode.SYMMETRIC:
            yaws = ["splay"] if shape.n_toes > 1 else []
        else:
            yaws = [f"toe{i + 1}.yaw" for i in range(shape.n_toes)]
        lo_yaw, hi_yaw = [splay.splay[0]] * len(yaws), [splay.splay[1]] * len(yaws)
    a, m, L = ca.SX.sym("joint_angle", n), ca.SX.sym("mass", n), ca.SX.sym("length", n)
    h = ca.SX.sym("ankle_height")
    w = ca.SX.sym("law", len(laws))
    psi = ca.SX.sym("splay", len(yaws))
    mult = [ca.SX(1)] + [ca.SX(shape.n_toes if kind.distinct_toes == 1 else 1)] * kind.distinct_toes
    g, lbg, ubg = [], [], []

    def add(expr, lo, hi):
        g.append(expr)
        lbg.extend([lo] * expr.numel())
        ubg.extend([hi] * expr.numel())

    _geometric_rows(config, distinct, a, m, L, h, mult, add)
    if splay is not None:
        _forward_reach_rows(config, shape, distinct, a, L, yaws, psi, add)
        if margin_rows and lim.support_margin is not None and shape.n_toes > 1:
            for j in range(len(yaws) - 1):  # per-toe yaws in order: the rows' contact order (docstring)
                add(psi[j + 1] - psi[j], 0.0, math.inf)
            _landing_support_rows(config, kind, distinct, a, m, L, psi, add, margin_form)
    x = ca.vertcat(a, m, L, h, w, psi)
    geometric = ca.Function("geometric", [x], [ca.vertcat(*g)])
    a_lo, a_hi = [], []
    for chain, bounds in zip(distinct, _chain_limits(config, kind), strict=True):
        a_lo += [bounds[j][0] for j in range(len(chain))]
        a_hi += [bounds[j][1] for j in range(len(chain))]
    lbx = np.concatenate([a_lo, [lim.min_link_mass * (1 + 1e-6)] * n, [LENGTH_FLOOR] * n, [0.0], lo_law, lo_yaw])
    ubx = np.concatenate([a_hi, [lim.foot_mass] * n, [math.inf] * n, [math.inf], hi_law, hi_yaw])
    return LandingNlp(
        config, shape, config.space.toe_symmetry is ToeSymmetry.IDENTICAL, tuple(laws), lbx, ubx,
        np.array([-math.inf, *lbg]), np.array([math.inf, *ubg]), geometric, tuple(yaws),
    )


def _forward_reach_rows(config: StudyConfig, shape: FootShape, distinct, a, L, yaws: list, psi, add) -> None:
    """Splayed toes: each toe's forward reach (its in-plane run times cos(yaw), less the heel's
    run) at least the foot length's lower bound (module docstring)."""
    lo_f = config.limits.foot_length[0]
    splay = config.space.splay
    runs = []
    for chain in distinct:
        acc, run = leg_chain(config.leg).foot_angle, 0
        for i in chain:
            acc = acc + a[i]
            run = run + L[i] * ca.cos(acc)
        runs.append(run)
    for i, yaw in enumerate(toe_yaws(splay, shape.n_toes, [psi[k] for k in range(len(yaws))])):
        run = runs[1] if len(distinct) == 2 else runs[1 + i]  # identical toes: one distinct chain
        add(run * ca.cos(yaw) - runs[0], lo_f + TIGHTEN, math.inf)


def landing_tree_values(config: StudyConfig, kind: FootKind, distinct: list, a, m, L, psi) -> tuple:
    """The whole spatial tree's design vector (:func:`optimizer.search.compiled._splayed_values`),
    every body's mass and the topology, symbolic in the landing NLP's angles, masses and lengths
    (per distinct rod: identical toes repeat theirs, as :meth:`LandingNlp.design` does) and its
    splay variables ``psi``."""
    splay = config.space.splay
    assert splay is not None
    lengths = ca.vertcat(*[L[i] for c in kind.chain_of for i in distinct[c]])
    yaws = toe_yaws(splay, kind.splayed_toes, [psi[j] for j in range(psi.numel())])
    return _splayed_values(config, kind, a, m, lengths, yaws)


def _landing_support_rows(
    config: StudyConfig, kind: FootKind, distinct: list, a, m, L, psi, add, form: str = "distance"
) -> None:
    """The support margin's rows (:func:`optimizer.search.compiled._support_rows`, of ``form``) on
    the tree of the landing NLP's point (:func:`landing_tree_values`), in units of
    :data:`MARGIN_UNIT`."""
    p, masses, topology = landing_tree_values(config, kind, distinct, a, m, L, psi)
    _support_rows(config, kind, topology, p, masses, add, MARGIN_UNIT, form)


def landing_objectives_of(config: StudyConfig) -> tuple[Objective, ...]:
    """The (at most two) objectives a landing NLP minimises, each signed (``Objective.sign``)."""
    return tuple(config.objectives[:2])


def landing_settings(config: StudyConfig) -> LandingSettings:
    """The landing settings the study's evaluation uses, for the nominal scene and every
    scenario over ``landings`` alike (:func:`optimizer.design_space.study_landing`)."""
    return study_landing(config.search.landing_tolerance)


def scenario_scenes(config: StudyConfig, design: FootDesign) -> tuple[Scene, ...]:
    """The scene of each landing the NLP scores: the nominal one (:func:`landing_scene`), or over
    ``landings`` each scenario's, as the outer search builds it (the design's model file with the
    scenario's overrides, :func:`optimizer.evaluation.scenarios.scenario_model`). The parameters
    the inner search varies (``INNER_LANDING_PARAMETERS``, in space ``INNER_SPATIAL_LANDING_PARAMETERS``)
    are the scene's constants: the same for every design."""
    if config.landings is None:
        return (landing_scene(config.scene, config.limits),)
    model = design_model(config.leg, design, config.scene, config.limits, config.space.joint_laws.stop_restitution)
    data, names = model_data(model), config.landings.names
    return tuple(scenario_model(data, overrides(model, names, row)).scene for row in config.landings.draw())


class _Landed:
    """The NLP's numeric landings at x, cached for the last x: each objective's signed value per
    scenario (objective-major: objective j's S values at j S .. j S + S - 1; S = 1 without
    ``landings``), and on request their gradients, each along its own landing's event sequence."""

    def __init__(self, nlp: LandingNlp) -> None:
        self.nlp = nlp
        self.objectives = landing_objectives_of(nlp.config)
        self.x_f: np.ndarray | None = None
        self.f: np.ndarray | None = None
        self.x_g: np.ndarray | None = None
        self.g: np.ndarray | None = None

    @property
    def n_scenarios(self) -> int:
        return 1 if self.nlp.config.landings is None else self.nlp.config.landings.count

    @property
    def n_f(self) -> int:
        return len(self.objectives) * self.n_scenarios

    def steps(self) -> tuple[float, ...]:
        """Each scenario's Runge-Kutta step (the nominal one: ``nlp.step``)."""
        return (self.nlp.step,) if self.nlp.config.landings is None else self.nlp.steps

    def model(self, x: np.ndarray):
        """The tree, joint laws and first scored scene of x (without ``landings``: the nominal one)."""
        tree, laws, scenes = self.models(x)
        return tree, laws, scenes[0]

    def models(self, x: np.ndarray):
        """The tree, joint laws and every scenario's scene of x (the scenes computed once)."""
        cfg = self.nlp.config
        design = self.nlp.design(x)
        tree = foot_tree(cfg.leg, design)
        laws = foot_joint_laws(cfg.leg, design, cfg.space.joint_laws.stop_restitution)
        if not self.nlp.scenes:
            self.nlp.scenes = scenario_scenes(cfg, design)
        return tree, laws, self.nlp.scenes

    def directions(self, x: np.ndarray, tree) -> np.ndarray | None:
        """d(theta, scene values)/dx at x, along whose n_x columns the landings' derivatives are
        carried (forward mode; the scenes do not move with x) where there are at most a quarter as
        many as theta's and the scene's values; else None (every column, then the chain rule).
        The sweep's cost, measured (``studies/landing_gradient/results.md``): at 8 of 47-107
        columns 0.53-0.82 x the full sweep's, at 16 of 47-60 0.85-1.07 x."""
        names = design_names(tree, self.nlp.space)
        n = len(names) + len(scene_names(tree, self.nlp.space))
        if 4 * self.nlp.n_x > n:
            return None
        T = self.nlp.chain_rule(x, tree, names, np.eye(len(names)))
        return np.vstack([T, np.zeros((n - len(names), self.nlp.n_x))])

    def values(self, x: np.ndarray) -> np.ndarray:
        if self.x_f is not None and np.array_equal(x, self.x_f):
            return self.f
        self.nlp.evaluations += 1
        settings = landing_settings(self.nlp.config)
        f = np.full((len(self.objectives), self.n_scenarios), np.nan)
        try:
            tree, laws, scenes = self.models(x)
            for k, (scene, step) in enumerate(zip(scenes, self.steps(), strict=True)):
                with np.errstate(all="ignore"):
                    r, _, _ = taped_run(tree, scene, laws, step, settings, self.nlp.space)
                f[:, k] = [o.sign * getattr(r, o.value) for o in self.objectives]
        except (NumericalError, ArithmeticError, np.linalg.LinAlgError, ValueError):
            f[:] = np.nan
        f = f.ravel()
        self.x_f, self.f = x.copy(), f
        return f

    def gradient(self, x: np.ndarray) -> np.ndarray:
        if self.x_g is not None and np.array_equal(x, self.x_g):
            return self.g
        self.nlp.gradients += 1
        settings = landing_settings(self.nlp.config)
        n_o, n_s = len(self.objectives), self.n_scenarios
        g = np.full((n_o, n_s, self.nlp.n_x), np.nan)
        try:
            tree, laws, scenes = self.models(x)
            directions = self.directions(x, tree)
            for k, (scene, step) in enumerate(zip(scenes, self.steps(), strict=True)):
                with np.errstate(all="ignore"):
                    gr = landing_gradient(tree, scene, laws, settings, step=step, space=self.nlp.space,
                                          directions=directions)
                self.nlp.sequences.add(hash(gr.sequence))
                d = np.vstack([o.sign * gr.jacobian[o.value] for o in self.objectives])
                g[:, k, :] = d if directions is not None else self.nlp.chain_rule(x, tree, gr.names, d)
        except (NumericalError, ArithmeticError, np.linalg.LinAlgError, ValueError):
            g[:] = np.nan
        g = g.reshape(n_o * n_s, self.nlp.n_x)
        self.x_g, self.g = x.copy(), g
        return g


class _Objectives(ca.Callback):
    """x -> the signed landing objectives (CasADi callback; its Jacobian: :class:`_Gradient`)."""

    def __init__(self, landed: _Landed, n_x: int, n_f: int) -> None:
        ca.Callback.__init__(self)
        self.landed, self.n_x, self.n_f = landed, n_x, n_f
        self.construct("landing_objectives", {"enable_fd": False})

    def get_n_in(self):
        return 1

    def get_n_out(self):
        return 1

    def get_sparsity_in(self, i):
        return ca.Sparsity.dense(self.n_x, 1)

    def get_sparsity_out(self, i):
        return ca.Sparsity.dense(self.n_f, 1)

    def eval(self, args):
        return [ca.DM(self.landed.values(np.asarray(args[0], dtype=float).ravel()))]

    def has_jacobian(self):
        return True

    def get_jacobian(self, name, inames, onames, opts):
        self._jacobian = _Gradient(name, self.landed, self.n_x, self.n_f, opts)
        return self._jacobian


class _Gradient(ca.Callback):
    """(x, objectives) -> d objectives / d x: the exact gradient along the landing's sequence."""

    def __init__(self, name: str, landed: _Landed, n_x: int, n_f: int, opts: dict) -> None:
        ca.Callback.__init__(self)
        self.landed, self.n_x, self.n_f = landed, n_x, n_f
        self.construct(name, opts)

    def get_n_in(self):
        return 2

    def get_n_out(self):
        return 1

    def get_sparsity_in(self, i):
        return ca.Sparsity.dense(self.n_x, 1) if i == 0 else ca.Sparsity.dense(self.n_f, 1)

    def get_sparsity_out(self, i):
        return ca.Sparsity.dense(self.n_f, self.n_x)

    def eval(self, args):
        return [ca.DM(self.landed.gradient(np.asarray(args[0], dtype=float).ravel()))]


@dataclass(frozen=True)
class LandingSolution:
    x: np.ndarray
    success: bool
    f: float
    f2: float
    status: str


def solver(nlp: LandingNlp, options: dict | None = None) -> tuple[ca.Function, _Landed]:
    """IPOPT on the landing NLP: parameters (w1, w2), row 0 = f2 (``options`` override
    :data:`LANDING_IPOPT`). Over ``landings`` each objective is its statistic over the scenarios'
    values (:func:`optimizer.search.compiled._statistic`, the first-impact NLP's form: ``max`` and
    ``cvar`` by epigraph variables appended to x, one row per scenario)."""
    landed = _Landed(nlp)
    F = _Objectives(landed, nlp.n_x, landed.n_f)
    x = ca.MX.sym("x", nlp.n_x)
    p = ca.MX.sym("p", 2)
    f, extra, rows = statistic_objectives(nlp, landed, F(x))
    f2 = f[1] if len(f) > 1 else ca.MX(0)
    g = ca.vertcat(f2, nlp.geometric(x), *(r for r, _, _ in rows))
    problem = {"x": ca.vertcat(x, *extra), "p": p, "f": p[0] * f[0] + p[1] * f2, "g": g}
    s = ca.nlpsol("landing_nlp", "ipopt", problem, {**LANDING_IPOPT, **(options or {})})
    s._keep = F  # the callback must outlive the solver
    return s, landed


def statistic_objectives(nlp: LandingNlp, landed: _Landed, values) -> tuple[list, list, list]:
    """The signed objectives of the NLP from the callback's per-scenario values (an MX column),
    the statistic's extra variables and its rows (expression, lower, upper bound). A statistic
    is of the objective's value (not its sign): f = sign * statistic(sign * values)."""
    S = landed.n_scenarios
    extra, rows = [], []

    def variable(name: str, size: int = 1):
        extra.append(ca.MX.sym(name, size))
        return extra[-1]

    def add(expr, lo: float, hi: float) -> None:
        rows.append((expr, np.full(expr.numel(), lo), np.full(expr.numel(), hi)))

    out = []
    for j, o in enumerate(landed.objectives):
        u = values[j * S : (j + 1) * S].T
        if nlp.config.landings is None:
            out.append(u)
        else:
            out.append(o.sign * _statistic(nlp.config.statistic_of(o), o.sign * u, variable, add))
    return out, extra, rows


def _extra_start(nlp: LandingNlp, landed: _Landed, x: np.ndarray) -> np.ndarray:
    """The statistics' extra variables at x, in :func:`statistic_objectives`' order, tight: a
    ``max`` level the largest value, a ``cvar`` level its minimising kink and each excess above it."""
    if nlp.config.landings is None:
        return np.zeros(0)
    S = landed.n_scenarios
    f = landed.values(x)
    out: list[float] = []
    for j, o in enumerate(landed.objectives):
        stat = nlp.config.statistic_of(o)
        u = o.sign * f[j * S : (j + 1) * S]
        if not np.all(np.isfinite(u)):
            u = np.zeros(S)
        if stat.kind is StatisticKind.MAX:
            out.append(float(np.max(u)))
        elif stat.kind is StatisticKind.CVAR:
            q = float(stat.q)
            t = min(u, key=lambda t: t + np.maximum(u - t, 0.0).sum() / ((1.0 - q) * S))
            out += [float(t), *np.maximum(u - t, 0.0)]
    return np.array(out)


def _extra_bounds(nlp: LandingNlp) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of the statistics' extra variables: a level free, an excess >= 0."""
    lo: list[float] = []
    for o in landing_objectives_of(nlp.config):
        if nlp.config.landings is None:
            continue
        stat = nlp.config.statistic_of(o)
        if stat.kind is StatisticKind.MAX:
            lo.append(-math.inf)
        elif stat.kind is StatisticKind.CVAR:
            lo += [-math.inf] + [0.0] * nlp.config.landings.count
    return np.array(lo), np.full(len(lo), math.inf)


def start_landing(nlp: LandingNlp, rng: np.random.Generator) -> np.ndarray | None:
    """A random level start (as the first-impact search's): angles uniform in their limits, mass
    shares uniform, lengths and ankle height from the linear program; law values uniform; per-toe
    yaws uniform, sorted (the order the margin rows keep)."""
    cfg, lim = nlp.config, nlp.config.limits
    n = nlp.n_rods
    a = rng.uniform(nlp.lbx[:n], nlp.ubx[:n])
    shares = rng.uniform(0.05, 1.0, n)
    mult = np.concatenate([[1] * nlp.sizes[0]] + [[nlp.shape.n_toes if nlp.identical else 1] * k for k in nlp.sizes[1:]])
    used = lim.foot_mass if lim.mass_mode is MassMode.EQUAL else lim.foot_mass * 0.9
    free = used - np.sum(mult) * lim.min_link_mass
    m = lim.min_link_mass + free * shares / np.sum(mult * shares)
    w = rng.uniform(nlp.lbx[3 * n + 1 :], nlp.ubx[3 * n + 1 :])  # law values, then splay
    if len(nlp.yaws) > 1:  # per-toe yaws in increasing order (any foot is one such, relabelled)
        w[len(nlp.laws) :] = np.sort(w[len(nlp.laws) :])
    design = nlp.design(np.concatenate([a, m, np.full(n, 0.1), [0.0], w]))
    angles = tuple(tuple(s.joint_angle for s in c) for c in design.chains)
    masses = tuple(tuple(s.mass for s in c) for c in design.chains)
    assignment = assign_lengths(cfg.leg, nlp.shape, angles, masses, lim, toe_yaws=design.toe_yaws)
    if assignment is None:
        return None
    L = np.concatenate([np.array(c) for c in assignment.lengths[: len(nlp.sizes)]])
    return np.concatenate([a, m, L, [assignment.ankle_height], w])


def set_steps(nlp: LandingNlp, x0: np.ndarray) -> bool:
    """Fix the solve's Runge-Kutta steps: each scored landing's step as ``landing()`` reports it
    at x0 with the evaluation's settings (:func:`landing_settings`; on Radau IIA, its RK4 landing's:
    :func:`replayed_step`); False when one fails."""
    landed = _Landed(nlp)
    tree, laws, scenes = landed.models(x0)
    settings = landing_settings(nlp.config)
    try:
        with np.errstate(all="ignore"):
            steps = tuple(replayed_step(tree, scene, laws, settings, nlp.space) for scene in scenes)
    except (NumericalError, ArithmeticError, np.linalg.LinAlgError, ValueError):
        return False
    nlp.step, nlp.steps = steps[0], steps
    return True


def solve_landing(nlp: LandingNlp, weights: tuple[float, float], eps: float, x0: np.ndarray,
                  options: dict | None = None) -> LandingSolution:
    """One IPOPT solve from x0 (the design's variables), at the steps ``landing()`` reports at x0
    (:func:`set_steps`); the statistics' extra variables start tight at x0 and are dropped from
    the solution."""
    x0 = np.asarray(x0, dtype=float)[: nlp.n_x]
    if not set_steps(nlp, x0):
        return LandingSolution(x0, False, math.nan, math.nan, "start point does not land")
    s, landed = solver(nlp, options)
    _, _, rows = statistic_objectives(nlp, landed, ca.MX.sym("v", landed.n_f))
    lo_e, hi_e = _extra_bounds(nlp)
    lbg = np.concatenate([nlp.lbg, *(lo for _, lo, _ in rows)])
    ubg = np.concatenate([nlp.ubg, *(hi for _, _, hi in rows)])
    ubg[0] = eps
    sol = s(x0=np.concatenate([x0, _extra_start(nlp, landed, x0)]), p=list(weights),
            lbx=np.concatenate([nlp.lbx, lo_e]), ubx=np.concatenate([nlp.ubx, hi_e]), lbg=lbg, ubg=ubg)
    stats = s.stats()
    # IPOPT relaxes the bounds by 1e-8 (bound_relax_factor): a joint angle at its limit ended 1e-8
    # rad past it, and the realised design was dropped as infeasible (studies/splayed_toes/results.md)
    x = np.clip(np.asarray(sol["x"]).ravel()[: nlp.n_x], nlp.lbx, nlp.ubx)
    return LandingSolution(x, bool(stats["success"]), float(sol["f"]), float(np.asarray(sol["g"]).ravel()[0]),
                           str(stats["return_status"]))


def realise_landing(nlp: LandingNlp, x: np.ndarray) -> DesignEvaluation | None:
    """The design of an NLP point, evaluated by the study's landing, over ``landings`` by the outer
    search's evaluation (masses rescaled to the budget in EQUAL mode); None when it is not
    feasible."""
    cfg, lim = nlp.config, nlp.config.limits
    design = nlp.design(x)
    if lim.mass_mode is MassMode.EQUAL:
        total = design.foot_mass
        n_all = len(design.segments)
        scale = (lim.foot_mass - n_all * lim.min_link_mass) / (total - n_all * lim.min_link_mass)
        design = FootDesign(
            heel=tuple(replace(s, mass=lim.min_link_mass + (s.mass - lim.min_link_mass) * scale) for s in design.heel),
            toes=tuple(tuple(replace(s, mass=lim.min_link_mass + (s.mass - lim.min_link_mass) * scale) for s in t)
                       for t in design.toes),
            toe_yaws=design.toe_yaws,
        )
    def evaluate(d: FootDesign) -> DesignEvaluation | None:
        if cfg.landings is not None:  # the outer search's evaluation over the landings
            from optimizer.search.outer import evaluate_design_over_landings

            ev = evaluate_design_over_landings(cfg, d)
        else:
            ev = evaluate_design_landing(cfg.leg, d, cfg.scene, lim, cfg.space.joint_laws.stop_restitution,
                                         cfg.search.landing_tolerance)
        return ev if ev.objectives is not None and ev.feasible else None

    ev = evaluate(design)
    if ev is not None:
        return ev
    # off the constraints (an unfinished solve, or rounding): the lengths from the linear program
    angles = tuple(tuple(s.joint_angle for s in c) for c in design.chains)
    masses = tuple(tuple(s.mass for s in c) for c in design.chains)
    assignment = assign_lengths(cfg.leg, nlp.shape, angles, masses, lim, toe_yaws=design.toe_yaws)
    return None if assignment is None else evaluate(with_lengths(design, assignment))


def landing_sweep(nlp: LandingNlp, rng: np.random.Generator) -> Iterator[DesignEvaluation]:
    """Anchors (each objective's minimum over ``search.starts`` random starts, the other as a
    tie-break), then ``search.front_points`` epsilon solves between them, each started from the
    previous one. A solve counts by its realised design (:func:`realise_landing`), whatever
    IPOPT's status: the landing's objective is only piecewise smooth, so IPOPT often stops at its
    iteration limit or an acceptable level rather than at its tolerance. Yields every feasible
    realised design, in a fixed order."""
    cfg = nlp.config
    starts = [x0 for x0 in (start_landing(nlp, rng) for _ in range(cfg.search.starts)) if x0 is not None]
    two = len(landing_objectives_of(cfg)) > 1
    weights = ((1.0, 1e-4), (1e-4, 1.0)) if two else ((1.0, 0.0),)
    anchors = []
    for w in weights:
        best = None
        for x0 in starts:
            s = solve_landing(nlp, w, math.inf, x0)
            if math.isfinite(s.f) and (best is None or s.f < best[0].f):
                ev = realise_landing(nlp, s.x)  # the study's landing decides, not IPOPT's status
                if ev is not None:
                    best = (s, ev)
        if best is not None:
            anchors.append(best)
            yield best[1]
    if len(anchors) < 2 or cfg.search.front_points == 0:
        return
    (first, _), (second, _) = anchors
    if not first.f2 > second.f2:
        return
    previous = first
    for eps in np.linspace(first.f2, second.f2, cfg.search.front_points + 2)[1:-1]:
        s = solve_landing(nlp, weights[0], float(eps), previous.x)
        ev = realise_landing(nlp, s.x) if math.isfinite(s.f) else None
        if ev is not None:
            yield ev
            previous = s


__all__ = [
    "LANDING_IPOPT",
    "LandingNlp",
    "LandingSolution",
    "build_landing_nlp",
    "landing_sweep",
    "realise_landing",
    "landing_settings",
    "rpy_rates",
    "scenario_scenes",
    "set_steps",
    "solve_landing",
    "start_landing",
]
