"""``clothsim view``: the interactive window, or a scripted run of it."""

from __future__ import annotations

import argparse

from ..errors import UsageError
from ..outputs import check_writable
from .common import add_scene_arg, add_simulation_args, load_simulation
from .render import add_look_arg, add_texture_args, apply_look, texture_assets
from .values import FRAMES_MAX, bounded_int, parse_size


def add_parser(sub) -> None:
    p = sub.add_parser("view", help="open the interactive viewer",
                       description="Simulate and draw a scene in a window, with a panel for every parameter.")
    add_scene_arg(p)
    add_simulation_args(p)
    p.add_argument("--shader", default="Phong", help="shader shown first (default Phong)")
    p.add_argument("--shaders", action="append", default=[], metavar="DIR",
                   help="folder of Name.vert/Name.frag files searched before the built-in ones")
    add_texture_args(p)
    add_look_arg(p)
    p.add_argument("--size", default="1280x800", help="window size WIDTHxHEIGHT (default 1280x800)")
    p.add_argument("--frames", type=bounded_int("--frames", 1, FRAMES_MAX), metavar="N",
                   help="scripted: run N frames, then exit")
    p.add_argument("--keys", default="", help='scripted: keys pressed before frames 1, 2, ... e.g. "p,n,r"')
    p.add_argument("--screenshot", metavar="OUT.png", help="scripted: save the last frame, panel included")
    p.add_argument("--overwrite", action="store_true", help="replace an existing screenshot file")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..render.shaders import ShaderLibrary
    from ..viewer.app import KEY_NAMES, ViewerApp, require_display

    keys = [k.strip().lower() for k in args.keys.split(",") if k.strip()]
    for k in keys:
        if k not in KEY_NAMES:
            raise UsageError(f"--keys: unknown key {k!r}; expected one of {', '.join(KEY_NAMES)}")
    if args.frames is not None and args.frames < 1:
        raise UsageError(f"--frames: expected at least 1, got {args.frames}")
    if (args.keys or args.screenshot) and args.frames is None:
        raise UsageError("--keys and --screenshot need --frames N (scripted mode)")
    if args.screenshot:
        check_writable(args.screenshot, args.overwrite)
    size = parse_size(args.size)
    require_display()
    sim = load_simulation(args)
    library = ShaderLibrary(args.shaders)
    if args.shader not in library.names():
        raise UsageError(f"--shader: unknown shader {args.shader!r}; available: {', '.join(library.names())}")
    units, cube = texture_assets(args)
    app = ViewerApp(sim, size=size, shaders=library, shader=args.shader, textures=units, cubemap=cube)
    apply_look(args, app.settings)
    try:
        if args.frames is None:
            app.run()
        else:
            app.run_script(args.frames, keys, args.screenshot)
            print(f"{args.frames} frames, t = {app.sim.time:.2f} s" +
                  (f"; wrote {args.screenshot}" if args.screenshot else ""))
    finally:
        if args.frames is not None:
            app.close()
    return 0
