"""Joint stops in MuJoCo (``footopt export``'s MJCF, ``export.stop_parameters``) against footopt's own
law: the whole landing (``impulse_core.timedomain.landing``) takes a stop as a rigid impact with
Newton's ``stop_restitution`` e; the exported hinge's stiff limit rebounds with e.

- A rod (the arm) on a hinge with stops, on a foot that lands: footopt's landing gives the arm's
  joint rate after its stop impact = -e times the rate before, to 1e-12, for e = 0, 0.3, 0.6, 0.9.
- The same model's exported MJCF in MuJoCo, the foot welded to the world (its freejoint removed)
  and no gravity: the hinge is driven into its lower stop at 1 rad/s, the stop closing at ten
  phases of a step; the rebound ratio (rate leaving the stop / rate arriving) is within 0.035 of e
  at the stated step (``STOP_TIMESTEP``, MuJoCo's default, kept by the file) and within 0.005 at a
  tenth of it (measured: 0.268..0.312 and 0.297..0.301 for e = 0.3); e = 0 rebounds with at
  most 0.025 (0.021 in the limit of short steps). The whole (floating) file does too, to 0.015.
"""

from __future__ import annotations

import dataclasses
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from impulse_core.model.joints import FREE, JointLaw
from impulse_core.model.tree import Body, Scene, Tree
from impulse_core.timedomain.landing import landing
from optimizer.results.export import STOP_TIMESTEP, stop_parameters, to_mjcf
from tests.conftest import report

mujoco = pytest.importorskip("mujoco")

RESTITUTIONS = (0.0, 0.3, 0.6, 0.9)
#: The arm's stops (rad), either side of its touchdown angle 1.2.
LIMITS = (1.15, 1.25)
TREE = Tree((Body("foot", None, 0.3, 1.0, 0.3, contacts=(0.0,)), Body("arm", 0, 0.4, 1.0, 1.2)))
SCENE = Scene(speed=1.0, restitution=0.0, duration=0.05)
#: Rebound tolerance at the stated step and at a tenth of it; e = 0's largest rebound.
AT_STEP, AT_TENTH, PLASTIC = 0.035, 0.005, 0.025
#: The floating file's tolerance at a tenth of the step.
FLOATING = 0.015


def _laws(e: float) -> tuple[JointLaw, ...]:
    return FREE, JointLaw(limits=LIMITS, stop_restitution=e)


@pytest.mark.parametrize("e", RESTITUTIONS)
def test_the_whole_landing_rebounds_at_a_stop_with_exactly_e(e: float):
    """Footopt's law: at the first stop event the arm's joint rate is -e times the rate before."""
    r = landing(TREE, SCENE, _laws(e))
    stop = next(ev for ev in r.events if ev.kind == "stop")
    assert abs(stop.v_minus[3]) > 1.0
    assert stop.v_plus[3] == pytest.approx(-e * stop.v_minus[3], abs=1e-12 * abs(stop.v_minus[3]))


def _mujoco(e: float, timestep: float, fixed: bool = True):  # type: ignore[no-untyped-def]
    """The exported MJCF with the arm's stops at restitution e, no gravity, MuJoCo steps of
    ``timestep``; the foot welded to the world when ``fixed``."""
    root = ET.fromstring(to_mjcf(TREE, SCENE, joints=_laws(e)))
    if fixed:
        foot = root.find("worldbody/body")
        foot.remove(foot.find("freejoint"))
    m = mujoco.MjModel.from_xml_string(ET.tostring(root, encoding="unicode"))
    m.opt.gravity[:] = 0.0
    m.opt.timestep = timestep
    return m


def rebound_ratio(m, phase: float, rate: float = 1.0) -> float:  # type: ignore[no-untyped-def]
    """The arm's rate leaving its lower stop over the rate arriving (driven in at ``rate``, the
    stop closing ``phase`` of a step after the start)."""
    d = mujoco.MjData(m)
    j = m.joint("arm")
    lower = m.jnt_range[j.id][0]
    q, v = j.qposadr[0], j.dofadr[0]
    d.qpos[q] = lower + phase * rate * m.opt.timestep
    d.qvel[v] = -rate
    arriving = rate
    for _ in range(100_000):
        if d.qpos[q] > lower:
            arriving = -d.qvel[v]  # the last rate before the stop closes
        mujoco.mj_step(m, d)
        if d.qpos[q] > lower and d.qvel[v] > 0:
            return float(d.qvel[v] / arriving)
    raise AssertionError("the arm never left its stop")


@pytest.mark.parametrize("e", RESTITUTIONS)
def test_an_exported_stop_rebounds_with_its_restitution_in_mujoco(e: float):
    """The exported hinge's limit at the stated step and at a tenth of it, ten closing phases."""
    m = _mujoco(e, STOP_TIMESTEP)
    k, b = stop_parameters(e)
    assert tuple(m.jnt_solref[m.joint("arm").id]) == pytest.approx((-k, -b), rel=1e-15)
    phases = np.linspace(0.05, 0.95, 10)
    for timestep, tol in ((STOP_TIMESTEP, AT_STEP), (STOP_TIMESTEP / 10, AT_TENTH)):
        ratios = np.array([rebound_ratio(_mujoco(e, timestep), p) for p in phases])
        report("stops", f"e = {e}: MuJoCo rebound {ratios.min():.4f}..{ratios.max():.4f} at timestep {timestep:g} s")
        if e == 0.0:
            assert np.all(ratios >= 0.0) and np.all(ratios <= PLASTIC)
        else:
            assert np.max(np.abs(ratios - e)) <= tol


@pytest.mark.parametrize("e", (0.3, 0.9))
def test_the_whole_exported_file_rebounds_too(e: float):
    """The floating foot (the file as written): the arm's stop rebounds with e to 0.015 (measured
    0.290..0.293 for 0.3): the stop's 40 ms closure is long enough for the foot's coupled turning
    to change the arm's rate on its own, which the welded foot does not."""
    ratios = np.array([rebound_ratio(_mujoco(e, STOP_TIMESTEP / 10, fixed=False), p) for p in (0.25, 0.75)])
    report("stops", f"e = {e}: floating file, rebound {ratios.min():.4f}..{ratios.max():.4f}")
    assert np.max(np.abs(ratios - e)) <= FLOATING


def test_the_drop_holds_the_stops_tuned_for_its_own_step():
    """``footopt drop`` (``drop_record``): MuJoCo's model holds the arm's stop tuned for the drop's
    step (the compliant rung's, ~5e-6 s at 1e8 1/s^2), where it rebounds with e as the export's at
    its stated step (the same steps per period, ten closing phases, within 0.035); the stop is not
    reached in the first impact's window, so the impulses are those without stops."""
    from impulse_core.evaluate import evaluate
    from optimizer.cli.drop import drop_record

    e = 0.6
    scene = dataclasses.replace(SCENE, restitution=0.5, duration=None)  # the drop's contacts need e > 0
    rigid = evaluate(TREE, scene)
    with_stops = drop_record(TREE, scene, 1e8, rigid, joints=_laws(e))
    without = drop_record(TREE, scene, 1e8, rigid)
    h = with_stops["settings"]["timestep"]
    assert h < STOP_TIMESTEP / 100
    k, b = stop_parameters(e, h)
    assert with_stops["settings"]["stops"] == {"arm": [-k, -b]} and without["settings"]["stops"] == {}
    assert with_stops["external"]["mujoco"] == without["external"]["mujoco"]
    root = ET.fromstring(to_mjcf(TREE, SCENE, joints=_laws(e), stop_timestep=h))
    foot = root.find("worldbody/body")
    foot.remove(foot.find("freejoint"))
    m = mujoco.MjModel.from_xml_string(ET.tostring(root, encoding="unicode"))
    m.opt.gravity[:] = 0.0
    m.opt.timestep = h
    ratios = np.array([rebound_ratio(m, p) for p in np.linspace(0.05, 0.95, 10)])
    report("stops", f"e = {e}: drop's step {h:.3g} s, rebound {ratios.min():.4f}..{ratios.max():.4f}")
    assert np.max(np.abs(ratios - e)) <= AT_STEP


def test_export_tunes_the_stops_for_a_stated_step(tmp_path, capsys):
    """``footopt export --stop-timestep S``: the stops' limits are tuned for MuJoCo steps of S (the
    file's solreflimit is stop_parameters(e, S)), and at that step the exported hinge rebounds
    with e to the stated step's tolerance; a bad step is refused naming the option."""
    from optimizer.cli.main import main
    from optimizer.config.model_file import ModelFile, format_model_file

    e, step = 0.6, 0.01
    model = tmp_path / "arm.yaml"
    model.write_text(format_model_file(ModelFile(TREE, SCENE, joints=_laws(e))), encoding="utf-8")
    out = tmp_path / "arm.xml"
    assert main(["export", str(model), "-o", str(out), "--stop-timestep", str(step)]) == 0
    root = ET.fromstring(out.read_text(encoding="utf-8"))
    foot = root.find("worldbody/body")
    foot.remove(foot.find("freejoint"))
    m = mujoco.MjModel.from_xml_string(ET.tostring(root, encoding="unicode"))
    m.opt.gravity[:], m.opt.timestep = 0.0, step
    k, b = stop_parameters(e, step)
    assert tuple(m.jnt_solref[m.joint("arm").id]) == pytest.approx((-k, -b), rel=1e-12)
    ratios = np.array([rebound_ratio(m, p) for p in np.linspace(0.05, 0.95, 5)])
    assert np.max(np.abs(ratios - e)) <= AT_STEP
    capsys.readouterr()
    for bad in ("-1", "1e300", "1e-300"):  # the fuzzer's 1e300 and 1e-300 wrote solreflimit -0.0 and -inf, exit 0
        assert main(["export", str(model), "-o", str(tmp_path / "x.xml"), f"--stop-timestep={bad}"]) == 2
        err = capsys.readouterr().err
        assert "--stop-timestep: must be a time step in [1e-08, 1]" in err and len(err.strip().splitlines()) == 1
