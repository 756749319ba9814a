"""The compliant rung against MuJoCo: the same leg, terrain and contact softness dropped in an
independent simulator (its own kinematics, mass matrix, constraint solver, and joint reaction
forces from its own recursive Newton-Euler pass, ``cfrc_int``).

Tolerances:
- Constraint law vs MuJoCo, same step and number of steps: 1e-4 relative on every external and
  internal impulse. Both integrate the same semi-implicit Euler steps of the same soft-constraint
  law; what differs is MuJoCo's regulariser R = (1 - d)/d * diagApprox, built from its
  approximate inverse weights where we use the exact A_ii: with d = 0.9999 that moves each force
  by at most ~(1 - d) = 1e-4 of itself (measured: 6e-6). Touchdown times: within one step (MuJoCo
  sees a contact from the step in which it penetrates; the rung interpolates the crossing).
- Penalty law vs MuJoCo (each contact's solref set to k/m_i, c/m_i): the two laws differ only
  in how finite accelerations (gravity, Coriolis and centrifugal terms, the free acceleration
  a_0) act during a contact, an effect that falls as the contact time, k^-1/2: checked to scale
  so, and to be below 3e-4 at 1e8 N/m.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("mujoco")

from fidelity_scenes import PAPER_SCENE, UNEVEN, case2, case3, chain  # noqa: E402

from impulse_core.timedomain.compliant import CompliantSettings, ContactLaw, simulate_impact  # noqa: E402
from impulse_core.evaluate import evaluate  # noqa: E402
from impulse_core.model.tree import Body, Scene, Tree  # noqa: E402
from optimizer.validation.mujoco_bridge import build_mjcf, drop  # noqa: E402
from tests.conftest import report  # noqa: E402

AGREE = 1e-4


def _relative(a, b) -> float:
    return float(np.max(np.abs(np.asarray(a) / np.asarray(b) - 1.0)))


@pytest.mark.parametrize(
    "name, make, terrain",
    [
        ("case2 flat", case2, None),
        ("case3 flat", case3, None),
        ("chain flat", chain, None),
        ("case2 uneven", case2, UNEVEN),
    ],
)
def test_constraint_law_agrees_with_mujoco(name, make, terrain):
    tree = make()
    kw = {} if terrain is None else {"terrain": terrain}
    st = CompliantSettings(law=ContactLaw.CONSTRAINT, stiffness=1e7, steps_per_period=120, flight_step=None)
    ours = simulate_impact(tree, PAPER_SCENE, st, **kw)
    mj = drop(tree, PAPER_SCENE, st, ours.n_steps, ours.timestep, **kw)
    ext, internal = _relative(mj.external, ours.external), _relative(mj.internal_magnitude, ours.internal_magnitude)
    report("mujoco", f"{name}, constraint law 1e7/s^2: external {ext:.1e}, internal {internal:.1e}")
    assert ext < AGREE and internal < AGREE
    np.testing.assert_allclose(mj.external_vector, ours.external_vector, rtol=AGREE, atol=AGREE * ours.external_norm)
    assert np.all(np.abs(mj.touchdown_time - ours.touchdown_time) <= 1.01 * ours.timestep)
    np.testing.assert_allclose(mj.v_plus, ours.v_plus, atol=AGREE * 10 * np.abs(ours.v_plus).max())
    assert not mj.loaded_at_end
    if terrain is not None:
        order = tuple(int(i) for i in np.argsort(mj.touchdown_time))
        assert order == ours.touchdown_order == (1, 0)


def test_the_agreement_check_can_fail():
    """Control: MuJoCo with 1 % more contact damping (e 0.2 % lower), or with the toe's sphere
    moved 1 mm along its rod, is told apart at the same tolerance."""
    from impulse_core.timedomain.compliant import damping_ratio_for_restitution

    tree = case2()
    st = CompliantSettings(law=ContactLaw.CONSTRAINT, stiffness=1e7, steps_per_period=120)
    ours = simulate_impact(tree, PAPER_SCENE, st)
    zeta = 1.01 * damping_ratio_for_restitution(PAPER_SCENE.restitution)
    damper = CompliantSettings(law=ContactLaw.CONSTRAINT, stiffness=1e7, steps_per_period=120, damping_ratio=zeta)
    mj = drop(tree, PAPER_SCENE, damper, ours.n_steps, ours.timestep)
    assert _relative(mj.external, ours.external) > AGREE
    bodies = list(tree.bodies)
    bodies[4] = Body(**{**bodies[4].__dict__, "contacts": (1.0 - 1e-3 / bodies[4].length,)})
    moved = Tree(tuple(bodies))
    mj = drop(moved, PAPER_SCENE, st, ours.n_steps, ours.timestep)
    assert _relative(mj.internal_magnitude, ours.internal_magnitude) > AGREE


def test_penalty_law_agrees_with_mujoco_as_contacts_stiffen():
    """Uneven terrain (toe, then heel 5 ms later): each contact's MuJoCo solref is set from its
    effective mass at its own touchdown."""
    errors = []
    for k in (1e6, 1e8):
        st = CompliantSettings(law=ContactLaw.PENALTY, stiffness=k, steps_per_period=120, flight_step=None)
        ours = simulate_impact(case2(), PAPER_SCENE, st, terrain=UNEVEN)
        mj = drop(
            case2(), PAPER_SCENE, st, ours.n_steps, ours.timestep, terrain=UNEVEN, effective_mass=ours.effective_mass
        )
        errors.append(
            max(_relative(mj.external, ours.external), _relative(mj.internal_magnitude, ours.internal_magnitude))
        )
    report("mujoco", f"uneven, penalty law vs MuJoCo at 1e6, 1e8 N/m: {errors[0]:.1e}, {errors[1]:.1e}")
    assert errors[1] < 3e-4
    assert 5.0 < errors[0] / errors[1] < 20.0  # ~ k^-1/2: a factor 10 over two decades


def test_mujoco_converges_to_newton_on_flat_ground():
    """Heel and toe at once (case 2), MuJoCo's contact at growing stiffness: its impulses approach
    eq. 11's, the error falling as k^-1/2."""
    rigid = evaluate(case2(), PAPER_SCENE)
    errors = []
    for k in (1e6, 1e8, 1e9):
        st = CompliantSettings(law=ContactLaw.CONSTRAINT, stiffness=k, steps_per_period=480)
        ours = simulate_impact(case2(), PAPER_SCENE, st)
        mj = drop(case2(), PAPER_SCENE, st, ours.n_steps, ours.timestep)
        errors.append(_relative(mj.external, rigid.external))
    report("mujoco", "case 2, MuJoCo vs Newton (external): " + " ".join(f"{x:.1e}" for x in errors))
    assert errors[-1] < 1.5e-3
    assert errors[0] > errors[1] > errors[2]


def test_mujoco_restitution_is_the_clipped_spring_dampers():
    """One contact under a body's centre of mass (pure translation): MuJoCo's contact, which
    releases instead of pulling, rebounds at e = 0.8 with the clipped-law damping ratio
    (zeta = 0.0744) and about 1 % faster with the textbook ratio (zeta = 0.0708)."""
    puck = Tree((Body("puck", None, 0.2, 1.0, 0.0, contacts=(0.5,)),))
    scene = Scene(speed=2.0, restitution=0.8)
    textbook = -math.log(0.8) / math.sqrt(math.pi**2 + math.log(0.8) ** 2)
    e = {}
    for name, zeta in (("clipped", None), ("textbook", textbook)):
        st = CompliantSettings(law=ContactLaw.CONSTRAINT, stiffness=1e6, steps_per_period=960, damping_ratio=zeta)
        ours = simulate_impact(puck, scene, st)
        mj = drop(puck, scene, st, ours.n_steps + 5, ours.timestep)
        e[name] = mj.v_plus[1] / scene.speed
    report(
        "mujoco", f"MuJoCo restitution for e = 0.8: clipped zeta -> {e['clipped']:.4f}, textbook -> {e['textbook']:.4f}"
    )
    assert e["clipped"] == pytest.approx(0.8, abs=1e-3)
    assert e["textbook"] == pytest.approx(0.8081, abs=1e-3)


def test_mjcf_has_massless_contact_spheres_and_explicit_inertias():
    text = build_mjcf(case2(), UNEVEN, 1e-5, np.array([1e6, 1e6]), np.array([100.0, 100.0]))
    assert text.count("<inertial") == 5 and text.count('type="sphere"') == 2 and 'mass="0"' in text
    assert text.count('type="box"') == 4  # two ramps' ends flat, one flat segment, one ramp
