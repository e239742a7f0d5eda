"""Images rendered headless (EGL, Mesa's llvmpipe in CI), checked pixel by pixel."""

from __future__ import annotations

import numpy as np
import pytest

from clothsim import RenderError, Simulation
from clothsim.cli import main
from clothsim.render import assets
from clothsim.render.camera import OrbitCamera
from clothsim.render.renderer import BACKGROUND, DrawSettings, Renderer
from clothsim.render.scene_view import SimulationView, default_camera
from clothsim.render.shaders import ORDER, ShaderLibrary

from .conftest import SCENES

SIZE = (160, 160)
BG = np.array(BACKGROUND) * 255


@pytest.fixture(scope="module")
def draped():
    """sphere.json after 1.5 s: the cloth lies on the sphere"""
    sim = Simulation.from_file(SCENES / "sphere.json")
    sim.run(1.5)
    return sim


@pytest.fixture(scope="module")
def renderer():
    r = Renderer(size=SIZE)
    yield r
    r.release()


def render(renderer, sim, camera=None, **settings):
    view = SimulationView(renderer, sim, (24, 24))
    view.sync()
    return renderer.render(camera or default_camera(sim, fixed=False), DrawSettings(**settings))


def foreground(img: np.ndarray) -> np.ndarray:
    return np.abs(img.astype(float) - BG).sum(axis=2) > 12


def interior(mask: np.ndarray) -> np.ndarray:
    """the mask without its outline, where anti-aliasing blends with the background
    (a pixel counts as outline when any of its 8 neighbours is background)"""
    m = mask.copy()
    core = mask[1:-1, 1:-1].copy()
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            core &= mask[1 + dr: mask.shape[0] - 1 + dr, 1 + dc: mask.shape[1] - 1 + dc]
    m[1:-1, 1:-1] = core
    m[[0, -1]] = False
    m[:, [0, -1]] = False
    return m


def cloth_only(sim):
    """a copy of the scene without colliders, so pixels belong to the cloth alone"""
    bare = Simulation(sim.scene)
    bare.state.positions[:] = sim.positions
    bare.spheres, bare.planes = [], []
    return bare


@pytest.mark.parametrize("name", ORDER)
def test_every_shader_draws_the_cloth(renderer, draped, name):
    """each built-in shader compiles and covers the cloth's part of the image"""
    img = render(renderer, cloth_only(draped), shader=name)
    fg = foreground(img)
    assert img.shape == (SIZE[1], SIZE[0], 3)
    assert fg.mean() > (0.02 if name == "Wireframe" else 0.15)
    assert not fg[0].any() and not fg[:, 0].any()  # framed with a margin


def test_diffuse_brighter_facing_the_light(renderer):
    """a flat cloth lit from above is brighter where it is nearer the light"""
    sim = Simulation.from_file(SCENES / "plane.json")
    cam = OrbitCamera(target=np.array([0.5, 1.0, 0.5]), azimuth=0, elevation=89, distance=2.0)
    near = render(renderer, cloth_only(sim), cam, shader="Diffuse", light=_light((0.5, 1.5, 0.9)))
    far = render(renderer, cloth_only(sim), cam, shader="Diffuse", light=_light((0.5, 1.5, 0.9)))
    assert np.array_equal(near, far)  # deterministic
    lum = near.astype(float).sum(axis=2)
    fg = foreground(near)
    # the light is above z = 0.9: the image half showing z near 0.9 is brighter
    top, bottom = lum[: SIZE[1] // 2][fg[: SIZE[1] // 2]].mean(), lum[SIZE[1] // 2:][fg[SIZE[1] // 2:]].mean()
    assert bottom > top * 1.3


def _light(pos):
    from clothsim.render.camera import Light

    return Light(position=pos)


def test_phong_has_a_highlight_diffuse_lacks(renderer, draped):
    """Blinn-Phong's brightest pixels are far brighter than Diffuse's on the same cloth"""
    sim = cloth_only(draped)
    diffuse = render(renderer, sim, shader="Diffuse", color=(0.5, 0.5, 0.5))
    phong = render(renderer, sim, shader="Phong", color=(0.5, 0.5, 0.5), ka=0.0, kd=1.0, ks=1.0, p=50)
    bright = phong.astype(int).sum(axis=2) > diffuse.astype(int).sum(axis=2).max() + 60
    assert bright.sum() >= 5  # a highlight: pixels far brighter than anything Diffuse shows
    only_specular = render(renderer, sim, shader="Phong", ka=0.0, kd=0.0, ks=1.0, p=50)
    spec = only_specular.astype(int).sum(axis=2)
    assert spec.sum() < 0.7 * phong.astype(int).sum()       # one term alone is darker overall
    assert (spec > 300).sum() >= 5                          # but keeps the highlight


def test_bump_keeps_silhouette_displacement_changes_it(renderer, draped):
    """Bump and Phong cover the same pixels; Displacement moves the outline"""
    sim = cloth_only(draped)
    phong = foreground(render(renderer, sim, shader="Phong"))
    bump_img = render(renderer, sim, shader="Bump")
    disp = foreground(render(renderer, sim, shader="Displacement", height_scaling=0.05))
    assert np.array_equal(foreground(bump_img), phong)
    assert (disp != phong).sum() > 50
    assert not np.array_equal(bump_img, render(renderer, sim, shader="Phong"))  # the bumps show


def test_mirror_colours_come_from_the_cube_map(draped):
    """swapping the cube map for a plain green one turns the mirrored cloth green"""
    sim = cloth_only(draped)
    sky = Renderer(size=SIZE)
    green = Renderer(size=SIZE, cubemap={f: np.full((8, 8, 3), (20, 200, 40), np.uint8) for f in assets.CUBE_FACES})
    a = render(sky, sim, shader="Mirror")
    b = render(green, sim, shader="Mirror")
    fg = interior(foreground(b))
    assert not np.array_equal(a, b)
    np.testing.assert_allclose(b[fg].mean(axis=0), (20, 200, 40), atol=6)
    sky.release()
    green.release()


def test_wireframe_only_lines_and_fewer_without_shearing(renderer, draped):
    """Wireframe draws lines in u_color; turning shearing off leaves fewer lit pixels"""
    sim = cloth_only(draped)
    cam = default_camera(sim, fixed=False)
    cam.distance *= 0.6
    full = foreground(render(renderer, sim, cam, shader="Wireframe"))
    sim.params.enable_shearing = False
    sparse_img = render(renderer, sim, cam, shader="Wireframe")
    sparse = foreground(sparse_img)
    assert sparse.sum() < 0.9 * full.sum()
    # lines, not filled faces: many background pixels lie inside the cloth's outline
    rows = np.flatnonzero(sparse.any(axis=1))
    inside = sparse[rows[len(rows) // 2]]
    span = np.flatnonzero(inside)
    assert (~inside[span[0]:span[-1]]).sum() > 5


def test_sphere_resolution_changes_outline(renderer):
    """a 6-band sphere has a visibly polygonal outline compared with a 60-band one"""
    sim = Simulation.from_file(SCENES / "sphere.json")
    sim.state.positions[:] += np.array([0.0, 5.0, 0.0])  # cloth out of view
    cam = OrbitCamera(target=np.array([0.5, 0.2, 0.5]), distance=1.0)
    coarse = SimulationView(renderer, sim, (6, 6))
    coarse.sync()
    a = foreground(renderer.render(cam, DrawSettings(shader="Normal")))
    fine = SimulationView(renderer, sim, (60, 60))
    fine.sync()
    b = foreground(renderer.render(cam, DrawSettings(shader="Normal")))
    assert b.sum() > a.sum() and (a != b).sum() > 30


def test_user_shader_folder_loads(tmp_path, renderer, draped):
    """a folder with only Name.frag pairs with Default.vert and can draw"""
    (tmp_path / "Flat.frag").write_text(
        "#version 330\nuniform vec4 u_color;\nout vec4 out_color;\n"
        "void main() { out_color = vec4(0.0, 1.0, 0.0, 1.0); }\n")
    lib = ShaderLibrary([tmp_path])
    assert "Flat" in lib.names() and lib.sources("Flat")[0].name == "Default.vert"
    r = Renderer(size=SIZE, shaders=lib)
    img = render(r, cloth_only(draped), shader="Flat")
    inside = interior(foreground(img))
    assert inside.sum() > 500 and (img[inside] == (0, 255, 0)).all()
    r.release()


def test_broken_shader_names_file_and_line(tmp_path):
    """a shader that does not compile raises RenderError with the file and line"""
    (tmp_path / "Broken.frag").write_text("#version 330\nout vec4 c;\nvoid main() {\n  c = vec4(1.0) + nope;\n}\n")
    r = Renderer(size=SIZE, shaders=ShaderLibrary([tmp_path]))
    with pytest.raises(RenderError, match=r"Broken\.frag: line 4: .*nope"):
        r.program("Broken")
    r.release()


def test_cli_render_png_and_contact_sheet(tmp_path, capsys):
    """render writes a PNG of the cloth and a labelled sheet with every shader"""
    from PIL import Image

    out = tmp_path / "c.png"
    assert main(["render", str(SCENES / "pinned2.json"), "-o", str(out), "--seconds", "0.3",
                 "--size", "120x100"]) == 0
    img = np.asarray(Image.open(out))
    assert img.shape == (100, 120, 3) and foreground(img).mean() > 0.1
    sheet = tmp_path / "all.png"
    assert main(["render", str(SCENES / "pinned2.json"), "-o", str(sheet), "--seconds", "0.1",
                 "--shader", "all", "--size", "64x64"]) == 0
    s = np.asarray(Image.open(sheet))
    assert s.shape[1] == 3 * 64 and s.shape[0] > 3 * 64  # 3x3 grid with caption strips


def test_cli_broken_shader_exit_2(tmp_path, capsys):
    """--shaders with a broken file exits 2 with the compiler's line, before simulating"""
    (tmp_path / "Bad.frag").write_text("#version 330\nvoid main() { oops }\n")
    code = main(["render", str(SCENES / "pinned2.json"), "-o", str(tmp_path / "x.png"),
                 "--shaders", str(tmp_path), "--shader", "Bad"])
    err = capsys.readouterr().err
    assert code == 2 and "Bad.frag: line 2" in err and not (tmp_path / "x.png").exists()


@pytest.mark.parametrize("suffix", ["gif", "mp4"])
def test_cli_video(tmp_path, capsys, suffix):
    """an animation has one image per shown frame and the cloth moves between them"""
    import imageio.v3 as iio

    out = tmp_path / f"a.{suffix}"
    assert main(["render", str(SCENES / "pinned2.json"), "-o", str(out), "--seconds", "0.2",
                 "--fps", "30", "--size", "96x96", "--no-self-collision"]) == 0
    frames = iio.imread(out, index=None)
    assert len(frames) == 7  # t = 0, 1/30, ..., 6/30
    assert np.abs(frames[0].astype(int) - frames[-1].astype(int)).mean() > 1.0
