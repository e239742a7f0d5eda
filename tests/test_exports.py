"""--export-sequence and --export-npz from simulate and render."""

from __future__ import annotations

import json

import numpy as np

from clothsim import Simulation
from clothsim.cli import main

from .conftest import small_scene


def test_simulate_npz_trajectory(tmp_path, write_scene, capsys):
    """the npz holds positions[frame, point, 3] from the start, the mesh and the scene"""
    scene = write_scene(small_scene())
    out = tmp_path / "t.npz"
    assert main(["simulate", str(scene), "--seconds", "0.1", "--export-npz", str(out)]) == 0
    d = np.load(out)
    assert d["positions"].shape == (10, 256, 3) and d["times"][0] == 0.0
    sim = Simulation.from_file(scene)
    np.testing.assert_array_equal(d["positions"][0], sim.model.rest_positions)
    for _ in range(9):
        sim.step()
    np.testing.assert_array_equal(d["positions"][-1], sim.positions)
    assert d["triangles"].shape == (450, 3) and d["uvs"].shape == (256, 2)
    assert json.loads(str(d["scene"]))["cloth"]["num_width_points"] == 16


def test_obj_sequence_one_file_per_frame(tmp_path, write_scene, capsys):
    """render --export-sequence writes frame_0000.obj .. frame_NNNN.obj, and refuses to overwrite them"""
    scene = write_scene(small_scene())
    seq = tmp_path / "seq"
    args = ["render", str(scene), "-o", str(tmp_path / "x.png"), "--seconds", "0.1", "--size", "32x32",
            "--export-sequence", str(seq)]
    assert main(args) == 0
    files = sorted(p.name for p in seq.iterdir())
    assert files == [f"frame_{k:04d}.obj" for k in range(10)]
    first = seq.joinpath("frame_0000.obj").read_text()
    last = seq.joinpath("frame_0009.obj").read_text()
    assert first != last and first.count("\nv ") == 256
    assert main(args[:3] + [str(tmp_path / "y.png")] + args[4:]) == 2
    assert "already holds frame_" in capsys.readouterr().err


def test_outputs_get_the_mode_of_the_users_umask(tmp_path):
    """a finished output is readable as any file the user makes, not 0600 like a temp file"""
    import os
    import stat

    from clothsim.outputs import UMASK, write_atomic

    out = tmp_path / "out.txt"
    write_atomic(out, lambda tmp: tmp.write_text("x"))
    assert stat.S_IMODE(os.stat(out).st_mode) == 0o666 & ~UMASK


# ------------------------------------------------------------------ several cloths, mesh cloths


def _two_cloths(write_scene):
    from .handmade import two_cloth_scene

    return write_scene(two_cloth_scene(), "two.json")


def _stepped(path, frames: int) -> Simulation:
    sim = Simulation.from_file(path)
    for _ in range(frames):
        sim.step()
    return sim


def _trimesh_objects(path):
    """the OBJ read back with trimesh, one geometry per ``o`` object"""
    import trimesh

    scene = trimesh.load(path, process=False, split_objects=True, group_material=False)
    return scene.geometry


def _assert_objects_are_the_cloths(geometry, sim, positions):
    """each cloth is one object of its name holding exactly its own faces, corner
    by corner at its points' positions (to the 9 digits of the v lines)"""
    assert sorted(geometry) == sorted(c.name for c in sim.cloths)
    for cloth in sim.cloths:
        g = geometry[cloth.name]
        mine = positions[cloth.model.points]
        assert len(g.faces) == len(cloth.triangles) and len(g.vertices) == len(mine)
        np.testing.assert_allclose(g.vertices[g.faces], mine[cloth.triangles], rtol=1e-8, atol=1e-12)


def test_npz_of_several_cloths_concatenated_with_their_ranges(tmp_path, write_scene, capsys):
    """positions hold every cloth's points in scene order; cloth_start, cloth_names and
    cloth_triangle_start say which points and triangles are whose"""
    scene = _two_cloths(write_scene)
    out = tmp_path / "t.npz"
    assert main(["simulate", str(scene), "--seconds", "0.1", "--export-npz", str(out)]) == 0
    d = np.load(out)
    assert d["positions"].shape == (10, 256 + 96, 3)
    assert d["cloth_names"].tolist() == ["cloth_0", "cloth_1"]
    assert d["cloth_start"].tolist() == [0, 256, 352]
    assert d["cloth_triangle_start"].tolist() == [0, 450, 450 + 154]
    sim = _stepped(scene, 9)
    np.testing.assert_array_equal(d["positions"][-1], sim.positions)
    for k, cloth in enumerate(sim.cloths):
        a, b = d["cloth_start"][k:k + 2]
        ta, tb = d["cloth_triangle_start"][k:k + 2]
        np.testing.assert_array_equal(d["positions"][-1, a:b], cloth.positions)
        np.testing.assert_array_equal(d["triangles"][ta:tb] - a, cloth.triangles)
        assert d["triangles"][ta:tb].min() >= a and d["triangles"][ta:tb].max() < b


def test_npz_of_one_cloth_names_it(tmp_path, write_scene, capsys):
    """a single cloth: one range over every point and triangle, named cloth"""
    out = tmp_path / "t.npz"
    assert main(["simulate", str(write_scene(small_scene())), "--seconds", "0.05", "--export-npz", str(out)]) == 0
    d = np.load(out)
    assert d["cloth_names"].tolist() == ["cloth"]
    assert d["cloth_start"].tolist() == [0, 256] and d["cloth_triangle_start"].tolist() == [0, 450]


def test_obj_one_object_per_cloth_read_by_trimesh(tmp_path, write_scene):
    """write_model_obj of two cloths: two objects named by the cloths, each with
    its own faces; a single cloth's file has no o line"""
    from clothsim.export import model_obj_text, write_model_obj

    sim = _stepped(_two_cloths(write_scene), 5)
    path = tmp_path / "two.obj"
    write_model_obj(path, sim.model, sim.positions, sim.normals)
    text = path.read_text()
    assert [line for line in text.splitlines() if line.startswith("o ")] == ["o cloth_0", "o cloth_1"]
    assert text == model_obj_text(sim.model, sim.positions)  # normals computed alike when not given
    _assert_objects_are_the_cloths(_trimesh_objects(path), sim, sim.positions)
    one = Simulation.from_file(write_scene(small_scene(), "one.json"))
    assert "\no " not in model_obj_text(one.model, one.positions)


def test_obj_of_a_mesh_cloth_keeps_its_faces(tmp_path):
    """a hand-made Delaunay disc beside a grid: the disc's object holds exactly
    its triangles (not a grid's), named as its cloth"""
    from clothsim.export import write_model_obj

    from .handmade import disc_and_grid, simulation_of

    sim = simulation_of(disc_and_grid())
    path = tmp_path / "mesh.obj"
    write_model_obj(path, sim.model, sim.positions)
    geometry = _trimesh_objects(path)
    assert sorted(geometry) == ["disc", "grid"]
    _assert_objects_are_the_cloths(geometry, sim, sim.positions)


def test_obj_sequence_of_several_cloths(tmp_path, write_scene, capsys):
    """render --export-sequence of two cloths: every frame has both objects, the
    last one at the run's last positions"""
    scene = _two_cloths(write_scene)
    seq = tmp_path / "seq"
    assert main(["render", str(scene), "-o", str(tmp_path / "x.png"), "--seconds", "0.1", "--size", "32x32",
                 "--export-sequence", str(seq)]) == 0
    files = sorted(seq.iterdir())
    assert len(files) == 10
    assert all(f.read_text().count("\no ") == 2 for f in files)
    sim = _stepped(scene, 9)
    _assert_objects_are_the_cloths(_trimesh_objects(files[-1]), sim, sim.positions)
    rest = Simulation.from_file(scene)
    _assert_objects_are_the_cloths(_trimesh_objects(files[0]), rest, rest.positions)


def test_simulation_export_obj_of_several_cloths(tmp_path, write_scene):
    """Simulation.export_obj: one object per cloth, as write_model_obj"""
    from clothsim.export import model_obj_text

    sim = Simulation.from_file(_two_cloths(write_scene))
    sim.export_obj(tmp_path / "s.obj")
    assert (tmp_path / "s.obj").read_text() == model_obj_text(sim.model, sim.positions, sim.normals)
    _assert_objects_are_the_cloths(_trimesh_objects(tmp_path / "s.obj"), sim, sim.positions)
