"""What a run accumulates (:class:`_Totals`): the contact impulses as totals and world vectors,
the joint impulses, the trajectory and when the tree last moved, and the :class:`LandingResult` built
from them at T."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from impulse_core.timedomain.compliant import world_velocity
from impulse_core.timedomain.events.settings import SETTLE_SPEED
from impulse_core.timedomain.events.results import LandingEvent, LandingResult
from impulse_core.timedomain.events.point import _Point, _any, _largest, tangent_basis
from impulse_core.timedomain.events.rows import _Mode
from impulse_core.timedomain.events.forces import contact_vectors, _unstacked


@dataclass
class _Totals:
    """What a run accumulates."""

    normal: np.ndarray
    tangential: np.ndarray
    events: list[LandingEvent] = field(default_factory=list)
    times: list[float] = field(default_factory=list)
    states: list[np.ndarray] = field(default_factory=list)
    moving_until: float = 0.0
    steps: int = 0
    impulse: np.ndarray = field(default_factory=lambda: np.zeros(2))  # the contact impulses' sum (world)
    chart_q: np.ndarray | None = None  # the last recorded q, in the rotation coordinates of its time
    vectors: np.ndarray | None = None  # each contact's impulse vector (d x n_c, world)
    #: joint impulses (d x bodies) of the impacts and of the steps in which a contact rests
    #: (:meth:`_Landing.tally_joints`; None: not kept)
    joint: np.ndarray | None = None


class _Tally:
    """What a run accumulates, and its result (:class:`_Totals`)."""

    def add(self, totals: _Totals, impulses: np.ndarray, q: np.ndarray, v: np.ndarray,
            vectors: np.ndarray | None = None) -> None:
        """Add stacked contact impulses (:func:`_stacked`, taken at (q, v)) to the totals (none
        changes where every impulse is 0: a flight's step, a projection without rows);
        ``vectors``: their world vectors where known (:meth:`step_vectors`), else along the
        normals and tangents at (q, v)."""
        if not _any(impulses):  # adding zeros leaves every total as it is, to the bit
            return
        fn, ft = _unstacked(impulses, self.nc, self.dims - 1)
        totals.normal += fn
        totals.tangential += ft
        F = vectors if vectors is not None else self.world_vectors(fn, ft, self.point(q, v) if self.sloped else None)
        totals.impulse += F.sum(axis=1)
        totals.vectors += F

    def world_vectors(self, fn: np.ndarray, ft: np.ndarray, pt: _Point | None) -> np.ndarray:
        """Contact impulses (normal ``fn``, tangential ``ft`` per contact) as world vectors (d x n_c),
        along ``pt``'s normals and tangents on sloped ground, else the flat ground's."""
        if self.sloped:
            return contact_vectors(pt.normal, pt.tangent, fn, ft)
        return contact_vectors(*self.flat_ground, fn, ft)

    def add_impact(self, totals: _Totals, event: LandingEvent, q: np.ndarray, v: np.ndarray, v_plus: np.ndarray
                   ) -> None:
        """Add an impact at q from v to ``v_plus`` (``event``) to the totals."""
        impulses = np.concatenate([event.external, np.reshape(event.tangential, (self.nc, -1)).T.ravel()])
        self.add(totals, impulses, q, v)
        self.tally_joints(totals, q, v, q, v_plus, impulses, 0.0, True)

    def segment_normals(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> np.ndarray | None:
        """On a plane's terrain, the normals at a compiled step's end (q, v) in ``mode``, where
        the projection after it keeps every contact on its segment (no valley corner): the
        normals at the projected point, bit for bit (each segment's is a constant), without the
        numpy point :meth:`add` would evaluate there; else None."""
        if not (self.planar and self.sloped) or self.any_seated or mode.has_corner:
            return None
        end = self.ended(q, v, mode)
        return None if end is None else end.normal

    def segment_vectors(self, normal: np.ndarray, impulses: np.ndarray) -> np.ndarray:
        """Stacked contact impulses (:func:`_stacked`) as world vectors along ``normal`` (n_c x d)
        and its tangents."""
        return contact_vectors(normal, tangent_basis(normal), *_unstacked(impulses, self.nc, self.dims - 1))

    def step_vectors(self, q: np.ndarray, v: np.ndarray, p: np.ndarray) -> np.ndarray | None:
        """On a curved heightfield (:attr:`turning`), the last step's impulse vectors
        (:attr:`vectors`) plus those of the projection after it (stacked ``p``, at its end (q,
        v)); elsewhere None."""
        return None if not self.turning else self.vectors + self.stage_vectors(q, v, p)

    def tally_joints(self, totals: _Totals, q0: np.ndarray, v0: np.ndarray, q1: np.ndarray, v1: np.ndarray,
                     impulses: np.ndarray, dt: float, loaded: bool, vectors: np.ndarray | None = None) -> None:
        """Where kept (:attr:`_Totals.joint`) and a contact pushes (``loaded``: an impact, or a
        step with resting contacts), add the joint impulses from (q0, v0) to (q1, v1): each
        subtree's momentum change minus the contact impulses (stacked, at (q1, v1)) on it and its
        weight's over ``dt``, as the compliant rung counts them; ``vectors``: the impulses' world
        vectors where known (:meth:`add`)."""
        if totals.joint is None or not loaded:
            return
        p0 = self.point(q0, v0).momentum.copy()
        pt = self.point(q1, v1)
        if vectors is None:
            vectors = contact_vectors(pt.normal, pt.tangent, *_unstacked(impulses, self.nc, self.dims - 1))
        weight = np.outer(self.weight(dt), self.subtree_mass / self.mass)
        totals.joint += pt.momentum - p0 - vectors @ self.in_subtree.T - weight

    def record(self, totals: _Totals, t0: float, v0: np.ndarray, t1: float, q1: np.ndarray, v1: np.ndarray) -> None:
        """Keep the trajectory and when the model last moved (some |v| >= SETTLE_SPEED): a step
        from (t0, v0) to (t1, v1), or a jump (t0 = t1) at an impact. Where every velocity falls
        below SETTLE_SPEED within a step, the crossing is interpolated linearly (exact under
        constant deceleration)."""
        q0 = q1 if totals.chart_q is None else totals.chart_q
        v0, v1 = world_velocity(q0, v0, self.space), world_velocity(q1, v1, self.space)
        totals.chart_q = q1.copy()
        totals.times.append(t1)
        totals.states.append(self.reported(q1))
        if _largest(np.abs(v1)) >= SETTLE_SPEED:
            totals.moving_until = math.nan  # still moving at t1
        elif math.isnan(totals.moving_until):
            a0, a1 = np.abs(v0), np.abs(v1)
            fast = a0 >= SETTLE_SPEED
            s = float(np.max((a0[fast] - SETTLE_SPEED) / (a0[fast] - a1[fast]), initial=0.0))
            totals.moving_until = t0 + s * (t1 - t0)

    def result(self, totals: _Totals, q: np.ndarray, v: np.ndarray, h: float, energy_before: float,
               energy_final: float, gravity_work: float) -> LandingResult:
        layout = self.layout
        v_world, q = world_velocity(q, v, self.space), self.reported(q)
        base = [q[2]] if self.planar else list(q[3:6])
        angles = base + [b.angle if k is None else q[k] for b, k in zip(self.tree.bodies[1:], layout.body_dof[1:])]
        settled = None if math.isnan(totals.moving_until) else totals.moving_until
        return LandingResult(
            events=tuple(totals.events),
            total_external=totals.normal.copy(),
            total_tangential=self.public_tangential(totals.tangential),
            settled_at=settled,
            q_final=q.copy(),
            v_final=v_world,
            final_angles=np.array(angles, dtype=float),
            energy_before=float(energy_before),
            energy_final=float(energy_final),
            gravity_work=float(gravity_work),
            duration=float(self.scene.duration),
            step=h,
            n_steps=totals.steps,
            integrator=self.method,
            trajectory=(np.array(totals.times), np.array(totals.states)),
            space=self.space.name,
            inexact=self.inexact,
            non_unique=self.non_unique,
            step_code=self.code,
        )
