"""The standard scenes of the moving world (a table, a spinning sphere, a torus,
a flag in the wind, a curtain): each runs, and each does what it is for."""

from __future__ import annotations

import json

import numpy as np
import pytest

from clothsim import Simulation, load_scene
from clothsim.procedural import face_normals, torus
from clothsim.scene import parse_scene

from .conftest import SCENES
from .handmade import turn_about_y

WORLD_SCENES = {"table_pull": 1600, "spinning_sphere": 2500, "torus_drape": 1600, "windy_flag": 960,
                "curtain": 1728}
"""the scenes and their points"""


def read(name: str) -> dict:
    return json.loads((SCENES / f"{name}.json").read_text())


@pytest.mark.parametrize("name", sorted(WORLD_SCENES))
def test_world_scene_loads_and_runs(name):
    """0.3 s of each: every point present and finite, none flung far, no point
    moving faster than a fall from a few metres (no blow-up)"""
    sim = Simulation.from_file(SCENES / f"{name}.json")
    assert sim.positions.shape == (WORLD_SCENES[name], 3)
    start = sim.positions.copy()
    for _ in range(27):
        before = sim.positions.copy()
        sim.step()
        assert np.isfinite(sim.positions).all()
        assert np.linalg.norm(sim.positions - before, axis=1).max() * 90 < 8.0  # m/s
    assert np.linalg.norm(sim.positions - start, axis=1).max() < 1.0


# ------------------------------------------------------------------ the table


TABLE_TOP = 0.75


def inside_table(p: np.ndarray, box: dict) -> np.ndarray:
    return np.all(np.abs(p - box["center"]) < np.asarray(box["size"]) / 2, axis=1)


def test_table_pull_lies_on_the_table_then_is_pulled_off_onto_the_floor():
    """before the pull (1.5 s) the cloth lies on the table top, every frame with no
    point inside the box; after it (5 s) no point is above the table top and most of
    the cloth lies on the floor, beyond the table's edge, not torn out of shape"""
    scene = read("table_pull")
    box = scene["box"]
    assert box["center"][1] + box["size"][1] / 2 == pytest.approx(TABLE_TOP)
    sim = Simulation.from_file(SCENES / "table_pull.json")
    handle = sim.model.pinned
    assert handle.sum() == 40
    for _ in range(135):
        sim.step()
        assert not inside_table(sim.positions, box).any()
    p = sim.positions
    assert p[:, 1].min() >= TABLE_TOP - 1e-9
    assert p[:, 1].max() < TABLE_TOP + 0.03
    assert np.all(p[~handle, 1] < TABLE_TOP + 0.01)  # flat on it, the held edge 1.5 cm up
    longest = 0.0
    for _ in range(315):
        sim.step()
        assert not inside_table(sim.positions, box).any()
        grid = sim.positions.reshape(40, 40, 3)
        longest = max(longest, np.linalg.norm(grid[:, 1:] - grid[:, :-1], axis=2).max() * 39)
    # dragged whole: the table's low friction (CS184's, a fraction of the tangential
    # motion taken each substep) lets the cloth follow with no spring past 120%
    assert longest < 1.2
    p = sim.positions
    assert p[:, 1].max() < TABLE_TOP
    on_floor = p[:, 1] < 0.02
    assert on_floor.mean() > 0.8
    assert p[on_floor, 0].min() > box["center"][0] + box["size"][0] / 2  # beyond the table


# --------------------------------------------------------- the spinning sphere


def test_spinning_sphere_twists_the_cloth_with_it():
    """the sphere turns once in 4 s about y (friction 1); over 4 s the cloth's mean
    angle about the sphere's axis, unwrapped frame by frame, turns by at least half
    of that, the same way (a positive turn about y takes +x toward -z)"""
    scene = read("spinning_sphere")
    sphere = scene["sphere"]
    assert sphere["friction"] == 1.0 and sphere["animation"]["loop"] is True
    assert sphere["animation"]["keys"][-1] == {"t": 4, "rotate": [0, 360, 0]}
    cx, cz = sphere["origin"][0], sphere["origin"][2]
    sim = Simulation.from_file(SCENES / "spinning_sphere.json")

    off_axis = np.hypot(sim.positions[:, 0] - cx, sim.positions[:, 2] - cz) > 0.1
    turned = turn_about_y(sim, (cx, cz), 360)
    assert np.isfinite(sim.positions).all()
    assert turned[off_axis].mean() / (-2 * np.pi) >= 0.5, np.degrees(turned[off_axis].mean())


# -------------------------------------------------------------------- the torus


MAJOR, MINOR = 0.25, 0.08


def torus_depth(points: np.ndarray, centre) -> np.ndarray:
    """distance of each point to the torus's circle centre-line, minus the minor
    radius: negative inside the exact torus"""
    q = points - np.asarray(centre)
    return np.hypot(np.hypot(q[:, 0], q[:, 2]) - MAJOR, q[:, 1]) - MINOR


def facet_depth(mesh, samples: int = 12) -> float:
    """how far inside the exact torus the shipped mesh's flat triangles reach
    (their sagitta), by sampling each triangle on a barycentric grid"""
    k = np.arange(samples + 1)
    a, b = np.meshgrid(k, k, indexing="ij")
    keep = a + b <= samples
    w = np.stack([a[keep], b[keep], samples - a[keep] - b[keep]], axis=1) / samples
    corners = mesh.vertices[mesh.faces]  # (F, 3, 3)
    pts = np.einsum("sk,fkd->fsd", w, corners).reshape(-1, 3)
    return float(-torus_depth(pts, (0, 0, 0)).min())


def test_torus_mesh_is_a_closed_outward_solid():
    """64x24 vertices on the exact surface, 3,072 triangles; every edge in two of
    them in opposite directions (closed, consistently wound), Euler characteristic 0,
    every normal pointing away from the centre-line; the facets reach about 1 mm in"""
    m = torus(major=MAJOR, minor=MINOR, segments=64, sides=24)
    assert m.vertices.shape == (1536, 3) and m.faces.shape == (3072, 3)
    np.testing.assert_allclose(torus_depth(m.vertices, (0, 0, 0)), 0, atol=1e-12)
    directed = np.concatenate([m.faces[:, [i, (i + 1) % 3]] for i in range(3)])
    assert len(np.unique(directed, axis=0)) == len(directed)
    undirected, count = np.unique(np.sort(directed, axis=1), axis=0, return_counts=True)
    assert np.all(count == 2)
    assert len(m.vertices) - len(undirected) + len(m.faces) == 0
    n = face_normals(m.vertices, m.faces)
    c = m.vertices[m.faces].mean(axis=1)
    foot = c * [1, 0, 1]
    foot *= MAJOR / np.linalg.norm(foot, axis=1)[:, None]
    assert np.all(np.einsum("ij,ij->i", n, c - foot) > 0)
    assert 0.0008 < facet_depth(m) < 0.0012
    assert np.all((m.uvs >= 0) & (m.uvs < 1))


def test_torus_drape_hangs_over_the_ring_and_never_enters_it():
    """the torus is a closed mesh collider; over 3 s no cloth point is inside the
    exact torus by more than its facets' sagitta, the cloth drapes (its middle sinks
    into the hole, its edges hang below the ring) and stays above the floor"""
    scene = load_scene(SCENES / "torus_drape.json")
    [collider] = scene.mesh_colliders
    assert collider.closed and collider.path == "meshes/torus.obj"
    centre = np.array(collider.transform.translate)
    allowed = facet_depth(torus(major=MAJOR, minor=MINOR, segments=64, sides=24)) + 1e-4
    sim = Simulation(scene)
    deepest = np.inf
    for _ in range(270):
        sim.step()
        deepest = min(deepest, torus_depth(sim.positions, centre).min())
    assert deepest >= -allowed, (deepest, allowed)
    p = sim.positions
    top = centre[1] + MINOR
    assert p[:, 1].max() < top + 0.02
    middle = np.hypot(p[:, 0] - centre[0], p[:, 2] - centre[2]) < 0.05
    assert middle.sum() >= 4 and np.all(p[middle, 1] < top - 0.02)  # sagged into the hole
    assert (p[:, 1] < centre[1] - MINOR).sum() > 300  # the hem below the ring
    assert p[:, 1].min() >= 0.0


# --------------------------------------------------------------------- the flag


def test_windy_flag_streams_out_along_the_wind():
    """pinned along its edge at the pole in a 5 m/s gusty wind: from 2 s to 4 s
    the mean offset of its points along the wind stays near the flag's flat
    0.5 m (a flat flag's mean is half its width; it ripples, so 90% of that),
    while the same flag without wind hangs by the pole"""
    scene = read("windy_flag")
    assert scene["wind"]["velocity"] == [5, 0, 0] and scene["cloth"]["orientation"] == 1
    pole = scene["box"]
    assert pole["center"][0] + pole["size"][0] / 2 < 0  # the pole is beside the pinned edge
    width = scene["cloth"]["width"]

    def offsets(spec: dict) -> list[float]:
        sim = Simulation(parse_scene(spec, "flag"))
        sim.run(2.0)
        out = []
        for _ in range(180):
            sim.step()
            out.append(sim.positions[:, 0].mean())
        assert np.isfinite(sim.positions).all()
        return out

    windy = offsets(scene)
    assert min(windy) >= 0.45 * width and np.mean(windy) >= 0.48 * width
    calm = dict(scene)
    del calm["wind"]
    assert max(offsets(calm)) < 0.25 * width


# ------------------------------------------------------------------ the curtain


def test_curtain_top_spreads_by_the_handles_travel():
    """the two handles (three top-row points each) slide together, hold, then apart:
    from the bunched pose (2 s) to the open one (3.5 s) the top row's spread grows by
    exactly their travel, back to the cloth's width; the curtain hangs below its top"""
    scene = read("curtain")
    cloth = scene["cloth"]
    nw, nh = cloth["num_width_points"], cloth["num_height_points"]
    left, right = cloth["handles"]
    travel = (left["animation"]["keys"][2]["translate"][0] - left["animation"]["keys"][3]["translate"][0]
              + right["animation"]["keys"][3]["translate"][0] - right["animation"]["keys"][2]["translate"][0])
    assert travel == pytest.approx(1.1)
    assert all(j == nh - 1 for h in (left, right) for _, j in h["points"])
    sim = Simulation.from_file(SCENES / "curtain.json")
    top = slice((nh - 1) * nw, nh * nw)

    def spread():
        x = sim.positions[top, 0]
        return x.max() - x.min()

    assert spread() == pytest.approx(cloth["width"])
    sim.run(2.0)
    bunched = spread()
    assert bunched == pytest.approx(cloth["width"] - travel, abs=1e-9)
    sim.run(1.5)
    assert spread() - bunched == pytest.approx(travel, abs=1e-9)
    p = sim.positions
    assert np.isfinite(p).all() and p[:, 1].max() <= cloth["height"] + 1e-9
    assert p[:nw, 1].mean() < 0.1  # the hem hangs at the bottom
