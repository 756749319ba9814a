"""The settled posture of random legs: footopt's whole landing against MuJoCo's (issue #13's check).

Issue #13: "Outside checks will compare ... the settled posture of hidden legs with MuJoCo (2e-3
rad)". The legs: seeded random planar trees that can come to rest, a plank (the base, 0.3-0.8 m,
1-3 kg) landing flat on its two ends with one to three sprung, damped chains of one or two rods
on it (each joint's spring a random 2-5 times the gravity torque of the rods it carries, its rest
angle near the touchdown angle); restitution 0-0.3, friction 0, 0.5 or 1, straight down at 0.3-1.5
m/s, 3 s. With ``--tips`` the chains hang below the plank and land on their tips (a body on
sprung legs: it lands on the lowest tips and comes to rest on its legs or its ends). With
``--spatial`` the legs are spatial (:func:`random_spatial_leg`: a body with a welded cross rod,
resting on a triangle, standing on three or four sprung chains splayed around it, landing on their
tips) and footopt lands them with ``space=SPATIAL``; their final posture is compared frame-free:
the angle of the relative rotation between the two final base orientations (and its tilt alone,
:func:`posture_gaps`) and each joint angle (settled_posture_spatial.md), and each final state is
put into footopt's statics (:func:`statics`). Frictionless they agree (joints and tilt within
6e-5 rad on 19 of 20, the base's free turn about the vertical, a geometric phase of the joints'
path, within 3.3e-3); with friction both reach rests, different ones (README: the paths part at
the impacts with friction; on the two legs tried MuJoCo's answer stays put from 1e6 to 1e9
1/s^2).

- footopt: ``landing()`` at its defaults (``--tolerance 1e-3``), ``final_angles`` and
  ``settled_at``.
- MuJoCo: ``footopt export``'s MJCF (joint springs, dampers, stops; spatial: its rotations and
  axes, a free base) made droppable as in
  ``speed.py`` (the bridge's 1 mm contact spheres, direct solref at 1e6 1/s^2, elliptic cones with
  friction), ``mj_step`` at 5e-5 s over the same 3 s, its final absolute base angle and joint
  angles in footopt's order. ``--mujoco`` compares with other contact settings, one column each
  (:class:`MujocoSettings`: stiffness, sphere radius, the friction rows' damping, impratio,
  noslip iterations); the default stays the bridge's, which the planks' table used.

Both are the same statics once at rest (springs, gravity, the ground), so the postures agree
where the rest is unique: frictionless, or where friction holds the contacts from the first touch.
A leg whose contacts slide on the way to rest may stop elsewhere (the slide's length depends on
the contact law during the impacts: rigid here, soft in MuJoCo), and its base angle with it.

No MuJoCo setting is footopt's contact law, so none is the default (settled_posture_tips.md:
none brings the legs with friction within 2e-3, and MuJoCo's own answer moves by more than that
between 1e8 and 1e9 1/s^2 on 7 of the 20 legs). A tip leaves seed 6's first impact
slipping at 5.1, 2.3, 0.72, 0.23 cm/s at 1e6, 1e7, 1e8, 1e9 (footopt's rigid impact: stuck):
at 1e6 mostly MuJoCo's friction rows, which relax a slip at the contact damping's rate (with
their damping at 1 / h: 0.50 cm/s), from 1e8 on the soft impact's length alone (the same with
the friction rows at 1 / h), in which the springs and gravity slide the tip while its normal
force fades. Stiffer friction rows (``fd``) make a sliding tip glide above the ground
(MuJoCo's convex cone: 0.38 mm on seed 0 resting at 1e7, fd 1), and ``impratio`` and
``noslip`` hardly change the gaps. The small sphere (``r``
1e-5) is the point contact's closest model: a 1 mm sphere rolls with its rod (seed 13 resting
on its tip for 0.2 s: 3.2e-3 rad at 1 mm, 3.3e-4 at 0.01 mm, settled_posture_resting.md).
``--resting`` tests the friction between impacts alone (:func:`compare_resting`).

Run: python studies/whole_landing/settled_posture.py [--seeds 20] [--tips | --spatial] [--mujoco SPEC ...]
[--resting] [--limit S]  (writes settled_posture[_tips|_spatial][_resting].md next to this file)
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import time
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from impulse_core.kinematics.spatial import PLANAR, SPATIAL, Space
from impulse_core.model.joints import JointLaw
from impulse_core.model.tree import Body, JointKind, Scene, Tree
from impulse_core.timedomain.compliant import chart_rotation
from impulse_core.timedomain.events.run import _Landing
from impulse_core.timedomain.landing import LandingSettings, landing
from optimizer.validation.mujoco_bridge import CONTACT_RADIUS

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from speed import Mujoco  # noqa: E402 - the speed study's MuJoCo landing (same export, same contacts)

G = 9.81
DURATION = 3.0
STIFFNESS = 1e6  # MuJoCo's contact stiffness, 1/s^2: a sag of g / k = 1e-5 m
STEP = 5e-5  # MuJoCo's step, s
FREE = JointLaw()


def random_leg(seed: int, tips: bool) -> tuple[Tree, tuple[JointLaw, ...], Scene]:
    """A plank on its two ends with 1-3 sprung chains of 1-2 rods (contacts at their tips if ``tips``)."""
    rng = np.random.default_rng(seed)
    bodies = [Body("plank", None, rng.uniform(0.3, 0.8), rng.uniform(1.0, 3.0), 0.0, contacts=(0.0, 1.0))]
    laws = [FREE]
    for c in range(int(rng.integers(1, 4))):
        links = int(rng.integers(1, 3))
        parent, at = 0, rng.uniform(0.1, 0.9)
        for k in range(links):
            length, mass = rng.uniform(0.1, 0.4), rng.uniform(0.05, 0.5)
            angle = (-1 if tips else 1) * rng.uniform(0.6, 2.5) if k == 0 else rng.uniform(-0.8, 0.8)
            tip = (1.0,) if tips and k == links - 1 else ()
            bodies.append(Body(f"chain{c}_{k}", parent, length, mass, angle, at=at, contacts=tip))
            laws.append(None)  # the spring below, once the rods it carries are known
            parent, at = len(bodies) - 1, 1.0
    tree = Tree(tuple(bodies))
    for i in range(1, len(bodies)):  # each spring 2-5 x the gravity torque of what it carries
        carried = [j for j in range(i, len(bodies)) if _below(tree, j, i)]
        torque = sum(bodies[j].mass for j in carried) * G * bodies[i].length
        laws[i] = JointLaw(stiffness=rng.uniform(2, 5) * torque, damping=rng.uniform(0.05, 0.3) * math.sqrt(torque),
                           rest=bodies[i].angle + rng.uniform(-0.3, 0.3))
    scene = Scene(speed=rng.uniform(0.3, 1.5), restitution=rng.uniform(0.0, 0.3),
                  friction=float(rng.choice([0.0, 0.5, 1.0])), gravity=G, duration=DURATION)
    return tree, tuple(laws), scene


def _below(tree: Tree, j: int, i: int) -> bool:
    """Body j is i or hangs from it."""
    while j is not None and j != i:
        j = tree.bodies[j].parent
    return j == i


#: the spatial legs' rods' radius (m): an axial inertia, so that no rod spins freely about its axis
RADIUS = 0.01


def random_spatial_leg(seed: int) -> tuple[Tree, tuple[JointLaw, ...], Scene]:
    """A body standing on 3-4 sprung chains splayed around it (``--spatial``): the base, a rod
    along x (0.3-0.8 m, 1-3 kg) with a cross rod welded at its middle along +z (0.2-0.5 m,
    0.2-0.8 kg), contacts at the plank's two ends and the cross's tip (a triangle it can rest
    on); each chain of one or two rods (0.1-0.3 m, 0.05-0.4 kg, radius :data:`RADIUS`) hangs
    from a random point of the plank, its first rod turned about the vertical to an azimuth
    spread around the body (2 pi c / n +- 0.4 rad) and rolled by up to 0.3 rad about itself (its
    hinge axis out of the horizontal), pointing 0.4-1.2 rad below the horizontal, the second
    rod turned by up to 0.3 rad in roll and pitch and bent by up to 0.8 rad; the contact at each
    chain's tip. Each joint's spring is a random 2-5 times the gravity torque it carries (the
    rods below it and the base's weight shared among the chains, over its rod's length), its
    damper 0.05-0.3 x sqrt of that torque, its rest within 0.3 rad of the touchdown angle. The
    scene as :func:`random_leg`'s: restitution 0-0.3, friction 0, 0.5 or 1, straight down at
    0.3-1.5 m/s, 3 s."""
    rng = np.random.default_rng(seed)
    plank, cross = rng.uniform(0.3, 0.8), rng.uniform(0.2, 0.5)
    bodies = [Body("base", None, plank, rng.uniform(1.0, 3.0), 0.0, contacts=(0.0, 1.0), radius=RADIUS),
              Body("cross", 0, cross, rng.uniform(0.2, 0.8), 0.0, at=0.5, joint=JointKind.FIXED,
                   rpy=(0.0, -math.pi / 2, 0.0), contacts=(1.0,), radius=RADIUS)]
    chains = int(rng.integers(3, 5))
    share = (bodies[0].mass + bodies[1].mass) / chains
    start = rng.uniform(0.0, 2.0 * math.pi)
    for c in range(chains):
        links = int(rng.integers(1, 3))
        parent, at = 0, rng.uniform(0.1, 0.9)
        for k in range(links):
            length, mass = rng.uniform(0.1, 0.3), rng.uniform(0.05, 0.4)
            if k == 0:
                rpy = (rng.uniform(-0.3, 0.3), start + 2.0 * math.pi * c / chains + rng.uniform(-0.4, 0.4), 0.0)
                angle = -rng.uniform(0.4, 1.2)
            else:
                rpy, angle = (rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), 0.0), rng.uniform(-0.8, 0.8)
            tip = (1.0,) if k == links - 1 else ()
            bodies.append(Body(f"chain{c}_{k}", parent, length, mass, angle, at=at, contacts=tip, rpy=rpy,
                               radius=RADIUS))
            parent, at = len(bodies) - 1, 1.0
    tree = Tree(tuple(bodies))
    laws = [FREE, FREE]
    for i in range(2, len(bodies)):
        carried = sum(bodies[j].mass for j in range(i, len(bodies)) if _below(tree, j, i)) + share
        torque = carried * G * bodies[i].length
        laws.append(JointLaw(stiffness=rng.uniform(2, 5) * torque, damping=rng.uniform(0.05, 0.3) * math.sqrt(torque),
                             rest=bodies[i].angle + rng.uniform(-0.3, 0.3)))
    scene = Scene(speed=rng.uniform(0.3, 1.5), restitution=rng.uniform(0.0, 0.3),
                  friction=float(rng.choice([0.0, 0.5, 1.0])), gravity=G, duration=DURATION)
    return tree, tuple(laws), scene


@dataclass(frozen=True)
class MujocoSettings:
    """MuJoCo's contact settings for one comparison (``--mujoco``: ``k=1e7,r=1e-5,fd=1,impratio=100,noslip=30``).

    Attributes:
        stiffness: the contacts' direct stiffness (1/s^2; ``k``); their damping gives each leg's
            restitution (the bridge's ``contact_parameters``).
        radius: the contact spheres' radius (m; ``r``). The bridge's 1 mm sphere rolls on the
            ground with its rod: a sticking tip moves r x the rod's turn (a point contact does
            not).
        friction_damping: 0 (``fd``; MuJoCo's default): the friction rows take the contact's
            solref, whose reference acceleration for a friction row is -b v_t alone (b: the
            contact damping, ~ sqrt(k)), so a tip's slip relaxes at the rate b, over a time
            as long as the impact's. f > 0: the contacts as explicit ``<pair>``s with
            ``solreffriction`` damping f / h (h the step; f = 1 stops a slip in one step).
        impratio: ``<option impratio>`` (elliptic cones: the friction rows' impedance over the
            normal's).
        noslip: ``<option noslip_iterations>`` (MuJoCo's post-processing that removes the
            friction rows' slip within a step).
    """

    stiffness: float = STIFFNESS
    radius: float = CONTACT_RADIUS
    friction_damping: float = 0.0
    impratio: float = 1.0
    noslip: int = 0

    KEYS = {"k": "stiffness", "r": "radius", "fd": "friction_damping", "impratio": "impratio", "noslip": "noslip"}

    @classmethod
    def parse(cls, spec: str) -> MujocoSettings:
        """``key=value,...`` (keys: :attr:`KEYS`); an empty spec is the bridge's settings."""
        values: dict = {}
        for item in filter(None, spec.split(",")):
            key, _, value = item.partition("=")
            if key.strip() not in cls.KEYS:
                raise SystemExit(f"--mujoco: {key!r} is not one of {', '.join(cls.KEYS)}")
            name = cls.KEYS[key.strip()]
            values[name] = int(value) if name == "noslip" else float(value)
        return cls(**values)

    @property
    def label(self) -> str:
        parts = [f"k {self.stiffness:g}", f"r {self.radius * 1e3:g} mm"]
        parts += [f"friction damping {self.friction_damping:g}/h"] if self.friction_damping else []
        parts += [f"impratio {self.impratio:g}"] if self.impratio != 1.0 else []
        parts += [f"noslip {self.noslip}"] if self.noslip else []
        return ", ".join(parts)


class StudyMujoco(Mujoco):
    """The speed study's MuJoCo landing with the study's contacts. Planar: the base held in the
    plane (slides along x and y, a hinge about z) instead of the export's free joint: a plank on
    two points of its axis is a line contact, about which a free body in MuJoCo topples sideways
    (its roll, unstable, grows from rounding within 2 s), a motion the planar model does not
    have. Spatial (``space``): the export's free joint. ``settings``: the contacts'
    (:class:`MujocoSettings`); the step: ``step``, or 0.2 / the contacts' damping (1/s) if
    shorter: MuJoCo's step takes the damper explicitly, and at h x damping > 1 a nearly plastic
    contact (e -> 0: damping -> infinity) throws the leg back up faster than it came (the study's
    first run: e = 0.0008, 1.7)."""

    def __init__(self, model, settings: MujocoSettings = MujocoSettings(),  # type: ignore[no-untyped-def]
                 step: float = STEP, space: Space = PLANAR) -> None:
        import mujoco

        super().__init__(model, settings.stiffness, space)
        self.space = space
        base = model.tree.bodies[0].name
        if space is PLANAR:
            planar = (f'<joint name="{base}_x" type="slide" axis="1 0 0" /><joint name="{base}_y" type="slide" '
                      f'axis="0 1 0" /><joint name="{base}" type="hinge" axis="0 0 1" />')
            self.text = self.text.replace(f'<freejoint name="{base}" />', planar, 1)
        damping = float(np.max(-np.array([float(g.split()[1]) for g in _solrefs(self.text)])))
        self.h = min(step, 0.2 / damping)
        self.text = _with_contacts(self.text, settings, self.h)
        self.m = mujoco.MjModel.from_xml_string(self.text)
        self.m.opt.tolerance, self.m.opt.iterations, self.m.opt.ls_tolerance = 1e-8, 100, 0.01
        self.m.opt.impratio, self.m.opt.noslip_iterations = settings.impratio, settings.noslip
        joint = self.m.joint(f"{base}_x" if space is PLANAR else base)
        self.base_q, self.base_v = joint.qposadr[0], joint.dofadr[0]

    def angles(self, d) -> np.ndarray:  # type: ignore[no-untyped-def]
        """footopt's ``final_angles`` at MuJoCo's state d: planar, the base's absolute angle;
        spatial, the rotation vector of the base's turn since touchdown (world frame, as
        footopt's phi); then the joint angles in footopt's order."""
        if self.space is PLANAR:
            angles = self.touchdown.copy()
            angles[0] += d.qpos[self.base_q + 2]
        else:
            angles = np.concatenate([np.zeros(3), self.touchdown[1:]])
            angles[:3] = _rotation_vector(_quaternion_matrix(d.qpos[self.base_q + 3: self.base_q + 7])
                                          @ _quaternion_matrix(self.m.qpos0[self.base_q + 3: self.base_q + 7]).T)
        shift = 0 if self.space is PLANAR else 2
        for i, name in zip(self.revolute, self.joints):
            angles[i + shift] += d.qpos[self.m.joint(name).qposadr[0]]
        return angles

    def final_state(self) -> tuple[np.ndarray, float]:
        """The angles after the landing (:meth:`angles`) and the largest generalized speed then
        (rad/s or m/s: at rest, ~0)."""
        d, n = self.start(self.h)
        for _ in range(n):
            self.mj.mj_step(self.m, d)
        self.final = d
        return self.angles(d), float(np.max(np.abs(d.qvel)))

    def configuration(self, d, q0: np.ndarray) -> np.ndarray:  # type: ignore[no-untyped-def]
        """A spatial landing's q (footopt's: base origin, rotation vector, revolute joints' angles;
        ``q0`` its touchdown) at MuJoCo's state d."""
        angles = self.angles(d)
        q = q0.copy()
        q[:3] += d.qpos[self.base_q: self.base_q + 3] - self.m.qpos0[self.base_q: self.base_q + 3]
        q[3:6] = angles[:3]
        q[6:] = angles[[2 + i for i in self.revolute]]
        return q

    def final_angles(self) -> np.ndarray:
        """The angles after the landing."""
        return self.final_state()[0]


def _quaternion_matrix(quat: np.ndarray) -> np.ndarray:
    """The rotation matrix of MuJoCo's unit quaternion (w, x, y, z)."""
    w, x, y, z = np.asarray(quat, dtype=float) / np.linalg.norm(quat)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _rotation_vector(R: np.ndarray) -> np.ndarray:
    """The rotation vector (angle in [0, pi] times the unit axis) of a rotation matrix."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(R).as_rotvec()


def posture_gaps(ours: np.ndarray, theirs: np.ndarray, space: Space) -> tuple[float, float, float]:
    """The gaps between two final postures (``final_angles``' layout): the base's (planar, its
    angle; spatial, the angle of the relative rotation Exp(ours)^T Exp(theirs) between the two
    orientations, whatever frame either is read in), the same for the base's tilt alone (the
    angle between the vertical seen in the two bases' frames: the turn the statics sets; the
    rest is a turn about the vertical; planar: the base's gap) and the largest joint gap."""
    if space is PLANAR:
        base = float(abs(ours[0] - theirs[0]))
        return base, base, float(np.max(np.abs(ours[1:] - theirs[1:])))
    a, b = np.asarray(chart_rotation(ours[:3])), np.asarray(chart_rotation(theirs[:3]))
    turn = float(np.linalg.norm(_rotation_vector(a.T @ b)))
    up = np.array([0.0, 1.0, 0.0])
    u, w = a.T @ up, b.T @ up
    tilt = float(math.atan2(np.linalg.norm(np.cross(u, w)), float(u @ w)))
    return turn, tilt, float(np.max(np.abs(ours[3:] - theirs[3:])))


def _with_contacts(text: str, settings: MujocoSettings, h: float) -> str:
    """The MJCF text with the contact spheres of ``settings.radius`` (the ground lowered alike, so
    that a sphere touches it where its centre, the contact point, is at height 0) and, with
    ``settings.friction_damping``, each sphere's contact with the ground as an explicit pair
    (same condim, friction, solref, solimp; the sphere's own contacts off) with solreffriction."""
    import xml.etree.ElementTree as ET

    root = ET.fromstring(text)
    spheres = [g for g in root.iter("geom") if (g.get("name") or "").startswith("contact")]
    for g in spheres:
        g.set("size", repr(settings.radius))
    ground = next(g for g in root.iter("geom") if g.get("name") == "ground")
    ground.set("pos", f"0 {-settings.radius!r} 0")
    if settings.friction_damping and all(g.get("friction") for g in spheres):  # frictionless: no friction rows
        contact = ET.SubElement(root, "contact")
        for g in spheres:
            g.set("contype", "0")
            mu = g.get("friction").split()[0]
            ET.SubElement(contact, "pair", geom1="ground", geom2=g.get("name"), condim=g.get("condim"),
                          friction=f"{mu} {mu} 0 0 0", solref=g.get("solref"), solimp=g.get("solimp"),
                          solreffriction=f"-1 {-settings.friction_damping / h!r}")
    return ET.tostring(root, encoding="unicode")


def _solrefs(text: str) -> list[str]:
    """The contacts' direct solref pairs ("-k -b") in an MJCF text."""
    import re

    return re.findall(r'solref="(-[^"]+)"', text)


def compare(seed: int, tips: bool, friction: float | None = None,
            settings: tuple[MujocoSettings, ...] = (MujocoSettings(),), spatial: bool = False,
            limit: float = 0.0) -> dict:
    """footopt's final angles for one leg (``spatial``: :func:`random_spatial_leg`'s, else
    :func:`random_leg`'s; ``friction``: instead of the leg's) against MuJoCo's at each of
    ``settings``: the gap in the base's orientation (:func:`posture_gaps`; with its tilt alone)
    and the largest in the joint angles, per setting, and how fast MuJoCo's last setting and
    footopt still move at the end (largest generalized speed). ``limit`` > 0: footopt's landing
    stopped after that many seconds (:class:`TooLong`)."""
    tree, laws, scene = random_spatial_leg(seed) if spatial else random_leg(seed, tips)
    space = SPATIAL if spatial else PLANAR
    scene = scene if friction is None else replace(scene, friction=friction)
    start = time.perf_counter()
    with _time_limit(limit):
        ours = landing(tree, scene, laws, LandingSettings(), space=space)
    seconds = time.perf_counter() - start
    model = SimpleNamespace(tree=tree, scene=scene, joints=laws)
    runs = [StudyMujoco(model, s, space=space) for s in settings]
    finals = [mj.final_state() for mj in runs]
    theirs = [a for a, _ in finals]
    gaps = [posture_gaps(ours.final_angles, a, space) for a in theirs]
    spread = max(posture_gaps(theirs[-1], theirs[-2], space)) if len(theirs) > 1 else math.nan
    row = {"seed": seed, "bodies": len(tree.bodies), "contacts": len(tree.contacts), "friction": scene.friction,
            "restitution": scene.restitution, "settled_at": ours.settled_at, "events": len(ours.events),
            "base": [g[0] for g in gaps], "tilt": [g[1] for g in gaps], "joints": [g[2] for g in gaps],
            "spread": spread, "converged": ours.converged, "speed_ours": float(np.max(np.abs(ours.v_final))),
            "speed_theirs": finals[-1][1], "seconds": seconds}
    if spatial:  # both final states in footopt's statics
        run = _Landing(tree, scene, laws, LandingSettings(), space)
        row["statics_ours"] = statics(run, ours.q_final, scene.friction)
        row["statics_theirs"] = statics(run, runs[-1].configuration(runs[-1].final, run.q0), scene.friction)
    return row


#: a contact within this of the ground (m) may carry force in :func:`statics` (MuJoCo's contacts sag
#: g / k = 1e-5 m into the ground)
ON_GROUND = 1e-4


def statics(run, q: np.ndarray, friction: float, sides: int = 16) -> float:  # type: ignore[no-untyped-def]
    """Whether q is a rest of ``run``'s leg (:class:`_Landing`): the smallest largest residual
    generalized force of gravity and the springs at q (at rest: no dampers) against forces at the
    contacts within :data:`ON_GROUND` of the ground, normal >= 0 and tangential inside the friction
    cone (a regular polygon of ``sides`` inscribed in it: conservative), over the weight (m: a
    torque over the weight is a length); a linear program. ~0: a rest."""
    from scipy.optimize import linprog

    pt, weight = run.point(q, np.zeros_like(q)), run.mass * run.scene.gravity
    on = np.flatnonzero(pt.gap < ON_GROUND)
    m, nt = len(on), (pt.Jt.shape[1] if friction > 0 else 0)
    A = np.array([pt.Jn[j] for j in on] + [t for j in on for t in pt.Jt[j]][: m * nt]).T.reshape(len(q), -1)
    n = A.shape[1]  # forces, then the residual's bound r: min r, -r <= A x + f <= r
    ones = np.ones((len(q), 1))
    rows, bounds = [np.hstack([A, -ones]), np.hstack([-A, -ones])], [-pt.f, pt.f]
    if nt:  # d_k . f_t <= mu cos(pi / sides) f_n, each side's normal d_k
        for k in range(sides):
            d = np.array([math.cos(2 * math.pi * k / sides), math.sin(2 * math.pi * k / sides)])
            side = np.zeros((m, n + 1))
            for c in range(m):
                side[c, c] = -friction * math.cos(math.pi / sides)
                side[c, m + nt * c: m + nt * c + nt] = d[:nt]
            rows.append(side)
            bounds.append(np.zeros(m))
    cost = np.zeros(n + 1)
    cost[-1] = 1.0
    limits = [(0, None)] * m + [(None, None)] * (n - m) + [(0, None)]
    result = linprog(cost, A_ub=np.vstack(rows), b_ub=np.concatenate(bounds), bounds=limits, method="highs")
    return float(result.x[-1]) / weight if result.success else math.inf


class TooLong(Exception):
    """footopt's landing took longer than ``--limit``."""


@contextmanager
def _time_limit(seconds: float):  # type: ignore[no-untyped-def]
    """Raise :class:`TooLong` in the block after ``seconds`` of wall time (0: no limit; SIGALRM)."""
    if seconds <= 0:
        yield
        return

    def expired(signum, frame):  # type: ignore[no-untyped-def]
        raise TooLong(f"over {seconds:g} s")

    previous = signal.signal(signal.SIGALRM, expired)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


#: the resting legs' touchdown speed (m/s): above the landing's plastic speed, so a bounce of e x it
RESTING_SPEED = 1e-3
#: a resting leg is compared until this long (s) before another contact than its first touches
RESTING_MARGIN = 5e-3


def compare_resting(seed: int, settings: tuple[MujocoSettings, ...]) -> dict:
    """The between-impact friction alone: the leg touching down at :data:`RESTING_SPEED` on its
    lowest tip, footopt's landing (``--tolerance 1e-5``) against MuJoCo's while it rests, sticks
    or slides on that tip only (until :data:`RESTING_MARGIN` before another contact touches):
    the largest angle gap over that phase (at footopt's step ends, MuJoCo's steps interpolated
    there: footopt's steps are too long to interpolate, 6.6e-4 rad on seed 10's springs) and
    when; and the frictional contact problem at touchdown (the tip's free normal acceleration,
    with its tangent held, and Painleve's W_nn - mu |W_nt|, negative: the problem may have
    several answers or none)."""
    import mujoco

    tree, laws, scene = random_leg(seed, True)
    scene = replace(scene, speed=RESTING_SPEED, duration=1.0)
    ours = landing(tree, scene, laws, LandingSettings(tolerance=1e-5))
    first = ours.events[0].external > 0
    later = [e.time for e in ours.events if (e.external[~first] > 0).any()]
    end = (later[0] if later else scene.duration) - RESTING_MARGIN
    times, states = ours.trajectory
    run = _Landing(tree, scene, laws, LandingSettings())
    v = np.zeros(run.nv)
    v[1] = -scene.speed
    pt = run.point(run.q0, v)
    j = int(np.argmin(pt.gap))
    J = np.vstack([pt.Jn[j], pt.Jt[j, 0]])
    W = J @ np.linalg.solve(pt.M, J.T)
    free = J @ np.linalg.solve(pt.M, pt.f) + np.array([pt.bn[j], pt.bt[j, 0]])
    row = {"seed": seed, "friction": scene.friction, "end": end, "free": float(free[0]),
           "held": float(free[0] - W[0, 1] * free[1] / W[1, 1]),
           "painleve": float(W[0, 0] - scene.friction * abs(W[0, 1])), "gaps": [], "at": []}
    for s in settings:
        mj = StudyMujoco(SimpleNamespace(tree=tree, scene=scene, joints=laws), s)
        d, _ = mj.start(mj.h)
        steps = int(end / mj.h)
        theirs = np.empty((steps + 1, len(mj.touchdown)))
        theirs[0] = mj.angles(d)
        for i in range(steps):
            mujoco.mj_step(mj.m, d)
            theirs[i + 1] = mj.angles(d)
        at = times[times <= steps * mj.h]  # footopt's step ends; MuJoCo's fine steps interpolated there
        mine = np.column_stack([states[: len(at), 2], states[: len(at), 3:]])
        grid = mj.h * np.arange(steps + 1)
        gap = np.max(np.abs(mine - np.column_stack([np.interp(at, grid, c) for c in theirs.T])), axis=1)
        row["gaps"].append(float(gap.max()))
        row["at"].append(float(at[int(gap.argmax())]))
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--tips", action="store_true", help="the chains hang below the plank, contacts at their tips")
    parser.add_argument("--friction", type=float, default=None, help="every leg at this friction (default: its own)")
    parser.add_argument("--mujoco", nargs="+", default=[""], metavar="SPEC",
                        help="MuJoCo's contact settings, one table column each: key=value,... with keys k "
                             "(stiffness, 1/s^2), r (sphere radius, m), fd (solreffriction damping x 1/h; 0: the "
                             "contact's solref), impratio, noslip (iterations); '' (default): the bridge's "
                             "(k=1e6,r=0.001). With several, the table also gives the largest difference between "
                             "MuJoCo's own final angles at the last two")
    parser.add_argument("--resting", action="store_true",
                        help="the tips' legs with friction touching down at 1 mm/s: the between-impact friction alone "
                             "(compare_resting; writes settled_posture_resting.md)")
    parser.add_argument("--only-friction", action="store_true", help="skip the frictionless legs")
    parser.add_argument("--spatial", action="store_true",
                        help="spatial legs (random_spatial_leg; writes settled_posture_spatial[_frictionF].md)")
    parser.add_argument("--limit", type=float, default=0.0,
                        help="skip a leg whose footopt landing takes longer than this (s; 0: no limit)")
    parser.add_argument("--first", type=int, default=0, help="the first seed")
    args = parser.parse_args()
    settings = tuple(MujocoSettings.parse(spec) for spec in args.mujoco)
    command = f"`python studies/whole_landing/settled_posture.py {' '.join(_quoted(a) for a in sys.argv[1:])}`"
    if args.resting:
        return resting_table(args, settings, command)
    rows, skipped = [], []
    for seed in range(args.first, args.first + args.seeds):
        leg = random_spatial_leg(seed) if args.spatial else random_leg(seed, args.tips)
        if args.only_friction and leg[2].friction == 0 and not args.friction:
            continue
        try:
            r = compare(seed, args.tips, args.friction, settings, args.spatial, args.limit)
        except TooLong:
            skipped.append(seed)
            print(f"seed {seed}: footopt's landing over {args.limit:g} s, skipped", flush=True)
            continue
        rows.append(r)
        print(r, flush=True)
    if args.spatial:
        return spatial_table(args, settings, command, rows, skipped)
    lines = [
        "# The settled posture of random legs: footopt against MuJoCo",
        "",
        f"{command}; the legs and settings: the script's docstring. Issue #13's check: 2e-3 rad.",
        "",
        "MuJoCo's settings (`--mujoco`, `MujocoSettings`): "
        + "; ".join(f"**{chr(65 + i)}** {s.label}" for i, s in enumerate(settings)) + ".",
        "",
    ]
    several = len(settings) > 1
    last = f"{chr(63 + len(settings))}-{chr(64 + len(settings))}"
    head = (" | ".join(f"gap {chr(65 + i)} (rad)" for i in range(len(settings))) + f" | MuJoCo {last} (rad)"
            if several else "base angle gap (rad) | worst joint gap (rad)")
    lines += [f"| seed | bodies | friction | restitution | events | settled at (s) | {head} |",
              "|---|---|---|---|---|---|" + "---|" * (len(settings) + 1 if several else 2)]
    for r in rows:
        settled = "-" if r["settled_at"] is None else f"{r['settled_at']:.3f}"
        gaps = ([f"{max(b, j):.1e}" for b, j in zip(r["base"], r["joints"])] + [f"{r['spread']:.1e}"] if several
                else [f"{r['base'][0]:.1e}", f"{r['joints'][0]:.1e}"])
        lines.append(f"| {r['seed']} | {r['bodies']} | {r['friction']:g} | {r['restitution']:.2f} | {r['events']} | "
                     f"{settled} | {' | '.join(gaps)} |")
    lines.append("")
    for i, s in enumerate(settings):
        worst = max(max(r["base"][i], r["joints"][i]) for r in rows)
        within = sum(max(r["base"][i], r["joints"][i]) <= 2e-3 for r in rows)
        name = f"{chr(65 + i)} ({s.label})" if several else f"the {len(rows)} legs"
        lines.append(f"- Worst gap over {name}: {worst:.1e} rad (check: 2e-3); {within} of {len(rows)} legs within it.")
    if several:
        spread = [r["spread"] for r in rows]
        lines.append(f"- MuJoCo {last}: the largest difference between MuJoCo's own final angles at the last two "
                     f"settings; over 2e-3 on {sum(x > 2e-3 for x in spread)} of {len(rows)} legs (worst "
                     f"{max(spread):.1e} rad).")
    lines.append("")
    name = "_".join(["settled_posture"] + (["tips"] if args.tips else [])
                    + ([f"friction{args.friction:g}"] if args.friction is not None else []))
    (HERE / f"{name}.md").write_text("\n".join(lines), encoding="utf-8")
    print("\n".join(lines))


def spatial_table(args, settings: tuple[MujocoSettings, ...], command: str,  # type: ignore[no-untyped-def]
                  rows: list[dict], skipped: list[int]) -> None:
    """``--spatial``'s table: per leg and MuJoCo setting, the base's turn between the two final
    orientations (with its tilt alone) and the worst joint gap."""
    several = len(settings) > 1
    lines = [
        "# The settled posture of random spatial legs: footopt against MuJoCo",
        "",
        f"{command}; the legs: `random_spatial_leg`, MuJoCo's settings: the script's docstring. Issue #13's "
        "check: 2e-3 rad. **base**: the angle of the relative rotation between footopt's and MuJoCo's final "
        "base orientations (frame-independent), **tilt**: the angle between the vertical seen in the two "
        "bases' frames (the part the statics sets; the rest is a turn about the vertical), **joints**: the "
        "largest joint angle gap. **speed**: the largest generalized speed at 3 s (rad/s, m/s), footopt / MuJoCo "
        "(the last setting). **statics**: each final state in footopt's statics (`statics`: gravity and the "
        "springs against forces at the contacts within 0.1 mm of the ground, inside the friction cone), the "
        "smallest residual over the weight (m; ~0: a rest), footopt / MuJoCo. **s**: footopt's landing, wall "
        "seconds (2 cores shared, nice 10).",
        "",
        "MuJoCo's settings: " + "; ".join(f"**{chr(65 + i)}** {s.label}" for i, s in enumerate(settings)) + ".",
        "",
    ]
    head = " | ".join(f"base / tilt / joints {chr(65 + i)} (rad)" for i in range(len(settings)))
    lines += [f"| seed | bodies | contacts | friction | restitution | events | settled at (s) | {head} | "
              "speed footopt / MuJoCo | statics footopt / MuJoCo | s |",
              "|---|---|---|---|---|---|---|" + "---|" * len(settings) + "---|---|---|"]
    for r in rows:
        settled = "-" if r["settled_at"] is None else f"{r['settled_at']:.3f}"
        gaps = [f"{b:.1e} / {t:.1e} / {j:.1e}" for b, t, j in zip(r["base"], r["tilt"], r["joints"])]
        lines.append(f"| {r['seed']} | {r['bodies']} | {r['contacts']} | {r['friction']:g} | {r['restitution']:.2f} | "
                     f"{r['events']} | {settled} | {' | '.join(gaps)} | {r['speed_ours']:.0e} / "
                     f"{r['speed_theirs']:.0e} | {r['statics_ours']:.0e} / {r['statics_theirs']:.0e} | "
                     f"{r['seconds']:.0f} |")
    lines.append("")
    if skipped:
        lines.append(f"- Skipped (footopt's landing over {args.limit:g} s): seeds {', '.join(map(str, skipped))}.")
    for i, s in enumerate(settings):
        name = f" at {chr(65 + i)} ({s.label})" if several else ""
        for label, group in (("all", rows), ("frictionless", [r for r in rows if r["friction"] == 0]),
                             ("with friction", [r for r in rows if r["friction"] > 0])):
            if not group:
                continue
            w = [max(r["base"][i], r["joints"][i]) for r in group]
            lines.append(f"- Worst gap{name}, {label} ({len(group)} legs): {max(w):.1e} rad (base "
                         f"{max(r['base'][i] for r in group):.1e}, tilt {max(r['tilt'][i] for r in group):.1e}, joints "
                         f"{max(r['joints'][i] for r in group):.1e}); {sum(x <= 2e-3 for x in w)} of {len(group)} "
                         "within 2e-3.")
    lines.append("")
    name = "_".join(["settled_posture_spatial"] + ([f"friction{args.friction:g}"] if args.friction is not None else []))
    (HERE / f"{name}.md").write_text("\n".join(lines), encoding="utf-8")
    print("\n".join(lines))


def _quoted(arg: str) -> str:
    return arg if arg and " " not in arg else f"'{arg}'"


def resting_table(args, settings: tuple[MujocoSettings, ...], command: str) -> None:  # type: ignore[no-untyped-def]
    rows = []
    for seed in range(args.seeds):
        if random_leg(seed, True)[2].friction == 0:
            continue
        r = compare_resting(seed, settings)
        rows.append(r)
        print(r, flush=True)
    lines = [
        "# Resting on a tip with friction: footopt's landing against MuJoCo between impacts",
        "",
        f"{command}: the `--tips` legs with friction touching down at {RESTING_SPEED:g} m/s on their lowest tip "
        "(`compare_resting`), compared while they rest, stick or slide on that tip alone. The contact problem at "
        "touchdown: the tip's free normal acceleration, the same with its tangent held (both negative: it stays "
        "loaded; free > 0 > held: it may lift or stick, two answers), and Painleve's W_nn - mu |W_nt| (< 0: "
        "sliding may have two answers or none).",
        "",
        "MuJoCo's settings: " + "; ".join(f"**{chr(65 + i)}** {s.label}" for i, s in enumerate(settings)) + ".",
        "",
        "| seed | friction | compared to (s) | free a_n (m/s^2) | held a_n | W_nn - mu W_nt | "
        + " | ".join(f"worst gap {chr(65 + i)} (rad, at s)" for i in range(len(settings))) + " |",
        "|---|---|---|---|---|---|" + "---|" * len(settings),
    ]
    for r in rows:
        gaps = [f"{g:.1e} ({t:.3f})" for g, t in zip(r["gaps"], r["at"])]
        lines.append(f"| {r['seed']} | {r['friction']:g} | {r['end']:.3f} | {r['free']:.1f} | {r['held']:.1f} | "
                     f"{r['painleve']:.2f} | {' | '.join(gaps)} |")
    lines.append("")
    (HERE / "settled_posture_resting.md").write_text("\n".join(lines), encoding="utf-8")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
