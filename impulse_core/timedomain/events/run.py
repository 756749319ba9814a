"""One run of the landing at a fixed step (:class:`_Landing`, composed of the mixins of
:mod:`impulse_core.timedomain.events`): from the first impact, steps and events until T
(:meth:`_Landing.run_once`), each event's impact and mode choice; :func:`~impulse_core.timedomain.landing.landing`
halves the step over such runs."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from impulse_core.errors import ModelError, NumericalError
from impulse_core.impact import lemke_c
from impulse_core.kinematics.spatial import AXIAL_GYRATION_FLOOR, PLANAR, Space, dof_layout, values_space
from impulse_core.model.heightfield import Heightfield
from impulse_core.model.joints import JointLaw
from impulse_core.model.terrain import Terrain, slope_normal
from impulse_core.model.terrain import _segment_normals as terrain_normals
from impulse_core.model.tree import Scene, Tree, design_vector
from impulse_core.timedomain.compliant import (
    BufferedCall, _check_chart, _require_known, spatial_ground, subtree_incidence, subtree_masses,
    touchdown_configuration,
)
from impulse_core.timedomain.events.settings import (
    AUTO, AUTO_CODE, AUTO_IMPLICIT, C_CODE, FIRST_STEPS, IMPLICIT, MASSLESS, MAX_SPLITS, MIN_BOUNCE,
    MOMENTUM_BALANCE, NUMPY_CODE, RADAU, RADAU_TRIES, RECHART, REPEAT_SPAN, REPEATS, RK4, RK4_PACE, RK4_PACE_AFTER,
    RK4_STABLE, SLIP_BUDGET, STEP_BUDGET, VM_CODE, Diverged, RadauTries, _Jams, _Unjammed, LandingProgress,
    LandingSettings, PainleveParadox, Progress, Until,
)
from impulse_core.timedomain.events.results import LandingResult
from impulse_core.timedomain.events.point import (
    _Point, _any, _finite, joint_arrays, joint_law_rate, landing_function, tangent_basis,
)
from impulse_core.timedomain.events.rows import _Mode, _same_kind
from impulse_core.timedomain.events.impact_law import RigidImpact
from impulse_core.timedomain.events.tally import _Tally, _Totals
from impulse_core.timedomain.events.dynamics import _Dynamics
from impulse_core.timedomain.events.stepping import _Stepping
from impulse_core.timedomain.events.location import _ROOT_SAMPLES, _Location, _hermite_root
from impulse_core.timedomain.events.impacts import _Impacts
from impulse_core.timedomain.events.choice import _ModeChoice
from impulse_core.timedomain.events.placement import _Placement
from impulse_core.timedomain.events.paradox import BRIDGE, JAM_WATCH, _Paradox
from impulse_core.timedomain.events.messages import _Messages
from impulse_core.timedomain.events.twins import mode_alike, symmetrized, twin_contacts, twin_groups


class _Landing(_Dynamics, _Stepping, _Location, _Impacts, _ModeChoice, _Placement, _Paradox, _Messages, _Tally):
    """The integration of one landing at one step length (:mod:`impulse_core.timedomain.landing`'s docstring)."""

    def __init__(self, tree: Tree, scene: Scene, laws: tuple[JointLaw, ...], settings: LandingSettings,
                 space: Space = PLANAR) -> None:
        _require_known(space)
        space = values_space(tree, space)  # the plane with centres of mass off the rods: PLANAR_OFFSET
        self.tree, self.scene, self.settings, self.space = tree, scene, settings, space
        self.topology = tree.topology()
        #: in the plane (PLANAR or PLANAR_OFFSET), not in space
        self.planar = space.joint_axis is not None
        ground = scene.terrain if self.planar else spatial_ground(scene)
        self.ground = ground  # the plane's profile, or space's heightfield
        fn = self.point_function(ground, space)
        #: the impacts' and mode choices' LCPs by Lemke's method as C with step code c (the same
        #: numbers; None: Python's, also without a C compiler)
        self.lemke = None
        #: the location's root of a cubic (:func:`_hermite_root`; with step code c as C, the same numbers)
        self.root = _hermite_root
        #: the design vector; a run's re-centred rotation coordinates change the base's orientation
        #: in the call's copy (:meth:`rechart`), and the next run starts from this one again
        self.design = design_vector(tree, space.body_values)
        self.call = BufferedCall(fn, self.design, scene.gravity)
        #: space: the turns the re-centrings put into the base's orientation (None: none), and the
        #: last reported rotation vector since touchdown (:meth:`reported`)
        self.chart: np.ndarray | None = None
        self.turn = np.zeros(3)
        self._last: tuple[tuple[bytes, bytes], _Point] | None = None  # see point()
        base_z = 0.0 if self.planar else float(scene.base_z)
        self.q0 = touchdown_configuration(tree, ground, scene.base_x, space=space, base_z=base_z)
        self.joints = joint_arrays(tree, laws, self.q0, space)
        self.layout = dof_layout(self.topology, space)
        #: the DOFs of each group of identical sibling subtrees (:func:`twin_groups`; :meth:`twinned`)
        self.twins = twin_groups(tree, self.joints, self.layout)
        #: each group's declared contacts (:func:`twin_contacts`; :meth:`held_alike`)
        self.twin_contacts = twin_contacts(tree, self.joints, self.layout)
        #: hold twins alike after each step (:meth:`held_alike`); False: never (a study's unheld reference)
        self.hold_twins = True
        self.nc, self.nv = len(tree.contacts), len(self.q0)
        #: the rows of a point's position: 2 in the plane, 3 in space
        self.dims = 2 if self.planar else 3
        self.mu, self.e = scene.friction, scene.restitution
        self.in_subtree = subtree_incidence(tree)
        self.mass = sum(b.mass for b in tree.bodies)
        #: space: the mass matrix's eigenvalue below which a direction moves no mass (:data:`MASSLESS`)
        self.massless = None if self.planar else MASSLESS * self.nv * sum(
            b.mass * (AXIAL_GYRATION_FLOOR * b.length) ** 2 for b in tree.bodies)
        self.subtree_mass = subtree_masses(tree)
        self.set_ground(ground)
        #: the contact normals at the last accepted step's end (None: after an event or a crossing)
        self.end_normals: np.ndarray | None = None
        #: the point (q, v) whose rows the last :meth:`project` took its velocity projection on,
        #: where its impulses act (:meth:`add`)
        self.projected_at: tuple[np.ndarray, np.ndarray] | None = None
        weight = self.mass * max(scene.gravity, 1.0)
        self.force_tol = 1e-9 * weight
        self.speed_tol = 1e-9 * max(1.0, scene.speed, abs(scene.velocity_x))
        M0 = self.mass_matrix_at(self.q0)
        self.choose_integrator(M0)
        #: circular-cone solves of the current run that fell back to the polyhedral answer
        self.inexact = self.non_unique = 0
        #: the current run's Moreau-Jean bridges across stalled events: (start, span) (:meth:`bridge`)
        self.bridges: list[tuple[float, float]] = []
        #: the law's answer at the last impact (:meth:`impact`)
        self.last_impact: RigidImpact | None = None
        #: the contacts whose turned slip the last :meth:`arrest` left sliding (its mode with them
        #: sticking does not hold); events that repeat so are a stall (:data:`REPEATS`)
        self.refused = np.zeros(0, int)
        #: None, or a list that each impact appends (q, v, its contacts, its point, the law's answer) to
        self.impact_log: list | None = None
        #: keep the joint impulses of impacts and resting phases (:attr:`_Totals.joint`)
        self.tally_joint = False
        #: the generalized velocity before the first touchdown (None: the scene's approach)
        self.v_minus: np.ndarray | None = None
        #: a rebound shorter than this (s) is plastic: MIN_BOUNCE of the duration at the first
        #: impact, and also ``settings.bounce_steps`` of the step after it (set by :meth:`run`)
        self.min_bounce = MIN_BOUNCE * float(scene.duration or 0.0)
        #: None, or a list that a run appends its committed operations to, in order (what
        #: :mod:`impulse_core.timedomain.landing_derivatives` replays): ("step", q, v, mode, dt,
        #: final), ("event_step", q, v, mode, tau, watch), ("vertex_step", q, v, mode, tau, crossed:
        #: a step to a resting contact passing a terrain breakpoint, :meth:`vertex_crossing`; the
        #: replay refuses it), ("impact", q, v, rows, e, sol, plastic:
        #: the rows whose restitution the plastic rules zeroed) and ("project", q, v, mode), that
        #: followed by ("crease_project",) where its correction carried a resting contact across a
        #: heightfield's grid line (its rows then the next cell's; the replay refuses it), and
        #: ("twins", groups) where :meth:`twinned` set identical toes to their mean; q, v are the
        #: operation's inputs.
        self.tape: list | None = None
        #: the halvings :meth:`slip_length` chose at each step's start of the last run, in order
        #: (0: none); and None, or such a list that a run takes its halvings from instead, as far as
        #: it reaches (``landing_derivatives.taped_run``: a run along another's split decisions)
        self.slip_halvings: list[int] = []
        self.given_halvings: list[int] | None = None
        #: the halvings of steps by the momentum balance in the last run (:meth:`balanced_step`: a
        #: step's residual over its share of the budget): where the coarser run of a pair of the
        #: step halving made any, :func:`landing` asks the finer for a smaller share (balance_order)
        self.balance_splits = 0
        #: the compiled step of the integrator (None: numpy), and the last compiled step's end (ended())
        self.fast = self.compiled_step(settings.step_code)
        #: the code the steps run on: c, vm or numpy (``auto``: c where the compile cache holds it)
        self.code = NUMPY_CODE if self.fast is None else C_CODE if self.fast.compiled else VM_CODE
        if self.code == C_CODE:
            self.lemke = lemke_c.compiled_lemke()
            self.root = lemke_c.hermite_root(_ROOT_SAMPLES) or _hermite_root
        self._end: tuple[bytes, bytes, object] | None = None
        #: a curved heightfield (turning): the last step's contact impulses as world vectors (d x n_c), each
        #: stage's force along its own point's normal and tangents (:meth:`stage_vectors`)
        self.vectors: np.ndarray | None = None
        self._unwatched: dict[bytes, np.ndarray] = {}  # see unwatched()
        self._solutions: tuple[_Point | None, dict] = (None, {})  # see mode_solution()
        self._steering: tuple = (None, b"")  # steer()'s last point, mode and figures
        self._jams: tuple[float, int] = (math.nan, 0)  # the last impulsive jam's time and its count there
        #: None (no impulsive jams), or, once a run of this landing stopped with Painleve's paradox
        #: (:meth:`run`), the fraction of its frictionless value below which a pressed sliding
        #: contact's A = n M^-1 (n - mu u t)^T jams at a step's start
        self.jam_watch: float | None = None
        #: RK4's stable step where this run is ``auto``'s implicit first run, or the Radau IIA run
        #: that ``auto`` went on with (:func:`landing` sets it; :data:`RK4_PACE`), else None
        self.rk4_pace: float | None = None
        #: the Radau IIA steps the current run tried, pieces of split steps and the balance's
        #: rejected trials included (:meth:`radau_step`): its work, which :meth:`check_budget` counts
        self.radau_tries = 0
        gap_tol, nc, nv = settings.gap_tolerance, self.nc, self.nv
        #: the witnesses' tolerances (:meth:`witness_and_rate`): gaps, forces, cone margins, slip,
        #: stop margins (twice), stop forces; and the NaN rates of the force and slip witnesses
        self.witness_scale = np.concatenate([np.full(nc, gap_tol), np.full(2 * nc, self.force_tol),
                                             np.full(nc, self.speed_tol), np.full(2 * nv, gap_tol),
                                             np.full(nv, self.force_tol)])
        self.unknown_rates = (np.full(3 * nc, np.nan), np.full(nv, np.nan))
        up = np.tile(np.eye(self.dims)[1], (self.nc, 1))
        #: flat ground's normals and tangents at every contact (:func:`tangent_basis`)
        self.flat_ground = (up, tangent_basis(up))
        self.refuse_massless_contacts(tree, M0)
        self.refuse_swinging_springs(tree, M0)

    def point_function(self, ground: Terrain | Heightfield, space: Space):
        """The dynamics at a point (:func:`landing_function`) on ``ground`` in ``space``: compiled to C with
        step code c (or auto), else on CasADi's virtual machine."""
        settings = self.settings
        if settings.step_code not in (C_CODE, VM_CODE, NUMPY_CODE, AUTO_CODE):
            raise ModelError(f"step_code: {settings.step_code!r} is not one of c, vm, numpy, auto")
        if settings.step_code in (C_CODE, AUTO_CODE):  # the point's dynamics compiled too
            from impulse_core.timedomain.landing_step import compiled_landing_function  # it builds on this module

            fn = compiled_landing_function(self.topology, ground, space, build=settings.step_code == C_CODE)
        else:
            fn = landing_function(self.topology, ground, space)
        return fn

    def set_ground(self, ground: Terrain | Heightfield) -> None:
        """The ground's figures the run reads: sloped or turning, the plane's terrain breakpoints and
        valleys, space's heightfield grid lines, and the contacts seated in valley corners."""
        scene = self.scene
        self.sloped = not ground.is_flat
        #: a curved ground whose normal turns under a sliding contact within a step (a sloped
        #: heightfield; a plane's terrain turns it only at its breakpoints, whose crossings are
        #: events): a step's impulse is then its stages' forces along their own directions
        self.turning = self.sloped and not self.planar
        #: the plane's terrain breakpoints (x, m) where a sloped profile's normal jumps; None: flat
        #: or space (:meth:`vertex_crossing`)
        self.vertices = np.asarray(scene.terrain.x, dtype=float) if self.planar and self.sloped else None
        #: space's sloped heightfield: its x and z grid lines, where the bilinear ground's normal
        #: jumps (a crease), so that a contact sliding across one is an event as a plane's
        #: breakpoint is (:meth:`pieces`); None: flat or the plane
        self.grid = (np.asarray(ground.x, dtype=float), np.asarray(ground.z, dtype=float)) \
            if self.turning else None
        #: per breakpoint of the plane's terrain, its left and right pieces' outward normals
        #: (K x 2 x 2; the rays beyond the ends are flat), and whether it is a valley's (concave:
        #: the slope rises across it), where a contact can rest held by both; None: flat or space
        self.valleys: np.ndarray | None = None
        self.concave: np.ndarray | None = None
        if self.vertices is not None:
            up = np.array([[0.0, 1.0]])
            pieces = np.vstack([up, terrain_normals(scene.terrain), up])
            self.valleys = np.stack([pieces[:-1], pieces[1:]], axis=1)
            left, right = self.valleys[:, 0], self.valleys[:, 1]
            self.concave = left[:, 0] * right[:, 1] - left[:, 1] * right[:, 0] > 1e-12  # the normal turns anticlockwise
        #: per contact, the valley breakpoint where the run's current mode holds it in the corner
        #: (-1: none); there the point's normal and tangent are the breakpoint's (the mean of its
        #: segments' normals, :func:`impulse_core.model.terrain.slope_normal`), whatever rounding
        #: places it on, so that its impulses sum in one frame (:meth:`seat`)
        self.seated = np.full(self.nc, -1)
        self.seat_frames = None if self.vertices is None else slope_normal(scene.terrain, self.vertices)

    def choose_integrator(self, M0: np.ndarray) -> None:
        """The integrator between events (:attr:`LandingSettings.integrator`; ``auto`` by the joint laws'
        fastest rate at touchdown, from the mass matrix ``M0`` there)."""
        settings, scene = self.settings, self.scene
        #: The integrator between events (RK4, IMPLICIT or RADAU), one for every step length.
        self.method = settings.integrator
        #: the joint laws' fastest rate at touchdown (1/s, :func:`joint_law_rate`)
        self.rate = joint_law_rate(M0, self.joints.damping, self.joints.stiffness)
        if self.method == AUTO:
            h0, limit = ((settings.step, RK4_STABLE) if settings.step
                         else ((scene.duration or 0.0) * FIRST_STEPS[0], AUTO_IMPLICIT))
            self.method = IMPLICIT if h0 * self.rate > limit else RK4
        if self.method not in (RK4, IMPLICIT, RADAU):
            raise ModelError(f"integrator: {settings.integrator!r} is not one of rk4, implicit, radau, auto")

    def run(self, h: float, progress: Progress | None = None, index: int = 0, until: Until | None = None,
            share: float = 1.0) -> LandingResult:
        """The landing at Runge-Kutta step ``h`` (:meth:`run_once`). Where a run stops with
        Painleve's paradox (its contact problem without solution, events stalled on it, or a
        divergence after a contact slid), the landing takes impulsive jams from then on
        (:attr:`jam_watch`, kept for this landing's later runs) and the run starts again: the
        same to the bit until a contact jams, and every run of the step halving judges alike
        where one does (a pressed sliding contact's A falls below JAM_WATCH of its
        frictionless value at a step's start, or the contact problem fails)."""
        try:
            return self.run_once(h, progress, index, until, share)
        except _Jams as paradox:
            if self.jam_watch is not None or self.tape is not None:  # the derivatives' replay: no jams
                raise paradox.failure from None
            self.jam_watch = JAM_WATCH
        return self.run_once(h, progress, index, until, share)

    def run_once(self, h: float, progress: Progress | None = None, index: int = 0, until: Until | None = None,
                 share: float = 1.0) -> LandingResult:
        """The landing at Runge-Kutta step ``h`` (``progress``: told after each step and event,
        as run ``index`` of the step halving); ``until``, asked after the first impact and after
        each step and event, ends it early (its ``duration`` is then the time reached);
        ``share``: the steps' momentum residual per second as a fraction of the default's
        (:data:`MOMENTUM_BALANCE`; :func:`landing`'s finer runs)."""
        T = float(self.scene.duration)
        self.inexact = self.non_unique = 0
        self.bridges = []
        self.min_bounce = MIN_BOUNCE * T
        self._jams = (math.nan, 0)
        self.refused = np.zeros(0, int)
        self.slip_halvings = []
        self.balance_splits = 0
        self.radau_tries = 0
        q, v, mode, totals = self.first_impact()
        slid = bool(self.mu) and _any(mode.closed & mode.sliding)  # a contact slid (a jam may follow)
        self.end_normals = None
        self.min_bounce = max(MIN_BOUNCE * T, self.settings.bounce_steps * h)
        energy_before = totals.events[0].energy_before
        height0 = self.point(self.q0, v).com_height
        wound = self.joints.energy(self.q0)  # the springs at touchdown
        cap = self.energy_cap(energy_before, wound, height0)
        t, stalled, repeated, again, bridged = 0.0, 0, 0, False, 0
        self.record(totals, t, v, t, q, v)
        p0 = self.point(self.q0, totals.events[0].v_minus).momentum[:, 0]
        reference = max(float(np.max(np.abs(p0))), self.mass * self.scene.gravity * T)
        rate = share * MOMENTUM_BALANCE * reference / T  # the steps' momentum residual per second
        trial = h  # the next step's length: h, or h / 2^k after the momentum balance split a step
        splits = self.settings.slip_splits
        while t < T * (1 - 1e-12) and not (until is not None and until(q, v, mode, totals)):
            if not self.planar and float(np.linalg.norm(q[3:6])) > RECHART:
                q, v = self.rechart(q, v, totals)
            if self.jam_watch is not None and _any(mode.closed & mode.sliding):
                jammed = self.watched_jam(q, v, mode, t, totals, min(h * BRIDGE, T - t), bridged)
                if jammed is not None:
                    q, v, mode, t, bridged = jammed
                    if progress is not None:
                        progress(LandingProgress(index, h, t, T, len(totals.events)))
                    continue
            # a slow turning slip splits the step where asked (slip_length), within SLIP_BUDGET steps per step h
            least = h / 2.0**splits if splits and totals.steps <= SLIP_BUDGET * T / h else math.inf
            length = self.split_length(q, v, mode, min(trial, T - t), least)
            q1, v1, impulse, dt, grown = self.balanced_step(q, v, mode, length, rate, h / 2.0**MAX_SPLITS)
            step_vectors = self.vectors  # a curved heightfield (trial steps below replace self.vectors)
            self.check_budget(totals.steps, t, h)
            final = dt == T - t and dt < trial  # shortened to end at T, not split
            trial = trial if final else min(h, grown)
            if not (_finite(q1) and _finite(v1) and self.kinetic(q1, v1) <= cap):
                q, v, mode, t, bridged = self.diverged(q, v, mode, t, h, totals, bridged, slid)
                continue
            _check_chart(q1, self.space, t + dt)
            graze, crossing = self.step_events(q, v, q1, v1, mode, dt, impulse, step_vectors)
            if graze is not None or crossing is not None:
                self.end_normals = None
            if graze is None and crossing is None:
                q, v = self.accept_step(q, v, q1, v1, mode, impulse, step_vectors, totals, t, dt, final)
                t += dt
                totals.steps += 1
                if progress is not None:
                    progress(LandingProgress(index, h, t, T, len(totals.events)))
                continue
            located, crossed, cornered = self.event_location(q, v, mode, graze, crossing)
            tau = located.tau
            q_e, v_e, impulse = self.take(q, v, mode, located)
            q_e, v_e = self.held_alike(q_e, v_e, mode)
            self.add(totals, impulse, q_e, v_e, self.vectors)
            self.tally_joints(totals, q, v, q_e, v_e, impulse, tau, _any(mode.closed), self.vectors)
            self.record(totals, t, v, t + tau, q_e, v_e)
            t += tau
            stalled = stalled + 1 if tau < 1e-12 * max(1.0, T) else 0
            repeated = repeated + 1 if again and (tau < REPEAT_SPAN * max(1.0, T) or self.refused.size) else 0
            if stalled > 20 or repeated > REPEATS:
                q, v, mode, t, bridged = self.unstall(q_e, v_e, mode, t, totals, min(h * BRIDGE, T - t), bridged)
                stalled = repeated = 0
                again = False
                if progress is not None:
                    progress(LandingProgress(index, h, t, T, len(totals.events)))
                continue
            if len(totals.events) > self.settings.max_events:
                raise NumericalError(self.budget_message(totals.events, t))
            before = mode.copy()
            q, v, mode = self.event(q_e, v_e, mode, t, totals, crossed, cornered)
            again = _same_kind(before, mode)  # the event gave back the mode it stopped
            slid = slid or bool(self.mu) and _any(mode.closed & mode.sliding)
            if progress is not None:
                progress(LandingProgress(index, h, t, T, len(totals.events)))
        pt = self.point(q, v)
        end = t if t < T * (1 - 1e-12) else T  # where ``until`` ended the run, or T
        gravity_work = self.mass * self.scene.gravity * (height0 - pt.com_height)
        residual = pt.momentum[:, 0] - p0 - totals.impulse - self.weight(end)
        balance = float(np.max(np.abs(residual))) / reference
        out = self.result(totals, q, v, h, energy_before, pt.kinetic + self.joints.energy(q), gravity_work)
        self.set_chart(self.design, None)  # q_final's rotation vector is since touchdown
        return replace(out, momentum_balance=balance, duration=end, spring_energy=wound, bridges=tuple(self.bridges),
                       share=share)

    def energy_cap(self, energy_before: float, wound: float, height0: float) -> float:
        """The kinetic energy beyond which a run has diverged (:meth:`run_once`), from the energy before
        touchdown, the springs ``wound`` at touchdown and the centre of mass's height ``height0`` there."""
        T = float(self.scene.duration)
        # No energy enters (passive joints, a fixed ground): the kinetic energy stays below what
        # touchdown, the springs wound at touchdown and gravity bring; far above it, the step is
        # too long for a stiff joint (random file 32069: a spring 0.21 rad from rest held 0.94 J
        # against 0.035 J of motion, and a landing without gravity stopped as diverged).
        weight = sum(b.mass for b in self.tree.bodies) * self.scene.gravity
        reach = sum(b.length for b in self.tree.bodies)
        return 10.0 * (energy_before + wound + weight * (height0 + reach + 10.0 * T * self.scene.speed)) + 1e-6

    def check_budget(self, steps: int, t: float, h: float) -> None:
        """Raise Diverged where a run at step ``h`` has taken more than its budget of ``steps`` by ``t``
        (:data:`STEP_BUDGET`), or, as ``auto``'s implicit run, fallen behind RK4's stable step
        (:data:`RK4_PACE`). On Radau IIA both also count its tries (:attr:`radau_tries`; the budget
        RADAU_TRIES x as many): where its Newton iterations fail (a spring so stiff that rounding in
        its torque keeps them from converging: the case-3 leg with a heel of 1e12 N m/rad, 17 tries a
        step, 5e-11 s each), a step is many tries, and the steps taken alone kept the run within
        its budget while it crawled (no end in 150 s of CPU)."""
        T = float(self.scene.duration)
        if steps > STEP_BUDGET * T / h:
            raise Diverged(  # landing() shortens the step (retry_factor)
                f"the landing took more than {STEP_BUDGET} x {T / h:.0f} steps by t = {t:.6g} s (the momentum "
                "balance split its steps: a light rod spinning fast)", reached=t / T,
            )
        if self.radau_tries > RADAU_TRIES * STEP_BUDGET * T / h:
            raise RadauTries(  # landing() goes on with RK4, or fails where Radau IIA was asked for
                f"Radau IIA tried more than {RADAU_TRIES} x {STEP_BUDGET} x {T / h:.0f} steps by t = {t:.6g} s (its "
                "Newton iterations failed, or the momentum balance split its steps)", reached=t / T,
            )
        if self.method == RADAU:
            steps = max(steps, self.radau_tries)
        if (self.rk4_pace is not None and steps > RK4_PACE_AFTER * T / h
                and steps * self.rk4_pace > RK4_PACE * t):
            why = ("Radau IIA's tries", "its Newton iterations failed or the momentum balance split them") \
                if self.method == RADAU else ("the implicit steps", "the momentum balance split them")
            raise Diverged(  # landing() goes on with RK4 from its stable step
                f"{why[0]} averaged {t / steps:.3g} s by t = {t:.6g} s, below half of RK4's "
                f"stable step {self.rk4_pace:.3g} s ({why[1]})", reached=t / T,
            )

    def split_length(self, q: np.ndarray, v: np.ndarray, mode: _Mode, trial: float, least: float) -> float:
        """:meth:`slip_length`, or where :attr:`given_halvings` reaches this step, ``trial`` halved as
        many times as it says; the halvings are kept (:attr:`slip_halvings`)."""
        given, k = self.given_halvings, len(self.slip_halvings)
        if given is not None and k < len(given):
            length = trial / 2.0 ** given[k]
        else:
            length = self.slip_length(q, v, mode, trial, least)
        self.slip_halvings.append(round(math.log2(trial / length)))
        return length

    def diverged(self, q: np.ndarray, v: np.ndarray, mode: _Mode, t: float, h: float, totals: _Totals,
                 bridged: int, slid: bool) -> tuple[np.ndarray, np.ndarray, _Mode, float, int]:
        """A step from (q, v) at ``t`` that diverged: a bridge from its start where the run has met
        Painleve's paradox (:meth:`bridge_within`: the state, mode, time and bridges after it), else
        Diverged, or :class:`_Jams` where a contact slid (``slid``) and the run does not yet jam."""
        T = float(self.scene.duration)
        failure = Diverged(f"the landing diverged at t = {t:.4g} s (step {h:.3g} s){self.singular_note(q)}"
                           f"{self.jam_note(q, v, mode) or self.paradox_note()}")
        if self._jams[1] and _any(mode.closed & mode.sliding):
            # a run that has met Painleve's paradox (a jam taken or tried), a step sliding into
            # it again (its force without bound): a bridge from the step's start (random file
            # 60690 at h / 8, after two jams); elsewhere a divergence is a step too long
            return self.bridge_within(q, v, mode, t, totals, min(h * BRIDGE, T - t), bridged, failure)
        if self.jam_watch is not None or not slid:
            raise failure
        # a sliding contact may have run into Painleve's paradox (its force -B / A without
        # bound as A falls to 0: the steps before the divergence are already off)
        raise _Jams(failure)

    def accept_step(self, q: np.ndarray, v: np.ndarray, q1: np.ndarray, v1: np.ndarray, mode: _Mode,
                    impulse: np.ndarray, step_vectors: np.ndarray | None, totals: _Totals, t: float, dt: float,
                    final: bool) -> tuple[np.ndarray, np.ndarray]:
        """Take a step from (q, v) at ``t`` to (q1, v1) in which no event happened: projected back onto the
        mode's constraints, its impulses (``impulse``, ``step_vectors``) counted and recorded; the state after."""
        if self.tape is not None:
            self.tape.append(("step", q.copy(), v.copy(), mode.copy(), dt, final))
        q0, v0 = q, v
        segments = self.segment_normals(q1, v1, mode)
        q, v, p = self.project(q1, v1, mode)
        self.follow_slip(q, v, mode)
        q, v = self.held_alike(q, v, mode)
        self.vectors = step_vectors
        vectors = self.step_vectors(*self.projected_at, p)
        applied = impulse + p  # read only below
        if segments is not None and vectors is None:
            vectors = self.segment_vectors(segments, applied)
        self.add(totals, applied, q, v, vectors)
        self.tally_joints(totals, q0, v0, q, v, applied, dt, _any(mode.closed), vectors)
        self.record(totals, t, v0, t + dt, q, v)
        return q, v

    def modes_after(self, q: np.ndarray, v: np.ndarray, mode: _Mode, t: float, totals: _Totals,
                    v_before: np.ndarray, jammed: bool = False) -> tuple[np.ndarray, np.ndarray, _Mode]:
        """After an event at ``t`` (the velocities ``v_before`` it): the modes
        (:meth:`resolve_or_jam`, ``jammed`` after a jam; a valley's corners seated), the
        projection onto them, counted in ``totals``, and the record: (q, v, mode) after."""
        q, v = self.twinned(q, v)
        q, v, mode = self.resolve_or_jam(q, v, mode, t, totals, jammed)
        if self.valleys is not None:
            self.seat(mode)
        q1, v1, p = self.project(q, v, mode)
        self.add(totals, p, *self.projected_at)
        self.tally_joints(totals, q, v, q1, v1, p, 0.0, _any(mode.closed))
        self.record(totals, t, v_before, t, q1, v1)
        return q1, v1, mode

    def twinned(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(q, v) with each group of twins (:attr:`twins`: identical toes on one parent) at the mean
        of their angles and velocities where they differ (taped as ("twins", groups)). The exact
        landing keeps twins identical; rounding parts them, and where their contacts rest on one
        point with the toes near straight, the rows that pin both tips are nearly redundant: the
        parting grows, and the mode's forces turn it into a squeeze of the twins against each other.
        Trial 38 of the landing study: two toes whose distal joints were 2e-4 rad from straight,
        apart by 3e-8 rad and 3e-5 rad/s at t = 0.107 s, the sticking pair's rows of condition 5e7,
        whose forces were 5.2 N and -4.3 N of friction on 9.8 N and 11.4 N (toe1 outside its cone)
        where the twins' mean state gives both 0.46 N on 10.6 N; no mode held, one toe slid and the
        other flipped its slip at every event, and the run stopped on the chatter."""
        q1, v1 = symmetrized(q, self.twins), symmetrized(v, self.twins)
        if self.tape is not None and (q1 is not q or v1 is not v):
            self.tape.append(("twins", self.twins))
        return q1, v1

    def held_alike(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> tuple[np.ndarray, np.ndarray]:
        """(q, v) at an accepted step's end or a located event in ``mode``, each group of twins set
        to their mean (:meth:`twinned`, taped so) where the mode treats them alike
        (:func:`mode_alike`), on every integrator (unless :attr:`hold_twins` is off); else as
        they are. The exact landing keeps twins identical; rounding parts them (Radau IIA's Newton
        iterations, and RK4's and ROS2's steps through the mass matrix's solve), and the
        mirror-antisymmetric motion grows (trial 64 of the landing study:
        5.6e-17 rad at 1 ms, 5.6e-11 at 3.8 ms, x ~10 every 0.5 ms) up to an impact on both toes
        at once whose split is ill-conditioned in their parting (both toes reaching their stops
        with both tips pressed: 2.94 and 0.09 N s where the even split is 1.52 and 1.52; the
        landing 0.33 from RK4's with an estimate of 8e-8; ``studies/whole_landing/stiff_designs.md``).
        RK4's steps part them too: a 5 ms landing of trial 64 at RK4's stable step split that impact
        2.94 and 0.09 N s as well, 0.28 from the held landing; trial 38's 20 ms parted on 924 of its
        1008 steps. Held on every integrator since (case 3's landing moved by 4e-15 rad and 3e-13
        N s, its 441 events the same; the landing tests' pinned figures held). Held alike,
        the twins are apart by at most one step's rounding, and at an event not at all. Where a
        mode parts them (a redundant pair's rows: one twin's contact closed, the other's open),
        their states may differ by its projection, and are left so. A no-op (no copy, nothing
        taped) where the twins are equal to the bit or there are none."""
        if not (self.hold_twins and self.twins
                and mode_alike(mode.stop, mode.closed, mode.slip, self.twins, self.twin_contacts)):
            return q, v
        return self.twinned(q, v)

    def resolve_or_jam(self, q: np.ndarray, v: np.ndarray, mode: _Mode, t: float, totals: _Totals,
                       jammed: bool = False) -> tuple[np.ndarray, np.ndarray, _Mode]:
        """:meth:`resolve`, or, where its contact problem has no solution (Painleve's paradox),
        the impulsive jam of the sliding contact there (:meth:`take_jam`) and then this again
        from the velocities after it: (q, v, mode). Right after a jam (``jammed``), also a mode
        whose force pulls on a sliding contact in the paradox (:meth:`painleve`) jams again at
        once: in space a jam that ended with its compression can leave its contact sliding in
        the paradox, and each jam then takes the slip by about the same factor towards 0 (random
        file 30325: 0.58, 21 jams at one instant, 4 at the next), which through the run's
        stalled events (21 per jam) cost 61 s instead of 9 s."""
        while True:
            try:
                new = self.resolve(q, v, mode, t)
            except PainleveParadox as paradox:
                if self.jam_watch is None:
                    raise _Jams(paradox) from None
                q, v, mode = self.take_jam(q, v, mode, t, totals, self.sliding_jams(q, v, mode), paradox)
                jammed = True
                continue
            again = self.painleve(q, v, new) if jammed else np.zeros(0, int)
            if not again.size:
                return q, v, new
            failure = NumericalError(self.stall_message(q, v, new, t))
            try:
                q, v, mode = self.take_jam(q, v, new, t, totals, again, failure)
            except NumericalError as unjammed:
                if unjammed is not failure:
                    raise
                raise _Unjammed(failure, q, v, new) from None

    def event(self, q: np.ndarray, v: np.ndarray, mode: _Mode, t: float, totals: _Totals,
              crossed: np.ndarray | None = None, cornered: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray, _Mode]:
        """Handle the event at (q, v): an impact where a contact touches or a joint reaches a
        stop, then the new modes. ``crossed``: the closed contacts that have just passed a
        terrain vertex (:meth:`vertex_crossing`): each meets the segment beyond it afresh, along
        that segment's normal: an impact where it approaches it (a valley), free where it leaves
        it (a ridge). ``cornered``: per contact -1, or the valley breakpoint it has just reached
        slower than the plastic speed: it rests in the corner, held by both segments' rows, while
        the contact LCP loads both (:meth:`resolve`, :meth:`keep_corners`); the projection takes
        its velocity to zero."""
        pt = self.point(q, v)
        vn = pt.vn(v)
        touching = ~mode.closed & (pt.gap <= self.settings.gap_tolerance) & (vn < 0)
        if crossed is not None:
            mode = mode.copy()
            mode.closed[crossed] = False
            mode.slip[crossed] = 0.0
            touching |= crossed & (vn < 0)
        if cornered is not None and _any(cornered >= 0):
            mode = mode.copy()
            at = cornered >= 0
            mode.closed[at], mode.corner[at], mode.slip[at] = True, cornered[at], 0.0
            touching |= at  # a plastic impact over both rows (approaching slower than the plastic speed)
        reaching = (mode.stop == 0) & (((q <= self.joints.lo + self.settings.gap_tolerance) & (v < 0))
                                        | ((q >= self.joints.hi - self.settings.gap_tolerance) & (v > 0)))
        v_before = v
        if _any(touching) or _any(reaching):
            # every contact at the ground takes part (one just released may be pushed back down)
            contacts = np.flatnonzero(mode.closed | (pt.gap <= self.settings.gap_tolerance) | touching)
            v_minus = v
            v, event, mode = self.impact(q, v, mode, t, contacts, "touchdown" if _any(touching) else "stop")
            totals.events.append(event)
            self.add_impact(totals, event, q, v_minus, v)
        q, v = self.arrest(q, v, mode, totals)
        return self.modes_after(q, v, mode, t, totals, v_before)
