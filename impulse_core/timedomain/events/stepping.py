"""The integrators between events (RK4, ROS2, Radau IIA), compiled or numpy, and the step that
keeps the momentum balance (:meth:`_Stepping.balanced_step`): a mode held fixed from (q, v) to the
step's end; :mod:`.location` finds where the mode stops holding."""

from __future__ import annotations

import math

import numpy as np

from impulse_core.timedomain.events.settings import (
    BALANCE_ROUNDING, FIRST_STEPS, IMPLICIT, NUMPY_CODE, RADAU, RADAU_A, RADAU_B, RADAU_ITERATIONS, RADAU_SPLITS,
    RADAU_TOL, RK4, RK4_STABLE, ROS2_GAMMA, SLIP_TURN,
)
from impulse_core.timedomain.events.point import _finite, _largest, momentum_terms
from impulse_core.timedomain.events.rows import _Mode, _mode_bytes, _mode_rows, _rests, slip_direction
from impulse_core.timedomain.events.forces import (
    _constrained_solve, _contact_forces, contact_vectors, impulse_vector, _stacked, _unstacked,
)


def _newton_verdict(size: float, last: float) -> int:
    """Radau IIA's simplified Newton iterations after a correction of ``size`` (RADAU_TOL (1 + |y|)
    units) following one of ``last``: 1 converged, -1 not contracting (NaN fails too), 0 go on."""
    if size <= 1.0:
        return 1
    return 0 if size < last else -1


def balanced_length(dt: float, ratio: float, order: int) -> float:
    """The next trial length after a step of length ``dt`` accepted with its momentum residual
    ``ratio`` times its share (:meth:`_Landing.balanced_step`): 2 dt where the ratio, grown as
    dt^p, would stay within 1 (ratio 2^p <= 1; an integrator of ``order`` p: the residual ~
    dt^(p + 1), the share ~ dt), else dt: an error-per-unit-step controller on the lengths h / 2^k.
    Doubling after every split made each accepted step cost a rejected trial where the balance
    sets the step; lengths h / 2^k keep runs at h and h / 2 whose every step the balance set one
    run, as :func:`landing` expects."""
    return 2.0 * dt if ratio * 2.0**order <= 1.0 else dt


class _Stepping:
    """The steps between events: the first step length, the integrators and the balanced step."""

    def first_step(self) -> float:
        """:attr:`LandingSettings.step`, or by default (:data:`FIRST_STEPS`) the implicit
        integrator's duration / 200 and RK4's :meth:`stable_step`."""
        if self.settings.step:
            return self.settings.step
        if self.method in (IMPLICIT, RADAU):
            return FIRST_STEPS[0] * float(self.scene.duration)
        return self.stable_step()

    def stable_step(self) -> float:
        """RK4's longest stable step for the joint laws at touchdown (RK4_STABLE / rate), at most
        duration / 100: where ``auto``'s implicit run overran its step budget (the momentum
        balance split its steps), :func:`landing` runs RK4 from this step instead (random file
        30039, h x rate 3.6: 97 s on ROS2 restarted at h / 16, 3.9 s so; 30094: about 10 min
        against 5.2 s; 30000: over 120 s against 28.5 s)."""
        longest = FIRST_STEPS[1] * float(self.scene.duration)
        return min(longest, RK4_STABLE / self.rate) if self.rate > 0 else longest

    def compiled_step(self, code: str):
        """The compiled step of this landing's integrator (:mod:`impulse_core.timedomain.landing_step`),
        or None where the numpy path integrates (``numpy``)."""
        if code == NUMPY_CODE:
            return None
        from impulse_core.timedomain.landing_step import CompiledStep  # it builds on this module

        return CompiledStep(self.topology, self.ground, self.design, self.scene.gravity, self.mu, self.joints,
                            code=code, space=self.space, floor=self.speed_tol, method=self.method)

    def ended(self, q: np.ndarray, v: np.ndarray, mode: _Mode | None = None):
        """The last compiled step's :class:`~impulse_core.timedomain.landing_step.StepEnd` if it
        ended at (q, v) (in ``mode``, if given), else None."""
        if self._end is None or self._end[0] != q.tobytes() + v.tobytes():
            return None
        if mode is not None and self._end[1] != _mode_bytes(mode):
            return None
        return self._end[2]

    def step(self, q: np.ndarray, v: np.ndarray, mode: _Mode, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One step of the landing's integrator: (q, v, contact impulses [normal, tangential])."""
        self.steer(q, v, mode, h)
        if self.method == RADAU:
            return self.radau_step(q, v, mode, h)
        end = self.compiled(q, v, mode, h)
        if end is not None:
            return self.kept(end, mode)
        try:
            return self.implicit_step(q, v, mode, h) if self.method == IMPLICIT else self.rk4_step(q, v, mode, h)
        except np.linalg.LinAlgError:  # a stage far off the motion (random file 60690: |v| ~ 1e21 within
            # one step): the step blew up, which the run reports as such and landing() shortens
            return np.full_like(q, np.nan), np.full_like(v, np.nan), np.full(self.nc * self.dims, np.nan)

    def compiled(self, q: np.ndarray, v: np.ndarray, mode: _Mode, h: float, z0: np.ndarray | None = None):
        """The compiled step's :class:`~impulse_core.timedomain.landing_step.StepEnd` (Radau IIA:
        from the stages' ``z0``), or None where the numpy path answers (no compiled step, a
        valley's corner, a redundant mode, a non-finite result)."""
        return None if self.fast is None or mode.has_corner else self.fast.step(q, v, h, mode, z0)

    def kept(self, end, mode: _Mode) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A compiled step's (q, v, contact impulses), its end kept for :meth:`ended`."""
        self._end = (end.q.tobytes() + end.v.tobytes(), _mode_bytes(mode), end)
        self.vectors = end.vectors.copy() if self.turning else None
        return end.q.copy(), end.v.copy(), end.impulse.copy()

    def steer(self, q: np.ndarray, v: np.ndarray, mode: _Mode, h: float) -> None:
        """Set ``mode.core`` for a step of length h from (q, v) (space, sliding contacts). A
        lateral slip s_perp of a sliding contact decays at the rate mu f_n w / |s| (w: the trace of
        its tangential inverse mass J_t M^-1 J_t^T): stiff as |s| falls, and an explicit step
        beyond 1 / rate amplifies it instead (a slow-slipping loaded toe turned the foot out of
        its plane within two steps). core = h mu f_n w caps that rate at 1 / h (RK4 is stable to
        2.8 / h): the direction is exact s / |s| above |s| = core and regularised below it; core
        shrinks with the step, so the landing's step halving converges to the exact law, at first
        order where the law is regularised: :meth:`slip_length` splits a turning slip's step
        instead where that reaches the exact law (:attr:`LandingSettings.slip_splits`). The plane
        (one tangent) is untouched."""
        if self.dims == 2 or self.mu <= 0 or not (mode.closed & mode.sliding).any():
            return
        mode.core[:] = 0.0
        pt = self.point(q, v)
        key = _mode_bytes(mode)
        if self._steering[0] is not pt or self._steering[1] != key:  # a new point or mode (not a retrial)
            rows, (_, lam) = self.mode_solution(pt, mode)
            forces, _ = _contact_forces(rows, lam, self.mu, self.nc)
            moving = np.flatnonzero(mode.closed & mode.sliding)
            X = np.linalg.solve(pt.M, pt.Jt[moving].reshape(-1, self.nv).T)
            w = np.einsum("ij,ji->i", pt.Jt[moving].reshape(-1, self.nv), X).reshape(len(moving), -1).sum(axis=1)
            self._steering = (pt, key, moving, np.maximum(forces[moving], 0.0), w)
        _, _, moving, pushing, w = self._steering
        mode.core[moving] = h * self.mu * pushing * w

    def slip_length(self, q: np.ndarray, v: np.ndarray, mode: _Mode, trial: float, least: float) -> float:
        """The length of a step from (q, v) in ``mode`` at most ``trial``: halved, not below ``least``,
        while a sliding contact in space whose slip turns would have its direction regularised
        (:meth:`steer`'s core h mu f_n w above its slip speed |s|): the exact law s / |s| then
        holds at the step's start. The core is proportional to the step, and so is the
        regularisation's error: on every step of a slow slip (random file 61600, :data:`SLIP_SPLITS`)
        the runs of the step halving converged at first order; split, the step holds RK4's order,
        and the regularisation acts only on a slip that even a step of ``least`` (h / 2^k,
        :attr:`LandingSettings.slip_splits`) would regularise: that step is not split (a slip
        about to stop, or crawling: random file 30891's at 2e-6 m/s, turning past a right angle
        every 1e-7 s). A slip that keeps its line (its acceleration across it below SLIP_TURN of
        the acceleration, a planar motion read in space) is not split: the regularised direction
        is then s / |s| exactly."""
        if self.dims == 2 or self.mu <= 0 or not (mode.closed & mode.sliding).any() or trial <= least:
            return trial
        self.steer(q, v, mode, trial)
        _, _, moving, pushing, w = self._steering
        pt = self.point(q, v)
        s = pt.slip[moving]
        speed = np.linalg.norm(s, axis=1)
        along = (np.sum(s * mode.slip[moving], axis=1) > 0) & (speed > pt.slip_floor)  # as slip_direction
        stiffness = np.where(along, self.mu * pushing * w, 0.0)  # the core per unit step
        if not np.any(trial * stiffness > speed):
            return trial
        a, _ = self.derivative(q, v, mode)
        rate = np.einsum("ckn,n->ck", pt.Jt[moving], a) + pt.bt[moving]  # the slip's acceleration
        unit = s / np.where(speed > 0, speed, 1.0)[:, None]
        across = rate - np.sum(rate * unit, axis=1, keepdims=True) * unit
        turning = np.linalg.norm(across, axis=1) > SLIP_TURN * np.linalg.norm(rate, axis=1)
        stiffness = np.where(turning, stiffness, 0.0)
        if np.any(least * stiffness > speed):  # no split reaches the exact law (30891: a slip of 2e-6 m/s)
            return trial
        while trial > least and np.any(trial * stiffness > speed):
            trial /= 2.0
        return max(trial, least)

    def follow_slip(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> None:
        """In space, after a step: each sliding contact's mode direction d becomes its friction's
        slip direction u at the step's end (:func:`slip_direction` with the step's core), so that
        the slip-stop witness (s . d) watches the slip as it turns and the regularised direction
        relaxes towards s / |s|."""
        if self.dims == 2 or self.mu <= 0 or not (mode.closed & mode.sliding).any():
            return
        pt = self.point(q, v)
        moving = mode.closed & mode.sliding
        mode.slip[moving] = slip_direction(pt, mode.slip, mode.core)[moving]

    def implicit_step(self, q: np.ndarray, v: np.ndarray, mode: _Mode, h: float
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One step of ROS2 (Verwer, Spee, Blom and Hundsdorfer 1999), a two-stage Rosenbrock-W
        method: second order for any matrix in (I - gamma h A) k = r, so A may hold only the
        stiff part of the Jacobian: here the joint springs and dampers, A = [[0, I], [-P M^-1 K,
        -P M^-1 D]] with P the mode's projection (its rows G, forces F at the step's start).
        Solving (I - gamma h A) k = r is then one constrained solve with the matrix
        W = M + gamma h D + gamma^2 h^2 K (MuJoCo's implicit damping, with the springs too):
        (W k_v - F^T nu = M r_v - gamma h K r_q, G k_v = G r_v; k_q = r_q + gamma h k_v).
        Stages: k1 from r = (v, a(y)); k2 from r = F(y + h k1) - 2 k1; y + h (3 k1 + k2) / 2.
        The contact impulses are the matching combination of the stages' row forces
        (h / 2 (nu_1 + lambda(y + h k1) + nu_2)): the first stage's implicit forces nu_1 and the
        second's correction nu_2 carry what the stiff laws transmit within the step (explicit
        samples of the contact forces would not), with the second stage's force taken with the
        first stage's mass matrix; the momentum balance closes to O(h^2) between events (on a
        random leg of the tests 7.9e-6, 2.0e-6, 5.0e-7 of the momentum at h = 5e-4, 2.5e-4,
        1.25e-4 s; RK4 2e-10 at 5e-4 s). The
        Coriolis terms stay explicit (as in MuJoCo's implicitfast), which keeps W symmetric
        positive definite and its base rows M's."""
        g = ROS2_GAMMA * h
        D, K = self.joints.damping, self.joints.stiffness
        pt = self.point(q, v)
        rows = _mode_rows(pt, mode, self.mu, self.valleys)
        W = pt.M + np.diag(g * D + g * g * K)
        k1v, nu1 = _constrained_solve(W, rows, pt.f - g * K * v, -rows.b)
        k1q = v + g * k1v
        q2, v2 = q + h * k1q, v + h * k1v
        a2, f2 = self.derivative(q2, v2, mode)
        v2_vectors = self.stage_vectors(q2, v2, f2)
        rq, rv = v2 - 2.0 * k1q, a2 - 2.0 * k1v
        k2v, nu2 = _constrained_solve(W, rows, pt.M @ rv - g * K * rq, rows.G @ rv)
        k2q = rq + g * k2v
        f1 = _stacked(*_contact_forces(rows, nu1, self.mu, self.nc))
        f3 = _stacked(*_contact_forces(rows, nu2, self.mu, self.nc))
        if self.turning:
            self.vectors = 0.5 * h * (self.stage_vectors(q, v, f1 + f3) + v2_vectors)
        return q + 0.5 * h * (3.0 * k1q + k2q), v + 0.5 * h * (3.0 * k1v + k2v), 0.5 * h * (f1 + f2 + f3)

    def radau_step(self, q: np.ndarray, v: np.ndarray, mode: _Mode, h: float, splits: int = RADAU_SPLITS
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A Radau IIA step of length h (:meth:`radau_once`), or where its Newton iterations do not
        converge, two of h / 2, each split so again, at most ``splits`` times (then NaN:
        :meth:`balanced_step` halves the step), down to RK4's stable step, where an RK4 step takes
        the piece. Random file 60147: the iterations failed on steps that crossed the point where
        a sliding contact's slip stops (the fixed mode's dynamics turn there), and an event
        location's trial step, NaN, reached the witnesses' least squares, which failed. Each call
        is a try (:attr:`_Landing.radau_tries`)."""
        self.radau_tries += 1
        q1, v1, impulse = self.radau_once(q, v, mode, h)
        if _finite(q1) and _finite(v1):
            return q1, v1, impulse
        if h <= self.stable_step():  # RK4 is stable here: a piece across the mode's end (60147: a slip stopping)
            return self.rk4_step(q, v, mode, h)
        if splits == 0:
            return q1, v1, impulse
        qa, va, pa = self.radau_step(q, v, mode, 0.5 * h, splits - 1)
        if not (_finite(qa) and _finite(va)):
            return qa, va, pa
        first = self.vectors
        qb, vb, pb = self.radau_step(qa, va, mode, 0.5 * h, splits - 1)
        if self.turning:
            self.vectors = first + self.vectors
        self._end = None  # the last piece's end is not the step's (its balance, its start)
        return qb, vb, pa + pb

    def radau_once(self, q: np.ndarray, v: np.ndarray, mode: _Mode, h: float
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One step of the two-stage Radau IIA method: the compiled step's Newton iterations
        (:func:`~impulse_core.timedomain.landing_step._radau`, RADAU_UNROLLED a call, each call
        from the last one's Z) to their convergence, NaN where they stop contracting or do not
        converge within RADAU_ITERATIONS; :meth:`radau_newton` where the compiled step does not answer."""
        Z, last, done = None, math.inf, 0
        while done < RADAU_ITERATIONS:
            end = self.compiled(q, v, mode, h, Z)
            if end is None:
                return self.radau_newton(q, v, mode, h)
            for size in end.newton:
                verdict, last = _newton_verdict(float(size), last), float(size)
                if verdict:
                    return self.kept(end, mode) if verdict > 0 else self.failed_step()
            Z, done = end.z, done + len(end.newton)
        return self.failed_step()

    def radau_newton(self, q: np.ndarray, v: np.ndarray, mode: _Mode, h: float
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One step of the two-stage Radau IIA method (:data:`RADAU_A`) on y' = (v, a(q, v)) in the
        fixed mode (a: the mode's accelerations, its rows' forces solved at each stage as the
        derivative does): stages Y_i = y + Z_i with Z = h A F(Y), the end Y_2. Simplified Newton
        iterations with the matrix I - h A x J, J the stiff part of the Jacobian at the step's
        start: the joint springs and dampers through the mode's constrained inverse mass
        (da/dq = -Pi M^-1 K, da/dv = -Pi M^-1 D, Pi M^-1 = M^-1 - M^-1 F^T (G M^-1 F^T)^-1 G M^-1). Unlike
        ROS2 it is stiffly accurate: at h x rate >> 1 a damped joint's motion keeps third order in
        the slow part (ROS2's error there is what splits its steps by the momentum balance). The
        contact impulses are h sum_i b_i (the stage's row forces). Non-converged iterations
        return NaN (:meth:`radau_step` splits the step). In numpy: the reference, and the step
        where the compiled one does not answer (:meth:`radau_once`)."""
        nv = self.nv
        pt = self.point(q, v)
        C = np.linalg.inv(pt.M)
        if _rests(mode):
            rows = _mode_rows(pt, mode, self.mu, self.valleys)
            if rows.G.shape[0]:
                X = C @ rows.F.T
                C = C - X @ np.linalg.lstsq(rows.G @ X, rows.G @ C, rcond=None)[0]
        n = 2 * nv
        J = np.zeros((n, n))
        J[:nv, nv:] = np.eye(nv)
        J[nv:, :nv] = -C * self.joints.stiffness[None, :]
        J[nv:, nv:] = -C * self.joints.damping[None, :]
        E = np.eye(2 * n) - h * np.kron(RADAU_A, J)
        y0 = np.concatenate([q, v])
        scale = RADAU_TOL * (1.0 + np.abs(y0))
        Z, last = np.zeros((2, n)), math.inf
        for _ in range(RADAU_ITERATIONS):
            stages = [self.derivative(y0[:nv] + Z[i, :nv], y0[nv:] + Z[i, nv:], mode) for i in range(2)]
            Fs = np.array([np.concatenate([y0[nv:] + Z[i, nv:], stages[i][0]]) for i in range(2)])
            dZ = np.linalg.solve(E, (h * (RADAU_A @ Fs) - Z).ravel()).reshape(2, n)
            Z += dZ
            size = float(np.max(np.abs(dZ) / scale))
            verdict, last = _newton_verdict(size, last), size
            if verdict > 0:
                break
            if verdict < 0:
                return self.failed_step()
        else:
            return self.failed_step()
        if self.turning:
            self.vectors = h * sum(RADAU_B[i] * self.stage_vectors(y0[:nv] + Z[i, :nv] - dZ[i, :nv],
                                                                   y0[nv:] + Z[i, nv:] - dZ[i, nv:], stages[i][1])
                                   for i in range(2))
        y1 = y0 + Z[1]
        return y1[:nv], y1[nv:], h * (RADAU_B[0] * stages[0][1] + RADAU_B[1] * stages[1][1])

    def failed_step(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A Radau IIA step whose Newton iterations did not converge: (q, v, contact impulses) NaN."""
        nan = np.full(self.nv, np.nan)
        return nan, nan.copy(), np.full(self.dims * self.nc, np.nan)

    @property
    def balance_order(self) -> int:
        """The order in the step of a step's momentum residual per unit time (RK4 4, Radau IIA 3,
        ROS2 2).
        Where two runs of the step halving were split alike by the balance, the next run asks its
        steps for a share of the balance smaller by 2 to this power (:func:`landing`), so that
        the steps the balance splits are halved with the rest: with the share fixed they stayed
        as long (random file 30730's runs at h / 2 to h / 64 took the same 33,917 steps, and
        their differences said nothing). Below the default tolerance so does the finer run of any
        pair whose coarser run the balance split (:attr:`balance_splits`), else their difference
        misses the split steps' error (random file 70025 at 1e-5: 1.5e-10 against 1.1e-8). At the
        default the share stays after distinct pairs: shrunk at every halving, the share of random
        file 30649 reached rounding's level by h / 64 (over 300 s instead of 63 s)."""
        return 4 if self.method == RK4 else 3 if self.method == RADAU else 2

    def balanced_step(self, q: np.ndarray, v: np.ndarray, mode: _Mode, trial: float, rate: float, floor: float
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, float]:
        """One step of length ``trial``, halved (not below ``floor``) until the step's momentum
        balance closes to ``rate`` times its length (:data:`MOMENTUM_BALANCE`): the step's change of the linear
        momentum equals its contact impulses plus the weight's, exactly for the true motion. A
        fast-spinning light rod resting on its tip (tens of kN of contact force over one step) is
        where the fixed step is too long; the residual is then the step's error, seen in a law
        the motion obeys. So it is for ROS2 at h x rate >> 1: the momentum P(q) v is not linear
        in the state, and the stiff joint motion's error reaches it (a flight's centre-of-mass
        velocity is off by the residual; studies/whole_landing/spatial_chatter.md). A residual
        within rounding's level (:meth:`balance_rounding`) closes the step, its error unseen
        below it, and is held to that level as to a share: the next doubles only where 2^p times
        the residual is within it (taken for none, every such step doubled, and where its real
        error was near the level, the doubled trial was split back: random file 70025 at 1e-6,
        its first run, 120 of 143 doubled trials). Returns (q, v, contact impulses, the step's
        length, the next trial's length: :func:`balanced_length`)."""
        p0 = None
        dt, order = trial, self.balance_order
        while True:
            q1, v1, impulse = self.step(q, v, mode, dt)
            if dt > floor and self.method == RADAU and not (_finite(q1) and _finite(v1)):
                dt /= 2.0  # its Newton iterations did not converge (radau_step)
                continue
            if dt <= floor or not (_finite(q1) and _finite(v1)):
                return q1, v1, impulse, dt, 2.0 * dt
            end = self.ended(q1, v1, mode)
            if end is None and p0 is None:
                p0 = self.point(q, v).momentum[:, 0].copy()
            balance = end.balance if end is not None else self.momentum_change(p0, q1, v1, impulse)
            weight = self.weight(dt)
            residual, share = float(_largest(np.abs(balance - weight))), rate * dt
            ratio = residual / share if share > 0 else (0.0 if residual <= 0 else math.inf)
            if ratio > 1.0 / 2.0**order:
                level = self.balance_rounding(q, v, q1, v1, end, p0, balance, weight)
                if residual <= level:  # rounding's: the step's error is below it (BALANCE_ROUNDING)
                    ratio = residual / max(share, level)
            if ratio <= 1.0:
                return q1, v1, impulse, dt, balanced_length(dt, ratio, order)
            self.balance_splits += 1
            dt /= 2.0

    def balance_rounding(self, q: np.ndarray, v: np.ndarray, q1: np.ndarray, v1: np.ndarray, end,
                         p0: np.ndarray | None, balance: np.ndarray, weight: np.ndarray) -> float:
        """The rounding level of the momentum residual ``balance`` - ``weight`` of the step from (q,
        v), of momentum ``p0``, to (q1, v1) (``end``: a compiled step's end, which holds both
        momenta and their terms): BALANCE_ROUNDING x eps times the largest of its terms: the
        momenta at both ends and their terms (:func:`momentum_terms`), the contact impulses (p1 -
        p0 - ``balance``) and the weight's. A momentum is a sum and rounds at its terms' scale, far
        above the momentum where fast joints carry bodies that hardly move (random file 70025's
        flight at up to 255 rad/s, its run at h / 2 and 1 / 16000 of the budget: momentum 3.9 N s,
        its terms 512 N s; residuals up to 2.2e-13 N s at every length from h / 2^9 to h / 2^14, up
        to 3.7 eps times the terms and 246 eps times the momentum: reckoned from the momentum, the
        balance split 3736 steps to the floor h / 2^14, 5132 steps in all, 1084 now)."""
        if end is not None:
            p0, p1, terms = end.momentum0, end.momentum1, end.terms
        else:  # the start's point, then the end's (which the run asks next)
            start = momentum_terms(self.point(q, v).M, v, self.dims)
            pt = self.point(q1, v1)
            p1, terms = pt.momentum[:, 0], np.concatenate([start, momentum_terms(pt.M, v1, self.dims)])
        applied = p1 - p0 - balance
        scale = max(float(_largest(np.abs(p0))), float(_largest(np.abs(p1))), float(_largest(np.abs(applied))),
                    float(_largest(np.abs(weight))), float(_largest(terms)))
        return BALANCE_ROUNDING * float(np.finfo(float).eps) * scale

    def momentum_change(self, p0: np.ndarray, q1: np.ndarray, v1: np.ndarray, impulse: np.ndarray) -> np.ndarray:
        """The linear momentum at (q1, v1) minus ``p0`` and the contact ``impulse`` ([normal,
        tangential] per contact, along the normals and tangents at (q1, v1); on a curved heightfield the
        step's :attr:`vectors`): a step's momentum balance but for the weight's impulse (numpy; a
        compiled step's is its ``balance``)."""
        pt = self.point(q1, v1)
        if self.turning:
            return pt.momentum[:, 0] - p0 - self.vectors.sum(axis=1)
        return pt.momentum[:, 0] - p0 - impulse_vector(pt.normal, *_unstacked(impulse, self.nc, self.dims - 1))

    def rk4_step(self, q: np.ndarray, v: np.ndarray, mode: _Mode, h: float
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One classical Runge-Kutta 4 step: (q, v, contact impulses [normal, tangential]); on
        a curved heightfield their world vectors by stage in :attr:`vectors`."""
        a1, f1 = self.derivative(q, v, mode)
        V1 = self.stage_vectors(q, v, f1)
        a2, f2 = self.derivative(q + 0.5 * h * v, v + 0.5 * h * a1, mode)
        V2 = self.stage_vectors(q + 0.5 * h * v, v + 0.5 * h * a1, f2)
        v2 = v + 0.5 * h * a1
        a3, f3 = self.derivative(q + 0.5 * h * v2, v + 0.5 * h * a2, mode)
        V3 = self.stage_vectors(q + 0.5 * h * v2, v + 0.5 * h * a2, f3)
        v3 = v + 0.5 * h * a2
        a4, f4 = self.derivative(q + h * v3, v + h * a3, mode)
        v4 = v + h * a3
        q1 = q + h / 6.0 * (v + 2 * v2 + 2 * v3 + v4)
        v1 = v + h / 6.0 * (a1 + 2 * a2 + 2 * a3 + a4)
        if self.turning:
            self.vectors = h / 6.0 * (V1 + 2 * V2 + 2 * V3 + self.stage_vectors(q + h * v3, v + h * a3, f4))
        return q1, v1, h / 6.0 * (f1 + 2 * f2 + 2 * f3 + f4)

    def stage_vectors(self, q: np.ndarray, v: np.ndarray, forces: np.ndarray) -> np.ndarray | None:
        """On a curved heightfield, the contact ``forces`` ([normal, tangential] per contact) at (q, v)
        as world vectors (d x n_c) along that point's normals and tangents: a step's impulse is
        its stages' forces, each along its own directions, which turn under a contact sliding
        across a curved heightfield (random file 30649: along the end's alone, the step's
        momentum balance is first order in the step, and the balance split steps to h / 2^13);
        elsewhere (flat ground, a plane's terrain: :attr:`turning`) None."""
        if not self.turning:
            return None
        pt = self.point(q, v)
        return contact_vectors(pt.normal, pt.tangent, *_unstacked(forces, self.nc, self.dims - 1))
