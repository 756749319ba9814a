"""A search's landing C built in the background (:mod:`optimizer.search.landing_code`), and step
code ``auto`` that takes it from the compile cache."""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np
import pytest

import impulse_core.compile.codegen as codegen
import optimizer.search.landing_code as landing_code
from impulse_core.kinematics.spatial import PLANAR
from impulse_core.model.joints import FREE, JointLaw
from impulse_core.model.tree import Body, Scene, Tree
from impulse_core.timedomain.landing import AUTO_CODE, LandingResult, landing
from optimizer.cli.main import main
from optimizer.config.study_config import load_study
from optimizer.design_space import STUDY_LANDING
from optimizer.search.landing_code import COMPILE_LANDINGS, LandingBuilds


def _leg() -> tuple[Tree, tuple[JointLaw, ...], Scene]:
    """A shank with a sprung, damped foot between stops landing on its tip with friction and
    gravity: impacts, a stop, sliding or sticking in 30 ms; small enough to compile in seconds."""
    bodies = (Body("shank", None, 0.5, 1.0, -1.2), Body("foot", 0, 0.15, 0.2, 1.0, contacts=(1.0,)))
    laws = (FREE, JointLaw(stiffness=20.0, damping=0.2, limits=(0.6, 1.4)))
    return Tree(bodies), laws, Scene(speed=2.0, restitution=0.3, friction=0.5, gravity=9.81, duration=0.03)


#: :func:`_leg` as a model file.
LEG_YAML = """
scene: {speed: 2.0, restitution: 0.3, friction: 0.5, gravity: 9.81, duration: 0.03}
model:
  bodies:
    - {name: shank, length: 0.5, mass: 1.0, angle: -1.2}
    - {name: foot, parent: shank, at: 1.0, length: 0.15, mass: 0.2, angle: 1.0, joint: revolute,
       stiffness: 20.0, damping: 0.2, limits: [0.6, 1.4], contacts: [1.0]}
"""


def _assert_same_bits(a: LandingResult, b: LandingResult) -> None:
    assert (a.n_steps, a.step, a.error_estimate, len(a.events)) == (b.n_steps, b.step, b.error_estimate, len(b.events))
    for x, y in zip(a.events, b.events, strict=True):
        assert x.time == y.time and x.kind == y.kind
        for key in ("external", "tangential", "internal", "stop", "v_plus"):
            assert np.array_equal(getattr(x, key), getattr(y, key)), key
    for key in ("q_final", "v_final", "total_external", "total_tangential"):
        assert np.array_equal(getattr(a, key), getattr(b, key)), key


def test_a_landing_takes_the_c_a_background_build_stored(tmp_path, monkeypatch, capsys):
    """Step code ``auto`` (the studies'): the virtual machine while the compile cache lacks the
    topology's C, and nothing is built; :class:`LandingBuilds` builds the step, the projection and
    the point's dynamics; the next landing runs on them and gives the same numbers bit for bit
    (plane). A topology already built, or a search planning too few landings, starts no build."""
    monkeypatch.setenv("FOOTOPT_CACHE_DIR", str(tmp_path))
    tree, laws, scene = _leg()
    assert STUDY_LANDING.step_code == AUTO_CODE
    before = landing(tree, scene, laws, STUDY_LANDING)
    assert before.step_code == "vm" and len(before.events) >= 2
    assert not list(tmp_path.iterdir())  # auto built nothing
    with LandingBuilds(planned=COMPILE_LANDINGS) as builds:
        builds.prepare(tree, scene, laws, STUDY_LANDING, PLANAR)
        builds.wait()
        assert builds.started == ["landing_step", "landing_projection", "landing"]
    after = landing(tree, scene, laws, STUDY_LANDING)
    assert after.step_code == "c"
    _assert_same_bits(before, after)
    model = tmp_path / "leg.yaml"  # footopt evaluate takes it too, and says so
    model.write_text(LEG_YAML)
    assert main(["evaluate", str(model)]) == 0
    assert "steps as C from the compile cache" in capsys.readouterr().out
    for planned in (COMPILE_LANDINGS, COMPILE_LANDINGS - 1):
        with LandingBuilds(planned=planned) as again:
            again.prepare(tree, scene, laws, STUDY_LANDING, PLANAR)
            assert again.started == []


def test_stopping_kills_a_running_build(tmp_path, monkeypatch):
    """A search that ends while a build runs (its last batch, a Ctrl-C) stops it at once: the
    compiler is killed, the thread ends, the cache holds no entry and no half-built folder."""
    cache, pid_file = tmp_path / "cache", tmp_path / "pid"
    compiler = tmp_path / "cc"
    compiler.write_text(f'#!/bin/sh\nif [ "$1" = "--version" ]; then echo fake 1.0; exit 0; fi\n'
                        f'echo $$ > "{pid_file}"\nexec sleep 60\n')
    compiler.chmod(0o755)
    monkeypatch.setattr(codegen, "find_compiler", lambda: str(compiler))
    tree, laws, scene = _leg()
    builds = LandingBuilds(planned=COMPILE_LANDINGS, root=cache)
    builds.prepare(tree, scene, laws, STUDY_LANDING, PLANAR)
    deadline = time.monotonic() + 30
    while not pid_file.exists() or not pid_file.read_text().strip():
        assert time.monotonic() < deadline, "the build did not start"
        time.sleep(0.05)
    pid = int(pid_file.read_text())
    started = time.monotonic()
    builds.stop()
    assert time.monotonic() - started < 10  # not the compiler's 60 s
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)
    assert not [p for p in cache.iterdir()]


def test_two_searches_on_one_cache_build_each_library_once(tmp_path, monkeypatch):
    """Workers of one study (each its own search and builds) share the compile cache: a library
    one of them is compiling, or has stored, the other skips (``cache.claim``), so the three
    libraries of a landing are compiled three times in all, not six (a fake compiler that takes
    a second and writes an empty library)."""
    cache, calls = tmp_path / "cache", tmp_path / "calls"
    compiler = tmp_path / "cc"
    compiler.write_text('#!/bin/sh\nif [ "$1" = "--version" ]; then echo fake 1.0; exit 0; fi\n'
                        'prev=""; for a in "$@"; do [ "$prev" = "-o" ] && out="$a"; prev="$a"; done\n'
                        f'echo $$ >> "{calls}"\nsleep 1\n: > "$out"\n')
    compiler.chmod(0o755)
    monkeypatch.setattr(codegen, "find_compiler", lambda: str(compiler))
    tree, laws, scene = _leg()
    with LandingBuilds(planned=COMPILE_LANDINGS, root=cache) as first, \
            LandingBuilds(planned=COMPILE_LANDINGS, root=cache) as second:
        first.prepare(tree, scene, laws, STUDY_LANDING, PLANAR)
        deadline = time.monotonic() + 30
        while not calls.exists():
            assert time.monotonic() < deadline, "the build did not start"
            time.sleep(0.05)
        second.prepare(tree, scene, laws, STUDY_LANDING, PLANAR)
        first.wait()
        second.wait()
    assert len(calls.read_text().split()) == 3
    assert len([p for p in cache.iterdir() if p.is_dir()]) == 3 and not list(cache.glob(".*"))


def test_a_search_plans_its_builds_by_landings_per_shape():
    """The outer search builds when trials x scenarios / shapes reaches COMPILE_LANDINGS, and
    never for a first-impact study."""
    from optimizer.search.outer import landing_builds

    config = load_study(Path("configs/landing_study.yaml"))
    shapes = len(config.space.shapes())
    assert shapes > 1
    assert landing_builds(config, COMPILE_LANDINGS * shapes).active
    assert not landing_builds(config, COMPILE_LANDINGS * shapes - 1).active
    assert not landing_builds(load_study(Path("configs/quick_study.yaml")), 10**6).active


def test_the_outer_search_prepares_every_design_and_stops_its_builds(tmp_path, monkeypatch):
    """run_outer hands each batch's designs to its builds before landing them, and stops the
    builds when it returns (no compiler left running into the report's forked pool)."""
    import optuna

    from optimizer.search.outer import open_study, run_outer

    seen, stopped = [], []
    monkeypatch.setattr(landing_code, "COMPILE_LANDINGS", 0)
    monkeypatch.setattr(LandingBuilds, "prepare", lambda self, tree, *rest: seen.append(len(tree.bodies)))
    monkeypatch.setattr(LandingBuilds, "stop", lambda self: stopped.append(True))
    config = load_study(Path("configs/landing_study.yaml"))
    study = open_study(config, optuna.storages.InMemoryStorage())
    run_outer(study, config, 2)
    assert len(seen) == 2 and all(n >= 4 for n in seen) and stopped == [True]
