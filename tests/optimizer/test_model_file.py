"""Model files: YAML 1.2 numbers, parsing and defaults, extensions, errors, writing."""

from __future__ import annotations

import dataclasses
import math
import string
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from impulse_core.errors import FootoptError
from impulse_core.model.terrain import FLAT, Terrain
from impulse_core.model.tree import UNIFORM_COM, UNIFORM_GYRATION, Body, ContactSelection, JointKind, Scene, Tree
from optimizer.errors import ConfigError
from optimizer.config.model_file import (
    ModelFile,
    Reference,
    dump_model_file,
    format_model_file,
    load_model_file,
    load_yaml,
    parse_model,
)
from tests.optimizer.conftest import LEG_YAML

ROOT = Path(__file__).resolve().parents[2]

# --------------------------------------------------------------------------------------------
# YAML 1.2 scalars


@pytest.mark.parametrize(
    ("text", "value"),
    [
        ("1e-6", 1e-6),
        ("2E3", 2000.0),
        (".5", 0.5),
        ("-1.5e+3", -1500.0),
        ("+.5", 0.5),
        ("1.", 1.0),
        ("3", 3),
        ("-7", -7),
        ("010", 10),  # decimal in YAML 1.2 (octal 8 in YAML 1.1)
        ("0o10", 8),
        ("0x1F", 31),
        ("true", True),
        ("False", False),
        ("~", None),
        ("null", None),
        ("", None),
        ("yes", "yes"),  # a boolean in YAML 1.1
        ("off", "off"),
        ("1_000", "1_000"),
        ("2021-05-01", "2021-05-01"),  # a date in YAML 1.1
        ("1e", "1e"),
        ("e5", "e5"),
    ],
)
def test_scalars_read_as_yaml_1_2(text: str, value: object) -> None:
    got = load_yaml(f"x: {text}\n")["x"]
    assert got == value
    assert type(got) is type(value)


def test_pyyaml_alone_reads_1e_minus_6_as_a_string() -> None:
    # why the loader exists: this must keep failing for plain PyYAML, and pass for ours
    assert yaml.safe_load("x: 1e-6")["x"] == "1e-6"
    assert load_yaml("x: 1e-6")["x"] == 1e-6


@pytest.mark.parametrize("text", [".inf", "-.inf", ".Inf", "+.INF"])
def test_infinities_are_floats(text: str) -> None:
    assert math.isinf(load_yaml(f"x: {text}")["x"])


def test_nan_is_a_float() -> None:
    assert math.isnan(load_yaml("x: .nan")["x"])


def test_json_is_read_too() -> None:
    data = load_yaml('{"scene": {"speed": 1e-3, "restitution": 5E-1}, "list": [1, 2.5, null, true]}')
    assert data == {"scene": {"speed": 1e-3, "restitution": 0.5}, "list": [1, 2.5, None, True]}


def test_duplicate_key_is_an_error_with_its_path() -> None:
    with pytest.raises(ConfigError, match=r"^a\.b\[1\]\.c: duplicate key"):
        load_yaml("a:\n  b:\n    - {c: 1}\n    - {c: 1, c: 2}\n")


def test_syntax_error_names_line_and_column() -> None:
    with pytest.raises(ConfigError, match=r"^YAML syntax error at line 2, column 3: mapping values are not allowed"):
        load_yaml("a: 1\n b: 2\n")
    with pytest.raises(ConfigError, match=r"flow sequence at line 2, column 4\)$"):
        load_yaml("a: 1\nb: [1, 2\n")


# --------------------------------------------------------------------------------------------
# Parsing


def test_leg_file_parses_to_the_hand_built_tree(leg_file: Path, leg_tree: Tree, leg_scene: Scene) -> None:
    model = load_model_file(leg_file)
    assert model.tree == leg_tree
    assert model.scene == leg_scene
    assert model.reference is None
    assert model.notes is None
    assert model.path == leg_file


def test_defaults(leg_file: Path) -> None:
    model = load_model_file(leg_file)
    thigh, shank, foot = model.tree.bodies
    assert (thigh.parent, shank.parent, foot.parent) == (None, 0, 1)
    assert shank.at == 1.0 and shank.joint is JointKind.REVOLUTE
    assert shank.com == UNIFORM_COM and shank.gyration == UNIFORM_GYRATION
    assert thigh.contacts == () and foot.contacts == (0.0, 1.0)
    assert model.scene.friction == 0.0
    assert model.scene.contact_tolerance == Scene().contact_tolerance


@pytest.mark.parametrize(
    ("line", "selection"),
    [
        ("", ContactSelection.LOWEST),
        ("  contacts: lowest\n", ContactSelection.LOWEST),
        ("  contacts: all\n", ContactSelection.ALL),
    ],
)
def test_contact_selection(write, line: str, selection: ContactSelection) -> None:
    text = LEG_YAML.replace("  contacts: all\n", line)
    assert load_model_file(write(text)).scene.selection is selection


def test_without_terrain_keys_the_ground_is_flat(leg_file: Path) -> None:
    scene = load_model_file(leg_file).scene
    assert scene.terrain == FLAT and scene.base_x == 0.0


def test_terrain_and_base_x_are_read(write) -> None:
    text = LEG_YAML.replace("  contacts: all\n", "  terrain: [[-1, 0], [0.5, 0.0], [1e0, 2E-2]]\n  base_x: -0.25\n")
    scene = load_model_file(write(text)).scene
    assert scene.terrain == Terrain((-1.0, 0.5, 1.0), (0.0, 0.0, 0.02))
    assert scene.base_x == -0.25
    one = load_model_file(write(LEG_YAML.replace("  contacts: all\n", "  terrain: [[3, 0.1]]\n"))).scene.terrain
    assert one == Terrain((3.0,), (0.1,)) and one.is_flat


@pytest.mark.parametrize(
    ("line", "message"),
    [
        ("  terrain: []", r"^scene\.terrain: must be a non-empty list"),
        ("  terrain: [0, 1]", r"^scene\.terrain\[0\]: must be a pair \[x, y\]"),
        ("  terrain: {x: 0}", r"^scene\.terrain: must be a non-empty list"),
        ("  terrain: [[0, 0], [1]]", r"^scene\.terrain\[1\]: must be a pair"),
        ("  terrain: [[0, 0], [1, 2, 3]]", r"^scene\.terrain\[1\]: must be a pair"),
        ("  terrain: [[0, 0], [1, yes]]", r"^scene\.terrain\[1\]\[1\]: must be a number"),
        ("  terrain: [[0, 0], [true, 1]]", r"^scene\.terrain\[1\]\[0\]: must be a number"),
        ("  terrain: [[0, 0], [0, 1]]", r"^scene\.terrain\[1\]: x must increase strictly"),
        ("  terrain: [[0, 0], [1, 0], [0.5, 1]]", r"^scene\.terrain\[2\]: x must increase strictly"),
        ("  terrain: [[0, .nan]]", r"^scene\.terrain\[0\]\[1\]: must be a finite number"),
        ("  base_x: east", r"^scene\.base_x: must be a number"),
        ("  base_x: .inf", r"^scene\.base_x: must be a finite number"),
        ("  terain: [[0, 0]]", r"^scene\.terain: unknown key \(did you mean 'terrain'\?"),
    ],
)
def test_bad_terrain_is_named_by_its_path(write, line: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        load_model_file(write(LEG_YAML.replace("  contacts: all\n", line + "\n")))


def test_scene_validates_base_x_and_stays_hashable() -> None:
    with pytest.raises(FootoptError, match=r"^scene\.base_x: must be a finite number"):
        Scene(base_x=math.nan)
    with pytest.raises(FootoptError, match=r"^scene\.terrain: must be a Terrain"):
        Scene(terrain=[[0.0, 0.0]])  # type: ignore[arg-type]
    ramp = Terrain((0.0, 1.0), (0.0, 0.1))
    assert hash(Scene(terrain=ramp, base_x=0.5)) == hash(Scene(terrain=Terrain((0.0, 1.0), (0.0, 0.1)), base_x=0.5))
    assert Scene() == Scene(terrain=FLAT, base_x=0.0)


def test_every_field(write) -> None:
    text = LEG_YAML.replace("  contacts: all\n", "  friction: 0.25\n  contact_tolerance: 1e-4\n").replace(
        "      angle: 1.2\n",
        "      angle: 1.2\n      at: .5\n      joint: fixed\n      com: 0.25\n      inertia: 2e-3\n",
    )
    model = load_model_file(write(text))
    foot = model.tree.bodies[2]
    assert (foot.at, foot.joint, foot.com) == (0.5, JointKind.FIXED, 0.25)
    assert model.scene.friction == 0.25 and model.scene.contact_tolerance == 1e-4


def test_inertia_becomes_gyration(write) -> None:
    text = LEG_YAML.replace("      angle: 1.2\n", "      angle: 1.2\n      inertia: 2e-3\n")
    foot = load_model_file(write(text)).tree.bodies[2]
    assert foot.gyration == math.sqrt(2e-3 / 0.3) / 0.25
    assert foot.inertia == pytest.approx(2e-3, rel=1e-15)


def test_uniform_inertia_is_the_default(write) -> None:
    uniform = 0.3 * 0.25**2 / 12
    text = LEG_YAML.replace("      angle: 1.2\n", f"      angle: 1.2\n      inertia: {uniform!r}\n")
    foot = load_model_file(write(text)).tree.bodies[2]
    assert foot.gyration == pytest.approx(UNIFORM_GYRATION, rel=1e-15)


def test_gyration_extension(write) -> None:
    text = LEG_YAML.replace("      angle: 1.2\n", "      angle: 1.2\n      gyration: 0.1\n")
    assert load_model_file(write(text)).tree.bodies[2].gyration == 0.1


def test_reference_and_notes(foot_file: Path) -> None:
    model = load_model_file(foot_file)
    assert model.reference == Reference(
        source="a made-up table", external=(None, 0.9), internal=(0.25, None, 0.8), external_norm=0.9
    )
    text = foot_file.read_text() + "notes: |\n  two lines\n  of notes\n"
    assert parse_model(load_yaml(text)).notes == "two lines\nof notes\n"


def test_parse_model_takes_loaded_data(leg_tree: Tree) -> None:
    data = yaml.safe_load(LEG_YAML)
    model = parse_model(data, "somewhere.yaml")
    assert model.tree == leg_tree
    assert model.path == Path("somewhere.yaml")


def test_parent_listed_later_says_list_parents_first() -> None:
    data = load_yaml(LEG_YAML.replace("parent: thigh", "parent: foot").replace("parent: shank", "parent: thigh"))
    with pytest.raises(
        ConfigError, match=r"^model\.bodies\[1\]\.parent: 'foot' is listed after 'shank'; list parents first$"
    ):
        parse_model(data)


def test_parent_cycle_is_named() -> None:
    data = load_yaml(LEG_YAML.replace("parent: thigh", "parent: foot"))
    with pytest.raises(ConfigError, match=r"^model\.bodies\[1\]\.parent: .*cycle: shank -> foot -> shank$"):
        parse_model(data)


def test_errors_are_config_errors_with_the_file_as_source(write) -> None:
    path = write(LEG_YAML.replace("mass: 0.3", "mass: -1"))
    with pytest.raises(ConfigError) as info:
        load_model_file(path)
    assert str(info.value) == "model.bodies[2].mass: must be a finite number > 0, got -1.0"
    assert info.value.source == path
    assert isinstance(info.value, FootoptError)


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="^file not found$"):
        load_model_file(tmp_path / "nope.yaml")


def test_reference_lengths_are_checked_against_the_tree(leg_tree: Tree, leg_scene: Scene) -> None:
    with pytest.raises(ConfigError, match=r"^reference\.external: has 3 entries, the model declares 2 contacts"):
        ModelFile(leg_tree, leg_scene, Reference(external=(1.0, 2.0, 3.0)))
    with pytest.raises(ConfigError, match=r"^reference\.internal: has 1 entries, the model has 2 joints"):
        ModelFile(leg_tree, leg_scene, Reference(internal=(1.0,)))


# --------------------------------------------------------------------------------------------
# Writing


def test_round_trip(tmp_path: Path, foot_file: Path) -> None:
    model = load_model_file(foot_file)
    again = load_model_file(dump_model_file(model, tmp_path / "again.yaml"))
    assert again == model
    assert again.path == tmp_path / "again.yaml"


def test_terrain_and_base_x_round_trip(tmp_path: Path, leg_tree: Tree) -> None:
    for terrain, base_x in ((Terrain((-1.0, 0.45, 0.75), (0.0, 0.0, 0.04)), -0.25), (Terrain((2.0,), (0.1,)), 0.0)):
        model = ModelFile(leg_tree, Scene(terrain=terrain, base_x=base_x))
        again = load_model_file(dump_model_file(model, tmp_path / "terrain.yaml", overwrite=True))
        assert again == model and again.scene.terrain == terrain and again.scene.base_x == base_x
    assert load_model_file(ROOT / "configs" / "uneven_terrain.yaml").scene.terrain == Terrain(
        (-1.0, 0.45, 0.75), (0.0, 0.0, 0.04)
    )


def test_defaults_are_left_out(leg_tree: Tree, leg_scene: Scene) -> None:
    text = format_model_file(ModelFile(leg_tree, leg_scene))
    for key in (
        "at:",
        "joint:",
        "com:",
        "inertia:",
        "gyration:",
        "contact_tolerance:",
        "reference:",
        "notes:",
        "terrain:",
        "base_x:",
    ):
        assert key not in text
    assert "parent: shank" in text  # parents are written as names


def test_dumped_numbers_read_the_same_in_yaml_1_1(tmp_path: Path, leg_tree: Tree) -> None:
    scene = Scene(speed=1e-6, restitution=0.5, contact_tolerance=2.5e-7)
    text = format_model_file(ModelFile(leg_tree, scene))
    assert yaml.safe_load(text)["scene"]["speed"] == 1e-6
    assert load_yaml(text)["scene"]["speed"] == 1e-6


def test_header_comment(tmp_path: Path, leg_tree: Tree, leg_scene: Scene) -> None:
    path = dump_model_file(leg_tree, tmp_path / "leg.yaml", leg_scene, header_comment="design 7\nfront: 3 of 12")
    text = path.read_text()
    assert text.startswith("# design 7\n# front: 3 of 12\n")
    assert load_model_file(path) == ModelFile(leg_tree, leg_scene)


def test_refuses_to_overwrite(tmp_path: Path, leg_tree: Tree, leg_scene: Scene) -> None:
    path = tmp_path / "leg.yaml"
    path.write_text("precious\n")
    with pytest.raises(ConfigError, match="already exists"):
        dump_model_file(leg_tree, path, leg_scene)
    assert path.read_text() == "precious\n"
    dump_model_file(leg_tree, path, leg_scene, overwrite=True)
    assert load_model_file(path).tree == leg_tree


def test_a_tree_needs_a_scene(tmp_path: Path, leg_tree: Tree) -> None:
    with pytest.raises(TypeError):
        dump_model_file(leg_tree, tmp_path / "leg.yaml")


def test_odd_names_round_trip(tmp_path: Path, leg_scene: Scene) -> None:
    names = ("yes", "a b", 'quo"te', "ü\u2028\x85\x00", "😀")
    bodies = [Body(names[0], None, 1.0, 1.0, 0.0)]
    bodies += [Body(n, i, 1.0, 1.0, 0.1, contacts=(1.0,)) for i, n in enumerate(names[1:])]
    model = ModelFile(Tree(tuple(bodies)), leg_scene, notes="line 1\nline 2: 'x' # not a comment")
    assert load_model_file(dump_model_file(model, tmp_path / "odd.yaml")) == model


_fraction = st.floats(0.0, 1.0)
_value = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)
_positive = st.floats(1e-9, 1e9, allow_nan=False, exclude_min=False)


@st.composite
def terrains(draw: st.DrawFn) -> Terrain:
    """Ground profiles: 1-5 points, x strictly increasing."""
    xs = sorted(draw(st.lists(_value, min_size=1, max_size=5, unique=True)))
    return Terrain(tuple(xs), tuple(draw(st.lists(_value, min_size=len(xs), max_size=len(xs)))))


@st.composite
def model_files(draw: st.DrawFn) -> ModelFile:
    n = draw(st.integers(1, 5))
    names = draw(
        st.lists(
            st.text(string.ascii_letters + string.digits + " _-:#'\"ü\n", min_size=1, max_size=6).filter(str.strip),
            min_size=n,
            max_size=n,
            unique=True,
        )
    )
    bodies = []
    for i in range(n):
        bodies.append(
            Body(
                name=names[i],
                parent=None if i == 0 else draw(st.integers(0, i - 1)),
                length=draw(_positive),
                mass=draw(_positive),
                angle=draw(_value),
                at=draw(_fraction),
                joint=draw(st.sampled_from(JointKind)),
                contacts=tuple(draw(st.lists(_fraction, max_size=3))),
                com=draw(st.one_of(st.just(UNIFORM_COM), _fraction)),
                gyration=draw(st.one_of(st.just(UNIFORM_GYRATION), st.floats(0.0, 2.0))),
            )
        )
    if not any(b.contacts for b in bodies):
        bodies[-1] = dataclasses.replace(bodies[-1], contacts=(1.0,))
    tree = Tree(tuple(bodies))
    scene = Scene(
        speed=draw(_positive),
        restitution=draw(_fraction),
        friction=draw(st.floats(0.0, 10.0)),
        selection=draw(st.sampled_from(ContactSelection)),
        contact_tolerance=draw(st.floats(0.0, 1.0)),
        terrain=draw(st.one_of(st.just(FLAT), terrains())),
        base_x=draw(st.one_of(st.just(0.0), _value)),
    )
    maybe = st.one_of(st.none(), _value)
    reference = draw(
        st.one_of(
            st.none(),
            st.builds(
                Reference,
                source=st.one_of(st.none(), st.text(max_size=10)),
                external=st.one_of(st.none(), st.tuples(*[maybe] * len(tree.contacts))),
                internal=st.one_of(st.none(), st.tuples(*[maybe] * (n - 1))),
                external_norm=maybe,
                internal_norm=maybe,
                note=st.one_of(st.none(), st.text(max_size=10)),
            ),
        )
    )
    notes = draw(st.one_of(st.none(), st.text(max_size=20)))
    return ModelFile(tree, scene, reference, notes)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(model=model_files())
def test_round_trip_of_random_model_files(tmp_path: Path, model: ModelFile) -> None:
    path = dump_model_file(model, tmp_path / "random.yaml", overwrite=True)
    assert load_model_file(path) == model


#: The example of MODEL_FORMAT.md, verbatim (comments included).
CONTRACT_EXAMPLE = """\
scene:
  speed: 3.43        # approach speed (m/s) of the whole model, straight down (-y); > 0
  restitution: 0.8   # Newton's coefficient e, 0 <= e <= 1
  friction: 0.0      # Coulomb coefficient; 0 = frictionless
  contacts: all      # 'all': every declared contact hits at the same instant (the paper's assumption).
                     # Default: the ground is at the lowest contact point, and contacts within a
                     # tolerance of it are the ones that hit.
model:
  bodies:            # a tree, listed parents first; the first body is the floating base
    - name: thigh
      length: 0.7
      mass: 1.0
      angle: -1.2    # base: absolute angle of its x axis; every other body: joint angle relative to its parent
    - name: shank
      parent: thigh
      at: 1.0        # where the joint sits on the parent, as a fraction of the parent's length (default 1.0, its tip)
      length: 0.7
      mass: 1.0
      angle: 0.6
      joint: revolute  # default; 'fixed' welds the body to its parent
    - name: heel
      parent: shank
      length: 0.15
      mass: 0.1
      angle: 2.0
      contacts: [1.0]  # contact points on this body, as fractions of its length (1.0 = tip)
"""


def test_the_contracts_example(write) -> None:
    model = load_model_file(write(CONTRACT_EXAMPLE))
    assert model.scene == Scene(speed=3.43, restitution=0.8, friction=0.0, selection=ContactSelection.ALL)
    assert model.tree == Tree(
        (
            Body("thigh", None, 0.7, 1.0, -1.2),
            Body("shank", 0, 0.7, 1.0, 0.6, at=1.0, joint=JointKind.REVOLUTE),
            Body("heel", 1, 0.15, 0.1, 2.0, contacts=(1.0,)),
        )
    )


def test_the_approach_keys_read_write_and_refuse(write, capsys) -> None:
    """``velocity: [vx, vy]`` and ``angular_velocity`` (MODEL_FORMAT "The approach"): read into
    the scene, written back equal, and refused with the field named when wrong."""
    from optimizer.cli.main import main
    from tests.optimizer.conftest import LEG_YAML

    text = LEG_YAML.replace("  speed: 2.0\n", "  velocity: [0.4, -2.0]\n  angular_velocity: -0.3\n")
    model = load_model_file(write(text, "oblique.yaml"))
    assert (model.scene.velocity_x, model.scene.speed, model.scene.angular_velocity) == (0.4, 2.0, -0.3)
    again = load_model_file(write(format_model_file(model), "again.yaml"))
    assert again.scene == model.scene
    bad = {
        "  velocity: [0.4, -2.0]\n  speed: 2.0\n": "scene.velocity: give speed",
        "  velocity: [0.4, 2.0]\n": "scene.velocity[1]: must be < 0",
        "  velocity: [0.4]\n": "scene.velocity: must be [vx, vy]",
        "  velocity: [.nan, -2.0]\n": "scene.velocity[0]",
        "  speed: 2.0\n  angular_velocity: fast\n": "scene.angular_velocity",
    }
    for block, message in bad.items():
        path = write(LEG_YAML.replace("  speed: 2.0\n", block), "bad.yaml")
        assert main(["evaluate", str(path)]) == 2
        err = capsys.readouterr().err
        assert message in err and "Traceback" not in err, err


# --------------------------------------------------------------------------------------------
# Joint laws, gravity and duration (the whole landing)

_KNEE = "      angle: 0.5\n"
_SPRUNG = (
    "      angle: 0.5\n      stiffness: 120\n      damping: 2.5\n      rest: 0.4\n"
    "      limits: [-1, 1e0]\n      stop_restitution: 0.2\n"
)


def test_joint_laws_gravity_and_duration_are_read_and_round_trip(write) -> None:
    from impulse_core.model.joints import FREE, JointLaw

    text = LEG_YAML.replace(_KNEE, _SPRUNG).replace("  contacts: all\n", "  contacts: all\n  gravity: 9.81\n  duration: 0.25\n")
    model = load_model_file(write(text))
    assert model.joints == (FREE, JointLaw(120.0, 2.5, 0.4, (-1.0, 1.0), 0.2), FREE)
    assert model.scene.gravity == 9.81 and model.scene.duration == 0.25
    again = parse_model(load_yaml(format_model_file(model)))
    assert again.joints == model.joints and again.scene == model.scene
    assert load_model_file(write(LEG_YAML)).joints == ()


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        (_KNEE, _KNEE + "      stiffness: -1\n", r"^model\.bodies\[1\]\.stiffness: must be a finite number >= 0"),
        (_KNEE, _KNEE + "      damping: soft\n", r"^model\.bodies\[1\]\.damping: must be a number"),
        (_KNEE, _KNEE + "      limits: [1, -1]\n", r"^model\.bodies\[1\]\.limits: must be \[lo, hi\] with lo < hi"),
        (_KNEE, _KNEE + "      limits: [0.6, 1]\n", r"^model\.bodies\[1\]\.limits: the touchdown angle 0\.5 lies outside"),
        (_KNEE, _KNEE + "      limits: 1\n", r"^model\.bodies\[1\]\.limits: must be \[lo, hi\]"),
        (_KNEE, _KNEE + "      stop_restitution: 2\n", r"^model\.bodies\[1\]\.stop_restitution: must be in \[0, 1\]"),
        ("      angle: -1.3\n", "      angle: -1.3\n      stiffness: 5\n", r"^model\.bodies\[0\]\.stiffness: applies to revolute joints only"),
        (_KNEE, _KNEE + "      stifness: 5\n", r"^model\.bodies\[1\]\.stifness: unknown key \(did you mean 'stiffness'\?"),
        ("  contacts: all\n", "  contacts: all\n  gravity: -9.81\n", r"^scene\.gravity: must be >= 0"),
        ("  contacts: all\n", "  contacts: all\n  duration: 0\n", r"^scene\.duration: must be a finite number > 0"),
    ],
)
def test_bad_joint_laws_are_named_by_their_path(write, old: str, new: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        load_model_file(write(LEG_YAML.replace(old, new, 1)))
