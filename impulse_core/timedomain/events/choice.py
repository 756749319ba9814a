"""Which mode holds after an event: the acceleration-level LCP over the resting rows
(:meth:`_ModeChoice.resolve`), sticking where it can, arresting a slip that turned, contacts held
by their forces, coincident contacts unified, and a starting slip along its own acceleration."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from impulse_core.errors import NumericalError
from impulse_core.impact.coulomb import UnilateralSolution
from impulse_core.timedomain.events.settings import PLASTIC_SPEED, SLIP_SCAN, PainleveParadox
from impulse_core.timedomain.events.point import _Point, _any
from impulse_core.timedomain.events.rows import _Mode, _Rows, _rests, _rows
from impulse_core.timedomain.events.forces import (
    REDUNDANT, _contact_forces, _corner_row_forces, _corner_side, _solve_rows, _unstacked,
)
from impulse_core.timedomain.events.tally import _Totals


#: A closed contact the contact LCP leaves unloaded rests on while the mode's force on it is above
#: -HOLD_FORCE force tolerances (:meth:`_Landing.held`; a force witness is located below -0.1).
HOLD_FORCE = 0.05
#: Contacts closer than this (m) are at one point (:meth:`_Landing.unify`).
COINCIDENT = 1e-9


def _unit(x: np.ndarray, tol: float) -> np.ndarray:
    """Rows of ``x`` made unit length where longer than ``tol``, else 0 (the plane: their signs)."""
    size = np.linalg.norm(x, axis=1, keepdims=True)
    return np.divide(x, size, out=np.zeros_like(x, dtype=float), where=size > tol)


def _followed_slip(along: Callable[[np.ndarray], tuple[float, float]], dims: int, acc_tol: float) -> np.ndarray | None:
    """A unit slip d whose acceleration follows it (``along(d)`` = (d x a_t(d), d . a_t(d)), the
    cross product 0 and the dot >= -acc_tol), or None: in the plane (``dims`` 1) the sign that
    does; in space the first of :data:`SLIP_SCAN` angles' brackets of the cross product's sign
    with a following acceleration, bisected to rounding."""
    if dims == 1:
        return next((d for d in (np.array([1.0]), np.array([-1.0])) if along(d)[1] >= -acc_tol), None)
    unit = lambda theta: np.array([math.cos(theta), math.sin(theta)])  # noqa: E731
    angles = np.linspace(-math.pi, math.pi, SLIP_SCAN + 1)
    values = [along(unit(theta)) for theta in angles]
    for (a, (ca_, _)), (b, (cb, _)) in zip(zip(angles, values), zip(angles[1:], values[1:])):
        if ca_ == 0.0 or (ca_ < 0.0) != (cb < 0.0):
            for _ in range(60):
                if ca_ == 0.0 or b - a <= 1e-15:
                    break
                mid = 0.5 * (a + b)
                cm = along(unit(mid))[0]
                a, b, ca_ = (a, mid, ca_) if (cm < 0.0) != (ca_ < 0.0) else (mid, b, cm)
            if along(unit(a))[1] >= -acc_tol:
                return unit(a)
    return None


class _ModeChoice:
    """The modes after an event: which rows rest, stick or slide."""

    def pressing(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> np.ndarray:
        """Per contact: closed in ``mode`` and pushed by its force at (q, v) beyond the force
        tolerance (a contact resting unloaded is not)."""
        pt = self.point(q, v)
        if not _any(mode.closed):
            return np.zeros(self.nc, bool)
        rows, (_, lam) = self.mode_solution(pt, mode)
        return mode.closed & (_contact_forces(rows, lam, self.mu, self.nc)[0] > self.force_tol)

    def resolve(self, q: np.ndarray, v: np.ndarray, mode: _Mode, t: float = 0.0) -> _Mode:
        """Which resting rows stay closed, stick or slide: ``mode`` itself where it holds with a
        margin (:meth:`persists`), else the contact LCP at the acceleration level (e = 0; a
        contact already sliding keeps its direction). ``t``: the time, for the error where no
        contact force exists (Painleve's paradox)."""
        if self.persists(q, v, mode):
            return mode
        pt = self.point(q, v)
        vn = pt.vn(v)
        near = mode.closed | ((pt.gap <= self.settings.gap_tolerance) & (np.abs(vn) <= self.speed_tol))
        contacts = np.flatnonzero(near)
        stops = self.stops_touching(q, mode)
        stops = np.where((mode.stop != 0) | (np.abs(v) <= self.speed_tol), stops, 0)
        if self.rests_nowhere(contacts, stops):  # the LCP would have no rows
            return self.flight()
        slip = _unit(pt.slip, self.speed_tol) if self.mu > 0 else self.no_slip()
        plain, corners = self.corner_split(mode, contacts)
        if corners is not None:
            slip[corners[0]] = 0.0
        for attempt in range(2):
            rows = _rows(pt, plain, slip, stops, self.mu, self.nv, corners=corners)
            minv = np.linalg.solve(pt.M, np.column_stack([pt.f, rows.F.T]))
            u = rows.G @ minv[:, 0] + rows.b
            try:
                sol, acceleration, exact = _solve_rows(rows.G @ minv[:, 1:], u, rows, np.zeros(rows.n), self.lemke)
                self.inexact += not exact
                break
            except NumericalError:
                if attempt or not slip[contacts].any():
                    raise PainleveParadox(self.painleve_message(
                        t, contacts, f"the contact problem has no solution with friction {self.mu:g}")) from None
                slip = self.no_slip()  # let the sliding contacts stick or slide afresh
        acc_tol = 1e-9 * max(1.0, float(np.max(np.abs(u), initial=0.0)))
        rest = sol.normal > self.force_tol  # an unloaded row opens (if it sinks, it touches again)
        rest |= self.held(pt, mode, rows, sol, acc_tol)
        new = self.flight()
        c = rows.contact >= 0
        new.closed[rows.contact[c & rest]] = True
        new.slip[:] = np.where(new.closed[:, None], slip, 0)
        if corners is not None:  # a corner rests on where both its rows do, else it opens
            self.keep_corners(new, mode, rows, rest[: rows.n])
        k = rows.contact[rows.owner]
        starting = (sol.slip > acc_tol) & new.closed[k]
        new.slip[k[starting]] = _unit(acceleration[starting], 0.0)
        d = rows.dof >= 0
        new.stop[rows.dof[d & rest]] = stops[rows.dof[d & rest]]
        new.redundant = self.redundant(pt, new)
        checked = self.consistent_slip(pt, v, self.unify(pt, v, self.slide_on_the_edge(q, v, new)), acc_tol)
        if checked is not new:  # the checks changed the mode (they return it unchanged otherwise)
            checked.redundant = self.redundant(pt, checked)
        return self.stick_where_it_can(q, v, checked)

    def stick_where_it_can(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> _Mode:
        """``mode`` with its contacts that start to slide from rest (|v_t| within the speed
        tolerance) sticking instead, where that mode holds with its own forces: every force
        witness (normal forces, cone margins, stop forces) at least one tolerance inside, as
        :meth:`persists` asks. Pfeiffer and Glocker's transition rule: a resting contact slides
        only when its friction force reaches the cone. The contact problem at the acceleration
        level can have both answers (redundant rows: several contacts on one rigid body; large
        friction), and Lemke's pivots may pick the sliding one, whose least-norm forces in the
        mode's own solve then disagree with the LCP's: the run switched slip directions at every
        event, 4000 events in 90 s at 6e-11 s each (random file 20606). Where the answer is unique
        it is the sticking one whenever this mode holds, so nothing else changes."""
        if self.mu <= 0:
            return mode
        starting = mode.closed & mode.sliding & (np.linalg.norm(self.point(q, v).vt(v), axis=1) <= self.speed_tol)
        if not _any(starting):
            return mode
        probe = mode.copy()
        probe.slip[starting] = 0.0
        probe.redundant = self.redundant(self.point(q, v), probe)
        return probe if self.held_by_its_forces(q, v, probe) else mode

    def held_by_its_forces(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> bool:
        """Whether ``mode`` holds at (q, v) with its own forces: every force witness (normal
        forces, cone margins, stop forces) at least one tolerance inside, as :meth:`persists`
        asks: its contacts push and those sticking have their friction inside the cone."""
        w, _ = self.witness_and_rate(q, v, mode)
        nc, nv = self.nc, self.nv
        forces = np.concatenate([w[nc : 3 * nc], w[4 * nc + 2 * nv :]])  # normal forces, cone margins, stop forces
        return bool((forces >= 2.0).all())

    def arrest(self, q: np.ndarray, v: np.ndarray, mode: _Mode, totals: _Totals) -> tuple[np.ndarray, np.ndarray]:
        """(q, v) with the slip of each closed contact whose slip has turned to or past a right
        angle from the direction it slid along (the slip-reversal witness s . d <= 0) at a slip
        speed below :data:`PLASTIC_SPEED` taken to zero, as a plastic impact takes an approach
        that slow: the mode's projection with those contacts sticking (its impulse counted in
        the totals), where that mode holds with its own forces (:meth:`held_by_its_forces`, the
        transition rule :meth:`stick_where_it_can` applies); else the same with each of them
        alone; where none holds, the same projection when it is slight (:meth:`slight_arrest`),
        else nothing changes (the contact LCP slides them on). The
        contact LCP then sticks them or starts them sliding from rest. In the plane a reversal
        is located at s = 0 and nothing changes; in space a slow slip under a lateral drive
        turns rather than stops (the regularised direction lags it: the lateral slip settles at
        the drive times the step), and each right angle was an event: random file 20693 slid at
        1e-5 m/s with an event every 1e-5 s, and a contact the LCP started sliding along its old
        direction kept its turned slip and reversed again at once. Where friction cannot hold
        the arrested contacts, the projection's impulse is no friction's: two resting contacts
        of a nearly redundant pair (random file 31088: the roots of hinged rods 9.4 cm apart,
        the sticking rows' G M^-1 G^T of condition 1e7) took the pair's squeeze, 595 N s
        tangential on a contact with 1.8 N s of normal impulse (the mode with both sticking
        needs 5e5 N of friction there), pulling in later arrests: the momentum balance cannot
        see it (it sums to zero), but the totals carried it. The mode probed and projected onto
        slides the contacts it calls sticking that slip at least at PLASTIC_SPEED
        (:meth:`as_it_slides`). Its normal impulses may pull a little: zeroing a slip at a closed
        contact whose normal velocity stays zero takes the Delassus matrix's normal-tangent
        coupling (random file 31088: a lone contact's slip of 6.7e-5 m/s, rows of condition 3.9,
        2.6e-4 N s tangential and -1.5e-4 N s normal). Released, that row would leave at 3.9e-5
        m/s, slower than PLASTIC_SPEED, which the projection after the contact LCP would take
        back with a pull of its own (a plastic contact that slow rests); against the mode's force
        (39 N) it is that force over 4e-6 s of the friction the arrest stands for."""
        self.refused = np.zeros(0, int)  # the turned contacts it leaves sliding (a stall, REPEATS, where that repeats)
        if self.dims == 2 or self.mu <= 0 or not _any(mode.closed & mode.sliding):
            return q, v
        slip = self.point(q, v).slip
        turned = (mode.closed & mode.sliding & (np.sum(slip * mode.slip, axis=1) <= 0)
                  & (np.linalg.norm(slip, axis=1) < PLASTIC_SPEED))
        if not _any(turned):
            return q, v
        sliding = self.as_it_slides(slip, mode)
        stuck = self.held_arrest(q, v, sliding, turned)
        taken = self.project(q, v, stuck) if stuck is not None else self.slight_arrest(q, v, sliding, turned)
        if taken is None:
            self.refused = np.flatnonzero(turned)
            return q, v
        q1, v1, p = taken
        self.add(totals, p, *self.projected_at)
        self.tally_joints(totals, q, v, q1, v1, p, 0.0, True)
        return q1, v1

    def slight_arrest(self, q: np.ndarray, v: np.ndarray, mode: _Mode, turned: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """Where no mode with the ``turned`` contacts sticking holds (:meth:`held_arrest`): the
        projection that stops their slips all the same, when its rows are well conditioned (not
        :data:`REDUNDANT`) and it moves each contact by less than :data:`PLASTIC_SPEED` times
        the tree's mass of impulse, as a plastic impact takes an approach that slow; else None.
        The contact LCP after it starts them sliding from rest along a slip their acceleration
        follows (:meth:`consistent_slip`). Left sliding, such a slip turns by a right angle at
        each event: random file 32113's lone tip contact slid at 1e-6 m/s, its acceleration
        square to its slip either way it was flagged, an event every 1e-8 s (a stall)."""
        stuck = mode.copy()
        stuck.slip[turned] = 0.0
        stuck.redundant = self.redundant(self.point(q, v), stuck)
        if stuck.redundant:
            return None
        q1, v1, p = self.project(q, v, stuck)
        fn, ft = _unstacked(p, self.nc, self.dims - 1)
        if float(np.max(np.hypot(fn, np.linalg.norm(ft, axis=1)))) > PLASTIC_SPEED * self.mass:
            return None
        return q1, v1, p

    def as_it_slides(self, slip: np.ndarray, mode: _Mode) -> _Mode:
        """``mode`` with each closed contact it calls sticking whose slip ``slip`` (per contact)
        is at least :data:`PLASTIC_SPEED` sliding along that slip instead: the mode an arrest
        probes and projects onto (:meth:`arrest`). An impact keeps the slip flags of the mode
        before it (:meth:`impact`), and the contact LCP that follows the arrest
        (:meth:`modes_after`) starts such a contact sliding; a projection sticking it would take
        its slip to zero by an impulse that is no arrest (random file 31088 before the squeeze
        fix: 0.012 N s at two contacts slipping at 1.2e-2 m/s after 46 impacts at one instant),
        since an arrest stops only slips slower than the plastic speed. A slower one the mode
        calls sticking stays sticking: its slip stops with the turned ones, as a plastic impact
        takes an approach that slow."""
        fast = mode.closed & ~mode.sliding & (np.linalg.norm(slip, axis=1) >= PLASTIC_SPEED)
        if not _any(fast):
            return mode
        sliding = mode.copy()
        sliding.slip[fast] = _unit(slip[fast], 0.0)
        return sliding

    def held_arrest(self, q: np.ndarray, v: np.ndarray, mode: _Mode, turned: np.ndarray) -> _Mode | None:
        """``mode`` with the ``turned`` contacts sticking where that holds with its own forces
        (:meth:`held_by_its_forces`), else with the first of them alone whose sticking does, or
        None (:meth:`arrest`)."""
        pt = self.point(q, v)
        k = np.flatnonzero(turned)
        for each in [k] + ([k[i : i + 1] for i in range(len(k))] if len(k) > 1 else []):
            stuck = mode.copy()
            stuck.slip[each] = 0.0
            stuck.redundant = self.redundant(pt, stuck)
            if self.held_by_its_forces(q, v, stuck):
                return stuck
        return None

    def held(self, pt: _Point, mode: _Mode, rows: _Rows, sol: UnilateralSolution, acc_tol: float) -> np.ndarray:
        """Per normal row of ``rows``: a closed contact that the acceleration-level LCP ``sol``
        leaves unloaded (force within the force tolerance) and not accelerating away (within
        ``acc_tol``), while the mode's own force on it does not pull (above -:data:`HOLD_FORCE`
        force tolerances). Both answers then meet the law, and the contact rests on, as a
        plastic touchdown leaves it: opened, it would touch down again at the closed rows' drift
        (one gap tolerance), microseconds later, with an impulse of rounding (a rod's tip resting
        on the point where the next rod's root rests, the LCP loading either one: f25's 685
        touchdowns in 0.05 s). When its force pulls, its witness opens it (located below -0.1
        tolerances, below the hold), so an unloading contact is never held at its own event."""
        c = rows.contact >= 0
        candidates = c & (sol.normal[: rows.n] <= self.force_tol) & (sol.velocity[: rows.n] <= acc_tol)
        candidates &= mode.closed[np.maximum(rows.contact, 0)]
        if not candidates.any():
            return np.zeros(rows.n, bool)
        probe = mode.copy()
        probe.redundant = self.redundant(pt, probe)
        mode_rows, (_, lam) = self.mode_solution(pt, probe)
        fn = _contact_forces(mode_rows, lam, self.mu, self.nc)[0]
        force = fn[np.maximum(rows.contact, 0)]
        if rows.cornered is not None and mode_rows.cornered is not None:  # a corner's rows: each its own
            own = _corner_row_forces(mode_rows, lam, self.nc)
            k = np.flatnonzero(rows.cornered)
            force[k] = own[rows.contact[k], _corner_side(rows)[k]]
        return candidates & (force >= -HOLD_FORCE * self.force_tol)

    def persists(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> bool:
        """Whether ``mode`` (after an impact: the rows it left resting, the contacts' slip as
        before) holds at (q, v) with a margin: its rows not redundant, its closed rows at rest
        (slower than the plastic speed, sticking contacts in every direction), every force and slip witness at least one
        tolerance inside (:meth:`witness_and_rate`), no gap or stop margin negative. Mode
        persistence: where the contact problem has several answers (toes that can stick with a
        joint held on its stop, or slide with the stop opening), the run keeps the one it is in;
        Lemke's method may pick the other at each event, and the run would switch between them
        every fraction of a microsecond (a study's design did, 2e5 times)."""
        if not _rests(mode):  # no rows to hold
            return False
        pt = self.point(q, v)
        closed_stop = mode.stop != 0
        sticking = mode.closed & ~mode.sliding
        at_rest = ((np.abs(pt.vn(v)[mode.closed]) < PLASTIC_SPEED).all()  # as an impact leaves them: the
                   and (np.abs(pt.vt(v)[sticking]) < PLASTIC_SPEED).all()  # projection takes the rest
                   and (np.abs(v[closed_stop]) < PLASTIC_SPEED).all())
        if not at_rest or self.redundant(pt, mode):
            return False
        w, _ = self.witness_and_rate(q, v, mode)
        nc, nv = self.nc, self.nv
        geometric = np.concatenate([w[:nc], w[4 * nc : 4 * nc + 2 * nv]])
        forces = np.concatenate([w[nc : 4 * nc], w[4 * nc + 2 * nv :]])
        return bool((geometric >= 1.0).all() and (forces >= 2.0).all())

    def unify(self, pt: _Point, v: np.ndarray, mode: _Mode) -> _Mode:
        """Resting contacts at one point moving alike (identical toes: their tips coincide to
        rounding) take one slip: the sliding one's where one slides and another sticks. The
        contact problem at such a point has many answers, and Lemke's method may stick one toe
        on the cone's edge while the other slides at zero slip acceleration; the identical toes'
        symmetric answer is both sliding (the same forces), and the asymmetric one stalled the
        run (the sticking toe leaves the cone at once)."""
        if self.mu <= 0:
            return mode
        closed = np.flatnonzero(mode.closed)
        vt = pt.vt(v)
        out = mode
        for a, i in enumerate(closed):
            for j in closed[a + 1 :]:
                if (out.sliding[i] != out.sliding[j] and not (mode.cornered[i] or mode.cornered[j])
                        and np.max(np.abs(pt.contacts[i] - pt.contacts[j])) <= COINCIDENT
                        and np.linalg.norm(vt[i] - vt[j]) <= self.speed_tol):
                    out = out.copy() if out is mode else out
                    out.slip[i] = out.slip[j] = out.slip[i] if out.sliding[i] else out.slip[j]
        return out

    def redundant(self, pt: _Point, mode: _Mode) -> bool:
        """Whether the mode's rows are redundant (:data:`REDUNDANT`): identical toes resting on
        one point, two sticking contacts of one rod."""
        rows = self.mode_solution(pt, mode, solve=False)[0]
        if rows.G.shape[0] < 2:
            return False
        s = np.linalg.svd(rows.G @ np.linalg.solve(pt.M, rows.F.T), compute_uv=False)
        return bool(s[-1] < REDUNDANT * s[0])

    def consistent_slip(self, pt: _Point, v: np.ndarray, mode: _Mode, acc_tol: float) -> _Mode:
        """A contact that starts sliding (|v_t| within the speed tolerance) must accelerate along
        its slip in the mode's own dynamics; where the LCP's answer is not unique (two identical
        toes on one point share a normal force in any split, and Lemke's pivots may start them
        sliding opposite ways), the mode's forces can make it accelerate against it, and the run
        would switch between mirror modes without end at one instant. Each such contact takes the
        slip of its acceleration in the mode (or sticks when that is below the tolerance), until
        the mode agrees with itself (at most one pass per contact); a mode still at odds with
        itself then has its slips searched (:meth:`searched_slip`)."""
        if self.mu <= 0:
            return mode
        for _ in range(self.nc):
            wrong, at = self.wrong_slip(pt, v, mode, acc_tol)
            if not wrong.any():
                return mode
            mode = mode.copy()
            mode.redundant = False
            mode.slip[wrong] = _unit(at[wrong], acc_tol)
        wrong, _ = self.wrong_slip(pt, v, mode, acc_tol)
        return self.searched_slip(pt, v, mode, wrong, acc_tol) if wrong.any() else mode

    def wrong_slip(self, pt: _Point, v: np.ndarray, mode: _Mode, acc_tol: float) -> tuple[np.ndarray, np.ndarray]:
        """The contacts starting to slide against their own slip acceleration in ``mode``, and
        every contact's slip acceleration."""
        _, (a, _) = self.mode_solution(pt, mode)
        at = pt.Jt @ a + pt.bt
        starting = mode.closed & mode.sliding & (np.linalg.norm(pt.vt(v), axis=1) <= self.speed_tol)
        return starting & (np.sum(mode.slip * at, axis=1) < -acc_tol), at

    def searched_slip(self, pt: _Point, v: np.ndarray, mode: _Mode, wrong: np.ndarray, acc_tol: float) -> _Mode:
        """Where turning each slip to its acceleration cycles (random file 30249: a contact on its
        cone's edge turned from (0.20, -0.98) to (-0.93, -0.36), whose acceleration points 122
        degrees away, at every event), each such contact in turn takes a slip d that its
        acceleration follows, a_t(d) = k d with k >= 0: in the plane the sign that does, in space
        the angle where d x a_t(d) changes sign with d . a_t(d) >= 0 (a scan of :data:`SLIP_SCAN`
        angles, then bisection). Where none exists the mode is left as it was."""
        mode = mode.copy()
        mode.redundant = False
        for k in np.flatnonzero(wrong):
            def along(d: np.ndarray) -> tuple[float, float]:  # (d x a_t(d), d . a_t(d)); the plane's cross is 0
                mode.slip[k] = d
                at = self.wrong_slip(pt, v, mode, acc_tol)[1][k]
                return (float(d[0] * at[1] - d[1] * at[0]) if d.size == 2 else 0.0), float(d @ at)

            kept = mode.slip[k].copy()
            found = _followed_slip(along, kept.size, acc_tol)
            mode.slip[k] = kept if found is None else found
        return mode

    def slide_on_the_edge(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> _Mode:
        """A sticking contact whose force, in the mode's own solve, lies within a force tolerance
        of the cone's edge (or beyond, by rounding) slides against its friction force: the LCP's
        answer at the edge (no slip acceleration) is the same in either mode, but sticking would
        leave the cone at once and stall the run. Repeated until no contact moves to its edge:
        one contact sliding moves the others' share of the friction (random file 20656: twin
        contacts on the edge beside a third, which slid first; the twins then stuck a rounding
        outside the cone and the run stalled)."""
        if self.mu <= 0:
            return mode
        pt = self.point(q, v)
        for _ in range(self.nc):
            if not (mode.closed & ~mode.sliding).any():
                break
            rows, (_, lam) = self.mode_solution(pt, mode)
            fn, ft = _contact_forces(rows, lam, self.mu, self.nc)
            magnitude = np.linalg.norm(ft, axis=1)
            edge = mode.closed & ~mode.sliding & (self.mu * fn - magnitude <= self.force_tol) & (magnitude != 0)
            edge &= ~mode.cornered  # a corner's force lies between its two normals, no cone's
            if not edge.any():
                break
            mode = mode.copy()
            mode.slip[edge] = -_unit(ft[edge], 0.0)
            mode.redundant = self.redundant(pt, mode)
        return mode
