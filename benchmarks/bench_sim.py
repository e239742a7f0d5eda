"""Simulation throughput: substeps/s and point updates/s per standard scene and size.

Prints one JSON object per measurement. The figures are single-threaded;
``substeps_per_s_threads`` is the same run with the substep cut over numba's
thread count (``NUMBA_NUM_THREADS``, by default the machine's cores). The
cost of the springs (forces and the Provot pass) and of self-collision per
substep come from differences of runs with each switched off. Each figure is
the median of ``--repeats`` rounds of runs of the same stretch of simulated
time from the scene's start, after a warm-up that compiles the kernels; a
round runs every variant back to back, and the costs are the medians of each
round's differences, so a slow spell of the machine (they last seconds here)
falls on the runs compared alike.

Then ``"bench": "settle"`` lines time the whole two-second fall and settle of
``selfCollision`` at 100x100 (``--settle-sizes 100,200`` for more) on one
thread and on all, in rounds that run one then the other, each line the best
of its rounds and the threaded one with each round's ratio and the round
trip of a cache line between the first two CPUs before and after the round
(``core_round_trip_ns``, from ``core_trip.c``, built with the C compiler on
PATH): the short stretches above end before the cloth piles up, which is
when self-collision costs most.

Last, ``"bench": "general_path"`` lines compare the solver's two paths at the
same point count (``--mesh-points``, 10,000 by default), self-collision on,
in ``sphere`` (a horizontal sheet dropped on the sphere) and
``selfCollision`` (a vertical sheet folding onto the floor): the n x n grid
on the grid path, the same grid on the general path, and an irregular
triangle mesh of as many points (:func:`clothsim.procedural.delaunay_square`,
1 m square) on the general path, one thread and all. The runs interleave,
each of ``--repeats`` rounds running every one once, and each figure is the
best of its rounds: the ratios are taken side by side.

``--against-soa [SOURCE]`` times clothsim against the C yardstick instead:
it compiles ``soa.c`` (by default the one in the ``shared/bench`` folder
beside this checkout) with ``cc -O3 -march=native``, then runs rounds, each
timing ``soa 50 300 3000 list`` once and every 50x50 scene once with
self-collision on and once with it off, one thread. A ``"bench": "soa"``
line per scene gives the best of the rounds of each and the ratios to
``soa list``, side by side: ten times the course code with self-collision
on is about 3x ``soa list``, six times its springs-only path about 5x (the
yardstick's README has how the course code compared on each kind of machine).

    python benchmarks/bench_sim.py [--sizes 50,100,200] [--scenes pinned2,sphere] [--repeats 3]
                                   [--no-settle | --settle-sizes 100,200]
                                   [--no-mesh] [--mesh-only] [--mesh-points 10000]
    python benchmarks/bench_sim.py --against-soa [path/to/soa.c] [--scenes ...] [--repeats 5]
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numba

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import SCENES, emit, machine, peak_rss_mib, sized  # noqa: E402
from core_trip import CoreTrip  # noqa: E402

from clothsim import Simulation  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
SECONDS = {50: 1.0, 100: 0.4, 200: 0.1}
SETTLE_SECONDS = 2.0


def run_once(scene: str, n: int, seconds: float, self_collision: bool = True, springs: bool = True,
             threads: int = 1) -> tuple[float, float]:
    """(substeps/s, neighbour-list rebuilds per 100 substeps) of one run from the scene's start"""
    sim = Simulation.from_file(ROOT / "scenes" / f"{scene}.json", sized(scene, n), threads=threads)
    sim.params.self_collision = self_collision and sim.params.self_collision
    if not springs:
        sim.params.enable_structural = sim.params.enable_shearing = sim.params.enable_bending = False
    frames = max(1, round(seconds * sim.params.frames_per_sec))
    start = time.perf_counter()
    advance(sim, frames)
    substeps = frames * sim.params.simulation_steps
    return substeps / (time.perf_counter() - start), 100.0 * sim.neighbour_list_rebuilds / substeps


FRAME_BY_FRAME = False
"""``--frame-by-frame``: each run calls ``Simulation.step`` once a frame (one
compiled call a frame, as the viewer steps), where by default it calls
``step_frames`` for the whole run, as ``Simulation.run`` and ``clothsim
simulate`` do: several frames to a compiled call"""


def advance(sim: Simulation, frames: int) -> None:
    """``frames`` frames of ``sim``, as FRAME_BY_FRAME says"""
    if FRAME_BY_FRAME:
        for _ in range(frames):
            sim.step()
    else:
        sim.step_frames(frames)


def measure(scene: str, n: int, seconds: float, self_collision: bool, repeats: int,
            springs: bool = True, threads: int = 1) -> tuple[float, float]:
    """(median substeps/s, neighbour-list rebuilds per 100 substeps)"""
    runs = [run_once(scene, n, seconds, self_collision, springs, threads) for _ in range(repeats)]
    return statistics.median(r for r, _ in runs), statistics.median(b for _, b in runs)


VARIANTS = {"with": {}, "without": {"self_collision": False},
            "bare": {"self_collision": False, "springs": False}}
"""the runs whose differences give the cost of self-collision (with - without) and
of the springs (without - bare)"""


def measure_rounds(scene: str, n: int, seconds: float, repeats: int, threads: int) -> dict:
    """Each round runs every variant once, then once cut over ``threads``, back to
    back, so a slow spell of the machine falls on all of them alike; the costs
    are medians of each round's differences."""
    rounds = []
    for _ in range(repeats):
        runs = {name: run_once(scene, n, seconds, **kw) for name, kw in VARIANTS.items()}
        runs["threads"] = run_once(scene, n, seconds, threads=threads)
        rounds.append(runs)
    us = [{name: 1e6 / rate for name, (rate, _) in runs.items()} for runs in rounds]
    median = statistics.median
    return {"with": median(r["with"][0] for r in rounds), "without": median(r["without"][0] for r in rounds),
            "threads": median(r["threads"][0] for r in rounds), "rebuilds": median(r["with"][1] for r in rounds),
            "springs_us": median(u["without"] - u["bare"] for u in us),
            "self_collision_us": median(u["with"] - u["without"] for u in us)}


MESH_SECONDS = {"sphere": 0.5, "selfCollision": 0.5}
"""simulated time of each general-path comparison run: past the first contact"""

MESH_PLACE = {"sphere": {"translate": [0.5, 1.0, 0.5]},
              "selfCollision": {"rotate": [-90, 0, 0], "translate": [0.5, 0.5, 0.0]}}
"""where the mesh (a 1 m square about the origin in the y=0 plane) goes to lie
where the scene's grid cloth starts"""


def settle(n: int, threads: int, repeats: int, info: dict) -> None:
    """The whole fall and settle of ``selfCollision`` at n x n on one thread and on
    ``threads``: each round runs one then the other, so a slow spell of the machine
    falls on both alike; the figures are the best of the rounds, and
    ``threads_over_one`` the ratio of the two in each round, with
    ``core_round_trip_ns`` the round trip of a line between CPUs 0 and 1 before
    and after each round (None where it cannot be measured): the threads gain
    only where that is short (docs/performance.md, "Two cores near and far")."""
    runs: dict[int, list[tuple[float, float]]] = {t: [] for t in sorted({1, threads})}
    trip, trips = CoreTrip(), []
    for _ in range(repeats):
        before = trip.probe()
        for t in runs:
            runs[t].append(run_once("selfCollision", n, SETTLE_SECONDS, threads=t))
        trips.append([before, trip.probe()])
    ratios = [round(a[0] / b[0], 3) for a, b in zip(runs[threads], runs[1])]
    for t, rounds in runs.items():
        rate = max(r for r, _ in rounds)
        record = {"bench": "settle", "scene": "selfCollision", "grid": f"{n}x{n}",
                  "simulated_s": SETTLE_SECONDS, "threads": t, "rounds": repeats,
                  "substeps_per_s": round(rate, 1),
                  "list_rebuilds_per_100_substeps": round(statistics.median(b for _, b in rounds), 1),
                  "realtime_factor": round(rate / 2700.0, 3)}
        if t != 1:
            record["threads_over_one"] = ratios
            # each round's placement of the first two CPUs, before and after it
            record["core_round_trip_ns"] = trips
        emit({**record, "peak_rss_mib": round(peak_rss_mib(), 1), **info})


def mesh_scene(scene: str, obj: Path, folder: Path) -> Path:
    """The standard scene with its grid cloth replaced by the mesh file ``obj``."""
    data = json.loads((ROOT / "scenes" / f"{scene}.json").read_text())
    grid = data["cloth"]
    data["cloth"] = {"mesh": str(obj), "transform": MESH_PLACE[scene], "thickness": grid["thickness"],
                     **{k: grid[k] for k in ("damping", "density", "ks") if k in grid}}
    path = folder / f"{scene}_mesh.json"
    path.write_text(json.dumps(data))
    return path


def timed(sim: Simulation, seconds: float) -> float:
    """substeps/s of ``seconds`` of simulated time, once its kernels are loaded"""
    sim.step(substeps=0)
    frames = max(1, round(seconds * sim.params.frames_per_sec))
    start = time.perf_counter()
    advance(sim, frames)
    return frames * sim.params.simulation_steps / (time.perf_counter() - start)


def general_path(points: int, repeats: int, info: dict) -> None:
    """The ``general_path`` lines: grid path, general path on the grid, general path on an
    irregular mesh, at the same point count, interleaved, best of ``repeats`` rounds."""
    from clothsim.procedural import delaunay_square, write_obj

    n = round(math.sqrt(points))
    threads = numba.get_num_threads()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        # spacing: the closest two points may come of a mesh this dense in a 1 m square
        mesh = delaunay_square(count=n * n, side=1.0, spacing=0.7 / n, seed=20)
        obj = write_obj(folder / "irregular.obj", mesh)
        for scene in MESH_SECONDS:
            runs = {"grid": lambda t: Simulation.from_file(ROOT / "scenes" / f"{scene}.json", sized(scene, n),
                                                           threads=t),
                    "grid_on_general_path": lambda t: Simulation.from_file(
                        ROOT / "scenes" / f"{scene}.json", sized(scene, n), threads=t, solver_path="mesh"),
                    "irregular_mesh": lambda t: Simulation.from_file(mesh_scene(scene, obj, folder), threads=t)}
            best: dict[tuple[str, int], float] = {}
            sizes = {}
            for _ in range(repeats):
                for name, make in runs.items():
                    for t in sorted({1, threads}):
                        sim = make(t)
                        sizes[name] = (sim.model.num_points, sim.model.num_springs, sim.solver.path)
                        rate = timed(sim, MESH_SECONDS[scene])
                        best[name, t] = max(best.get((name, t), 0.0), rate)
            grid = best["grid", 1]
            for name in runs:
                points_, springs, path = sizes[name]
                emit({"bench": "general_path", "scene": scene, "cloth": name, "solver_path": path,
                      "points": points_, "springs": springs, "simulated_s": MESH_SECONDS[scene],
                      "substeps_per_s": round(best[name, 1], 1), "of_grid_path": round(best[name, 1] / grid, 3),
                      "threads": threads, "substeps_per_s_threads": round(best[name, threads], 1),
                      "threads_gain": round(best[name, threads] / best[name, 1], 3), "rounds": repeats,
                      **info})


SOA_DEFAULT = ROOT.parent / "shared" / "bench" / "soa.c"
"""where the C yardstick's source lies beside a checkout of the project"""

SOA_ARGS = ["50", "300", "3000", "list"]
"""the yardstick's run: 50x50, 300 substeps of warm-up, 3,000 timed, the list variant"""

SOA_SECONDS = 1.0
"""simulated time of each clothsim run against it"""


def refuse(message: str) -> None:
    """One line on stderr and exit status 2, as the command line tools do."""
    print(f"bench_sim.py: --against-soa: {message}", file=sys.stderr)
    sys.exit(2)


def build_soa(source: Path, folder: Path) -> Path:
    """Compile the yardstick; exits 2 with one line when it cannot."""
    if not source.is_file():
        refuse(f"no C source at {source}")
    cc = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if cc is None:
        refuse("no C compiler (cc, gcc or clang) on PATH")
    exe = folder / "soa"
    done = subprocess.run([cc, "-O3", "-march=native", "-o", str(exe), str(source), "-lm"],
                          capture_output=True, text=True)
    if done.returncode != 0:
        first = (done.stderr.strip().splitlines() or ["no message"])[0]
        refuse(f"{source} did not compile: {first}")
    return exe


def run_soa(exe: Path) -> float:
    """substeps/s of one run of the yardstick"""
    out = subprocess.run([str(exe), *SOA_ARGS], capture_output=True, text=True, check=True).stdout
    return float(json.loads(out.strip().splitlines()[-1])["substeps_per_s"])


def against_soa(source: Path, scenes: list[str], repeats: int, info: dict) -> None:
    """The ``soa`` lines: every scene with and without self-collision against the
    yardstick, interleaved, best of ``repeats`` rounds."""
    with tempfile.TemporaryDirectory() as tmp:
        exe = build_soa(source, Path(tmp))  # a source it cannot build is refused before any work
        for scene in scenes:  # load every compiled variant before any is timed
            sim = Simulation.from_file(ROOT / "scenes" / f"{scene}.json", threads=1)
            sim.step(substeps=0)
            sim.params.self_collision = False
            sim.step(substeps=0)
        best = {"soa": 0.0}
        for r in range(repeats):
            best["soa"] = max(best["soa"], run_soa(exe))
            # alternate the order of the scenes so no scene always runs first in a round
            for scene in (scenes if r % 2 == 0 else scenes[::-1]):
                for self_collision in (True, False):
                    rate, _ = run_once(scene, 50, SOA_SECONDS, self_collision)
                    key = (scene, self_collision)
                    best[key] = max(best.get(key, 0.0), rate)
        soa = best["soa"]
        for scene in scenes:
            on, off = best[scene, True], best[scene, False]
            emit({"bench": "soa", "scene": scene, "grid": "50x50", "threads": 1, "rounds": repeats,
                  "soa_list_substeps_per_s": round(soa, 1), "substeps_per_s": round(on, 1),
                  "substeps_per_s_no_self_collision": round(off, 1),
                  "of_soa_list": round(on / soa, 3), "of_soa_list_no_self_collision": round(off / soa, 3),
                  "goal_of_soa_list": 3.0, "goal_of_soa_list_no_self_collision": 5.0, **info})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="50,100,200")
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--no-settle", action="store_true",
                    help="leave out the 2-second fall and settle of selfCollision 100x100")
    ap.add_argument("--settle-sizes", default="100",
                    help="grid sizes of the fall and settle, e.g. 100,200 (200x200 takes minutes)")
    ap.add_argument("--no-mesh", action="store_true", help="leave out the general path's comparison")
    ap.add_argument("--mesh-only", action="store_true", help="only the general path's comparison")
    ap.add_argument("--mesh-points", type=int, default=10000)
    ap.add_argument("--against-soa", nargs="?", const=str(SOA_DEFAULT), default=None, metavar="SOURCE",
                    help="time the 50x50 scenes against the C yardstick soa.c instead")
    ap.add_argument("--frame-by-frame", action="store_true",
                    help="one compiled call a frame (Simulation.step), not several (Simulation.step_frames)")
    args = ap.parse_args()
    global FRAME_BY_FRAME
    FRAME_BY_FRAME = args.frame_by_frame
    info = machine()
    info = {**info, "frames_a_call": "one" if FRAME_BY_FRAME else "step_frames"}
    if args.against_soa is not None:
        against_soa(Path(args.against_soa), args.scenes.split(","), args.repeats, info)
        return
    if args.mesh_only:
        general_path(args.mesh_points, args.repeats, info)
        return
    threads = numba.get_num_threads()
    # load every compiled variant the runs take (serial and threaded, per set of
    # collider kinds) before any is timed: loading one from the cache takes a
    # fraction of a second, which the first run of a scene would count
    for scene in args.scenes.split(","):
        for t in {1, threads}:
            Simulation.from_file(ROOT / "scenes" / f"{scene}.json", threads=t).step(substeps=0)
    for n in (int(s) for s in args.sizes.split(",")):
        for scene in args.scenes.split(","):
            seconds = SECONDS.get(n, 0.1)
            m = measure_rounds(scene, n, seconds, args.repeats, threads)
            with_self, without, split = m["with"], m["without"], m["threads"]
            emit({"bench": "simulate", "scene": scene, "points": n * n, "grid": f"{n}x{n}",
                  "simulated_s": seconds, "substeps_per_s": round(with_self, 1),
                  "point_updates_per_s": round(with_self * n * n),
                  "substeps_per_s_no_self_collision": round(without, 1),
                  "threads": threads, "substeps_per_s_threads": round(split, 1),
                  "springs_us_per_substep": round(m["springs_us"], 1),
                  "self_collision_us_per_substep": round(m["self_collision_us"], 1),
                  "list_rebuilds_per_100_substeps": round(m["rebuilds"], 1),
                  "realtime_factor": round(with_self / 2700.0, 3),
                  "realtime_factor_threads": round(split / 2700.0, 3),
                  "peak_rss_mib": round(peak_rss_mib(), 1), **info})
    if "selfCollision" in args.scenes.split(",") and not args.no_settle:
        for n in (int(s) for s in args.settle_sizes.split(",")):
            settle(n, threads, args.repeats, info)
    if not args.no_mesh:
        general_path(args.mesh_points, args.repeats, info)


if __name__ == "__main__":
    main()
