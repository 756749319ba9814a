"""When an event happens: the witnesses that stay >= 0 while a mode holds (gaps, forces, cone
margins, slips, stop margins), a gap dipping within a step (cubic Hermite fit), a terrain
breakpoint or heightfield crease crossed, and the Illinois location of the first crossing
(:meth:`_Location.locate`); the event then goes to :mod:`.impacts` and :mod:`.choice`."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from impulse_core.timedomain.events.settings import PLASTIC_SPEED, RADAU, TRIAL_SPLITS, Diverged
from impulse_core.timedomain.events.point import _along, _any, _finite
from impulse_core.timedomain.events.rows import _Mode, _rests
from impulse_core.timedomain.events.forces import _contact_forces, _corner_forces


@dataclass(frozen=True)
class _Trial:
    """A step of length ``tau`` (:meth:`_Landing.trial`): its end (q, v), contact impulses, the
    compiled step's end (None: the numpy path's), and the witnesses and their rates at its end."""

    tau: float
    q: np.ndarray
    v: np.ndarray
    impulse: np.ndarray
    end: tuple | None
    w: np.ndarray
    r: np.ndarray
    vectors: np.ndarray | None = None  # a curved heightfield: its impulses' world vectors (_Landing.vectors)


#: Where :func:`_hermite_root` samples the cubic for its first sign change.
_ROOT_SAMPLES = np.linspace(0.0, 1.0, 65)
#: Where :meth:`_Landing.grazing` samples a step (interior points), and the cubic Hermite basis
#: (h00, h10, h01, h11) there.
_GRAZE_SAMPLES = np.linspace(0.0, 1.0, 17)[1:-1, None]
_GRAZE_BASIS = tuple(
    c[0] * _GRAZE_SAMPLES**3 + c[1] * _GRAZE_SAMPLES**2 + c[2] * _GRAZE_SAMPLES + c[3]
    for c in ((2, -3, 0, 1), (1, -2, 1, 0), (-2, 3, 0, 0), (1, -1, 0, 0))
)
#: Where :meth:`_Landing.locate` puts an event, in witness tolerances below zero: gaps and stop
#: margins (LOCATE_DEPTH), forces, cone margins and slips (FORCE_DEPTH); see its docstring.
LOCATE_DEPTH = 0.01
FORCE_DEPTH = 0.1


def location_offsets(start: np.ndarray, geometric: np.ndarray) -> np.ndarray:
    """Per watched witness (scaled, minus 1, at the step's start), d of its location window
    [-2 d, -d] (:meth:`_Landing.locate`): LOCATE_DEPTH for gaps and stop margins (``geometric``),
    FORCE_DEPTH for the others, or as far below the start's own value; at most 1."""
    depth = np.where(geometric, LOCATE_DEPTH, FORCE_DEPTH)
    return np.minimum(1.0, np.maximum(depth, depth - start))


def _hermite_root(g0: float, d0: float, g1: float, d1: float) -> float:
    """The first s in (0, 1) where the cubic Hermite fit of g(s) (values g0, g1 and slopes d0,
    d1 at s = 0, 1) falls below 0; NaN when the slopes are unknown or it does not."""
    if not (math.isfinite(d0) and math.isfinite(d1) and math.isfinite(g0) and math.isfinite(g1)):
        return math.nan
    s = _ROOT_SAMPLES
    c3, c2, c1, c0 = (float(c) for c in (2 * g0 + d0 - 2 * g1 + d1, -3 * g0 - 2 * d0 + 3 * g1 - d1, d0, g0))
    below = ((c3 * s + c2) * s + c1) * s + c0 < 0  # Horner's rule, as np.polyval
    first = int(below.argmax())
    if first == 0:  # none below, or below at s = 0
        return math.nan
    a, b = float(s[first - 1]), float(s[first])
    for _ in range(40):  # bisection on the polynomial: cheap (Horner's rule in Python floats)
        m = 0.5 * (a + b)
        if ((c3 * m + c2) * m + c1) * m + c0 >= 0:
            a = m
        else:
            b = m
    return b


class _Location:
    """Where a step's mode stops holding: witnesses, crossings and their location."""

    def witness(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> np.ndarray:
        """Values that stay >= 0 while the mode holds (scaled to tolerances of 1): open gaps,
        normal and cone margins of closed contacts, slip of sliding ones, joint-stop margins."""
        return self.witness_and_rate(q, v, mode)[0]

    def witness_and_rate(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`witness` and the time derivative of the geometric ones (gaps and stop margins;
        NaN for the force and slip witnesses)."""
        end = self.ended(q, v, mode)
        if end is None:
            fn, ft, stop_force = np.zeros(self.nc), np.zeros((self.nc, self.dims - 1)), np.zeros(self.nv)
            if _rests(mode):
                pt = self.point(q, v)
                rows, (_, lam) = self.mode_solution(pt, mode)
                fn, ft = _contact_forces(rows, lam, self.mu, self.nc)
                stop_force[rows.dof[rows.dof >= 0]] = lam[: rows.n][rows.dof >= 0]
                gap, vn, moving = pt.gap, pt.vn(v), pt.slip
                if rows.cornered is not None:  # a corner holds while both its rows push
                    fn = np.where(mode.cornered, _corner_forces(rows, lam, self.nc), fn)
            else:  # no rows: the gaps and normal speeds alone (the forces and slips go unwatched)
                gap, vn = self.gaps_and_speeds(q, v)
                moving = np.zeros((self.nc, self.dims - 1))
        else:
            fn, ft, stop_force, gap, vn, moving = end.fn, end.ft, end.stop_force, end.gap, end.vn, end.slip
        if ft.shape[1] == 1:  # the plane: |ft| and s . d of one tangent
            cone, slip = self.mu * fn - np.abs(ft[:, 0]), mode.slip[:, 0] * moving[:, 0]
        else:
            cone, slip = self.mu * fn - np.linalg.norm(ft, axis=1), np.sum(mode.slip * moving, axis=1)
        lo, hi = self.joints.lo, self.joints.hi
        values = np.concatenate([gap, fn, cone, slip, q - lo, hi - q, stop_force]) / self.witness_scale + 1.0
        values[self.unwatched(mode)] = np.inf
        rates = np.concatenate([vn, self.unknown_rates[0], v, -v, self.unknown_rates[1]]) / self.settings.gap_tolerance
        return values, rates

    def gaps_and_speeds(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The gaps and normal contact speeds at (q, v): the point's ``gap`` and ``vn(v)`` to the
        bit (the same normal components of the same Jacobian rows, in the same memory order),
        from the kept point if it is at (q, v), else without the rest of a point (a flight's
        witnesses at the start of a located step need no more)."""
        last = self._last
        if last is not None and last[0] == (q.tobytes(), v.tobytes()):
            return last[1].gap, last[1].vn(v)
        self.call.call(q, v)
        o, f = self.call.out, self.call.flat
        Jn = _along(o[1].T.copy(), o[2].reshape(self.nc, self.dims, self.nv))
        return f[0].copy(), Jn @ v

    def unwatched(self, mode: _Mode) -> np.ndarray:
        """Per witness of :meth:`witness_and_rate`, whether the mode leaves it unwatched (inf):
        gaps of closed contacts, forces of open ones, cone margins but of sticking contacts, slip
        but of sliding ones, stop margins of joints on a stop, stop forces of free joints."""
        # the corners always in the key, as in _mode_bytes (all -1 in a corner-free mode)
        key = b"".join((mode.closed.tobytes(), (mode.slip != 0).tobytes(), mode.stop.tobytes(), mode.corner.tobytes()))
        mask = self._unwatched.get(key)
        if mask is None:
            closed, friction, free = mode.closed, self.mu > 0, mode.stop == 0
            sticking, sliding = closed & ~mode.sliding & friction, closed & mode.sliding & friction
            sticking &= ~mode.cornered  # a corner's frictionless rows: no cone (its force witness is its rows')
            mask = np.concatenate([closed, ~closed, ~sticking, ~sliding, ~free, ~free, free])
            self._unwatched = self._unwatched if len(self._unwatched) < 256 else {}
            self._unwatched[key] = mask
        return mask

    def grazing(self, q0: np.ndarray, v0: np.ndarray, q1: np.ndarray, v1: np.ndarray, mode: _Mode, h: float
                ) -> float | None:
        """The step fraction where an open contact's gap dips below the ground and comes back, or
        a free joint passes its stop and comes back (a stiff spring turns it within one step),
        on cubic Hermite fits over the step; or None."""
        end = self.ended(q1, v1, mode)
        if end is not None:  # the step's own ends
            g0, d0, g1, d1 = end.gap0, end.vn0 * h, end.gap, end.vn * h
        else:
            p0 = self.point(q0, v0)
            g0, d0 = p0.gap, p0.vn(v0) * h
            p1 = self.point(q1, v1)
            g1, d1 = p1.gap, p1.vn(v1) * h
        s, (h00, h10, h01, h11) = _GRAZE_SAMPLES, _GRAZE_BASIS
        g = h00 * g0 + h10 * d0 + h01 * g1 + h11 * d1
        tol = self.settings.gap_tolerance
        dips = (g < -tol) & ~mode.closed
        if _any(self.joints.stopped):
            x = h00 * q0 + h10 * v0 * h + h01 * q1 + h11 * v1 * h
            lo, hi = self.graze_bounds
            past = ((x > hi) | (x < lo)) & (mode.stop == 0)
            dips = np.concatenate([dips, past], axis=1)  # np.hstack's concatenation of 2-D arrays
        if not _any(dips):
            return None
        return float(s[np.argmax(dips.any(axis=1)), 0])

    @property
    def graze_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The stops widened by the gap tolerance, (lo - tol, hi + tol), that :meth:`grazing` asks of
        every step: kept for the joint arrays and tolerance they were made of (both fixed for a landing)."""
        joints, tol = self.joints, self.settings.gap_tolerance
        kept = self.__dict__.get("_graze_bounds")
        if kept is None or kept[0] is not joints or kept[1] != tol:
            kept = self._graze_bounds = (joints, tol, (joints.lo - tol, joints.hi + tol))
        return kept[2]

    def pieces(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Per contact, the piece of the ground below it: in the plane, the number of breakpoints
        of its terrain at or left of its x (0: the left ray); in space, the heightfield's cell
        (the grid lines at or below its x, and its z, as one number; the flat ground beyond the
        grid counts as cells too)."""
        at = self.point(q, v).contacts
        if self.grid is None:
            return np.searchsorted(self.vertices, at[:, 0], side="right")
        x, z = self.grid
        return np.searchsorted(x, at[:, 0], side="right") * (len(z) + 1) + np.searchsorted(z, at[:, 2], side="right")

    def vertex_crossing(self, q: np.ndarray, v: np.ndarray, q1: np.ndarray, v1: np.ndarray, mode: _Mode, h: float
                        ) -> tuple[_Trial, np.ndarray, np.ndarray] | None:
        """Where a closed contact passes a breakpoint of the plane's terrain over the step (q, v)
        -> (q1, v1) of length ``h``: the step to just past it (bisected to rounding) and which
        closed contacts passed one; or None. Beyond a breakpoint the ground's normal is the next
        segment's: a contact sliding into a valley meets it moving into it (an impact), one
        sliding over a ridge leaves it. Unlocated, the projection onto the next segment took the
        valley's impact plastically whatever the restitution, and pulled the contact down onto
        the ridge's far side (a pulling impulse). A crossing that changes no normal speed by more
        than the plastic speed (1e-4 m/s) is left to the projection (a plastic change).

        A contact that passes a valley's breakpoint (:attr:`concave`) is located whatever its
        speed, and where its whole velocity there is below the plastic speed it comes to rest in
        the corner, held by both segments (the third item returned: per contact the breakpoint, or
        -1; :meth:`event`): the rocking across a valley's breakpoint at restitution 0 loses cos a
        of its speed per crossing (a the angle between the normals) and the crossings accumulate
        (Zeno), each step crossing it once its rocking is shorter than a step. That slow, the
        corner's projection takes the point's velocity to zero within the plastic speed, as a
        plastic impact takes an approach that slow (an event: the impact over both rows). A faster
        contact crosses as before, but as an event however slowly it approaches the far segment
        (plastic below the plastic speed; so a contact sliding through a shallow valley keeps its
        speed along the far segment, and every loss at a valley is an event's)."""
        # the normals at the step's ends (the last accepted step's end's for its start): unchanged,
        # no breakpoint passed (nor one between collinear segments, which changes nothing)
        end = self.ended(q1, v1, mode)
        n1 = end.normal if end is not None else self.point(q1, v1).normal
        n0, self.end_normals = self.end_normals, n1
        n0 = n0 if n0 is not None else self.point(q, v).normal
        if not _any(mode.closed & (np.maximum.reduce(np.abs(n1 - n0), axis=1) > 1e-12)):
            return None
        self.end_normals = None
        k0 = self.pieces(q, v)
        k1 = self.pieces(q1, v1)
        passing = mode.closed & ~mode.cornered & (k1 != k0)
        if not _any(passing):
            return None
        if self.grid is not None:  # space: no valley corners (a crease's crossing is an event alike)
            return self.crossing_event(q, v, h, mode, k0, passing)
        # a crossing too slow to locate (the contact's velocity at the step's start along the
        # next segment's normal within half the plastic speed): no bisection (the step's cost x 50)
        # unless it passes a valley's breakpoint, where it may come to rest in the corner
        pt, normal = self.point(q, v), self.point(q1, v1).normal
        velocity = pt.normal * pt.vn(v)[:, None] + pt.tangent[:, 0] * pt.vt(v)[:, 0][:, None]
        valley = passing & (np.abs(k1 - k0) == 1) & self.concave[np.minimum(k0, k1) % len(self.concave)]
        kept_end = self._end
        if not _any(passing & (np.abs(np.sum(normal * velocity, axis=1)) > 0.5 * PLASTIC_SPEED)) and not _any(valley):
            return None
        lo, hi, found, before = self.first_crossing(q, v, mode, h, k0)
        if before is not None:
            # the step to just before the breakpoint (its stages all on this side: a step past it
            # holds the contact to the next segment in its last stages), then on at that speed
            # (the plane's q' = v) over the bracket's rest, twice, to just past it
            nudged = replace(before, tau=lo + 2.0 * (hi - lo), q=before.q + 2.0 * (hi - lo) * before.v, end=None)
            if _any(mode.closed & (self.pieces(nudged.q, nudged.v) != k0)):
                found = nudged
            if _any(valley):
                # past a valley's breakpoint by more than the profile's coincidence radius (1e-12
                # m), where the normal is the far segment's: a leftward crossing located to
                # rounding stayed within it (the segment's parameter rounds to its end), and met
                # the mean of the two normals (its impact sent the puck of the valley file level
                # into the far slope, a loss at the next step's projection)
                k = np.minimum(k0, k1) % len(self.concave)
                far = np.where((k1 > k0)[:, None], self.valleys[k][:, 1], self.valleys[k][:, 0])
                reach = 2.0
                for _ in range(200):
                    if not _any(valley & (np.max(np.abs(self.point(found.q, found.v).normal - far), axis=1) > 1e-12)):
                        break
                    reach *= 2.0
                    if lo + reach * (hi - lo) > h:
                        break
                    found = replace(before, tau=lo + reach * (hi - lo), q=before.q + reach * (hi - lo) * before.v,
                                    end=None)
        crossed = mode.closed & ~mode.cornered & (self.pieces(found.q, found.v) != k0)
        pt = self.point(found.q, found.v)
        cornered = np.full(self.nc, -1)
        if _any(valley):
            speed = np.hypot(pt.vn(found.v), pt.vt(found.v)[:, 0])  # the contact point's whole velocity
            resting = crossed & valley & (speed <= PLASTIC_SPEED)
            cornered[resting] = np.minimum(k0, k1)[resting]
            crossed &= ~resting
        crossed &= (np.abs(pt.vn(found.v)) > PLASTIC_SPEED) | valley  # a valley's: an event, plastic that slow
        if _any(crossed) or _any(cornered >= 0):
            return found, crossed, cornered
        self._end = kept_end  # as unlocated: the step's end (q1, v1) is the compiled step's again
        return None

    def first_crossing(self, q: np.ndarray, v: np.ndarray, mode: _Mode, h: float, k0: np.ndarray
                       ) -> tuple[float, float, _Trial, _Trial | None]:
        """Where a closed contact first leaves its piece of the ground (``k0``, :meth:`pieces`)
        over a step of length ``h`` from (q, v), bisected to rounding: the step lengths (lo, hi)
        that bracket it, the step to hi (just past it) and the step to lo (None where lo is 0)."""
        lo, hi, found, before = 0.0, h, None, None
        for _ in range(200):
            if hi - lo <= 1e-15 * max(1.0, hi):
                break
            mid = 0.5 * (lo + hi)
            trial = self.trial(q, v, mode, mid)
            if _any(mode.closed & (self.pieces(trial.q, trial.v) != k0)):
                hi, found = mid, trial
            else:
                lo, before = mid, trial
        found = found if found is not None else self.trial(q, v, mode, hi)
        return lo, hi, found, before

    def crossing_event(self, q: np.ndarray, v: np.ndarray, h: float, mode: _Mode, k0: np.ndarray,
                       passing: np.ndarray) -> tuple[_Trial, np.ndarray, np.ndarray] | None:
        """Space: where closed contacts (``passing``) leave their heightfield cells (``k0``) over a
        step of length ``h``: the step to the first such crossing (bisected to rounding; its end
        just past the grid line) and which closed contacts crossed, each meeting the next cell's
        surface afresh (:meth:`event`: an impact where it moves into it, a crease's valley, free
        where it leaves it); None where no crossing changes a normal speed by more than the
        plastic speed, which the projection takes (random file 30882: a contact sliding at 1.1
        m/s onto a 32 degree slope met it at 0.6 m/s in a step's projection, 0.38 N s along the
        normal alone, plastic and frictionless whatever the laws, and its momentum balance 1.9e-4)."""
        kept_end = self._end
        found = self.first_crossing(q, v, mode, h, k0)[2]
        crossed = mode.closed & ~mode.cornered & (self.pieces(found.q, found.v) != k0)
        crossed &= np.abs(self.point(found.q, found.v).vn(found.v)) > PLASTIC_SPEED
        if _any(crossed):
            return found, crossed, np.full(self.nc, -1)
        self._end = kept_end  # as unlocated: the step's end is the compiled step's again
        return None

    def step_events(self, q: np.ndarray, v: np.ndarray, q1: np.ndarray, v1: np.ndarray, mode: _Mode, dt: float,
                    impulse: np.ndarray, step_vectors: np.ndarray | None
                    ) -> tuple[_Trial | None, tuple[_Trial, np.ndarray, np.ndarray] | None]:
        """What ended ``mode`` within the step of length ``dt`` from (q, v) to (q1, v1) (contact
        ``impulse``, ``step_vectors``): a witness below zero at its end or within it (a graze, as a
        trial step), else a closed contact crossing a terrain breakpoint or heightfield crease
        (:meth:`vertex_crossing`), else nothing: (graze, crossing), None where none."""
        w, r = self.witness_and_rate(q1, v1, mode)
        all_hold = np.count_nonzero(w >= 0) == w.size  # (w >= 0).all()
        graze = None if all_hold else _Trial(dt, q1, v1, impulse, self._end, w, r, step_vectors)
        if graze is None:
            fraction = self.grazing(q, v, q1, v1, mode, dt)
            graze = None if fraction is None else self.trial(q, v, mode, fraction * dt)
            graze = graze if graze is not None and _any(graze.w < 0) else None
        crossing = None
        if graze is None and (self.vertices is not None or self.grid is not None) and _any(mode.closed):
            crossing = self.vertex_crossing(q, v, q1, v1, mode, dt)
        return graze, crossing

    def event_location(self, q: np.ndarray, v: np.ndarray, mode: _Mode, graze: _Trial | None,
                       crossing: tuple[_Trial, np.ndarray, np.ndarray] | None
                       ) -> tuple[_Trial, np.ndarray | None, np.ndarray | None]:
        """The step from (q, v) to the event :meth:`step_events` found (``graze`` or ``crossing``),
        recorded on the tape: (that step, and a crossing's crossed contacts and corners, else None)."""
        if crossing is not None:  # a closed contact passed a terrain vertex (located just past it)
            located, crossed, cornered = crossing
            if self.tape is not None:
                self.tape.append(("vertex_step", q.copy(), v.copy(), mode.copy(), located.tau,
                                  crossed | (cornered >= 0)))
            return located, crossed, cornered
        watch = graze.w < 0
        located = self.locate(q, v, mode, graze, watch)
        for _ in range(8):  # a witness that crossed earlier and came back by the step's end
            missed = (located.w < 0) & ~watch
            if not _any(missed):
                break
            watch = located.w < 0
            located = self.locate(q, v, mode, located, watch)
        if self.tape is not None:
            self.tape.append(("event_step", q.copy(), v.copy(), mode.copy(), located.tau, watch))
        return located, None, None

    def trial(self, q: np.ndarray, v: np.ndarray, mode: _Mode, tau: float) -> _Trial:
        """A step of length ``tau`` from (q, v) in ``mode`` and its end's witnesses and rates.
        A trial's length is where it looks, so it is not halved as :meth:`balanced_step` halves a
        step: Radau IIA's pieces are split down to RK4's stable step (random file 60779: its trial
        at 0.98 ms stayed NaN after RADAU_SPLITS); a trial that blows up otherwise is the run's
        divergence (:class:`Diverged`, which :func:`landing` shortens), not its witnesses' failure."""
        q1, v1, impulse = self.step(q, v, mode, tau)
        if self.method == RADAU and not (_finite(q1) and _finite(v1)):
            q1, v1, impulse = self.radau_step(q, v, mode, tau, splits=TRIAL_SPLITS)
        if not (_finite(q1) and _finite(v1)):
            raise Diverged(f"the landing diverged locating an event (a trial step of {tau:.3g} s)")
        w, r = self.witness_and_rate(q1, v1, mode)
        return _Trial(tau, q1, v1, impulse, self._end, w, r, self.vectors)

    def take(self, q: np.ndarray, v: np.ndarray, mode: _Mode, trial: _Trial
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``trial``'s step taken again without its cost: what :meth:`step` of its length would
        return and leave behind (the mode's steering, the compiled step's end for :meth:`ended`)."""
        self.steer(q, v, mode, trial.tau)
        self._end, self.vectors = trial.end, trial.vectors
        return trial.q.copy(), trial.v.copy(), trial.impulse.copy()

    def locate(self, q: np.ndarray, v: np.ndarray, mode: _Mode, first: _Trial, watch: np.ndarray) -> _Trial:
        """The first step length in (0, ``first.tau``] at which a watched witness crosses its
        threshold, and that step (``first``: the step at the bracket's end, already taken).

        Witnesses are triggered at -1 (one tolerance below zero) but located within a window
        ``[-2 d, -d]`` tolerances (or as far below their start's value): d = ``LOCATE_DEPTH`` for
        gaps and stop margins, ``FORCE_DEPTH`` for forces, cone margins and slips. A contact is
        thus met within 0.02 gap tolerances of the ground: each bounce is located that close to
        where the last one left (the projection lifts a bounced contact to zero gap), so the
        drive a pushing it down gains at most a 2 d tol per bounce, far below restitution's loss
        unless the bounce is slower than sqrt(4 a d tol / (1 - e^2)) (the plastic speed, 1e-4 m/s,
        at a = 9e4 m/s^2, e = 0.8). The next guess is the first root, aimed at the window's
        middle, of the cubic Hermite fit of the crossing witness over the bracket where its rate
        is known (gaps and stop margins: the contact's or joint's speed), else the Illinois
        method; a bisection where the bracket stopped halving (rounding's plateau)."""
        w0, r0 = self.witness_and_rate(q, v, mode)
        start = w0[watch] - 1.0
        offset = location_offsets(start, np.isfinite(r0[watch]))
        aim = 0.5 * offset  # the window's middle: rounding either way stays inside

        def phi(trial: _Trial) -> tuple[np.ndarray, np.ndarray]:
            return trial.w[watch] - 1.0 + offset, trial.r[watch]

        lo, hi, (w_lo, r_lo), found = 0.0, first.tau, (start + offset, r0[watch]), first
        w_hi, r_hi = phi(first)
        f_lo, f_hi, side, slow = float(w_lo.min()), float(w_hi.min()), 0, 0
        for _ in range(100):
            if hi - lo <= 1e-14 * max(1.0, hi) or (w_hi >= -offset).all():  # inside the window
                break
            i, width = int(w_hi.argmin()), hi - lo
            mid = lo + width * self.root(w_lo[i] + aim[i], r_lo[i] * width, w_hi[i] + aim[i], r_hi[i] * width)
            if slow >= 2:  # two steps without halving the bracket
                mid, slow = 0.5 * (lo + hi), 0
            elif not lo < mid < hi:  # Illinois
                mid = (lo * f_hi - hi * f_lo) / (f_hi - f_lo) if f_lo != f_hi else 0.5 * (lo + hi)
                if not lo < mid < hi:
                    mid = 0.5 * (lo + hi)
            trial = self.trial(q, v, mode, mid)
            w_mid, r_mid = phi(trial)
            f_mid = float(w_mid.min())
            if f_mid < 0:
                hi, w_hi, r_hi, f_hi, found = mid, w_mid, r_mid, f_mid, trial
                f_lo = f_lo / 2 if side == -1 else f_lo
                side = -1
            else:
                lo, w_lo, r_lo, f_lo = mid, w_mid, r_mid, f_mid
                f_hi = f_hi / 2 if side == 1 else f_hi
                side = 1
            slow = slow + 1 if hi - lo > 0.5 * width else 0
        return found
