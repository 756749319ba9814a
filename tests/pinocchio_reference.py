"""The tree built in Pinocchio, for agreement tests (the bridge lives in the package, where the
benchmark uses it too)."""

from optimizer.validation.pinocchio_bridge import PinocchioTree, build, velocity_map

__all__ = ["PinocchioTree", "build", "velocity_map"]
