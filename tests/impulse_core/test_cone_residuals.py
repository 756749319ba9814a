"""The circular cone's own law check (``impulse_core.impact.cone.law_residuals``), part by part.

``law_residuals`` decides whether an answer is the exact law's (``ConeImpact.exact``) or only
the polygon's, so each of its parts must see its own violation: an answer that breaks exactly one
part of the law is flagged by that part and by no other.
"""

from __future__ import annotations

import numpy as np
import pytest

from impulse_core.impact.cone import law_residuals

#: One contact (rows n, x, z), W diagonal: the impulses act on their own rows only.
W = np.diag([2.0, 3.0, 3.0])


def _flagged(u: np.ndarray, e: float, mu: float, normal: float, tangential: tuple[float, float]) -> dict[str, float]:
    r = law_residuals(W, u, e, mu, np.array([normal]), np.array([tangential]))
    return {k: v for k, v in r.items() if v > 1e-12}


@pytest.mark.parametrize("e", [0.0, 0.4])
def test_each_part_of_the_law_sees_its_own_violation(e: float) -> None:
    """By hand, one contact approaching at 1 m/s with W = diag(2, 3, 3): the law's sticking answer
    is flagged nowhere; an impulse too large (it leaves faster than e times the approach while
    pushing) only by complementarity; none at all (it keeps approaching) only by restitution; a
    tangential impulse beyond mu times the normal one, with the slip stopped, only by the cone."""
    mu = 0.5
    u = np.array([-1.0, 0.2, -0.1])  # approaching, a little slip
    lam_n = (1 + e) / 2.0  # v+_n = -1 + 2 lam_n = e: restitution met with equality
    stick = (-u[1] / 3.0, -u[2] / 3.0)  # v+_t = 0, |t| = 0.075 < mu lam_n
    assert _flagged(u, e, mu, lam_n, stick) == {}
    assert set(_flagged(u, e, mu, lam_n * 1.5, stick)) == {"complementarity"}
    assert set(_flagged(u, e, mu, 0.0, (0.0, 0.0))) == {"restitution >= 0"}
    fast = np.array([-1.0, 3.0, 0.0])  # a slip that only a tangential impulse of 1 stops
    assert set(_flagged(fast, e, mu, lam_n, (-1.0, 0.0))) == {"cone"}


def test_a_slow_slip_is_still_held_to_the_sliding_law() -> None:
    """A contact that still slips after the impact, at 1e-6 of the approach speed: its friction
    must be mu lambda_n against the slip. An impulse half that (inside the cone, so no other part
    objects) is flagged by "sliding opposes slip" however slow the slip, down to the law's
    tolerance (1e-9 of the approach speed)."""
    e, mu = 0.0, 0.5
    lam_n = 0.5
    for slip in (1e-3, 1e-6, 1e-8):
        t = -0.5 * mu * lam_n  # half the sliding friction, along -x
        u = np.array([-1.0, slip - 3.0 * t, 0.0])  # so that v+_x = slip
        r = law_residuals(W, u, e, mu, np.array([lam_n]), np.array([[t, 0.0]]))
        assert r["sliding opposes slip"] == pytest.approx(0.5 * mu, rel=1e-9), slip
        assert max(v for k, v in r.items() if k != "sliding opposes slip") <= 1e-12
