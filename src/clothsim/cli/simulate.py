"""``clothsim simulate``: run a scene headless, print a summary, optionally write an OBJ."""

from __future__ import annotations

import argparse

from ..outputs import check_writable
from .common import add_scene_args, load_simulation, make_recorder, run_with_progress, summary
from .values import check_seconds


def add_parser(sub) -> None:
    p = sub.add_parser("simulate", help="run a scene headless and export the cloth",
                       description="Run a scene headless; print a summary; optionally write an OBJ.")
    add_scene_args(p, seconds=2.0)
    p.add_argument("--export", metavar="OUT.obj", help="write the final cloth as a Wavefront OBJ")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    check_seconds(args.seconds)
    if args.export:
        check_writable(args.export, args.overwrite)
    sim = load_simulation(args)
    recorder = make_recorder(args, sim)
    frames, wall = run_with_progress(sim, args.seconds, not args.no_progress,
                                     recorder if recorder.active else None)
    recorder.finish(sim)
    if args.export:
        sim.export_obj(args.export, overwrite=args.overwrite)
    print(summary(sim, frames, wall) + (f"; wrote {args.export}" if args.export else ""))
    return 0
