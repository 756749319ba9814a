"""What acts at a revolute joint between impacts: a torsional spring and damper, and mechanical
stops (``MODEL_FORMAT.md``, "Joint stops and springs").

Springs and dampers give no impulse, so the first impact does not see them; they act during a
whole landing (``impulse_core.timedomain.landing``). Reaching a stop is an impact of the joint with
the stop's own restitution.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from impulse_core.errors import ModelError


@dataclass(frozen=True)
class JointLaw:
    """One revolute joint's spring, damper and stops (all optional).

    Attributes:
        stiffness: torsional stiffness (N m/rad), >= 0.
        damping: torsional damping (N m s/rad), >= 0.
        rest: the spring's rest angle (rad); None: the touchdown angle.
        limits: (lo, hi) joint-angle stops (rad), lo < hi; None: no stops.
        stop_restitution: Newton's coefficient of an impact at a stop, in [0, 1].
    """

    stiffness: float = 0.0
    damping: float = 0.0
    rest: float | None = None
    limits: tuple[float, float] | None = None
    stop_restitution: float = 0.0

    def validate(self, where: str) -> None:
        """Raise ModelError naming the field (``where`` is the body's path) at fault."""
        for name in ("stiffness", "damping"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ModelError(f"{where}.{name}: must be a finite number >= 0, got {v}")
        if self.rest is not None and not math.isfinite(self.rest):
            raise ModelError(f"{where}.rest: must be a finite number (rad), got {self.rest}")
        if not (math.isfinite(self.stop_restitution) and 0.0 <= self.stop_restitution <= 1.0):
            raise ModelError(f"{where}.stop_restitution: must be in [0, 1], got {self.stop_restitution}")
        if self.limits is not None:
            lo, hi = self.limits
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                raise ModelError(f"{where}.limits: must be [lo, hi] with lo < hi (rad), got [{lo}, {hi}]")

    @property
    def is_default(self) -> bool:
        """True when the joint is free: no spring, damper or stops."""
        return self == JointLaw()


#: A free joint.
FREE = JointLaw()


__all__ = ["FREE", "JointLaw"]
