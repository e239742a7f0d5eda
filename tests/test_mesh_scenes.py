"""The standard mesh scenes: their generated meshes are what they claim, the
shipped files are what the generators write, and the scenes behave."""

from __future__ import annotations

import subprocess
import sys
import tomllib

import numpy as np
import pytest

from clothsim.procedural import (STANDARD_MESHES, Mesh, delaunay_square, disc, face_normals, meshes_dir,
                                 morton_order, obj_text, poisson_points, quad_grid, write_obj,
                                 write_standard_meshes)

from .conftest import ROOT


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
                         capture_output=True, text=True, timeout=120)
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
