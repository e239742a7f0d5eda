"""The standard mesh scenes: their generated meshes are what they claim, the
shipped files are what the generators write, and the scenes behave."""

from __future__ import annotations

import subprocess
import sys
import tomllib

import numpy as np
import pytest

from clothsim.procedural import (
    STANDARD_MESHES,
    Mesh,
    delaunay_square,
    disc,
    face_normals,
    meshes_dir,
    morton_order,
    obj_text,
    poisson_points,
    quad_grid,
    write_obj,
    write_standard_meshes,
)

from .conftest import ROOT, SCENES


def read_obj(path) -> tuple[np.ndarray, list[list[int]], np.ndarray]:
    """A minimal reader of the files we write: positions, faces (0-based), uvs."""
    v, vt, f = [], [], []
    for line in path.read_text().splitlines():
        parts = line.split()
        if not parts or parts[0] == "#":
            continue
        if parts[0] == "v":
            v.append([float(x) for x in parts[1:]])
        elif parts[0] == "vt":
            vt.append([float(x) for x in parts[1:]])
        elif parts[0] == "f":
            corners = [p.split("/") for p in parts[1:]]
            assert all(c[0] == c[1] for c in corners)  # texture vertex k is vertex k
            f.append([int(c[0]) - 1 for c in corners])
    return np.array(v), f, np.array(vt)


def edges_of(faces: np.ndarray) -> np.ndarray:
    """Directed edges (E, 2) of every face, in winding order."""
    k = faces.shape[1]
    return np.concatenate([faces[:, [i, (i + 1) % k]] for i in range(k)])


def boundary_vertices(faces: np.ndarray) -> np.ndarray:
    """Vertices on an edge that only one face has."""
    e = np.sort(edges_of(faces), axis=1)
    uniq, count = np.unique(e, axis=0, return_counts=True)
    return np.unique(uniq[count == 1])


def assert_oriented_manifold_disc(mesh: Mesh) -> None:
    """Every vertex used; every edge in one or two faces, and in opposite
    directions when in two (one consistent winding); every vertex's star one fan
    (no bow-ties); Euler characteristic 1 (one piece, no holes)."""
    f = mesh.faces
    n = len(mesh.vertices)
    assert np.array_equal(np.unique(f), np.arange(n))
    directed = edges_of(f)
    assert len(np.unique(directed, axis=0)) == len(directed), "an edge twice in the same direction"
    undirected, count = np.unique(np.sort(directed, axis=1), axis=0, return_counts=True)
    assert count.max() == 2
    # a vertex's star is one fan: it lies on at most two boundary edges
    boundary = undirected[count == 1]
    assert np.bincount(boundary.ravel(), minlength=n).max() <= 2
    # and one fan, not two: its faces are connected through its edges
    per_vertex: dict[int, list[int]] = {}
    for fi, face in enumerate(f.tolist()):
        for v in face:
            per_vertex.setdefault(v, []).append(fi)
    for v, star in per_vertex.items():
        neighbours = [set(f[fi].tolist()) - {v} for fi in star]
        seen, todo = {0}, [0]
        while todo:
            a = todo.pop()
            for b in range(len(star)):
                if b not in seen and neighbours[a] & neighbours[b]:
                    seen.add(b)
                    todo.append(b)
        assert len(seen) == len(star), f"vertex {v} is a bow-tie"
    assert n - len(undirected) + len(f) == 1


def median_index_gap(mesh: Mesh) -> float:
    e = edges_of(mesh.faces)
    return float(np.median(np.abs(e[:, 0] - e[:, 1])))


# ------------------------------------------------------------------- the disc


def test_disc_is_a_round_counterclockwise_disc():
    """25 rings: 1 + 3*25*26 vertices, 6*25² triangles; the boundary is the 150
    outer-ring vertices, all exactly at the radius, everything else inside;
    every triangle faces +y and none is degenerate"""
    m = disc(radius=0.7, rings=25)
    assert m.vertices.shape == (1951, 3) and m.faces.shape == (3750, 3)
    assert np.all(m.vertices[:, 1] == 0)
    r = np.hypot(m.vertices[:, 0], m.vertices[:, 2])
    edge = boundary_vertices(m.faces)
    assert len(edge) == 150
    np.testing.assert_allclose(r[edge], 0.7, atol=1e-12)
    inside = np.setdiff1d(np.arange(1951), edge)
    assert r[inside].max() == pytest.approx(0.7 * 24 / 25)
    n = face_normals(m.vertices, m.faces)
    area = np.linalg.norm(n, axis=1) / 2
    assert np.all(n[:, 1] > 0) and np.allclose(n[:, [0, 2]], 0)
    assert area.min() > 0.7 * area.mean()  # no slivers: the smallest is near the typical one
    # the triangles tile the disc: area of the inscribed 150-gon
    assert area.sum() == pytest.approx(0.5 * 150 * 0.7 ** 2 * np.sin(2 * np.pi / 150), rel=1e-12)
    assert_oriented_manifold_disc(m)
    np.testing.assert_allclose(m.uvs, (m.vertices[:, [0, 2]] + 0.7) / 1.4)


def test_disc_vertices_are_near_their_neighbours_in_memory():
    """Morton order: an edge's two ends are a few indices apart (a ring order
    would put rings ~150 apart, a random one ~650)"""
    m = disc()
    assert median_index_gap(m) <= 8
    shuffled = np.random.default_rng(0).permutation(len(m.vertices))
    inverse = np.argsort(shuffled)
    assert median_index_gap(Mesh(m.vertices[shuffled], inverse[m.faces], m.uvs[shuffled])) > 300


def test_morton_order_walks_a_grid_in_z_order():
    """on the 4x4 grid of cells the curve visits each 2x2 block before the next"""
    x, z = np.meshgrid(np.arange(4.0), np.arange(4.0))
    pts = np.stack([x.ravel(), z.ravel()], axis=1)
    order = morton_order(pts)
    assert [tuple(map(int, pts[k])) for k in order[:8]] == [(0, 0), (1, 0), (0, 1), (1, 1),
                                                            (2, 0), (3, 0), (2, 1), (3, 1)]


# ------------------------------------------------------------- quads, Delaunay


def test_flag_is_a_vertical_quad_strip():
    """40x20 vertices row-major over 1.0 x 0.5 m in z=0, 39*19 quads facing +z"""
    m = quad_grid(columns=40, rows=20, width=1.0, height=0.5, vertical=True)
    assert m.vertices.shape == (800, 3) and m.faces.shape == (741, 4)
    np.testing.assert_allclose(m.vertices[41], [1 / 39, 0.5 / 19, 0])
    assert m.vertices[:, 0].max() == 1.0 and m.vertices[:, 1].max() == 0.5 and np.all(m.vertices[:, 2] == 0)
    n = face_normals(m.vertices, m.faces)
    np.testing.assert_allclose(n / np.linalg.norm(n, axis=1)[:, None], np.tile([0, 0, 1], (741, 1)), atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1) / 2, (1 / 39) * (0.5 / 19))
    assert m.faces[0].tolist() == [0, 1, 41, 40]
    assert_oriented_manifold_disc(m)


def test_shipped_flag_is_jittered_off_its_plane():
    """the flag's vertices leave z=0 by a seeded amount within 1 mm (as CS184 does
    for vertical cloth, so it can buckle), the rest of the layout unchanged"""
    m = STANDARD_MESHES["flag.obj"]()
    flat = quad_grid(columns=40, rows=20, width=1.0, height=0.5, vertical=True)
    z = m.vertices[:, 2]
    assert np.abs(z).max() <= 0.001 and z.std() > 0.0004 and len(np.unique(z)) == 800
    np.testing.assert_array_equal(m.vertices[:, :2], flat.vertices[:, :2])
    assert np.array_equal(m.faces, flat.faces)
    assert np.all(face_normals(m.vertices, m.faces)[:, 2] > 0)


def test_horizontal_sheet_faces_up_and_is_centred():
    m = quad_grid(columns=32, rows=32, width=0.8, height=0.8, vertical=False)
    assert np.allclose(m.vertices.min(axis=0), [-0.4, 0, -0.4]) and np.allclose(m.vertices.max(axis=0), [0.4, 0, 0.4])
    assert np.all(face_normals(m.vertices, m.faces)[:, 1] > 0)


def test_poisson_points_keep_their_spacing_and_fill_the_square():
    from scipy.spatial import cKDTree

    p = poisson_points(2500, 1.0, 0.014, seed=20)
    assert p.shape == (2500, 2) and np.abs(p).max() <= 0.5
    d, _ = cKDTree(p).query(p, k=2)
    assert d[:, 1].min() >= 0.014
    # the four corners are points, and the seed makes the set reproducible
    for corner in [(-0.5, -0.5), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5)]:
        assert np.any(np.all(np.isclose(p, corner), axis=1))
    assert np.array_equal(p, poisson_points(2500, 1.0, 0.014, seed=20))
    assert not np.array_equal(p, poisson_points(2500, 1.0, 0.014, seed=21))


def test_delaunay_square_is_an_irregular_manifold_sheet():
    """2,500 distinct vertices, triangles facing +y that tile the 1 m square
    exactly, one oriented manifold piece, valences from 4 to 9 (not a grid)"""
    from scipy.spatial import cKDTree

    m = delaunay_square()
    assert m.vertices.shape == (2500, 3) and m.faces.shape[1] == 3
    assert len(cKDTree(m.vertices).query_pairs(1e-6)) == 0  # no duplicate vertices
    n = face_normals(m.vertices, m.faces)
    area = np.linalg.norm(n, axis=1) / 2
    assert np.all(n[:, 1] > 0) and area.min() > 1e-5
    assert area.sum() == pytest.approx(1.0, rel=1e-12)
    assert_oriented_manifold_disc(m)
    # Euler on a triangulated disc: F = 2V - B - 2
    assert len(m.faces) == 2 * 2500 - len(boundary_vertices(m.faces)) - 2
    valence = np.bincount(np.unique(np.sort(edges_of(m.faces), axis=1), axis=0).ravel())
    interior = np.setdiff1d(np.arange(2500), boundary_vertices(m.faces))
    assert valence[interior].min() <= 4 and valence[interior].max() >= 8
    assert median_index_gap(m) <= 8


# -------------------------------------------------------------------- OBJ files


def test_obj_text_of_a_quad_and_a_triangle():
    """v, vt and f lines; a quad stays one 4-vertex face; no trailing zeros, no -0"""
    mesh = Mesh(np.array([[0, 0, 0], [1, 0, 0], [1, -1e-9, 1], [0, 0.5, 1], [0.25, 0, 2]], dtype=float),
                np.array([[0, 1, 2, 3]]), np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.125, 0.3333333]]),
                "hand-made")
    assert obj_text(mesh) == ("# clothsim.procedural: hand-made\n# 5 vertices, 1 faces\n"
                              "v 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0.5 1\nv 0.25 0 2\n"
                              "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 0.125 0.333333\n"
                              "f 1/1 2/2 3/3 4/4\n")


def test_obj_file_holds_the_mesh(tmp_path):
    """reading a written disc back gives its positions to the µm and its faces exactly"""
    m = disc(radius=0.3, rings=4)
    v, f, vt = read_obj(write_obj(tmp_path / "d.obj", m))
    np.testing.assert_allclose(v, m.vertices, atol=5e-7)
    np.testing.assert_allclose(vt, m.uvs, atol=5e-7)
    assert f == m.faces.tolist()


def test_shipped_meshes_are_what_the_generators_write(tmp_path):
    """`python -m clothsim.procedural DIR` rewrites every shipped mesh byte for
    byte, and the package ships no other mesh"""
    out = subprocess.run([sys.executable, "-m", "clothsim.procedural", str(tmp_path)],
                         check=False, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    shipped = sorted(p.name for p in meshes_dir().glob("*.obj"))
    assert shipped == sorted(STANDARD_MESHES) == sorted(p.name for p in tmp_path.iterdir())
    for name in shipped:
        assert (tmp_path / name).read_bytes() == (meshes_dir() / name).read_bytes(), name
    assert [p.name for p in write_standard_meshes(tmp_path / "again")] == list(STANDARD_MESHES)


def test_package_data_carries_the_meshes():
    """pyproject's package data names the mesh files, so a wheel carries them"""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    globs = config["tool"]["setuptools"]["package-data"]["clothsim"]
    package = ROOT / "src" / "clothsim"
    carried = {p.name for g in globs for p in package.glob(g) if p.parent.name == "meshes"}
    assert carried == set(STANDARD_MESHES)


# ------------------------------------------------------------ the scenes


SPHERE_CENTRE, SPHERE_RADIUS = np.array([0.5, 0.2, 0.5]), 0.2
MESH_SCENES = {"tablecloth": 1951, "flag": 800, "drape": 2500, "two_cloths": 1600 + 1024}


def test_mesh_scenes_are_standard_scenes_of_their_meshes():
    """each mesh scene names a shipped mesh relative to itself (every shipped mesh
    is a cloth's but the torus, a collider's); the sphere ones use sphere.json's
    sphere; two_cloths holds a soft grid and a stiff mesh"""
    from clothsim import load_scene
    from clothsim.standard_scenes import names, scene_path

    assert set(MESH_SCENES) <= set(names())
    sphere = load_scene(scene_path("sphere")).spheres[0]
    for name in ("tablecloth", "drape"):
        s = load_scene(scene_path(name)).spheres
        assert len(s) == 1 and (s[0].origin, s[0].radius) == (sphere.origin, sphere.radius)
        assert (s[0].origin, s[0].radius) == (tuple(SPHERE_CENTRE), SPHERE_RADIUS)
    meshes = {c.mesh for n in MESH_SCENES for c in load_scene(scene_path(n)).cloths if hasattr(c, "mesh")}
    colliders = {m.path for n in names() for m in load_scene(scene_path(n)).mesh_colliders}
    assert meshes == {f"meshes/{m}" for m in STANDARD_MESHES if m != "torus.obj"}
    assert colliders == {"meshes/torus.obj"}  # the one collider mesh, of torus_drape
    two = load_scene(scene_path("two_cloths"))
    assert [c.ks for c in two.cloths] == [500.0, 5000.0] and not hasattr(two.cloths[0], "mesh")


@pytest.mark.parametrize("name", sorted(MESH_SCENES))
def test_mesh_scene_loads_and_runs(name):
    """a few frames of each mesh scene: every point present, finite, the free
    ones fallen, the pinned ones exactly where they were"""
    from clothsim import Simulation

    sim = Simulation.from_file(SCENES / f"{name}.json")
    assert sim.positions.shape == (MESH_SCENES[name], 3)
    start = sim.positions.copy()
    pinned = sim.model.pinned
    assert pinned.sum() == (20 if name == "flag" else 0)
    sim.run(0.1)
    p = sim.positions
    assert np.isfinite(p).all()
    assert np.array_equal(p[pinned], start[pinned])
    fall = start[~pinned, 1] - p[~pinned, 1]
    assert np.median(fall) > 0.02  # 0.1 s of gravity: about 5 cm for a free point


def test_flag_hangs_from_its_pole():
    """pinned along its short edge x=0 (the 20 points of column 0), the flag
    hangs: its free edge swings down and in towards the pole, the pole unmoved"""
    from clothsim import Simulation

    sim = Simulation.from_file(SCENES / "flag.json")
    start = sim.positions.copy()
    pole = sim.model.pinned
    assert np.array_equal(np.nonzero(pole)[0], np.arange(0, 800, 40))
    np.testing.assert_allclose(start[pole, 0], 0, atol=1e-12)
    np.testing.assert_allclose(start[pole, 1], 1.2 + np.arange(20) / 38, atol=1e-6)
    sim.run(1.0)
    p = sim.positions
    assert np.array_equal(p[pole], start[pole])
    free_edge = np.arange(39, 800, 40)
    assert p[free_edge, 1].mean() < start[free_edge, 1].mean() - 0.3
    assert p[free_edge, 0].max() < 0.9


@pytest.fixture(scope="module")
def tablecloth():
    """tablecloth.json after 2 s (it lands at 0.25 s and is still by 1 s), and
    where it was 0.1 s before"""
    from clothsim import Simulation

    sim = Simulation.from_file(SCENES / "tablecloth.json")
    sim.run(1.9)
    before = sim.positions.copy()
    sim.run(0.1)
    return sim, before


def test_tablecloth_rests_on_the_sphere_and_hangs_below_its_equator(tablecloth):
    """no point inside the sphere; the top of the cloth on the sphere's top;
    the hem hanging below the equator all round; still and centred"""
    sim, before = tablecloth
    p = sim.positions
    d = np.linalg.norm(p - SPHERE_CENTRE, axis=1)
    assert d.min() >= SPHERE_RADIUS - 1e-3
    assert p[:, 1].max() == pytest.approx(SPHERE_CENTRE[1] + SPHERE_RADIUS, abs=0.01)
    assert p[:, 1].min() < SPHERE_CENTRE[1] - 0.2
    # the hem: the 150 rim points (they started at 0.7 m from the axis), all below the equator
    start = sim.model.rest_positions
    rim = np.hypot(start[:, 0] - 0.5, start[:, 2] - 0.5) > 0.7 - 1e-6
    assert rim.sum() == 150 and np.all(p[rim, 1] < SPHERE_CENTRE[1])
    assert np.abs(p[:, [0, 2]].mean(axis=0) - SPHERE_CENTRE[[0, 2]]).max() < 0.01
    # still: in its last 0.1 s the points moved about 2 mm on average, the hem
    # swaying (while it fell they moved 10-20 cm in 0.1 s)
    assert np.linalg.norm(p - before, axis=1).mean() < 0.004
    assert abs(p[:, 1].min() - before[:, 1].min()) < 0.002


def test_drape_lies_over_the_sphere():
    """the Delaunay sheet after 1.5 s: no point inside the sphere, its middle on
    the sphere's top, its four corners (turned 30°) hanging below the equator"""
    from clothsim import Simulation

    sim = Simulation.from_file(SCENES / "drape.json")
    rest = sim.model.rest_positions
    reach = np.hypot(rest[:, 0] - 0.5, rest[:, 2] - 0.5)
    corners = np.argsort(reach)[-4:]  # the points farthest from the sphere's axis
    np.testing.assert_allclose(reach[corners], np.sqrt(0.5), atol=1e-6)
    sim.run(1.5)
    p = sim.positions
    assert np.linalg.norm(p - SPHERE_CENTRE, axis=1).min() >= SPHERE_RADIUS - 1e-3
    assert p[:, 1].max() == pytest.approx(SPHERE_CENTRE[1] + SPHERE_RADIUS, abs=0.01)
    assert np.all(p[corners, 1] < SPHERE_CENTRE[1] - 0.1)


def test_two_cloths_never_interpenetrate(tmp_path):
    """two_cloths for 2 s: at every frame no point of one cloth within the
    thickness of a point of the other; at the end the stiff sheet lies on the
    soft one (in contact, and above it wherever it is over it)"""
    from scipy.spatial import cKDTree

    from clothsim import Simulation

    sim = Simulation.from_file(SCENES / "two_cloths.json")
    thickness = sim.model.cloths[0].thickness
    assert thickness == sim.model.cloths[1].thickness == 0.0095
    assert [c.params.ks for c in sim.cloths] == [500.0, 5000.0]
    closest = []

    def gap(*_):
        a, b = sim.cloths[0].positions, sim.cloths[1].positions
        closest.append(cKDTree(a).query(b)[0].min())

    sim.run(2.0, on_frame=gap)
    assert len(closest) == 180
    assert min(closest) >= thickness
    assert closest[-1] < 3 * thickness  # they touch: the test is not vacuous
    lower, upper = sim.cloths[0].positions, sim.cloths[1].positions
    assert lower[:, 1].max() < 0.01  # the soft cloth lies on the plane
    # over it: within the lower cloth's spacing of one of its points, seen from above
    dist, nearest = cKDTree(lower[:, [0, 2]]).query(upper[:, [0, 2]])
    over = dist < 0.5 / 39
    assert over.sum() > 500
    assert np.all(upper[over, 1] > lower[nearest[over], 1] + thickness)


def test_tablecloth_seen_from_above_is_round(tmp_path):
    """the Phong image of the disc before it falls, from straight above: the
    cloth's pixels fill pi/4 of their bounding square (a square cloth fills all
    of it, a hexagon 0.75), and its outline is at one distance from its centre"""
    from PIL import Image

    from clothsim.cli import main
    from clothsim.render.renderer import BACKGROUND

    out = tmp_path / "top.png"
    assert main(["render", str(SCENES / "tablecloth.json"), "-o", str(out), "--seconds", "0",
                 "--size", "200x200", "--camera", "0,90,3", "--no-progress"]) == 0
    img = np.asarray(Image.open(out).convert("RGB")).astype(float)
    cloth = np.abs(img - np.array(BACKGROUND) * 255).sum(axis=2) > 12
    rows, cols = np.nonzero(cloth)
    h, w = np.ptp(rows) + 1, np.ptp(cols) + 1
    assert h > 120 and abs(h - w) <= 2 and not cloth[[0, -1]].any() and not cloth[:, [0, -1]].any()
    assert cloth.sum() / (h * w) == pytest.approx(np.pi / 4, rel=0.02)
    # the outline: cloth pixels with a background neighbour
    edge = cloth & ~(np.roll(cloth, 1, 0) & np.roll(cloth, -1, 0) & np.roll(cloth, 1, 1) & np.roll(cloth, -1, 1))
    er, ec = np.nonzero(edge)
    r = np.hypot(er - rows.mean(), ec - cols.mean())
    assert r.std() / r.mean() < 0.01
    assert img[cloth][:, 0].mean() > 2 * img[cloth][:, 2].mean()  # cloth-coloured (red), lit
