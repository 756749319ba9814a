"""Fuzzed study and model files (seeded): deleted keys, wrong types, NaN/inf, negative values,
unknown keys and garbage YAML. Every invalid file ends with exit 2 and one line naming the field
(or the YAML line), never a traceback; a file that stays valid runs (model files) or loads
(study files)."""

from __future__ import annotations

import copy
import json
import math
import random
import re
from pathlib import Path

import pytest
import yaml

from optimizer.cli.main import main
from optimizer.config.study_config import load_study
from optimizer.errors import ConfigError
from tests.optimizer.conftest import TINY_STUDY_YAML
from tests.optimizer.imports.test_leg import SPATIAL_LEG, rod_urdf

REPO = Path(__file__).resolve().parents[2]
TOP = ("scene|model|name|seed|storage|design_space|constraints|objectives|search|leg|notes|reference|landings|statistic"
       "|the top level")
FIELD = re.compile(rf"^footopt: error: .*(line \d+|: (?:{TOP})[\w.\[\]]*:|: empty file)", re.M)
BAD_VALUES = [None, True, "ten", [], {}, [1, 2, 3], -1.0, 0.0, math.nan, math.inf, -math.inf, 1e308, -5, "1e-3x"]


def _paths(node, prefix=()):
    """Every (path, value) in a nested dict/list."""
    yield prefix, node
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    for k, v in items:
        yield from _paths(v, (*prefix, k))


def _mutate(data, rng: random.Random):
    """One random mutation of a copy of ``data`` (a loaded YAML document), or garbage text."""
    data = copy.deepcopy(data)
    paths = [p for p, _ in _paths(data) if p]
    path = rng.choice(paths)
    *head, last = path
    parent = data
    for k in head:
        parent = parent[k]
    kind = rng.randrange(4)
    if kind == 0 and isinstance(parent, dict):
        del parent[last]
    elif kind == 1 and isinstance(parent, dict):
        parent[str(last) + rng.choice(["x", "_", "s"])] = parent.pop(last)  # a misspelt key
    else:
        parent[last] = rng.choice(BAD_VALUES)
    return data


def _dump(data) -> str:
    text = json.dumps(data, allow_nan=True)  # NaN/Infinity as JSON writes them: not YAML numbers
    return text.replace("NaN", ".nan").replace("-Infinity", "-.inf").replace("Infinity", ".inf")


GARBAGE = ["scene: [1, 2\n", "{{{", "model:\n  bodies:\n    - name: a\n   length: 1\n", "\t- x", ": :", "a: b: c"]


def _check(status: int, err: str) -> None:
    assert "Traceback" not in err, err
    assert status in (0, 1, 2), (status, err)
    if status == 2:
        assert FIELD.search(err), err


def _fuzzed_studies(bases: list, rng: random.Random, garbage_every: int, tmp_path: Path, capsys) -> int:
    """60 fuzzed study files (garbage text every ``garbage_every``): each that does not load is
    refused by ``footopt optimize`` with exit 2 and one line naming the field; how many."""
    invalid = 0
    for k in range(60):
        text = rng.choice(GARBAGE) if k % garbage_every == 0 else _dump(_mutate(rng.choice(bases), rng))
        f = tmp_path / f"s{k}.yaml"
        f.write_text(text, encoding="utf-8")
        try:
            load_study(f)
        except ConfigError:
            status = main(["optimize", str(f), "--out", str(tmp_path / f"run{k}")])
            _check(status, capsys.readouterr().err)
            assert status == 2
            invalid += 1
    return invalid


@pytest.mark.parametrize("seed", range(4))
def test_fuzzed_model_files(seed: int, tmp_path: Path, capsys) -> None:
    rng = random.Random(seed)
    bases = [yaml.safe_load((REPO / "configs" / f).read_text()) for f in ("paper_case2.yaml", "uneven_terrain.yaml")]
    invalid = 0
    for k in range(60):
        text = rng.choice(GARBAGE) if k % 15 == 0 else _dump(_mutate(rng.choice(bases), rng))
        f = tmp_path / f"m{k}.yaml"
        f.write_text(text, encoding="utf-8")
        status = main(["evaluate", "--json", str(f)])
        _check(status, capsys.readouterr().err)
        invalid += status == 2
    assert invalid >= 20  # the fuzzer does reach the validation


@pytest.mark.parametrize("seed", range(4))
def test_fuzzed_study_files(seed: int, tmp_path: Path, capsys) -> None:
    rng = random.Random(100 + seed)
    base = yaml.safe_load((REPO / "configs" / "quick_study.yaml").read_text())
    base |= yaml.safe_load(TINY_STUDY_YAML)
    assert _fuzzed_studies([base], rng, 15, tmp_path, capsys) >= 20


@pytest.mark.parametrize("seed", range(3))
def test_fuzzed_spatial_model_files(seed: int, tmp_path: Path, capsys) -> None:
    """The same on spatial files (rpy, axis, radius, 3-vector approaches; with and without
    friction: the circular cone's solver meets the fuzz too)."""
    rng = random.Random(200 + seed)
    base = yaml.safe_load((REPO / "configs" / "spatial_case3.yaml").read_text())
    frictional = copy.deepcopy(base)
    frictional["scene"]["friction"] = 0.6
    invalid = 0
    for k in range(40):
        f = tmp_path / f"sp{k}.yaml"
        f.write_text(_dump(_mutate(rng.choice([base, frictional]), rng)), encoding="utf-8")
        status = main(["evaluate", "--json", str(f)])
        _check(status, capsys.readouterr().err)
        invalid += status == 2
    assert invalid >= 10


@pytest.mark.parametrize("seed", range(2))
def test_fuzzed_general_spatial_model_files(seed: int, tmp_path: Path, capsys) -> None:
    """The same on spatial files whose bodies carry ``com_offset`` and ``inertia_tensor``."""
    rng = random.Random(300 + seed)
    base = yaml.safe_load((REPO / "configs" / "spatial_case3.yaml").read_text())
    for i, b in enumerate(base["model"]["bodies"]):
        b["com_offset"] = [0.002 * i, -0.001 * i]
        if i % 2 == 0:
            del b["radius"]
            b["inertia_tensor"] = [0.002 * b["mass"], 0.04 * b["mass"], 0.041 * b["mass"], 1e-6, -2e-6, 3e-6]
    invalid = 0
    for k in range(40):
        f = tmp_path / f"g{k}.yaml"
        f.write_text(_dump(_mutate(base, rng)), encoding="utf-8")
        status = main(["evaluate", "--json", str(f)])
        _check(status, capsys.readouterr().err)
        invalid += status == 2
    assert invalid >= 10


def _landing_model(duration: float = 0.005) -> dict:
    """configs/landing_case3.yaml landing for ``duration`` s (each run well under a second)."""
    data = yaml.safe_load((REPO / "configs" / "landing_case3.yaml").read_text())
    data["scene"]["duration"] = duration
    return data


@pytest.mark.parametrize("key, value", [("angle", 1e12), ("angle", -1e308), ("rest", 1e12)])
def test_a_far_angle_is_refused_not_run_forever(key: str, value: float, tmp_path: Path, capsys) -> None:
    """Found by the fuzzer: a joint at 1e12 rad (finite) made a 5 ms landing run for ever, its
    steps lost in the angle's rounding; a rest there took seconds to fail."""
    data = _landing_model()
    data["model"]["bodies"][7][key] = value
    f = tmp_path / "far.yaml"
    f.write_text(_dump(data), encoding="utf-8")
    assert main(["evaluate", "--json", str(f)]) == 2
    err = capsys.readouterr().err
    assert f"model.bodies[7].{key}: must be an angle within [-1e+06, 1e+06] rad" in err, err
    study = yaml.safe_load(TINY_STUDY_YAML) | {"leg": {"thigh": {"angle": value}}}
    f.write_text(_dump(study), encoding="utf-8")
    with pytest.raises(ConfigError, match=r"leg.thigh.angle: must be an angle within"):
        load_study(f)


def test_a_urdf_loop_is_refused_not_walked_for_ever(tmp_path: Path, capsys) -> None:
    """Found by the fuzzer: a joint whose parent hangs below its child made ``footopt import`` walk
    the loop for ever."""
    text = rod_urdf(SPATIAL_LEG).replace('<parent link="hip"/><child link="thigh"/>',
                                         '<parent link="shank"/><child link="thigh"/>')
    src = tmp_path / "loop.urdf"
    src.write_text(text, encoding="utf-8")
    assert main(["import", str(src), "--root", "base", "--ankle", "shank", "-o", str(tmp_path / "o.yaml")]) == 2
    err = capsys.readouterr().err
    assert "joint 'thigh_joint': closes a loop (thigh <- shank <- thigh)" in err and err.count("\n") == 1, err


# --------------------------------------------------------------------------------------------
# Whole landings, their studies, robust studies, --landings, import, export and drop

#: What a line about a command-line option or a robot description names: the option, a link,
#: joint, body, geom or site, or the XML line.
WHERE = re.compile(r"^footopt: error: (--[\w-]+: |.*(?:(?:link|joint|body|geom|site)\b|line \d+|<\w+>"
                   r"|: cannot write: ))", re.M)
LANDING_FLAGS = [["--tolerance", "1e-300"], ["--tolerance=-1"], ["--tolerance", "nan"], ["--tolerance", "1e300"],
                 ["--model", "compliant"], ["--model", "sequential"], ["--model", "lcp"], ["--plot", "drawing.txt"]]


def _check_where(status: int, err: str) -> None:
    """The contract for an option or a robot description: as _check, the line naming it."""
    assert "Traceback" not in err and "internal error" not in err, err
    assert status in (0, 1, 2), (status, err)
    if status == 2:
        assert FIELD.search(err) or WHERE.search(err), err


@pytest.mark.parametrize("seed", range(2))
def test_fuzzed_landing_model_files(seed: int, tmp_path: Path, capsys) -> None:
    """Whole landings (5 ms of landing_case3.yaml, with and without a terrain, a stop's restitution
    and a rest), some with a bad or inapplicable --tolerance, --model or --plot."""
    rng = random.Random(400 + seed)
    base = _landing_model()
    other = copy.deepcopy(base)
    other["scene"]["terrain"] = [[-1.0, 0.0], [0.0, 0.0], [0.5, 0.01]]
    other["model"]["bodies"][2] |= {"stop_restitution": 0.3, "limits": [-1.5, 0.0], "rest": -0.7}
    invalid = 0
    for k in range(40):
        text = rng.choice(GARBAGE) if k % 20 == 0 else _dump(_mutate(rng.choice([base, other]), rng))
        f = tmp_path / f"l{k}.yaml"
        f.write_text(text, encoding="utf-8")
        flags = rng.choice(LANDING_FLAGS) if rng.random() < 0.3 else []
        status = main(["evaluate", "--json", str(f), *[str(tmp_path / x) if x.endswith(".txt") else x for x in flags]])
        _check_where(status, capsys.readouterr().err)
        invalid += status == 2
    assert invalid >= 20


def _landing_studies() -> list[dict]:
    """Whole-landing studies: the tiny one, it over landings (inner search), a robust first-impact
    study and configs/landing_study.yaml."""
    from tests.optimizer.test_landing_inner_robust import robust_yaml
    from tests.optimizer.test_landing_study import TINY_LANDING_YAML
    from tests.optimizer.test_robust import ROBUST_YAML

    statistic = "{peak_external_norm: 'cvar:0.5', energy_absorbed: mean}"
    texts = [TINY_LANDING_YAML, robust_yaml(statistic), ROBUST_YAML,
             (REPO / "configs" / "landing_study.yaml").read_text()]
    return [yaml.safe_load(t) for t in texts]


@pytest.mark.parametrize("seed", range(2))
def test_fuzzed_landing_study_files(seed: int, tmp_path: Path, capsys) -> None:
    """Joint law ranges, landing_tolerance, landing objectives, landings: and statistic: blocks."""
    rng = random.Random(500 + seed)
    bases = _landing_studies()
    assert _fuzzed_studies(bases, rng, 20, tmp_path, capsys) >= 30


def test_fuzzed_evaluations_over_landings(tmp_path: Path, capsys) -> None:
    """``footopt evaluate --landings STUDY MODEL``, the study or the model fuzzed (2 landings of 5 ms)."""
    rng = random.Random(600)
    studies = _landing_studies()[1:3]
    for s in studies:
        s["landings"]["count"] = 2
    model = _landing_model()
    invalid = 0
    for k in range(12):
        study = rng.choice(studies)
        study, m = (_mutate(study, rng), model) if k % 2 else (study, _mutate(model, rng))
        fs, fm = tmp_path / f"s{k}.yaml", tmp_path / f"m{k}.yaml"
        fs.write_text(_dump(study), encoding="utf-8")
        fm.write_text(_dump(m), encoding="utf-8")
        status = main(["evaluate", "--json", "--landings", str(fs), str(fm)])
        _check(status, capsys.readouterr().err)
        invalid += status == 2
    assert invalid >= 6


_ATTRIBUTE = re.compile(r'(\w+)="([^"]*)"')
_ELEMENT = re.compile(r"<(inertial|mass|inertia|origin|axis|parent|child|limit|joint|geom|body|link)\b[^>]*/>")
XML_VALUES = ["nan", "inf", "-1", "0", "abc", "", "1 2", "1e400", "-inf", "1 2 3 4", "0 0 0", "1e308"]
MJCF_LEG = """<mujoco model="leg"><worldbody>
<body name="base" pos="0 0 1"><freejoint/><inertial pos="0.1 0 0" mass="3" diaginertia="0.01 0.01 0.01"/>
 <body name="thigh" pos="0.2 0 0">
  <joint name="hip" type="hinge" axis="0 0 1" range="-1 1" stiffness="10" damping="0.1"/>
  <inertial pos="0 -0.15 0" mass="1" diaginertia="0.008 0.0002 0.008"/>
  <body name="shank" pos="0 -0.3 0"><joint name="knee" type="hinge" axis="0 0 1" range="-2 0"/>
   <inertial pos="0 -0.1 0" mass="0.3" diaginertia="0.002 0.0001 0.002"/>
   <body name="foot" pos="0 -0.2 0"><geom name="toe" type="sphere" size="0.01" mass="0.05"/></body>
  </body></body></body></worldbody></mujoco>
"""


def _mutate_xml(text: str, rng: random.Random) -> str:
    """One random mutation of a robot description: an attribute's value bad, taken from another
    attribute of its name (a link named twice, a loop), misspelt or deleted, or an element deleted."""
    found = list(_ATTRIBUTE.finditer(text))
    m = rng.choice(found)
    kind = rng.randrange(5)
    if kind == 3:
        return text[: m.start()] + text[m.end() :]
    if kind == 4:
        el = rng.choice(list(_ELEMENT.finditer(text)))
        return text[: el.start()] + text[el.end() :]
    value = (rng.choice(XML_VALUES) if kind == 0 else m.group(2) + rng.choice(["x", " 0"]) if kind == 1
             else rng.choice([a.group(2) for a in found if a.group(1) == m.group(1)]))
    return text[: m.start(2)] + value + text[m.end(2) :]


@pytest.mark.parametrize("seed", range(2))
def test_fuzzed_robot_descriptions(seed: int, tmp_path: Path, capsys) -> None:
    """``footopt import`` of URDF and MJCF legs with masses, inertias, origins, axes, names and
    elements fuzzed, some with options; a leg it writes, ``footopt evaluate`` runs or refuses."""
    rng = random.Random(700 + seed)
    invalid = 0
    for k in range(40):
        urdf = rng.random() < 0.6
        text = _mutate_xml(rod_urdf(SPATIAL_LEG) if urdf else MJCF_LEG, rng)
        if rng.random() < 0.3:
            text = _mutate_xml(text, rng)
        src, out = tmp_path / (f"r{k}.urdf" if urdf else f"r{k}.xml"), tmp_path / f"r{k}.yaml"
        src.write_text(text, encoding="utf-8")
        options = rng.choice([[], [], ["--space", "planar"], ["--com-on-rods"], ["--angle", "shank_joint=1e300"]])
        status = main(["import", str(src), "--root", "base", "--ankle", rng.choice(["foot", "shank"]),
                       "-o", str(out), *options])
        _check_where(status, capsys.readouterr().err)
        invalid += status == 2
        if status == 0 and k % 3 == 0:
            _check(main(["evaluate", "--json", str(out)]), capsys.readouterr().err)
    assert invalid >= 15


def test_fuzzed_export_and_drop_options(tmp_path: Path, capsys) -> None:
    """``footopt export`` and ``footopt drop`` with bad option values (and fuzzed landing models to export)."""
    rng = random.Random(800)
    good = REPO / "configs" / "paper_case2.yaml"
    values = ["0", "-1", "nan", "inf", "-inf", "1e300", "1e-300"]
    invalid = 0
    for k in range(30):
        model = good
        if k % 2:
            model = tmp_path / f"m{k}.yaml"
            model.write_text(_dump(_mutate(_landing_model(), rng)), encoding="utf-8")
        out = str(tmp_path / rng.choice([f"e{k}.urdf", f"e{k}.xml", f"e{k}.txt", "no/e.xml"]))
        step = [f"--stop-timestep={rng.choice(values)}"] if rng.random() < 0.5 else []
        status = main(["export", str(model), "-o", out, *step])
        _check_where(status, capsys.readouterr().err)
        invalid += status == 2
        if k % 3 == 0:  # drop: a bad stiffness is refused before MuJoCo runs
            status = main(["drop", str(good), "--json", f"--stiffness={rng.choice(values)}"])
            _check_where(status, capsys.readouterr().err)
            assert status == 2
    assert invalid >= 10
