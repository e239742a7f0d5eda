"""The moving world drawn: boxes, mesh colliders and animated colliders, checked in real images."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from clothsim import Simulation
from clothsim.cli import main
from clothsim.render.camera import OrbitCamera
from clothsim.render.geometry import box_mesh, triangle_mesh
from clothsim.render.renderer import DrawSettings, Renderer
from clothsim.render.scene_view import SimulationView, collider_poses, default_camera
from clothsim.scene import load_scene, parse_scene
from clothsim.viewer.picking import project

from .conftest import small_scene
from .test_render import foreground

SIZE = (160, 160)
SLIDE = {"keys": [{"t": 0}, {"t": 1, "translate": [0.3, 0, 0]}]}
BOX = {"center": [0.5, 0.2, 0.5], "size": [0.3, 0.1, 0.3], "friction": 0.5}


@pytest.fixture(scope="module")
def renderer():
    r = Renderer(size=SIZE)
    yield r
    r.release()


def top_camera(target=(0.5, 0.2, 0.5)) -> OrbitCamera:
    """looking straight down: image x is world x, image y world z"""
    return OrbitCamera(target=np.array(target, float), azimuth=0.0, elevation=89.0, distance=2.0)


def world_sim(scene: dict, tmp_path=None) -> Simulation:
    """the simulation of ``scene`` with its cloth moved far out of view, so that
    every drawn pixel is a collider's; mesh colliders are attached after the
    simulation is made (drawing needs only ``sim.mesh_colliders``)"""
    if tmp_path is None:
        spec = parse_scene(scene, "world")
    else:
        path = tmp_path / "world.json"
        path.write_text(json.dumps(scene))
        spec = load_scene(path)
    sim = Simulation(dataclasses.replace(spec, mesh_colliders=[]))
    sim.mesh_colliders = list(spec.mesh_colliders)
    sim.state.positions[:] += [100.0, 0.0, 0.0]
    return sim


def draw(renderer, sim, camera, t=None, **settings) -> np.ndarray:
    if t is not None:
        sim.state.time = t
    view = SimulationView(renderer, sim, (24, 24))
    view.sync()
    return renderer.render(camera, DrawSettings(**settings))


def grey(img: np.ndarray) -> np.ndarray:
    """collider pixels: unlike the background, and grey (the cloth is red)"""
    rgb = img.astype(int)
    return foreground(img) & (rgb.max(axis=2) - rgb.min(axis=2) < 25)


def corners(center, size, R=None) -> np.ndarray:
    """the 8 corners of a box [m] turned by ``R`` (3, 3), (8, 3)"""
    R = np.eye(3) if R is None else R
    s = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
    return (s * size) @ R.T + center


def test_box_mesh_has_flat_outward_faces():
    """24 vertices, 12 triangles wound counter-clockwise seen from outside, each
    vertex's normal its face's, 12 edges as lines"""
    m = box_mesh((1.0, 2.0, 3.0), (0.2, 0.4, 0.6))
    assert m.vertices.shape == (24, 14) and m.triangles.shape == (12, 3) and m.lines.shape == (24, 2)
    pos, normal = m.vertices[:, :3].astype(float), m.vertices[:, 4:7]
    a, b, c = (pos[m.triangles[:, k]] for k in range(3))
    face = np.cross(b - a, c - a)
    assert np.allclose(face / np.linalg.norm(face, axis=1, keepdims=True), normal[m.triangles[:, 0]], atol=1e-6)
    assert (np.einsum("ij,ij->i", a - [1.0, 2.0, 3.0], normal[m.triangles[:, 0]]) > 0).all()  # outward
    assert np.allclose(np.ptp(pos, axis=0), [0.2, 0.4, 0.6], atol=1e-6)


def test_triangle_mesh_keeps_creases_and_smooths_curves():
    """a cube's corners keep their faces' normals; a finely cut cylinder's are smooth"""
    cube = box_mesh((0, 0, 0), (1, 1, 1))
    pos = cube.vertices[:, :3].astype(float)
    m = triangle_mesh(pos, cube.triangles)
    assert np.allclose(m.vertices[:, 4:7].reshape(12, 3, 3), cube.vertices[cube.triangles, 4:7], atol=1e-6)
    ang = np.linspace(0, 2 * np.pi, 48, endpoint=False)
    ring = np.c_[np.cos(ang), np.zeros(48), np.sin(ang)]
    v = np.concatenate([ring, ring + [0, 1, 0]])
    k, k1 = np.arange(48), (np.arange(48) + 1) % 48
    tris = np.concatenate([np.c_[k, k + 48, k1], np.c_[k1, k + 48, k1 + 48]])
    n = triangle_mesh(v, tris).vertices[:, 4:7].astype(float)
    radial = v[tris.ravel()] * [1, 0, 1]
    assert np.abs(np.einsum("ij,ij->i", n, radial)).min() > 0.995  # along the radius, not a facet's


def test_box_drawn_where_it_projects(renderer):
    """a box seen from above: grey pixels fill the square its corners project to, and none lie outside it"""
    sim = world_sim(small_scene(box=BOX))
    cam = top_camera()
    img = draw(renderer, sim, cam)
    box = grey(img)
    px, _ = project(corners(BOX["center"], BOX["size"]), cam.view_projection(1.0), SIZE)
    (x0, y0), (x1, y1) = px.min(axis=0), px.max(axis=0)
    rows, cols = np.nonzero(box)
    assert cols.min() >= x0 - 1.5 and cols.max() <= x1 + 1.5 and rows.min() >= y0 - 1.5 and rows.max() <= y1 + 1.5
    inside = box[int(np.ceil(y0)) + 1: int(y1) - 1, int(np.ceil(x0)) + 1: int(x1) - 1]
    assert inside.mean() > 0.98
    assert box.sum() > 0.8 * (x1 - x0) * (y1 - y0)


def test_animated_box_moves_with_time(renderer):
    """drawn at t = 0 and t = 1 s of a slide 0.3 m along +x: the box's pixels move
    right by what 0.3 m projects to, keep their area; a still box does not move"""
    cam = top_camera((0.65, 0.2, 0.5))
    sim = world_sim(small_scene(box={**BOX, "animation": SLIDE}))
    before, after = (grey(draw(renderer, sim, cam, t)) for t in (0.0, 1.0))
    shift = np.nonzero(after)[1].mean() - np.nonzero(before)[1].mean()
    px, _ = project(np.array([BOX["center"], np.add(BOX["center"], [0.3, 0, 0])]), cam.view_projection(1.0), SIZE)
    assert shift == pytest.approx(px[1, 0] - px[0, 0], abs=1.0) and shift > 10
    assert abs(np.nonzero(after)[0].mean() - np.nonzero(before)[0].mean()) < 1.0
    assert after.sum() == pytest.approx(before.sum(), rel=0.05)
    still = world_sim(small_scene(box=BOX))
    assert np.array_equal(draw(renderer, still, cam, 0.0), draw(renderer, still, cam, 1.0))


def test_turning_box_and_moving_sphere(renderer):
    """a box turned 45 degrees about y covers the diamond its corners project to;
    a sphere carried 0.3 m along +x is drawn there"""
    cam = top_camera((0.65, 0.2, 0.5))
    turn = {"keys": [{"t": 0}, {"t": 1, "rotate": [0, 45, 0]}]}
    sim = world_sim(small_scene(box={**BOX, "animation": turn}))
    img = grey(draw(renderer, sim, cam, 1.0))
    R = collider_poses(sim)[0][:3, :3]
    px, _ = project(corners(BOX["center"], BOX["size"], R), cam.view_projection(1.0), SIZE)
    cx, cy = px.mean(axis=0)
    rows, cols = np.nonzero(img)
    assert np.abs(cols - cx).max() == pytest.approx(np.abs(px[:, 0] - cx).max(), abs=1.5)  # a corner's reach
    assert not img[int(cy - 0.9 * (px[:, 1].max() - cy)), int(cx - 0.9 * (px[:, 0].max() - cx))]  # a cut corner

    ball = world_sim(small_scene(sphere={"origin": [0.5, 0.2, 0.5], "radius": 0.08, "friction": 0.3,
                                         "animation": SLIDE}))
    img = grey(draw(renderer, ball, cam, 1.0))
    px, _ = project(np.array([[0.8, 0.2, 0.5]]), cam.view_projection(1.0), SIZE)
    rows, cols = np.nonzero(img)
    assert abs(cols.mean() - px[0, 0]) < 1.0 and abs(rows.mean() - px[0, 1]) < 1.0


def _torus_obj(path, center, R=0.15, r=0.05, nu=32, nv=16) -> None:
    u = np.linspace(0, 2 * np.pi, nu, endpoint=False)[:, None]
    v = np.linspace(0, 2 * np.pi, nv, endpoint=False)[None, :]
    p = np.stack([(R + r * np.cos(v)) * np.cos(u), r * np.sin(v) + 0 * u, (R + r * np.cos(v)) * np.sin(u)], -1)
    p = p.reshape(-1, 3) + center
    idx = np.arange(nu * nv).reshape(nu, nv)
    a, b, c = idx, np.roll(idx, -1, 0), np.roll(idx, -1, 1)
    d = np.roll(b, -1, 1)
    faces = np.concatenate([np.stack([a, c, b], -1).reshape(-1, 3), np.stack([b, c, d], -1).reshape(-1, 3)])
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in p] + [f"f {i} {j} {k}" for i, j, k in faces + 1]
    path.write_text("\n".join(lines) + "\n")


def test_mesh_collider_appears_and_moves(renderer, tmp_path):
    """a torus from an OBJ seen from above: a grey ring round its projected
    centre with the background in its hole; with an animation it is drawn
    where its pose at ``sim.time`` puts it"""
    _torus_obj(tmp_path / "torus.obj", [0.5, 0.2, 0.5])
    cam = top_camera((0.65, 0.2, 0.5))
    vp = cam.view_projection(1.0)
    sim = world_sim(small_scene(mesh={"path": "torus.obj", "friction": 0.3, "animation": SLIDE}), tmp_path)
    for t, x in ((0.0, 0.5), (1.0, 0.8)):
        img = grey(draw(renderer, sim, cam, t, shader="Phong"))
        (cx, cy), (rx, _) = project(np.array([[x, 0.2, 0.5], [x + 0.15, 0.2, 0.5]]), vp, SIZE)[0]
        assert not img[round(cy), round(cx)]                               # the hole
        assert img[round(cy), round(rx)] and img[round(cy), round(2 * cx - rx)]  # the ring either side
        rows, cols = np.nonzero(img)
        assert abs(cols.mean() - cx) < 1.0 and abs(rows.mean() - cy) < 1.0


def test_default_camera_frames_the_colliders(tmp_path):
    """the fixed framing takes in a box wherever its keys carry it, and a mesh collider"""
    _torus_obj(tmp_path / "torus.obj", [-1.0, 0.1, 0.5])
    far = {"keys": [{"t": 0}, {"t": 1, "translate": [2.0, 0, 0]}]}
    sim = world_sim(small_scene(box={**BOX, "animation": far}, mesh={"path": "torus.obj", "friction": 0.3}),
                    tmp_path)
    sim.state.positions[:] = sim.model.rest_positions
    cam = default_camera(sim, fixed=True)
    points = np.concatenate([corners(np.add(BOX["center"], [2.0, 0, 0]), BOX["size"]),
                             sim.mesh_colliders[0].vertices])
    px, front = project(points, cam.view_projection(1.0), SIZE)
    assert front.all() and (px >= 0).all() and (px <= SIZE[0]).all()


def test_cli_video_shows_the_box_moving(tmp_path):
    """``clothsim render`` to a GIF: the box slides right between its first and last frames"""
    import imageio.v3 as iio

    scene = small_scene(box={**BOX, "center": [2.0, 0.2, 0.5],
                             "animation": {"keys": [{"t": 0}, {"t": 0.2, "translate": [0.4, 0, 0]}]}})
    path = tmp_path / "slide.json"
    path.write_text(json.dumps(scene))
    out = tmp_path / "slide.gif"
    assert main(["render", str(path), "-o", str(out), "--seconds", "0.2", "--fps", "30", "--size", "96x96",
                 "--no-progress"]) == 0
    frames = iio.imread(out, index=None)[..., :3]
    first, last = grey(frames[0]), grey(frames[-1])
    assert first.sum() > 30 and last.sum() > 30
    assert np.nonzero(last)[1].mean() > np.nonzero(first)[1].mean() + 3
