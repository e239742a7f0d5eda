"""Where a threaded substep's time goes: each parallel region, and each part's work in it.

The stage benchmark (``bench_stages.py``) calls each stage on its own, from
Python; what two threads lose in a run also comes from how the stages meet:
a region's start and join, a part that waits for the slower one, the lines
one core wrote last and the other reads next. This one times them inside the
real run. It copies the ``clothsim`` package into a temporary folder,
inserts reads of the CPU's time-stamp counter (``llvm.readcyclecounter``)
around each parallel region of the grid path's substep and of
self-collision, and around each part's work inside it, and runs the first
``--seconds`` (2 by default) of ``--scene`` (``selfCollision`` by default:
then its whole fall and settle), resized to ``--size`` with its pins kept
at the corners, on each thread count of ``--threads``, in a process of its
own with a numba cache of its own (the copy compiles once; the user's cache
is not touched).

A ``"bench": "regions"`` line per stage and thread count gives µs per
substep averaged over the run (a build's stages spread over every
substep): ``region_us`` from before the region's start to after its join
(for stages that run on one thread, the stage), ``parts_us`` each part's
work in it, and ``half_of_one_thread_us`` the stage on one thread halved
(on the line of more threads than one). A ``"stage": "substep"`` line gives
the whole substep, substeps/s and the builds of the neighbour list. The
counter's rate is taken against the wall clock over half a second; it is
the same on every core of the machines here (``constant_tsc``).

    python benchmarks/bench_regions.py [--size 100] [--threads 1,2] [--seconds 2.0] [--scene selfCollision]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import clothsim

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import SCENES  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent

TIMER = '''"""reads of the time-stamp counter, summed into ACC (written by bench_regions.py)"""
import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic
from numba.np.numpy_support import carray

ACC = np.zeros((64, 32), dtype=np.uint64)
ACC_AT = ACC.ctypes.data


@intrinsic
def rdtsc(typingctx):
    def codegen(context, builder, signature, args):
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.IntType(64), []),
                                            "llvm.readcyclecounter")
        return builder.call(fn, [])
    return types.uint64(), codegen


@intrinsic
def _pointer(typingctx, at):
    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], cgutils.voidptr_t)
    return types.voidptr(at), codegen


@njit(inline="always")
def acc_view():
    return carray(_pointer(ACC_AT), (64, 32), np.uint64)
'''

STAGES = {
    # row of ACC: (stage, whether its parts are timed too)
    0: ("springs and Verlet", True),
    1: ("handles and wind (one thread)", False),
    10: ("self-collision: copy and drift test", False),
    11: ("self-collision: cell sort", True),
    12: ("self-collision: query", True),
    13: ("self-collision: slack labels", True),
    14: ("self-collision: slack sort", False),
    15: ("self-collision: copy after a build", False),
    16: ("self-collision: pushes", True),
    17: ("self-collision: pushes applied", True),
    4: ("colliders and Provot", True),
    5: ("Provot across the cuts (one thread)", False),
}
"""the row a stage's parts add into; its region's time is in row + 20 where it has parts"""

SUBSTEPS, BUILDS, SELF_COLLISION = 6, 9, 3


def _patch(text: str, edits: list[tuple[str, str]], name: str) -> str:
    """each (old, new) of ``edits`` once into ``text``, or a clear error naming the file"""
    for old, new in edits:
        if text.count(old) != 1:
            raise SystemExit(f"bench_regions.py: {name} no longer holds the line it times after:\n{old}")
        text = text.replace(old, new)
    return text


def _region(indent: str, row: int, head: str, body_first: str, body_last: str) -> list[tuple[str, str]]:
    """edits that time a prange region (head) in ACC row + 20 and each part's work in row"""
    inner = indent + "    "
    return [(indent + head + "\n" + inner + body_first,
             f"{indent}r0 = rdtsc()\n{indent}{head}\n{inner}s0 = rdtsc()\n{inner}{body_first}"),
            (inner + body_last,
             f"{inner}{body_last}\n{inner}acc[{row}, t * 8] += rdtsc() - s0\n{indent}acc[{row + 20}, 0] += rdtsc() - r0")]


def instrument(package: Path) -> None:
    """Insert the counter's reads into the copy of clothsim at ``package``."""
    (package / "solver" / "region_timer.py").write_text(TIMER)
    step = package / "solver" / "step.py"
    edits = [("from .selfcollide import self_collide",
              "from .selfcollide import self_collide\nfrom .region_timer import acc_view, rdtsc"),
             ("    while done < frames:\n", "    acc = acc_view()\n    while done < frames:\n"),
             *_region(" " * 12, 0, "for t in prange(parts):", "lo, hi = _part_span(n, parts, t, ahead)\n" + " " * 16
                      + "integrate(", "integrate(P, L, free, knobs, springs, F[t], max(lo - ahead, 0), hi, lo)"),
             ("            P, L = L, P  # the new positions were written over the last ones\n",
              "            P, L = L, P  # the new positions were written over the last ones\n            r1 = rdtsc()\n"),
             ("            if self_collision:\n                pairs, _ = self_collide(P, points, simulation_steps,"
              " lists, pairs)\n",
              "            acc[1, 0] += rdtsc() - r1\n            r1 = rdtsc()\n"
              "            if self_collision:\n                pairs, _ = self_collide(P, points, simulation_steps,"
              " lists, pairs)\n            acc[3, 0] += rdtsc() - r1\n"),
             *_region(" " * 12, 4, "for t in prange(parts):", "lo, hi = _part_span(n, parts, t, ahead)\n" + " " * 16
                      + "collide(", "provot(P, springs, enabled, masks[t], lo, hi, False)"),
             ("            for t in range(1, parts):\n                lo, _ = _part_span(n, parts, t, ahead)\n"
              "                provot(P, springs, enabled, masks[0], lo, lo, True)\n",
              "            r1 = rdtsc()\n            for t in range(1, parts):\n"
              "                lo, _ = _part_span(n, parts, t, ahead)\n"
              "                provot(P, springs, enabled, masks[0], lo, lo, True)\n"
              "            acc[5, 0] += rdtsc() - r1\n            acc[6, 0] += 1\n")]
    step.write_text(_patch(step.read_text(), edits, "solver/step.py"))
    collide = package / "solver" / "selfcollide" / "collide.py"
    edits = [("from .slack import checked_pairs, label_pairs, sort_by_slack",
              "from .slack import checked_pairs, label_pairs, sort_by_slack\n"
              "from ..region_timer import acc_view, rdtsc"),
             ("    worst = np.empty((parts, 2), dtype=np.int32)\n",
              "    acc = acc_view()\n    r1 = rdtsc()\n    worst = np.empty((parts, 2), dtype=np.int32)\n"),
             ("    fresh = not bound < skin\n",
              "    fresh = not bound < skin\n    acc[10, 0] += rdtsc() - r1\n    acc[9, 0] += 1 if fresh else 0\n"),
             *_region(" " * 8, 11, "for t in prange(copies):", "grid = sort_into_cells(", "grids[t, c] = grid[c]"),
             *_region(" " * 12, 12, "for t in prange(parts):", "own = np.int64(t)  # prange's index is unsigned: "
                      "with the 0, a float", "to_rows(P, rows, lo, hi)"),
             *_region(" " * 8, 13, "for t in prange(parts):", "own, segs = np.int64(t), segments.shape[0]",
                      "label_pairs(rows, reach, pairs, k0, k0 + segments[i, 1], labels, (SLACK_BUCKETS - 1) / span2)"),
             ("        pairs = sort_by_slack(pairs, labels, segments, meta, parts)\n",
              "        r1 = rdtsc()\n        pairs = sort_by_slack(pairs, labels, segments, meta, parts)\n"
              "        acc[14, 0] += rdtsc() - r1\n        r1 = rdtsc()\n"),
             ("        meta[REBUILDS] += 1\n", "        meta[REBUILDS] += 1\n        acc[15, 0] += rdtsc() - r1\n"),
             *_region(" " * 4, 16, "for t in prange(parts):", "own = np.int64(t)  # prange's index is unsigned: "
                      "with the 1 below, a float", "tally[t, 1] = h + pair_pushes(P, reach, pairs, sure, sure, "
                      "checked, lists, t, h, wide2)"),
             *_region(" " * 12, 17, "for t in prange(parts):", "lo, hi = part_range(n, parts, t)\n" + " " * 16
                      + "apply_pushes(", "apply_pushes(P, push, count, free, inv_steps, lo, hi)")]
    collide.write_text(_patch(collide.read_text(), edits, "solver/selfcollide/collide.py"))


def child(size: int, threads: list[int], seconds: float, name: str) -> None:
    """In the process with the instrumented copy first on the path: run and print."""
    import time

    from common import emit, machine, sized
    from numba import njit

    from clothsim import Simulation
    from clothsim.solver import region_timer

    @njit
    def now():
        return region_timer.rdtsc()

    now()
    c0, w0 = now(), time.perf_counter()
    time.sleep(0.5)
    ghz = (now() - c0) / (time.perf_counter() - w0) / 1e9
    info = {**machine(), "scene": name, "grid": f"{size}x{size}", "tsc_ghz": round(ghz, 3)}
    scene = ROOT / "scenes" / f"{name}.json"
    halves: dict = {}
    for t in threads:
        sim = Simulation.from_file(scene, sized(name, size), threads=t)
        sim.step(substeps=0)  # compiled before the timing
        frames = round(seconds * sim.params.frames_per_sec)
        region_timer.ACC[:] = 0
        start = time.perf_counter()
        sim.step_frames(frames)
        wall = time.perf_counter() - start
        acc = region_timer.ACC.astype(float)
        substeps = acc[SUBSTEPS, 0]
        us = 1e6 / (ghz * 1e9) / substeps  # µs per substep of a count of ticks

        def one(row: int) -> float:
            return round(float(acc[row, 0]) * us, 2)

        for row, (stage, parted) in STAGES.items():
            line = {"bench": "regions", "stage": stage, "threads": t,
                    "region_us": one(row + 20) if parted else one(row)}
            if parted:
                line["parts_us"] = [round(float(v) * us, 2) for v in acc[row, ::8][:sim.solver.parts]]
            if t == 1:
                halves[stage] = line["region_us"] / 2
            elif stage in halves:
                line["half_of_one_thread_us"] = round(halves[stage], 2)
            emit({**line, **info})
        emit({"bench": "regions", "stage": "substep", "threads": t, "parts": sim.solver.parts,
              "us_per_substep": round(1e6 * wall / substeps, 1), "substeps_per_s": round(substeps / wall),
              "self_collision_us": one(SELF_COLLISION), "builds": int(acc[BUILDS, 0]),
              "transposed": bool(sim.solver.transposed), **info})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=int, default=100)
    ap.add_argument("--threads", default="1,2", help="thread counts to run, in turn (default 1,2)")
    ap.add_argument("--seconds", type=float, default=2.0)
    ap.add_argument("--scene", default="selfCollision", choices=SCENES,
                    help="the standard scene to run (default selfCollision)")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    try:
        threads = [int(t) for t in args.threads.split(",")]
    except ValueError:
        ap.error(f"--threads: expected thread counts such as 1,2, got {args.threads!r}")
    if args.size < 2 or args.seconds <= 0 or min(threads) < 1:
        ap.error("--size must be 2 or more, --seconds more than 0 and every thread count 1 or more")
    if args.child:
        child(args.size, threads, args.seconds, args.scene)
        return
    with tempfile.TemporaryDirectory() as tmp:
        package = Path(tmp) / "clothsim"
        shutil.copytree(Path(clothsim.__file__).parent, package,
                        ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
        instrument(package)
        env = {**os.environ, "PYTHONPATH": os.pathsep.join([tmp, os.environ.get("PYTHONPATH", "")]),
               "NUMBA_CACHE_DIR": str(Path(tmp) / "numba-cache")}
        done = subprocess.run([sys.executable, __file__, "--child", "--size", str(args.size), "--threads",
                               args.threads, "--seconds", str(args.seconds), "--scene", args.scene], env=env)
    sys.exit(done.returncode)


if __name__ == "__main__":
    main()
