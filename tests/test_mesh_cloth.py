"""Cloth from a mesh file: the springs, pins, masses and uvs of the model it
builds, checked against the grid builder and against counts made by hand, and
every bad mesh a one-line scene error."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import pytest
import trimesh

from clothsim import SceneError, load_scene, parse_scene
from clothsim.cli import main
from clothsim.model import BENDING, SHEARING, STRUCTURAL, build_model, build_scene_model

from .conftest import SCENES


def write_obj(path: Path, verts, faces, uvs=None) -> Path:
    """An OBJ of ``verts`` (V, 3) and 0-based ``faces`` (lists of 3 or 4), with
    one ``vt`` per vertex when ``uvs`` is given."""
    lines = ["v " + " ".join(repr(float(x)) for x in v) for v in verts]
    if uvs is not None:
        lines += [f"vt {float(u)!r} {float(w)!r}" for u, w in uvs]
    for f in faces:
        lines.append("f " + " ".join(f"{k + 1}/{k + 1}" if uvs is not None else str(k + 1) for k in f))
    path.write_text("\n".join(lines) + "\n")
    return path


def mesh_scene(tmp_path: Path, verts, faces, uvs=None, name="mesh.obj", **cloth) -> Path:
    write_obj(tmp_path / name, verts, faces, uvs)
    scene = tmp_path / "scene.json"
    scene.write_text(json.dumps({"cloth": {"mesh": name, "thickness": 0.01, **cloth}}))
    return scene


def springs(model, kind) -> np.ndarray:
    """the (a, b) pairs of one kind, smaller first, sorted: int64 (S, 2)"""
    s = slice(model.kind_start[kind], model.kind_start[kind + 1])
    pairs = np.sort(np.stack([model.spring_a[s], model.spring_b[s]], axis=1).astype(np.int64), axis=1)
    return pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]


def counts(model) -> tuple[int, int, int]:
    return tuple(int(n) for n in np.diff(model.kind_start))


def grid_patch(nw: int, nh: int, d: float = 1.0):
    """vertices i + j*nw in the y=0 plane and one quad per cell"""
    verts = [(i * d, 0.0, j * d) for j in range(nh) for i in range(nw)]
    quads = [[i + j * nw, i + 1 + j * nw, i + 1 + (j + 1) * nw, i + (j + 1) * nw]
             for j in range(nh - 1) for i in range(nw - 1)]
    return verts, quads


# --------------------------------------------------------------------------
# the quad grid: exactly the grid's springs


@pytest.fixture(scope="module")
def pinned2_obj(tmp_path_factory):
    """the 50x50 pinned2 grid's rest positions as a quad OBJ, and the grid model"""
    grid = build_model(load_scene(SCENES / "pinned2.json").cloth)
    nw, nh = grid.num_width_points, grid.num_height_points
    _, quads = grid_patch(nw, nh)
    folder = tmp_path_factory.mktemp("pinned2")
    write_obj(folder / "pinned2.obj", grid.rest_positions, quads)
    (folder / "scene.json").write_text(json.dumps(
        {"cloth": {"mesh": "pinned2.obj", "thickness": 0.0095, "pinned_vertices": [0, 49]}}))
    return folder, grid


def test_quad_grid_obj_has_exactly_the_grid_springs(pinned2_obj):
    """per kind the same count, the same pairs and rest lengths (1e-12 m) as the grid builder"""
    folder, grid = pinned2_obj
    mesh = build_scene_model(load_scene(folder / "scene.json"))
    assert counts(mesh) == counts(grid) == (4900, 4802, 4800)
    for kind in (STRUCTURAL, SHEARING, BENDING):
        assert np.array_equal(springs(mesh, kind), springs(grid, kind))

        def rest_by_pair(m, kind=kind):
            s = slice(m.kind_start[kind], m.kind_start[kind + 1])
            a, b = np.minimum(m.spring_a[s], m.spring_b[s]), np.maximum(m.spring_a[s], m.spring_b[s])
            return m.spring_rest[s][np.lexsort((b, a))]
        np.testing.assert_allclose(rest_by_pair(mesh), rest_by_pair(grid), rtol=0, atol=1e-12)
    assert np.array_equal(mesh.rest_positions, grid.rest_positions)
    assert np.array_equal(mesh.pinned, grid.pinned)
    assert mesh.cloth.grid is None and len(mesh.triangles) == len(grid.triangles)
    assert mesh.cloth.point_mass(150.0) == pytest.approx(grid.cloth.point_mass(150.0), rel=1e-12)
    assert (mesh.cloth.width, mesh.cloth.height) == pytest.approx((1.0, 1.0), abs=1e-12)
    for arr in (mesh.rest_positions, mesh.pinned, mesh.spring_a, mesh.spring_rest, mesh.triangles, mesh.uvs):
        assert not arr.flags.writeable


def test_quad_obj_read_as_trimesh_reads_it(pinned2_obj):
    """the OBJ reader's vertices and area agree with trimesh reading the same file"""
    folder, _ = pinned2_obj
    mesh = build_scene_model(load_scene(folder / "scene.json"))
    tm = trimesh.load(folder / "pinned2.obj", force="mesh", process=False, maintain_order=True)
    assert np.array_equal(mesh.rest_positions, tm.vertices)
    assert mesh.cloth.area == pytest.approx(tm.area, rel=1e-12)
    assert len(mesh.triangles) == len(tm.faces)


def test_vertex_order_does_not_change_the_springs(tmp_path):
    """a shuffled file gives the same springs, renumbered"""
    verts, quads = grid_patch(7, 5)
    perm = np.random.default_rng(3).permutation(len(verts))  # new index of old vertex k is where(perm == k)
    new_of_old = np.argsort(perm)
    shuffled = [verts[k] for k in perm]
    a = build_scene_model(load_scene(mesh_scene(tmp_path, verts, quads)))
    b = build_scene_model(load_scene(mesh_scene(tmp_path, shuffled, [[int(new_of_old[k]) for k in q] for q in quads],
                                                name="shuffled.obj")))
    for kind in (STRUCTURAL, SHEARING, BENDING):
        mapped = np.sort(new_of_old[springs(a, kind)], axis=1)
        assert np.array_equal(mapped[np.lexsort((mapped[:, 1], mapped[:, 0]))], springs(b, kind))


# --------------------------------------------------------------------------
# small meshes counted by hand


SQUARE = [(0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1)]


def test_two_triangles(tmp_path):
    """two triangles sharing the edge 0-2: 5 edges, no quad, one spring across the edge (1-3)"""
    m = build_scene_model(load_scene(mesh_scene(tmp_path, SQUARE, [[0, 1, 2], [0, 2, 3]])))
    assert counts(m) == (5, 0, 1)
    assert springs(m, STRUCTURAL).tolist() == [[0, 1], [0, 2], [0, 3], [1, 2], [2, 3]]
    assert springs(m, BENDING).tolist() == [[1, 3]]
    assert m.spring_rest[m.kind_start[BENDING]] == pytest.approx(2 ** 0.5, abs=1e-15)
    assert m.triangles.tolist() == [[0, 1, 2], [0, 2, 3]]


def test_one_quad(tmp_path):
    """one quad: its four edges, its two diagonals, no bending"""
    m = build_scene_model(load_scene(mesh_scene(tmp_path, SQUARE, [[0, 1, 2, 3]])))
    assert counts(m) == (4, 2, 0)
    assert springs(m, SHEARING).tolist() == [[0, 2], [1, 3]]
    assert m.triangles.tolist() == [[0, 1, 2], [0, 2, 3]]  # split, wound as in the file
    assert m.cloth.area == pytest.approx(1.0, abs=1e-15)


def test_three_by_three_quad_patch(tmp_path):
    """2x2 quads (vertices 0..8 row by row): 12 edges, 8 diagonals, and a bending
    spring two apart along each of the 3 rows and 3 columns"""
    verts, quads = grid_patch(3, 3)
    m = build_scene_model(load_scene(mesh_scene(tmp_path, verts, quads)))
    assert counts(m) == (12, 8, 6)
    assert springs(m, BENDING).tolist() == [[0, 2], [0, 6], [1, 7], [2, 8], [3, 5], [6, 8]]
    assert np.allclose(m.spring_rest[m.kind_start[BENDING]:], 2.0)


def test_l_shape_takes_the_straightest_partner(tmp_path):
    """three quads of a 2x2 patch: at the inner corner (4) the edges to 5 and 7 share
    no face, but each has a straighter partner (3 and 1), so no 5-7 spring"""
    verts, quads = grid_patch(3, 3)
    verts = verts[:8]
    quads = quads[:3]
    m = build_scene_model(load_scene(mesh_scene(tmp_path, verts, quads)))
    assert counts(m) == (10, 6, 4)
    assert springs(m, BENDING).tolist() == [[0, 2], [0, 6], [1, 7], [3, 5]]


def test_triangulated_patch(tmp_path):
    """a 3x3-vertex patch, each cell cut in two: 16 edges, 8 of them interior, one
    spring across each"""
    verts, quads = grid_patch(3, 3)
    tris = [t for a, b, c, d in quads for t in ([a, b, c], [a, c, d])]
    m = build_scene_model(load_scene(mesh_scene(tmp_path, verts, tris)))
    assert counts(m) == (16, 0, 8)
    # across the diagonal 0-4 of the first cell: the vertices 1 and 3
    assert [1, 3] in springs(m, BENDING).tolist()


# --------------------------------------------------------------------------
# pins, transform, mass, uvs


def test_pinned_vertices_and_region(tmp_path):
    """pinned_vertices pins those file vertices; pinned_region every point inside the
    box after the transform (here: the row j = 0, moved to z = 2)"""
    verts, quads = grid_patch(5, 4, d=0.25)
    m = build_scene_model(load_scene(mesh_scene(
        tmp_path, verts, quads, pinned_vertices=[19, 7],
        transform={"translate": [0, 0, 2]},
        pinned_region={"min": [-1, -1, 1.99], "max": [1, 1, 2.01]})))
    assert np.flatnonzero(m.pinned).tolist() == [0, 1, 2, 3, 4, 7, 19]


def test_transform_scale_then_rotate_x_y_z_then_translate(tmp_path):
    """(0, 1, 0) scaled by [1, 2, 1] is (0, 2, 0); 90° about x takes it to (0, 0, 2), then 90°
    about y to (2, 0, 0); translated by (1, 1, 1): (3, 1, 1). The other orders land elsewhere."""
    verts = [(0, 1, 0), (1, 1, 0), (0, 1, 1)]
    m = build_scene_model(load_scene(mesh_scene(
        tmp_path, verts, [[0, 1, 2]],
        transform={"scale": [1, 2, 1], "rotate": [90, 90, 0], "translate": [1, 1, 1]})))
    np.testing.assert_allclose(m.rest_positions[0], (3, 1, 1), atol=1e-12)
    # (1, 1, 0) -> (1, 2, 0) -> (1, 0, 2) -> (2, 0, -1) -> (3, 1, 0)
    np.testing.assert_allclose(m.rest_positions[1], (3, 1, 0), atol=1e-12)
    # (0, 1, 1) -> (0, 2, 1) -> (0, -1, 2) -> (2, -1, 0) -> (3, 0, 1)
    np.testing.assert_allclose(m.rest_positions[2], (3, 0, 1), atol=1e-12)
    # rest lengths from the transformed positions: the scale along y is felt by no edge here
    np.testing.assert_allclose(sorted(m.spring_rest), [1, 1, 2 ** 0.5], atol=1e-12)


def test_uniform_scale_scales_rest_lengths_and_area(tmp_path):
    verts, quads = grid_patch(3, 3)
    m = build_scene_model(load_scene(mesh_scene(tmp_path, verts, quads, transform={"scale": 0.5})))
    assert np.allclose(m.spring_rest[:m.kind_start[1]], 0.5)
    assert m.cloth.area == pytest.approx(1.0)
    assert m.cloth.point_mass(150.0) == pytest.approx(1.0 * 150.0 / 9)


def test_mass_is_area_times_density_over_vertices(tmp_path):
    """a 2 m x 1 m rectangle of two triangles and a unit square beside it: 3 m² over 6 vertices"""
    verts = [(0, 0, 0), (2, 0, 0), (2, 0, 1), (0, 0, 1), (3, 0, 0), (3, 0, 1)]
    m = build_scene_model(load_scene(mesh_scene(tmp_path, verts, [[0, 1, 2], [0, 2, 3], [1, 4, 5, 2]],
                                                density=20)))
    assert m.cloth.area == pytest.approx(3.0, abs=1e-14)
    assert m.cloth.point_mass(20.0) == pytest.approx(3.0 * 20.0 / 6, abs=1e-12)
    assert (m.cloth.width, m.cloth.height) == (3.0, 1.0)


def test_planar_uvs_in_the_unit_square(tmp_path):
    """without vt: the two largest axes of the rest box (here x and y of a tilted
    sheet), scaled to [0, 1]"""
    verts, quads = grid_patch(4, 3, d=0.5)
    m = build_scene_model(load_scene(mesh_scene(tmp_path, verts, quads, transform={"rotate": [-80, 0, 0]})))
    uv = m.uvs
    assert uv.dtype == np.float32 and uv.shape == (12, 2)
    assert uv.min(axis=0) == pytest.approx((0, 0)) and uv.max(axis=0) == pytest.approx((1, 1))
    np.testing.assert_allclose(uv[:, 0], np.tile(np.arange(4) / 3, 3), atol=1e-6)
    np.testing.assert_allclose(uv[:, 1], np.repeat(np.arange(3) / 2, 4), atol=1e-6)


def test_uvs_from_the_file(tmp_path):
    uvs = [(0.1, 0.2), (0.9, 0.2), (0.9, 0.7), (0.1, 0.7)]
    m = build_scene_model(load_scene(mesh_scene(tmp_path, SQUARE, [[0, 1, 2, 3]], uvs=uvs)))
    np.testing.assert_allclose(m.uvs, uvs, atol=1e-7)


# --------------------------------------------------------------------------
# other formats, welding


def test_ply_stl_glb_through_trimesh(tmp_path, capsys):
    """PLY and GLB keep the vertices; STL has three per triangle, welded (and said so)"""
    verts, quads = grid_patch(4, 4, d=0.2)
    tris = np.array([t for a, b, c, d in quads for t in ([a, b, c], [a, c, d])])
    tm = trimesh.Trimesh(np.array(verts, dtype=float), tris, process=False)
    ref = build_scene_model(load_scene(mesh_scene(tmp_path, verts, tris.tolist())))
    for ext in ("ply", "stl", "glb"):
        tm.export(tmp_path / f"sheet.{ext}")
        (tmp_path / "s.json").write_text(json.dumps({"cloth": {"mesh": f"sheet.{ext}", "thickness": 0.01}}))
        capsys.readouterr()
        m = build_scene_model(load_scene(tmp_path / "s.json"))
        err = capsys.readouterr().err
        if ext == "stl":
            assert err.strip().splitlines() == [
                (f"clothsim: warning: {tmp_path / 's.json'}: cloth.mesh: {tmp_path / 'sheet.stl'}: "
                 f"{3 * len(tris) - 16} vertices welded onto another at the same position")]
        else:
            assert err == ""
        assert m.num_points == 16 and counts(m) == counts(ref)
        if ext == "stl":  # the points in order of first use by the triangles; float32 positions
            first_use = list(dict.fromkeys(tris.ravel().tolist()))
            np.testing.assert_allclose(m.rest_positions, ref.rest_positions[first_use], atol=1e-6)
            assert np.array_equal(np.array(first_use)[m.triangles], ref.triangles)
        else:
            np.testing.assert_allclose(m.rest_positions, ref.rest_positions, atol=1e-6)
            assert np.array_equal(m.triangles, ref.triangles)


def test_seam_duplicates_are_welded_with_a_warning(tmp_path, capsys):
    """two quads whose shared edge is written twice (vertices 4 and 5 repeat 1 and 2):
    welded into one 6-point cloth, and a pin on the duplicate pins the welded point"""
    verts = [(0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1), (1, 0, 0), (1, 0, 1), (2, 0, 0), (2, 0, 1)]
    scene = mesh_scene(tmp_path, verts, [[0, 1, 2, 3], [4, 6, 7, 5]], pinned_vertices=[5])
    m = build_scene_model(load_scene(scene))
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [(f"clothsim: warning: {scene}: cloth.mesh: {tmp_path / 'mesh.obj'}: "
                    "2 vertices welded onto another at the same position")]
    assert m.num_points == 6 and counts(m) == (7, 4, 2)
    assert np.flatnonzero(m.pinned).tolist() == [2]


def test_round_trip_and_overrides(tmp_path):
    """to_dict reloads to the same scene; --set reaches a mesh cloth's material"""
    verts, quads = grid_patch(3, 3)
    path = mesh_scene(tmp_path, verts, quads, pinned_vertices=[0, 2], pinned_region={"min": [0, 0, 0],
                      "max": [1, 1, 0]}, transform={"scale": [1, 2, 3], "rotate": [10, 20, 30]}, ks=800)
    scene = load_scene(path)
    again = parse_scene(scene.to_dict(), str(path))
    assert again == scene
    assert np.array_equal(build_scene_model(again).rest_positions, build_scene_model(scene).rest_positions)
    assert load_scene(path, ["cloth.ks=123", "cloth.enable_bending=false"]).cloth.ks == 123
    assert scene.cloth.path == str(tmp_path / "mesh.obj")


def test_a_10000_vertex_mesh_builds_fast(tmp_path):
    verts, quads = grid_patch(100, 100, d=0.01)
    scene = mesh_scene(tmp_path, verts, quads)
    t0 = time.perf_counter()
    m = build_scene_model(load_scene(scene))
    took = time.perf_counter() - t0
    assert counts(m) == (2 * 100 * 99, 2 * 99 * 99, 2 * 100 * 98)
    assert took < 1.0, f"{took:.2f} s"


def test_vertices_in_no_face_are_dropped_with_a_warning(tmp_path, capsys):
    scene = mesh_scene(tmp_path, SQUARE + [(5, 5, 5)], [[0, 1, 2, 3]])
    m = build_scene_model(load_scene(scene))
    assert m.num_points == 4 and m.rest_positions.max() == 1
    assert capsys.readouterr().err.strip().splitlines() == [
        f"clothsim: warning: {scene}: cloth.mesh: {tmp_path / 'mesh.obj'}: 1 vertex dropped: in no face"]


# --------------------------------------------------------------------------
# bad input: one line naming the scene file, the key and the mesh file


def _tri(extra_lines=""):
    return "v 0 0 0\nv 1 0 0\nv 0 0 1\nv 1 0 1\n" + extra_lines


BAD_MESHES = [
    # (mesh file name, its text or bytes, extra cloth keys, key path, message part)
    ("nothere.obj", None, {}, "cloth.mesh", "nothere.obj: no such file"),
    ("bad.ply", b"garbage\x00\x01", {}, "cloth.mesh", "bad.ply: cannot read"),
    ("bad.obj", "v 0 0 zz\n", {}, "cloth.mesh", "bad.obj: line 1: cannot read 'v'"),
    ("binary.obj", b"\xff\xfe\x00v", {}, "cloth.mesh", "binary.obj: cannot read: not a text OBJ file"),
    ("empty.obj", _tri(), {}, "cloth.mesh", "empty.obj: the file holds no faces"),
    ("empty.stl", b"", {}, "cloth.mesh", "empty.stl: the file holds no faces"),
    ("flat.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n", {}, "cloth.mesh", "flat.obj: face 0 is degenerate: it has zero area"),
    ("twice.obj", _tri("f 1 2 3\nf 2 4 4\n"), {}, "cloth.mesh", "twice.obj: face 1 is degenerate: it names a vertex twice"),
    ("weld.obj", _tri("v 1 0 0\nf 1 2 3\nf 2 5 4\n"), {}, "cloth.mesh",
     "weld.obj: face 1 is degenerate: two of its vertices are at the same position"),
    ("fin.obj", _tri("v 0 1 0\nf 1 2 3\nf 2 1 4\nf 1 2 5\n"), {}, "cloth.mesh",
     "fin.obj: non-manifold: the edge between vertices 0 and 1 is shared by 3 faces"),
    ("pent.obj", _tri("v 2 0 0\nf 1 2 5 4 3\n"), {}, "cloth.mesh", "pent.obj: line 6: a face of 5 vertices"),
    ("range.obj", _tri("f 1 2 9\n"), {}, "cloth.mesh", "range.obj: a face names vertex 9, but only 4"),
    ("sheet.fbx", "", {}, "cloth.mesh", "expected an OBJ, PLY, STL or glTF/GLB file"),
    ("ok.obj", _tri("f 1 2 4 3\n"), {"pinned_vertices": [0, 4]}, "cloth.pinned_vertices[1]",
     "expected a vertex index of"),
    ("ok.obj", _tri("f 1 2 4 3\n"), {"pinned_vertices": [-1]}, "cloth.pinned_vertices[0]", "(0..3), got -1"),
    ("ok.obj", _tri("f 1 2 4 3\n"), {"pinned_region": {"min": [0, 1, 0], "max": [1, 0, 1]}},
     "cloth.pinned_region", "expected min <= max on every axis, got y min 1 > max 0"),
    ("ok.obj", _tri("f 1 2 4 3\n"), {"width": 1.0}, "cloth.width", "has no grid keys"),
    ("ok.obj", _tri("f 1 2 4 3\n"), {"transform": {"scale": 0}}, "cloth.transform.scale", "expected a number > 0"),
    ("ok.obj", _tri("f 1 2 4 3\n"), {"transform": {"spin": 1}}, "cloth.transform.spin", "unknown key"),
    ("ok.obj", _tri("f 1 2 4 3\n"), {"transform": {"scale": 1e6, "translate": [1e6, 0, 0]}}, "cloth.mesh",
     "expected every point within ±1e+06 m after the transform, got one at 2e+06"),
    ("far.obj", _tri("v 1e300 0 0\nf 1 2 5\n"), {}, "cloth.mesh", "vertex 4 has a coordinate beyond ±1e+12"),
    ("ok.obj", _tri("f 1 2 4 3\n"), {"transform": {"scale": 1e300}}, "cloth.transform.scale", "<= 1e+06"),
    ("ok.obj", _tri("f 1 2 4 3\n"), {"thickness": 5e-324}, "cloth.thickness", ">= 1e-06"),
]


def _bad_scene(tmp_path, name, content, extra):
    if isinstance(content, bytes):
        (tmp_path / name).write_bytes(content)
    elif content is not None:
        (tmp_path / name).write_text(content)
    scene = tmp_path / "scene.json"
    scene.write_text(json.dumps({"cloth": {"mesh": name, "thickness": 0.01, **extra}}))
    return scene


@pytest.mark.parametrize("name, content, extra, key, message", BAD_MESHES,
                         ids=[f"{c[0]}-{c[3]}" for c in BAD_MESHES])
def test_bad_mesh_is_a_scene_error(tmp_path, capsys, name, content, extra, key, message):
    """a SceneError naming the key (and, for the file itself, the mesh file); through
    the CLI one line on stderr and exit code 2"""
    scene = _bad_scene(tmp_path, name, content, extra)
    with pytest.raises(SceneError) as exc:
        load_scene(scene)
    assert exc.value.key == key and exc.value.source == str(scene)
    assert message in exc.value.message
    capsys.readouterr()
    assert main(["simulate", str(scene), "--seconds", "0.01", "--no-progress"]) == 2
    assert capsys.readouterr().err.splitlines() == [f"clothsim: error: {scene}: {key}: {exc.value.message}"]


def test_bad_mesh_in_a_cloth_list_names_its_index(tmp_path):
    (tmp_path / "ok.obj").write_text(_tri("f 1 2 4 3\n"))
    scene = tmp_path / "scene.json"
    scene.write_text(json.dumps({"cloth": [{"mesh": "ok.obj", "thickness": 0.01},
                                           {"mesh": "meshes/gone.obj", "thickness": 0.01}]}))
    with pytest.raises(SceneError) as exc:
        load_scene(scene)
    assert str(exc.value) == f"{scene}: cloth[1].mesh: {tmp_path / 'meshes' / 'gone.obj'}: no such file"


def test_bad_mesh_through_the_command_line_process(tmp_path):
    """the real command: one line on stderr, exit code 2, no traceback"""
    import subprocess
    import sys
    scene = _bad_scene(tmp_path, "fin.obj", BAD_MESHES[9][1], {})
    r = subprocess.run([sys.executable, "-m", "clothsim", "simulate", str(scene), "--seconds", "0.01"],
                       capture_output=True, text=True, timeout=120, check=False)
    assert r.returncode == 2
    assert r.stderr.splitlines() == [(f"clothsim: error: {scene}: cloth.mesh: {tmp_path / 'fin.obj'}: non-manifold: "
                                      "the edge between vertices 0 and 1 is shared by 3 faces (at most 2)")]


# --------------------------------------------------------------------------
# a whole run


def test_pinned2_quad_obj_rests_where_the_grid_does(pinned2_obj):
    """2 s of the pinned2 grid and of its quad OBJ: mean heights within 1 cm (the
    springs, masses and pins are the same; only the solver path differs)"""
    from clothsim import Simulation
    folder, _ = pinned2_obj
    grid = Simulation(load_scene(SCENES / "pinned2.json"))
    mesh = Simulation(load_scene(folder / "scene.json"))
    assert mesh.model.cloth.grid is None
    grid.run(2.0)
    mesh.run(2.0)
    assert np.array_equal(mesh.positions[[0, 49]], grid.positions[[0, 49]])  # the pins held
    assert mesh.positions[:, 1].mean() < 0.6  # it fell
    assert abs(mesh.positions[:, 1].mean() - grid.positions[:, 1].mean()) < 0.01


def test_non_finite_vertex_is_a_scene_error(tmp_path):
    scene = _bad_scene(tmp_path, "nan.obj", "v 0 0 0\nv 1 0 nan\nv 0 0 1\nf 1 2 3\n", {})
    with pytest.raises(SceneError, match=r"nan.obj: vertex 1 is not at a finite position$"):
        load_scene(scene)


def test_welded_point_takes_the_uv_of_a_vertex_a_face_names(tmp_path, capsys):
    """vertex 0 is in no face but at the place of vertex 4, which a face names with
    its uv: the welded point has vertex 4's uv"""
    text = ("v 1 0 0\nv 0 0 0\nv 1 0 1\nv 0 0 1\nv 1 0 0\n"
            "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
            "f 2/1 5/2 3/3 4/4\n")
    scene = _bad_scene(tmp_path, "uv.obj", text, {"pinned_vertices": [0]})
    m = build_scene_model(load_scene(scene))
    assert m.num_points == 4 and "1 vertex welded" in capsys.readouterr().err
    np.testing.assert_array_equal(m.rest_positions, [[1, 0, 0], [0, 0, 0], [1, 0, 1], [0, 0, 1]])
    np.testing.assert_array_equal(m.uvs, [[1, 0], [0, 0], [1, 1], [0, 1]])
    assert np.flatnonzero(m.pinned).tolist() == [0]
