"""Scene files: CS184 files load unchanged; every bad input names file, key and expectation."""

from __future__ import annotations

import json

import pytest

from clothsim import SceneError, SceneWarning, load_scene, parse_scene
from clothsim.scene import apply_overrides

from .conftest import SCENES, small_scene


@pytest.mark.parametrize("name", ["pinned2", "pinned4", "sphere", "plane", "selfCollision"])
def test_standard_scenes_load(name):
    """each standard scene loads with the values the project promises"""
    scene = load_scene(SCENES / f"{name}.json")
    c = scene.cloth
    assert (c.width, c.height, c.num_width_points, c.num_height_points) == (1.0, 1.0, 50, 50)
    assert (c.damping, c.density, c.ks, c.thickness) == (0.2, 150.0, 5000.0, 0.0095)


def test_standard_scene_contents():
    """the collider and pin values in the standard scenes are the documented ones"""
    assert load_scene(SCENES / "pinned2.json").cloth.pinned == [(0, 0), (49, 0)]
    assert len(load_scene(SCENES / "pinned4.json").cloth.pinned) == 4
    s = load_scene(SCENES / "sphere.json").spheres[0]
    assert (s.origin, s.radius, s.friction) == ((0.5, 0.2, 0.5), 0.2, 0.3)
    p = load_scene(SCENES / "plane.json").planes[0]
    assert (p.point, p.normal, p.friction) == ((0, 0, 0), (0, 1, 0), 0.5)
    sc = load_scene(SCENES / "selfCollision.json")
    assert sc.cloth.orientation == 1 and sc.planes[0].normal == (0, 1, 0)


def test_cs184_defaults_fill_in():
    """a CS184 file without damping, density, ks, enable_* or pinned gets the CS184 defaults"""
    data = small_scene()
    for key in ("damping", "density", "ks", "pinned"):
        del data["cloth"][key]
    scene = parse_scene(data)
    c = scene.cloth
    assert (c.damping, c.density, c.ks, c.pinned) == (0.2, 150.0, 5000.0, [])
    assert c.enable_structural and c.enable_shearing and c.enable_bending
    assert scene.simulation.frames_per_sec == 90 and scene.simulation.simulation_steps == 30


def test_plane_normal_is_normalised_and_lists_allowed():
    """plane normals are normalised; sphere and plane accept lists (extension)"""
    scene = parse_scene(small_scene(
        plane={"point": [0, 0, 0], "normal": [0, 2, 0], "friction": 0.1},
        sphere=[{"origin": [0, 0, 0], "radius": 1, "friction": 0},
                {"origin": [1, 0, 0], "radius": 2, "friction": 1}]))
    assert scene.planes[0].normal == (0.0, 1.0, 0.0)
    assert [s.radius for s in scene.spheres] == [1.0, 2.0]


BAD = [
    ({"cloth": small_scene()["cloth"], "spheres": {}}, "spheres", "unknown top-level key"),
    ({"plane": {}}, "cloth", "missing required key"),
    (small_scene(cloth={"width": "wide"}), "cloth.width", "expected a number"),
    (small_scene(cloth={"width": -1}), "cloth.width", "expected a number >= 1e-06 and <= 1e+06"),
    (small_scene(cloth={"num_width_points": 1}), "cloth.num_width_points", "expected an integer >= 2"),
    (small_scene(cloth={"num_height_points": 2.5}), "cloth.num_height_points", "expected an integer"),
    (small_scene(cloth={"orientation": 2}), "cloth.orientation", "expected 0 (horizontal) or 1"),
    (small_scene(cloth={"damping": 101}), "cloth.damping", "<= 100"),
    (small_scene(cloth={"ks": -5}), "cloth.ks", ">= 0"),
    (small_scene(cloth={"enable_bending": "yes"}), "cloth.enable_bending", "expected true or false"),
    (small_scene(cloth={"pinned": [[0]]}), "cloth.pinned[0]", "expected a pair"),
    (small_scene(simulation={"frames": 90}), "simulation.frames", "unknown key"),
    (small_scene(sphere={"origin": [0, 0], "radius": 1, "friction": 0}), "sphere.origin",
     "expected a list of 3 numbers"),
    (small_scene(sphere={"origin": [0, 0, 0], "radius": 1}), "sphere.friction", "missing required key"),
    (small_scene(sphere={"origin": [0, 0, 0], "radius": 1, "friction": 2}), "sphere.friction", "<= 1"),
    (small_scene(plane={"point": [0, 0, 0], "normal": [0, 0, 0], "friction": 0}), "plane.normal",
     "non-zero"),
    (small_scene(simulation={"simulation_steps": 0}), "simulation.simulation_steps", ">= 1"),
    (small_scene(simulation={"gravity": [0, "down", 0]}), "simulation.gravity[1]", "expected a number"),
]
for key in ("width", "height", "num_width_points", "num_height_points", "thickness", "orientation"):
    missing = small_scene()
    del missing["cloth"][key]
    BAD.append((missing, f"cloth.{key}", "missing required key"))


@pytest.mark.parametrize("data,key,expected", BAD, ids=[b[1] + ":" + b[2][:20] for b in BAD])
def test_bad_scene_names_key(write_scene, data, key, expected):
    """every invalid scene raises SceneError naming the file, the key path and what was expected"""
    path = write_scene(data)
    with pytest.raises(SceneError) as info:
        load_scene(path)
    err = info.value
    assert err.key == key
    assert err.source == str(path)
    assert expected in str(err)
    assert str(path) in str(err) and "\n" not in str(err)


IGNORED = [  # what the CS184 loader ignores: (scene, key, words of the warning)
    (small_scene(cloth={"colour": [1, 0, 0]}), "cloth.colour", "known keys: damping, density"),  # none near
    (small_scene(cloth={"kss": 500}), "cloth.kss", "nearest known key: 'ks'"),
    (small_scene(cloth={"pinned": [[0, 0], [3, 3], [16, 0]]}), "cloth.pinned[2]", "inside the 16x16 grid"),
    (small_scene(sphere={"origin": [0, 0, 0], "radius": 1, "friction": 0, "radiuss": 2}), "sphere.radiuss",
     "nearest known key: 'radius'"),
    (small_scene(plane=[{"point": [0, 0, 0], "normal": [0, 1, 0], "friction": 0, "normals": [0, 1, 0]}]),
     "plane[0].normals", "nearest known key: 'normal'"),
]


@pytest.mark.parametrize("data,key,expected", IGNORED, ids=[i[1] for i in IGNORED])
def test_what_cs184_ignores_loads_with_one_warning(write_scene, data, key, expected):
    """an unknown key inside cloth, sphere or plane and a pinned point outside the grid
    are ignored with one SceneWarning naming file, key (and the nearest known key);
    under strict each is a SceneError"""
    path = write_scene(data)
    with pytest.warns(SceneWarning) as caught:
        scene = load_scene(path)
    assert len(caught) == 1
    warning = caught[0].message
    assert warning.key == key and warning.source == str(path)
    assert str(warning).startswith(f"{path}: {key}: ") and expected in str(warning) and "ignored" in str(warning)
    if key == "cloth.kss":
        assert scene.cloth.ks == 5000  # the misspelt key sets nothing
    if key.startswith("cloth.pinned"):
        assert scene.cloth.pinned == [(0, 0), (3, 3)]  # the point outside pins nothing
    with pytest.raises(SceneError) as info:
        load_scene(path, strict=True)
    assert info.value.key == key and "ignored" not in str(info.value)


def test_unknown_mesh_cloth_key_is_a_warning(write_scene):
    path = write_scene({"cloth": {"mesh": "quad.obj", "thickness": 0.01, "colour": 1}})
    (path.parent / "quad.obj").write_text(QUAD_OBJ)
    with pytest.warns(SceneWarning, match=r"cloth.colour: unknown key; known keys: damping, .*mesh, .*; ignored"):
        load_scene(path)
    with pytest.raises(SceneError, match="cloth.colour: unknown key"):
        load_scene(path, strict=True)


def test_a_clean_scene_warns_nothing(write_scene, recwarn):
    load_scene(write_scene(small_scene(sphere={"origin": [0, 0, 0], "radius": 1, "friction": 0})))
    assert not [w for w in recwarn if issubclass(w.category, SceneWarning)]


def test_invalid_json_gives_line_and_column(write_scene):
    """a JSON syntax error reports its line and column"""
    path = write_scene('{\n  "cloth": {\n    "width": 1,,\n  }\n}')
    with pytest.raises(SceneError, match=r"invalid JSON at line 3, column 16"):
        load_scene(path)


def test_missing_file(tmp_path):
    """a missing file is a SceneError, not an OSError traceback"""
    with pytest.raises(SceneError, match="no such file"):
        load_scene(tmp_path / "nope.json")


def test_overrides_set_dotted_keys():
    """--set style overrides reach nested keys and list elements, values parsed as JSON"""
    data = small_scene(sphere=[{"origin": [0, 0, 0], "radius": 1, "friction": 0}])
    out = apply_overrides(data, ["cloth.ks=500", "sphere[0].radius=0.25", "simulation.gravity=[0,-1,0]",
                                 "cloth.enable_bending=false"])
    scene = parse_scene(out)
    assert scene.cloth.ks == 500 and scene.spheres[0].radius == 0.25
    assert scene.simulation.gravity == (0, -1, 0) and not scene.cloth.enable_bending
    assert data["cloth"]["ks"] == 5000  # the input is not modified


def test_override_of_wrong_type_is_named(write_scene):
    """an override with a bad value fails validation under its key"""
    path = write_scene(small_scene())
    with pytest.raises(SceneError) as info:
        load_scene(path, ["cloth.ks=soft"])
    assert info.value.key == "cloth.ks"


def test_scene_round_trips_through_dict():
    """to_dict gives JSON that parses back to the same scene"""
    scene = load_scene(SCENES / "sphere.json")
    again = parse_scene(json.loads(json.dumps(scene.to_dict())))
    assert again.cloth == scene.cloth and again.spheres == scene.spheres


# --------------------------------------------------------------------------
# mesh cloths (extension): the keys; the meshes themselves in test_mesh_cloth.py

QUAD_OBJ = "v 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1\nf 1 2 3 4\n"


def test_grid_and_mesh_cloths_in_one_list(write_scene):
    """a list of a grid and a mesh cloth: each its own kind and material, the mesh
    with the CS184 material defaults; to_dict reloads to the same scene; --set reaches each"""
    from clothsim.scene import ClothSpec, MeshClothSpec
    path = write_scene({"cloth": [small_scene()["cloth"], {"mesh": "quad.obj", "thickness": 0.02}]})
    (path.parent / "quad.obj").write_text(QUAD_OBJ)
    scene = load_scene(path)
    grid, mesh = scene.cloths
    assert isinstance(grid, ClothSpec) and isinstance(mesh, MeshClothSpec)
    assert (mesh.mesh, mesh.path, mesh.thickness) == ("quad.obj", str(path.parent / "quad.obj"), 0.02)
    assert (mesh.damping, mesh.density, mesh.ks, mesh.pinned_vertices, mesh.pinned_region) == (0.2, 150, 5000, [], None)
    assert mesh.enable_structural and mesh.enable_shearing and mesh.enable_bending
    assert mesh.data.vertices.tolist() == [[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1]]
    assert parse_scene(scene.to_dict(), str(path)) == scene
    assert parse_scene(json.loads(json.dumps(scene.to_dict())), str(path)).cloths[1].data.faces.tolist() == [[0, 1, 2, 3]]
    changed = load_scene(path, ["cloth[1].ks=42", "cloth[1].transform.scale=2"])
    assert changed.cloths[1].ks == 42 and changed.cloths[0].ks == 5000
    assert changed.cloths[1].data.vertices.max() == 2.0


def test_mesh_path_without_a_scene_file_is_the_working_folders(tmp_path, monkeypatch):
    (tmp_path / "quad.obj").write_text(QUAD_OBJ)
    monkeypatch.chdir(tmp_path)
    scene = parse_scene({"cloth": {"mesh": "quad.obj", "thickness": 0.01}})
    assert scene.cloth.path == str(tmp_path / "quad.obj")
    with pytest.raises(SceneError, match=r"^cloth.mesh: elsewhere.obj: no such file$"):
        parse_scene({"cloth": {"mesh": "elsewhere.obj", "thickness": 0.01}})


@pytest.mark.parametrize("cloth, key, expected", [
    ({"mesh": "quad.obj"}, "cloth.thickness", "missing required key"),
    ({"mesh": 3, "thickness": 0.01}, "cloth.mesh", "expected the name of a mesh file, got 3"),
    ({"mesh": "quad.obj", "thickness": 0.01, "orientation": 0}, "cloth.orientation", "has no grid keys"),
    ({"mesh": "quad.obj", "thickness": 0.01, "pinned": [[0, 0]]}, "cloth.pinned", "drop 'pinned' or 'mesh'"),
    ({"mesh": "quad.obj", "thickness": 0.01, "transform": {"spin": 1}}, "cloth.transform.spin", "unknown key"),
    ({"mesh": "quad.obj", "thickness": 0.01, "ks": -1}, "cloth.ks", ">= 0"),
    ({"mesh": "quad.obj", "thickness": 0.01, "pinned_vertices": 3}, "cloth.pinned_vertices", "expected a list"),
    ({"mesh": "quad.obj", "thickness": 0.01, "pinned_vertices": [1.5]}, "cloth.pinned_vertices[0]",
     "expected an integer"),
    ({"mesh": "quad.obj", "thickness": 0.01, "pinned_region": {"min": [0, 0, 0]}}, "cloth.pinned_region.max",
     "missing required key"),
    ({"mesh": "quad.obj", "thickness": 0.01, "transform": {"rotate": [0, 90]}}, "cloth.transform.rotate",
     "expected a list of 3 numbers"),
    ({"mesh": "quad.obj", "thickness": 0.01, "transform": {"scale": [1, -1, 1]}}, "cloth.transform.scale[1]",
     "expected a number > 0"),
])
def test_bad_mesh_cloth_keys(write_scene, cloth, key, expected):
    path = write_scene({"cloth": cloth})
    (path.parent / "quad.obj").write_text(QUAD_OBJ)
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert info.value.key == key and expected in str(info.value) and str(path) in str(info.value)
