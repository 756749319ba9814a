"""The adaptive compliant rung's Dormand-Prince 5(4) tableau (``impulse_core.timedomain.adaptive``):
its orders, measured on an equation with a known solution.

A mistyped coefficient leaves the integrator running (its step control shrinks the steps until
the estimate is met) but costs it its order, or makes the error estimate measure something else:
the rung's answers would still converge, slowly, and the tolerance would not mean what it says.
"""

from __future__ import annotations

import numpy as np
import pytest

from impulse_core.timedomain.adaptive import DOPRI_A, DOPRI_E


def _rate(y: np.ndarray) -> np.ndarray:
    """y = (t, u), u' = -2 t u^2 (non-autonomous and nonlinear: every order condition matters);
    u = 1 / (1 + t^2) through (0, 1)."""
    return np.array([1.0, -2.0 * y[0] * y[1] ** 2])


def _exact(t: float) -> float:
    return 1.0 / (1.0 + t * t)


def _step(y: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """One step as the module's compiled step takes it: the stages from DOPRI_A, the last stage's
    point the fifth-order answer (FSAL), and h sum DOPRI_E k the error estimate."""
    ks = [_rate(y)]
    stage = y
    for row in DOPRI_A[1:]:
        stage = y + h * sum((a * k for a, k in zip(row, ks)), np.zeros_like(y))
        ks.append(_rate(stage))
    return stage, h * sum((e * k for e, k in zip(DOPRI_E, ks)), np.zeros_like(y))


def test_the_tableau_is_consistent() -> None:
    """The fifth-order weights (the last row, FSAL) sum to 1; the fourth-order ones (the weights
    less DOPRI_E) too, so the estimate's weights sum to 0; each row's nodes lie in [0, 1]."""
    weights = np.array(DOPRI_A[-1] + (0.0,))
    assert weights.sum() == pytest.approx(1.0, abs=1e-15)
    assert sum(DOPRI_E) == pytest.approx(0.0, abs=1e-15)
    assert (weights - np.array(DOPRI_E)).sum() == pytest.approx(1.0, abs=1e-15)
    assert all(0.0 <= sum(row) <= 1.0 + 1e-15 for row in DOPRI_A)


@pytest.mark.parametrize("t0", [0.3, 1.1])
def test_local_errors_have_the_orders_five_and_four(t0: float) -> None:
    """Halving the step divides the fifth-order answer's local error by about 2^6 and the error
    estimate (the fourth-order answer's local error, to leading order) by about 2^5."""
    errors, estimates = [], []
    for h in (0.08, 0.04, 0.02):
        y5, estimate = _step(np.array([t0, _exact(t0)]), h)
        assert y5[0] == pytest.approx(t0 + h, abs=1e-15)
        errors.append(abs(y5[1] - _exact(t0 + h)))
        estimates.append(abs(estimate[1]))
    for a, b in zip(errors, errors[1:]):
        assert 40.0 < a / b < 100.0, errors
    for a, b in zip(estimates, estimates[1:]):
        assert 20.0 < a / b < 50.0, estimates
