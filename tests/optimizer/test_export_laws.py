"""What MuJoCo reads from an exported MJCF: a spring's rest angle relative to the touchdown angle
(the exported zero), and the refusal of a rod whose principal moments MuJoCo would refuse.

configs/landing_case3.yaml's springs rest at their touchdown angles, where an absolute and a
relative rest angle are both 0 in the exported frame; here the rests differ from the angles.
"""

from __future__ import annotations

import math

import pytest

from impulse_core.kinematics.spatial import SPATIAL
from impulse_core.model.joints import FREE, JointLaw
from impulse_core.model.tree import Body, Scene, Tree
from optimizer.errors import ConfigError
from optimizer.results.export import check_inertias, to_mjcf

mujoco = pytest.importorskip("mujoco")

LEG = Tree((
    Body("hip", None, 0.4, 3.0, -1.2),
    Body("knee", 0, 0.4, 1.0, 0.7),
    Body("ankle", 1, 0.2, 0.5, -0.4, contacts=(1.0,)),
))
SCENE = Scene(speed=2.0, restitution=0.3)


def test_a_springs_rest_is_written_relative_to_the_touchdown_angle() -> None:
    laws = (FREE, JointLaw(stiffness=40.0, rest=0.2), JointLaw(stiffness=15.0, rest=-1.0, damping=0.3))
    m = mujoco.MjModel.from_xml_string(to_mjcf(LEG, SCENE, joints=laws))
    for b, law in zip(LEG.bodies[1:], laws[1:]):
        j = m.joint(b.name)
        assert m.jnt_stiffness[j.id] == law.stiffness
        assert m.qpos_spring[j.qposadr[0]] == pytest.approx(law.rest - b.angle, abs=1e-12)
        assert m.qpos0[j.qposadr[0]] == 0.0  # the touchdown posture is the exported zero


def _rod(radius: float, inertia: float) -> Tree:
    gyration = math.sqrt(inertia / 2.0) / 0.5
    return Tree((Body("puck", None, 0.5, 2.0, -1.0, contacts=(1.0,), radius=radius, gyration=gyration),))


def test_a_rod_outside_the_triangle_inequality_is_refused_and_one_inside_loads() -> None:
    """m r^2 / 2 about the axis against the inertia across: MuJoCo needs the axial moment at most
    twice the transverse one (each principal moment at most the sum of the other two)."""
    r = 0.1  # 2 kg: m r^2 / 2 = 0.01 kg m^2
    inside = _rod(r, 0.0051)  # 0.01 <= 2 x 0.0051
    check_inertias(inside)
    mujoco.MjModel.from_xml_string(to_mjcf(inside, SCENE, space=SPATIAL))
    outside = _rod(r, 0.0049)  # 0.01 > 2 x 0.0049
    with pytest.raises(ConfigError, match=r"^model\.bodies\[0\]\.radius: "):
        check_inertias(outside)
    with pytest.raises(ConfigError, match=r"^model\.bodies\[0\]\.radius: "):
        to_mjcf(outside, SCENE, space=SPATIAL)
