"""``clothsim render``: simulate, then draw the final frame, a contact sheet or the whole animation,
or write a web page that plays it."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from ..errors import UsageError
from ..outputs import check_writable, write_atomic
from ..render.media import IMAGE_SUFFIXES, VIDEO_SUFFIXES
from .common import add_scene_args, load_simulation, make_recorder, progress_bar, run_with_progress, summary
from .values import (LOOK_MAX, VIDEO_FPS_MAX, bounded_float, check_seconds, frame_count, parse_floats, parse_size,
                     parse_sphere_res)


def add_parser(sub) -> None:
    p = sub.add_parser("render", help="simulate and render an image, a contact sheet or a video",
                       description="Simulate a scene headless and render the final frame (PNG), or the "
                                   "animation (MP4/GIF), with a GLSL shader; or write the animation as one "
                                   "self-contained web page (HTML) to orbit, play and scrub in a browser.")
    add_scene_args(p, seconds=2.0)
    p.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="OUT.png for the last frame, OUT.mp4 or OUT.gif for the animation, "
                        "OUT.html for a web player of it (works offline, opened from disk)")
    p.add_argument("--shader", default="Phong", help="shader name, or 'all' for a contact sheet (default Phong)")
    p.add_argument("--shaders", action="append", default=[], metavar="DIR",
                   help="folder of Name.vert/Name.frag files searched before the built-in ones")
    p.add_argument("--size", default=None,
                   help="image size WIDTHxHEIGHT (default 800x800; for .html the player's size in CSS "
                        "pixels, default the browser window)")
    p.add_argument("--color", default=None, metavar="R,G,B", help="cloth colour, components in [0, 1]")
    p.add_argument("--normal-scaling", type=bounded_float("--normal-scaling", -LOOK_MAX, LOOK_MAX), default=None,
                   metavar="X")
    p.add_argument("--height-scaling", type=bounded_float("--height-scaling", -LOOK_MAX, LOOK_MAX), default=None,
                   metavar="X")
    p.add_argument("--phong", default=None, metavar="KA,KD,KS,P", help="Blinn-Phong weights and shininess")
    p.add_argument("--camera", default=None, metavar="AZ,EL,DIST",
                   help="azimuth and elevation in degrees, distance in metres")
    p.add_argument("--light", default=None, metavar="X,Y,Z", help="light position (default 0.5,2,2)")
    p.add_argument("--light-intensity", default=None, metavar="R,G,B", help="(default 3,3,3)")
    p.add_argument("--sphere-res", default="40", metavar="N|LAT,LON", help="sphere tessellation (default 40)")
    add_texture_args(p)
    add_look_arg(p)
    p.add_argument("--fps", type=bounded_float("--fps", 0.0, VIDEO_FPS_MAX, lo_open=True), default=30.0,
                   help=f"video frames per second, up to {VIDEO_FPS_MAX:g} (default 30)")
    p.set_defaults(func=run)


def add_texture_args(p: argparse.ArgumentParser) -> None:
    """The images of the texture units and the cube map (``render`` and ``view``)."""
    p.add_argument("--texture-1", "--texture", dest="texture_1", metavar="IMG",
                   help="u_texture_1, the colour texture of Texture (--texture is the same)")
    p.add_argument("--texture-2", "--height-map", dest="texture_2", metavar="IMG",
                   help="u_texture_2, the height map of Bump and Displacement (--height-map is the same)")
    p.add_argument("--texture-3", dest="texture_3", metavar="IMG", help="u_texture_3")
    p.add_argument("--texture-4", dest="texture_4", metavar="IMG", help="u_texture_4 (default: u_texture_1's image)")
    p.add_argument("--cubemap", metavar="DIR", help="folder with posx, negx, posy, negy, posz, negz images")
    p.add_argument("--textures", metavar="DIR",
                   help="CS184's textures folder: texture_1.png .. texture_4.png and cube/ (posx .. negz); "
                        "default: a textures/ folder beside (or inside) a --shaders DIR; "
                        "--texture-N and --cubemap win over it")


CS184_LOOK = {"color": (1.0, 1.0, 1.0), "normal_scaling": 2.0, "height_scaling": 0.1}
"""CS184's defaults, which a student's shader folder is tuned for"""


def add_look_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument("--cs184", action=argparse.BooleanOptionalAction, default=None,
                   help="CS184's look: white cloth, normal scaling 2, height scaling 0.1 (on by itself with "
                        "--shaders DIR, --no-cs184 turns it off; --color and the scalings win over it)")


def apply_look(args: argparse.Namespace, settings) -> None:
    """CS184's defaults on ``settings`` under ``--cs184``, or by themselves with ``--shaders``."""
    if args.cs184 or (args.cs184 is None and args.shaders):
        for name, value in CS184_LOOK.items():
            setattr(settings, name, value)


def texture_folder(args: argparse.Namespace) -> Path | None:
    """``--textures DIR``, else the first ``textures/`` folder beside a ``--shaders`` folder
    (CS184's layout: ``shaders/`` and ``textures/`` side by side) or inside one."""
    if args.textures:
        return Path(args.textures)
    for d in args.shaders:
        for candidate in (Path(d).resolve().parent / "textures", Path(d) / "textures"):
            if candidate.is_dir():
                return candidate
    return None


def texture_assets(args: argparse.Namespace) -> tuple[dict, dict | None]:
    """The images of the texture units (by number) and the cube map's faces the options ask for."""
    from ..render import assets

    units, cube = {}, None
    folder = texture_folder(args)
    if folder is not None:
        units, cube = assets.read_texture_folder(folder)
    for unit in assets.TEXTURE_UNITS:
        path = getattr(args, f"texture_{unit}")
        if path:
            units[unit] = assets.read_image(path, f"--texture-{unit}")
    if args.cubemap:
        cube = assets.read_cubemap(args.cubemap)
    return units, cube


def settings_from_args(args: argparse.Namespace):
    """The renderer's draw settings and light from the options."""
    from ..render.camera import Light
    from ..render.renderer import DrawSettings

    s = DrawSettings(shader=args.shader)
    apply_look(args, s)
    if args.color:
        s.color = parse_floats(args.color, 3, "--color")
    if args.normal_scaling is not None:
        s.normal_scaling = args.normal_scaling
    if args.height_scaling is not None:
        s.height_scaling = args.height_scaling
    if args.phong:
        s.ka, s.kd, s.ks, s.p = parse_floats(args.phong, 4, "--phong")
    light = Light()
    if args.light:
        light.position = parse_floats(args.light, 3, "--light")
    if args.light_intensity:
        light.intensity = parse_floats(args.light_intensity, 3, "--light-intensity")
    s.light = light
    return s


def make_renderer(args: argparse.Namespace):
    """An offscreen renderer of ``--size`` with the shader folders and image assets asked for."""
    from ..render.renderer import Renderer
    from ..render.shaders import ShaderLibrary

    library = ShaderLibrary(args.shaders)
    units, cube = texture_assets(args)
    return Renderer(size=parse_size(args.size or DEFAULT_SIZE), shaders=library, textures=units, cubemap=cube)


DEFAULT_SIZE = "800x800"
PLAYER_SUFFIXES = {".html", ".htm"}
PLAYER_REFUSES = (("shader", "--shader", "Phong"), ("shaders", "--shaders", []), ("texture_1", "--texture-1", None),
                  ("texture_2", "--texture-2", None), ("texture_3", "--texture-3", None),
                  ("texture_4", "--texture-4", None), ("textures", "--textures", None), ("cubemap", "--cubemap", None),
                  ("cs184", "--cs184", None),
                  ("normal_scaling", "--normal-scaling", None), ("height_scaling", "--height-scaling", None))
"""options of the GLSL renderer the web player has no use for: (dest, option, default)"""


def validate(args: argparse.Namespace) -> str:
    """Check every option before any work; return the output's suffix."""
    suffix = Path(args.output).suffix.lower()
    if suffix not in VIDEO_SUFFIXES | IMAGE_SUFFIXES | PLAYER_SUFFIXES:
        raise UsageError(f"{args.output}: expected an output ending in .png, .jpg, .mp4, .gif or .html")
    if suffix in PLAYER_SUFFIXES:
        for dest, option, default in PLAYER_REFUSES:
            if getattr(args, dest) != default:
                raise UsageError(f"{option}: not used by the web player (.html draws with its own Phong "
                                 "shading; it takes --color, --phong, --light, --light-intensity, --camera "
                                 "and --size)")
    if suffix in VIDEO_SUFFIXES and args.shader == "all":
        raise UsageError("--shader all makes a contact sheet image; use a .png output")
    check_seconds(args.seconds)
    parse_size(args.size or DEFAULT_SIZE)
    args.sphere_res_pair = parse_sphere_res(args.sphere_res)
    for text, count, option in ((args.color, 3, "--color"), (args.phong, 4, "--phong"),
                                (args.camera, 3, "--camera"), (args.light, 3, "--light"),
                                (args.light_intensity, 3, "--light-intensity")):
        if text:
            parse_floats(text, count, option)  # refused here, before the run, when not finite
    return suffix


def _check_shader_names(args: argparse.Namespace) -> None:
    """An unknown ``--shader`` (or one without a vertex shader to pair with) is refused
    here, from the folders' file names alone, before the scene is loaded and its
    kernels compiled; compile errors come once the renderer exists."""
    from ..render.shaders import ShaderLibrary

    library = ShaderLibrary(args.shaders)
    for name in library.names() if args.shader == "all" else [args.shader]:
        library.sources(name)


def run(args: argparse.Namespace) -> int:
    from ..render.media import save_image
    from ..render.scene_view import SimulationView, default_camera
    from ..render.sheet import contact_sheet

    suffix = validate(args)
    check_writable(args.output, args.overwrite)  # its folder too: exists, is a folder, takes a file
    if suffix in PLAYER_SUFFIXES:
        return _write_player(args)
    settings = settings_from_args(args)
    _check_shader_names(args)
    sim = load_simulation(args)
    renderer = make_renderer(args)
    names = renderer.library.names() if args.shader == "all" else [args.shader]
    for name in names:  # compile first: a broken shader fails before a long simulation
        renderer.program(name)
    view = SimulationView(renderer, sim, args.sphere_res_pair)
    recorder = make_recorder(args, sim)

    def camera(fixed: bool):
        cam = default_camera(sim, fixed=fixed)
        if args.camera:
            cam.azimuth, cam.elevation, cam.distance = parse_floats(args.camera, 3, "--camera")
        return cam

    if suffix in VIDEO_SUFFIXES:
        code = _render_video(args, sim, view, settings, camera(fixed=True), recorder)
        recorder.finish(sim)
        return code

    frames, wall = run_with_progress(sim, args.seconds, not args.no_progress,
                                     recorder if recorder.active else None)
    recorder.finish(sim)
    view.sync()
    cam = camera(fixed=False)
    images = []
    for name in names:
        settings.shader = name
        images.append(renderer.render(cam, settings))
    image = images[0] if len(images) == 1 else contact_sheet(images, names)
    save_image(args.output, image, overwrite=args.overwrite)
    print(summary(sim, frames, wall) + f"; wrote {args.output}")
    return 0


def player_look(args: argparse.Namespace) -> dict:
    """The keywords of :func:`clothsim.export.web.player_html` that the options ask for."""
    from ..render.camera import Light

    look: dict = {}
    if args.color:
        look["color"] = parse_floats(args.color, 3, "--color")
        if not all(0.0 <= c <= 1.0 for c in look["color"]):
            raise UsageError(f"--color: expected components in [0, 1], got {args.color!r}")
    if args.size:
        look["width"], look["height"] = parse_size(args.size)
    if args.camera:
        look["camera"] = parse_floats(args.camera, 3, "--camera")
    if args.phong:
        look["phong"] = parse_floats(args.phong, 4, "--phong")
        if min(look["phong"]) < 0:
            raise UsageError(f"--phong: expected numbers >= 0, got {args.phong!r}")
    if args.light or args.light_intensity:
        light = Light()
        if args.light:
            light.position = parse_floats(args.light, 3, "--light")
        if args.light_intensity:
            light.intensity = parse_floats(args.light_intensity, 3, "--light-intensity")
        look["light"] = light
    return look


def _write_player(args: argparse.Namespace) -> int:
    """Simulate, keeping every frame, then write the web player: no GL context."""
    from ..export.web import write_player
    from ..trajectory import TrajectoryRecorder

    look = player_look(args)
    sim = load_simulation(args)
    recorder = make_recorder(args, sim)
    frames = TrajectoryRecorder(sim)

    def on_frame(s) -> None:
        frames(s)
        if recorder.active:
            recorder(s)

    count, wall = run_with_progress(sim, args.seconds, not args.no_progress, on_frame)
    recorder.finish(sim)
    start = time.perf_counter()
    traj = frames.trajectory(sim)
    write_atomic(args.output, lambda tmp: write_player(tmp, traj, **look), args.overwrite)
    took = time.perf_counter() - start
    size = Path(args.output).stat().st_size
    print(summary(sim, count, wall) + f"; wrote {args.output} ({size / 1e6:.1f} MB in {took:.2f} s)")
    return 0


def _render_video(args, sim, view, settings, cam, recorder) -> int:
    from ..render.media import write_animation

    every = max(1, int(round(sim.params.frames_per_sec / args.fps)))
    sim_frames = frame_count(args.seconds, sim.params.frames_per_sec)
    bar = progress_bar(sim_frames // every + 1, "frame", not args.no_progress, leave=False)
    start = time.perf_counter()
    try:
        shown = write_animation(args.output, sim, view, cam, settings, sim_frames, every,
                                on_frame=recorder if recorder.active else None,
                                on_drawn=lambda: bar.update(1), overwrite=args.overwrite)
    finally:
        bar.close()
    wall = time.perf_counter() - start
    print(f"{Path(sim.scene.source or args.scene).name}: {shown} video frames ({sim.time:.2f} s simulated) "
          f"in {wall:.2f} s wall, {1e3 * wall / shown:.1f} ms per frame; wrote {args.output}")
    return 0
