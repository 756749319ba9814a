#!/usr/bin/env python3
"""Time per evaluation and error of each rigid rung of the impact-model ladder (decoupled eq. 14,
Newton eq. 11, complementarity LCP, Coulomb friction; impulse_core/contact_models.py) on the
paper's cases, against the finest rung that applies to the scene (FRICTION when the scene has
friction, else LCP, which is exact for frictionless rigid contact).

Errors: ``external``: |lambda - lambda_ref| / |lambda_ref| over the contact impulse vectors
(normal and tangential parts); ``internal``: the same over the joint impulse magnitudes;
``v+``: the post-impact velocity's error in the energy norm, sqrt(dv^T M dv / v-^T M v-).
Timings: the full ``evaluate()`` path, median over repeats, after a first call that builds the
CasADi functions (its time is the ``build`` column, measured from empty caches); the rungs are
timed in turn, in batches, and the fastest batch counts (robust to a shared, noisy machine).
Quote the ratios to the Newton rung, not the microseconds (machines differ).

Usage (from the repository root):
    .venv/bin/python studies/rigid_rungs/bench_rigid_rungs.py           # print the tables (markdown)
    .venv/bin/python studies/rigid_rungs/bench_rigid_rungs.py --write   # and write studies/fidelity/rigid_rungs.md
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import itertools
import math
import platform
import sys
import time
from collections.abc import Callable
from pathlib import Path

import casadi as ca
import numpy as np

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:  # run from a checkout without installing the package
    sys.path.insert(0, str(ROOT))

from impulse_core import evaluate as evaluate_module  # noqa: E402
from impulse_core.impact.laws import ImpactModel, complementarity_impulse, coulomb_impulse  # noqa: E402
from impulse_core.evaluate import ImpactResult, evaluate  # noqa: E402
from impulse_core.impact.delassus import mass_matrix_function  # noqa: E402
from impulse_core.model.tree import Body, ContactSelection, JointKind, Scene, Tree, design_vector  # noqa: E402

OUTPUT = ROOT / "studies" / "fidelity" / "rigid_rungs.md"
CONFIGS = ROOT / "configs"


def three_toe_leg() -> Tree:
    """Fallback when configs/paper_case3.yaml is missing: case 3's structure (ERRATA.md) with
    illustrative angles."""
    toe = []
    for k in (1, 2, 3):
        toe.append(Body(f"toe{k}_proximal", 1, 0.3, 0.0889, 1.54))
        toe.append(Body(f"toe{k}_distal", 3 + 2 * (k - 1), 0.15, 0.0444, 0.26, contacts=(1.0,)))
    return Tree((
        Body("thigh", None, 0.7, 1.0, -1.12),
        Body("shank", 0, 0.7, 1.0, -0.68),
        Body("heel", 1, 0.15, 0.1, -0.8, contacts=(1.0,)),
        *toe,
    ))  # fmt: skip


def pulling_leg() -> Tree:
    """A welded toe with two nearly coincident contacts (tests/optimizer/conftest.py): Newton's
    law makes one of them pull."""
    return Tree((
        Body("thigh", None, 0.7, 1.0, -1.2),
        Body("shank", 0, 0.7, 1.0, 0.6),
        Body("heel", 1, 0.15, 0.1, 2.0, contacts=(1.0,)),
        Body("toe", 1, 0.2, 0.1, -1.0, joint=JointKind.FIXED, contacts=(1.0, 0.5)),
    ))  # fmt: skip


def scenes() -> list[tuple[str, Tree, Scene]]:
    """(name, tree, scene): the paper's cases as given (frictionless, all soles at once), case 3
    with Coulomb friction 0.3 and 1.0, and the pulling leg."""
    out = []
    paper = Scene(speed=3.43, restitution=0.8, selection=ContactSelection.ALL)
    for case in (1, 2, 3):
        path = CONFIGS / f"paper_case{case}.yaml"
        if path.exists():
            from optimizer.config.model_file import load_model_file

            model = load_model_file(path)
            out.append((f"paper case {case}", model.tree, model.scene))
        elif case == 3:
            out.append(("3-toe leg (paper case 3 structure, built in code)", three_toe_leg(), paper))
    name3, tree3, scene3 = next(s for s in out if "3" in s[0])
    for mu in (0.3, 1.0):
        out.append((f"{name3.split(' (')[0]}, friction {mu:g}", tree3, dataclasses.replace(scene3, friction=mu)))
    out.append(("pulling leg (welded toe)", pulling_leg(), paper))
    return out


@dataclasses.dataclass(frozen=True)
class Row:
    requested: str
    ran: ImpactModel
    us_per_eval: float
    build_ms: float
    external_error: float
    internal_error: float
    v_error: float
    energy_after: float
    energy_before: float
    hop: float
    max_impulse: float
    notes: str


def _interleaved_min_us(fns: dict[str, Callable[[], object]], calls: int, repeats: int = 7) -> dict[str, float]:
    """Microseconds per call of each function: batches of ``calls`` calls, the functions taken in
    turn (so that a load change on a shared machine hits them all), the fastest batch of each."""
    best = {k: math.inf for k in fns}
    for _ in range(repeats):
        for k, fn in fns.items():
            t0 = time.perf_counter()
            for _ in range(calls):
                fn()
            best[k] = min(best[k], (time.perf_counter() - t0) / calls * 1e6)
    return best


def _clear_caches() -> None:
    for name in ("compiled_model", "compiled_metric", "compiled_friction"):
        getattr(evaluate_module, name).cache_clear()


def _hop(res: ImpactResult, scene: Scene) -> float:
    """The largest v+_n + e v-_n (m/s) at a contact that carries impulse: 0 under Newton's law and
    the LCP; the convex friction law's "hop" at sliding contacts (contact_models, known limits)."""
    lam = res.external[list(res.active)]
    loaded = lam > 1e-12 * max(float(lam.max(initial=0.0)), 1e-300)
    y = res.contact_velocity - scene.restitution * scene.speed
    return float(np.max(y[loaded], initial=0.0))


def _relative(a: np.ndarray, b: np.ndarray) -> float:
    scale = float(np.linalg.norm(b))
    return float(np.linalg.norm(a - b) / scale) if scale > 0 else float(np.linalg.norm(a - b))


def rung_rows(tree: Tree, scene: Scene, calls: int = 200) -> tuple[ImpactModel, list[Row]]:
    """One row per requested rung (and 'auto'): timing and error against the finest applicable rung."""
    finest = ImpactModel.FRICTION if scene.friction > 0 else ImpactModel.LCP
    reference = evaluate(tree, scene, finest)
    M = np.array(mass_matrix_function(tree.topology())(p=design_vector(tree))["M"])
    v_scale = math.sqrt(reference.v_minus @ M @ reference.v_minus)
    ref_contact = np.concatenate([reference.external, reference.tangential])
    requests = {"auto" if r is None else r.value: r for r in (None, *ImpactModel)}
    results: dict[str, ImpactResult] = {}
    build_ms: dict[str, float] = {}
    for label, requested in requests.items():
        _clear_caches()
        t0 = time.perf_counter()
        results[label] = evaluate(tree, scene, requested)
        build_ms[label] = (time.perf_counter() - t0) * 1e3
    for requested in requests.values():  # warm every cache before timing
        evaluate(tree, scene, requested)
    us = _interleaved_min_us({k: functools.partial(evaluate, tree, scene, r) for k, r in requests.items()}, calls)
    rows = []
    for label, requested in requests.items():
        res = results[label]
        dv = res.v_plus - reference.v_plus
        notes = []
        if res.pulling:
            notes.append(f"{len(res.pulling)} pulling")
        if res.separating:
            notes.append(f"{len(res.separating)} separating")
        if not res.split_unique:
            notes.append("split not unique")
        if requested is ImpactModel.FRICTION and scene.friction == 0:
            notes.append("mu = 0: the LCP")
        rows.append(Row(
            requested=label,
            ran=res.model,
            us_per_eval=us[label],
            build_ms=build_ms[label],
            external_error=_relative(np.concatenate([res.external, res.tangential]), ref_contact),
            internal_error=_relative(res.internal_magnitude, reference.internal_magnitude),
            v_error=math.sqrt(abs(dv @ M @ dv)) / v_scale,
            energy_after=res.energy_after,
            energy_before=res.energy_before,
            hop=_hop(res, scene),
            max_impulse=float(np.max(np.abs(res.external))),
            notes=", ".join(notes),
        ))  # fmt: skip
    return finest, rows


@dataclasses.dataclass(frozen=True)
class Exact:
    """A solution of the exact (non-convex) Coulomb-Newton impact law: contact modes, impulses,
    and what follows from them."""

    modes: tuple[str, ...]
    normal: np.ndarray
    tangential: np.ndarray
    internal_magnitude: np.ndarray
    v_plus: np.ndarray


MODES = ("separates", "sticks", "slides +x", "slides -x")


def exact_coulomb(tree: Tree, scene: Scene, max_contacts: int = 6) -> list[Exact]:
    """Every solution of Newton's restitution with Coulomb friction in its exact complementarity
    form (Stewart & Trinkle's impact law; no convex relaxation), by enumerating the 4^n contact
    modes: separating (no impulse, v+_n >= e s), sticking (v+_n = e s, v+_t = 0, inside the
    cone), sliding either way (v+_n = e s, impulse on the cone's edge against the slip). A study
    reference only: exponential in the contacts, and the law may have several solutions or none."""
    active = evaluate_module.active_contacts(tree, scene)
    n = len(active)
    if n > max_contacts:
        return []
    topology = tree.topology(active)
    v = evaluate_module.approach_velocity(topology, scene.speed)
    p = design_vector(tree)
    out = evaluate_module.compiled_metric(topology, tangent=True)(p=p, v_minus=v)
    J, W = np.array(out["contact_jacobian"]), np.array(out["delassus"])
    w = J @ v
    e, mu = scene.restitution, scene.friction
    eye = np.eye(2 * n)
    solutions = []
    for modes in itertools.product(range(4), repeat=n):
        rows, rhs = [], []
        for i, mode in enumerate(modes):
            if mode == 0:
                rows += [eye[i], eye[n + i]]
                rhs += [0.0, 0.0]
                continue
            rows.append(W[i])  # v+_n = -e v-_n
            rhs.append(-(1 + e) * w[i])
            if mode == 1:
                rows.append(W[n + i])  # v+_t = 0 (v-_t = 0 when landing straight down; kept general)
                rhs.append(-w[n + i])
            else:  # on the cone's edge, against the slip
                rows.append(eye[n + i] + (mu if mode == 2 else -mu) * eye[i])
                rhs.append(0.0)
        R, r = np.array(rows), np.array(rhs)
        lam = np.linalg.lstsq(R, r, rcond=None)[0]
        if np.abs(R @ lam - r).max() > 1e-9 * np.abs(r).max():
            continue
        vp = w + W @ lam
        ln, lt, tol = lam[:n], lam[n:], 1e-9 * max(np.abs(lam).max(), 1.0)
        vtol = 1e-9 * scene.speed
        ok = True
        for i, mode in enumerate(modes):
            if mode == 0:
                ok &= vp[i] >= e * scene.speed - vtol
            else:
                ok &= ln[i] >= -tol
                ok &= (abs(lt[i]) <= mu * ln[i] + tol) if mode == 1 else (vp[n + i] >= -vtol if mode == 2 else
                                                                            vp[n + i] <= vtol)
        if ok:
            resp = evaluate_module.compiled_friction(topology)(p=p, v_minus=v, external=ln, tangential=lt)
            solutions.append(Exact(
                modes=tuple(MODES[m] for m in modes),
                normal=ln,
                tangential=lt,
                internal_magnitude=np.array(resp["internal_magnitude"]).ravel(),
                v_plus=np.array(resp["v_plus"]).ravel(),
            ))  # fmt: skip
    return solutions


@dataclasses.dataclass(frozen=True)
class ExactComparison:
    """Errors of a rung (or of the study-only KE-min law) against the exact Coulomb-Newton solution."""

    label: str
    external_error: float
    internal_error: float
    v_error: float
    normal_error: float  # the largest relative error of one contact's normal impulse


def ke_min_law(tree: Tree, scene: Scene) -> tuple[np.ndarray, np.ndarray] | None:
    """The other convex law (study only, cvxpy): minimise the post-impact kinetic energy over the
    Coulomb cone with Newton's restitution as a constraint, v+_n >= -e v-_n (the law the
    contact_models docstring rejects: it does not stick for e > 0). None without cvxpy."""
    try:
        import cvxpy as cp
    except ImportError:
        return None
    active = evaluate_module.active_contacts(tree, scene)
    topology = tree.topology(active)
    n = len(active)
    v = evaluate_module.approach_velocity(topology, scene.speed)
    out = evaluate_module.compiled_metric(topology, tangent=True)(p=design_vector(tree), v_minus=v)
    J, W, E = (np.array(out[k]) for k in ("contact_jacobian", "delassus", "metric_factor"))
    u = np.array(out["u_minus"]).ravel()
    w = J @ v
    lam = cp.Variable(2 * n)
    constraints = [cp.abs(lam[n:]) <= scene.friction * lam[:n], W[:n] @ lam + w[:n] >= -scene.restitution * w[:n]]
    cp.Problem(cp.Minimize(0.5 * cp.sum_squares(E @ lam + u)), constraints).solve(solver=cp.CLARABEL)
    return np.asarray(lam.value[:n]), np.asarray(lam.value[n:])


def _respond(tree: Tree, scene: Scene, ln: np.ndarray, lt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(internal magnitudes, v+) of given normal and tangential impulses."""
    topology = tree.topology(evaluate_module.active_contacts(tree, scene))
    v = evaluate_module.approach_velocity(topology, scene.speed)
    resp = evaluate_module.compiled_friction(topology)(p=design_vector(tree), v_minus=v, external=ln, tangential=lt)
    return np.array(resp["internal_magnitude"]).ravel(), np.array(resp["v_plus"]).ravel()


def exact_comparison(tree: Tree, scene: Scene) -> tuple[list[Exact], list[ExactComparison]]:
    """The exact solutions, and (when there is exactly one) the friction and LCP rungs and the
    KE-min law against it."""
    solutions = exact_coulomb(tree, scene)
    if len(solutions) != 1:
        return solutions, []
    ex = solutions[0]
    M = np.array(mass_matrix_function(tree.topology())(p=design_vector(tree))["M"])
    candidates = {}
    for model in (ImpactModel.FRICTION, ImpactModel.LCP):
        res = evaluate(tree, scene, model)
        act = list(res.active)
        candidates[model.value] = (
            res.external[act], res.tangential[act], res.internal_magnitude, res.v_plus, res.v_minus
        )
    other = ke_min_law(tree, scene)
    if other is not None:
        candidates["KE-min law (study, cvxpy)"] = (*other, *_respond(tree, scene, *other), candidates["lcp"][4])
    out = []
    for label, (ln, lt, internal, v_plus, v_minus) in candidates.items():
        dv = v_plus - ex.v_plus
        out.append(ExactComparison(
            label=label,
            external_error=_relative(np.concatenate([ln, lt]), np.concatenate([ex.normal, ex.tangential])),
            internal_error=_relative(internal, ex.internal_magnitude),
            v_error=math.sqrt(abs(dv @ M @ dv) / (v_minus @ M @ v_minus)),
            normal_error=float(np.max(np.abs(ln - ex.normal) / np.maximum(np.abs(ex.normal), 1e-300))),
        ))  # fmt: skip
    return solutions, out


def random_friction_errors(count: int = 40, seed: int = 4001) -> dict[str, list[float]]:
    """v+ error (energy norm) against the exact Coulomb-Newton law on seeded random frictional
    scenes (tests/conftest.py's generator; 2-6 contacts, mu in {0.1 ... 2}) where that law has one
    solution: the friction rung, the KE-min law and the frictionless LCP."""
    from tests.conftest import random_tree

    rng = np.random.default_rng(seed)
    errors: dict[str, list[float]] = {}
    tried = 0
    while tried < count:
        tree = random_tree(rng, int(rng.integers(1, 8)), max_contacts_per_body=2, p_contact=0.7)
        if not 2 <= len(tree.contacts) <= 6:
            continue
        tried += 1
        scene = Scene(speed=float(rng.uniform(0.5, 5.0)), restitution=float(rng.uniform(0.0, 1.0)),
                      friction=float(rng.choice([0.1, 0.3, 0.6, 1.0, 2.0])), selection=ContactSelection.ALL)
        _, comparisons = exact_comparison(tree, scene)
        for c in comparisons:
            errors.setdefault(c.label, []).append(c.v_error)
    return errors


def exact_table(tree: Tree, solutions: list[Exact], comparisons: list[ExactComparison]) -> str:
    """The friction rung and the frictionless LCP against the exact Coulomb-Newton law."""
    if not comparisons:
        return f"Exact Coulomb-Newton law (contact modes enumerated): {len(solutions)} solutions, no comparison.\n"
    ex = solutions[0]
    names = [f"{tree.bodies[b].name}[{k}]" for b, k in tree.contacts]
    lines = [
        f"Against the exact Coulomb-Newton law (contact modes enumerated; one solution: "
        f"{', '.join(f'{n} {m}' for n, m in zip(names, ex.modes, strict=True))}; normal impulses "
        f"{', '.join(f'{x:.4f}' for x in ex.normal)} N s):",
        "",
        "| rung | external error | internal error | v+ error | largest error of one normal impulse |",
        "|---|---:|---:|---:|---:|",
    ]
    for c in comparisons:
        lines.append(f"| {c.label} | {_pct(c.external_error)} | {_pct(c.internal_error)} | {_pct(c.v_error)} "
                     f"| {_pct(c.normal_error)} |")
    return "\n".join(lines) + "\n"


def markdown(name: str, tree: Tree, scene: Scene, finest: ImpactModel, rows: list[Row]) -> str:
    newton = next(r for r in rows if r.requested == "newton").us_per_eval
    lines = [
        f"### {name}",
        "",
        f"{tree.n_bodies} bodies, {len(tree.contacts)} contacts; speed {scene.speed:g} m/s, e = {scene.restitution:g}, "
        f"friction {scene.friction:g}. Reference: the {finest.value} rung.",
        "",
        "| requested | ran | time / newton | us per evaluation | build ms | external error | internal error "
        "| v+ error | kinetic energy after / before | hop m/s | notes |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r.requested} | {r.ran.value} | {r.us_per_eval / newton:.2f} | {r.us_per_eval:.0f} | {r.build_ms:.0f} "
            f"| {_pct(r.external_error)} | {_pct(r.internal_error)} | {_pct(r.v_error)} "
            f"| {r.energy_after / r.energy_before:.4f} | {max(r.hop, 0.0):.3f} | {r.notes} |"
        )
    return "\n".join(lines) + "\n"


def _pct(x: float) -> str:
    return "0" if x < 1e-12 else f"{100 * x:.2g} %" if x >= 1e-4 else f"{x:.1e}"


def solver_times(tree: Tree, scene: Scene, calls: int) -> dict[str, float]:
    """Microseconds of the solve alone (no model evaluation): the core's NNLS for the LCP and the
    friction program, eq. 11 as a dense solve, and cvxpy (Clarabel) on the same LCP and friction
    programs, parametrised once so that only the solve is timed (when cvxpy is installed)."""
    active = evaluate_module.active_contacts(tree, scene)
    topology = tree.topology(active)
    v = evaluate_module.approach_velocity(topology, scene.speed)
    n = len(active)
    out = evaluate_module.compiled_metric(topology, tangent=True)(p=design_vector(tree), v_minus=v)
    J, A, E = (np.array(out[k]) for k in ("contact_jacobian", "delassus", "metric_factor"))
    f = -(1 + scene.restitution) * np.array(out["u_minus"]).ravel()
    b = E[:, :n].T @ f
    mu = scene.friction or 0.3
    fns: dict[str, Callable[[], object]] = {
        "eq. 11, dense solve (numpy)": lambda: np.linalg.solve(A[:n, :n], b),
        "LCP, NNLS (core)": lambda: complementarity_impulse(E[:, :n], f),
        f"friction mu = {mu:g}, NNLS (core)": lambda: coulomb_impulse(E[:, :n], E[:, n:], f, mu),
    }
    try:
        import cvxpy as cp
    except ImportError:
        cp = None
    if cp is not None:
        lam = cp.Variable(n)
        lcp = cp.Problem(cp.Minimize(0.5 * cp.sum_squares(E[:, :n] @ lam - f)), [lam >= 0])
        ln, lt = cp.Variable(n), cp.Variable(n)
        fric = cp.Problem(cp.Minimize(0.5 * cp.sum_squares(E[:, :n] @ ln + E[:, n:] @ lt - f)), [cp.abs(lt) <= mu * ln])
        lcp.solve(solver=cp.CLARABEL)
        fric.solve(solver=cp.CLARABEL)
        fns["LCP, cvxpy + Clarabel"] = lambda: lcp.solve(solver=cp.CLARABEL)
        fns[f"friction mu = {mu:g}, cvxpy + Clarabel"] = lambda: fric.solve(solver=cp.CLARABEL)
    return _interleaved_min_us(fns, max(calls // 10, 5) if cp is not None else calls)


def reading(
    results: dict[str, tuple[ImpactModel, list[Row]]],
    exact: dict[str, list[ExactComparison]],
    solvers: dict[str, float],
    random_errors: dict[str, list[float]],
) -> str:
    """A short reading of the tables, with the numbers taken from them."""

    def row(scene: str, requested: str) -> Row:
        return next(r for r in results[scene][1] if r.requested == requested)

    def ratio(requested: str) -> str:
        values = [r.us_per_eval / row(name, "newton").us_per_eval for name, (_, rows) in results.items()
                  for r in rows if r.requested == requested]
        return f"{min(values):.1f}-{max(values):.1f}x"

    case3 = next(name for name in results if "3" in name and "friction" not in name)
    lines = [
        "### Reading",
        "",
        f"- **Cost.** Per full evaluation, against Newton (eq. 11): decoupled {ratio('decoupled')}, LCP "
        f"{ratio('lcp')}, friction {ratio('friction')}. The automatic choice costs what Newton costs where "
        f"Newton is exact, and Newton + LCP where a contact would pull. The LCP and friction rungs add a second "
        f"CasADi call (the contact problem in the kinetic-energy metric) and an NNLS in numpy (block principal "
        f"pivoting, Lawson-Hanson as fallback). The solve alone on {case3}: "
        + "; ".join(f"{k} {us:.0f} us" for k, us in solvers.items()) + ".",
    ]
    d = row(case3, "decoupled")
    if "paper case 1" in results:
        case1 = row("paper case 1", "decoupled")
        flat = (f"; on paper case 1 (a flat foot) {_pct(case1.external_error)} and {_pct(case1.internal_error)}, "
                f"keeping {case1.energy_after / case1.energy_before:.1%} of the kinetic energy where eq. 11 keeps "
                f"{row('paper case 1', 'newton').energy_after / case1.energy_before:.1%}")
    else:
        flat = ""
    lines.append(
        f"- **Decoupled (eq. 14) vs eq. 11.** Exact only when all impulses are equal. On {case3} its external "
        f"impulses are {_pct(d.external_error)} off and its joint impulses {_pct(d.internal_error)}{flat}; it can "
        f"also create energy (tests/optimizer/test_impact_model_cli.py). For reproducing the paper only."
    )
    pulling = next((name for name in results if "pulling" in name), None)
    if pulling:
        n, lcp = row(pulling, "newton"), row(pulling, "lcp")
        lines.append(
            f"- **Newton vs LCP.** On the paper's cases every Newton impulse is >= 0, so Newton is the LCP answer "
            f"and the automatic choice runs Newton. On the {pulling} Newton's split is absurd (impulses up to "
            f"{n.max_impulse:.3g} N s, one pulling, against {lcp.max_impulse:.3g} N s for the LCP, which lets two "
            f"contacts separate): the rung matters whenever a design loads nearly dependent contacts."
        )
    for name, comparisons in exact.items():
        f, n = row(name, "friction"), row(name, "newton")
        text = (f"- **{name}.** The frictionless rungs are {_pct(n.external_error)} off the friction rung in the "
                f"contact impulses and {_pct(n.v_error)} in v+.")
        by = {c.label: c for c in comparisons}
        if "friction" in by:
            fc, lc = by["friction"], by["lcp"]
            text += (
                f" Against the exact Coulomb-Newton law (contact modes above) the friction rung is "
                f"{_pct(fc.external_error)} off in the contact impulses (one normal impulse by "
                f"{_pct(fc.normal_error)}, v+ by {_pct(fc.v_error)}), the frictionless LCP {_pct(lc.external_error)} "
                f"(v+ {_pct(lc.v_error)}): the convex relaxation's hop (a sliding contact leaves up to {f.hop:.2f} m/s "
                f"faster than restitution while carrying impulse) inflates the normal impulse of sliding contacts."
            )
            ke = by.get("KE-min law (study, cvxpy)")
            if ke is not None:
                text += (f" The KE-min law (restitution as a constraint), which the friction rung does not use "
                         f"because it cannot stick for e > 0, is {_pct(ke.external_error)} off here.")
        lines.append(text)
    if random_errors:
        summary = "; ".join(f"{label} median {_pct(float(np.median(v)))}, worst {_pct(max(v))}"
                            for label, v in random_errors.items())
        lines.append(
            f"- **Friction laws on {len(next(iter(random_errors.values())))} random frictional scenes** (seeded, "
            f"tests/conftest.py's trees, sticking and sliding mixed, exact law unique), v+ error in the energy norm "
            f"against the exact Coulomb-Newton law: {summary}. Neither convex law dominates: the friction rung is "
            f"exact for sticking contacts, the KE-min law for sliding ones; an exact rung (the enumerated contact "
            f"modes here, or a mode polish of the friction rung's answer) is the next step if friction matters."
        )
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--write", action="store_true", help=f"write the tables to {OUTPUT.relative_to(ROOT)}")
    parser.add_argument("--calls", type=int, default=200, help="evaluations per timing batch (default 200)")
    args = parser.parse_args(argv)
    parts = [
        "## Rigid rungs: time per evaluation and error against the finest rung",
        "",
        f"Generated by `studies/rigid_rungs/bench_rigid_rungs.py` ({platform.machine()}, Python "
        f"{platform.python_version()}, CasADi {ca.__version__}, numpy {np.__version__}; CasADi's virtual machine, no "
        f"compiled C). Errors: relative norm of the contact impulses (normal and tangential), of the joint impulse "
        f"magnitudes, and of v+ in the energy norm, each against the reference rung; 0 means below 1e-12. Times: "
        f"the full `evaluate()` call, fastest of 7 interleaved batches; quote the ratio to newton. hop: the largest "
        f"v+_n + e v-_n at a contact that carries impulse (0 where Newton's restitution holds).",
        "",
    ]
    results = {}
    exact: dict[str, list[ExactComparison]] = {}
    all_scenes = scenes()
    for name, tree, scene in all_scenes:
        finest, rows = rung_rows(tree, scene, args.calls)
        results[name] = (finest, rows)
        parts.append(markdown(name, tree, scene, finest, rows))
        if scene.friction > 0:
            solutions, comparisons = exact_comparison(tree, scene)
            exact[name] = comparisons
            parts.append(exact_table(tree, solutions, comparisons))
    case3 = next((t, s) for name, t, s in all_scenes if "3" in name and "friction" not in name)
    parts.append(reading(results, exact, solver_times(*case3, args.calls), random_friction_errors()))
    text = "\n".join(parts)
    print(text)
    if args.write:
        OUTPUT.parent.mkdir(parents=True, exist_ok=True)
        OUTPUT.write_text(text, encoding="utf-8")
        print(f"written: {OUTPUT.relative_to(ROOT)}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
