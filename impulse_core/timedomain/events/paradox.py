"""Painleve's paradox and stalled events: an impulsive jam at a pressed sliding contact
(:meth:`_Paradox.jam`, Darboux-Keller's sliding phase then the impact law at e = 0), and where no
jam ends a stall, a Moreau-Jean bridge across it (:meth:`_Paradox.bridge`)."""

from __future__ import annotations

import numpy as np

from impulse_core.errors import NumericalError
from impulse_core.timedomain.compliant import CHART_LIMIT, joint_impulses, world_velocity
from impulse_core.timedomain.events.settings import PLASTIC_SPEED, _Jams, _Unjammed
from impulse_core.timedomain.events.results import LandingEvent
from impulse_core.timedomain.events.point import _Point, _along, _any, _finite
from impulse_core.timedomain.events.rows import _Mode, _rows
from impulse_core.timedomain.events.forces import contact_impulses, _stacked, _unstacked
from impulse_core.timedomain.events.impact_law import rigid_impact
from impulse_core.timedomain.events.tally import _Totals


#: a diverged run names a pressed sliding contact whose row's effective inverse mass with
#: friction is below this fraction of its frictionless one (:meth:`_Landing.jam_note`)
JAM_NOTE = 1e-4
#: Impulsive jams at one instant after which the run stops with Painleve's paradox's error (the
#: jams did not end it: :meth:`_Landing.take_jam`; a cascade of jams at one instant takes the slip
#: by about a fixed factor each, 0.58 on random file 30325: 40 take it from 1 to 1e-9 m/s).
JAM_REPEATS = 200
#: Jams closer than this fraction of the duration are at one instant (:meth:`_Landing.take_jam`).
JAM_INSTANT = 1e-9
#: A run that diverged with a contact sliding is run again (:meth:`_Landing.run`); a pressed
#: sliding contact whose A = n M^-1 (n - mu u t)^T falls below this fraction of its frictionless
#: value then jams at a step's start, before its force -B / A takes the steps off (random file
#: 40029: by A at 2e-6 of it the steps had taken the slip from -2 to -25 m/s).
JAM_WATCH = 1e-3
#: Darboux-Keller's sliding phase in space (:func:`darboux_keller_slide`): RK4 steps in the normal
#: impulse, each a quarter of the slip over its rate, at most this many.
JAM_SLIDE_STEPS = 4000


def darboux_keller_slide(W: np.ndarray, slip: np.ndarray, mu: float) -> tuple[float, np.ndarray] | None:
    """The sliding phase of one contact's impulsive jam (impact without collision; Darboux-Keller,
    as in Genot and Brogliato 1999 and Champneys and Varkonyi 2016, "The Painleve paradox in
    contact mechanics", section 4): with the contact's normal impulse p as the impact's time,
    its impulse grows along the friction cone's edge, dP = (1, -mu u) dp with u = s / |s| its
    slip direction, its slip s (tangent basis, d - 1 entries) changes as ds/dp = W_tn - mu W_tt u
    and its normal velocity as dv_n/dp = A = W_nn - mu W_nt u (the row's effective inverse mass
    with friction: compression where A < 0), W = [n; t] M^-1 [n; t]^T the contact's Delassus
    matrix (rows normal, then tangents; constant during an impact). It ends when the slip
    vanishes, or (in space, where u and so A turn) when a compression deeper than JAM_NOTE of
    the initial slip speed is over, v_n back to its start (Newton's law at e = 0 against the
    pre-jam normal velocity); a shallower one is the dynamic jam's limit (A -> 0, v_n moving by
    A p -> 0: the slide goes on). In the plane in one step (u and A fixed, s linear in p); in
    space by RK4 in p, the compression's end bisected.

    Returns (p, the tangential impulse P_t, d - 1), or None where the slip does not fall along
    the edge (u . ds/dp >= 0: no edge impulse stops it)."""
    w_tn, w_tt, w_nt = W[1:, 0], W[1:, 1:], W[0, 1:]
    s = np.asarray(slip, dtype=float).copy()
    s0 = float(np.linalg.norm(s))
    if s0 == 0.0:
        return 0.0, np.zeros_like(s)
    if len(s) == 1:  # the plane: the slip falls linearly in p
        u = np.sign(s)
        rate = float(w_tn[0] - mu * w_tt[0, 0] * u[0])
        if rate * u[0] >= 0.0:
            return None
        p = -float(s[0]) / rate
        return p, -mu * u * p

    def derivative(y: np.ndarray) -> np.ndarray:  # y = (s, P_t, v_n - its start)
        u = y[:2] / np.linalg.norm(y[:2])
        return np.concatenate([w_tn - mu * w_tt @ u, -mu * u, [W[0, 0] - mu * w_nt @ u]])

    def rk4(y: np.ndarray, dp: float) -> np.ndarray:
        k1 = derivative(y)
        k2 = derivative(y + 0.5 * dp * k1)
        k3 = derivative(y + 0.5 * dp * k2)
        k4 = derivative(y + dp * k3)
        return y + dp / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)

    y, p, compressed = np.concatenate([s, np.zeros(3)]), 0.0, False
    for _ in range(JAM_SLIDE_STEPS):
        size = float(np.linalg.norm(y[:2]))
        if size <= 1e-12 * s0:
            return p, y[2:4]
        rate = derivative(y)[:2]
        if float(rate @ y[:2]) >= 0.0:
            return None
        dp = 0.25 * size / float(np.linalg.norm(rate))
        y1 = rk4(y, dp)
        if compressed and y1[4] >= 0.0:  # the compression ends within this step: bisect it
            lo, hi = 0.0, dp
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if rk4(y, mid)[4] < 0.0 else (lo, mid)
            return p + lo, rk4(y, lo)[2:4]
        compressed = compressed or y1[4] < -JAM_NOTE * s0
        y, p = y1, p + dp
    return None


#: Events stalled without a Painleve jam: the run crosses BRIDGE x its step by BRIDGE_STEPS
#: Moreau-Jean steps (:meth:`_Landing.bridge`), at most MAX_BRIDGES times a run.
BRIDGE = 1.0 / 8.0
BRIDGE_STEPS = 8
MAX_BRIDGES = 64


class _BridgeBlewUp(Exception):
    """A bridge's Moreau-Jean step left finite numbers or the base's chart (:meth:`_Paradox.bridge`)."""


class _Paradox:
    """Impulsive jams at Painleve's paradox and Moreau-Jean bridges across stalled events."""

    def painleve(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> np.ndarray:
        """Closed sliding contacts in Painleve's paradox at (q, v): their own row's effective
        inverse mass with its friction along the slip, n M^-1 (n - mu u t)^T, is negative, so no
        pushing force keeps them on the ground, and the mode's force on them pulls."""
        if not self.mu or not _any(mode.sliding & mode.closed):
            return np.zeros(0, int)
        contact, inverse_mass, _, fn = self.sliding_rows(q, v, mode)
        jammed = (inverse_mass < 0) & mode.sliding[contact] & (fn < -self.force_tol)
        return contact[jammed]

    def sliding_jams(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> np.ndarray:
        """Contacts resting on the ground (closed in ``mode``, or at the ground with no normal
        speed) that slide (|s| above the speed tolerance) where their row's effective inverse
        mass with friction along the slip, A = n M^-1 (n - mu u t)^T with u = s / |s|, is
        negative or below JAM_NOTE of n M^-1 n^T: where the contact problem at the acceleration
        level fails (:class:`PainleveParadox`), the contacts that can jam."""
        if not self.mu:
            return np.zeros(0, int)
        pt = self.point(q, v)
        speed = np.linalg.norm(pt.slip, axis=1)
        near = mode.closed | ((pt.gap <= self.settings.gap_tolerance) & (np.abs(pt.vn(v)) <= self.speed_tol))
        c = np.flatnonzero(near & (speed > self.speed_tol))
        if not c.size:
            return c
        u = pt.slip[c] / speed[c, None]
        F = pt.Jn[c] - _along(self.mu * u, pt.Jt[c])
        minv_jn = np.linalg.solve(pt.M, pt.Jn[c].T)
        A = np.einsum("ij,ji->i", F, minv_jn)
        A0 = np.einsum("ij,ji->i", pt.Jn[c], minv_jn)
        return c[A < JAM_NOTE * A0]

    def jam(self, q: np.ndarray, v: np.ndarray, mode: _Mode, t: float, contact: int
            ) -> tuple[np.ndarray, LandingEvent, _Mode] | None:
        """The impulsive jam at (q, v) of the sliding ``contact`` in Painleve's paradox (an impact
        without collision: Genot and Brogliato 1999; Or and Rimon 2012; Champneys and Varkonyi
        2016): the velocities after, the event (kind "touchdown", ``jam`` set) and the rows resting
        after it; None where the slip does not fall along the cone's edge.

        The law, in two phases (Darboux-Keller with Newton's law):
        1. the contact's sliding phase (:func:`darboux_keller_slide`): its impulse grows along the
           cone's edge, n - mu u t, until its slip stops (or, in space, a compression ends); its
           normal velocity changes by A p (compression where A < 0).
        2. the landing's impact law (:func:`rigid_impact`: Newton's restitution, exact Coulomb
           friction) over every contact at the ground and every joint on a stop, at e = 0 (Newton's
           law refers to the pre-jam normal velocities, 0: v_n+ >= 0), from phase 1's velocities.
        Why this law: (a) where A < 0 and a single contact jams in the plane it is the h -> 0
        limit of velocity-level time stepping (Stewart-Trinkle, Anitescu-Potra) with the pressing
        free velocity: zero is then no solution of the step's LCP, no small one exists (it would
        need p = -h B / A < 0), and the limit is the sticking impulse -W^-1 (0, s), inside the cone
        exactly when A < 0; phase 1 then 2 give that impulse (W invertible: same end velocity). (b)
        where A falls to 0+ while pressed, the mode's own force -B / A integrates (logarithmically
        without bound) to an impulse along the edge within a vanishing time: phase 1 is that limit,
        and A p, the normal velocity it leaves, vanishes with A (the run takes the jam at A below
        JAM_WATCH of its frictionless value; over the jam's vanishing duration the pressing
        free acceleration B takes back the normal speed A p the slide gives: the contact rests
        after it, and the projection takes that O(A) rest).
        The total impulse is in the cone (a sum of cone members), its normal part >= 0; the
        other contacts take part in phase 2 only (the jam's sliding phase is the jammed
        contact's alone: a sequential split where several contacts are loaded)."""
        if self.tape is not None:
            raise NumericalError(f"an impulsive jam at t = {t:.6g} s: exact landing derivatives are refused across it")
        pt = self.point(q, v)
        J = np.vstack([pt.Jn[contact][None], pt.Jt[contact]])  # d x nv: normal, then tangents
        minv_jt = np.linalg.solve(pt.M, J.T)
        slide = darboux_keller_slide(J @ minv_jt, pt.slip[contact], self.mu)
        if slide is None:
            return None
        p, p_t = slide
        impulse = np.concatenate([[p], p_t])
        v1 = v + minv_jt @ impulse
        lift = max(float(J[0] @ minv_jt @ impulse), 0.0)  # the normal speed the slide left (A p where A > 0)
        stops = self.stops_touching(q, mode)
        contacts = np.flatnonzero(mode.closed | (pt.gap <= self.settings.gap_tolerance))
        rows = _rows(pt, contacts, self.no_slip(), stops, self.mu, self.nv)
        law = rigid_impact(pt, v1, rows, np.zeros(rows.n), self.mu, self.lemke)
        self.last_impact = law
        if self.impact_log is not None:
            self.impact_log.append((q.copy(), v.copy(), np.array(contacts), pt, law))
        self.inexact += not law.exact
        self.non_unique += not law.split_unique
        v_plus, fn, ft = law.v_plus, law.normal.copy(), law.tangential.copy()
        fn[contact] += p
        ft[contact] += p_t
        F = contact_impulses(pt, fn, ft)
        internal, magnitude = joint_impulses(self.point(q, v_plus).momentum - pt.momentum - F @ self.in_subtree.T)
        n, on_contact, on_stop = rows.n, rows.contact >= 0, rows.dof >= 0
        stop = np.zeros(self.nv)
        stop[rows.dof[on_stop]] = (-stops[rows.dof[on_stop]]) * law.solution.normal[on_stop]
        leaving = law.solution.velocity[:n]
        after = leaving < PLASTIC_SPEED  # e = 0: a row left slower than the plastic speed rests
        # the jammed contact rests where it leaves only at the speed its slide gave it: where A > 0
        # (a dynamic jam taken at A below JAM_WATCH, not at 0) the pressing free acceleration
        # holds it over the jam's vanishing duration, B dt = -A p, and the projection takes it
        after |= (rows.contact == contact) & (leaving <= lift + PLASTIC_SPEED)
        on_ground = pt.gap[np.maximum(rows.contact, 0)] <= self.scene.contact_tolerance + self.settings.gap_tolerance
        new = mode.copy()
        new.closed[:] = False
        new.closed[rows.contact[on_contact & after & on_ground]] = True
        new.slip[:] = 0.0
        new.stop[:] = 0
        at = rows.dof[on_stop & after]
        new.stop[at] = stops[at]
        event = LandingEvent(
            time=t, kind="touchdown", external=fn, tangential=self.public_tangential(ft),
            internal=internal[:, : self.dims], internal_magnitude=magnitude, stop=self.per_joint(stop),
            v_minus=world_velocity(q, v, self.space), v_plus=world_velocity(q, v_plus, self.space),
            energy_before=float(v @ pt.M @ v) / 2, energy_after=float(v_plus @ pt.M @ v_plus) / 2, jam=True,
        )
        return v_plus, event, new

    def take_jam(self, q: np.ndarray, v: np.ndarray, mode: _Mode, t: float, totals: _Totals,
                 jammed: np.ndarray, failure: NumericalError) -> tuple[np.ndarray, np.ndarray, _Mode]:
        """The impulsive jam (:meth:`jam`) of the one contact in ``jammed`` at (q, v), counted in
        ``totals``, and the slow slips arrested after it (:meth:`arrest`): (q, v, the rows resting
        after it). Raises ``failure`` (the error the landing stopped with before jams were
        modelled) where not one contact jams, where the jam's sliding phase does not stop the
        slip, or where this is the JAM_REPEATS-th jam at one instant (the jam did not end it)."""
        last, count = self._jams
        count = count + 1 if abs(t - last) <= JAM_INSTANT * float(self.scene.duration) else 1
        self._jams = (t, count)
        if len(jammed) != 1 or count >= JAM_REPEATS:
            raise failure
        jam = self.jam(q, v, mode, t, int(jammed[0]))
        if jam is None:
            raise failure
        v_plus, event, new = jam
        totals.events.append(event)
        self.add_impact(totals, event, q, v, v_plus)
        q1, v1 = self.arrest(q, v_plus, new, totals)
        return q1, v1, new

    def bridge(self, q: np.ndarray, v: np.ndarray, mode: _Mode, t: float, totals: _Totals, span: float
               ) -> tuple[np.ndarray, np.ndarray, _Mode, float]:
        """Events stalled where no Painleve jam explains it (a start of slip, or a stick-slip
        cycle among nearly redundant contacts, that the modes do not resolve): the landing crosses
        ``span`` by :data:`BRIDGE_STEPS` Moreau-Jean steps (:meth:`bridge_step`), whose impulses
        are the contacts' (continuous: no events), then takes the modes at the end
        (:meth:`modes_after`). First order in the step, as the step halving's estimate sees.
        Returns (q, v, mode, t) after; raises :class:`_BridgeBlewUp` where a step's state is not
        finite or turns the base beyond the rotation coordinates' chart."""
        if self.tape is not None:
            self.tape.append(("bridge", q.copy(), v.copy(), mode.copy(), span))
        start, dt, v_before, closed = t, span / BRIDGE_STEPS, v, mode.closed
        for _ in range(BRIDGE_STEPS):
            q1, v1, impulses, closed = self.bridge_step(q, v, mode, closed, dt)
            if not (_finite(q1) and _finite(v1)) or (not self.planar and float(np.linalg.norm(q1[3:6])) > CHART_LIMIT):
                raise _BridgeBlewUp()
            self.add(totals, impulses, q, v)
            self.tally_joints(totals, q, v, q1, v1, impulses, dt, True)
            self.record(totals, t, v, t + dt, q1, v1)
            q, v, t = q1, v1, t + dt
            totals.steps += 1
        after = self.flight()
        after.closed[:] = closed
        after.stop[:] = self.stops_touching(q, mode)
        q, v, mode = self.modes_after(q, v, after, t, totals, v_before)
        self.bridges.append((start, span))
        return q, v, mode, t

    def bridge_step(self, q: np.ndarray, v: np.ndarray, mode: _Mode, closed: np.ndarray, dt: float
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """One Moreau-Jean step (Moreau 1988, Jean 1999; Siconos's ``MoreauJeanOSI`` at theta =
        1): the free velocity v + dt M^-1 f, then the rigid law with e = 0 and exact Coulomb
        friction (:func:`rigid_impact`; every row sticking, so the law picks stick or slip) over
        the contacts ``closed`` or whose gap the free velocity closes within the step, and the
        stops reached (``mode``'s or within the step); then q + dt v+. Returns (q, v, the law's
        impulses [normal, tangential] per contact, the contacts that took a normal impulse)."""
        pt = self.point(q, v)
        v_free = v + dt * np.linalg.solve(pt.M, pt.f)
        reach = closed | (pt.gap + dt * np.minimum(pt.vn(v_free), 0.0) <= self.settings.gap_tolerance)
        plain, corners = self.corner_split(mode, np.flatnonzero(reach))
        rows = _rows(pt, plain, self.no_slip(), self.stops_touching(q + dt * v_free, mode), self.mu, self.nv,
                     corners=corners)
        law = rigid_impact(pt, v_free, rows, np.zeros(rows.n), self.mu, self.lemke)
        self.inexact += not law.exact
        impulses, q1 = _stacked(law.normal, law.tangential), q + dt * law.v_plus
        return q1, self.balance_kept(pt, q1, law.v_plus, impulses, dt), impulses, law.normal > 0

    def balance_kept(self, pt: _Point, q1: np.ndarray, v1: np.ndarray, impulses: np.ndarray, dt: float
                     ) -> np.ndarray:
        """``v1`` with the base's translation velocity shifted so that the linear momentum at (q1, v1)
        is the momentum at ``pt`` plus the weight's impulse over ``dt`` and the contact ``impulses``
        (stacked, along ``pt``'s directions): a Moreau-Jean step's momentum at its end. Its velocity
        after is taken at q1, while its forces were at q: across a velocity jump the step changed
        the momentum by dt times the jump in the Coriolis terms, first order in dt (random file
        60690: a bridge took a tumbling rod from 35 to 26 rad/s, the landing's balance 1.1e-4)."""
        applied = self.world_vectors(*_unstacked(impulses, self.nc, self.dims - 1), pt).sum(axis=1)
        return self.with_momentum(q1, v1, pt.momentum[:, 0] + self.weight(dt) + applied, pt.M[0, 0])

    def jam_event(self, q: np.ndarray, v: np.ndarray, mode: _Mode, t: float, totals: _Totals,
                  jammed: np.ndarray, failure: NumericalError) -> tuple[np.ndarray, np.ndarray, _Mode]:
        """An event that is only an impulsive jam at (q, v) (:meth:`take_jam`; a run's step that
        ran into Painleve's paradox, or events stalled by it), then the modes after it (as
        :meth:`event`): the state and mode after."""
        q1, v1, new = self.take_jam(q, v, mode, t, totals, jammed, failure)
        return self.modes_after(q1, v1, new, t, totals, v, jammed=True)

    def watched_jam(self, q: np.ndarray, v: np.ndarray, mode: _Mode, t: float, totals: _Totals, span: float,
                    bridged: int) -> tuple[np.ndarray, np.ndarray, _Mode, float, int] | None:
        """At a step's start in a run that watches for jams (:attr:`jam_watch`): where a pressed sliding
        contact's A fell below the watch, the state, mode, time and bridges after its jam (or a bridge of
        ``span``, :meth:`jam_or_bridge`); else None."""
        jammed, ratio = self.near_jam(q, v, mode, self.jam_watch)
        jammed = jammed[ratio > 0.0]  # A falling to 0 while pressed (A < 0 pressed: a choice, B > 0)
        if not jammed.size:
            return None
        failure = NumericalError(self.painleve_message(
            t, jammed, f"friction {self.mu:g} takes their rows' effective mass to 0"))
        return self.jam_or_bridge(q, v, mode, t, totals, jammed, failure, span, bridged)

    def unstall(self, q: np.ndarray, v: np.ndarray, mode: _Mode, t: float, totals: _Totals, span: float,
                bridged: int) -> tuple[np.ndarray, np.ndarray, _Mode, float, int]:
        """Events stalled at (q, v, ``t``): the state, mode, time and bridges after a bridge of ``span``
        (:meth:`bridge_within`), or after an impulsive jam where Painleve's paradox stalled them
        (:meth:`jam_or_bridge`; :class:`_Jams` where the run does not yet jam)."""
        failure = NumericalError(self.stall_message(q, v, mode, t))
        jammed = self.painleve(q, v, mode)
        if not jammed.size:
            return self.bridge_within(q, v, mode, t, totals, span, bridged, failure)
        if self.jam_watch is None:
            raise _Jams(failure)
        # events stalled by Painleve's paradox: the impulsive jam, here
        return self.jam_or_bridge(q, v, mode, t, totals, jammed, failure, span, bridged)

    def jam_or_bridge(self, q: np.ndarray, v: np.ndarray, mode: _Mode, t: float, totals: _Totals,
                      jammed: np.ndarray, failure: NumericalError, span: float, bridged: int
                      ) -> tuple[np.ndarray, np.ndarray, _Mode, float, int]:
        """:meth:`jam_event`, or where the jam cannot be taken (it raises ``failure``: its slide does
        not stop the slip, or it came back at one instant) a bridge across ``span`` (:meth:`bridge`;
        ``bridged`` so far, at most MAX_BRIDGES): Moreau-Jean's velocity-level law has a solution
        where the acceleration-level one has none (Stewart 1998). Random file 60690: a rod's tip
        at friction 0.3, whose jam stopped ending its slip at t = 0.1777 s. (q, v, mode, t, bridged)."""
        try:
            return (*self.jam_event(q, v, mode, t, totals, jammed, failure), t, bridged)
        except _Unjammed as after:  # a jam taken, the next one not: the bridge starts after the first
            return self.bridge_within(after.q, after.v, after.mode, t, totals, span, bridged, after.failure)
        except NumericalError as unjammed:
            if unjammed is not failure:
                raise
        return self.bridge_within(q, v, mode, t, totals, span, bridged, failure)

    def bridge_within(self, q: np.ndarray, v: np.ndarray, mode: _Mode, t: float, totals: _Totals, span: float,
                      bridged: int, failure: NumericalError) -> tuple[np.ndarray, np.ndarray, _Mode, float, int]:
        """A bridge across ``span`` (:meth:`bridge`) as the run's next, (q, v, mode, t, bridged + 1);
        raises ``failure`` where the run has taken MAX_BRIDGES already."""
        if bridged >= MAX_BRIDGES:
            raise failure
        try:
            return (*self.bridge(q, v, mode, t, totals, span), bridged + 1)
        except _BridgeBlewUp:  # random file 32113 at its first step: the run stops as without the bridge
            raise failure from None
