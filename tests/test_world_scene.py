"""The scene keys of the moving world: box, mesh colliders, animation, handles, wind."""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest

from clothsim.errors import SceneError
from clothsim.motion import Animation, Keyframe
from clothsim.scene import load_scene, parse_scene

from .conftest import small_scene
from .test_cli import clothsim_process

CUBE_OBJ = """v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1
f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8
"""
QUAD_OBJ = "v 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1\nf 1 2 3 4\n"
ANIM = {"keys": [{"t": 0}, {"t": 1.5, "translate": [0.3, 0, 0], "rotate": [0, 90, 0]}], "loop": True}
BOX = {"center": [0, 0, 0], "size": [1, 1, 1], "friction": 0.3}
WIND = {"velocity": [2, 0, 0]}


def scene_with(**sections) -> dict:
    return small_scene(**copy.deepcopy(sections))


def load(write_scene, data, meshes=None, **kw):
    path = write_scene(data)
    for name, text in (meshes or {}).items():
        (path.parent / name).write_text(text)
    return load_scene(path, **kw), path


def error_of(write_scene, data, meshes=None, overrides=()) -> tuple[SceneError, str]:
    path = write_scene(data)
    for name, text in (meshes or {"cube.obj": CUBE_OBJ, "quad.obj": QUAD_OBJ}).items():
        (path.parent / name).write_text(text)
    with pytest.raises(SceneError) as info:
        load_scene(path, list(overrides))
    return info.value, str(path)


def assert_names(err: SceneError, path: str, key: str, expected: str = "expected") -> None:
    """one line naming the file and the key path, saying what was expected (or that a
    required key is missing; a fault of a mesh file itself says what is wrong with it,
    as a mesh cloth's does)"""
    text = str(err)
    assert "\n" not in text
    assert err.key == key and text.startswith(f"{path}: {key}: "), text
    assert expected in text, text
    file_fault = any(s in text for s in ("no such file", "no faces", "not at a finite", "zero area"))
    assert "expected" in text or "missing required key" in text or file_fault, text


# --------------------------------------------------------------------------
# animation


def test_animation_reads_keys_and_defaults(write_scene):
    scene, _ = load(write_scene, scene_with(sphere={"origin": [0, 0, 0], "radius": 0.1, "friction": 0.2,
                                                    "animation": ANIM}))
    a = scene.spheres[0].animation
    assert a == Animation(keys=(Keyframe(0.0), Keyframe(1.5, (0.3, 0.0, 0.0), (0.0, 90.0, 0.0))), loop=True)
    still = parse_scene(scene_with(sphere={"origin": [0, 0, 0], "radius": 0.1, "friction": 0.2}))
    assert still.spheres[0].animation is None


def test_parsed_animation_samples():
    """a read animation interpolates, loops, and turns about its pivot"""
    a = parse_scene(scene_with(box=dict(BOX, animation=ANIM))).boxes[0].animation
    tr, rot = a.offsets([0.75, 1.5, 2.25])
    np.testing.assert_allclose(tr[:, 0], [0.15, 0.3, 0.15])
    np.testing.assert_allclose(rot[:, 1], [45, 90, 45])
    R, o = a.rigid([1.5], pivot=[1, 0, 0])
    np.testing.assert_allclose(R[0] @ [2, 0, 0] + o[0], [1.3, 0, -1], atol=1e-12)


ANIMATION_ERRORS = [
    ({"loop": True}, "keys", "missing required key"),
    ({"keys": []}, "keys", "expected a non-empty list"),
    ({"keys": {"t": 0}}, "keys", "expected a non-empty list"),
    ({"keys": [3]}, "keys[0]", "expected an object"),
    ({"keys": [{"translate": [0, 0, 0]}]}, "keys[0].t", "missing required key"),
    ({"keys": [{"t": -0.5}]}, "keys[0].t", ">= 0"),
    ({"keys": [{"t": "soon"}]}, "keys[0].t", "expected a number"),
    ({"keys": [{"t": 1e30}]}, "keys[0].t", "<= 1e+09"),
    ({"keys": [{"t": 0}, {"t": 1.5}, {"t": 0.5}]}, "keys[2].t", "expected a time after 1.5 (keys[1].t), got 0.5"),
    ({"keys": [{"t": 0}, {"t": 1}, {"t": 1}]}, "keys[2].t", "expected a time after 1 (keys[1].t), got 1"),
    ({"keys": [{"t": 0, "translate": [0, 0]}]}, "keys[0].translate", "expected a list of 3 numbers"),
    ({"keys": [{"t": 0, "translate": [0, 2e6, 0]}]}, "keys[0].translate[1]", "<= 1e+06"),
    ({"keys": [{"t": 0, "rotate": [0, 0, -2e6]}]}, "keys[0].rotate[2]", ">= -1e+06"),
    ({"keys": [{"t": 0, "scale": 2}]}, "keys[0].scale", "unknown key"),
    ({"keys": [{"t": 0}], "speed": 2}, "speed", "unknown key"),
    ({"keys": [{"t": 0}], "loop": "yes"}, "loop", "expected true or false"),
]


@pytest.mark.parametrize("anim, sub, expected", ANIMATION_ERRORS)
def test_bad_animation_names_key(write_scene, anim, sub, expected):
    data = scene_with(sphere={"origin": [0, 0, 0], "radius": 0.1, "friction": 0.2, "animation": anim})
    err, path = error_of(write_scene, data)
    assert_names(err, path, f"sphere.animation.{sub}", expected)


def test_animation_not_an_object(write_scene):
    err, path = error_of(write_scene, scene_with(plane={"point": [0, 0, 0], "normal": [0, 1, 0], "friction": 0.5,
                                                        "animation": [1]}))
    assert_names(err, path, "plane.animation", "expected an object")


@pytest.mark.parametrize("section, prefix", [
    ({"plane": [{"point": [0, 0, 0], "normal": [0, 1, 0], "friction": 0.5},
                {"point": [0, 0, 0], "normal": [0, 1, 0], "friction": 0.5, "animation": "A"}]}, "plane[1]"),
    ({"box": dict(BOX, animation="A")}, "box"),
    ({"mesh": [dict(path="cube.obj", friction=0.5, animation="A")]}, "mesh[0]"),
    ({"cloth": {"handles": [{"points": [[0, 1]], "animation": "A"}]}}, "cloth.handles[0]"),
])
def test_every_animation_is_checked_at_its_key(write_scene, section, prefix):
    data = json.loads(json.dumps(scene_with(**section)).replace('"A"', json.dumps(
        {"keys": [{"t": 0}, {"t": 2}, {"t": 1}]})))
    err, path = error_of(write_scene, data)
    assert_names(err, path, f"{prefix}.animation.keys[2].t", "expected a time after 2 (keys[1].t), got 1")


# --------------------------------------------------------------------------
# box


def test_box_defaults_and_list(write_scene):
    scene, _ = load(write_scene, scene_with(box=[BOX, dict(BOX, rotate=[0, 45, 0], margin=0.01, animation=ANIM)]))
    a, b = scene.boxes
    assert (a.center, a.size, a.friction, a.rotate, a.margin, a.animation) == (
        (0, 0, 0), (1, 1, 1), 0.3, (0, 0, 0), 0.001, None)
    assert b.rotate == (0, 45, 0) and b.margin == 0.01 and b.animation.loop


@pytest.mark.parametrize("box, key, expected", [
    ({"size": [1, 1, 0]}, "box.size[2]", "expected a number >= 1e-06"),
    ({"size": [1, -1, 1]}, "box.size[1]", ">= 1e-06"),
    ({"size": [1, 1, 2e6]}, "box.size[2]", "<= 1e+06"),
    ({"size": 1}, "box.size", "expected a list of 3 numbers"),
    ({"center": [0, 0, "x"]}, "box.center[2]", "expected a number"),
    ({"friction": 1.5}, "box.friction", "<= 1"),
    ({"rotate": [0, 0]}, "box.rotate", "expected a list of 3 numbers"),
    ({"margin": -0.1}, "box.margin", ">= 0"),
    ({"margin": 2}, "box.margin", "<= 1"),
    ({"colour": 1}, "box.colour", "unknown key"),
])
def test_bad_box_names_key(write_scene, box, key, expected):
    err, path = error_of(write_scene, scene_with(box=dict(BOX, **box)))
    assert_names(err, path, key, expected)


def test_missing_box_key_and_second_of_a_list(write_scene):
    err, path = error_of(write_scene, scene_with(box={"center": [0, 0, 0], "size": [1, 1, 1]}))
    assert err.key == "box.friction" and "missing required key" in str(err)
    err, path = error_of(write_scene, scene_with(box=[BOX, dict(BOX, size=[1, 1, 0])]))
    assert_names(err, path, "box[1].size[2]")


# --------------------------------------------------------------------------
# mesh colliders


def test_closed_cube_quads_split_and_transform_applied(write_scene):
    scene, path = load(write_scene, scene_with(mesh={"path": "cube.obj", "friction": 0.4, "transform": {
        "scale": 2, "translate": [1, 0, 0]}}), {"cube.obj": CUBE_OBJ})
    (m,) = scene.mesh_colliders
    assert m.closed and m.path == "cube.obj" and m.file == str(path.parent / "cube.obj")
    assert m.triangles.shape == (12, 3) and m.triangles.dtype == np.int64
    assert m.vertices.dtype == np.float64 and m.vertices.shape == (8, 3)
    assert m.vertices.min(axis=0).tolist() == [1, 0, 0] and m.vertices.max(axis=0).tolist() == [3, 2, 2]
    assert m.pivot.tolist() == [2, 1, 1] and (m.margin, m.friction, m.animation) == (0.001, 0.4, None)


def test_open_quad_is_not_closed(write_scene):
    scene, _ = load(write_scene, scene_with(mesh=[{"path": "quad.obj", "friction": 0.1}]), {"quad.obj": QUAD_OBJ})
    (m,) = scene.mesh_colliders
    assert not m.closed and m.triangles.tolist() == [[0, 1, 2], [0, 2, 3]]


def test_triangle_soup_is_welded_and_degenerate_faces_dropped(write_scene):
    """a cube written as separate triangles (as an STL is) welds into a closed solid; a
    zero-area face is dropped; an edge of three faces is allowed for a collider"""
    v = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]]
    tris = [[0, 3, 2], [0, 2, 1], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4], [1, 2, 6], [1, 6, 5],
            [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]]
    text = "".join(f"v {' '.join(map(str, v[i]))}\n" for t in tris for i in t)
    text += "".join(f"f {3 * k + 1} {3 * k + 2} {3 * k + 3}\n" for k in range(len(tris)))
    text += "v 0 0 0\nv 0.5 0 0\nv 1 0 0\nf -3 -2 -1\n"  # three corners on a line
    scene, _ = load(write_scene, scene_with(mesh={"path": "soup.obj", "friction": 0.1}), {"soup.obj": text})
    m = scene.mesh_colliders[0]
    assert m.closed and m.vertices.shape == (8, 3) and m.triangles.shape == (12, 3)
    fin = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 2 5\n"
    scene, _ = load(write_scene, scene_with(mesh={"path": "fin.obj", "friction": 0.1}), {"fin.obj": fin})
    assert not scene.mesh_colliders[0].closed and len(scene.mesh_colliders[0].triangles) == 3


@pytest.mark.parametrize("mesh, meshes, key, expected", [
    ({"path": "nowhere.obj"}, {}, "mesh.path", "nowhere.obj: no such file"),
    ({"path": "empty.obj"}, {"empty.obj": "v 0 0 0\n"}, "mesh.path", "empty.obj: the file holds no faces"),
    ({"path": "nan.obj"}, {"nan.obj": "v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"}, "mesh.path",
     "nan.obj: vertex 0 is not at a finite position"),
    ({"path": "flat.obj"}, {"flat.obj": "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n"}, "mesh.path",
     "flat.obj: every face has zero area"),
    ({"path": "cube.txt"}, {"cube.txt": CUBE_OBJ}, "mesh.path", "cube.txt: expected an OBJ"),
    ({"path": 7}, {}, "mesh.path", "expected the name of a mesh file, got 7"),
    ({"path": "cube.obj", "transform": {"scale": 0}}, None, "mesh.transform.scale", "> 0"),
    ({"path": "cube.obj", "transform": {"scale": 1e6, "translate": [9e5, 0, 0]}}, None, "mesh.path",
     "within ±1e+06 m after the transform"),
    ({"path": "cube.obj", "friction": -1}, None, "mesh.friction", ">= 0"),
    ({"path": "cube.obj", "margin": 5}, None, "mesh.margin", "<= 1"),
    ({"path": "cube.obj", "closed": True}, None, "mesh.closed", "unknown key"),
])
def test_bad_mesh_collider_names_key_and_file(write_scene, mesh, meshes, key, expected):
    data = scene_with(mesh={"friction": 0.5, **mesh})
    err, path = error_of(write_scene, data, meshes)
    assert_names(err, path, key, expected)


def test_missing_mesh_collider_key(write_scene):
    err, path = error_of(write_scene, scene_with(mesh=[{"path": "cube.obj"}]))
    assert str(err) == f"{path}: mesh[0].friction: missing required key"


def test_too_many_triangles(write_scene, monkeypatch):
    import clothsim.collider_mesh as cm
    monkeypatch.setattr(cm, "TRIANGLES_MAX", 11)
    err, path = error_of(write_scene, scene_with(mesh={"path": "cube.obj", "friction": 0.5}))
    assert_names(err, path, "mesh.path", "at most 11 triangles, got 12")


# --------------------------------------------------------------------------
# wind


def test_wind_defaults():
    w = parse_scene(scene_with(wind=WIND)).wind
    assert (w.velocity, w.turbulence, w.drag, w.lift, w.seed) == ((2, 0, 0), 0, 1, 0, 0)
    assert parse_scene(scene_with()).wind is None


@pytest.mark.parametrize("wind, key, expected", [
    ({"velocity": [1, 0]}, "wind.velocity", "expected a list of 3 numbers"),
    ({"velocity": 3}, "wind.velocity", "expected a list of 3 numbers"),
    ({"velocity": [1, 0, 2e6]}, "wind.velocity[2]", "<= 1e+06"),
    ({"turbulence": 1.5}, "wind.turbulence", "<= 1"),
    ({"drag": -1}, "wind.drag", ">= 0"),
    ({"drag": 1e4}, "wind.drag", "<= 1000"),
    ({"lift": -1e4}, "wind.lift", ">= -1000"),
    ({"seed": -1}, "wind.seed", ">= 0"),
    ({"seed": 0.5}, "wind.seed", "expected an integer"),
    ({"gusts": 1}, "wind.gusts", "unknown key"),
])
def test_bad_wind_names_key(write_scene, wind, key, expected):
    err, path = error_of(write_scene, scene_with(wind=dict(WIND, **wind)))
    assert_names(err, path, key, expected)


def test_wind_is_one_object_with_velocity(write_scene):
    err, path = error_of(write_scene, scene_with(wind=[WIND]))
    assert_names(err, path, "wind", "expected an object")
    err, path = error_of(write_scene, scene_with(wind={"drag": 1}))
    assert str(err) == f"{path}: wind.velocity: missing required key"


# --------------------------------------------------------------------------
# handles


def test_grid_handles():
    scene = parse_scene(scene_with(cloth={"pinned": [], "handles": [
        {"points": [[0, 0], [15, 0]], "animation": ANIM}, {"points": [[3, 4]], "animation": {"keys": [{"t": 0}]}}]}))
    a, b = scene.cloth.handles
    assert a.points == [(0, 0), (15, 0)] and a.vertices == [] and a.animation.loop
    assert b.points == [(3, 4)] and b.animation.keys == (Keyframe(0.0),)


@pytest.mark.parametrize("handles, key, expected", [
    ({"points": [[0, 1], [16, 0]]}, "cloth.handles[0].points[1]", "inside the 16x16 grid"),
    ({"points": [[0, 1], [0, 2], [1, 2], [0, -1]]}, "cloth.handles[0].points[3]", "inside the 16x16 grid"),
    ({"points": []}, "cloth.handles[0].points", "expected a non-empty list"),
    ({"points": [[0, 1, 2]]}, "cloth.handles[0].points[0]", "expected a pair [i, j]"),
    ({"points": [[0, 1.5]]}, "cloth.handles[0].points[0][1]", "expected an integer"),
    ({"points": [[0, 0]]}, "cloth.handles[0].points[0]", "already pinned"),
    ({"points": [[0, 1], [0, 1]]}, "cloth.handles[0].points[1]", "already in cloth.handles[0]"),
    ({"vertices": [0]}, "cloth.handles[0].vertices", "expected 'points' for a grid cloth's handle"),
    ({"points": [[0, 1]], "weight": 1}, "cloth.handles[0].weight", "unknown key"),
])
def test_bad_grid_handle_names_key(write_scene, handles, key, expected):
    handle = dict({"animation": ANIM}, **handles)
    err, path = error_of(write_scene, scene_with(cloth={"handles": [handle]}))
    assert_names(err, path, key, expected)


def test_handle_needs_an_animation_and_handles_a_list(write_scene):
    err, path = error_of(write_scene, scene_with(cloth={"handles": [{"points": [[1, 1]]}]}))
    assert str(err) == f"{path}: cloth.handles[0].animation: missing required key"
    err, path = error_of(write_scene, scene_with(cloth={"handles": {"points": [[1, 1]], "animation": ANIM}}))
    assert_names(err, path, "cloth.handles", "expected a list of handles")


def mesh_cloth(**keys) -> dict:
    return {"cloth": {"mesh": "quad.obj", "thickness": 0.01, **keys}}


def test_mesh_handles(write_scene):
    scene, _ = load(write_scene, mesh_cloth(pinned_vertices=[0], handles=[{"vertices": [2, 3], "animation": ANIM}]),
                    {"quad.obj": QUAD_OBJ})
    (h,) = scene.cloth.handles
    assert h.vertices == [2, 3] and h.points == []


@pytest.mark.parametrize("handles, key, expected", [
    ({"vertices": [5]}, "cloth.handles[0].vertices[0]", "expected a vertex index of"),
    ({"vertices": [-1]}, "cloth.handles[0].vertices[0]", "(0..4)"),
    ({"vertices": [1, 0]}, "cloth.handles[0].vertices[1]", "already pinned"),
    ({"vertices": []}, "cloth.handles[0].vertices", "expected a non-empty list"),
    ({"points": [[0, 0]]}, "cloth.handles[0].points", "expected 'vertices' for a mesh cloth's handle"),
])
def test_bad_mesh_handle_names_key(write_scene, handles, key, expected):
    quad_and_stray = "v 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1\nv 5 5 5\nf 1 2 3 4\n"
    err, path = error_of(write_scene, mesh_cloth(pinned_vertices=[0], handles=[dict({"animation": ANIM}, **handles)]),
                         {"quad.obj": quad_and_stray})
    assert_names(err, path, key, expected)


def test_mesh_handle_vertex_in_no_face(write_scene):
    err, path = error_of(write_scene, mesh_cloth(handles=[{"vertices": [4], "animation": ANIM}]),
                         {"quad.obj": "v 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1\nv 5 5 5\nf 1 2 3 4\n"})
    assert_names(err, path, "cloth.handles[0].vertices[0]", "in no face")


# --------------------------------------------------------------------------
# round trips and overrides


EVERYTHING = dict(
    cloth={"pinned": [[0, 0]], "handles": [{"points": [[15, 0], [15, 15]], "animation": ANIM}]},
    sphere=[{"origin": [0.5, 0, 0.5], "radius": 0.2, "friction": 0.3},
            {"origin": [0, 0, 0], "radius": 0.1, "friction": 0.3, "animation": ANIM}],
    plane={"point": [0, 0, 0], "normal": [0, 2, 0], "friction": 0.5, "animation": {"keys": [{"t": 0}]}},
    box=[BOX, dict(BOX, rotate=[10, 20, 30], margin=0.0, animation=ANIM)],
    mesh=[{"path": "cube.obj", "friction": 0.4, "transform": {"scale": [1, 2, 3], "rotate": [0, 30, 0]}},
          {"path": "sub/quad.obj", "friction": 0.0, "margin": 0.01, "animation": ANIM}],
    wind={"velocity": [1, 0, 0.5], "turbulence": 0.2, "drag": 0.8, "lift": -0.1, "seed": 7},
)


def test_everything_round_trips_through_dict(write_scene, recwarn):
    path = write_scene(scene_with(**EVERYTHING))
    (path.parent / "cube.obj").write_text(CUBE_OBJ)
    (path.parent / "sub").mkdir()
    (path.parent / "sub" / "quad.obj").write_text(QUAD_OBJ)
    scene = load_scene(path)
    out = scene.to_dict()
    assert "animation" not in out["sphere"][0] and "animation" in out["sphere"][1]
    assert out["mesh"][1]["path"] == "sub/quad.obj"
    again = parse_scene(json.loads(json.dumps(out)), str(path))
    assert again == scene
    np.testing.assert_array_equal(again.mesh_colliders[0].vertices, scene.mesh_colliders[0].vertices)
    assert len(recwarn) == 0


def test_scene_without_new_keys_writes_none_of_them():
    out = parse_scene(scene_with(sphere={"origin": [0, 0, 0], "radius": 0.1, "friction": 0.2})).to_dict()
    assert not {"box", "mesh", "wind"} & set(out) and "handles" not in out["cloth"]
    assert "animation" not in out["sphere"][0]


def test_mesh_cloth_handles_round_trip(write_scene):
    scene, path = load(write_scene, mesh_cloth(handles=[{"vertices": [1], "animation": ANIM}]),
                       {"quad.obj": QUAD_OBJ})
    assert scene.to_dict()["cloth"]["handles"][0]["vertices"] == [1]
    assert parse_scene(json.loads(json.dumps(scene.to_dict())), str(path)) == scene


def test_set_reaches_a_lone_box_mesh_and_the_wind(write_scene):
    scene, path = load(write_scene, scene_with(box=BOX, mesh={"path": "cube.obj", "friction": 0.2}, wind=WIND),
                       {"cube.obj": CUBE_OBJ})
    changed = load_scene(path, ["box[0].friction=0.5", "wind.velocity=[1,0,0]", "mesh[0].margin=0.02",
                                "box.size=[2,2,2]"])
    assert changed.boxes[0].friction == 0.5 and changed.boxes[0].size == (2, 2, 2)
    assert changed.wind.velocity == (1, 0, 0) and changed.mesh_colliders[0].margin == 0.02
    err, _ = error_of(write_scene, scene_with(wind=WIND), overrides=["wind.velocity=fast"])
    assert err.key == "wind.velocity" and "expected a list of 3 numbers" in str(err)
    with pytest.raises(SceneError, match=r"box\[1\]"):
        load_scene(path, ["box[1].friction=0.5"])


# --------------------------------------------------------------------------
# the command line: exit 2 at load, one line


@pytest.mark.parametrize("section, key", [
    ({"box": dict(BOX, animation={"keys": [{"t": 0}, {"t": 2}, {"t": 1}]})}, "box.animation.keys[2].t"),
    ({"sphere": {"origin": [0, 0, 0], "radius": 0.1, "friction": 0.1, "animation": {"keys": [{"t": -1}]}}},
     "sphere.animation.keys[0].t"),
    ({"mesh": {"path": "missing.obj", "friction": 0.2}}, "mesh.path"),
    ({"box": dict(BOX, size=[1, 0, 1])}, "box.size[1]"),
    ({"wind": {"velocity": [1, 2]}}, "wind.velocity"),
])
def test_command_line_refuses_at_load(write_scene, tmp_path, section, key):
    scene = write_scene(scene_with(**section))
    out = tmp_path / "out.obj"
    r = clothsim_process("simulate", scene, "--seconds", "0.01", "--no-progress", "--export", out)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    assert lines[0].startswith("clothsim: error:") and f"{scene}: {key}: " in lines[0]
    assert ("no such file" if key == "mesh.path" else "expected") in lines[0]
    assert "Traceback" not in r.stderr and not out.exists()
