"""The dynamics along a run: the point at (q, v), kept for the next ask (:meth:`_Dynamics.point`),
a mode's rows and forces there, the acceleration the integrators step, and the per-DOF and per-joint
bookkeeping of stops."""

from __future__ import annotations

import functools

import numpy as np

from impulse_core.timedomain.events.point import _Point, _along, _any, tangent_basis
from impulse_core.timedomain.events.rows import _Mode, _Rows, _mode_bytes, _mode_rows, _rests
from impulse_core.timedomain.events.forces import _accelerations, _contact_forces, _stacked


class _Dynamics:
    """The dynamics at a run's states (:class:`~.point._Point`) and in its modes."""

    def seat(self, mode: _Mode) -> None:
        """Take ``mode``'s corners as the run's (:attr:`seated`): the kept points are dropped where
        they change."""
        if np.array_equal(mode.corner, self.seated):
            return
        self.seated = mode.corner.copy()
        self._last, self._solutions, self._end = None, (None, {}), None

    @property
    def any_seated(self) -> bool:
        return bool(_any(self.seated >= 0))

    # ---- dynamics

    def point(self, q: np.ndarray, v: np.ndarray) -> _Point:
        """The dynamics at (q, v); the last one is kept, since a step's end is asked for by the
        momentum balance, the divergence check and the witnesses in turn (read only)."""
        key = (q.tobytes(), v.tobytes())
        last = self._last
        if last is not None and last[0] == key:
            return last[1]
        # at the last point's q (an impact's velocity after it): its geometry is this one's
        pt = self._evaluate(q, v, last[1] if last is not None and last[0][0] == key[0] else None)
        self._last = (key, pt)
        return pt

    def _evaluate(self, q: np.ndarray, v: np.ndarray, like: _Point | None = None) -> _Point:
        """The dynamics at (q, v); ``like``: a point at the same q, whose figures of q alone (gap,
        normal and tangents, Jacobians, mass matrix, contact positions: the compiled function
        computes them alike from q) are shared rather than derived again (read only)."""
        self.call.call(q, v)
        o, f = self.call.out, self.call.flat
        d = self.dims
        nc, nv = self.nc, self.nv
        bias = f[3].reshape(nc, d)
        if like is None and d == 2:
            # the plane: the normal and tangent components of the Jacobian rows and of the bias at
            # once, (n_x x + n_y y, as _along adds them) over [J | bias] per contact
            normal = o[1].T.copy()
            if self.any_seated:  # a contact in a valley corner: the breakpoint's frame
                held = self.seated >= 0
                normal[held] = self.seat_frames[self.seated[held]]
            tangent = tangent_basis(normal)
            JB = np.concatenate([o[2].reshape(nc, d, nv), bias[:, :, None]], axis=2)  # nc x d x (nv + 1)
            D = np.stack([normal, tangent[:, 0]], axis=1)[:, :, :, None]  # nc x (normal, tangent) x d x 1
            out = D[:, :, 0] * JB[:, None, 0]
            out += D[:, :, 1] * JB[:, None, 1]
            # in _along's memory order (the compiled function's column-major J), the tangent's axis
            # added as a view as before: matmul takes another path, and rounds otherwise, on other strides
            Jn, Jt = np.asfortranarray(out[:, 0, :nv]), np.asfortranarray(out[:, 1, :nv])[:, None]
            bn, bt = np.ascontiguousarray(out[:, 0, nv]), np.ascontiguousarray(out[:, 1, nv])[:, None]
            gap, M, contacts = f[0].copy(), o[4].copy(), o[9].T.copy()
        else:
            if like is None:
                normal = o[1].T.copy()
                tangent = tangent_basis(normal)
                J = o[2].reshape(nc, d, nv)  # per contact, its x, y, z rows
                Jt = np.stack([_along(tangent[:, a], J) for a in range(d - 1)], axis=1)
                gap, Jn, M, contacts = f[0].copy(), _along(normal, J), o[4].copy(), o[9].T.copy()
            else:
                normal, tangent, Jt = like.normal, like.tangent, like.Jt
                gap, Jn, M, contacts = like.gap, like.Jn, like.M, like.contacts
            bn = _along(normal, bias)
            if d == 2:
                bt = _along(tangent[:, 0], bias)[:, None]
            else:
                bt = np.column_stack([_along(tangent[:, a], bias) for a in range(d - 1)])
        return _Point(
            gap=gap,
            normal=normal,
            tangent=tangent,
            Jn=Jn,
            Jt=Jt,
            bn=bn,
            bt=bt,
            M=M,
            f=f[5] + self.joints.torque(q, v),
            kinetic=float(f[6][0]),
            momentum=o[7].copy(),
            com_height=float(f[8][0]),
            contacts=contacts,
            slip=Jt @ v,
            slip_floor=self.speed_tol,
        )

    def mode_solution(self, pt: _Point, mode: _Mode, solve: bool = True
                      ) -> tuple[_Rows, tuple[np.ndarray, np.ndarray] | None]:
        """The mode's rows at ``pt`` (:func:`_mode_rows`) and, if ``solve``, its accelerations and
        row forces (:func:`_accelerations`), kept for the last point asked: an event's mode choice,
        its checks and the projection after it ask them of one point for one or two modes."""
        if self._solutions[0] is not pt:
            self._solutions = (pt, {})
        known = self._solutions[1]
        key = _mode_bytes(mode) + mode.core.tobytes()
        rows, solution = known.get(key, (None, None))
        if rows is None:
            rows = _mode_rows(pt, mode, self.mu, self.valleys)
        if solve and solution is None:
            solution = _accelerations(pt, rows)
        known[key] = (rows, solution)
        return rows, solution

    def mass_matrix_at(self, q: np.ndarray) -> np.ndarray:
        """The mass matrix at q."""
        self.call.call(q, np.zeros(self.nv))
        return self.call.out[4].copy()

    def derivative(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> tuple[np.ndarray, np.ndarray]:
        """(acceleration, [normal forces, tangential forces]) in the fixed mode."""
        pt = self.point(q, v)
        if not _rests(mode):  # free flight: no rows to build
            return np.linalg.solve(pt.M, pt.f), np.zeros(self.dims * self.nc)
        rows = _mode_rows(pt, mode, self.mu, self.valleys)
        a, lam = _accelerations(pt, rows)
        return a, _stacked(*_contact_forces(rows, lam, self.mu, self.nc))

    def kinetic(self, q: np.ndarray, v: np.ndarray) -> float:
        """The kinetic energy at (q, v)."""
        end = self.ended(q, v)
        return end.kinetic if end is not None else self.point(q, v).kinetic

    def weight(self, duration: float) -> np.ndarray:
        """The weight's impulse over ``duration`` (world frame: along -y)."""
        return -self.mass * self.scene.gravity * duration * self.flat_ground[0][0]

    def flight(self) -> _Mode:
        """The mode without rows: every contact open, every joint free."""
        return _Mode(np.zeros(self.nc, bool), self.no_slip(), np.zeros(self.nv, int))

    def no_slip(self) -> np.ndarray:
        """A mode's ``slip`` with every contact sticking (n_c x (d - 1))."""
        return np.zeros((self.nc, self.dims - 1))

    def public_tangential(self, ft: np.ndarray) -> np.ndarray:
        """Tangential impulses per contact as reported: along +x in the plane (n_c), [t_x, t_z] in
        space (n_c x 2)."""
        return ft[:, 0].copy() if self.dims == 2 else ft.copy()

    def stops_touching(self, q: np.ndarray, mode: _Mode) -> np.ndarray:
        """Per DOF: the stop it rests on or has reached (-1 lower, +1 upper), else 0."""
        lo, hi = self.stop_reach
        at = np.where(q <= lo, -1, np.where(q >= hi, 1, 0))
        return np.where(mode.stop != 0, mode.stop, at)

    @functools.cached_property
    def stop_reach(self) -> tuple[np.ndarray, np.ndarray]:
        """Where a joint reaches its stops (:meth:`stops_touching`): within the gap tolerance."""
        tol = self.settings.gap_tolerance
        return self.joints.lo + tol, self.joints.hi - tol

    def per_joint(self, per_dof: np.ndarray) -> np.ndarray:
        """A per-DOF quantity as one entry per non-base body (0 for fixed joints)."""
        jointed, dofs = self.joint_dofs
        out = np.zeros(len(jointed))
        out[jointed] = per_dof[dofs]
        return out

    @functools.cached_property
    def joint_dofs(self) -> tuple[np.ndarray, np.ndarray]:
        """Per non-base body whether it has a DOF, and those DOFs (:meth:`per_joint`)."""
        body_dof = self.layout.body_dof[1:]
        return np.array([k is not None for k in body_dof], bool), np.array([k for k in body_dof if k is not None], int)
