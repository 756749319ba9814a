"""A landing's step that fails is a step that blew up, which ``landing()`` shortens, not the run's end.

- Random file 60690 (spatial, one light rod): its first run, RK4 at T / 100, blew up within one
  step; an RK4 stage at |v| ~ 1e21 met a singular mass matrix, and the numpy ``LinAlgError``
  ended ``footopt evaluate`` with "numerical failure: Singular matrix". The step now comes back
  NaN and the run raises :class:`Diverged`, which ``landing()`` shortens.
- Random file 60779 (spatial heightfield, Radau IIA): an event location's trial step stayed NaN
  after RADAU_SPLITS (its Newton iterations did not converge), and the witnesses' least squares
  on NaN failed ("SVD did not converge"). A trial's length is where it looks, so its pieces are now
  split down to RK4's stable step; a trial that blows up is the run's divergence.
- Random file 61227 (a light rod's tip, friction 0.3): a run that diverges after Painleve's
  paradox says so, and the remedy.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from impulse_core.timedomain.events.run import _Landing
from impulse_core.timedomain.events.settings import RADAU_SPLITS
from impulse_core.timedomain.landing import NUMPY_CODE, RADAU, RK4, Diverged, LandingSettings
from optimizer.config.model_file import load_model_file
from tests.impulse_core.test_landing import _light_tip_leg
from tests.impulse_core.test_landing_radau import _resting_state

DATA = Path(__file__).parent / "data"


def test_a_singular_stage_is_a_step_that_blew_up():
    """60690's run at T / 100 ends in Diverged (which landing() shortens), not a LinAlgError. Its slow
    slip's direction regularised (slip_splits 0: the run the file was found with); split (the
    default), the same run slides on accurately enough to jam at 0.1739 s and is bridged at 0.2346 s."""
    model = load_model_file(DATA / "singular_stage_60690.yaml")
    run = _Landing(model.tree, model.scene, model.joints, LandingSettings(slip_splits=0), model.space)
    assert run.method == RK4
    with np.errstate(all="ignore"), pytest.raises(Diverged, match="diverged"):
        run.run(model.scene.duration / 100.0)


def _radau_at_rest() -> tuple[_Landing, np.ndarray, np.ndarray, object]:
    """The light-tip leg on numpy's Radau IIA step, at the RK4 run's state with the tip resting."""
    tree, laws, scene = _light_tip_leg()
    run = _Landing(tree, scene, laws, LandingSettings(step_code=NUMPY_CODE, integrator=RADAU))
    q, v, mode = _resting_state(_Landing(tree, scene, laws, LandingSettings(integrator=RK4)), 2e-3)
    return run, q, v, mode


def test_a_trial_splits_radau_pieces_past_the_step_budget(monkeypatch):
    """A Radau IIA step whose iterations converge only on pieces 2^-(RADAU_SPLITS + 2) of it: the
    step is NaN (balanced_step halves it), the trial of the same length is not, and it ends where
    the pieces, one after another, end."""
    run, q, v, mode = _radau_at_rest()
    tau = 8.0 * run.stable_step() * 2.0 ** (RADAU_SPLITS + 2)
    piece = tau / 2.0 ** (RADAU_SPLITS + 2)
    once = run.radau_once
    monkeypatch.setattr(run, "radau_once", lambda q, v, mode, h: once(q, v, mode, h) if h <= piece * (1 + 1e-12)
                        else run.failed_step())
    q1, _, _ = run.step(q, v, mode.copy(), tau)
    assert not np.isfinite(q1).all()
    trial = run.trial(q, v, mode.copy(), tau)
    assert np.isfinite(trial.q).all() and np.isfinite(trial.v).all() and trial.tau == tau
    qa, va = q, v
    for _ in range(2 ** (RADAU_SPLITS + 2)):
        qa, va, _ = once(qa, va, mode.copy(), piece)
    assert np.max(np.abs(trial.q - qa)) <= 1e-12 * (1 + np.max(np.abs(qa)))
    assert np.max(np.abs(trial.v - va)) <= 1e-9 * (1 + np.max(np.abs(va)))


def test_a_trial_that_blows_up_is_the_runs_divergence(monkeypatch):
    """A NaN trial step (RK4) raises Diverged instead of reaching the witnesses' solves."""
    tree, laws, scene = _light_tip_leg()
    run = _Landing(tree, scene, laws, LandingSettings(integrator=RK4))
    q, v, mode = _resting_state(run, 2e-3)
    monkeypatch.setattr(run, "step", lambda q, v, mode, h: (q * np.nan, v * np.nan, np.zeros(run.nc * run.dims)))
    with pytest.raises(Diverged, match="locating an event"):
        run.trial(q, v, mode.copy(), 1e-4)


def test_a_divergence_after_painleves_paradox_says_so():
    """Random file 61227 (a light rod's tip, friction 0.3): its run at T / 800 diverges 1.9 ms after
    an impulsive jam, in a mode no jam note explains; the error names the paradox met before and
    the remedy (it said "the landing diverged" alone). Its slow slip's direction regularised
    (slip_splits 0: the run the file was found with); split (the default), the same run jams at
    0.0655 s and after, crosses by two bridges and lands."""
    model = load_model_file(DATA / "paradox_diverged_61227.yaml")
    run = _Landing(model.tree, model.scene, model.joints, LandingSettings(slip_splits=0), model.space)
    said = "after Painleve's paradox at t = 0.06.*lower the friction"
    with np.errstate(all="ignore"), pytest.raises(Diverged, match=said):
        run.run(model.scene.duration / 800.0)
    assert run._jams[1] >= 1
