"""The planar Coulomb impact's modes at the boundary between sticking and sliding, by hand.

One contact (rows n, t) with W = I, approaching at 1 m/s, e = 0: the normal impulse is 1 N s and
friction can take up to mu of tangential speed; a tangential speed u_t beyond mu leaves the
contact sliding at u_t - mu, however slowly, with friction -mu lambda_n; below mu it sticks with
friction -u_t. The modes (``ContactMode``) feed the reports and the derivatives along the mode
(:mod:`impulse_core.impact.mode_derivatives`), so a slow slide must not be called sticking.
"""

from __future__ import annotations

import numpy as np
import pytest

from impulse_core.impact.coulomb import ContactMode, coulomb_impact

MU = 0.5


@pytest.mark.parametrize("slip", [1e-2, 1e-5, 1e-7, 1e-8])
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_a_slow_slide_is_sliding_and_takes_the_whole_friction(slip: float, sign: float) -> None:
    u = np.array([-1.0, sign * (MU + slip)])
    r = coulomb_impact(np.eye(2), u, 0.0, MU)
    assert r.normal[0] == pytest.approx(1.0, rel=1e-12)
    assert r.tangential[0] == pytest.approx(-sign * MU, rel=1e-12)
    assert r.velocity[1] == pytest.approx(sign * slip, rel=1e-6)
    assert r.modes == (ContactMode.SLIDING,)


@pytest.mark.parametrize("margin", [1e-2, 1e-7])
def test_a_contact_inside_the_cone_sticks(margin: float) -> None:
    u = np.array([-1.0, MU - margin])
    r = coulomb_impact(np.eye(2), u, 0.0, MU)
    assert r.tangential[0] == pytest.approx(-(MU - margin), rel=1e-12)
    assert abs(r.velocity[1]) <= 1e-14
    assert r.modes == (ContactMode.STICKING,)


def test_a_contact_that_leaves_is_separating() -> None:
    r = coulomb_impact(np.eye(2), np.array([0.5, 0.3]), 0.0, MU)
    assert r.normal[0] == 0.0 and r.tangential[0] == 0.0
    assert r.modes == (ContactMode.SEPARATING,)


@pytest.mark.parametrize("seed", range(5))
def test_without_friction_the_impact_is_the_frictionless_lcp_and_takes_no_tangential_impulse(seed: int) -> None:
    """mu = 0: the normal impulses are the frictionless LCP's (by NNLS on a factor E with
    E^T E = W_nn, ``laws.complementarity_impulse``: an independent solver), and the tangential
    ones are exactly 0, not the 1e-17 that Lemke's basic friction variables keep."""
    from impulse_core.impact.laws import complementarity_impulse

    rng = np.random.default_rng(seed)
    for _ in range(20):
        n = int(rng.integers(1, 5))
        A = rng.normal(size=(2 * n, 2 * n))
        W = A @ A.T + 0.1 * np.eye(2 * n)
        u = rng.normal(size=2 * n)
        u[:n] = -np.abs(u[:n])
        e = 0.3
        r = coulomb_impact(W, u, e, 0.0)
        assert np.all(r.tangential == 0.0), r.tangential
        E = np.linalg.cholesky(W[:n, :n]).T  # E^T E = W_nn
        f = -(1 + e) * np.linalg.solve(E.T, u[:n])  # E^T f = -(1 + e) u_n
        expected = complementarity_impulse(E, f)
        assert np.allclose(r.normal, expected, rtol=0, atol=1e-10 * max(1.0, np.abs(expected).max()))


@pytest.mark.parametrize("light", [1e-8, 1e-5])
def test_a_lightly_loaded_contact_is_not_separating_in_the_plane_or_in_space(light: float) -> None:
    """Two independent contacts (W = I), one approaching at 1 m/s and one at ``light`` m/s, e = 0,
    no slip: the second takes an impulse ``light`` times the first's and sticks; it is loaded,
    not separating, down to the modes' threshold (1e-9 of the largest normal impulse)."""
    from impulse_core.impact.cone import cone_impact

    planar = coulomb_impact(np.eye(4), np.array([-1.0, -light, 0.0, 0.0]), 0.0, MU)
    assert planar.normal == pytest.approx([1.0, light], rel=1e-12)
    assert planar.modes == (ContactMode.STICKING, ContactMode.STICKING)
    spatial = cone_impact(np.eye(6), np.array([-1.0, -light, 0.0, 0.0, 0.0, 0.0]), 0.0, MU)
    assert spatial.exact and spatial.normal == pytest.approx([1.0, light], rel=1e-12)
    assert spatial.modes == (ContactMode.STICKING, ContactMode.STICKING)
