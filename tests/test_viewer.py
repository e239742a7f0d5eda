"""The viewer in a real window on a virtual X display (Xvfb), driven like a user would."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time

import numpy as np
import pytest
from PIL import Image

from clothsim import Simulation

from .conftest import SCENES

XVFB = shutil.which("Xvfb")
if XVFB is None and not os.environ.get("CI"):
    pytest.skip("Xvfb is not installed (apt-get install xvfb); CI installs it", allow_module_level=True)


@pytest.fixture(scope="module")
def display():
    """a private Xvfb display for this module"""
    num = 90 + os.getpid() % 100
    proc = subprocess.Popen([XVFB, f":{num}", "-screen", "0", "1024x768x24", "-nolisten", "tcp"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 20
    while not os.path.exists(f"/tmp/.X11-unix/X{num}") and time.time() < deadline:
        time.sleep(0.1)
    old = os.environ.get("DISPLAY")
    os.environ["DISPLAY"] = f":{num}"
    yield f":{num}"
    if old is None:
        os.environ.pop("DISPLAY", None)
    else:
        os.environ["DISPLAY"] = old
    proc.terminate()
    proc.wait(timeout=10)


@pytest.fixture(scope="module")
def app(display):
    from clothsim.viewer.app import ViewerApp

    a = ViewerApp(Simulation.from_file(SCENES / "pinned2.json"), size=(640, 480))
    yield a
    a.close()


def test_window_after_offscreen_renderer(display):
    """a window opens in a process that rendered offscreen and released its EGL context

    Here in the test process after a released renderer, and in a fresh process.
    """
    from clothsim.render.renderer import DrawSettings, Renderer
    from clothsim.render.scene_view import SimulationView, default_camera

    sim = Simulation.from_file(SCENES / "plane.json")
    r = Renderer(size=(32, 32))
    SimulationView(r, sim).sync()
    assert r.render(default_camera(sim), DrawSettings()).any()
    r.release()
    code = ("import sys; from clothsim import Simulation; from clothsim.render.renderer import Renderer;"
            "from clothsim.viewer.app import ViewerApp;"
            "r = Renderer(size=(16, 16)); r.release();"
            f"a = ViewerApp(Simulation.from_file({str(SCENES / 'plane.json')!r}), size=(160, 120));"
            "a.frame(realtime=False); a.close(); print('ok')")
    # in a fresh process too, where nothing else has touched GL before
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                         env={**os.environ, "DISPLAY": display})
    assert out.returncode == 0 and "ok" in out.stdout, out.stderr


def frames(app, n):
    for _ in range(n):
        app.frame(realtime=False)
        app.swap()


def test_runs_frames(app):
    """each displayed frame advances the simulation by one frame"""
    start = app.sim.frame
    frames(app, 5)
    assert app.sim.frame == start + 5
    assert app.sim.time == pytest.approx(app.sim.frame / 90)


def test_pause_step_and_reset(app):
    """P freezes the cloth, N steps one frame while paused, R puts it back at the start"""
    frames(app, 3)
    app.press("p")
    before = app.sim.positions.copy()
    frames(app, 3)
    assert np.array_equal(app.sim.positions, before)
    app.press("n")
    frames(app, 2)
    assert not np.array_equal(app.sim.positions, before) and app.sim.frame > 0
    app.press("p")
    app.press("r")
    assert np.array_equal(app.sim.positions, app.sim.model.rest_positions)
    frames(app, 1)
    assert app.sim.frame == 1


def test_shader_key_changes_pixels(app, tmp_path):
    """pressing 2 switches to the Normal shader and the image changes"""
    app.press("1" if app.settings.shader != "Phong" else "4")  # Phong is the 4th built-in
    frames(app, 2)
    a = np.asarray(Image.open(app.save_screenshot(tmp_path / "a.png")))
    app.press("2")
    assert app.settings.shader == "Normal"
    app.press("p")
    frames(app, 1)
    b = np.asarray(Image.open(app.save_screenshot(tmp_path / "b.png")))
    app.press("p")
    assert np.abs(a.astype(int) - b.astype(int)).sum(axis=2).astype(bool).mean() > 0.02


def test_grab_pulls_point_toward_target(app):
    """shift-drag: the grabbed point follows the cursor onto a plane facing the camera"""
    from clothsim.viewer import picking

    app.press("r")
    frames(app, 20)
    size = app.window_size
    vp = app.camera.view_projection(size[0] / size[1])
    index = app.sim.model.index(25, 30)
    px, _ = picking.project(app.sim.positions[index:index + 1], vp, size)
    grabbed = app.grab_at(tuple(px[0]))
    assert grabbed >= 0 and app.sim.grabbed == grabbed
    start = app.sim.positions[grabbed].copy()
    target_px = (px[0][0] + 60, px[0][1] - 80)
    app.drag_to(target_px)
    frames(app, 10)
    now, _ = picking.project(app.sim.positions[grabbed:grabbed + 1], vp, size)
    assert np.linalg.norm(now[0] - np.array(target_px)) < 2.0  # under the cursor
    assert np.linalg.norm(app.sim.positions[grabbed] - start) > 0.05
    app._on_release(0, 0, app.wnd.mouse.left)
    assert app.sim.grabbed == -1


def test_screenshot_shows_cloth_and_panel(app, tmp_path):
    """the screenshot is the window: the panel on the left, the cloth in the view"""
    app.press("r")
    app.set_shader("Phong")
    frames(app, 10)
    img = np.asarray(Image.open(app.save_screenshot(tmp_path / "s.png")))
    assert img.shape == (480, 640, 3)
    bg = np.array(app.settings.background) * 255
    differs = np.abs(img.astype(float) - bg).sum(axis=2) > 20
    assert differs[:, :300].mean() > 0.3      # the panel
    assert differs[:, 340:].mean() > 0.03     # the cloth
    red = (img[:, 340:, 0].astype(int) - img[:, 340:, 2]) > 40
    assert red.sum() > 500                    # the red cloth itself


def test_scripted_cli(display, tmp_path):
    """clothsim view --frames N --keys --screenshot runs, saves and exits 0"""
    out = tmp_path / "v.png"
    r = subprocess.run([sys.executable, "-m", "clothsim", "view", str(SCENES / "sphere.json"), "--frames", "12",
                        "--keys", "p,n,n", "--screenshot", str(out), "--size", "480x360"],
                       capture_output=True, text=True, env={**os.environ, "DISPLAY": display}, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "t = 0.02 s" in r.stdout  # P pauses before frame 1; the two N presses step 2 frames: 2/90 s
    assert Image.open(out).size == (480, 360)


def test_no_display_points_to_render(tmp_path):
    """without a display, view exits 2 with a message that names clothsim render"""
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    r = subprocess.run([sys.executable, "-m", "clothsim", "view", str(SCENES / "sphere.json")],
                       capture_output=True, text=True, env=env, timeout=60)
    assert r.returncode == 2 and "clothsim render" in r.stderr and "Traceback" not in r.stderr


# ------------------------------------------------------------------ several cloths, any mesh


def test_pick_point_on_any_triangles():
    """a coarse mesh is grabbed anywhere on a triangle (its nearest corner), far
    from every vertex where the nearest-point pick finds nothing; of two layers
    the one nearer the camera wins"""
    from clothsim.render.camera import OrbitCamera
    from clothsim.viewer import picking

    big = np.array([[0, 1, 0], [1, 1, 0], [0, 1, 1], [1, 1, 1]], float)
    tris = np.array([[0, 2, 1], [1, 2, 3]])
    cam = OrbitCamera(target=np.array([0.5, 1.0, 0.5]), azimuth=0, elevation=89, distance=3.0)
    size = (400, 400)
    vp = cam.view_projection(1.0)
    target = np.array([0.2, 1.0, 0.3])  # inside triangle 0, nearest corner 0 (weight 0.5)
    cursor = tuple(picking.project(target[None], vp, size)[0][0])
    assert picking.nearest_point(big, vp, size, cursor) == -1
    assert picking.pick_point(big, tris, vp, size, cursor) == 0
    hit = picking.ray_hit(big, tris, *picking.cursor_ray(vp, size, cursor))
    assert hit[0] == 0 and np.allclose(hit[1] @ big[tris[0]], target, atol=1e-9)
    layers = np.concatenate([big, big + [0, 0.5, 0]])  # a second sheet above, nearer the camera
    both = np.concatenate([tris, tris + 4])
    assert picking.pick_point(layers, both, vp, size, cursor) == 4
    far = picking.project(np.array([[3.0, 1.0, 3.0]]), vp, size)[0][0]
    assert picking.pick_point(big, tris, vp, size, tuple(far)) == -1  # off the mesh, far from it


@pytest.fixture(scope="module")
def two_app(display):
    from clothsim.scene import parse_scene
    from clothsim.viewer.app import ViewerApp

    from .handmade import two_cloth_scene

    a = ViewerApp(Simulation(parse_scene(two_cloth_scene(), "two")), size=(640, 480))
    yield a
    a.close()


def _click(app, xy):
    """a left click at window pixel ``xy`` through the panel's input, a frame per
    event (the simulation paused meanwhile)"""
    x, y = xy
    if not app.paused:
        app.press("p")
    app.gui.mouse_position_event(x, y, 0, 0)
    frames(app, 1)
    app.gui.mouse_press_event(x, y, app.wnd.mouse.left)
    frames(app, 1)
    app.gui.mouse_release_event(x, y, app.wnd.mouse.left)
    frames(app, 2)


def test_panel_has_a_section_per_cloth(two_app, tmp_path):
    """two cloths: a section each with its own toggles; clicking the second
    cloth's shearing box turns off that cloth's shearing only, and the
    wireframe drops its shearing springs"""
    from clothsim.model import SHEARING
    from clothsim.render.scene_view import spring_lines

    frames(two_app, 2)
    items = two_app.panel_items
    assert {"cloth_0/shearing", "cloth_1/shearing", "cloth_0/ks", "cloth_1/ks"} <= set(items)
    assert items["cloth_1/shearing"][1] > items["cloth_0/ks"][1]  # the second section below the first
    sim = two_app.sim
    _click(two_app, items["cloth_1/shearing"])
    assert sim.cloths[1].params.enable_shearing is False
    assert sim.cloths[0].params.enable_shearing is True
    lines = spring_lines(sim)
    shear_1 = (sim.model.spring_kind == SHEARING) & (sim.model.spring_a >= sim.model.cloths[1].start)
    assert len(lines) == sim.model.num_springs - shear_1.sum()
    _click(two_app, items["cloth_1/shearing"])
    assert sim.cloths[1].params.enable_shearing is True
    assert any("2 cloths" in line for line in two_app.status_lines())
    two_app.save_screenshot(tmp_path / "panel.png")
    panel = np.asarray(Image.open(tmp_path / "panel.png"))[:, :300].astype(int)
    assert (np.abs(panel - panel[0, 0]).sum(axis=2) > 60).mean() > 0.05  # text and widgets drawn
    two_app.press("p")


def test_grab_a_point_of_the_second_cloth(two_app):
    """shift-drag picks on any cloth: a point of the hanging cloth, pulled toward the cursor"""
    from clothsim.viewer import picking

    app = two_app
    app.press("r")
    if app.paused:
        app.press("p")
    frames(app, 3)
    size = app.window_size
    vp = app.camera.view_projection(size[0] / size[1])
    lower = app.sim.model.cloths[1]
    index = lower.start + 3 * 12 + 6
    px, _ = picking.project(app.sim.positions[index:index + 1], vp, size)
    grabbed = app.grab_at(tuple(px[0]))
    assert lower.start <= grabbed < lower.stop
    start = app.sim.positions[grabbed].copy()
    target_px = (px[0][0] + 40, px[0][1] - 40)
    app.drag_to(target_px)
    frames(app, 10)
    now, _ = picking.project(app.sim.positions[grabbed:grabbed + 1], vp, size)
    assert np.linalg.norm(now[0] - np.array(target_px)) < 2.0
    assert np.linalg.norm(app.sim.positions[grabbed] - start) > 0.02
    app._on_release(0, 0, app.wnd.mouse.left)


# ------------------------------------------------------------------ the moving world and the wind


@pytest.fixture(scope="module")
def world_app(display):
    from clothsim.scene import parse_scene
    from clothsim.viewer.app import ViewerApp

    from .conftest import small_scene

    slide = {"keys": [{"t": 0}, {"t": 1, "translate": [0.4, 0, 0]}]}
    scene = small_scene(box={"center": [0.3, 0.2, 0.5], "size": [0.3, 0.1, 0.3], "friction": 0.5,
                             "animation": slide})
    a = ViewerApp(Simulation(parse_scene(scene, "world")), size=(1000, 720))  # the scene right of the panel
    yield a
    a.close()


def test_panel_wind_section_edits_sim_wind(world_app):
    """no wind: an "add wind" button that adds a 2 m/s breeze along +x; then
    sliders that edit sim.wind live, and a friction slider for the box"""
    from clothsim.world_spec import WindSpec

    app = world_app
    frames(app, 1)
    assert app.sim.wind is None and "wind/turbulence" not in app.panel_items
    assert "box0/friction" in app.panel_items
    _click(app, app.panel_items["wind/add"])
    assert app.sim.wind == WindSpec(velocity=(2.0, 0.0, 0.0))
    items = app.panel_items
    assert {"wind/velocity", "wind/turbulence", "wind/drag", "wind/lift"} <= set(items)
    assert "wind/add" not in items
    _click(app, items["wind/turbulence"])
    _click(app, items["wind/lift"])
    wind = app.sim.wind
    assert 0.0 < wind.turbulence <= 1.0 and 0.0 < wind.lift <= 5.0 and wind.drag == 1.0
    _click(app, items["box0/friction"])
    assert app.sim.boxes[0].friction != 0.5
    app.sim.wind = None
    app.press("p")


def test_viewer_draws_the_box_where_it_is_now(world_app, tmp_path):
    """the box is drawn at its pose at sim.time: 0.4 m further along +x at t = 1 s"""
    app = world_app
    if not app.paused:
        app.press("p")
    app.sim.state.positions[:] += [100.0, 0.0, 0.0]  # the cloth out of view: every drawn pixel is the box's
    centres = []
    for t in (0.0, 1.0):
        app.sim.state.time = t
        frames(app, 1)
        img = np.asarray(Image.open(app.save_screenshot(tmp_path / f"t{t}.png"))).astype(int)[:, 400:]
        box = (np.abs(img - np.array(app.settings.background) * 255).sum(axis=2) > 20) & \
              (img.max(axis=2) - img.min(axis=2) < 25)
        assert box.sum() > 200
        centres.append(np.nonzero(box)[1].mean())
    assert centres[1] > centres[0] + 10
    app.press("r")
