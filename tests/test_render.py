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


GREEN_VERT = """#version 330
uniform mat4 u_model;
uniform mat4 u_view_projection;
in vec4 in_position;
out vec4 v_tint;
void main() {
    v_tint = vec4(0.0, 1.0, 0.0, 1.0);
    gl_Position = u_view_projection * u_model * in_position;
}
"""
TINT_FRAG = "#version 330\nin vec4 v_tint;\nout vec4 out_color;\nvoid main() { out_color = v_tint; }\n"


def test_user_wireframe_frag_pairs_with_the_users_default_vert(tmp_path, draped):
    """as in CS184, a user's Wireframe.frag without Wireframe.vert takes the user's
    Default.vert (whose output it reads: with our Wireframe.vert it would not link);
    our own shaders keep their pairs"""
    (tmp_path / "Default.vert").write_text(GREEN_VERT)
    (tmp_path / "Wireframe.frag").write_text(TINT_FRAG)
    lib = ShaderLibrary([tmp_path])
    assert lib.sources("Wireframe") == (tmp_path / "Default.vert", tmp_path / "Wireframe.frag")
    assert lib.sources("Displacement")[0].parent != tmp_path  # ours, beside its .frag
    r = Renderer(size=SIZE, shaders=lib)
    img = render(r, cloth_only(draped), shader="Wireframe")
    lines = foreground(img)
    assert lines.mean() > 0.02
    pure = img[lines]
    assert (pure[:, 1] > 2 * pure[:, 0] + 20).mean() > 0.9  # the user's green lines
    r.release()


def test_a_users_own_vert_beats_their_default_vert(tmp_path):
    (tmp_path / "Default.vert").write_text(GREEN_VERT)
    (tmp_path / "Wireframe.vert").write_text(GREEN_VERT)
    (tmp_path / "Wireframe.frag").write_text(TINT_FRAG)
    other = tmp_path / "more"
    other.mkdir()
    (other / "Bump.frag").write_text(TINT_FRAG)
    lib = ShaderLibrary([other, tmp_path])
    assert lib.sources("Wireframe")[0] == tmp_path / "Wireframe.vert"
    assert lib.sources("Bump")[0] == tmp_path / "Default.vert"  # any user folder's, before ours


def _top_band_image(size=64, band=8):
    """blue, with its first ``band`` rows (the top of the image) red"""
    img = np.zeros((size, size, 3), np.uint8)
    img[:, :, 2] = 255
    img[:band] = (255, 0, 0)
    return img


def test_texture_first_row_is_at_v_0_as_in_cs184():
    """an image's first row lies at v = 0, where CS184 puts it: on a flat grid cloth
    (v = 0 along its j = 0 edge, at z = 0) seen from above, the red top band of the
    texture is drawn along the z = 0 edge, not along z = 1"""
    sim = Simulation.from_file(SCENES / "plane.json")
    bare = cloth_only(sim)
    cam = OrbitCamera(target=np.array([0.5, 1.0, 0.5]), azimuth=0, elevation=89, distance=2.0)
    r = Renderer(size=SIZE, texture=_top_band_image())
    img = render(r, bare, cam, shader="Texture", light=_light((0.5, 3.0, 0.5)))
    r.release()
    red = (img[:, :, 0] > 2 * img[:, :, 2] + 20) & foreground(img)
    blue = (img[:, :, 2] > 2 * img[:, :, 0] + 20) & foreground(img)
    assert 0.03 < red.sum() / (red.sum() + blue.sum()) < 0.3  # the band is an eighth of the image
    rows, cols = np.nonzero(red)
    red_centre = np.array([cols.mean(), rows.mean()])
    pos = bare.positions
    edge_v0 = _projected_centre(pos[np.isclose(pos[:, 2], 0.0)], cam, SIZE)
    edge_v1 = _projected_centre(pos[np.isclose(pos[:, 2], 1.0)], cam, SIZE)
    assert np.linalg.norm(red_centre - edge_v0) < 0.25 * np.linalg.norm(edge_v1 - edge_v0)


UNIT_FRAG = ("#version 330\nuniform sampler2D u_texture_{n};\nin vec2 v_uv;\nout vec4 out_color;\n"
             "void main() {{ out_color = vec4(texture(u_texture_{n}, v_uv).rgb, 1.0); }}\n")
CUBE_FRAG = ("#version 330\nuniform samplerCube u_texture_cubemap;\nout vec4 out_color;\n"
             "void main() { out_color = vec4(texture(u_texture_cubemap, vec3(0.3, 0.5, 0.8)).rgb, 1.0); }\n")
UNIT_COLORS = {1: (250, 20, 20), 2: (20, 250, 20), 3: (20, 20, 250), 4: (250, 250, 20), "cube": (20, 250, 250)}


def _solid(path, color, size=8):
    from PIL import Image

    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(np.full((size, size, 3), color, np.uint8)).save(path)


@pytest.fixture
def cs184_project(tmp_path):
    """CS184's layout: shaders/ (one shader per texture unit, one for the cube map)
    beside textures/ (texture_1..4.png, cube/posx..negz.png), each a solid colour"""
    shaders = tmp_path / "shaders"
    shaders.mkdir()
    for n in (1, 2, 3, 4):
        (shaders / f"Unit{n}.frag").write_text(UNIT_FRAG.format(n=n))
        _solid(tmp_path / "textures" / f"texture_{n}.png", UNIT_COLORS[n])
    (shaders / "Cube.frag").write_text(CUBE_FRAG)
    for face in assets.CUBE_FACES:
        _solid(tmp_path / "textures" / "cube" / f"{face}.png", UNIT_COLORS["cube"])
    return tmp_path


def _cli_image(tmp_path, *argv):
    import subprocess
    import sys

    from PIL import Image

    out = tmp_path / "out.png"
    run = subprocess.run([sys.executable, "-m", "clothsim", "render", str(SCENES / "plane.json"), "-o", str(out),
                          "--overwrite", "--seconds", "0.02", "--size", "64x64", *map(str, argv)],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0 and "Traceback" not in run.stderr, run.stderr
    img = np.asarray(Image.open(out))
    inside = interior(foreground(img))
    assert inside.sum() > 200
    return img[inside].mean(axis=0)


@pytest.mark.parametrize("unit", [1, 2, 3, 4, "cube"])
def test_textures_folder_beside_the_shaders_feeds_every_unit(cs184_project, unit):
    """as CS184 does, textures/ beside --shaders DIR loads texture_N.png into u_texture_N
    and cube/ as the cube map (each unit's shader draws that unit's colour)"""
    name = "Cube" if unit == "cube" else f"Unit{unit}"
    seen = _cli_image(cs184_project, "--shaders", cs184_project / "shaders", "--shader", name)
    np.testing.assert_allclose(seen, UNIT_COLORS[unit], atol=3)


def test_texture_options_win_over_the_folder_and_keep_their_aliases(cs184_project, tmp_path):
    """--texture-N (and --texture, --height-map for units 1 and 2) and --textures DIR"""
    _solid(tmp_path / "grey.png", (128, 128, 128))
    _solid(tmp_path / "pink.png", (250, 120, 200))
    shaders = ("--shaders", cs184_project / "shaders")
    np.testing.assert_allclose(_cli_image(tmp_path, *shaders, "--shader", "Unit3", "--texture-3", tmp_path / "grey.png"),
                               (128, 128, 128), atol=3)
    np.testing.assert_allclose(_cli_image(tmp_path, *shaders, "--shader", "Unit1", "--texture", tmp_path / "pink.png"),
                               (250, 120, 200), atol=3)
    np.testing.assert_allclose(_cli_image(tmp_path, *shaders, "--shader", "Unit2", "--height-map",
                                          tmp_path / "grey.png"), (128, 128, 128), atol=3)
    elsewhere = tmp_path / "elsewhere"
    (cs184_project / "shaders").rename(elsewhere)  # no textures/ beside it now: --textures names it
    np.testing.assert_allclose(_cli_image(tmp_path, "--shaders", elsewhere, "--shader", "Unit4",
                                          "--textures", cs184_project / "textures"), UNIT_COLORS[4], atol=3)


def test_cs184_look_white_cloth_by_itself_with_a_shader_folder(tmp_path):
    """--cs184 (and, by itself, --shaders DIR) draws CS184's white cloth; without it
    ours is red; --no-cs184 and --color win"""
    (tmp_path / "Extra.frag").write_text(TINT_FRAG.replace("v_tint", "v_normal"))
    red = _cli_image(tmp_path, "--shader", "Diffuse")
    assert red[0] > 1.5 * red[1]
    for argv in (["--cs184"], ["--shaders", tmp_path]):
        white = _cli_image(tmp_path, "--shader", "Diffuse", *argv)
        assert white.max() < 1.1 * white.min() and white[1] > 1.3 * red[1], (argv, white, red)
    again = _cli_image(tmp_path, "--shader", "Diffuse", "--shaders", tmp_path, "--no-cs184")
    np.testing.assert_allclose(again, red, atol=2)
    green = _cli_image(tmp_path, "--shader", "Diffuse", "--cs184", "--color", "0,1,0")
    assert green[1] > 1.5 * green[0]


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


def test_cli_unknown_shader_is_refused_before_the_scene_is_loaded(tmp_path, capsys, monkeypatch):
    """an unknown --shader name is one line and exit 2 without loading (or compiling) anything"""
    import clothsim.cli.render as render_cli

    def no_load(args):
        raise AssertionError("the scene was loaded before the shader name was checked")

    monkeypatch.setattr(render_cli, "load_simulation", no_load)
    code = main(["render", str(SCENES / "pinned2.json"), "-o", str(tmp_path / "x.png"), "--shader", "NoSuch"])
    err = capsys.readouterr().err
    assert code == 2 and "unknown shader 'NoSuch'" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x.png").exists()


SKELETON_VERT = "#version 330\nuniform mat4 u_view_projection;\nin vec4 in_position;\nvoid main() { }\n"
EMPTY_VERT = "#version 330\nvoid main() { }\n"
EMPTY_FRAG = "#version 330\nout vec4 out_color;\nvoid main() { }\n"


@pytest.mark.parametrize("vert", [EMPTY_VERT, SKELETON_VERT], ids=["no-attributes", "unused-attribute"])
def test_a_shader_that_reads_no_attributes_draws_nothing(tmp_path, draped, vert):
    """the course skeleton (an empty main(), which compiles; its declared inputs
    unused, so the linker drops them) draws nothing, cloth, wireframe and colliders,
    instead of failing in moderngl"""
    (tmp_path / "Default.vert").write_text(vert)
    (tmp_path / "Skeleton.frag").write_text(EMPTY_FRAG)
    (tmp_path / "Wireframe.frag").write_text(EMPTY_FRAG)  # pairs with the user's Default.vert
    r = Renderer(size=SIZE, shaders=ShaderLibrary([tmp_path]))
    for name in ("Skeleton", "Wireframe"):
        img = render(r, draped, shader=name)
        assert not foreground(img).any(), name  # the background alone
    r.release()


def test_cli_skeleton_shader_exits_0(tmp_path):
    """clothsim render with the skeleton shaders writes an image of the background, exit 0"""
    import subprocess
    import sys

    from PIL import Image

    (tmp_path / "Default.vert").write_text(EMPTY_VERT)
    (tmp_path / "Skeleton.frag").write_text(EMPTY_FRAG)
    out = tmp_path / "x.png"
    run = subprocess.run([sys.executable, "-m", "clothsim", "render", str(SCENES / "sphere.json"), "-o", str(out),
                          "--seconds", "0.02", "--size", "64x64", "--shaders", str(tmp_path), "--shader", "Skeleton"],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0 and "Traceback" not in run.stderr, run.stderr
    assert not foreground(np.asarray(Image.open(out))).any()


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


# ---------------------------------------------------------------- meshes and several cloths


def _flat_mesh(seed=3):
    """an irregular flat mesh in a tilted plane, uvs an affine map of its
    in-plane coordinates: its true dP/du is known"""
    from scipy.spatial import Delaunay

    rng = np.random.default_rng(seed)
    st = np.concatenate([rng.uniform(0, 1, (60, 2)), [[0, 0], [1, 0], [0, 1], [1, 1]]])
    tri = Delaunay(st).simplices.astype(np.int32)
    e1, e2 = np.array([0.8, 0.3, 0.1]), np.array([-0.2, 0.5, 0.9])
    pos = np.array([0.1, 0.2, 0.3]) + st[:, :1] * e1 + st[:, 1:] * e2
    a = np.array([[0.6, 0.5], [-0.4, 0.7]])  # uv = a @ (s, t) + b
    uvs = st @ a.T + np.array([0.1, 0.2])
    n = np.cross(e1, e2)
    return pos, tri, uvs, np.tile(n / np.linalg.norm(n), (len(pos), 1)), e1, e2, a


def test_uv_tangents_follow_u_on_an_irregular_mesh():
    """on a flat irregular mesh with an affine uv map every vertex's tangent is
    the unit dP/du of that map (exact to rounding), perpendicular to the normal"""
    from clothsim.render.tangents import UvTangents

    pos, tri, uvs, normals, e1, e2, a = _flat_mesh()
    inv = np.linalg.inv(a)  # (s, t) = inv @ (uv - b): dP/du = e1 inv[0, 0] + e2 inv[1, 0]
    expected = e1 * inv[0, 0] + e2 * inv[1, 0]
    expected /= np.linalg.norm(expected)
    t = UvTangents(uvs, tri)(pos, normals)
    np.testing.assert_allclose(t, np.tile(expected, (len(pos), 1)), atol=1e-12)
    # a mirrored map (u -> 1 - u) turns the tangent round
    mirrored = uvs * [-1.0, 1.0] + [1.0, 0.0]
    np.testing.assert_allclose(UvTangents(mirrored, tri)(pos, normals), -t, atol=1e-12)


def test_uv_tangents_orthogonal_to_a_bent_normal_and_degenerate_fallback():
    """a tangent is made perpendicular to its vertex normal; a vertex whose
    triangles all have degenerate uvs gets the shaders' fallback n x (1, 0, 0)
    (|n_y| >= 0.9), one whose triangles are partly degenerate the others' tangent"""
    from clothsim.render.tangents import UvTangents, perpendicular

    pos = np.array([[0, 0, 0], [1, 0, 0], [0, 0, 1], [1, 0, 1], [2, 0, 0]], float)
    tri = np.array([[0, 2, 1], [1, 2, 3], [1, 3, 4]], np.int32)
    uvs = np.array([[0, 0], [1, 0], [0, 1], [1, 1], [1, 0]], np.float32)  # the last triangle: collinear uvs
    normals = np.tile([0.0, 1.0, 0.0], (5, 1))
    normals[0] = [0.6, 0.8, 0.0]  # a tilted normal at vertex 0
    t = UvTangents(uvs, tri)
    assert t.degenerate == 1
    out = t(pos, normals)
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0)
    np.testing.assert_allclose(np.sum(out * normals, axis=1), 0.0, atol=1e-15)
    np.testing.assert_allclose(out[0], [0.8, -0.6, 0.0], atol=1e-15)  # +x, made perpendicular
    np.testing.assert_allclose(out[1:4], np.tile([1.0, 0.0, 0.0], (3, 1)), atol=1e-15)
    np.testing.assert_allclose(out[4], [0.0, 0.0, -1.0])  # only the degenerate triangle: y x x = -z
    np.testing.assert_allclose(perpendicular([[1.0, 0.0, 0.0]]), [[0.0, 0.0, 1.0]])  # x x y = z
    flat = UvTangents(np.zeros((5, 2)), tri)(pos, normals)  # every uv the same point
    np.testing.assert_allclose(flat[1:], np.tile([0.0, 0.0, -1.0], (4, 1)))


def test_grid_tangents_run_along_the_width():
    """the plane scene's flat grid: every tangent is +x, as the width index grows"""
    from clothsim.render.scene_view import cloth_tangents

    sim = Simulation.from_file(SCENES / "plane.json")
    np.testing.assert_allclose(cloth_tangents(sim)(sim.positions, sim.normals),
                               np.tile([1.0, 0.0, 0.0], (sim.model.num_points, 1)), atol=1e-12)


def _blobs(mask):
    from scipy import ndimage

    labels, count = ndimage.label(mask)
    sizes = ndimage.sum(mask, labels, range(1, count + 1))
    keep = [k + 1 for k in np.flatnonzero(sizes > 20)]
    return labels, keep


def _projected_centre(points, camera, size):
    from clothsim.viewer.picking import project

    px, _ = project(points, camera.view_projection(size[0] / size[1]), size)
    return px.mean(axis=0)


def test_two_cloths_are_two_blobs_where_they_hang(renderer):
    """a scene of two grid cloths (one above, one hanging below) renders with
    Phong as two separate blobs, each round the projection of its own cloth's
    centre and in its own colour: the first in the cloth colour (red), the
    second a hue turned from it (green over red)"""
    from clothsim.scene import parse_scene

    from .handmade import two_cloth_scene

    sim = Simulation(parse_scene(two_cloth_scene(), "two"))
    cam = default_camera(sim, fixed=False)
    img = render(renderer, sim, cam, shader="Phong")
    fg = foreground(img)
    labels, blobs = _blobs(fg)
    assert len(blobs) == 2
    assert not fg[0].any() and not fg[-1].any() and not fg[:, 0].any() and not fg[:, -1].any()
    for cloth in sim.cloths:
        cx, cy = _projected_centre(cloth.positions, cam, SIZE)
        assert labels[round(cy), round(cx)] in blobs
    ids = [labels[round(c[1]), round(c[0])]
           for c in (_projected_centre(cl.positions, cam, SIZE) for cl in sim.cloths)]
    assert ids[0] != ids[1]
    first, second = (img[labels == k].astype(int) for k in ids)
    assert (first[:, 0] > first[:, 1] + 20).mean() > 0.95  # the cloth colour: red over green
    assert (second[:, 1] > second[:, 0] + 20).mean() > 0.95  # the next cloth's: green over red


@pytest.mark.parametrize("name", ORDER)
def test_every_shader_draws_a_mesh_cloth(renderer, name):
    """each built-in shader draws a model of a Delaunay disc (no grid) beside a
    grid cloth: two blobs, each over its cloth's projected centre, no pixel of
    the disc's interior black (NaN tangents or normals would leave them so)"""
    from .handmade import disc_and_grid, simulation_of

    sim = simulation_of(disc_and_grid())
    cam = default_camera(sim, fixed=False)
    img = render(renderer, sim, cam, shader=name)
    fg = foreground(img)
    labels, blobs = _blobs(fg)
    assert not fg[0].any() and not fg[-1].any() and not fg[:, 0].any() and not fg[:, -1].any()
    centres = [_projected_centre(c.positions, cam, SIZE) for c in sim.cloths]
    if name == "Wireframe":  # lines: fragments of cloth round each centre
        for cx, cy in centres:
            assert fg[int(cy) - 6:int(cy) + 7, int(cx) - 6:int(cx) + 7].sum() > 10
        return
    assert len(blobs) == 2
    disc = labels == labels[round(centres[0][1]), round(centres[0][0])]
    assert disc.sum() > 300
    assert (img[interior(disc)].astype(int).sum(axis=1) > 30).all()


def test_bump_and_displacement_work_on_a_mesh(renderer):
    """on the disc the bumps show (Bump differs from Phong inside, same outline)
    and Displacement moves the outline, as on a grid"""
    from .handmade import disc_model, simulation_of

    sim = simulation_of(disc_model())
    cam = OrbitCamera(target=np.array([0.5, 1.0, 0.5]), azimuth=20, elevation=50, distance=2.2)
    phong = render(renderer, sim, cam, shader="Phong")
    bump = render(renderer, sim, cam, shader="Bump", height_scaling=0.05)
    disp = render(renderer, sim, cam, shader="Displacement", height_scaling=0.05)
    inside = interior(foreground(phong))
    assert np.array_equal(foreground(bump), foreground(phong))
    assert np.abs(bump[inside].astype(int) - phong[inside]).sum(axis=1).mean() > 3
    assert (foreground(disp) != foreground(phong)).sum() > 30


def test_phong_disc_from_above_is_round(renderer):
    """the Phong image of the disc seen from straight above is a circle: it
    fills pi/4 of its bounding square (a square cloth fills all of it)"""
    from .handmade import disc_model, simulation_of

    sim = simulation_of(disc_model())
    cam = OrbitCamera(target=np.array([0.5, 1.0, 0.5]), azimuth=0, elevation=89.9, distance=2.5)
    fg = foreground(render(renderer, sim, cam, shader="Phong"))
    rows, cols = np.flatnonzero(fg.any(axis=1)), np.flatnonzero(fg.any(axis=0))
    h, w = rows[-1] - rows[0] + 1, cols[-1] - cols[0] + 1
    assert abs(h - w) <= 2 and h > 60
    assert fg.sum() / (h * w) == pytest.approx(np.pi / 4, abs=0.04)


def test_wireframe_of_several_cloths_follows_each_cloths_toggles():
    """the wireframe's lines are the springs that act, by their own cloth's
    material: turning shearing off in the second cloth drops its shearing
    springs only, and SimulationView rebuilds the lines on sync"""
    from clothsim.model import SHEARING
    from clothsim.render.scene_view import spring_lines
    from clothsim.scene import parse_scene
    from clothsim.spring_mask import spring_cloth

    from .handmade import two_cloth_scene

    sim = Simulation(parse_scene(two_cloth_scene(), "two"))
    m = sim.model
    assert len(spring_lines(sim)) == m.num_springs
    sim.cloths[1].params.enable_shearing = False
    lines = spring_lines(sim)
    owner = spring_cloth(m)
    dropped = (owner == 1) & (m.spring_kind == SHEARING)
    assert dropped.sum() == 2 * 11 * 7 and len(lines) == m.num_springs - dropped.sum()
    kept = {tuple(p) for p in lines.tolist()}
    assert all((a, b) not in kept for a, b in zip(m.spring_a[dropped], m.spring_b[dropped]))
    assert all((a, b) in kept for a, b in zip(m.spring_a[~dropped][:50], m.spring_b[~dropped][:50]))


def test_fixed_camera_keeps_the_rest_layout_in_view(renderer):
    """the reach-box camera (videos, sweeps) shows the whole cloth at rest, and
    so does the still camera of a flat cloth at rest (its bounding sphere alone
    left a corner out of the default oblique view)"""
    sim = Simulation.from_file(SCENES / "pinned2.json")
    for fixed in (True, False):
        fg = foreground(render(renderer, cloth_only(sim), default_camera(sim, fixed=fixed), shader="Normal"))
        assert fg.mean() > 0.05
        assert not fg[0].any() and not fg[-1].any() and not fg[:, 0].any() and not fg[:, -1].any()
