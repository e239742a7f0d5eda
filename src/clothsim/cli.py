"""The ``clothsim`` command: parses arguments and wires the library together."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from . import __version__
from .errors import ClothsimError, UsageError
from .outputs import check_writable
from .simulation import Simulation


def _add_scene_args(p: argparse.ArgumentParser, seconds: float) -> None:
    p.add_argument("scene", help="scene file (CS184 ClothSim JSON)")
    p.add_argument("--seconds", type=float, default=seconds, metavar="S",
                   help=f"simulated time before the output (default {seconds:g})")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scene value by its dotted key, e.g. cloth.ks=500 (repeatable)")
    p.add_argument("--no-self-collision", action="store_true", help="turn self-collision off")
    p.add_argument("--overwrite", action="store_true", help="replace output files that already exist")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--export-sequence", metavar="DIR", help="write one OBJ per frame into DIR")
    p.add_argument("--export-npz", metavar="OUT.npz", help="write the whole trajectory as NumPy arrays")
    p.add_argument("--threads", type=_positive_int, default=None, metavar="N",
                   help="threads that share each substep (default: one below 5,000 points, "
                        "else all cores; NUMBA_NUM_THREADS caps them)")


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number of at least 1, not {text!r}")
    return value


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="clothsim", description="Mass-spring cloth simulator with GLSL rendering.")
    parser.add_argument("--version", action="version", version=f"clothsim {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("simulate", help="run a scene headless and export the cloth",
                       description="Run a scene headless; print a summary; optionally write an OBJ.")
    _add_scene_args(p, seconds=2.0)
    p.add_argument("--export", metavar="OUT.obj", help="write the final cloth as a Wavefront OBJ")
    p.set_defaults(func=cmd_simulate)
    from .render.cli import add_render_parser
    add_render_parser(sub, _add_scene_args)
    from .sweep.cli import add_sweep_parser
    add_sweep_parser(sub)
    from .viewer.cli import add_view_parser
    add_view_parser(sub)
    return parser


def load_simulation(args: argparse.Namespace) -> Simulation:
    sim = Simulation.from_file(args.scene, args.overrides, threads=args.threads)
    if args.no_self_collision:
        sim.params.self_collision = False
    return sim


def run_with_progress(sim: Simulation, seconds: float, show: bool, on_frame=None) -> tuple[int, float]:
    """Run ``seconds`` with a progress bar on a terminal; return (frames, wall seconds).

    The wall time leaves out loading the compiled kernels from numba's cache
    (about 0.3 s, or the first compile): counted in, it made a one-second
    run of a 50×50 cloth report a third of its speed.
    """
    from tqdm import tqdm

    frames = max(0, int(round(seconds * sim.params.frames_per_sec)))
    sim.step(substeps=0)  # loads (or compiles) the kernels; advances nothing
    bar = tqdm(total=frames, unit="frame", disable=not (show and sys.stderr.isatty()), leave=False)
    start = time.perf_counter()
    try:
        for _ in range(frames):
            sim.step()
            if on_frame is not None:
                on_frame(sim)
            bar.update(1)
    finally:
        bar.close()
    return frames, time.perf_counter() - start


def summary(sim: Simulation, frames: int, wall: float) -> str:
    substeps = frames * sim.params.simulation_steps
    rate = substeps / wall if wall > 0 else float("inf")
    return (f"{Path(sim.scene.source or 'scene').name}: {frames} frames ({sim.time:.2f} s simulated, "
            f"{sim.model.num_points} points, {sim.model.num_springs} springs) in {wall:.2f} s wall, "
            f"{rate:,.0f} substeps/s")


def make_recorder(args: argparse.Namespace, sim: Simulation):
    from .recording import FrameRecorder

    return FrameRecorder(sim, args.export_sequence, args.export_npz, args.overwrite)


def cmd_simulate(args: argparse.Namespace) -> int:
    if args.seconds < 0:
        raise UsageError(f"--seconds: expected a number >= 0, got {args.seconds:g}")
    if args.export:
        check_writable(args.export, args.overwrite)
    sim = load_simulation(args)
    recorder = make_recorder(args, sim)
    frames, wall = run_with_progress(sim, args.seconds, not args.no_progress,
                                     recorder if recorder.active else None)
    recorder.finish(sim)
    if args.export:
        sim.export_obj(args.export)
    print(summary(sim, frames, wall) + (f"; wrote {args.export}" if args.export else ""))
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except ClothsimError as exc:
        print(f"clothsim: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("clothsim: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
