"""Contact modes and their constraint rows: a mode (:class:`_Mode`: each contact open, sticking or
sliding, each joint free or on a stop) gives the rows G a + b = 0 and their forces F^T lambda
(:class:`_Rows`, :func:`_mode_rows`) at a point; :mod:`.forces` solves them."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from impulse_core.timedomain.events.point import _Point, _along, _any


@dataclass
class _Mode:
    """Which rows are closed between two events."""

    closed: np.ndarray  # bool per contact: resting on the ground
    #: per contact (n_c x (d - 1)): 0 sticking (or frictionless), else the unit slip direction in
    #: its tangent basis (the plane: +-1 sliding along +-t); a 1-D array is the plane's signs
    slip: np.ndarray
    stop: np.ndarray  # int per DOF: 0 free, -1 resting on its lower stop, +1 on its upper
    #: the rows are redundant (e.g. two identical toes sticking on one point): their forces are
    #: the least-norm split (:data:`REDUNDANT`), which is the symmetric one between identical toes
    redundant: bool = False
    #: per contact: the slip speed (m/s) below which its sliding friction's direction is
    #: regularised (:func:`slip_direction`, :meth:`_Landing.steer`); None: 0, exact
    core: np.ndarray | None = None
    #: per contact: -1, or the index of the plane's valley breakpoint where it rests held by both
    #: adjacent segments (two normal rows, :func:`_corner_rows`); None: -1 for every contact
    corner: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.slip.ndim == 1:
            self.slip = self.slip.astype(float)[:, None]
        if self.core is None:
            self.core = np.zeros(len(self.closed))
        if self.corner is None:
            self.corner = np.full(len(self.closed), -1)

    def copy(self) -> _Mode:
        return _Mode(self.closed.copy(), self.slip.copy(), self.stop.copy(), self.redundant, self.core.copy(),
                     self.corner.copy())

    @property
    def cornered(self) -> np.ndarray:
        """Per contact: resting in a valley corner (:attr:`corner`)."""
        return self.corner >= 0

    @property
    def has_corner(self) -> bool:
        """Whether some contact rests in a valley corner (``cornered.any()``, in Python ints: the
        step loop asks it a few times a step)."""
        return max(self.corner.tolist(), default=-1) >= 0

    @property
    def sliding(self) -> np.ndarray:
        """Per contact: whether it slides."""
        return (self.slip != 0).any(axis=1)

    @property
    def side(self) -> np.ndarray:
        """The plane's slip per contact: 0, or +-1 sliding along +-t."""
        return np.sign(self.slip[:, 0]).astype(int)


@dataclass(frozen=True)
class _Rows:
    """Constraint rows of a mode: velocity rows G (normal rows first, then the tangent rows: the
    first tangent of every sticking contact, then, in space, the second's), force rows F (= G but
    for sliding contacts), (dG/dt) v, and what each row is."""

    G: np.ndarray
    F: np.ndarray
    b: np.ndarray
    contact: np.ndarray  # per normal row: its contact, or -1 for a stop
    dof: np.ndarray  # per normal row: its DOF (stops), or -1
    owner: np.ndarray  # per sticking contact (its d - 1 tangent rows): its normal row
    mu: np.ndarray  # per sticking contact
    #: per contact (n_c x (d - 1)): the unit direction its sliding friction opposes, or 0
    direction: np.ndarray = field(default_factory=lambda: np.zeros((0, 1)))
    redundant: bool = False  # the mode's rows are redundant: least-norm forces
    #: per normal row, whether it is one of a valley corner's two rows (:func:`_corner_rows`), and
    #: its direction's components along its contact's normal and tangent at the point (n x 2); None:
    #: no corner, every contact row along its contact's normal
    cornered: np.ndarray | None = None
    turn: np.ndarray | None = None

    @property
    def n(self) -> int:
        return len(self.contact)


def slip_direction(pt: _Point, slip: np.ndarray, core: np.ndarray | None = None) -> np.ndarray:
    """Per contact, the direction u of its sliding friction's slip: the current slip velocity's
    s / |s| while it points along the mode's ``slip`` d (s . d > 0) and |s| exceeds the resting
    threshold, else d (a contact starting to slide, or one whose slip reverses: an event). Below
    the speed ``core`` (per contact; 0: none) u = (s + (core - |s|) d) / |...|: the lateral
    sensitivity of the direction, mu f_n / |s|, is capped at mu f_n / core (see
    :meth:`_Landing.steer`). In the plane u is the mode's +-1 in every case (the plane's
    fixed-direction force); in space it turns with the slip."""
    if slip.shape[1] == 1:
        return slip
    speed = np.linalg.norm(pt.slip, axis=1, keepdims=True)
    along = (np.sum(pt.slip * slip, axis=1, keepdims=True) > 0) & (speed > pt.slip_floor)
    lifted = pt.slip if core is None else pt.slip + np.maximum(core[:, None] - speed, 0.0) * slip
    size = np.linalg.norm(lifted, axis=1, keepdims=True)
    current = np.divide(lifted, size, out=np.zeros_like(pt.slip), where=along)
    return np.where(along, current, slip)


def _corner_rows(pt: _Point, contacts: np.ndarray, normals: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The two rows of each contact resting in a plane's valley corner: ``contacts`` (m indices),
    ``normals`` (m x 2 x 2: the left and right segments' outward unit normals). A row along a
    world direction u of the contact's velocity is u . J = (u . n) J_n + (u . t) J_t (n, t the
    point's orthonormal normal and tangent there), its bias likewise. Returns G (2m x nv: each
    contact's left row, then its right row), b (2m) and the rows' (u . n, u . t) (2m x 2)."""
    n, t = pt.normal[contacts], pt.tangent[contacts, 0]
    u = normals.reshape(-1, 2)  # left, right per contact
    c = np.repeat(contacts, 2)
    turn = np.column_stack([np.sum(u * np.repeat(n, 2, axis=0), axis=1), np.sum(u * np.repeat(t, 2, axis=0), axis=1)])
    G = turn[:, :1] * pt.Jn[c] + turn[:, 1:] * pt.Jt[c, 0]
    b = turn[:, 0] * pt.bn[c] + turn[:, 1] * pt.bt[c, 0]
    return G, b, turn


def _rows(pt: _Point, contacts: np.ndarray, slip: np.ndarray, stops: np.ndarray, mu: float, nv: int,
          core: np.ndarray | None = None, corners: tuple[np.ndarray, np.ndarray] | None = None) -> _Rows:
    """Rows for the given contacts (indices; ``slip`` per contact, n_c x (d - 1)), stops (DOF ->
    side, dict-like array: 0 none) and friction coefficient; tangent rows for non-sliding contacts
    when mu > 0; a sliding contact's force row is n - mu u^T t along its slip direction u
    (:func:`slip_direction`). ``corners``: (contacts, their segments' normals m x 2 x 2) resting in
    a valley corner, two frictionless normal rows each after the other contacts' (:func:`_corner_rows`;
    the two normals fix the point in the plane, so a tangent row would be redundant, and with
    both rows pushing no friction is needed: friction acts once one row is released)."""
    if corners is not None and len(corners[0]):
        return _with_corners(_rows(pt, contacts, slip, stops, mu, nv, core), pt, contacts, *corners)
    dofs = np.flatnonzero(stops)
    G_stop = np.zeros((len(dofs), nv))
    G_stop[np.arange(len(dofs)), dofs] = -stops[dofs]
    direction = slip_direction(pt, slip, core) if mu > 0 else np.zeros_like(slip)
    sliding = direction[contacts]
    Fn = pt.Jn[contacts] - _along(mu * sliding, pt.Jt[contacts])
    sticking = contacts[~(sliding != 0).any(axis=1)] if mu > 0 else contacts[:0]
    tangent_rows = pt.Jt[sticking].transpose(1, 0, 2).reshape(-1, nv)
    G = np.vstack([pt.Jn[contacts], G_stop, tangent_rows])
    F = np.vstack([Fn, G_stop, tangent_rows])
    b = np.concatenate([pt.bn[contacts], np.zeros(len(dofs)), pt.bt[sticking].T.ravel()])
    owner = np.searchsorted(contacts, sticking)
    return _Rows(
        G, F, b,
        np.concatenate([contacts, -np.ones(len(dofs), int)]),
        np.concatenate([-np.ones(len(contacts), int), dofs]),
        owner, np.full(len(sticking), mu), direction,
    )


def _with_corners(rows: _Rows, pt: _Point, contacts: np.ndarray, cornered: np.ndarray, normals: np.ndarray) -> _Rows:
    """``rows`` (of ``contacts``) with the corner rows of ``cornered`` (:func:`_corner_rows`)
    inserted after the contacts' normal rows."""
    Gc, bc, turn = _corner_rows(pt, cornered, normals)
    k, m = len(contacts), len(Gc)
    G = np.vstack([rows.G[:k], Gc, rows.G[k:]])
    F = np.vstack([rows.F[:k], Gc, rows.F[k:]])
    b = np.concatenate([rows.b[:k], bc, rows.b[k:]])
    n = rows.n
    flags = np.zeros(n + m, bool)
    flags[k : k + m] = True
    axes = np.zeros((n + m, 2))
    axes[:, 0] = 1.0
    axes[k : k + m] = turn
    return replace(
        rows, G=G, F=F, b=b,
        contact=np.concatenate([rows.contact[:k], np.repeat(cornered, 2), rows.contact[k:]]),
        dof=np.concatenate([rows.dof[:k], -np.ones(m, int), rows.dof[k:]]),
        cornered=flags, turn=axes,
    )


def _mode_bytes(mode: _Mode) -> bytes:
    """What of a mode a compiled step depends on, as bytes (:meth:`_Landing.ended`; a mode with a
    corner, which no compiled step takes, also names its corners). The corners are always in the
    key: within one landing its arrays keep their lengths and a corner-free mode's are all -1, so
    two keys are equal exactly where they were with the corners named only where some contact has
    one (two reductions cheaper; the key is asked about nine times a step)."""
    return b"".join((mode.closed.tobytes(), mode.slip.tobytes(), mode.stop.tobytes(), bytes([mode.redundant]),
                     mode.corner.tobytes()))


def _rests(mode: _Mode) -> bool:
    """Some contact is closed or some joint rests on a stop (the mode has rows)."""
    return bool(_any(mode.closed) or _any(mode.stop))


def _mode_rows(pt: _Point, mode: _Mode, mu: float, valleys: np.ndarray | None = None) -> _Rows:
    """The mode's rows at ``pt``; ``valleys``: per breakpoint of the plane's terrain its two
    segments' normals (:attr:`_Landing.valleys`), for the mode's contacts resting in a corner."""
    if valleys is not None and mode.has_corner:
        cornered = np.flatnonzero(mode.closed & mode.cornered)
        contacts = np.flatnonzero(mode.closed & ~mode.cornered)
        rows = _rows(pt, contacts, mode.slip, mode.stop, mu, pt.M.shape[0], mode.core,
                     (cornered, valleys[mode.corner[cornered]]))
    else:
        rows = _rows(pt, np.flatnonzero(mode.closed), mode.slip, mode.stop, mu, pt.M.shape[0], mode.core)
    return replace(rows, redundant=True) if mode.redundant else rows


def _same_kind(a: _Mode, b: _Mode) -> bool:
    """The same contacts closed, the same sliding, the same stops (slip directions aside)."""
    return bool(np.array_equal(a.closed, b.closed) and np.array_equal(a.sliding, b.sliding)
                and np.array_equal(a.stop, b.stop))
