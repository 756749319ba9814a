"""Random whole landings against the contract (``docs/MODEL_FORMAT.md``, "Precise meanings").

A seeded generator of valid landing model files (planar and spatial trees of 1-6 rods, chains
and branches, contacts, joint springs, dampers, rests, stops, oblique approaches and spins,
friction 0 / 0.3 / 0.5 / 1, restitution, gravity, a duration of 0.02-0.5 s, sometimes a planar
``terrain`` or a spatial ``heightfield``) and a runner that lands each file and checks what the
outside checks check:

- exit status: 0; 2 with one line on stderr and no traceback is a refusal (reported as such);
  anything else (1: a numerical failure, a traceback, the wall-clock limit) fails;
- the first event against the first-impact rung on the same file (``--model lcp``, or
  ``friction`` when the scene has friction): the relative difference per list (``external``,
  ``internal``, ``tangential``: max |a_i - b_i| / max |b_i|), the largest, at most 1e-9;
- the momentum balance over the landing, at most 1e-4: the change of the tree's linear momentum
  over [0, T] minus the contact impulses (each contact's total normal impulse along +y, the
  ground's normal, plus its total tangential impulse along x, and z in space) minus the weight's
  impulse -m g T, largest component, over max(|p0|, m g T) (the contract's reference for the
  landing's own balance). The JSON has no tangential totals, and the momentum of a tree is its
  kinematics, so each file runs in a worker process that is ``python -m optimizer evaluate FILE
  --json`` itself (the CLI's ``main``, its stdout and exit status passed through) with a spy on
  ``model_choice.landing`` that keeps the LandingResult the CLI reported; the worker computes
  p0 and p1 with footopt's own kinematics (``_Landing.point(...).momentum``, as
  ``tests/impulse_core/test_landing_spatial.py::_momentum_error`` does) from the touchdown state
  and ``q_final``/``v_final``, and the runner checks that the spied result's ``total_external`` is
  the JSON's. On a terrain or heightfield the contact normals move with the contacts, so totals
  per contact do not give the impulse's direction: there the figure is the run's own
  ``momentum_balance`` (its world-frame impulse sum), marked ``own``.
  The same worker runs the first-impact rung first, in-process, through the same ``main``.
- the wall time of the worker (the landing and the first impact; startup included).

Run: python studies/whole_landing/random_landings.py --seeds 30000 30100 [--limit 60]
     [--spatial 0.5] [--terrain 0.3] [--heightfield 0.3] [--axis 0] [--inertia 0] [--offset 0] [--tensor 0] [--out DIR]
Prints one line per seed and a Markdown summary; keeps every file and a ``results.jsonl`` in DIR.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
import os
import subprocess
import sys
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

REPO = Path(__file__).resolve().parents[2]
#: The contract's bounds.
FIRST_EVENT_TOL = 1e-9
BALANCE_TOL = 1e-4
FRICTIONS = (0.0, 0.3, 0.5, 1.0)
DEFAULT_LIMIT = 60.0


@dataclass(frozen=True)
class Options:
    """Probabilities (and ranges) of the generator."""

    spatial: float = 0.5  # a spatial model
    terrain: float = 0.3  # planar: a piecewise-linear terrain
    heightfield: float = 0.3  # spatial: a heightfield
    max_bodies: int = 6
    chain: float = 0.6  # a body's parent is the previous body (else any earlier one)
    fixed: float = 0.12  # a welded joint
    contacts: float = 0.6  # a non-base body has contacts
    stiffness: float = 0.6
    damping: float = 0.5
    rest: float = 0.3
    limits: float = 0.3
    stop_restitution: float = 0.5  # given limits
    velocity: float = 0.5  # scene.velocity instead of speed
    angular_velocity: float = 0.3
    gravity: float = 0.85
    contacts_all: float = 0.1  # scene.contacts: all
    radius: float = 0.8  # spatial: a body has a radius (else 0)
    splay: float = 0.6  # spatial: a non-base body has a splayed rpy
    duration: tuple[float, float] = (0.02, 0.5)  # log-uniform
    # Drawn from a second stream (:func:`_rigid_extras`), so a seed's file is the same as before
    # these options existed wherever they are 0 (their default):
    axis: float = 0.0  # spatial: a revolute joint turns about a random axis (else z)
    inertia: float = 0.0  # a body has `gyration` or `inertia` (else a uniform rod's)
    offset: float = 0.0  # a body's centre of mass is off its axis (`com_offset`)
    tensor: float = 0.0  # spatial: a body has a full `inertia_tensor` (instead of the above)


def _r(x: float) -> float:
    """x to 6 significant digits (readable files)."""
    return float(f"{x:.6g}")


def _log_uniform(rng: np.random.Generator, lo: float, hi: float) -> float:
    return _r(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def random_model(seed: int, options: Options = Options()) -> dict[str, Any]:
    """A valid landing model file (as a YAML-ready dict) for ``seed``: deterministic."""
    rng = np.random.default_rng(seed)
    spatial = bool(rng.random() < options.spatial)
    n = int(rng.integers(1, options.max_bodies + 1))
    bodies: list[dict[str, Any]] = []
    for i in range(n):
        b: dict[str, Any] = {"name": f"b{i}", "length": _log_uniform(rng, 0.04, 0.8), "mass": _log_uniform(rng, 0.02, 3.0)}
        if i == 0:
            b["angle"] = _r(rng.uniform(-math.pi, math.pi))
        else:
            parent = i - 1 if rng.random() < options.chain else int(rng.integers(0, i))
            b["parent"] = f"b{parent}"
            if rng.random() < 0.3:
                b["at"] = _r(rng.uniform(0.0, 1.0))
            b["angle"] = _r(rng.uniform(-2.2, 2.2))
            if rng.random() < options.fixed:
                b["joint"] = "fixed"
            else:
                b["joint"] = "revolute"
                if rng.random() < options.stiffness:
                    b["stiffness"] = _log_uniform(rng, 0.5, 300.0)
                if rng.random() < options.damping:
                    b["damping"] = _log_uniform(rng, 0.005, 10.0)
                if rng.random() < options.rest:
                    b["rest"] = _r(b["angle"] + rng.uniform(-0.4, 0.4))
                if rng.random() < options.limits:
                    b["limits"] = [_r(b["angle"] - rng.uniform(0.05, 1.2)), _r(b["angle"] + rng.uniform(0.05, 1.2))]
                    if rng.random() < options.stop_restitution:
                        b["stop_restitution"] = _r(rng.uniform(0.0, 1.0))
        if (i > 0 or n == 1 or rng.random() < 0.3) and rng.random() < options.contacts:
            b["contacts"] = _contacts(rng)
        if rng.random() < 0.15:
            b["com"] = _r(rng.uniform(0.2, 0.8))
        if spatial:
            if rng.random() < options.radius:
                b["radius"] = _r(rng.uniform(0.003, 0.02))
            if i > 0 and rng.random() < options.splay:
                b["rpy"] = [_r(rng.uniform(-0.5, 0.5)), _r(rng.uniform(-0.3, 0.3)), _r(rng.uniform(-0.5, 0.5))]
            elif i == 0 and rng.random() < 0.5:
                b["rpy"] = [_r(rng.uniform(-0.3, 0.3)), _r(rng.uniform(-0.3, 0.3)), 0.0]
        bodies.append(b)
    if not any("contacts" in b for b in bodies):
        bodies[-1]["contacts"] = [1.0]
    scene = _scene(rng, spatial, options)
    _rigid_extras(np.random.default_rng([seed, 1]), bodies, spatial, options)
    model: dict[str, Any] = {"bodies": bodies}
    if spatial:
        model = {"space": "spatial", **model}
    return {"scene": scene, "model": model, "notes": f"random_landings.py seed {seed}"}


def _rigid_extras(rng: np.random.Generator, bodies: list[dict[str, Any]], spatial: bool, options: Options) -> None:
    """Joint axes, inertias, centres of mass off the axis and full tensors (MODEL_FORMAT's
    "Spatial models" and "Bodies"), each with its option's probability, added to ``bodies``."""
    for b in bodies:
        u = rng.random(5)
        if spatial and "parent" in b and b.get("joint") != "fixed" and u[0] < options.axis:
            b["axis"] = [_r(x) for x in _unit_vector(rng)]
        length, mass = b["length"], b["mass"]
        if spatial and u[1] < options.tensor:
            b.pop("radius", None)
            b["inertia_tensor"] = _inertia_tensor(rng, mass, length)
        elif u[2] < options.inertia:
            if u[3] < 0.5:
                b["gyration"] = _r(rng.uniform(0.1, 0.6))
            else:
                b["inertia"] = _r(mass * length**2 * rng.uniform(0.005, 0.3))
        if u[4] < options.offset:
            dy = _r(length * rng.uniform(-0.3, 0.3))
            b["com_offset"] = [dy, _r(length * rng.uniform(-0.3, 0.3)) if spatial else 0.0]


def _unit_vector(rng: np.random.Generator) -> np.ndarray:
    """A principal axis (half the time) or a random direction."""
    if rng.random() < 0.5:
        return np.eye(3)[int(rng.integers(0, 3))] * (1 if rng.random() < 0.5 else -1)
    x = rng.standard_normal(3)
    return x / np.linalg.norm(x)


def _inertia_tensor(rng: np.random.Generator, mass: float, length: float) -> list[float]:
    """[ixx, iyy, izz, ixy, ixz, iyz] of a random solid box about its centre of mass, turned at
    random (a rigid body's: positive definite, each principal moment below the others' sum)."""
    a, b, c = length * rng.uniform(0.05, 1.0, 3)
    principal = np.diag(mass / 12 * np.array([b * b + c * c, a * a + c * c, a * a + b * b]))
    q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
    t = q @ principal @ q.T
    return [_r(x) for x in (t[0, 0], t[1, 1], t[2, 2], t[0, 1], t[0, 2], t[1, 2])]


def _contacts(rng: np.random.Generator) -> list[float]:
    kind = rng.random()
    if kind < 0.6:
        return [1.0]
    if kind < 0.8:
        return [0.0, 1.0]
    return sorted({_r(x) for x in rng.uniform(0.0, 1.0, int(rng.integers(1, 4)))})


def _scene(rng: np.random.Generator, spatial: bool, options: Options) -> dict[str, Any]:
    scene: dict[str, Any] = {}
    vy = _r(rng.uniform(0.3, 5.0))
    if rng.random() < options.velocity:
        lateral = [_r(rng.uniform(-1.5, 1.5))] + ([_r(rng.uniform(-1.0, 1.0))] if spatial else [])
        scene["velocity"] = [lateral[0], -vy, *lateral[1:]]
    else:
        scene["speed"] = vy
    if rng.random() < options.angular_velocity:
        scene["angular_velocity"] = [_r(w) for w in rng.uniform(-4.0, 4.0, 3)] if spatial else _r(rng.uniform(-6.0, 6.0))
    u = rng.random()
    scene["restitution"] = 0.0 if u < 0.1 else 1.0 if u < 0.15 else _r(rng.uniform(0.0, 1.0))
    scene["friction"] = float(FRICTIONS[int(rng.integers(0, len(FRICTIONS)))])
    if rng.random() < options.contacts_all:
        scene["contacts"] = "all"
    scene["gravity"] = 9.81 if rng.random() < options.gravity else 0.0
    scene["duration"] = _log_uniform(rng, *options.duration)
    if not spatial and rng.random() < options.terrain:
        k = int(rng.integers(2, 6))
        xs = np.sort(rng.uniform(-0.6, 1.0, k))
        xs = xs + 0.05 * np.arange(k)  # strictly increasing, at least 5 cm apart
        ys = rng.uniform(-0.06, 0.06, k)
        scene["terrain"] = [[_r(x), _r(y)] for x, y in zip(xs, ys)]
        scene["base_x"] = _r(rng.uniform(-0.3, 0.3))
    elif spatial and rng.random() < options.heightfield:
        nx, nz = int(rng.integers(2, 5)), int(rng.integers(2, 4))
        xs = np.sort(rng.uniform(-0.6, 1.0, nx)) + 0.05 * np.arange(nx)
        zs = np.sort(rng.uniform(-0.5, 0.5, nz)) + 0.05 * np.arange(nz)
        heights = rng.uniform(-0.05, 0.05, (nx, nz))
        scene["heightfield"] = {"x": [_r(x) for x in xs], "z": [_r(z) for z in zs],
                                "heights": [[_r(h) for h in row] for row in heights]}
        scene["base_x"] = _r(rng.uniform(-0.3, 0.3))
        scene["base_z"] = _r(rng.uniform(-0.3, 0.3))
    return scene


def ground_kind(data: dict[str, Any]) -> str:
    """``flat``, ``terrain`` or ``heightfield``."""
    scene = data["scene"]
    return "heightfield" if "heightfield" in scene else "terrain" if "terrain" in scene else "flat"


def write_model(data: dict[str, Any], path: Path) -> None:
    """The file as YAML."""
    path.write_text(yaml.safe_dump(data, sort_keys=False, default_flow_style=None, width=120))


# --------------------------------------------------------------------------------------------
# The checks (pure: on the JSON the CLI printed and the worker's balance)


def relative_difference(a: Any, b: Any) -> float:
    """max |a_i - b_i| / max |b_i| over the flattened lists (0 / 0 = 0; x / 0 = inf)."""
    x, y = np.ravel(np.asarray(a, float)), np.ravel(np.asarray(b, float))
    if x.shape != y.shape:
        return math.inf
    if x.size == 0:
        return 0.0
    num, den = float(np.max(np.abs(x - y))), float(np.max(np.abs(y)))
    return num / den if den > 0 else (0.0 if num == 0 else math.inf)


def first_event_difference(landing: dict[str, Any], first: dict[str, Any]) -> float:
    """The largest relative difference per list of the landing's first event from the
    first-impact rung's answer (``external``, ``internal``, ``tangential`` where both give it)."""
    event = landing["events"][0]
    keys = ["external", "internal"] + (["tangential"] if "tangential" in first and "tangential" in event else [])
    return max(relative_difference(event[k], first[k]) for k in keys)


def check(status: int, stderr: str, landing: dict[str, Any] | None, first: dict[str, Any] | None,
          balance: float | None, spied_total: list[float] | None = None) -> list[str]:
    """What fails, as short labels with figures (empty: the file passes). ``status`` and ``stderr``
    are the landing's; ``first`` the first-impact rung's JSON (None: it did not answer)."""
    if "Traceback" in stderr:
        return [f"traceback (exit {status})"]
    if status == 2:
        lines = [ln for ln in stderr.splitlines() if ln.strip()]
        return [] if len(lines) == 1 else [f"exit 2 with {len(lines)} lines"]
    if status != 0:
        return [f"exit {status}: {_last_line(stderr)}"]
    if landing is None:
        return ["no JSON"]
    if "landing" not in landing:  # --files: a model file without scene.duration (the first-impact JSON)
        return ["no-landing: the file has no scene.duration"]
    fails = []
    if not landing.get("events") or landing["events"][0]["t"] != 0:
        fails.append("first event not at t = 0")
    elif first is None:
        fails.append("first-impact rung gave no answer")
    else:
        d = first_event_difference(landing, first)
        if not d <= FIRST_EVENT_TOL:
            fails.append(f"first event {d:.2g}")
    if balance is None or not balance <= BALANCE_TOL:
        fails.append(f"balance {balance:.2g}" if balance is not None else "balance missing")
    if spied_total is not None and relative_difference(spied_total, landing["landing"]["total_external"]) > 1e-12:
        fails.append("spied result is not the reported one")
    return fails


def verdict(status: int, fails: list[str]) -> str:
    """``ok``, ``refused`` (exit 2, one line) or the first failure's kind."""
    if not fails:
        return "refused" if status == 2 else "ok"
    return fails[0].split(":")[0].split(" ")[0] if not fails[0].startswith("exit") else fails[0].split(":")[0]


def _last_line(text: str) -> str:
    lines = [ln for ln in text.splitlines() if ln.strip()]
    return lines[-1][:160] if lines else ""


# --------------------------------------------------------------------------------------------
# The worker: the CLI itself, with a spy on the landing


def worker(file: str, first_model: str, sidecar: str) -> int:
    """``footopt evaluate FILE --json --model first_model`` (captured) then ``footopt evaluate
    FILE --json`` (stdout, stderr and status passed through), the balance to ``sidecar``."""
    import optimizer.evaluation.model_choice as choice
    from optimizer.cli.main import main

    spied: dict[str, Any] = {}
    real = choice.landing

    def spy(*args: Any, **kwargs: Any) -> Any:
        result = real(*args, **kwargs)
        spied["args"], spied["kwargs"], spied["result"] = args, kwargs, result
        return result

    choice.landing = spy
    out, err = io.StringIO(), io.StringIO()
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        first_status = main(["evaluate", file, "--json", "--model", first_model])
    first_time = time.perf_counter() - t0
    spied.clear()
    status = main(["evaluate", file, "--json"])
    side: dict[str, Any] = {"first_status": first_status, "first_stdout": out.getvalue(),
                            "first_stderr": err.getvalue(), "first_time": first_time}
    if status == 0 and "result" in spied:
        side.update(momentum_balance(*spied["args"], result=spied["result"], **spied["kwargs"]))
    Path(sidecar).write_text(json.dumps(side))
    return status


def momentum_balance(tree: Any, scene: Any, joints: Any = (), settings: Any = None, space: Any = None,
                     progress: Any = None, *, result: Any) -> dict[str, Any]:
    """The landing's momentum balance from its result (see the module docstring): {balance, own,
    total_external}."""
    from impulse_core.kinematics.spatial import PLANAR
    from impulse_core.timedomain.compliant import chart_rates
    from impulse_core.timedomain.events.run import _Landing
    from impulse_core.timedomain.landing import LandingSettings

    space = PLANAR if space is None else space
    run = _Landing(tree, scene, tuple(joints), settings or LandingSettings(), space)
    planar = result.space == "planar"
    own = not (scene.terrain.is_flat and (scene.heightfield is None or scene.heightfield.is_flat))

    def rates(q: np.ndarray, v: np.ndarray) -> np.ndarray:
        if planar:
            return v
        v = v.copy()
        v[3:6] = np.linalg.solve(np.asarray(chart_rates(q[3:6]), float), v[3:6])
        return v

    r = result
    p0 = run.point(run.q0, rates(run.q0, r.events[0].v_minus)).momentum[:, 0]
    p1 = run.point(r.q_final, rates(r.q_final, r.v_final)).momentum[:, 0]
    mass = sum(b.mass for b in tree.bodies)
    weight = mass * scene.gravity * r.duration
    tangential = np.asarray(r.total_tangential, float)
    if planar:
        impulse = np.array([tangential.sum(), r.total_external.sum() - weight])
    else:
        tx, tz = tangential.reshape(-1, 2).sum(axis=0)
        impulse = np.array([tx, r.total_external.sum() - weight, tz])
    reference = max(float(np.max(np.abs(p0))), weight)
    derived = float(np.max(np.abs(p1 - p0 - impulse))) / reference
    return {"balance": float(r.momentum_balance) if own else derived, "own": bool(own), "derived": derived,
            "run_balance": float(r.momentum_balance), "total_external": [float(x) for x in r.total_external]}


# --------------------------------------------------------------------------------------------
# The runner


@dataclass
class Outcome:
    """One seed's landing, checked."""

    seed: int | str  # --files: the file's stem where it is not a number
    space: str
    friction: float
    ground: str
    status: int | None  # None: the limit
    events: int | None
    seconds: float
    balance: float | None
    own_balance: bool
    first_difference: float | None
    fails: list[str]
    message: str

    @property
    def verdict(self) -> str:
        if self.status is None:
            return "timeout"
        return verdict(self.status, self.fails)

    def line(self) -> str:
        bal = "-" if self.balance is None else f"{self.balance:.1e}" + ("*" if self.own_balance else "")
        fe = "-" if self.first_difference is None else f"{self.first_difference:.1e}"
        ev = "-" if self.events is None else str(self.events)
        what = "; ".join(self.fails) if self.fails else self.message
        return (f"{self.seed} {self.space:7s} mu={self.friction:<3g} {self.ground:11s} events={ev:>5s} "
                f"{self.seconds:6.1f}s balance={bal:9s} first={fe:8s} {self.verdict}" + (f"  {what}" if what else ""))


def run_seed(seed: int, options: Options, out: Path, limit: float) -> Outcome:
    """Write ``seed``'s file to ``out``, land it in a worker within ``limit`` s, check it."""
    data = random_model(seed, options)
    path = out / f"{seed}.yaml"
    write_model(data, path)
    return run_file(seed, data, path, out, limit)


def run_file(seed: int | str, data: dict[str, Any], path: Path, out: Path, limit: float) -> Outcome:
    """Land the model file ``path`` (its contents ``data``) in a worker within ``limit`` s and
    check it (the worker's side file in ``out``)."""
    space = data["model"].get("space", "planar")
    friction = float(data["scene"]["friction"])
    first_model = "friction" if friction > 0 else "lcp"
    sidecar = out / f"{seed}.side.json"
    sidecar.unlink(missing_ok=True)
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    cmd = [sys.executable, str(Path(__file__).resolve()), "--worker", str(path), first_model, str(sidecar)]
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=limit, env=env, cwd=REPO)
    except subprocess.TimeoutExpired:
        return Outcome(seed, space, friction, ground_kind(data), None, None, time.perf_counter() - t0, None, False,
                       None, [f"over {limit:g} s"], "")
    seconds = time.perf_counter() - t0
    side = json.loads(sidecar.read_text()) if sidecar.exists() else {}
    landing = _json(proc.stdout)
    first = _json(side.get("first_stdout", "")) if side.get("first_status") == 0 else None
    fails = check(proc.returncode, proc.stderr, landing, first, side.get("balance"), side.get("total_external"))
    events = landing.get("events") if landing else None
    diff = first_event_difference(landing, first) if first and events else None
    message = _last_line(proc.stderr) if proc.returncode else ""
    if side.get("first_status") not in (0, None):
        message = (message + " | first impact: " + _last_line(side.get("first_stderr", ""))).strip(" |")
    return Outcome(seed, space, friction, ground_kind(data), proc.returncode,
                   None if events is None else len(events), seconds, side.get("balance"),
                   bool(side.get("own")), diff, fails, message)


def _json(text: str) -> dict[str, Any] | None:
    lines = [ln for ln in text.splitlines() if ln.startswith("{")]
    return json.loads(lines[-1]) if lines else None


def summary(outcomes: list[Outcome]) -> str:
    """A Markdown table of counts by space and ground, then every failure."""
    rows = Counter((o.space, o.ground, o.verdict) for o in outcomes)
    verdicts = sorted({o.verdict for o in outcomes}, key=lambda v: (v != "ok", v))
    groups = sorted({(o.space, o.ground) for o in outcomes})
    lines = ["| space | ground | files | " + " | ".join(verdicts) + " |", "|---|---|---|" + "---|" * len(verdicts)]
    for g in groups:
        total = sum(rows[(*g, v)] for v in verdicts)
        lines.append(f"| {g[0]} | {g[1]} | {total} | " + " | ".join(str(rows[(*g, v)]) for v in verdicts) + " |")
    lines.append(f"| all | | {len(outcomes)} | " + " | ".join(str(sum(o.verdict == v for o in outcomes)) for v in verdicts) + " |")
    bad = [o for o in outcomes if o.verdict not in ("ok", "refused")]
    if bad:
        lines += ["", "Failures:", *[f"- {o.line()}" for o in bad]]
    slow = sorted((o for o in outcomes if o.status is not None), key=lambda o: -o.seconds)[:6]
    lines += ["", "Slowest within the limit: " + ", ".join(f"{o.seed} ({o.seconds:.0f} s, {o.verdict})" for o in slow)]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """The command line (module docstring)."""
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--worker"]:
        return worker(*argv[1:4])
    p = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    p.add_argument("--seeds", nargs=2, type=int, metavar=("LO", "HI"), default=(30000, 30010), help="seeds LO..HI-1")
    p.add_argument("--limit", type=float, default=DEFAULT_LIMIT, help="wall-clock limit per file (s)")
    p.add_argument("--spatial", type=float, default=Options.spatial, help="probability of a spatial model")
    p.add_argument("--terrain", type=float, default=Options.terrain, help="planar: probability of a terrain")
    p.add_argument("--heightfield", type=float, default=Options.heightfield, help="spatial: probability of a heightfield")
    p.add_argument("--axis", type=float, default=Options.axis, help="spatial: probability of a random joint axis")
    p.add_argument("--inertia", type=float, default=Options.inertia, help="probability of a gyration or inertia")
    p.add_argument("--offset", type=float, default=Options.offset, help="probability of a com_offset")
    p.add_argument("--tensor", type=float, default=Options.tensor, help="spatial: probability of an inertia_tensor")
    p.add_argument("--out", type=Path, default=Path("/tmp/random_landings"), help="folder for the files and results.jsonl")
    p.add_argument("--report", action="store_true", help="only print the summary of DIR's results.jsonl")
    p.add_argument("--files", type=Path, nargs="+",
                   help="check these model files (e.g. random_failures/) instead of seeds")
    args = p.parse_args(argv)
    if args.report:
        fields = set(Outcome.__dataclass_fields__)
        rows = [json.loads(ln) for ln in (args.out / "results.jsonl").read_text().splitlines() if ln.strip()]
        print(summary([Outcome(**{k: v for k, v in r.items() if k in fields}) for r in rows]))
        return 0
    options = Options(spatial=args.spatial, terrain=args.terrain, heightfield=args.heightfield, axis=args.axis,
                      inertia=args.inertia, offset=args.offset, tensor=args.tensor)
    args.out.mkdir(parents=True, exist_ok=True)
    outcomes = []
    with open(args.out / "results.jsonl", "a") as log:
        for job in args.files or range(*args.seeds):
            if isinstance(job, Path):
                seed = int(job.stem) if job.stem.isdigit() else job.stem  # its side file named alike
                o = run_file(seed, yaml.safe_load(job.read_text()), job.resolve(), args.out, args.limit)
            else:
                o = run_seed(job, options, args.out, args.limit)
            outcomes.append(o)
            print(o.line(), flush=True)
            log.write(json.dumps({**o.__dict__, "verdict": o.verdict}) + "\n")
            log.flush()
    print()
    print(summary(outcomes))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
