"""Exact derivatives of the exact-friction impulses along the reported contact modes.

The Newton-Coulomb law (:mod:`impulse_core.impact.coulomb`) is piecewise smooth: within one
assignment of contact modes its impulses solve a linear system, so the implicit function theorem
gives their derivatives w.r.t. the design values. Per contact i, with v+ = v- + W lambda:

    separating:  lambda_n,i = 0,                lambda_t,i = 0
    sticking:    v+_n,i = -e v-_n,i,            v+_t,i = 0
    sliding:     v+_n,i = -e v-_n,i,            lambda_t,i = -mu s_i lambda_n,i   (s_i = sign v+_t,i)

K(p) lambda = r(p) is built symbolically from the metric function (W and J of the design values
p), and CasADi differentiates lambda = K^-1 r. The derivative is that of the reported branch: where
a small change of p changes a mode, the impulses have a kink there and this is one side of it.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from impulse_core.impact.coulomb import ContactMode


def mode_impulse_function(
    metric: ca.Function, n: int, modes: tuple[ContactMode, ...], signs: tuple[float, ...]
) -> ca.Function:
    """``(p, v_minus, restitution, mu) -> (normal, tangential, d_normal, d_tangential)`` along the
    given modes; ``d_*`` are Jacobians w.r.t. ``p`` (n x n_values).

    Args:
        metric: the tree's metric function with tangent rows (``compiled_metric(..., tangent=True)``):
            outputs ``contact_jacobian`` (normal rows, then tangent rows) and ``delassus``.
        n: active contacts.
        modes, signs: each active contact's mode and, sliding, the sign of its post-impact slip.
    """
    p = ca.SX.sym("p", metric.size1_in(0))
    v = ca.SX.sym("v_minus", metric.size1_in(1))
    e, mu = ca.SX.sym("restitution"), ca.SX.sym("mu")
    out = metric(p=p, v_minus=v)
    J, W = out["contact_jacobian"], out["delassus"]
    w = ca.mtimes(J, v)  # contact velocities before the impact, normal then tangent
    rows, rhs = [], []
    for i, mode in enumerate(modes):
        unit_n, unit_t = _unit(2 * n, i), _unit(2 * n, n + i)
        if mode is ContactMode.SEPARATING:
            rows += [unit_n, unit_t]
            rhs += [0, 0]
            continue
        rows.append(W[i, :])  # v+_n = w_n + W_n lambda = -e w_n
        rhs.append(-(1 + e) * w[i])
        if mode is ContactMode.STICKING:
            rows.append(W[n + i, :])
            rhs.append(-w[n + i])
        else:
            rows.append(unit_t + mu * signs[i] * unit_n)
            rhs.append(0)
    lam = ca.solve(ca.vcat(rows), ca.vcat(rhs))
    normal, tangential = lam[:n], lam[n:]
    return ca.Function(
        "mode_impulses",
        [p, v, e, mu],
        [normal, tangential, ca.jacobian(normal, p), ca.jacobian(tangential, p)],
        ["p", "v_minus", "restitution", "mu"],
        ["normal", "tangential", "d_normal", "d_tangential"],
    )


def _unit(size: int, k: int) -> ca.SX:
    row = ca.SX.zeros(1, size)
    row[k] = 1
    return row


def slip_signs(tangent_velocity: np.ndarray) -> tuple[float, ...]:
    """The sign of each contact's post-impact slip (+1 where it does not slip)."""
    return tuple(float(np.sign(s)) or 1.0 for s in np.asarray(tangent_velocity, dtype=float))


__all__ = ["mode_impulse_function", "slip_signs"]
