"""``footopt export`` on a spatial file with ``scene.heightfield``: the MJCF carries the ground as a
MuJoCo ``hfield`` (read back by MuJoCo itself: its nodes are footopt's heights, a ray down hits
them, a sphere placed on a node touches there, the robot's first contact touches footopt's
ground), the triangulation's departure from the bilinear patch is the number the file states,
an uneven grid is written on a common step or refused in one line, and the URDF says it has no
terrain."""

from __future__ import annotations

import dataclasses
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from impulse_core.evaluate import touchdown_geometry
from impulse_core.kinematics.spatial import SPATIAL
from impulse_core.model import heightfield as hfield
from impulse_core.model.heightfield import Heightfield
from impulse_core.model.tree import Scene, Tree
from impulse_core.timedomain.compliant import touchdown_configuration
from optimizer.cli.main import main
from optimizer.config.model_file import load_model_file
from optimizer.errors import ConfigError
from optimizer.results.export import (
    HFIELD_NAME,
    HFIELD_ROUNDING,
    HFIELD_SKIRT_MAX_CELLS,
    base_pose,
    ground_cover,
    regular_heightfield,
    to_mjcf,
    to_urdf,
)
from tests.conftest import report

mujoco = pytest.importorskip("mujoco")

REPO = Path(__file__).resolve().parents[2]
EXAMPLE = load_model_file(REPO / "configs" / "spatial_heightfield.yaml")
RNG = np.random.default_rng(16)

FIELDS = {
    # the repository's example: x spacings 0.6 and 0.4 (written on a step of 0.2), a twisted cell
    "example": EXAMPLE.scene.heightfield,
    # a regular grid of random heights, some below zero
    "random": Heightfield.from_arrays(np.linspace(-0.4, 0.6, 6), np.linspace(-0.25, 0.35, 5),
                                      RNG.uniform(-0.03, 0.05, (6, 5))),
    # uneven both ways (steps 0.05 and 0.1), random heights
    "uneven": Heightfield.from_arrays([-0.3, -0.2, -0.15, 0.2, 0.6], [-0.3, 0.0, 0.1, 0.3],
                                      RNG.uniform(0.0, 0.04, (5, 4))),
    # one z point: the ground varies along x only (footopt: constant along z)
    "one row": Heightfield.from_arrays([-0.3, 0.1, 0.7], [0.05], [[0.0], [0.02], [-0.01]]),
}


def _scene(hf: Heightfield) -> Scene:
    return dataclasses.replace(EXAMPLE.scene, heightfield=hf)


def _tol(hf: Heightfield) -> float:
    """MuJoCo's float32 heights: within the range x 2^-24 (x 2 for the ray's own arithmetic)."""
    g = np.array(hf.heights)
    return 2.0 * (g.max() - g.min()) * HFIELD_ROUNDING + 1e-12


def _model(tree: Tree, hf: Heightfield):
    m = mujoco.MjModel.from_xml_string(to_mjcf(tree, _scene(hf), space=SPATIAL))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    return m, d


def _nodes(m, d) -> np.ndarray:
    """Every hfield node in the world (nrow x ncol x 3), from MuJoCo's own model: the geom's pose,
    the hfield's size (radius x, radius y, elevation) and its normalised data (row 0 at -radius y)."""
    geom = m.geom(HFIELD_NAME)
    h = geom.dataid[0]
    nrow, ncol = m.hfield_nrow[h], m.hfield_ncol[h]
    rx, ry, elevation, _ = m.hfield_size[h]
    data = m.hfield_data[m.hfield_adr[h] : m.hfield_adr[h] + nrow * ncol].reshape(nrow, ncol).astype(float)
    X, Y = np.meshgrid(np.linspace(-rx, rx, ncol), np.linspace(-ry, ry, nrow))
    local = np.stack([X, Y, elevation * data], -1)
    R = d.geom_xmat[geom.id].reshape(3, 3)
    return local @ R.T + d.geom_xpos[geom.id]


def _ray_height(m, d, x: float, z: float) -> float:
    """The height at which a ray straight down (footopt's -y) at (x, z) hits the hfield geom."""
    geom = np.zeros(1, np.int32)
    top = 1.0
    ground_only = np.array([1, 0, 0, 0, 0, 0], np.uint8)  # group 0: the rods' capsules are group 1
    dist = mujoco.mj_ray(m, d, np.array([x, top, z]), np.array([0.0, -1.0, 0.0]), ground_only, 1, -1, geom)
    assert geom[0] == m.geom(HFIELD_NAME).id, (x, z)
    return top - dist


@pytest.mark.parametrize("name", list(FIELDS))
def test_mujocos_hfield_holds_footopts_heights_at_every_node(name: str) -> None:
    """MuJoCo's nodes (its geometry, not ours) lie on footopt's ground; every model grid point is a
    node; a ray down beside each model point (1e-7 m) hits footopt's height (float32: the range x
    2^-24, and 1e-8 for the ray)."""
    hf = FIELDS[name]
    m, d = _model(EXAMPLE.tree, hf)
    P = _nodes(m, d).reshape(-1, 3)
    err = np.abs(P[:, 1] - hfield.height(hf, P[:, 0], P[:, 2]))
    tol = _tol(hf)
    report("export heightfield",
           f"{name}: {m.hfield_ncol[0]} x {m.hfield_nrow[0]} nodes, largest node error {err.max():.3g} m "
           f"(tol {tol:.3g})")
    assert err.max() <= tol
    for x in hf.x:
        for z in hf.z:
            assert np.min(np.hypot(P[:, 0] - x, P[:, 2] - z)) < 1e-12  # a node
            # 1e-7 m off the node: a ray through a triangle's very vertex can slip between the
            # triangles in mj_ray (measured: it then hits far below)
            x_in, z_in = x + 1e-7, z + 1e-7
            assert abs(_ray_height(m, d, x_in, z_in) - hfield.height(hf, x_in, z_in)) <= tol + 1e-8


@pytest.mark.parametrize("name", ["example", "random", "uneven"])
def test_cell_centres_follow_the_triangles_and_the_stated_largest_difference(name: str) -> None:
    """At each cell's centre MuJoCo's ground is the mean of one diagonal's two nodes (a
    triangulation), footopt's the mean of all four: they differ by |twist| / 4, and the largest over
    the cells is the number the file states (``triangulation_error``)."""
    hf = FIELDS[name]
    m, d = _model(EXAMPLE.tree, hf)
    g = regular_heightfield(hf)
    H, tol = g.heights, _tol(hf)
    worst = 0.0
    for i in range(len(g.x) - 1):
        for j in range(len(g.z) - 1):
            x, z = 0.5 * (g.x[i] + g.x[i + 1]), 0.5 * (g.z[j] + g.z[j + 1])
            hit = _ray_height(m, d, x, z)
            diagonals = (0.5 * (H[i, j] + H[i + 1, j + 1]), 0.5 * (H[i + 1, j] + H[i, j + 1]))
            assert min(abs(hit - v) for v in diagonals) <= tol + 1e-8
            bilinear = float(hfield.height(hf, x, z))
            assert bilinear == pytest.approx(H[i : i + 2, j : j + 2].mean(), abs=1e-15)
            worst = max(worst, abs(hit - bilinear))
    report("export heightfield",
           f"{name}: largest bilinear - triangles at a cell centre {worst:.6g} m, stated {g.triangulation_error:.6g} m")
    assert worst == pytest.approx(g.triangulation_error, abs=tol + 1e-8)
    note = to_mjcf(EXAMPLE.tree, _scene(hf), space=SPATIAL)
    assert f"bilinear patch by up to {g.triangulation_error!r} m\n(|twist| / 4" in note
    if name == "example":  # the rising cell's twist 0.015 (x 0.4..0.8), split in two on the step 0.2: 0.0075 / 4
        assert g.triangulation_error == pytest.approx(0.001875, abs=1e-15)


@pytest.mark.parametrize("name", list(FIELDS))
def test_the_skirt_beyond_the_grid_is_footopts_flat_extension(name: str) -> None:
    """Beyond the grid the hfield goes on as footopt's ground does (flat: the edge's heights) out
    to the rods' total length past the grid and the touchdown contacts (``ground_cover``, read from
    MuJoCo's geom: its centre +- size); rays down at random points there hit footopt's height."""
    hf = FIELDS[name]
    m, d = _model(EXAMPLE.tree, hf)
    geom = m.geom(HFIELD_NAME)
    rx, ry = m.hfield_size[geom.dataid[0]][:2]
    centre = d.geom_xpos[geom.id]
    (xlo, xhi), (zlo, zhi) = ground_cover(EXAMPLE.tree, _scene(hf), SPATIAL)
    reach = sum(b.length for b in EXAMPLE.tree.bodies)
    assert xhi - xlo > 2 * reach and zhi - zlo > 2 * reach
    assert centre[0] - rx <= xlo + 1e-12 and centre[0] + rx >= xhi - 1e-12
    assert centre[2] - ry <= zlo + 1e-12 and centre[2] + ry >= zhi - 1e-12
    tol = _tol(hf)
    points = RNG.uniform((xlo, zlo), (xhi, zhi), (200, 2))
    outside = [(x, z) for x, z in points if not (hf.x[0] <= x <= hf.x[-1] and hf.z[0] <= z <= hf.z[-1])]
    assert len(outside) > 150
    err = max(abs(_ray_height(m, d, x, z) - hfield.height(hf, x, z)) for x, z in outside)
    report("export heightfield", f"{name}: skirt x [{xlo:.2f}, {xhi:.2f}], z [{zlo:.2f}, {zhi:.2f}] m, "
                                 f"rays at {len(outside)} points beyond the grid: {err:.2g} m")
    assert err <= tol + 1e-8
    if name == "example":  # as docs/MODEL_FORMAT.md says: rods of 2.9 m in all
        assert reach == pytest.approx(2.9, abs=1e-12) and (m.hfield_ncol[0], m.hfield_nrow[0]) == (36, 23)
        assert "36 x 23 nodes, x in [-3.2, 3.8], z in [-3.3, 3.3] m" in to_mjcf(EXAMPLE.tree, _scene(hf), space=SPATIAL)


def test_the_skirt_stops_at_its_cell_limit() -> None:
    """A fine grid (1 mm step) with a far cover: 200 cells a side, no more."""
    hf = Heightfield.from_arrays([0.0, 0.001, 0.002], [0.0, 0.001], [[0.0, 0.001], [0.0, 0.0], [0.002, 0.0]])
    g = regular_heightfield(hf, ((-5.0, 5.0), (-0.0005, 0.0015)))
    assert len(g.x) == 3 + 2 * HFIELD_SKIRT_MAX_CELLS and g.x[0] == pytest.approx(-0.2, abs=1e-12)
    assert len(g.z) == 2 + 2  # half a step beyond each side: one whole step
    assert np.all(g.heights[:HFIELD_SKIRT_MAX_CELLS + 1, 1:-1] == np.array(hf.heights)[0])  # the edge's heights


def test_a_sphere_placed_on_a_node_touches_at_footopts_height() -> None:
    """A 1 cm sphere placed on each model grid point of the example, its lowest point at footopt's
    height (then 1 mm above it): where the ground is level all round the node MuJoCo's contact
    distance is 0 (then 1 mm) to 1e-9; where a triangle at the node slopes, the sphere dips into it
    by at most r (1 - cos) of the steepest slope (the geometry of a sphere above a sloped plane)."""
    hf = FIELDS["example"]
    g = regular_heightfield(hf)
    root = ET.fromstring(to_mjcf(EXAMPLE.tree, _scene(hf), space=SPATIAL))
    world = root.find("worldbody")
    r = 0.01
    points = [(x, z) for x in hf.x for z in hf.z]
    for k, (x, z) in enumerate(points):
        body = ET.SubElement(world, "body", name=f"ball{k}", pos=f"{x} {hfield.height(hf, x, z) + r} {z}")
        ET.SubElement(body, "freejoint")
        ET.SubElement(body, "geom", name=f"ball{k}", type="sphere", size=str(r), margin="0.01", mass="0.01")
    m = mujoco.MjModel.from_xml_string(ET.tostring(root, encoding="unicode"))
    d = mujoco.MjData(m)
    slope = np.hypot(np.abs(np.diff(g.heights, axis=0)).max() / (g.x[1] - g.x[0]),
                     np.abs(np.diff(g.heights, axis=1)).max() / (g.z[1] - g.z[0]))
    dip = r * (1.0 - 1.0 / np.hypot(1.0, slope))
    ground = m.geom(HFIELD_NAME).id
    level = 0
    for lift in (0.0, 0.001):
        for k, (x, z) in enumerate(points):
            adr = m.jnt_qposadr[m.body(f"ball{k}").jntadr[0]]
            d.qpos[adr + 1] = hfield.height(hf, x, z) + r + lift
        mujoco.mj_forward(m, d)
        for k, (x, z) in enumerate(points):
            ball = m.geom(f"ball{k}").id
            found = [(np.hypot(c.pos[0] - x, c.pos[2] - z), c.dist) for c in d.contact[: d.ncon]
                     if {c.geom1, c.geom2} == {ball, ground}]
            assert found, (x, z, lift)
            deepest = min(dist for _, dist in found)
            i, j = int(np.argmin(np.abs(g.x - x))), int(np.argmin(np.abs(g.z - z)))
            around = g.heights[max(i - 1, 0) : i + 2, max(j - 1, 0) : j + 2]
            if np.ptp(around) == 0.0:  # level all round the node: it touches at footopt's height
                assert deepest == pytest.approx(lift, abs=1e-9), (x, z, lift, found)
                level += 1
            else:  # a sloped triangle at the node: the sphere dips into it by at most r (1 - cos)
                assert lift - dip - 1e-12 <= deepest <= lift + 1e-9, (x, z, lift, found, dip)
    assert level == 2 * 3  # the three points at x = -0.2, twice


def test_the_robot_stands_at_its_touchdown_on_footopts_ground() -> None:
    """The exported base pose is the touchdown on the heightfield: base origin above (base_x,
    base_z) as footopt's touchdown configuration (clearance 0); MuJoCo's contact sites lie on or
    above footopt's ground, the lowest on it (1e-12); the URDF's contact frames in Pinocchio's
    neutral pose are the same points (1e-12), and its comment says it has no terrain."""
    tree, scene = EXAMPLE.tree, EXAMPLE.scene
    q = touchdown_configuration(tree, scene.heightfield, scene.base_x, clearance=0.0, space=SPATIAL,
                                base_z=scene.base_z)
    origin, _ = base_pose(tree, scene, SPATIAL)
    assert np.allclose(origin, q[:3], atol=0.0, rtol=0.0)
    m, d = _model(tree, scene.heightfield)
    sites = np.array([d.site_xpos[m.site(f"{tree.bodies[b].name}_contact{k}").id] for b, k in tree.contacts])
    clearance = hfield.vertical_clearance(scene.heightfield, sites)
    report("export heightfield", f"contact clearances above footopt's ground: {np.round(clearance, 6)}")
    assert clearance.min() == pytest.approx(0.0, abs=1e-12) and np.all(clearance > -1e-12)
    assert np.allclose(sites, touchdown_geometry(tree, SPATIAL).contacts + origin, atol=1e-12)
    urdf = to_urdf(tree, scene, space=SPATIAL)
    assert "URDF has no terrain: scene.heightfield (3 x 3 points" in urdf
    pin = pytest.importorskip("pinocchio")
    model = pin.buildModelFromXML(urdf, pin.JointModelFreeFlyer())
    data = model.createData()
    pin.framesForwardKinematics(model, data, pin.neutral(model))
    frames = np.array([data.oMf[model.getFrameId(f"{tree.bodies[b].name}_contact{k}", pin.BODY)].translation
                       for b, k in tree.contacts])
    assert np.allclose(frames, sites, atol=1e-12)  # Pinocchio's neutral pose: the same touchdown on the heightfield


def test_a_flat_heightfield_is_a_plane_and_drop_leaves_the_ground_out() -> None:
    """A heightfield whose heights are equal is a plane at that height (exact everywhere); the MJCF
    ``footopt drop`` builds on (``ground=False``) holds no ground of its own."""
    flat = Heightfield.from_arrays([0.0, 1.0], [0.0], [[0.02], [0.02]])
    m, d = _model(EXAMPLE.tree, flat)
    geom = m.geom(HFIELD_NAME)
    assert geom.type[0] == mujoco.mjtGeom.mjGEOM_PLANE and m.nhfield == 0
    assert _ray_height(m, d, 3.0, -2.0) == pytest.approx(0.02, abs=1e-12)
    text = to_mjcf(EXAMPLE.tree, EXAMPLE.scene, space=SPATIAL, ground=False)
    assert HFIELD_NAME not in ET.fromstring(text).find("worldbody").attrib.values()
    assert "<hfield" not in text and 'name="heightfield"' not in text


def test_an_incommensurate_grid_is_refused_in_one_line(tmp_path: Path, capsys) -> None:
    """An uneven grid whose spacings share no step within 1000 cells: exit 2, one line naming
    scene.heightfield.z; the same grid evenly spaced is written."""
    text = (REPO / "configs" / "spatial_heightfield.yaml").read_text()
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace("z: [-0.3, 0.0, 0.3]", "z: [-0.3, 0.0, 0.31415926535]"))
    assert main(["export", str(bad), "-o", str(tmp_path / "leg.xml")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"footopt: error: {bad}: scene.heightfield.z: its spacings") and err.count("\n") == 1
    assert "regular grid" in err and not (tmp_path / "leg.xml").exists()
    with pytest.raises(ConfigError, match=r"^scene\.heightfield\.x: "):
        regular_heightfield(Heightfield.from_arrays([0.0, 1.0, 1.0 + 2**0.5], [0.0], [[0.0], [0.1], [0.0]]))
    assert main(["export", str(bad), "-o", str(tmp_path / "leg.urdf")]) == 0  # URDF: no terrain, no grid needed
    good = tmp_path / "good.yaml"
    good.write_text(text)
    assert main(["export", str(good), "-o", str(tmp_path / "leg.xml")]) == 0
    assert (tmp_path / "leg.xml").read_text() == to_mjcf(EXAMPLE.tree, EXAMPLE.scene, "good", space=SPATIAL)


def test_a_regular_grid_written_to_rounded_decimals_is_exported_and_says_how_far_nodes_moved() -> None:
    """z = linspace(-0.4, 0.4, 4) written to six decimals (spacings 0.266667, 0.266666, 0.266667:
    a regular grid a user typed) is exported, not refused: MuJoCo's evenly spaced nodes sit within
    1e-5 of a step of the model's points, the file states that distance, and each node holds the
    model's height at its point (MuJoCo's node within the stated shift of the point)."""
    z = [-0.4, -0.133333, 0.133333, 0.4]
    hf = Heightfield.from_arrays([-0.3, 0.1, 0.5], z, RNG.uniform(0.0, 0.03, (3, 4)))
    g = regular_heightfield(hf, ground_cover(EXAMPLE.tree, _scene(hf), SPATIAL))  # the grid written, skirt and all
    assert 0.0 < g.node_shift <= 1e-5 * (0.8 / 3)
    text = to_mjcf(EXAMPLE.tree, _scene(hf), space=SPATIAL)
    assert f"sit up to {g.node_shift!r} m from the model's rounded points" in text
    m, d = _model(EXAMPLE.tree, hf)
    P = _nodes(m, d).reshape(-1, 3)
    for i, x in enumerate(hf.x):
        for j, zj in enumerate(hf.z):
            k = int(np.argmin(np.hypot(P[:, 0] - x, P[:, 2] - zj)))
            assert np.hypot(P[k, 0] - x, P[k, 2] - zj) <= g.node_shift + 1e-12
            assert abs(P[k, 1] - hf.heights[i][j]) <= _tol(hf)
