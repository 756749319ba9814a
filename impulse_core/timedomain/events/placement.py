"""Back onto the constraints after each step and event (:meth:`_Placement.project`: positions,
then velocities, the projection's impulse counted, the linear momentum kept), no velocity along a
massless direction, and in space the base's rotation chart (re-centred, reported since touchdown)."""

from __future__ import annotations

import math

import numpy as np

from impulse_core.errors import ModelError
from impulse_core.model.rods import rotation_rpy
from impulse_core.model.tree import Tree
from impulse_core.timedomain.compliant import chart_rotation, continued_rotation_vector, world_velocity
from impulse_core.timedomain.events.settings import MASSLESS_REACH, MASSLESS_SWING
from impulse_core.timedomain.events.point import _Point, _any
from impulse_core.timedomain.events.rows import _Mode, _corner_rows, _rests
from impulse_core.timedomain.events.forces import _contact_forces, _least_norm, _stacked
from impulse_core.timedomain.events.tally import _Totals


class _Placement:
    """Projection onto the mode's constraints, massless directions and the base's chart."""

    def project(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Back onto the mode's constraints (:meth:`placed`), and in space no velocity along a
        motion that moves no mass (:meth:`unspun`); returns (q, v, the projection's impulses
        [normal, tangential] per contact)."""
        q1, v1, p = self.placed(q, v, mode)
        return q1, self.unspun(q1, v1), p

    def unspun(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``v`` without its part along the mass matrix's massless directions at q (:data:`MASSLESS`:
        a rod of radius 0 spinning about its own axis); ``v`` itself where there is none. The part
        removed carries kinetic energy and momentum at the floor's level (1e-14 of the rod's)."""
        if self.massless is None:
            return v
        n = self.massless_directions(self.point(q, v).M)
        if n is None:
            return v
        if self.tape is not None:
            self.tape.append(("unspun",))
        return v - n @ (n.T @ v)

    def massless_directions(self, M: np.ndarray) -> np.ndarray | None:
        """The unit eigenvectors of ``M`` (columns) whose eigenvalue is at most :attr:`massless`, or
        None where there is none (or in the plane)."""
        if self.massless is None:
            return None
        try:  # every eigenvalue above the bound (the common case): nothing moves without mass
            np.linalg.cholesky(M - self.massless * np.eye(self.nv))
            return None
        except np.linalg.LinAlgError:
            pass
        w, V = np.linalg.eigh(M)
        n = V[:, w <= self.massless]
        return n if n.shape[1] else None

    def refuse_massless_contacts(self, tree: Tree, M0: np.ndarray) -> None:
        """Refuse (ModelError) a landing in which a massless direction of the mass matrix at
        touchdown (``M0``, :data:`MASSLESS`) moves a contact: a rod of radius 0 whose centre of mass is off
        its axis (``com_offset``, no ``inertia_tensor``) turns about the axis through its centre of
        mass with nothing but the core's floor as inertia (1e-14 of its own), and that turn moves
        its contacts, so the landing would follow the floor, not the model: random file 60145
        chattered, its planar reading in space diverged. A rod of radius 0 spinning about its own
        axis moves no contact and is held still instead (:meth:`unspun`)."""
        n = self.massless_directions(M0)
        if n is None:
            return
        pt = self.point(self.q0, np.zeros(self.nv))
        moved = np.vstack([pt.Jn, pt.Jt.reshape(-1, self.nv)]) @ n
        if np.max(np.abs(moved)) <= MASSLESS_REACH * max(b.length for b in tree.bodies):
            return
        off = [i for i, b in enumerate(tree.bodies) if b.radius == 0.0 and not any(b.tensor) and any(b.com_offset)]
        field = f"model.bodies[{off[0]}].com_offset" if off else "model.bodies"
        raise ModelError(
            f"{field}: the whole landing needs inertia wherever a contact moves, but a rod of radius 0 with its "
            "centre of mass off its axis has none about the axis through that centre (only the core's floor, 1e-14 "
            "of its own) and that turn moves its contacts; give the rod a radius or an inertia_tensor")

    def refuse_swinging_springs(self, tree: Tree, M0: np.ndarray) -> None:
        """Refuse (ModelError) a landing whose springs act along a massless direction of the mass
        matrix at touchdown (``M0``: a rod of radius 0 spinning about its own axis, a joint turning
        back) with no damper on it, wound at touchdown more than :data:`MASSLESS_SWING` from their
        balance along it: the small radius's swing keeps their energy at a rate without bound, and
        the landing at radius 0 is no limit of it. A damper along the direction makes the limit a
        relaxation to the balance (random file 60443, which lands); springs at their balance stay
        there as r -> 0, the rod's spin following (60603 with b1's rest at its angle: 3 mm and 1 mm
        end 1e-5 apart), and are taken, though such a run at radius 0 still diverges."""
        n = self.massless_directions(M0)
        if n is None:
            return
        stiffness, damping = self.joints.stiffness, self.joints.damping
        damped = (damping > 0.0) & np.any(np.abs(n) > MASSLESS_REACH, axis=1)
        if np.any(damped):  # the combinations of the directions that no damper moves
            _, s, vt = np.linalg.svd(n[damped], full_matrices=True)
            n = n @ vt[int(np.sum(s > MASSLESS_REACH)):].T
            if n.shape[1] == 0:
                return
        torque = n.T @ (-stiffness * (self.q0 - self.joints.rest))  # the springs' along the directions
        swing = n @ np.linalg.lstsq(n.T @ (stiffness[:, None] * n), torque, rcond=None)[0]
        wound = np.abs(swing) * (stiffness > 0.0)
        if float(np.max(wound)) <= MASSLESS_SWING:
            return
        j = int(np.argmax(wound))
        b = self.joints.dof_body[j]
        energy = 0.5 * float(swing @ (stiffness * swing))
        rods = ", ".join(body.name for body in tree.bodies if body.radius == 0.0 and not any(body.tensor))
        raise ModelError(
            f"model.bodies[{b}].stiffness: {tree.bodies[b].name}'s spring acts along a motion without inertia (a rod "
            "of radius 0 spinning about its own axis, a joint turning back, nothing else moving) with no damper on "
            f"it, and starts {wound[j]:.3g} rad from its balance along it ({energy:.3g} J): with a radius r the spin "
            "swings about that balance ever faster as r -> 0 (~ 1 / r), keeping that energy, so the angles along it at "
            f"T have no limit at radius 0; give the rod a radius (the rods of radius 0: {rods}) or damp the joint")

    def placed(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Back onto the mode's constraints: closed gaps and stops, and open contacts below the
        ground, to zero (positions), then the closed rows' velocities to zero; returns (q, v,
        the projection's impulses [normal, tangential] per contact). A redundant mode's impulses
        are the split of its forces (:func:`_least_norm`: least-norm on the rows as
        :data:`REDUNDANT` ranks them, pushing where a split does): solved to rounding, a nearly
        redundant pair's velocities took its squeeze (random file 31088: an arrest's 1.95e4 N s
        tangential at two contacts 9.4 cm apart, for slips of 2.5e-6 m/s)."""
        if self.tape is not None:
            self.tape.append(("project", q.copy(), v.copy(), mode.copy()))
        end = self.ended(q, v, mode)
        own = (end is not None and not _any(~mode.closed & (end.gap < 0))
               and not _any((mode.stop == 0) & ((q > self.joints.hi) | (q < self.joints.lo))))
        self.projected_at = (q, v)
        if own:  # a compiled step's end whose placement is the mode's own: the compiled projection
            projected = self.fast.project(q, v, mode)
            if projected is not None and not self.carried_across(q, v, projected[0], mode):
                return projected
        pt = self.point(q, v)
        if self.in_place(pt, q, mode):  # what placement() and the velocity rows would find: nothing to do
            return q.copy(), v, np.zeros(self.dims * self.nc)
        corrected = q - self.placement(pt, q, mode)[1]
        if self.carried_across(q, v, corrected, mode):  # the rows of the cell it now rests on
            pt = self.point(corrected, v)
            self.projected_at = (corrected, v)
            if self.tape is not None:
                self.tape.append(("crease_project",))
        if _any(corrected != q):
            v = self.momentum_kept(q, corrected, v)
        q = corrected
        rows = self.mode_solution(pt, mode, solve=False)[0] if _rests(mode) else None
        if rows is None or not rows.G.shape[0]:
            return q, v, np.zeros(self.dims * self.nc)
        minv_gt = np.linalg.solve(pt.M, rows.G.T)
        if rows.redundant:  # the split of its forces (_accelerations): least-norm, pushing where it can
            v, impulse = _least_norm(rows.G @ minv_gt, -rows.G @ v, v, minv_gt, rows.n)
        else:
            impulse = -np.linalg.lstsq(rows.G @ minv_gt, rows.G @ v, rcond=None)[0]
            v = v + minv_gt @ impulse
        return q, v, _stacked(*_contact_forces(rows, impulse, 0.0, self.nc))

    def momentum_kept(self, q: np.ndarray, corrected: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``v`` with the base's translation velocity shifted by dp / m, dp the linear momentum that
        moving q to ``corrected`` at fixed v would change (the velocity projection after it then
        counts what its rows take as impulses): a position correction moves no momentum. Without
        it random file 60624's corrections (348, a tip resting and sliding across a heightfield)
        moved 1.1e-4 of its momentum with no impulse, above the contract's balance of 1e-4."""
        here = self.point(q, v)
        return self.with_momentum(corrected, v, here.momentum[:, 0], here.M[0, 0])

    def with_momentum(self, q: np.ndarray, v: np.ndarray, p: np.ndarray, mass: float) -> np.ndarray:
        """``v`` with the base's translation velocity shifted so that the linear momentum at (q, v)
        is ``p`` (``mass``: M's corner, the whole mass)."""
        out = v.copy()
        out[: self.dims] += (p - self.point(q, v).momentum[:, 0]) / mass
        return out

    def carried_across(self, q: np.ndarray, v: np.ndarray, corrected: np.ndarray, mode: _Mode) -> bool:
        """Whether the position correction from q to ``corrected`` carries a closed contact into
        another heightfield cell (across a crease)."""
        if self.grid is None or not _any(mode.closed):
            return False
        k0 = self.pieces(q, v)
        return bool(_any(mode.closed & (self.pieces(corrected, v) != k0)))

    def in_place(self, pt: _Point, q: np.ndarray, mode: _Mode) -> bool:
        """Whether :meth:`project` has nothing to do at (q, ``pt``): no rows in the mode, no open
        contact below the ground, no joint past a stop (a flight after a bounce)."""
        return not _rests(mode) and not _any(pt.gap < 0) and not _any(self.beyond(q))

    def placement(self, pt: _Point, q: np.ndarray, mode: _Mode) -> tuple[_Mode, np.ndarray]:
        """The rows a projection at (q, ``pt``) zeroes: the mode's, an open contact left below the
        ground (by rounding), and a free joint past a stop, also one that the correction of the
        others would carry past it (it is put back onto the stop); and that position correction."""
        place = mode.copy()
        place.closed |= pt.gap < 0
        place.stop = np.where(place.stop == 0, self.beyond(q), place.stop)
        dq = self.position_correction(pt, q, place)
        carried = np.where(place.stop == 0, self.beyond(q - dq), 0)
        if _any(carried):
            place.stop = np.where(place.stop == 0, carried, place.stop)
            dq = self.position_correction(pt, q, place)
        return place, dq

    def beyond(self, q: np.ndarray) -> np.ndarray:
        """Per DOF: +1 past its upper stop, -1 past its lower one, else 0. A joint that an impact
        left on its stop moving away (the other rows' impulses can do that) may be carried past
        it by the step's rounding; unprojected, its stop margin stays below the event threshold
        and every step is an event of length 0 (the run stalled so)."""
        return np.where(q > self.joints.hi, 1, np.where(q < self.joints.lo, -1, 0))

    def position_correction(self, pt: _Point, q: np.ndarray, mode: _Mode) -> np.ndarray:
        """The smallest (kinetic-metric) change of q that zeroes the mode's closed gaps and stops."""
        # the mode's normal and stop rows alone (:func:`_rows`' first rows, the same numbers)
        contacts, d = np.flatnonzero(mode.closed), np.flatnonzero(mode.stop)
        nc, n = len(contacts), len(contacts) + len(d)
        if not n:
            return np.zeros_like(q)
        G = np.zeros((n, self.nv))
        G[:nc] = pt.Jn[contacts]
        G[nc + np.arange(len(d)), d] = -mode.stop[d]
        residual = np.empty(n)
        residual[:nc] = pt.gap[contacts]
        residual[nc:] = -mode.stop[d] * (q[d] - np.where(mode.stop[d] > 0, self.joints.hi[d], self.joints.lo[d]))
        if _any(mode.cornered & mode.closed):  # a corner's two rows: the point's distances to the two segments' lines
            c = np.flatnonzero(mode.cornered & mode.closed)
            normals = self.valleys[mode.corner[c]]
            Gc, _, _ = _corner_rows(pt, c, normals)
            vertex = np.column_stack([self.vertices, self.ground.y])[mode.corner[c]]
            distance = np.sum(normals * (pt.contacts[c] - vertex)[:, None, :], axis=2).ravel()
            plain = ~np.isin(np.arange(nc), np.flatnonzero(np.isin(contacts, c)))
            G = np.vstack([G[:nc][plain], Gc, G[nc:]])
            residual = np.concatenate([residual[:nc][plain], distance, residual[nc:]])
        minv_gt = np.linalg.solve(pt.M, G.T)
        return minv_gt @ np.linalg.lstsq(G @ minv_gt, residual, rcond=None)[0]

    # ---- the base's rotation coordinates (space)

    def base_rotation(self) -> np.ndarray:
        """The base's orientation in the call's design vector: R(rpy) R(axis, angle)."""
        names, p = self.space.body_values, self.call.args[2]
        rpy = tuple(float(p[names.index(k)]) for k in ("roll", "pitch", "yaw"))
        k = np.array([float(p[names.index(k)]) for k in ("axis_x", "axis_y", "axis_z")])
        k /= np.linalg.norm(k)
        angle = float(p[names.index("angle")])
        kk = np.outer(k, k)
        turn = kk + math.cos(angle) * (np.eye(3) - kk) + math.sin(angle) * np.array(
            [[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
        return rotation_rpy(rpy) @ turn

    def set_chart(self, design: np.ndarray, chart: np.ndarray | None) -> None:
        """Evaluate the dynamics with ``design`` from now on (the kept points are dropped)."""
        self.call.args[2][:] = design
        if self.fast is not None:
            self.fast.set_design(design)
        self.chart = chart
        self._last, self._solutions, self._end = None, (None, {}), None

    def rechart(self, q: np.ndarray, v: np.ndarray, totals: _Totals) -> tuple[np.ndarray, np.ndarray]:
        """Re-centre the base's rotation coordinates phi = q[3:6] on its current orientation: the
        base's orientation in the design vector becomes Exp(phi) times it (as an axis and an
        angle, rpy 0), phi becomes 0 and its rates S(phi) phi', the world angular velocity. The
        tree's placement and motion are the same, up to rounding."""
        self.turn = self.reported(q)[3:6]
        from scipy.spatial.transform import Rotation  # here: importing scipy.spatial costs ~0.8 s of CPU

        E = chart_rotation(q[3:6])
        rotvec = Rotation.from_matrix(E @ self.base_rotation()).as_rotvec()
        angle = float(np.linalg.norm(rotvec))
        names, design = self.space.body_values, self.call.args[2].copy()
        design[[names.index(k) for k in ("roll", "pitch", "yaw")]] = 0.0
        design[[names.index(k) for k in ("axis_x", "axis_y", "axis_z")]] = rotvec / angle if angle > 0 else (0, 0, 1)
        design[names.index("angle")] = angle
        q_new, v_new = q.copy(), world_velocity(q, v, self.space)
        q_new[3:6] = 0.0
        self.set_chart(design, E if self.chart is None else E @ self.chart)
        totals.chart_q = q_new.copy()
        if self.tape is not None:
            self.tape.append(("rechart", q.copy(), v.copy()))
        return q_new, v_new

    def reported(self, q: np.ndarray) -> np.ndarray:
        """q as reported: in space the base's rotation vector since touchdown (continued through
        the re-centrings, not wrapped), else q itself."""
        if self.chart is None:
            return q.copy()
        out = q.copy()
        out[3:6] = self.turn = continued_rotation_vector(chart_rotation(q[3:6]) @ self.chart, self.turn)
        return out
