"""Model files with a ground profile: the proposed ``scene.terrain`` and ``scene.base_x`` keys.

Until the model-file parser knows these keys (``optimizer.model_file.SCENE_KEYS``), this module
reads them itself: it takes them out of the ``scene`` block, validates them, and hands the rest
to :func:`optimizer.model_file.parse_model`. Proposed contract (an extension of MODEL_FORMAT.md;
a file without these keys means flat ground at y = 0 and the base above x = 0, as before)::

    scene:
      terrain: [[-1.0, 0.0], [0.45, 0.0], [0.75, 0.04]]   # ground profile y(x), world frame, m:
                          # breakpoints with strictly increasing x, linear between them, flat
                          # beyond the ends; one point [x, y] is flat ground at height y
      base_x: 0.0         # x (m) of the base's origin (the first body's joint end) at touchdown;
                          # the model, at its touchdown angles, is lowered straight down until its
                          # first contact touches the terrain (smallest vertical clearance)

The rigid rungs (``impulse_core.evaluate``) assume flat ground and ignore both keys; the compliant
rung (``impulse_core.compliant.simulate_impact``) and the sequential rigid model
(``impulse_core.sequential.sequential_impacts``) take ``terrain`` and ``base_x``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from impulse_core.errors import ModelError
from impulse_core.terrain import FLAT, Terrain
from optimizer.errors import ConfigError
from optimizer.model_file import ModelFile, load_yaml, parse_model

TERRAIN_SCENE_KEYS = ("terrain", "base_x")


@dataclass(frozen=True)
class TerrainScene:
    """A model file's tree and scene with its ground profile and placement."""

    model: ModelFile
    terrain: Terrain = FLAT
    base_x: float = 0.0


def parse_terrain(value: Any, where: str = "scene.terrain") -> Terrain:
    """Validate ``scene.terrain``: a non-empty list of ``[x, y]`` pairs of finite numbers with x
    strictly increasing.

    Raises:
        ConfigError: naming the entry at fault (``scene.terrain[2]: ...``).
    """
    if not isinstance(value, list) or not value:
        raise ConfigError(f"{where}: must be a non-empty list of [x, y] points (m), got {value!r}")
    points = []
    for i, p in enumerate(value):
        if not (isinstance(p, list) and len(p) == 2):
            raise ConfigError(f"{where}[{i}]: must be a pair [x, y] (m), got {p!r}")
        for k, c in enumerate(p):
            if isinstance(c, bool) or not isinstance(c, (int, float)) or not math.isfinite(float(c)):
                raise ConfigError(f"{where}[{i}][{k}]: must be a finite number, got {c!r}")
        points.append((float(p[0]), float(p[1])))
    try:
        return Terrain.from_points(points)
    except ModelError as e:
        raise ConfigError(str(e).replace("scene.terrain", where, 1)) from None


def parse_base_x(value: Any, where: str = "scene.base_x") -> float:
    """Validate ``scene.base_x``: a finite number (m)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(float(value)):
        raise ConfigError(f"{where}: must be a finite number (m), got {value!r}")
    return float(value)


def parse_terrain_scene(data: Any, path: str | Path | None = None) -> TerrainScene:
    """A loaded model document, with the terrain keys taken out of ``scene`` and validated."""
    terrain, base_x = FLAT, 0.0
    if isinstance(data, dict) and isinstance(data.get("scene"), dict):
        scene = dict(data["scene"])
        if "terrain" in scene:
            terrain = parse_terrain(scene.pop("terrain"))
        if "base_x" in scene:
            base_x = parse_base_x(scene.pop("base_x"))
        data = {**data, "scene": scene}
    return TerrainScene(parse_model(data, path), terrain, base_x)


def load_terrain_scene(path: str | Path) -> TerrainScene:
    """Read a model file that may carry ``scene.terrain`` and ``scene.base_x``."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as e:
        raise ConfigError(f"cannot read the file: {e.strerror or e}", path) from None
    try:
        return parse_terrain_scene(load_yaml(text, path), path)
    except ConfigError as e:
        e.source = e.source or path
        raise


__all__ = [
    "TERRAIN_SCENE_KEYS",
    "TerrainScene",
    "load_terrain_scene",
    "parse_base_x",
    "parse_terrain",
    "parse_terrain_scene",
]
