"""``clothsim render``: simulate, then draw the final frame or the whole animation."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from ..errors import UsageError
from ..outputs import atomic_path, check_writable

VIDEO_SUFFIXES = {".mp4", ".gif"}
IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg"}


def _floats(text: str, count: int, what: str) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != count:
        raise UsageError(f"{what}: expected {count} comma-separated numbers, got {text!r}")
    return values


def _size(text: str) -> tuple[int, int]:
    parts = text.lower().split("x")
    if len(parts) != 2 or not all(p.isdigit() and 16 <= int(p) <= 8192 for p in parts):
        raise UsageError(f"--size: expected WIDTHxHEIGHT with each 16..8192, got {text!r}")
    return int(parts[0]), int(parts[1])


def add_render_parser(sub, add_scene_args) -> None:
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
    p.set_defaults(func=cmd_render)


def settings_from_args(args: argparse.Namespace):
    from .camera import Light
    from .renderer import DrawSettings

    s = DrawSettings(shader=args.shader)
    if args.color:
        s.color = _floats(args.color, 3, "--color")
    if args.normal_scaling is not None:
        s.normal_scaling = args.normal_scaling
    if args.height_scaling is not None:
        s.height_scaling = args.height_scaling
    if args.phong:
        s.ka, s.kd, s.ks, s.p = _floats(args.phong, 4, "--phong")
    light = Light()
    if args.light:
        light.position = _floats(args.light, 3, "--light")
    if args.light_intensity:
        light.intensity = _floats(args.light_intensity, 3, "--light-intensity")
    s.light = light
    return s


def make_renderer(args: argparse.Namespace):
    from . import assets
    from .renderer import Renderer
    from .shaders import ShaderLibrary

    return Renderer(
        size=_size(args.size), shaders=ShaderLibrary(args.shaders),
        texture=assets.read_image(args.texture, "texture") if args.texture else None,
        height_map=assets.read_image(args.height_map, "height map") if args.height_map else None,
        cubemap=assets.read_cubemap(args.cubemap) if args.cubemap else None)


def _validate(args: argparse.Namespace) -> str:
    from .geometry import parse_resolution

    suffix = Path(args.output).suffix.lower()
    if suffix not in VIDEO_SUFFIXES | IMAGE_SUFFIXES:
        raise UsageError(f"{args.output}: expected an output ending in .png, .jpg, .mp4 or .gif")
    if suffix in VIDEO_SUFFIXES and args.shader == "all":
        raise UsageError("--shader all makes a contact sheet image; use a .png output")
    if args.seconds < 0:
        raise UsageError(f"--seconds: expected a number >= 0, got {args.seconds:g}")
    if args.fps <= 0:
        raise UsageError(f"--fps: expected a number > 0, got {args.fps:g}")
    _size(args.size)
    try:
        args.sphere_res_pair = parse_resolution(args.sphere_res)
    except ValueError as exc:
        raise UsageError(f"--sphere-res: {exc}") from None
    return suffix


def cmd_render(args: argparse.Namespace) -> int:
    from ..cli import load_simulation, make_recorder, run_with_progress, summary
    from .scene_view import SimulationView, default_camera
    from .sheet import contact_sheet

    suffix = _validate(args)
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
            cam.azimuth, cam.elevation, cam.distance = _floats(args.camera, 3, "--camera")
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
    _save_image(args.output, image)
    print(summary(sim, frames, wall) + f"; wrote {args.output}")
    return 0


def _save_image(path: str, image: np.ndarray) -> None:
    from PIL import Image

    with atomic_path(path) as tmp:
        Image.fromarray(image).save(tmp, format="JPEG" if Path(path).suffix.lower() in {".jpg", ".jpeg"} else "PNG")


def _render_video(args, sim, view, settings, cam, recorder) -> int:
    import time

    import imageio.v2 as imageio
    from tqdm import tqdm

    every = max(1, int(round(sim.params.frames_per_sec / args.fps)))
    sim_frames = max(0, int(round(args.seconds * sim.params.frames_per_sec)))
    shown = sim_frames // every + 1
    bar = tqdm(total=shown, unit="frame", disable=args.no_progress or not sys.stderr.isatty(), leave=False)
    start = time.perf_counter()
    fps = sim.params.frames_per_sec / every
    kwargs = {"fps": fps, "macro_block_size": 1} if Path(args.output).suffix.lower() == ".mp4" \
        else {"duration": 1000.0 / fps, "loop": 0}
    with atomic_path(args.output) as tmp:
        writer = imageio.get_writer(tmp, **kwargs)
        try:
            view.sync()
            writer.append_data(view.renderer.render(cam, settings))
            bar.update(1)
            for frame in range(1, sim_frames + 1):
                sim.step()
                if recorder.active:
                    recorder(sim)
                if frame % every == 0:
                    view.sync()
                    writer.append_data(view.renderer.render(cam, settings))
                    bar.update(1)
        finally:
            writer.close()
            bar.close()
    wall = time.perf_counter() - start
    print(f"{Path(args.scene).name}: {shown} video frames ({sim.time:.2f} s simulated) in {wall:.2f} s wall, "
          f"{1e3 * wall / shown:.1f} ms per frame; wrote {args.output}")
    return 0
