"""One landing by any model of the ladder: the rigid rungs on flat ground, or one of the two
time-domain models when the ground is uneven (or on request).

``auto`` (the default) keeps the rigid ladder's automatic choice (``impulse_core.evaluate``) on
flat ground, and runs the sequential rigid model (``impulse_core.timedomain.sequential``: a rigid impact
(LCP, or exact Coulomb friction) along the local ground normal at each touchdown, free flight or resting
contacts between)
when ``scene.terrain`` (in space ``scene.heightfield``) is not flat: the flat rungs assume level ground
and simultaneous contacts. There ``lcp`` and ``friction`` on request give the first instant (the
contacts touching at t = 0 along their local normals, :mod:`impulse_core.timedomain.first_instant`);
``newton``, ``decoupled`` and ``friction-relaxed`` are refused naming the ground's key.
The compliant rung (``impulse_core.timedomain.compliant``) runs on request only: it needs a contact
stiffness, which is a modelling choice (studies/fidelity/README.md).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from impulse_core.errors import ModelError
from impulse_core.evaluate import ImpactResult, approach_velocity, evaluate, pre_impact_velocity
from impulse_core.impact.laws import ImpactModel
from impulse_core.kinematics.spatial import PLANAR, Space
from impulse_core.model.tree import ContactSelection, Scene, Tree
from impulse_core.model.joints import JointLaw
from impulse_core.timedomain.first_instant import first_instant
from impulse_core.timedomain.compliant import (
    CompliantResult,
    CompliantSettings,
    ContactLaw,
    simulate_impact,
    simulate_to_tolerance,
)
from impulse_core.timedomain.landing import LandingResult, LandingSettings, Progress, landing
from impulse_core.timedomain.sequential import SequentialResult, SequentialSettings, sequential_impacts

SEQUENTIAL, COMPLIANT, LANDING = "sequential", "compliant", "landing"
#: The rigid first-impact rungs (``--model`` values).
_RIGID = frozenset(m.value for m in ImpactModel)
#: The models that integrate through the landing instead of one instantaneous impact.
TIME_DOMAIN_MODELS = (SEQUENTIAL, COMPLIANT, LANDING)
#: Every model name ``footopt evaluate --model`` takes: 'auto', the rigid rungs, the time-domain models.
MODEL_CHOICES = ("auto", *(m.value for m in ImpactModel), *TIME_DOMAIN_MODELS)

_DESCRIPTIONS = {
    SEQUENTIAL: "sequential rigid impacts on the terrain (an LCP impact, with scene.friction exact Coulomb friction, "
    "along the local normal at each touchdown; free flight between, a plastic contact resting with a contact force)",
    COMPLIANT: "compliant contacts in the time domain (spring-dampers along the local normal; fixed semi-implicit "
    "Euler steps, or adaptive Dormand-Prince 5(4) steps between located contact switches to a tolerance)",
    LANDING: "the whole landing: every touchdown and joint stop an impact by the first-impact law, resting contact "
    "with Coulomb friction, joint springs, dampers and gravity in between (event-driven RK4)",
}


@dataclass(frozen=True)
class TimeDomainResult:
    """A landing by the sequential or the compliant model, with what a report needs beside it.

    The attributes a rigid ``ImpactResult`` also has (``external``, ``active``, ``internal``,
    ``internal_magnitude``, the norms, ``max_internal``, ``v_minus``, ``v_plus``, the energies,
    ``reason``) mean the same, so reports and plots read either.

    Attributes:
        impact_model: ``sequential`` or ``compliant``.
        reason: why it ran (automatic choice or request) and what the reader must know.
        result: the model's own result (touchdown times and order; compliant: status, force
            profiles, ...).
        v_minus: generalized velocity before the first touchdown.
        settings: the settings it ran with.
    """

    impact_model: str
    reason: str
    result: SequentialResult | CompliantResult | LandingResult
    v_minus: np.ndarray
    settings: SequentialSettings | CompliantSettings | LandingSettings

    @property
    def description(self) -> str:
        """One line naming the model (and, compliant, its law)."""
        text = _DESCRIPTIONS[self.impact_model]
        return f"{text}; {self.result.law.value} law" if isinstance(self.result, CompliantResult) else text

    @property
    def external(self) -> np.ndarray:
        return self.result.external

    @property
    def active(self) -> tuple[int, ...]:
        """Contacts that touched down, in declaration order."""
        return self.result.active

    @property
    def internal(self) -> np.ndarray:
        return self.result.internal

    @property
    def internal_magnitude(self) -> np.ndarray:
        return self.result.internal_magnitude

    @property
    def external_norm(self) -> float:
        return self.result.external_norm

    @property
    def internal_norm(self) -> float:
        return self.result.internal_norm

    @property
    def max_internal(self) -> float:
        return self.result.max_internal

    @property
    def v_plus(self) -> np.ndarray:
        return self.result.v_plus

    @property
    def energy_before(self) -> float:
        return self.result.energy_before

    @property
    def energy_after(self) -> float:
        return self.result.energy_after

    @property
    def touchdown_time(self) -> np.ndarray:
        """Per declared contact: its first touchdown (s from the first one), NaN if it never touched."""
        return self.result.touchdown_time

    @property
    def touchdown_order(self) -> tuple[int, ...]:
        return self.result.touchdown_order


def evaluate_landing(
    tree: Tree,
    scene: Scene,
    model: str = "auto",
    compliant: CompliantSettings | None = None,
    sequential: SequentialSettings | None = None,
    joints: tuple[JointLaw, ...] = (),
    whole: LandingSettings | None = None,
    compliant_tolerance: float | None = None,
    space: Space = PLANAR,
    progress: Progress | None = None,
) -> ImpactResult | TimeDomainResult:
    """The landing of ``tree`` as ``scene`` says, by ``model`` (one of :data:`MODEL_CHOICES`), the
    time-domain models with their settings (default: the modules' defaults). ``auto`` runs the
    whole landing when the scene has a ``duration`` (with the joint laws ``joints``). The compliant
    rung refines its steps to ``compliant_tolerance`` when given (else runs ``compliant`` as set).
    ``progress`` is told where a whole landing's runs are (:class:`LandingProgress`).

    Raises:
        ModelError: newton, decoupled or friction-relaxed on a terrain that is not flat, friction under
            the compliant model (frictionless), or an unknown model name.
        NumericalError: the solve or the integration failed.
    """
    if model == LANDING or model == "auto" and scene.duration is not None:
        return _whole_landing(tree, scene, joints, whole or LandingSettings(), model == LANDING, space, progress)
    if space is not PLANAR:
        return _spatial(tree, scene, model, compliant, sequential, compliant_tolerance, space)
    flat = scene.terrain.is_flat
    if model == "auto" and flat or model in _RIGID and flat:
        return evaluate(tree, scene, None if model == "auto" else ImpactModel(model))
    if model in _RIGID:
        return _first_instant(tree, scene, ImpactModel(model), "scene.terrain", PLANAR)
    why = (
        "automatic: scene.terrain is not flat, so the contacts touch down at different times and on slopes, "
        "which the flat-ground rigid rungs cannot describe; the sequential rigid model is their stiff limit "
        "(--model compliant for finite contact stiffness)"
    )
    return _time_domain(tree, scene, model, why, compliant, sequential, compliant_tolerance, PLANAR)


def _time_domain(
    tree: Tree,
    scene: Scene,
    model: str,
    why: str,
    compliant: CompliantSettings | None,
    sequential: SequentialSettings | None,
    compliant_tolerance: float | None,
    space: Space,
) -> TimeDomainResult:
    """The sequential or compliant landing (``auto``: sequential, for the reason ``why``)."""
    notes = []
    if model == "auto":
        model = SEQUENTIAL
        notes.append(why)
    elif model in (SEQUENTIAL, COMPLIANT):
        notes.append("requested")
    else:
        raise ModelError(f"model: unknown model {model!r} (choices: {', '.join(MODEL_CHOICES)})")
    if scene.selection is ContactSelection.ALL:
        notes.append("scene.contacts: all is not used here: the geometry decides which contacts touch and when")
    v_minus = approach_velocity(tree.topology(), scene.speed) if space is PLANAR else None
    settings: SequentialSettings | CompliantSettings
    result: SequentialResult | CompliantResult
    if model == SEQUENTIAL:
        settings = _scene_gravity(sequential or SequentialSettings(), scene)
        result = sequential_impacts(tree, scene, settings, space=space)
    else:
        settings = _scene_gravity(compliant or CompliantSettings(), scene)
        if compliant_tolerance is None:
            result = simulate_impact(tree, scene, settings, space=space)
        else:
            result = simulate_to_tolerance(tree, scene, settings, compliant_tolerance, space=space)
        unit = "N/m" if settings.law is ContactLaw.PENALTY else "1/s^2"
        steps = result.steps_per_period or settings.steps_per_period
        how = (
            f"{steps:g} semi-implicit Euler steps per contact period (step {result.timestep:.3g} s)"
            if result.integrator == "euler"
            else f"adaptive Dormand-Prince 5(4) steps between located contact switches ({steps:.3g} per contact "
            f"period on average, mean step {result.timestep:.3g} s)"
        )
        notes.append(
            f"{settings.law.value} law, stiffness {settings.stiffness:g} {unit}, {how}"
            + ("" if compliant_tolerance is None else f", refined to a tolerance of {compliant_tolerance:g}")
        )
    if settings.gravity:
        notes.append(f"gravity {settings.gravity:g} m/s^2")
    if v_minus is None:
        v_minus = pre_impact_velocity(tree.topology(), scene, space)
    return TimeDomainResult(model, "; ".join(notes), result, v_minus, settings)


def _spatial(
    tree: Tree,
    scene: Scene,
    model: str,
    compliant: CompliantSettings | None,
    sequential: SequentialSettings | None,
    compliant_tolerance: float | None,
    space: Space,
) -> ImpactResult | TimeDomainResult:
    """A spatial model's landing: the first-impact rungs on flat ground; on a heightfield that is
    not flat (``auto``), or on request, the sequential or compliant rung. A planar
    ``scene.terrain`` that is not flat is refused."""
    if not scene.terrain.is_flat:
        raise ModelError(
            "scene.terrain: a ground profile y(x) is planar; a spatial model's uneven ground is scene.heightfield "
            "(x and z grids and heights; constant along z for a profile)"
        )
    uneven = scene.heightfield is not None and not scene.heightfield.is_flat
    if model == "auto" and not uneven or model in _RIGID and not uneven:
        return evaluate(tree, scene, None if model == "auto" else ImpactModel(model), space)
    if model in _RIGID:
        return _first_instant(tree, scene, ImpactModel(model), "scene.heightfield", space)
    why = (
        "automatic: scene.heightfield is not flat, so the contacts touch down at different times and on slopes, "
        "which the flat-ground rigid rungs cannot describe; the sequential rigid model is their stiff limit "
        "(--model compliant for finite contact stiffness)"
    )
    return _time_domain(tree, scene, model, why, compliant, sequential, compliant_tolerance, space)


def _first_instant(tree: Tree, scene: Scene, model: ImpactModel, ground: str, space: Space) -> ImpactResult:
    """The lcp or friction rung on uneven ground (``ground`` names the scene's key): the first
    instant (:func:`impulse_core.timedomain.first_instant.first_instant`); the other rigid rungs
    are refused naming it."""
    if model not in (ImpactModel.LCP, ImpactModel.FRICTION):
        raise ModelError(
            f"{ground}: --model {model.value} assumes flat ground and this ground is not flat; on uneven ground the "
            "first instant is --model lcp or friction, the landing sequential, compliant or landing"
        )
    return first_instant(tree, scene, model, space)


def _scene_gravity(settings, scene: Scene):  # type: ignore[no-untyped-def]
    """The settings with the scene's gravity where they give none (``--gravity`` wins)."""
    return replace(settings, gravity=scene.gravity) if settings.gravity == 0 and scene.gravity else settings


def _whole_landing(
    tree: Tree, scene: Scene, joints: tuple[JointLaw, ...], settings: LandingSettings, requested: bool,
    space: Space = PLANAR, progress: Progress | None = None,
) -> TimeDomainResult:
    """The whole landing, with why it ran (in space on flat ground or a heightfield)."""
    if scene.duration is None:
        raise ModelError("scene.duration: --model landing needs the landing's duration (s) in the scene")
    why = "requested" if requested else "automatic: scene.duration is given, so the whole landing runs"
    result = landing(tree, scene, joints, settings, space, progress)
    notes = [why, f"{len(result.events)} impacts over {scene.duration:g} s, Runge-Kutta step {result.step:.3g} s"]
    if scene.gravity:
        notes.append(f"gravity {scene.gravity:g} m/s^2")
    v_minus = pre_impact_velocity(tree.topology(), scene, space)
    return TimeDomainResult(LANDING, "; ".join(notes), result, v_minus, settings)


__all__ = [
    "COMPLIANT",
    "LANDING",
    "MODEL_CHOICES",
    "SEQUENTIAL",
    "TIME_DOMAIN_MODELS",
    "TimeDomainResult",
    "evaluate_landing",
]
