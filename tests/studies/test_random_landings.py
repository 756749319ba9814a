"""``studies/whole_landing/random_landings.py``: its files are valid model files (planar and
spatial, terrains and heightfields, read by the model-file reader), and its checker flags a
wrong first event, a wrong momentum balance and bad exits (doctored JSON and a doctored result)."""

from __future__ import annotations

import copy
import json
from dataclasses import replace

import numpy as np
import pytest

from impulse_core.kinematics.spatial import SPATIAL
from optimizer.config.model_file import load_model_file

from tests.studies.scripts import study_module


def _module():
    return study_module("random_landings")


rl = _module()


def test_generated_files_are_valid_model_files(tmp_path):
    """Twelve seeds (and four with heightfields forced): every file loads, its space and ground
    are what the generator says, and the same seed gives the same file."""
    kinds = set()
    cases = [(s, rl.Options()) for s in range(12)] + [(s, rl.Options(spatial=1.0, heightfield=1.0)) for s in range(4)]
    for seed, options in cases:
        data = rl.random_model(seed, options)
        assert data == rl.random_model(seed, options)
        path = tmp_path / f"{seed}.yaml"
        rl.write_model(data, path)
        model = load_model_file(path)
        spatial = data["model"].get("space") == "spatial"
        assert (model.space == SPATIAL) == spatial
        ground = rl.ground_kind(data)
        if ground == "terrain":
            assert not model.scene.terrain.is_flat
        if ground == "heightfield":
            assert model.scene.heightfield is not None and not model.scene.heightfield.is_flat
        assert model.scene.duration == data["scene"]["duration"] and 0.02 <= model.scene.duration <= 0.5
        assert any(b.contacts for b in model.tree.bodies)
        kinds.add(("spatial" if spatial else "planar", ground))
    assert kinds == {("planar", "flat"), ("planar", "terrain"), ("spatial", "flat"), ("spatial", "heightfield")}


def _jsons():
    """A landing's JSON (its first event) and the first-impact rung's, agreeing."""
    first = {"external": [0.5, 0.25], "internal": [0.1], "tangential": [0.2, -0.1]}
    landing = {"events": [{"t": 0.0, "kind": "touchdown", **copy.deepcopy(first)},
                          {"t": 0.01, "kind": "touchdown", "external": [0.1, 0], "internal": [0.0], "tangential": [0, 0]}],
               "landing": {"total_external": [1.0, 2.0]}}
    return landing, first


def test_the_checker_passes_a_good_landing_and_flags_a_wrong_first_event_or_balance():
    landing, first = _jsons()
    assert rl.check(0, "", landing, first, 5e-5, [1.0, 2.0]) == []
    assert rl.verdict(0, []) == "ok"
    bad = copy.deepcopy(landing)
    bad["events"][0]["external"][1] *= 1 + 1e-8  # 2.5e-9 of the list's largest (0.5): over 1e-9
    fails = rl.check(0, "", bad, first, 5e-5)
    assert fails == ["first event 5e-09"] and rl.verdict(0, fails) == "first"
    bad = copy.deepcopy(landing)
    bad["events"][0]["tangential"][0] = 0.2 + 1e-12  # within 1e-9 of 0.2
    assert rl.check(0, "", bad, first, 5e-5) == []
    bad["events"][0]["internal"] = [0.1, 0.0]  # a list of another length
    assert rl.check(0, "", bad, first, 5e-5) == ["first event inf"]
    assert rl.check(0, "", landing, first, 2e-4) == ["balance 0.0002"]
    assert rl.check(0, "", landing, first, None) == ["balance missing"]
    assert rl.check(0, "", landing, None, 0.0) == ["first-impact rung gave no answer"]
    assert rl.check(0, "", landing, first, 0.0, [1.0, 2.5]) == ["spied result is not the reported one"]
    late = copy.deepcopy(landing)
    late["events"][0]["t"] = 1e-3
    assert rl.check(0, "", late, first, 0.0) == ["first event not at t = 0"]


def test_the_checker_reads_exit_statuses():
    assert rl.check(2, "footopt: error: x.yaml: scene.speed: must be > 0\n", None, None, None) == []
    assert rl.verdict(2, []) == "refused"
    assert rl.check(2, "usage: footopt\nfootopt: error: bad\n", None, None, None) == ["exit 2 with 2 lines"]
    fails = rl.check(1, "footopt: error: x.yaml: the landing chatters at t = 0.1\n", None, None, None)
    assert fails == ["exit 1: footopt: error: x.yaml: the landing chatters at t = 0.1"] and rl.verdict(1, fails) == "exit 1"
    assert rl.check(1, "Traceback (most recent call last):\n  ...\nValueError: x\n", None, None, None) == ["traceback (exit 1)"]


def test_the_momentum_balance_is_derived_from_the_result_and_flags_a_doctored_one(tmp_path):
    """A one-rod spatial landing with friction (seed 2, 37 ms): the balance derived from the
    result's momenta and totals is the run's own to rounding and within 1e-4; a total normal
    impulse 1 % off, or a tangential total dropped, is flagged."""
    from impulse_core.timedomain.landing import LandingSettings, landing

    path = tmp_path / "2.yaml"
    rl.write_model(rl.random_model(2), path)
    model = load_model_file(path)
    args = (model.tree, model.scene, model.joints, LandingSettings(), model.space)
    result = landing(*args)
    good = rl.momentum_balance(*args, result=result)
    assert not good["own"] and good["balance"] == good["derived"] <= 1e-6
    assert good["derived"] == pytest.approx(result.momentum_balance, rel=1e-3, abs=1e-12)
    heavier = rl.momentum_balance(*args, result=replace(result, total_external=result.total_external * 1.01))
    assert heavier["balance"] > 1e-3
    assert np.max(np.abs(result.total_tangential)) > 1e-3  # it slides: friction acts
    frictionless = rl.momentum_balance(*args, result=replace(result, total_tangential=0 * result.total_tangential))
    assert frictionless["balance"] > 1e-3


def test_files_are_checked_as_seeds_are(tmp_path):
    """``--files``: a model file already written (a kept failure) is landed and checked as a seed's
    is, under its name's number."""
    seed = 3
    path = tmp_path / f"{seed}.yaml"
    rl.write_model(rl.random_model(seed), path)
    out = tmp_path / "out"
    assert rl.main(["--files", str(path), "--out", str(out), "--limit", "120"]) == 0
    by_file = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    (tmp_path / "seed").mkdir()
    again = rl.run_seed(seed, rl.Options(), tmp_path / "seed", 120.0)
    assert [r["seed"] for r in by_file] == [seed] and by_file[0]["verdict"] == again.verdict == "ok"
    assert by_file[0]["events"] == again.events and by_file[0]["balance"] == pytest.approx(again.balance, rel=1e-12)


def test_files_without_a_number_or_a_duration_are_named_and_flagged(tmp_path):
    """``--files`` on a first-impact file (no ``scene.duration``) under a name that is not a number:
    no crash (it read the JSON's ``events``), the verdict says it is not a landing, the record and
    side file go by the file's name (not a shared -1)."""
    data = rl.random_model(3)
    del data["scene"]["duration"]
    path = tmp_path / "paper_leg.yaml"
    rl.write_model(data, path)
    out = tmp_path / "out"
    assert rl.main(["--files", str(path), "--out", str(out), "--limit", "120"]) == 0
    record = json.loads((out / "results.jsonl").read_text())
    assert record["seed"] == "paper_leg" and record["events"] is None
    assert record["fails"] == ["no-landing: the file has no scene.duration"] and record["verdict"] == "no-landing"
    assert (out / "paper_leg.side.json").exists()
