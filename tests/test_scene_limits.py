"""Scene numbers and documents at their edges: each ends in a scene or a
SceneError naming the key and the bound, never a traceback or an inf."""

from __future__ import annotations

import json
import math

import pytest

from clothsim import SceneError, load_scene, parse_scene
from clothsim.scene import apply_overrides
from clothsim.scene_limits import DEPTH_MAX, POINTS_MAX

from .conftest import small_scene

SPHERE = {"origin": [0.5, 0.2, 0.5], "radius": 0.2, "friction": 0.3}
PLANE = {"point": [0, 0, 0], "normal": [0, 1, 0], "friction": 0.5}


@pytest.mark.parametrize("key", ["sphere", "plane", "cloth"])
def test_index_0_of_a_lone_collider_object_is_that_object(key):
    """--set sphere[0].friction=... works where sphere holds one object, as the README shows"""
    data = small_scene(sphere=dict(SPHERE), plane=dict(PLANE))
    out = apply_overrides(data, [f"{key}[0].friction=0.25" if key != "cloth" else "cloth[0].ks=700"])
    scene = parse_scene(out)
    if key == "cloth":
        assert scene.cloth.ks == 700
    else:
        assert getattr(scene, key + "s")[0].friction == 0.25
    assert isinstance(out[key], dict)  # still one object, not turned into a list


def test_index_0_of_a_lone_object_replaces_it_whole():
    out = apply_overrides(small_scene(sphere=dict(SPHERE)), [('sphere[0]={"origin": [0, 0, 0], "radius": 0.3, '
                                                             '"friction": 0}')])
    assert parse_scene(out).spheres[0].radius == 0.3


@pytest.mark.parametrize("override", ["sphere[1].radius=0.3", "sphere[1]={}"])
def test_index_1_of_a_lone_collider_object_is_an_error_naming_the_key(override):
    with pytest.raises(SceneError) as info:
        apply_overrides(small_scene(sphere=dict(SPHERE)), [override], "s.json")
    assert info.value.key == override.split("=")[0]
    assert "sphere holds one object" in str(info.value)


def test_readme_override_on_the_packaged_sphere_scene():
    from clothsim.standard_scenes import find_scene

    assert load_scene(find_scene("sphere"), ["sphere[0].radius=0.3"]).spheres[0].radius == 0.3


@pytest.mark.parametrize("normal,unit", [
    ([0, 1e200, 0], (0.0, 1.0, 0.0)),
    ([1e-200, 0, 0], (1.0, 0.0, 0.0)),
    ([5e-324, 5e-324, 0], (math.sqrt(0.5), math.sqrt(0.5), 0.0)),
    ([-1e308, 1e308, 0], (-math.sqrt(0.5), math.sqrt(0.5), 0.0)),
])
def test_plane_normals_of_extreme_size_normalise_to_their_direction(normal, unit):
    plane = parse_scene(small_scene(plane={**PLANE, "normal": normal})).planes[0]
    assert plane.normal == pytest.approx(unit)


WRONG_TYPES = [
    ("simulation.gravity", 9.8), ("simulation.gravity", "down"), ("simulation.gravity", {"y": -9.8}),
    ("simulation.gravity", None), ("simulation.frames_per_sec", [90]), ("simulation.simulation_steps", "30"),
    ("simulation.self_collision", 1), ("simulation.seed", 0.5), ("sphere.origin", 0.5), ("sphere.radius", [1]),
    ("sphere.friction", "x"), ("plane.point", {"x": 0}), ("plane.normal", "up"), ("plane.friction", True),
]


@pytest.mark.parametrize("key,value", WRONG_TYPES, ids=[f"{k}={v!r}" for k, v in WRONG_TYPES])
def test_a_value_of_the_wrong_type_is_an_error_naming_its_key(key, value):
    data = small_scene(sphere=dict(SPHERE), plane=dict(PLANE), simulation={})
    section, name = key.split(".")
    data[section][name] = value
    with pytest.raises(SceneError) as info:
        parse_scene(data, "s.json")
    assert info.value.key == key and "expected" in info.value.message


EXTREMES = [
    ("cloth.width", 1e308, "<= 1e+06"), ("cloth.height", 5e-324, ">= 1e-06"),
    ("cloth.thickness", 5e-324, ">= 1e-06"), ("cloth.thickness", 1e-8, ">= 1e-06"),
    ("cloth.ks", 1e300, "<= 1e+12"), ("cloth.density", 5e-324, ">= 1e-06"), ("cloth.density", 1e308, "<= 1e+06"),
    ("cloth.num_width_points", 10**4000, "<= 2,000,000"), ("sphere.radius", 1e308, "<= 1e+06"),
    ("sphere.radius", 5e-324, ">= 1e-06"), ("sphere.origin[0]", 1e308, "<= 1e+06"),
    ("plane.point[1]", -1e308, ">= -1e+06"), ("simulation.gravity[1]", -1e308, ">= -1e+06"),
    ("simulation.frames_per_sec", 1e300, "<= 10000"), ("simulation.frames_per_sec", 5e-324, ">= 0.001"),
    ("simulation.simulation_steps", 10**18, "<= 100,000"), ("simulation.seed", 10**30, "<= "),
    ("cloth.ks", 10**400, "<= 1e+12"),
]


def _short(v) -> str:
    return f"{len(str(v))}-digit int" if isinstance(v, int) else f"{v:.3g}"


@pytest.mark.parametrize("key,value,bound", EXTREMES, ids=[f"{k}={_short(v)}" for k, v, _ in EXTREMES])
def test_extreme_numbers_are_refused_naming_the_bound(key, value, bound):
    data = small_scene(sphere=dict(SPHERE), plane=dict(PLANE), simulation={"gravity": [0, -9.8, 0]})
    section, rest = key.split(".")
    name, _, index = rest.partition("[")
    if index:
        data[section][name] = list(data[section][name])
        data[section][name][int(index[:-1])] = value
    else:
        data[section][name] = value
    with pytest.raises(SceneError) as info:
        parse_scene(json.loads(json.dumps(data)), "s.json")
    assert info.value.key == key
    assert bound in info.value.message


def test_a_grid_of_more_points_than_the_bound_is_refused_before_any_allocation():
    data = small_scene(cloth={"num_width_points": 3000, "num_height_points": 3000, "pinned": []})
    with pytest.raises(SceneError) as info:
        parse_scene(data, "s.json")
    assert info.value.key == "cloth" and f"{POINTS_MAX:,} points" in info.value.message


def test_bounds_themselves_are_accepted():
    data = small_scene(cloth={"width": 1e6, "height": 1e-6, "thickness": 1e-6, "ks": 1e12, "density": 1e6},
                       sphere={"origin": [1e6, -1e6, 0], "radius": 1e6, "friction": 1},
                       simulation={"frames_per_sec": 1e4, "simulation_steps": 100_000, "gravity": [0, -1e6, 0]})
    assert parse_scene(data).simulation.simulation_steps == 100_000


def test_an_integer_of_thousands_of_digits_in_the_file_is_one_error(write_scene):
    path = write_scene('{"cloth": {"num_width_points": ' + "9" * 5000 + "}}")
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert "digits" in str(info.value) and "\n" not in str(info.value)


def test_an_integer_of_thousands_of_digits_in_an_override_is_one_error_naming_the_key(write_scene):
    with pytest.raises(SceneError) as info:
        load_scene(write_scene(small_scene()), ["cloth.ks=" + "9" * 5000])
    assert info.value.key == "cloth.ks" and "digits" in info.value.message


@pytest.mark.parametrize("depth", [DEPTH_MAX + 1, 100_000])
def test_very_deep_json_in_the_file_is_one_error(write_scene, depth):
    path = write_scene('{"cloth": ' + "[" * depth + "]" * depth + "}")
    with pytest.raises(SceneError) as info:
        load_scene(path, ["cloth.ks=1"])
    assert f"at most {DEPTH_MAX} levels" in str(info.value)


def test_very_deep_json_in_an_override_is_one_error_naming_the_key(write_scene):
    with pytest.raises(SceneError) as info:
        load_scene(write_scene(small_scene()), ["cloth.ks=" + "[" * 100_000 + "]" * 100_000])
    assert info.value.key == "cloth.ks" and f"at most {DEPTH_MAX} levels" in info.value.message


def test_deep_data_given_to_apply_overrides_is_one_error():
    deep: list = []
    for _ in range(5000):
        deep = [deep]
    with pytest.raises(SceneError):
        apply_overrides({"cloth": deep}, ["cloth.ks=1"])


def test_a_run_that_is_no_longer_finite_says_so_even_where_the_blow_up_limit_is_inf():
    import numpy as np

    from clothsim import Simulation, SimulationError

    sim = Simulation(parse_scene(small_scene(simulation={"self_collision": False})))
    sim.solver.runaway2 = math.inf  # what a size near 1e308 made of it
    sim.state.positions[3] = np.inf
    with pytest.raises(SimulationError, match="no longer finite"):
        sim.step()
