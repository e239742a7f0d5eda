"""What the subcommands share: the scene options, value parsers, progress bar and summary.

Nothing here imports numba, numpy or a GL library at module level: the
parser of every subcommand is built on each call of ``clothsim``, and
``clothsim --help`` must answer at once.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

from .values import SECONDS_MAX, THREADS_MAX, bounded_float, frame_count, positive_int

if TYPE_CHECKING:
    from ..simulation import Simulation

SCENE_HELP = "scene file (CS184 ClothSim JSON), or the name of a standard scene (see 'clothsim scenes')"


# ---------------------------------------------------------------------------
# shared options


def add_scene_arg(p: argparse.ArgumentParser, set_help: str | None = None) -> None:
    """The scene (a file or a standard scene's name) and ``--set`` overrides."""
    p.add_argument("scene", help=SCENE_HELP)
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help=set_help or "override a scene value by its dotted key, e.g. cloth.ks=500 (repeatable)")
    p.add_argument("--strict", action="store_true",
                   help="refuse what the CS184 loader ignores (and clothsim otherwise ignores with a warning): "
                        "an unknown key inside cloth, sphere or plane, a pinned point outside the grid")


def add_simulation_args(p: argparse.ArgumentParser) -> None:
    """How the one simulation of a command runs: self-collision and threads."""
    p.add_argument("--no-self-collision", action="store_true", help="turn self-collision off")
    p.add_argument("--threads", type=positive_int, default=None, metavar="N",
                   help=f"threads that share each substep, 1..{THREADS_MAX} (default: one below 5,000 points, "
                        "else all cores; NUMBA_NUM_THREADS caps them)")


def add_run_args(p: argparse.ArgumentParser, seconds: float) -> None:
    """A headless run of ``--seconds``: outputs, overwriting, progress, per-frame exports."""
    p.add_argument("--seconds", type=bounded_float("--seconds", 0.0, SECONDS_MAX), default=seconds, metavar="S",
                   help=f"simulated time before the output (default {seconds:g})")
    p.add_argument("--overwrite", action="store_true", help="replace output files that already exist")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--export-sequence", metavar="DIR", help="write one OBJ per frame into DIR")
    p.add_argument("--export-npz", metavar="OUT.npz", help="write the whole trajectory as NumPy arrays")
    p.add_argument("--export-usd", metavar="OUT.usda|OUT.usdc|OUT.usd",
                   help="write the run as a time-sampled USD stage (cloth mesh with points and normals "
                        "at every frame, uvs, the colliders; metres, y up, played at the frame rate): "
                        ".usda text, .usdc or .usd binary; for Blender, Houdini, Omniverse, usdview")


def add_scene_args(p: argparse.ArgumentParser, seconds: float) -> None:
    """Everything ``simulate`` and ``render`` share."""
    add_scene_arg(p)
    add_simulation_args(p)
    add_run_args(p, seconds)


# ---------------------------------------------------------------------------
# from options to a running simulation


def scene_path(text: str) -> str:
    """The scene file the positional argument means: the path when it exists,
    else a standard scene of that bare name (``sphere``)."""
    from ..standard_scenes import find_scene

    return str(find_scene(text))


def load_simulation(args: argparse.Namespace) -> Simulation:
    """The simulation of ``args.scene`` with ``--set``, ``--threads`` and ``--no-self-collision``."""
    from ..scene import load_scene
    from ..simulation import Simulation
    from ..solver.cloth_solver import build_compiled

    check_exports(args)
    scene = load_scene(scene_path(args.scene), args.overrides, getattr(args, "strict", False))
    if getattr(args, "seconds", None) is not None:
        frame_count(args.seconds, scene.simulation.frames_per_sec)  # refuses a count beyond FRAMES_MAX now
    told = not build_compiled()
    if told:
        say_compiling()
    sim = Simulation(scene, threads=getattr(args, "threads", None))
    if getattr(args, "no_self_collision", False):
        sim.params.self_collision = False
    if not told and not sim.kernels_compiled:
        say_compiling()
    return sim


def check_exports(args: argparse.Namespace) -> None:
    """Fail before the scene is built (and the kernels compile) when an export
    cannot be written: ``--export``, ``--export-usd`` (its extension too),
    ``--export-npz`` (each: not there without ``--overwrite``, its folder there,
    a folder and writable) and ``--export-sequence`` (a writable folder, or one
    that can be made). :class:`~clothsim.recording.FrameRecorder` checks again."""
    from ..outputs import check_output_folder, check_writable

    overwrite = getattr(args, "overwrite", False)
    if getattr(args, "export_usd", None):
        from ..export.usd import check_usd_path

        check_usd_path(args.export_usd, overwrite)
    if getattr(args, "export_npz", None):
        check_writable(args.export_npz, overwrite)
    if getattr(args, "export", None):
        check_writable(args.export, overwrite)
    if getattr(args, "export_sequence", None):
        check_output_folder(args.export_sequence)


def say_compiling() -> None:
    """The one line that explains a silent first run: numba compiles the kernels."""
    print("clothsim: compiling the simulation kernels for this machine, once (10-60 s); "
          "later runs load them from the cache", file=sys.stderr, flush=True)


def make_recorder(args: argparse.Namespace, sim: Simulation):
    """The per-frame exporter of ``--export-sequence`` / ``--export-npz`` / ``--export-usd``
    (inactive without them)."""
    from ..recording import FrameRecorder

    return FrameRecorder(sim, args.export_sequence, args.export_npz, args.overwrite,
                         outputs={"usd": getattr(args, "export_usd", None)})


def progress_bar(total: int, unit: str, show: bool, **kwargs):
    """A tqdm bar on stderr, drawn only when ``show`` and stderr is a terminal."""
    from tqdm import tqdm

    return tqdm(total=total, unit=unit, disable=not (show and sys.stderr.isatty()), **kwargs)


def run_with_progress(sim: Simulation, seconds: float, show: bool, on_frame=None) -> tuple[int, float]:
    """Run ``seconds`` with a progress bar on a terminal; return (frames, wall seconds).

    The wall time leaves out loading the compiled kernels from numba's cache
    (or the first compile): counted in, it made a one-second run of a 50×50
    cloth report a third of its speed. Without ``on_frame`` the frames go
    :attr:`~clothsim.Simulation.frames_per_call` at a time
    (:meth:`~clothsim.Simulation.step_frames`), and the bar moves by as many.
    """
    frames = frame_count(seconds, sim.params.frames_per_sec)
    sim.step(substeps=0)  # loads (or compiles) the kernels; advances nothing
    bar = progress_bar(frames, "frame", show, leave=False)
    start = time.perf_counter()
    try:
        done = 0
        while done < frames:
            if on_frame is None:  # several frames a compiled call (Simulation.step_frames)
                many = min(frames - done, sim.frames_per_call)
                sim.step_frames(many)
            else:
                many = 1
                sim.step()
                on_frame(sim)
            bar.update(many)
            done += many
    finally:
        bar.close()
    return frames, time.perf_counter() - start


def summary(sim: Simulation, frames: int, wall: float) -> str:
    """One line: scene, frames, simulated time, size, wall time and substeps/s."""
    substeps = frames * sim.params.simulation_steps
    rate = substeps / wall if wall > 0 else float("inf")
    return (f"{Path(sim.scene.source or 'scene').name}: {frames} frames ({sim.time:.2f} s simulated, "
            f"{sim.model.num_points} points, {sim.model.num_springs} springs) in {wall:.2f} s wall, "
            f"{rate:,.0f} substeps/s")
