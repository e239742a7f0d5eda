"""``clothsim sweep``: every combination of scene values, simulated and rendered in parallel."""

from __future__ import annotations

import argparse
import os
import sys
import warnings

from ..errors import SceneWarning, UsageError
from .common import add_scene_arg, progress_bar, scene_path
from .values import SECONDS_MAX, THREADS_MAX, bounded_float, bounded_int, check_seconds, frame_count, parse_size


def add_parser(sub) -> None:
    p = sub.add_parser(
        "sweep", help="run every combination of scene values in parallel (locally or on Dask)",
        description="Simulate and render the cross product of --vary lists; write one PNG and OBJ per run, "
                    "runs.csv with measured results and a labelled sheet.png into OUTDIR.")
    add_scene_arg(p, set_help="a value shared by every run")
    p.add_argument("--vary", action="append", default=[], metavar="KEY=V1,V2|START:STOP:COUNT", required=True,
                   help="values of one dotted scene key (repeat for a cross product)")
    p.add_argument("--seconds", type=bounded_float("--seconds", 0.0, SECONDS_MAX), default=2.0,
                   help="simulated time per run (default 2)")
    p.add_argument("--shader", default="Phong", help="shader of the images (default Phong)")
    p.add_argument("--size", default="400x400", help="image size per run (default 400x400)")
    p.add_argument("-o", "--output", required=True, metavar="OUTDIR", help="output folder")
    p.add_argument("--workers", type=bounded_int("--workers", 1, THREADS_MAX), default=os.cpu_count() or 1,
                   help="local worker processes (default: the number of cores)")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                   help="send the runs to this Dask distributed scheduler instead")
    p.add_argument("--force", action="store_true", help="redo runs already in OUTDIR and replace their files")
    p.add_argument("--no-progress", action="store_true")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..outputs import check_output_folder
    from ..render.shaders import ShaderLibrary
    from ..scene import apply_overrides, parse_scene, read_scene_json
    from ..sweep.outdir import SweepDir
    from ..sweep.plan import plan_runs

    check_seconds(args.seconds)
    check_output_folder(args.output)
    if args.workers < 1:
        raise UsageError(f"--workers: expected at least 1, got {args.workers}")
    if args.shader not in ShaderLibrary().names():
        raise UsageError(f"--shader: unknown shader {args.shader!r}; available: {', '.join(ShaderLibrary().names())}")
    scene = scene_path(args.scene)
    data = read_scene_json(scene)
    specs = plan_runs(data, scene, args.vary, args.seconds, args.shader, parse_size(args.size),
                      tuple(args.overrides))
    # validate every combination up front: a typo in a key fails now, not in a worker;
    # what is ignored is said once, not once per run (the workers say nothing)
    with warnings.catch_warnings(record=True) as ignored:
        warnings.simplefilter("always", SceneWarning)
        for spec in specs:
            parsed = parse_scene(apply_overrides(data, spec.overrides, scene), scene, args.strict)
            frame_count(args.seconds, parsed.simulation.frames_per_sec)
    for text in dict.fromkeys(str(w.message) for w in ignored if issubclass(w.category, SceneWarning)):
        print(f"clothsim: warning: {text}", file=sys.stderr)
    out = SweepDir(args.output, args.force)
    with out.lock():  # one sweep at a time into a folder
        todo, done, failed, workers = _run(args, out, specs, scene)
    where = args.scheduler or f"{workers} local worker(s)"
    print(f"{len(specs)} runs ({len(todo)} run now on {where}, {len(done)} already done, {len(failed)} failed); "
          f"wrote {args.output}/runs.csv and {args.output}/sheet.png")
    # a run that failed before and is not redone (same settings) still failed
    failures = len(failed) + sum(1 for spec in done if (out.load_record(spec) or {}).get("error"))
    if failures:
        print(f"clothsim: {failures} of {len(specs)} runs failed (their errors are in {args.output}/runs.csv)",
              file=sys.stderr)
        return 1
    return 0


def _run(args: argparse.Namespace, out, specs: list, scene: str) -> tuple[list, list, list, int]:
    """Run what the folder does not hold yet, saving each run as it finishes; write the summary."""
    from ..sweep.runner import run_sweep

    todo, done = out.plan(specs)
    bar = progress_bar(len(specs), "run", not args.no_progress, initial=len(done))
    failed = []

    def on_result(result) -> None:
        out.save(result)
        if result.error:
            failed.append(result)
            bar.write(f"run {result.spec.name} failed: {result.error}")
        bar.update(1)

    workers = min(args.workers, max(1, len(todo)))
    try:
        run_sweep(todo, workers=workers, scheduler=args.scheduler, on_result=on_result)
    finally:
        bar.close()
    out.write_summary(specs, scene)
    return todo, done, failed, workers
