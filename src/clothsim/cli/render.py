"""``clothsim render``: simulate, then draw the final frame, a contact sheet or the whole animation."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from ..errors import UsageError
from ..outputs import check_writable
from ..render.media import IMAGE_SUFFIXES, VIDEO_SUFFIXES
from .common import (add_scene_args, check_seconds, load_simulation, make_recorder, parse_floats, parse_size,
                     progress_bar, run_with_progress, summary)


def add_parser(sub) -> None:
    p = sub.add_parser("render", help="simulate and render an image, a contact sheet or a video",
                       description="Simulate a scene headless and render the final frame (PNG), or the "
                                   "animation (MP4/GIF), with a GLSL shader.")
    add_scene_args(p, seconds=2.0)
    p.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="OUT.png for the last frame, OUT.mp4 or OUT.gif for the animation")
    p.add_argument("--shader", default="Phong", help="shader name, or 'all' for a contact sheet (default Phong)")
    p.add_argument("--shaders", action="append", default=[], metavar="DIR",
                   help="folder of Name.vert/Name.frag files searched before the built-in ones")
    p.add_argument("--size", default="800x800", help="image size WIDTHxHEIGHT (default 800x800)")
    p.add_argument("--color", default=None, metavar="R,G,B", help="cloth colour, components in [0, 1]")
    p.add_argument("--normal-scaling", type=float, default=None, metavar="X")
    p.add_argument("--height-scaling", type=float, default=None, metavar="X")
    p.add_argument("--phong", default=None, metavar="KA,KD,KS,P", help="Blinn-Phong weights and shininess")
    p.add_argument("--camera", default=None, metavar="AZ,EL,DIST",
                   help="azimuth and elevation in degrees, distance in metres")
    p.add_argument("--light", default=None, metavar="X,Y,Z", help="light position (default 0.5,2,2)")
    p.add_argument("--light-intensity", default=None, metavar="R,G,B", help="(default 3,3,3)")
    p.add_argument("--sphere-res", default="40", metavar="N|LAT,LON", help="sphere tessellation (default 40)")
    p.add_argument("--texture", metavar="IMG", help="colour texture for the Texture shader")
    p.add_argument("--height-map", metavar="IMG", help="height map for Bump and Displacement")
    p.add_argument("--cubemap", metavar="DIR", help="folder with posx, negx, posy, negy, posz, negz images")
    p.add_argument("--fps", type=float, default=30.0, help="video frames per second (default 30)")
    p.set_defaults(func=run)


def settings_from_args(args: argparse.Namespace):
    """The renderer's draw settings and light from the options."""
    from ..render.camera import Light
    from ..render.renderer import DrawSettings

    s = DrawSettings(shader=args.shader)
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
    from ..render import assets
    from ..render.renderer import Renderer
    from ..render.shaders import ShaderLibrary

    return Renderer(
        size=parse_size(args.size), shaders=ShaderLibrary(args.shaders),
        texture=assets.read_image(args.texture, "texture") if args.texture else None,
        height_map=assets.read_image(args.height_map, "height map") if args.height_map else None,
        cubemap=assets.read_cubemap(args.cubemap) if args.cubemap else None)


def validate(args: argparse.Namespace) -> str:
    """Check every option before any work; return the output's suffix."""
    from ..render.geometry import parse_resolution

    suffix = Path(args.output).suffix.lower()
    if suffix not in VIDEO_SUFFIXES | IMAGE_SUFFIXES:
        raise UsageError(f"{args.output}: expected an output ending in .png, .jpg, .mp4 or .gif")
    if suffix in VIDEO_SUFFIXES and args.shader == "all":
        raise UsageError("--shader all makes a contact sheet image; use a .png output")
    check_seconds(args.seconds)
    if args.fps <= 0:
        raise UsageError(f"--fps: expected a number > 0, got {args.fps:g}")
    parse_size(args.size)
    try:
        args.sphere_res_pair = parse_resolution(args.sphere_res)
    except ValueError as exc:
        raise UsageError(f"--sphere-res: {exc}") from None
    return suffix


def run(args: argparse.Namespace) -> int:
    from ..render.media import save_image
    from ..render.scene_view import SimulationView, default_camera
    from ..render.sheet import contact_sheet

    suffix = validate(args)
    check_writable(args.output, args.overwrite)
    settings = settings_from_args(args)
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
    save_image(args.output, image)
    print(summary(sim, frames, wall) + f"; wrote {args.output}")
    return 0


def _render_video(args, sim, view, settings, cam, recorder) -> int:
    from ..render.media import write_animation

    every = max(1, int(round(sim.params.frames_per_sec / args.fps)))
    sim_frames = max(0, int(round(args.seconds * sim.params.frames_per_sec)))
    bar = progress_bar(sim_frames // every + 1, "frame", not args.no_progress, leave=False)
    start = time.perf_counter()
    try:
        shown = write_animation(args.output, sim, view, cam, settings, sim_frames, every,
                                on_frame=recorder if recorder.active else None,
                                on_drawn=lambda: bar.update(1))
    finally:
        bar.close()
    wall = time.perf_counter() - start
    print(f"{Path(sim.scene.source or args.scene).name}: {shown} video frames ({sim.time:.2f} s simulated) "
          f"in {wall:.2f} s wall, {1e3 * wall / shown:.1f} ms per frame; wrote {args.output}")
    return 0
