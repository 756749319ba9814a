"""Random file 32924's flight after its last impact: chaotic, or a wrong run?

(``spatial_chatter.md``, "Session 37: 32924".) Lands the file with ``landing()``'s first run (RK4 at
its stable step h) until its fifth impact, then integrates the 0.21 s of free flight left

- with scipy's DOP853 on footopt's own dynamics (rtol 1e-13; the base's rotation coordinates
  re-centred as the landing does): the energy over the flight, and the growth of a 1e-10 kick
  of the starting velocity (a Lyapunov-like rate);
- with MuJoCo (``footopt export``'s MJCF without ground; its RK4 at 1e-6 s) from the same state:
  its difference from DOP853 for MuJoCo's inertia floors on the rods of radius 0 (``--floors``),
  and its own growth of a 1e-10 kick.

Run: python studies/whole_landing/tumbling_flight.py [--floors 1e-9 1e-11 1e-13] (about 2 min).
"""

from __future__ import annotations

import argparse
import types
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

from impulse_core.timedomain.compliant import chart_rates, chart_rotation, world_velocity
from impulse_core.timedomain.events.run import _Landing
from impulse_core.timedomain.events.settings import RECHART
from impulse_core.timedomain.landing import VM_CODE, LandingSettings
from optimizer.config.model_file import load_model_file

FILE = Path(__file__).resolve().parent / "random_failures" / "32924.yaml"
KICK = 1e-10


def after_impacts(model, events: int = 5):
    """A run at the landing's first step until its ``events``-th impact: (run, t, q, chart rates v)."""
    run = _Landing(model.tree, model.scene, model.joints, LandingSettings(step_code=VM_CODE), model.space)
    r = run.run(run.first_step(), until=lambda q, v, mode, totals: len(totals.events) >= events)
    q, v = r.q_final.copy(), r.v_final.copy()  # the rotation since touchdown, world velocities
    v[3:6] = np.linalg.solve(chart_rates(q[3:6]), v[3:6])
    totals = types.SimpleNamespace(chart_q=None)
    q, v = run.rechart(q, v, totals)  # rotation coordinates centred on the base's orientation now
    return run, r.duration, q, v


def features(run, q, v) -> np.ndarray:
    """Base origin (3), base rotation matrix (9), joint angles, then world velocities."""
    R = chart_rotation(q[3:6]) @ run.base_rotation()
    return np.concatenate([q[:3], R.ravel(), q[6:], world_velocity(q, v, run.space)])


def energy(run, q, v, gravity: float) -> float:
    pt = run.point(q, v)
    return pt.kinetic + run.joints.energy(q) + run.mass * gravity * pt.com_height


def dop853(run, t0, q, v, t_end, samples, rtol=1e-13, atol=1e-15):
    """Free flight by DOP853 from (t0, q, v): the features at ``samples`` and the end state."""
    flight, nq, out, samples = run.flight(), q.size, [], list(samples)
    t, y = t0, np.concatenate([q, v])
    totals = types.SimpleNamespace(chart_q=None)
    while t < t_end:
        def rhs(_t, y):
            return np.concatenate([y[nq:], run.derivative(y[:nq], y[nq:], flight)[0]])

        def chart(_t, y):
            return np.linalg.norm(y[3:6]) - RECHART
        chart.terminal, chart.direction = True, 1
        sol = solve_ivp(rhs, (t, t_end), y, method="DOP853", rtol=rtol, atol=atol, events=chart, dense_output=True)
        while samples and samples[0] <= sol.t[-1]:
            s = samples.pop(0)
            out.append(features(run, sol.sol(s)[:nq], sol.sol(s)[nq:]))
        t, y = sol.t[-1], sol.y[:, -1]
        if sol.status == 1:
            y = np.concatenate(run.rechart(y[:nq], y[nq:], totals))
    return np.array(out), (y[:nq], y[nq:])


def mujoco_flight(model, run, t0, q, v, samples, floor: float, dt: float = 1e-6, kick: np.ndarray | None = None):
    """The same flight in MuJoCo (RK4, ``dt``), the rods' zero moments written as ``floor``."""
    import mujoco
    from scipy.spatial.transform import Rotation

    import optimizer.results.export as export

    export.INERTIA_FLOOR, kept = floor, export.INERTIA_FLOOR
    try:
        xml = export.to_mjcf(model.tree, model.scene, gravity=model.scene.gravity, joints=model.joints,
                             space=model.space, ground=False)
    finally:
        export.INERTIA_FLOOR = kept
    m = mujoco.MjModel.from_xml_string(xml.replace("<option ", '<option integrator="RK4" '))
    d = mujoco.MjData(m)
    names = [b.name for b in model.tree.bodies]
    angles0 = np.array([b.angle for b in model.tree.bodies[1:]])
    R, w = chart_rotation(q[3:6]) @ run.base_rotation(), world_velocity(q, v, run.space)
    free = m.joint(names[0])
    a, b = free.qposadr[0], free.dofadr[0]
    d.qpos[a:a + 3] = q[:3]
    x, y, z, s = Rotation.from_matrix(R).as_quat()
    d.qpos[a + 3:a + 7] = [s, x, y, z]
    d.qvel[b:b + 3], d.qvel[b + 3:b + 6] = w[:3], R.T @ w[3:6]
    joints = [m.joint(n) for n in names[1:]]
    for k, j in enumerate(joints):
        d.qpos[j.qposadr[0]], d.qvel[j.dofadr[0]] = q[6 + k] - angles0[k], w[6 + k]
    if kick is not None:
        d.qvel[:] += kick * np.linalg.norm(d.qvel)
    out, t = [], t0
    for s in samples:
        n = int((s - t) / dt)
        m.opt.timestep = dt
        for _ in range(n):
            mujoco.mj_step(m, d)
        m.opt.timestep = s - t - n * dt  # the rest of the way to the sample
        mujoco.mj_step(m, d)
        t = s
        w_, x_, y_, z_ = d.qpos[a + 3:a + 7]
        Rm = Rotation.from_quat([x_, y_, z_, w_]).as_matrix()
        out.append(np.concatenate([d.qpos[a:a + 3], Rm.ravel(),
                                   [d.qpos[j.qposadr[0]] + angles0[k] for k, j in enumerate(joints)]]))
    return np.array(out)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--floors", type=float, nargs="*", default=[1e-9, 1e-11, 1e-13],
                   help="MuJoCo inertia floors (kg m^2) for the rods' zero moments; none: skip MuJoCo")
    args = p.parse_args(argv)
    model = load_model_file(FILE)
    T, g = float(model.scene.duration), model.scene.gravity
    run, t0, q, v = after_impacts(model)
    chart = (run.call.args[2].copy(), None if run.chart is None else run.chart.copy())

    def start():  # every integration re-centres the chart as it goes: back to the start's
        run.set_chart(*chart)
        return run
    samples = np.linspace(t0, T, 21)[1:]
    u = np.random.default_rng(1).standard_normal(v.size)
    u /= np.linalg.norm(u)
    E0 = energy(start(), q, v, g)
    ref, (q1, v1) = dop853(run, t0, q, v, T, samples)
    drift = energy(run, q1, v1, g) - E0
    print(f"flight from t = {t0:.6g} s to {T:.6g} s; DOP853 energy {E0:.9f} J, drift {drift:.2g} J")
    kicked, _ = dop853(start(), t0, q, v + KICK * np.linalg.norm(v) * u, T, samples)
    mj = {f: mujoco_flight(model, start(), t0, q, v, samples, f) for f in args.floors}
    if args.floors:
        w = np.random.default_rng(2).standard_normal(v.size)
        mj_kicked = mujoco_flight(model, start(), t0, q, v, samples, args.floors[-1], kick=KICK * w / np.linalg.norm(w))
    head = "t (s)     kick: posture  velocity" + "".join(f"  mj({f:g})-DOP" for f in args.floors)
    print(head + ("  mj kick" if args.floors else ""))
    for i, s in enumerate(samples):
        apart = kicked[i] - ref[i]
        line = (f"{s:.4f}  {np.linalg.norm(apart[:14]):13.3e}  {np.linalg.norm(apart[14:]):8.3e}"
                + "".join(f"  {np.linalg.norm(mj[f][i] - ref[i, :14]):12.3e}" for f in args.floors))
        if args.floors:
            line += f"  {np.linalg.norm(mj_kicked[i] - mj[args.floors[-1]][i]):8.3e}"
        print(line)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
