"""The impacts: the first touchdown at t = 0 and each later touchdown or stop, by the impact law
(:mod:`.impact_law`) over every contact that touches and every joint on a stop, plastic where
slow or short (:meth:`_Impacts.impact`)."""

from __future__ import annotations

import math

import numpy as np

from impulse_core.evaluate import pre_impact_velocity
from impulse_core.model.tree import ContactSelection
from impulse_core.timedomain.compliant import joint_impulses, world_velocity
from impulse_core.timedomain.events.settings import PLASTIC_SPEED, SETTLE_SPEED
from impulse_core.timedomain.events.results import LandingEvent
from impulse_core.timedomain.events.point import _Point, _any
from impulse_core.timedomain.events.rows import _Mode, _Rows, _rows
from impulse_core.timedomain.events.forces import contact_impulses
from impulse_core.timedomain.events.impact_law import rigid_impact
from impulse_core.timedomain.events.tally import _Totals


class _Impacts:
    """The impacts of a run: the first touchdown and every later one."""

    def impact(
        self, q: np.ndarray, v: np.ndarray, mode: _Mode, t: float, contacts: np.ndarray, kind: str
    ) -> tuple[np.ndarray, LandingEvent, _Mode]:
        """The rigid impact at (q, v) over ``contacts`` and every joint on or past a stop: the
        velocities after, the event, and which rows rest afterwards."""
        pt = self.point(q, v)
        stops = self.stops_touching(q, mode)
        plain, corners = self.corner_split(mode, contacts)
        rows = _rows(pt, plain, self.no_slip(), stops, self.mu, self.nv, corners=corners)
        n, on_contact, on_stop = rows.n, rows.contact >= 0, rows.dof >= 0
        u = rows.G @ v
        approach = -u[:n]
        e = np.where(on_contact, self.e, self.joints.restitution[np.maximum(rows.dof, 0)])
        e = np.where(approach > PLASTIC_SPEED, e, 0.0)
        plastic = (approach <= PLASTIC_SPEED) | (self.bounce_time(pt, rows, e * approach) < self.min_bounce)
        e = np.where(plastic, 0.0, e)
        law = rigid_impact(pt, v, rows, e, self.mu, self.lemke)
        self.last_impact = law
        if self.impact_log is not None:
            self.impact_log.append((q.copy(), v.copy(), np.array(contacts), pt, law))
        self.inexact += not law.exact
        self.non_unique += not law.split_unique
        sol, v_plus, fn, ft = law.solution, law.v_plus, law.normal, law.tangential
        if self.tape is not None:
            self.tape.append(("impact", q.copy(), v.copy(), rows, e.copy(), sol, plastic))
        F = contact_impulses(pt, fn, ft)
        joint = self.point(q, v_plus).momentum - pt.momentum - F @ self.in_subtree.T
        internal, magnitude = joint_impulses(joint)
        stop = np.zeros(self.nv)
        stop_dofs = rows.dof[on_stop]
        stop[stop_dofs] = (-stops[stop_dofs]) * sol.normal[on_stop]
        # resting afterwards: no bounce, or a plastic row left slower than the plastic speed (it
        # rests unless the forces pull it away; the velocity projection takes the rest)
        leaving = sol.velocity[:n]
        after = (leaving <= self.speed_tol) | ((e == 0) & (leaving < PLASTIC_SPEED))
        # a contact above the ground (``contacts: all`` makes every one hit at t = 0) stays open
        on_ground = pt.gap[np.maximum(rows.contact, 0)] <= self.scene.contact_tolerance + self.settings.gap_tolerance
        new = mode.copy()
        new.closed[:] = False
        new.closed[rows.contact[on_contact & after & on_ground]] = True
        if corners is not None:  # a corner rests on where both its rows do; else it opens (touching again)
            self.keep_corners(new, mode, rows, (on_contact & after & on_ground)[:n])
        new.stop[:] = 0
        at = rows.dof[on_stop & after]
        new.stop[at] = stops[at]
        event = LandingEvent(
            time=t, kind=kind, external=fn, tangential=self.public_tangential(ft), internal=internal[:, : self.dims],
            internal_magnitude=magnitude, stop=self.per_joint(stop), v_minus=world_velocity(q, v, self.space),
            v_plus=world_velocity(q, v_plus, self.space),
            energy_before=float(v @ pt.M @ v) / 2, energy_after=float(v_plus @ pt.M @ v_plus) / 2,
        )
        return v_plus, event, new

    def corner_split(self, mode: _Mode, contacts: np.ndarray
                     ) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray] | None]:
        """``contacts`` split into those with one row each and ``mode``'s resting in a corner,
        with their segments' normals (:func:`_rows`' ``corners``; None: none)."""
        if not mode.has_corner:
            return contacts, None
        held = mode.cornered[contacts] & mode.closed[contacts]
        cornered = contacts[held]
        return contacts[~held], (cornered, self.valleys[mode.corner[cornered]])

    def keep_corners(self, new: _Mode, mode: _Mode, rows: _Rows, rest: np.ndarray) -> None:
        """In ``new`` (closed where some row of the contact rests): each of ``mode``'s corner
        contacts in ``rows`` stays in its corner where both its rows rest (``rest``, per normal
        row), else opens: released from one segment it touches the other again (an event, plastic
        that slow) along that segment's own normal, which a point exactly at the breakpoint would
        not have (its normal is the mean of the two)."""
        both = np.zeros(self.nc, int)
        np.add.at(both, rows.contact[: rows.n][rows.cornered], rest[rows.cornered].astype(int))
        cornered = np.unique(rows.contact[: rows.n][rows.cornered])
        kept = both[cornered] == 2
        new.closed[cornered] = kept
        new.corner[:] = -1
        new.corner[cornered[kept]] = mode.corner[cornered[kept]]
        new.slip[cornered] = 0.0

    @staticmethod
    def rests_nowhere(contacts: np.ndarray, stops: np.ndarray) -> bool:
        """No contact near the ground at rest and no joint on a stop: :meth:`resolve`'s LCP would
        have no rows and leave every contact open and every joint free (:meth:`flight`)."""
        return not contacts.size and not _any(stops)

    def bounce_time(self, pt: _Point, rows: _Rows, rebound: np.ndarray) -> np.ndarray:
        """Per normal row: how long a rebound at speed ``rebound`` would last before the row's
        free acceleration (springs, gravity, spin) brings it back (inf where it pulls away)."""
        free = rows.G[: rows.n] @ np.linalg.solve(pt.M, pt.f) + rows.b[: rows.n]
        time, back = np.full(rows.n, np.inf), free < 0
        time[back] = 2.0 * rebound[back] / -free[back]
        return time

    def touchdown(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, LandingEvent, _Mode]:
        """The first event (t = 0): the touchdown state (q, v), the velocity after, the event and
        the rows resting after it; the law's answer is :attr:`last_impact`."""
        self.set_chart(self.design, None)
        self.seated = np.full(self.nc, -1)
        q = self.q0.copy()
        v = pre_impact_velocity(self.topology, self.scene, self.space) if self.v_minus is None else self.v_minus.copy()
        none = self.flight()
        hit = self.first_contacts(self.point(q, v))
        v_plus, event, mode = self.impact(q, v, none, 0.0, hit, "touchdown")
        return q, v, v_plus, event, mode

    def first_impact(self) -> tuple[np.ndarray, np.ndarray, _Mode, _Totals]:
        """t = 0: the first-impact law over the contacts the scene selects."""
        q, v, v_plus, event, mode = self.touchdown()
        totals = _Totals(np.zeros(self.nc), np.zeros((self.nc, self.dims - 1)), [event])
        totals.impulse, totals.vectors = np.zeros(self.dims), np.zeros((self.dims, self.nc))
        totals.joint = np.zeros((self.dims, self.tree.n_bodies)) if self.tally_joint else None
        totals.moving_until = 0.0 if np.max(np.abs(v_plus)) < SETTLE_SPEED else math.nan
        self.add_impact(totals, event, q, v, v_plus)
        q, v_plus, mode = self.resolve_or_jam(q, v_plus, mode, 0.0, totals)
        q1, v1, impulse = self.project(q, v_plus, mode)
        self.add(totals, impulse, *self.projected_at)
        self.tally_joints(totals, q, v_plus, q1, v1, impulse, 0.0, _any(mode.closed))
        return q1, v1, mode, totals

    def first_contacts(self, pt: _Point) -> np.ndarray:
        """The contacts of the first impact: every one (``contacts: all``), or those whose gap is
        within ``scene.contact_tolerance`` of the smallest: on flat ground the rigid rungs' lowest
        contacts (:func:`impulse_core.evaluate.active_contacts`), on uneven ground (a terrain, a
        heightfield) those that touch, not those lowest in the tree's own frame."""
        if self.scene.selection is ContactSelection.ALL:
            return np.arange(self.nc)
        return np.flatnonzero(pt.gap <= np.min(pt.gap) + self.scene.contact_tolerance)
