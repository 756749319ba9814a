"""Why a run failed, in the model file's words: the impact budget's contact, a near-singular
mass matrix, a contact near Painleve's paradox, a stall."""

from __future__ import annotations

import numpy as np

from impulse_core.errors import NumericalError
from impulse_core.timedomain.events.results import LandingEvent
from impulse_core.timedomain.events.point import _any
from impulse_core.timedomain.events.rows import _Mode
from impulse_core.timedomain.events.forces import _contact_forces
from impulse_core.timedomain.events.paradox import JAM_NOTE


#: A mass matrix whose condition number exceeds this is near singular (:meth:`_Landing.singular_note`).
SINGULAR_MASS = 1e8


class _Messages:
    """The messages and notes of a run that failed."""

    def budget_message(self, events: list[LandingEvent], t: float) -> str:
        """Why a run passed its impact budget at ``t``: the contact (or stop) that took most of
        the last thousand impacts, and, where its restitution is 1, that an elastic contact
        pressed to the ground bounces without end (random file 20144: a light base driven down at
        2000 m/s^2 bounced at e = 1 ever faster, 20000 impacts by 18 ms)."""
        recent = events[-1000:]
        external = np.array([e.external for e in recent]) > 0
        stops = np.array([e.stop for e in recent]) != 0
        counts = np.concatenate([external.sum(axis=0), stops.sum(axis=0)])
        k = int(np.argmax(counts))
        head = f"the landing took more than {self.settings.max_events} impacts by t = {t:.6g} s"
        if k < self.nc:
            who, e, field = f"contact {self.contact_labels([k])}", self.e, "scene.restitution"
        else:
            body = self.tree.bodies[k - self.nc + 1]
            e = float(self.per_joint(self.joints.restitution)[k - self.nc])
            who, field = f"the stop of {body.name}", f"{body.name}.stop_restitution"
        note = f": {who} took {counts[k]} of the last {len(recent)}"
        if e >= 1.0:
            note += (f" at restitution {e:g} (an elastic contact pressed to the ground bounces without end: "
                     f"lower {field})")
        return head + note

    def contact_labels(self, contacts) -> str:
        """The contacts (indices) as the model file names them: ``body[k]``, comma-separated."""
        return ", ".join(f"{self.tree.bodies[b].name}[{k}]" for b, k in (self.tree.contacts[int(c)] for c in contacts))

    def singular_note(self, q: np.ndarray) -> str:
        """Why a run diverged at ``q`` where its mass matrix is near singular (condition number
        above SINGULAR_MASS): e.g. rods of zero radius, each spinning about its own axis, which
        moves no mass where a hinge lets them (rods in line; random file 32365: a child's axis in
        the plane of its parent's and the hinge's, 11 degrees apart), spin up without bound as they
        pass that posture; else nothing."""
        cond = float(np.linalg.cond(self.mass_matrix_at(q)))
        if cond <= SINGULAR_MASS:
            return ""
        return (f": its mass matrix is near singular there (condition number {cond:.1e}: a motion with almost no "
                "inertia, e.g. rods of zero radius spinning about their own axes, where they lie in line or a "
                "child's axis lies in the plane of its parent's and its hinge's); give the rods a radius")

    def paradox_note(self) -> str:
        """Where a run that diverged had met Painleve's paradox before (its last impulsive jam, taken
        or tried), that and the remedy; else nothing (random file 61227: its run at h / 8 diverged
        1.9 ms after a jam, in a mode no jam note explains)."""
        if not self._jams[1]:
            return ""
        return (f", after Painleve's paradox at t = {self._jams[0]:.6g} s (an impulsive jam taken or tried there: "
                f"friction {self.mu:g} takes a sliding contact's effective mass to 0): lower the friction")

    def jam_note(self, q: np.ndarray, v: np.ndarray, mode: _Mode) -> str:
        """Why a run diverged at (q, v) in ``mode`` where a closed sliding contact is pressed
        while its row's effective inverse mass with friction along the slip, A = n M^-1 (n - mu u
        t)^T, has fallen below JAM_NOTE of its frictionless n M^-1 n^T: its force -B / A grows
        without bound as A reaches 0 (Painleve's paradox approached while sliding; Genot and
        Brogliato 1999, Or and Rimon 2012), which no step resolves (random file 40029: at every
        step of the halving, A fell from 0.46 of it at 0.11 s to 2e-6..1e-8 at 0.1423 s, the force
        from 74 N to 1e5-1e9 N); else nothing."""
        contact, ratio = self.near_jam(q, v, mode)
        if not contact.size:
            return ""
        return (f": contacts {self.contact_labels(contact)} slide pressed where their rows' effective mass "
                f"with friction {self.mu:g} has nearly vanished (n M^-1 (n - mu u t)^T at "
                f"{float(np.min(ratio)):.1e} of its frictionless value): Painleve's paradox ahead, the "
                "contact force growing without bound (a dynamic jam, which the landing could not take here: it jams "
                "one sliding contact at a time, by a slide that stops its slip): lower the friction")

    def near_jam(self, q: np.ndarray, v: np.ndarray, mode: _Mode, below: float = JAM_NOTE
                 ) -> tuple[np.ndarray, np.ndarray]:
        """The closed sliding contacts that ``mode`` presses (force above the tolerance) where
        their row's A = n M^-1 (n - mu u t)^T is below ``below`` times n M^-1 n^T (JAM_NOTE:
        :meth:`jam_note`; JAM_WATCH: :meth:`run`'s watch), and those ratios."""
        none = np.zeros(0, int), np.zeros(0)
        if not self.mu or not _any(mode.sliding & mode.closed):
            return none
        try:
            contact, A, A0, fn = self.sliding_rows(q, v, mode)
        except (NumericalError, np.linalg.LinAlgError):
            return none
        ratio = A / A0
        near = (ratio < below) & mode.sliding[contact] & (fn > self.force_tol)
        return contact[near], ratio[near]

    def sliding_rows(self, q: np.ndarray, v: np.ndarray, mode: _Mode
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The contacts of ``mode``'s normal rows at (q, v), each row's effective inverse mass
        with its friction along the slip, A = n M^-1 (n - mu u t)^T (n M^-1 n^T where it sticks),
        its frictionless one n M^-1 n^T, and the mode's normal force on it."""
        pt = self.point(q, v)
        rows, (_, lam) = self.mode_solution(pt, mode)
        fn = _contact_forces(rows, lam, self.mu, self.nc)[0]
        c = np.flatnonzero(rows.contact[: rows.n] >= 0)
        contact, G = rows.contact[c], rows.G[c]
        A = np.einsum("ij,ji->i", G, np.linalg.solve(pt.M, rows.F[c].T))
        return contact, A, np.einsum("ij,ji->i", G, np.linalg.solve(pt.M, G.T)), fn[contact]

    def stall_message(self, q: np.ndarray, v: np.ndarray, mode: _Mode, t: float) -> str:
        """Why events stopped making progress at (q, v): Painleve's paradox where a sliding
        contact has no consistent force (:meth:`painleve`), else chatter."""
        jammed = self.painleve(q, v, mode)
        if not jammed.size:
            pt = self.point(q, v)
            against = np.flatnonzero(self.wrong_slip(pt, v, mode, 0.0)[0]) if self.mu > 0 else []
            note = "" if not len(against) else (
                f": contacts {self.contact_labels(against)} start to slide from rest against their own slip "
                "acceleration in the mode (no slip direction found that it follows)")
            if not note and self.refused.size:
                note = (f": the slow slip of contacts {self.contact_labels(self.refused)} turns at each event, and "
                        "the mode with them sticking does not hold (not arrested)")
            return f"the landing chatters at t = {t:.6g} s (events without progress{note})"
        return self.painleve_message(t, jammed, f"friction {self.mu:g} makes their rows' effective mass negative")

    def painleve_message(self, t: float, contacts: np.ndarray, why: str) -> str:
        """Painleve's paradox at ``t``: the sliding ``contacts`` have no consistent contact
        force, ``why``."""
        return (f"Painleve's paradox at t = {t:.6g} s: contacts {self.contact_labels(contacts)} slide with no "
                f"consistent contact force ({why}; rigid bodies then need an impulsive jam, which the landing could "
                "not take here: it jams one sliding contact at a time, by a slide that stops its slip): lower the "
                "friction")
