"""``footopt drop``: a design in MuJoCo beside footopt (its soft contacts of the same law as the
compliant rung: they agree to MuJoCo's integration; both near the rigid answer at 1e8 1/s^2)."""

from __future__ import annotations

import builtins
import json
from pathlib import Path

import numpy as np
import pytest

from optimizer.cli.main import main

REPO = Path(__file__).resolve().parents[2]
pytest.importorskip("mujoco", reason="mujoco is a test dependency")


@pytest.mark.parametrize("case", ["paper_case2", "paper_case3"])
def test_mujoco_matches_the_compliant_rung_and_nears_the_rigid_answer(case, capsys):
    assert main(["drop", str(REPO / "configs" / f"{case}.yaml"), "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    ext, internal = r["external"], r["internal"]
    assert len(ext["mujoco"]) == len(r["contacts"]) and len(internal["mujoco"]) == len(r["joints"])
    mj, soft, rigid = (np.array(ext[k]) for k in ("mujoco", "compliant", "footopt"))
    assert np.max(np.abs(mj - soft)) <= 1e-4 * np.max(soft)  # same law, same step: MuJoCo's own integration
    assert np.max(np.abs(mj - rigid)) <= 1e-2 * np.max(rigid)  # 1e8 1/s^2 is near the rigid limit
    assert r["settings"]["solref"][0] == -1e8 and r["settings"]["steps"] > 10


def test_an_oblique_turning_approach_reaches_mujoco(capsys, tmp_path):
    """velocity_x and angular_velocity reach MuJoCo's initial state: with them the three answers
    still agree, and they differ from the straight-down drop's."""
    text = (REPO / "configs" / "paper_case2.yaml").read_text(encoding="utf-8")
    text = text.replace("  speed: 3.43", "  velocity: [1.2, -3.43]\n  angular_velocity: -2.0", 1)
    assert "velocity: [1.2" in text
    oblique = tmp_path / "oblique.yaml"
    oblique.write_text(text, encoding="utf-8")
    assert main(["drop", str(oblique), "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    assert main(["drop", str(REPO / "configs" / "paper_case2.yaml"), "--json"]) == 0
    straight = json.loads(capsys.readouterr().out)
    mj, soft, rigid = (np.array(r["external"][k]) for k in ("mujoco", "compliant", "footopt"))
    assert np.max(np.abs(mj - soft)) <= 1e-4 * np.max(soft)
    assert np.max(np.abs(mj - rigid)) <= 2e-2 * np.max(rigid)
    assert np.max(np.abs(mj - np.array(straight["external"]["mujoco"]))) > 0.05 * np.max(mj)


def test_the_table_names_the_contact_settings(capsys):
    assert main(["drop", str(REPO / "configs" / "paper_case2.yaml"), "--stiffness", "1e7"]) == 0
    out = capsys.readouterr().out
    assert "solref (-1e+07" in out and "heel[0]" in out and "MuJoCo" in out


@pytest.mark.parametrize("args, where", [
    (["--stiffness", "-1"], "--stiffness"), ([], "nothere.yaml"),
    (["--stiffness", "1e300"], "--stiffness: must be in [1, 1e+16]"),  # the fuzzer's: ran for ever
    (["--stiffness", "1e-300"], "--stiffness: must be in [1, 1e+16]"),  # the fuzzer's: a LinAlgError traceback
])
def test_bad_input_exits_2_naming_it(args, where, capsys, tmp_path):
    model = str(tmp_path / "nothere.yaml") if not args else str(REPO / "configs" / "paper_case2.yaml")
    assert main(["drop", model, *args]) == 2
    err = capsys.readouterr().err
    assert where in err and err.count("\n") == 1


def test_without_mujoco_it_says_how_to_get_it(monkeypatch, capsys):
    real_import = builtins.__import__

    def no_mujoco(name, *a, **k):
        if name == "mujoco":
            raise ImportError("no mujoco")
        return real_import(name, *a, **k)

    monkeypatch.setattr(builtins, "__import__", no_mujoco)
    assert main(["drop", str(REPO / "configs" / "paper_case2.yaml")]) == 2
    assert "pip install mujoco" in capsys.readouterr().err


def test_with_friction_mujoco_meets_the_exact_law_not_the_relaxation(capsys, tmp_path):
    """Case 3 at friction 0.3 (every contact slides): MuJoCo's elliptic cones at 1e8 1/s^2 land
    within 2 % of the exact Newton-Coulomb impulses (heel normal and tangential), where the convex
    relaxation is 20 % high (studies/fidelity/exact_friction.md)."""
    text = (REPO / "configs" / "paper_case3.yaml").read_text(encoding="utf-8").replace("friction: 0.0", "friction: 0.3", 1)
    model = tmp_path / "case3_mu03.yaml"
    model.write_text(text, encoding="utf-8")
    assert main(["drop", str(model), "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    assert r["settings"]["cone"] == "elliptic" and r["external"]["compliant"] is None
    for kind in ("external", "tangential"):
        exact, mj = r[kind]["footopt"][0], r[kind]["mujoco"][0]
        assert abs(mj - exact) <= 0.02 * abs(exact), kind
    assert r["settings"]["rigid_model"] == "friction"


def test_the_exported_mjcf_drops_as_the_bridges_model():
    """footopt drop drops footopt export's MJCF (a freejoint base, contact spheres added at its
    sites): its impulses equal those of the bridge's own model (slides and a hinge) to 1e-6."""
    from impulse_core.evaluate import pre_impact_velocity
    from impulse_core.timedomain.compliant import CompliantSettings, ContactLaw, simulate_impact
    from optimizer.config.model_file import load_model_file
    from optimizer.results.export import to_mjcf
    from optimizer.validation.mujoco_bridge import drop

    model = load_model_file(REPO / "configs" / "paper_case3.yaml")
    tree, scene = model.tree, model.scene
    settings = CompliantSettings(law=ContactLaw.CONSTRAINT, stiffness=1e8)
    soft = simulate_impact(tree, scene, settings)
    steps = int(round(soft.duration / soft.timestep))
    v = pre_impact_velocity(tree.topology(), scene)
    bridge = drop(tree, scene, settings, steps, soft.timestep, v_minus=v)
    exported = drop(tree, scene, settings, steps, soft.timestep, v_minus=v, exported=to_mjcf(tree, scene))
    for a, b in ((exported.external, bridge.external), (exported.internal_magnitude, bridge.internal_magnitude)):
        assert np.abs(a - b).max() <= 1e-6 * np.abs(b).max()
    assert "<freejoint" in exported.mjcf and "<freejoint" not in bridge.mjcf


def test_a_spatial_design_drops_as_footopt_exports_it(capsys, tmp_path):
    """A spatial file (splayed toes, an oblique turning approach): MuJoCo on the exported MJCF
    meets the spatial compliant rung (same law, same step) and nears the rigid answer."""
    assert main(["drop", str(REPO / "configs" / "spatial_case3.yaml"), "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    assert r["settings"]["space"] == "spatial" and len(r["external"]["mujoco"]) == len(r["contacts"])
    mj, soft, rigid = (np.array(r["external"][k]) for k in ("mujoco", "compliant", "footopt"))
    assert np.max(np.abs(mj - soft)) <= 1e-3 * np.max(soft)
    assert np.max(np.abs(mj - rigid)) <= 1e-2 * np.max(rigid)
    mj_j, soft_j = (np.array(r["internal"][k]) for k in ("mujoco", "compliant"))
    assert np.max(np.abs(mj_j - soft_j)) <= 1e-3 * np.max(soft_j)


def _spatial_file(tmp_path, source: str, old: str, new: str) -> Path:
    text = (REPO / "configs" / source).read_text(encoding="utf-8")
    assert old in text
    path = tmp_path / f"edited_{source}"
    path.write_text(text.replace(old, new, 1), encoding="utf-8")
    return path


def test_a_splayed_foot_with_friction_meets_the_exact_cone(capsys, tmp_path):
    """configs/spatial_case3.yaml at friction 0.5 (every contact slides): MuJoCo's elliptic cones
    (condim 3) beside footopt's exact circular cone. Measured (same run, gap / largest value):
    normal 2.3 % at 1e8 1/s^2 and 2.8 % at 1e9, tangential vectors 13 % and 15 %, internal 3.4 %
    and 4.1 %: stiffer contact does not close it, so the gap is the law, not the softness: footopt
    puts Coulomb's cone on the whole impulse (the slip after the impact), MuJoCo integrates the
    force while the slip turns during the impact (its tangential impulses lie at 0.92 to 1.0 of
    mu x normal). Stated: 5 % and 20 %. Each tangential impulse opposes footopt's slip after the
    impact and lies inside mu x normal."""
    from impulse_core.evaluate import evaluate
    from impulse_core.kinematics.spatial import SPATIAL
    from optimizer.config.model_file import load_model_file

    mu = 0.5
    path = _spatial_file(tmp_path, "spatial_case3.yaml", "  friction: 0.0\n", f"  friction: {mu}\n")
    assert main(["drop", str(path), "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    s = r["settings"]
    assert (s["cone"], s["condim"], s["rigid_model"], s["friction"]) == ("elliptic", 3, "friction", mu)
    n_f, n_m = np.array(r["external"]["footopt"]), np.array(r["external"]["mujoco"])
    t_f, t_m = np.array(r["tangential"]["footopt"]), np.array(r["tangential"]["mujoco"])
    assert t_m.shape == (len(r["contacts"]), 2)  # [t_x, t_z] per contact
    assert np.max(np.abs(n_m - n_f)) <= 0.05 * np.max(n_f)
    assert np.max(np.linalg.norm(t_m - t_f, axis=1)) <= 0.2 * np.max(np.linalg.norm(t_f, axis=1))
    assert np.all(np.linalg.norm(t_m, axis=1) <= mu * n_m * (1 + 1e-6))
    assert np.all(np.linalg.norm(t_m, axis=1) >= 0.8 * mu * n_m)  # sliding: near the cone's edge
    model = load_model_file(path)
    slip = evaluate(model.tree, model.scene, None, SPATIAL).tangent_velocity  # (x, z) after the impact
    assert np.all(np.linalg.norm(slip, axis=1) > 1e-3) and np.all(np.sum(t_m * slip, axis=1) < 0)
    assert main(["drop", str(path)]) == 0
    assert "condim 3" in capsys.readouterr().out


def test_a_heightfield_drop_lands_on_the_heightfield(capsys):
    """configs/spatial_heightfield.yaml (rising under the toes, forward and sideways): each
    contact lands on the heightfield's tangent plane at its touchdown point; MuJoCo's first touch
    is at the heightfield's height and normal there (the toes' normals tilt back and to -z), and
    its impulses meet the compliant rung (same law) and footopt's sequential rigid model. Measured
    (same run, gap / largest value): normal 2.9e-3 at 1e8 1/s^2, 5.4e-4 at 1e9 against the rigid
    model (softness: it closes as k^-1/2 ... k^-1), 9.4e-4 against the compliant rung."""
    from impulse_core.model import heightfield as hfield
    from optimizer.config.model_file import load_model_file

    path = REPO / "configs" / "spatial_heightfield.yaml"
    assert main(["drop", str(path), "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    assert r["settings"]["rigid_model"] == "sequential" and "tangent plane" in r["settings"]["ground"]
    ground = load_model_file(path).scene.heightfield
    P, N = np.array(r["touchdown"]["point"]), np.array(r["touchdown"]["normal"])
    assert np.abs(P[:, 1] - hfield.height(ground, P[:, 0], P[:, 2])).max() <= 1e-6
    assert np.abs(N - hfield.normal(ground, P[:, 0], P[:, 2])).max() <= 1e-3
    assert np.all(N[1:, 0] < -0.04) and np.all(N[1:, 2] < -0.01) and abs(N[0, 0]) < 1e-9  # toes on the slope
    n_f, n_c, n_m = (np.array(r["external"][k]) for k in ("footopt", "compliant", "mujoco"))
    assert np.max(np.abs(n_m - n_c)) <= 2e-3 * np.max(n_c)
    assert np.max(np.abs(n_m - n_f)) <= 1e-2 * np.max(n_f)
    i_c, i_m = np.array(r["internal"]["compliant"]), np.array(r["internal"]["mujoco"])
    assert np.max(np.abs(i_m - i_c)) <= 2e-3 * np.max(i_c)


@pytest.mark.parametrize("source, old, new, normal, tangential", [
    ("uneven_terrain.yaml", "  friction: 0.0", "  friction: 0.4", 0.04, 0.15),
    ("spatial_case3.yaml", "  friction: 0.0\n",
     "  friction: 0.5\n  heightfield: {x: [-1.0, 1.0], z: [-1.0, 1.0], heights: [[-0.015, -0.005], [0.005, 0.015]]}\n",
     0.05, 0.2),
])
def test_friction_on_uneven_ground_meets_the_rigid_landing(source, old, new, normal, tangential, capsys, tmp_path):
    """Friction on uneven ground: case 2 on configs/uneven_terrain.yaml (a heel on the flat, a toe
    on a 13 % slope) at friction 0.4, and spatial case 3 on a heightfield sloping 1 % forward and
    0.5 % sideways at 0.5. MuJoCo's contacts on each contact's tangent plane (elliptic cones, condim
    3) beside footopt's rigid landing (the sequential model, Coulomb's law on each impulse), the
    tangential impulses along the ground's tangents. Measured (same run, gap / largest value): the
    plane: normal 1.8 %, tangential 9.7 %; space: normal 2.0 %, tangential 15 % (as on flat
    ground, the law's gap: MuJoCo integrates the force while the slip turns). Stated: 4 % and 15 %,
    5 % and 20 %."""
    path = _spatial_file(tmp_path, source, old, new)
    assert main(["drop", str(path), "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    mu = r["settings"]["friction"]
    assert r["settings"]["rigid_model"] == "sequential" and r["settings"]["condim"] == 3 and mu > 0
    n_f, n_m = np.array(r["external"]["footopt"]), np.array(r["external"]["mujoco"])
    t_f, t_m = (np.array(r["tangential"][k]).reshape(len(n_f), -1) for k in ("footopt", "mujoco"))
    assert np.max(np.abs(n_m - n_f)) <= normal * np.max(n_f)
    assert np.max(np.linalg.norm(t_m - t_f, axis=1)) <= tangential * np.max(np.linalg.norm(t_f, axis=1))
    assert np.all(np.linalg.norm(t_m, axis=1) <= mu * n_m * (1 + 1e-6))


@pytest.mark.parametrize("d", [2, 3])
def test_mujoco_tangential_impulses_lie_along_footopt_s_ground_tangents(d):
    """mujoco_tangential on steep grounds: an impulse built from a normal part and tangential parts
    along footopt's tangent basis at the touchdown normal gives those parts back (1e-12); a
    contact that never touched reads on flat ground (x, and z in space)."""
    from types import SimpleNamespace

    from impulse_core.kinematics.spatial import PLANAR, SPATIAL
    from impulse_core.timedomain.events.point import tangent_basis
    from optimizer.cli.drop import mujoco_tangential

    rng = np.random.default_rng(d)
    normal = np.column_stack([rng.uniform(-0.6, 0.6, 5), np.ones(5), rng.uniform(-0.6, 0.6, 5)])[:, :d]
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    fn, ft = rng.uniform(0.1, 1.0, 5), rng.uniform(-0.3, 0.3, (5, d - 1))
    vector = normal * fn[:, None] + np.einsum("kad,ka->kd", tangent_basis(normal), ft)
    touch = np.zeros((5, 3))
    touch[:, :d] = normal
    touch[4] = np.nan  # never touched: flat ground's tangents
    vector[4] = [0.2, 0.7, -0.1][:d]
    ft[4] = [0.2, -0.1][: d - 1]
    mj = SimpleNamespace(external=fn, external_vector=vector, touchdown_normal=touch)
    got = mujoco_tangential(mj, PLANAR if d == 2 else SPATIAL)
    assert np.max(np.abs(np.reshape(got, ft.shape) - ft)) <= 1e-12


def test_bad_spatial_drops_exit_2_naming_the_field(capsys, tmp_path):
    bad_grid = _spatial_file(tmp_path, "spatial_case3.yaml", "  friction: 0.0\n",
                             "  friction: 0.0\n  heightfield: {x: [1, 0], z: [0], heights: [[0], [0]]}\n")
    for path, where in ((bad_grid, "scene.heightfield.x[1]"),):
        assert main(["drop", str(path)]) == 2
        err = capsys.readouterr().err
        assert where in err and err.count("\n") == 1, err


def test_centres_of_mass_off_the_rods_reach_mujoco(capsys, tmp_path):
    """Paper case 2 with its thigh's and shank's centres of mass off the rods (com_offset): MuJoCo
    (the exported MJCF, which writes them) agrees with the compliant rung as closely as without
    offsets, joints included; the offsets move the knee's impulse, so they reach both."""
    text = (REPO / "configs" / "paper_case2.yaml").read_text(encoding="utf-8")
    for angle, dy in (("-1.0928283971375934", 0.2), ("-0.7322878470240894", -0.15)):
        text = text.replace(f"      angle: {angle}", f"      com_offset: [{dy}, 0]\n      angle: {angle}", 1)
    assert text.count("com_offset") == 2
    (tmp_path / "offsets.yaml").write_text(text, encoding="utf-8")
    runs = []
    for path in (tmp_path / "offsets.yaml", REPO / "configs" / "paper_case2.yaml"):
        assert main(["drop", str(path), "--json"]) == 0
        runs.append(json.loads(capsys.readouterr().out))
    r, rods = runs
    for kind in ("external", "internal"):
        mj, soft = np.array(r[kind]["mujoco"]), np.array(r[kind]["compliant"])
        assert np.max(np.abs(mj - soft)) <= 1e-4 * np.max(soft), kind
    mj, rigid = np.array(r["external"]["mujoco"]), np.array(r["external"]["footopt"])
    assert np.max(np.abs(mj - rigid)) <= 1e-2 * np.max(rigid)
    knee, knee_rods = r["internal"]["mujoco"][0], rods["internal"]["mujoco"][0]
    assert abs(knee / knee_rods - 1) > 0.1 and knee == pytest.approx(r["internal"]["compliant"][0], rel=1e-4)
