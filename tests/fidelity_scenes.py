"""Scenes for the compliant-rung, terrain and MuJoCo tests, defined in code (independent of the
model-file parser; configs/uneven_terrain.yaml carries the same scene as ``scene.terrain``).

``case2`` is the paper's case-2 foot as reconstructed in configs/paper_case2.yaml (the same
links and touchdown angles); ``UNEVEN`` is configs/uneven_terrain.yaml's ground (toe on a ramp,
heel on the flat below); ``rod`` and ``chain`` are single-contact trees.
"""

from __future__ import annotations

from impulse_core.model.terrain import Terrain
from impulse_core.model.tree import Body, ContactSelection, Scene, Tree

#: The paper's landing: 3.43 m/s straight down, e = 0.8, frictionless.
PAPER_SCENE = Scene(speed=3.43, restitution=0.8, friction=0.0, selection=ContactSelection.ALL)
#: configs/uneven_terrain.yaml: the toe lands on a 7.6 deg ramp, the heel ~18 mm lower on flat ground.
UNEVEN = Terrain((-1.0, 0.45, 0.75), (0.0, 0.0, 0.04))


def case2() -> Tree:
    """Thigh, shank, heel, two-link toe: configs/paper_case2.yaml's tree (heel and toe level)."""
    return Tree(
        (
            Body("thigh", None, 0.7, 1.0, -1.092828420382082),
            Body("shank", 0, 0.7, 1.0, -0.7322878207449532),
            Body("heel", 1, 0.15, 0.1, -0.7749100362086652, contacts=(1.0,)),
            Body("toe_proximal", 1, 0.3, 0.2667, 1.5662662433584877),
            Body("toe_distal", 3, 0.15, 0.1333, 0.25530919850114353, contacts=(1.0,)),
        )
    )


def case3() -> Tree:
    """Case 2 with three identical toe chains in the plane (the paper's case 3 structure), at
    case 2's angles and case 3's toe masses (Table 7: a third each)."""
    toes = []
    for k in range(3):
        toes += [
            Body(f"toe{k + 1}_proximal", 1, 0.3, 0.0889, 1.5662662433584877),
            Body(f"toe{k + 1}_distal", 3 + 2 * k, 0.15, 0.0444, 0.25530919850114353, contacts=(1.0,)),
        ]
    base = case2().bodies
    return Tree((*base[:3], *toes))


def rod(angle: float = -0.7) -> Tree:
    """One rod landing on its tip, tilted: a single contact with rotation."""
    return Tree((Body("rod", None, 1.0, 1.0, angle, contacts=(1.0,)),))


def chain() -> Tree:
    """Three passive links, one contact at the end: a single contact with internal joints."""
    return Tree(
        (
            Body("thigh", None, 0.5, 2.0, -1.3),
            Body("shank", 0, 0.5, 1.0, 0.5),
            Body("foot", 1, 0.2, 0.3, 1.2, contacts=(1.0,)),
        )
    )
