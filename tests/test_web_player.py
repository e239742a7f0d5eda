"""The web player (``render -o OUT.html``): its data decoded in Python, the page's
self-containment, its size and cost, bad input, and the page in a real headless
browser (Debian's chromium, software WebGL2), screenshots checked pixel by pixel."""

from __future__ import annotations

import base64
import re
import shutil
import subprocess
import time
import zlib
from pathlib import Path

import numpy as np
import pytest

from clothsim import Simulation
from clothsim.cli import main
from clothsim.export import web
from clothsim.render.renderer import BACKGROUND, COLLIDER_COLOR, DrawSettings
from clothsim.scene import PlaneSpec, SphereSpec
from clothsim.trajectory import Trajectory, TrajectoryRecorder

from .browser import Page
from .conftest import SCENES

GREEN = (0.2, 0.7, 0.3)
"""a cloth colour far from the background's and the colliders' greys"""


def synthetic(frames: int = 6, nx: int = 5, ny: int = 4, seed: int = 0) -> Trajectory:
    """A small grid moving at random, with jumps far beyond one byte of delta, and a flat axis"""
    rng = np.random.default_rng(seed)
    u, v = np.meshgrid(np.linspace(0, 1, nx), np.linspace(0, 1, ny))
    start = np.stack([u.ravel(), np.full(u.size, 0.7), v.ravel()], axis=1)
    steps = rng.normal(0, 1e-3, (frames, u.size, 3))
    steps[:, :, 1] = 0.0  # y stays put: a zero span
    steps[frames // 2, :3, 0] += 0.4  # a jump: escapes
    steps[0] = 0.0
    positions = start + np.cumsum(steps, axis=0)
    tris = []
    for j in range(ny - 1):
        for i in range(nx - 1):
            a = j * nx + i
            tris += [(a, a + nx, a + 1), (a + 1, a + nx, a + nx + 1)]
    return Trajectory(positions=positions, times=np.arange(frames) / 90.0, triangles=np.array(tris, np.int32),
                      uvs=np.zeros((u.size, 2), np.float32), frames_per_sec=90.0,
                      spheres=[SphereSpec((0.5, 0.2, 0.5), 0.2, 0.3)],
                      planes=[PlaneSpec((0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 0.5)],
                      name="synthetic <test>", description="ks=5000 N/m & more")


def scripts(page: str) -> dict[str, str]:
    return {m.group(1): m.group(2).strip()
            for m in re.finditer(r'<script[^>]* id="([^"]+)">(.*?)</script>', page, re.S)}


# ---------------------------------------------------------------------------
# the data, decoded in Python


def test_decoding_reproduces_positions_to_the_quantization_step():
    """read_player gives back every frame within half a quantization step, and the mesh and times"""
    traj = synthetic()
    page = web.player_html(traj)
    got = web.read_player(page)
    step = np.array(got["meta"]["step"])
    assert step[1] == 0.0 and (step[[0, 2]] > 0).all()
    err = np.abs(got["positions"] - traj.positions).max(axis=(0, 1))
    assert (err <= step / 2 + 1e-12).all(), (err, step)
    np.testing.assert_array_equal(got["triangles"], traj.triangles)
    np.testing.assert_allclose(got["times"], traj.times, atol=1e-6)
    assert got["meta"]["escapes"][0] > traj.positions.shape[1]  # the jump needed whole deltas


def test_format_as_documented():
    """decoding the page's bytes one by one, as the page's script does, gives the same frames"""
    traj = synthetic(frames=5, nx=3, ny=3, seed=1)
    page = web.player_html(traj)
    meta = web.read_player(page)["meta"]
    blobs = scripts(page)
    frames, points = meta["frames"], meta["points"]
    for a in range(3):
        data = zlib.decompress(base64.b64decode(blobs[f"clothsim-pos-{a}"]))
        assert len(data) == frames * points + 2 * meta["escapes"][a]
        acc, e = [0] * points, frames * points
        for f in range(frames):
            for p in range(points):
                z = data[f * points + p]
                if z == 255:
                    d, e = data[e] | data[e + 1] << 8, e + 2
                else:
                    d = (z >> 1) ^ -(z & 1)
                acc[p] = (acc[p] + d) % 65536
                x = meta["lo"][a] + acc[p] * meta["step"][a]
                assert abs(x - traj.positions[f, p, a]) <= meta["step"][a] / 2 + 1e-12
        assert e == len(data)


def test_page_is_self_contained():
    """no address to fetch, no file to load: nothing but the page itself, and its text escaped"""
    page = web.player_html(synthetic())
    assert "http://" not in page and "https://" not in page
    for pattern in (r"\bfetch\(", r"XMLHttpRequest", r"\bimport\(", r"<link\b", r"\bsrc=", r"@import",
                    r"url\(", r"WebSocket", r"navigator\.sendBeacon"):
        assert not re.search(pattern, page), pattern
    assert "synthetic &lt;test&gt;" in page and "ks=5000 N/m &amp; more" in page
    assert page.count("<script") == page.count("</script>") == 6  # meta, triangles, player, 3 axes


def test_look_and_sizes():
    """colour, size and camera reach the page; bad values are refused"""
    page = web.player_html(synthetic(), color=GREEN, width=640, height=480, camera=(10, 20, 3))
    meta = web.read_player(page)["meta"]
    assert meta["look"]["color"] == list(GREEN) and meta["look"]["collider"] == list(COLLIDER_COLOR)
    assert meta["camera"]["azimuth"] == 10 and meta["camera"]["distance"] == 3
    assert "width:640px;height:480px" in page
    assert web.DEFAULT_COLOR == DrawSettings().color
    for bad in ({"color": (1.5, 0, 0)}, {"color": (1, 0)}, {"width": 5, "height": 10}, {"camera": (1, 2)}):
        with pytest.raises(ValueError):
            web.player_html(synthetic(), **bad)
    single = synthetic(frames=1)
    assert web.read_player(web.player_html(single))["positions"].shape == (1, 20, 3)


@pytest.fixture(scope="module")
def five_seconds():
    """sphere.json, 50x50, 5 s recorded frame by frame; the simulation's CPU time"""
    sim = Simulation.from_file(SCENES / "sphere.json")
    sim.step(substeps=0)  # load the kernels first
    recorder = TrajectoryRecorder(sim)
    start = time.process_time()
    sim.run(5.0, on_frame=recorder)
    return recorder, sim, time.process_time() - start


def test_five_second_run_size_and_cost(five_seconds, tmp_path):
    """a 5 s 50x50 run (451 frames of 2,500 points) fits in under 5 MB, and collecting
    and writing it costs under a fifth of the simulation's CPU time"""
    recorder, sim, sim_cpu = five_seconds
    out = tmp_path / "p.html"
    costs = []
    for _ in range(3):  # the least of three: other processes on the machine only add to it
        start = time.process_time()
        traj = recorder.trajectory(sim)
        web.write_player(out, traj)
        costs.append(time.process_time() - start)
    cost = min(costs)
    size = out.stat().st_size
    print(f"5 s 50x50: {size / 1e6:.2f} MB, written in {cost * 1e3:.0f} ms CPU, "
          f"simulated in {sim_cpu * 1e3:.0f} ms CPU ({100 * cost / sim_cpu:.0f}%)")
    assert traj.positions.shape == (451, 2500, 3)
    assert size < 5e6
    assert cost < 0.2 * sim_cpu


# ---------------------------------------------------------------------------
# render -o OUT.html


def test_cli_writes_player(tmp_path, capsys):
    """render -o OUT.html writes the page of every frame, no GL needed, and says how big it is"""
    out = tmp_path / "p.html"
    assert main(["render", "pinned2", "-o", str(out), "--seconds", "0.2", "--color", "0.2,0.7,0.3",
                 "--size", "640x480", "--no-progress"]) == 0
    line = capsys.readouterr().out
    assert f"wrote {out}" in line and "MB in" in line
    got = web.read_player(out.read_text())
    assert got["positions"].shape == (19, 2500, 3) and got["meta"]["name"] == "pinned2"
    assert got["meta"]["look"]["color"] == list(GREEN) and "ks=" in got["meta"]["description"]
    assert not list(tmp_path.glob(".*"))  # no temporary file left


def test_frame_recorder_writes_player(tmp_path):
    """FrameRecorder(outputs={"html": path}) writes the same page from the frames it collected"""
    from clothsim.recording import FrameRecorder

    sim = Simulation.from_file(SCENES / "pinned2.json")
    out = tmp_path / "r.html"
    recorder = FrameRecorder(sim, outputs={"html": str(out)})
    sim.run(0.1, on_frame=recorder)
    recorder.finish(sim)
    got = web.read_player(out.read_text())
    assert got["positions"].shape == (10, 2500, 3) and got["meta"]["look"]["color"] == list(web.DEFAULT_COLOR)
    assert np.abs(got["positions"][-1] - sim.positions).max() <= max(got["meta"]["step"]) / 2 + 1e-12


def _not_run(*args, **kwargs):
    raise AssertionError("the simulation should not have started")


@pytest.mark.parametrize("case", ["exists", "folder is a file", "no folder", "extension", "shader", "color"])
def test_cli_bad_output_one_line_exit_2_before_the_run(tmp_path, capsys, monkeypatch, case):
    """each bad output is one line and exit 2 before any simulation, and leaves nothing behind"""
    import clothsim.cli.render as render_cli

    monkeypatch.setattr(render_cli, "load_simulation", _not_run)
    out, extra, expected = tmp_path / "p.html", [], None
    if case == "exists":
        out.write_text("keep")
        expected = "already exists; pass --overwrite"
    elif case == "folder is a file":
        (tmp_path / "file").write_text("")
        out = tmp_path / "file" / "p.html"
        extra, expected = ["--overwrite"], "is not a folder"
    elif case == "no folder":
        out, expected = tmp_path / "nowhere" / "p.html", "does not exist"
    elif case == "extension":
        out, expected = tmp_path / "p.htmx", ".mp4, .gif or .html"
    elif case == "shader":
        extra, expected = ["--shader", "Normal"], "--shader: not used by the web player"
    else:
        extra, expected = ["--color", "2,0,0"], "--color: expected components in [0, 1]"
    before = sorted(tmp_path.rglob("*"))
    assert main(["render", "pinned2", "-o", str(out), "--seconds", "0.1", *extra]) == 2
    err = capsys.readouterr().err
    assert expected in err and len(err.strip().splitlines()) == 1, err
    assert sorted(tmp_path.rglob("*")) == before
    if case == "exists":
        assert out.read_text() == "keep"


# ---------------------------------------------------------------------------
# in a real browser

CHROMIUM = shutil.which("chromium") or ("/usr/bin/chromium" if Path("/usr/bin/chromium").exists() else None)
needs_chromium = pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed "
                                    "(.ci/run installs Debian's: apt-get install chromium)")

BROWSER_FLAGS = [
    "--headless", "--no-sandbox",
    # WebGL2 without a GPU: ANGLE on SwiftShader, the software Vulkan renderer
    "--disable-gpu", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
    # no network at all: every host name fails to resolve, and nothing phones home
    "--host-resolver-rules=MAP * ~NOTFOUND", "--disable-background-networking", "--disable-component-update",
    "--disable-sync", "--disable-extensions", "--disable-default-apps", "--no-first-run",
    "--no-default-browser-check", "--mute-audio", "--hide-scrollbars",
    "--window-size=800,600",
]

VIRTUAL_TIME = "--virtual-time-budget=8000"
"""for a page read once it has loaded: its decoding and first drawing finish before
the dump or the screenshot (animation frames do not follow it: see tests/browser.py)"""


def new_profile(tmp_path: Path) -> Path:
    return tmp_path / f"profile-{len(list(tmp_path.glob('profile-*')))}"


def browse(url: str, tmp_path: Path, *action: str) -> subprocess.CompletedProcess:
    return subprocess.run([CHROMIUM, *BROWSER_FLAGS, VIRTUAL_TIME, f"--user-data-dir={new_profile(tmp_path)}",
                           *action, url], capture_output=True, text=True, timeout=180, cwd=tmp_path)


def screenshot(page: Path, fragment: str, tmp_path: Path) -> np.ndarray:
    from PIL import Image

    png = tmp_path / f"shot-{fragment.replace('=', '-')}.png"
    result = browse(f"{page.as_uri()}#{fragment}", tmp_path, f"--screenshot={png}")
    assert png.exists(), result.stderr[-2000:]
    return np.asarray(Image.open(png).convert("RGB")).astype(float)


def state(page: Path, fragment: str, tmp_path: Path) -> dict[str, str]:
    """the <html> element's data-* attributes after the page ran"""
    result = browse(f"{page.as_uri()}{fragment}", tmp_path, "--dump-dom")
    tag = re.search(r"<html[^>]*>", result.stdout)
    assert tag, result.stderr[-2000:]
    return dict(re.findall(r'data-(\w+)="([^"]*)"', tag.group(0)))


def shades_of(img: np.ndarray, color) -> np.ndarray:
    """pixels whose colour is a brighter or darker shade of ``color`` (its direction in RGB)"""
    c = np.asarray(color, float) / np.linalg.norm(color)
    norm = np.linalg.norm(img, axis=2)
    cosine = (img @ c) / np.maximum(norm, 1e-9)
    return (cosine > 0.985) & (norm > 20)


@pytest.fixture(scope="module")
def sphere_page(tmp_path_factory):
    """render sphere -o page.html for 1 s in green: the cloth falls onto the sphere"""
    out = tmp_path_factory.mktemp("web") / "page.html"
    assert main(["render", "sphere", "-o", str(out), "--seconds", "1", "--color", ",".join(map(str, GREEN)),
                 "--no-progress"]) == 0
    return out


LOADED = "/^(ready|error)/.test(document.documentElement.dataset.state || '')"
"""true once the page has decoded its run (or failed to)"""


def open_page(page: Path, fragment: str, tmp_path: Path) -> Page:
    """the page in chromium, running in real time, for questions through the DevTools protocol"""
    return Page(CHROMIUM, BROWSER_FLAGS, f"{page.as_uri()}{fragment}", new_profile(tmp_path))


@needs_chromium
def test_browser_plays_the_page(sphere_page, tmp_path):
    """the page decodes, draws and plays in chromium with software WebGL2, offline;
    an address that names a frame shows that frame and stays on it"""
    ready = state(sphere_page, "#frame=last", tmp_path)
    assert ready["state"] == "ready" and ready["frame"] == "90" and ready["playing"] == "false", ready
    # playing goes by animation frames, which come in real time, not on virtual time
    with open_page(sphere_page, "", tmp_path) as browser:
        assert browser.wait_for(LOADED, 60), browser.dataset()
        assert browser.dataset()["state"] == "ready", browser.dataset()
        assert browser.wait_for("Number(document.documentElement.dataset.stepped) > 0", 60), browser.dataset()
        played = browser.dataset()
        assert played["playing"] == "true" and played["frame"] != "0", played  # it moved on by itself
        # and keeps going
        assert browser.wait_for(f"Number(document.documentElement.dataset.stepped) > {played['stepped']}", 60)
    with open_page(sphere_page, "#frame=last", tmp_path) as browser:
        assert browser.wait_for(LOADED, 60) and browser.dataset()["state"] == "ready", browser.dataset()
        time.sleep(1.0)  # a second of animation frames, paused
        still = browser.dataset()
        assert still["frame"] == "90" and still["stepped"] == "0" and still["playing"] == "false", still
        # space bar plays it: from the last frame it loops round to the start
        browser.evaluate("document.dispatchEvent(new KeyboardEvent('keydown', {key: ' '}))")
        assert browser.wait_for("Number(document.documentElement.dataset.stepped) > 0", 60), browser.dataset()


@needs_chromium
def test_browser_screenshots_show_the_cloth_moving(sphere_page, tmp_path):
    """screenshots at the first and the last frame: the cloth's colour is there, with the
    sphere's grey, on the background, and where the cloth is differs between the two"""
    first = screenshot(sphere_page, "frame=0", tmp_path)
    last = screenshot(sphere_page, "frame=last", tmp_path)
    assert first.shape == (600, 800, 3)
    cloth_first, cloth_last = shades_of(first, GREEN), shades_of(last, GREEN)
    assert cloth_first.mean() > 0.01 and cloth_last.mean() > 0.01, (cloth_first.mean(), cloth_last.mean())
    moved = (cloth_first ^ cloth_last).sum() / (cloth_first | cloth_last).sum()
    assert moved > 0.3, moved
    # the cloth fell: its pixels are lower in the last image
    rows = np.arange(first.shape[0])[:, None]
    assert (rows * cloth_last).sum() / cloth_last.sum() > (rows * cloth_first).sum() / cloth_first.sum() + 50
    grey = shades_of(first, COLLIDER_COLOR) & (np.linalg.norm(first - np.array(BACKGROUND) * 255, axis=2) > 40)
    assert grey[100:550].mean() > 0.01  # the sphere (the text above it and the bar below left out)
    background = np.abs(first - np.array(BACKGROUND) * 255).sum(axis=2) < 6
    assert background.mean() > 0.5


# ---------------------------------------------------------------------------
# several cloths, a mesh cloth


@pytest.fixture(scope="module")
def two_cloth_page(tmp_path_factory):
    """the player of a hand-made disc (no grid) beside a grid cloth, two frames
    (the second lifted 0.1 m), in green"""
    from .handmade import disc_and_grid, simulation_of

    sim = simulation_of(disc_and_grid())
    frames = TrajectoryRecorder(sim)
    sim.state.positions[:, 1] += 0.1
    sim.state.time = 1 / 90
    frames(sim)
    traj = frames.trajectory(sim)
    out = tmp_path_factory.mktemp("web2") / "two.html"
    web.write_player(out, traj, color=GREEN)
    return out, sim, traj


def test_player_holds_every_cloth(two_cloth_page):
    """the page's frames are every cloth's points in scene order, its triangles
    the mesh's own, and meta.cloths each cloth's name and ranges"""
    out, sim, traj = two_cloth_page
    got = web.read_player(out.read_text())
    assert got["meta"]["cloths"] == [
        {"name": c.name, "start": c.model.start, "stop": c.model.stop, "tri_start": c.model.tri_start,
         "tri_stop": c.model.tri_stop} for c in sim.cloths]
    assert [c["name"] for c in got["meta"]["cloths"]] == ["disc", "grid"]
    np.testing.assert_array_equal(got["triangles"], sim.model.triangles)
    assert np.abs(got["positions"] - traj.positions).max() <= max(got["meta"]["step"]) / 2 + 1e-12


@needs_chromium
def test_browser_shows_both_cloths(two_cloth_page, tmp_path):
    """in chromium the page draws two separate patches of the cloth colour, the
    disc's round one beside the grid's"""
    from scipy import ndimage

    out, _, _ = two_cloth_page
    assert state(out, "#frame=0", tmp_path)["state"] == "ready"
    img = screenshot(out, "frame=0", tmp_path)
    green = shades_of(img, GREEN)
    labels, count = ndimage.label(green)
    sizes = ndimage.sum(green, labels, range(1, count + 1))
    big = np.flatnonzero(sizes > 0.02 * green.size)
    assert len(big) == 2, sorted(sizes)[-4:]
    assert green[:, :5].sum() == 0 and green[:, -5:].sum() == 0  # both in view
