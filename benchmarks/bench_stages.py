"""What each stage of the grid path's substep costs, on its own, on one thread and on all.

The whole-substep benchmarks (``bench_sim.py``) say how fast a scene runs;
this one says where the time goes, to hold each stage against the work it
does and the bound it meets (docs/performance.md, 'The roof'). It takes a
cloth mid-run, copies its state, and calls each stage's kernels on that copy
many times, putting the copy back before each batch; a line per stage gives
the best microseconds per call over ``--rounds`` batches, the work (springs,
points or pairs) and nanoseconds per item.

- ``pinned2`` at 50x50 after 10 frames, one thread: the spring forces, their
  gathering with the Verlet step, the Provot pass, and the Provot pass's check
  alone (its vector loop over every spring, without the corrections); then
  what a call from Python costs with no work to do, which each of these
  figures includes and the compiled substep does not pay; then the Provot
  pass and its check again after 90 frames, on the positions the substep's
  springs and step hand the pass, when some 500 springs a substep are over
  their limit (a handful after 10 frames: the corrections cost next to
  nothing there);
- ``selfCollision`` at ``--size`` (100 by default) after its 2 s fall and
  settle, when the cloth lies piled up (or after ``--frame`` frames: 12 at
  90 frames a second finds it still falling, where two threads gain least),
  on one thread and cut over numba's threads: the springs with Verlet, the
  Provot pass, self-collision between list builds, its drift test with the
  copy to single precision made beside it, the cell sort of a build, and a
  whole build (the substep of self-collision that makes a new list); then,
  on one thread, the parts of self-collision between builds (``between
  builds: ...``, on the list as just built: the near stencil with every
  block checked, the pairs that touched at the build, the checks alone of
  those in the next seven slack buckets, which none of them passes yet, and
  the application of the pushes to every point), and a build's three passes
  over the pairs it finds (``pairs``): the cell sort with the query of every
  point's neighbours (``build_list``), the pairs' slack labels (with their
  copy of the positions as rows), and the sort by slack.

- the general path (spring lists, ``meshstep.py``) on the irregular mesh of
  ``bench_sim.py --mesh-only`` (10,000 points) in ``sphere`` after 10 frames,
  one thread: the copy of the positions as rows, the springs with Verlet
  as each point's pulls, and the Provot pass (with its copy of the rows)
  as the substep calls it.

The stages are wrapped here the way the substep calls them (``prange`` over
the parts), compiled apart from the solver's own frame loop.

    python benchmarks/bench_stages.py [--size 100] [--frame 12] [--rounds 5]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numba
import numpy as np
from common import emit, machine
from numba import njit, prange

from clothsim import Simulation
from clothsim.solver.mesh_pulls import rows_buffer, to_rows
from clothsim.solver.provot import check_set, provot
from clothsim.solver.selfcollide.buffers import BUCKET, PAIRS, SKIN, VALID
from clothsim.solver.selfcollide.collide import self_collide
from clothsim.solver.selfcollide.drift import copy_and_level, drift_bound, widened2
from clothsim.solver.selfcollide.hashgrid import sort_into_cells
from clothsim.solver.selfcollide.listbuild import build_list
from clothsim.solver.selfcollide.nearstencil import NEAR_LEVELS, near_pushes
from clothsim.solver.selfcollide.pushes import apply_pushes, pair_pushes
from clothsim.solver.selfcollide.slack import SLACK_BUCKETS, label_pairs, sort_by_slack
from clothsim.solver.shared import KERNEL_OPTIONS
from clothsim.solver.springs import integrate, spring_forces, verlet_gather
from clothsim.solver.step import _part_span, _gather_planes

ROOT = Path(__file__).resolve().parent.parent


def _springs(P, L, free, knobs, springs, F, masks):
    parts = masks.shape[0]
    n = P.shape[1]
    for t in prange(parts):
        lo, hi = _part_span(n, parts, t, springs.ahead)
        integrate(P, L, free, knobs, springs, F[t], max(lo - springs.ahead, 0), hi, lo)


def _provot(P, springs, enabled, masks):
    parts = masks.shape[0]
    n = P.shape[1]
    for t in prange(parts):
        lo, hi = _part_span(n, parts, t, springs.ahead)
        provot(P, springs, enabled, masks[t], lo, hi, False)
    for t in range(1, parts):
        lo, _ = _part_span(n, parts, t, springs.ahead)
        provot(P, springs, enabled, masks[0], lo, lo, True)


def _self_collide(P, points, steps, lists, pairs):
    return self_collide(P, points, steps, lists, pairs)


def _drift(P, lists, reach):
    """the drift test with the copy to single precision it is made beside, as a substep makes them"""
    skin = 0.001 * lists.meta[SKIN] * reach
    worst = np.empty((lists.extent32.shape[0], 2), dtype=np.int32)
    extent = copy_and_level(P, lists.frame, lists.pos32, lists.extent32, lists.reference, skin, lists.centres,
                            worst)
    return drift_bound(lists.pos32, lists.reference, skin, lists.centres, extent + lists.frame[3], worst)


@njit
def _extent(P, lists, reach):
    """the extent of the copy to single precision, as the drift test makes it"""
    skin = 0.001 * lists.meta[SKIN] * reach
    worst = np.empty((lists.extent32.shape[0], 2), dtype=np.int32)
    return copy_and_level(P, lists.frame, lists.pos32, lists.extent32, lists.reference, skin, lists.centres,
                          worst)


@njit
def _between(P, free, lists, reach, wide2, inv_steps, part):
    """one part of self-collision between builds, on one thread, as the substep
    calls it, on the list the copy's last build made: ``part`` 0 the near
    stencil with every block checked, 1 the pairs that touched at the build
    (pushed without a branch), 2 those of the next seven slack buckets (tested
    in single precision first), 3 the pushes applied to every point"""
    meta = lists.meta
    touching, later = meta[BUCKET], meta[BUCKET + 7]
    if part == 0:
        span2 = (reach * (1.0 + 0.001 * meta[SKIN])) ** 2 - reach * reach
        return near_pushes(P, reach, lists, 0, 1, False, np.float64(NEAR_LEVELS + 1), NEAR_LEVELS / span2, wide2,
                           True)
    if part == 1:
        return pair_pushes(P, reach, lists.pairs, 0, touching, touching, lists, 0, 0, wide2)
    if part == 2:
        return pair_pushes(P, reach, lists.pairs, touching, touching, later, lists, 0, 0, wide2)
    apply_pushes(P, lists.push, lists.count, free, inv_steps, 0, P.shape[1])
    return 0


@njit
def _cells(P, radius, span, lists):
    """the cell sort into copy 0, on one thread: with threads, each part sorts
    into a copy of its own at the same time (GRID_COPIES)"""
    return sort_into_cells(P, radius, span, lists, 0)


@njit
def _labels(P, R, reach, pairs, count, labels, scale):
    """a build's slack labels with the copy of the positions as rows they read, on one thread"""
    to_rows(P, R, 0, P.shape[1])
    label_pairs(R, reach, pairs, 0, count, labels, scale)


@njit
def _slack_sort(pairs, labels, segments, meta):
    """a build's sort by slack, on one thread (its result a new array, as in a build)"""
    return sort_by_slack(pairs, labels, segments, meta, 1)


WRAPPED = {parallel: [njit(parallel=parallel)(f) for f in (_springs, _provot, _self_collide, _drift)]
           for parallel in (False, True)}
"""each wrapper compiled serial and parallel"""


@njit(**KERNEL_OPTIONS)
def provot_check(P, springs, masks):
    """The Provot pass's check alone: a bit per spring over its limit, every set
    (and, as in the pass, each word's marks for the second batch cleared)."""
    start, end, count, limit = springs.start, springs.end, springs.count, springs.limit
    for s in range(6):
        check_set((P[0], P[1], P[2]), start[s], end[s], limit[s], 0, count[s], masks[0], masks[1])


class Copy:
    """A solver's planes filled from the simulation's state, and put back on demand."""

    def __init__(self, sim: Simulation):
        self.sim, self.solver = sim, sim.solver
        self.scratch = s = self.solver.scratch
        order = self.solver.points.order  # the solver's slots (see grid_order)
        _gather_planes(sim.state.positions, s.P, order)
        _gather_planes(sim.state.last_positions, s.L, order)
        self.P0, self.L0 = s.P.copy(), s.L.copy()

    def reset(self) -> None:
        self.scratch.P[:] = self.P0
        self.scratch.L[:] = self.L0


def best_us(call, copy: Copy, calls: int, rounds: int) -> float:
    """Best microseconds per call over ``rounds`` batches of ``calls``, each from the
    copy, after one call that compiles (or loads) the kernels: with ``--rounds 1``
    the only batch took the compile too, some 280 µs a call on the Provot check."""
    copy.reset()
    call()
    best = float("inf")
    for _ in range(rounds):
        copy.reset()
        start = time.perf_counter()
        for _ in range(calls):
            call()
        best = min(best, (time.perf_counter() - start) / calls * 1e6)
    return best


def line(stage: str, scene: str, grid: str, threads: int, us: float, work: int, unit: str, info: dict) -> None:
    emit({"bench": "stage", "stage": stage, "scene": scene, "grid": grid, "threads": threads,
          "us_per_call": round(us, 2), unit: work, f"ns_per_{unit[:-1]}": round(1000 * us / work, 3), **info})


def spring_stages(rounds: int, info: dict) -> None:
    sim = Simulation.from_file(ROOT / "scenes" / "pinned2.json", threads=1)
    sim.params.self_collision = False
    for _ in range(10):
        sim.step()
    copy = Copy(sim)
    sol, s = copy.solver, copy.scratch
    knobs, springs, free = sol.knobs(sim.params), sol.springs, sol.points.free
    n = s.P.shape[1]
    slots = int(springs.count.sum())
    calls = {
        "spring forces": lambda: spring_forces(s.P, knobs.k_over_m, springs, s.F[0], 0, n),
        "gather and Verlet": lambda: verlet_gather(s.P, s.L, free, knobs, springs, s.F[0], 0, n, True),
        "springs and Verlet": lambda: integrate(s.P, s.L, free, knobs, springs, s.F[0], 0, n, 0),
        "Provot": lambda: provot(s.P, springs, knobs.enabled, s.masks[0], 0, n, False),
        "Provot check": lambda: provot_check(s.P, springs, s.masks[0]),
    }
    for stage, call in calls.items():
        us = best_us(call, copy, 2000, rounds)
        points = stage == "gather and Verlet"
        line(stage, "pinned2", "50x50", 1, us, n if points else slots, "points" if points else "springs", info)
    # what each figure above spends in the call from Python (unboxing the groups'
    # arrays), which the compiled substep does not pay: the force call on no points
    us = best_us(lambda: spring_forces(s.P, knobs.k_over_m, springs, s.F[0], 0, 0), copy, 2000, rounds)
    emit({"bench": "stage", "stage": "call from Python, no work", "scene": "pinned2", "grid": "50x50",
          "threads": 1, "us_per_call": round(us, 2), **info})
    # the Provot pass as a run meets it a second in, on the positions a
    # substep's springs and step hand it: some 500 springs over their limit
    # a substep, where the cloth above (10 frames) has a handful
    for _ in range(80):
        sim.step()
    copy = Copy(sim)
    integrate(s.P, s.L, free, knobs, springs, s.F[0], 0, n, 0)
    copy.P0, copy.L0 = s.L.copy(), s.P.copy()  # the step wrote the new positions over the last ones
    copy.reset()
    over = sum(int(np.count_nonzero(gap2_all(s.P, springs, t) > springs.limit[t, :springs.count[t]] ** 2))
               for t in range(6))
    for stage, call in (("Provot, after 1 s", calls["Provot"]), ("Provot check, after 1 s", calls["Provot check"])):
        us = best_us(call, copy, 2000, rounds)
        line(stage, "pinned2", "50x50", 1, us, slots, "springs", {**info, "frame": 90, "springs_over_limit": over})


def general_stages(rounds: int, info: dict) -> None:
    import tempfile

    from bench_sim import mesh_scene

    from clothsim.procedural import delaunay_square, write_obj
    from clothsim.solver.mesh_pulls import pull_step
    from clothsim.solver.meshsprings import mesh_provot

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        obj = write_obj(folder / "irregular.obj", delaunay_square(count=10000, side=1.0, spacing=0.007, seed=20))
        sim = Simulation.from_file(mesh_scene("sphere", obj, folder), threads=1)
    for _ in range(10):
        sim.step()
    copy = Copy(sim)
    sol, s = copy.solver, copy.scratch
    knobs, springs, pulls, free = sol.knobs(sim.params), sol.springs, sol.pulls, sol.points.free
    n, count = s.P.shape[1], len(springs.a)
    eights = -(-n // 8)

    def provot_pass():
        to_rows(s.P, s.F, 0, n)
        mesh_provot(s.P, s.F, springs, knobs.enabled, 0, count)

    calls = {"general: rows": (lambda: to_rows(s.P, s.F, 0, n), n, "points"),
             "general: springs and Verlet": (lambda: pull_step(s.P, s.F, s.L, free, knobs, pulls, 0, eights),
                                             count, "springs"),
             "general: Provot with its rows": (provot_pass, count, "springs")}
    to_rows(s.P, s.F, 0, n)
    for stage, (call, work, unit) in calls.items():
        us = best_us(call, copy, 200, rounds)
        line(stage, "sphere", "irregular mesh", 1, us, work, unit,
             {**info, "slots_per_point": round(pulls.other.size / n, 2)})


def gap2_all(P, springs, t):
    """the squared lengths of set t's springs, (count,)"""
    a, b, c = springs.start[t], springs.end[t], springs.count[t]
    return ((P[:, b:b + c] - P[:, a:a + c]) ** 2).sum(axis=0)


def piled_stages(size: int, rounds: int, info: dict, frame: int | None = None) -> None:
    grid = [f"cloth.num_width_points={size}", f"cloth.num_height_points={size}"]
    threads = numba.get_num_threads()
    sims = {t: Simulation.from_file(ROOT / "scenes" / "selfCollision.json", grid, threads=t)
            for t in sorted({1, threads})}
    # the pile is made on one thread: a change to how the parts split their work changes
    # the threaded run's positions in the last bits, and its pile with them, so that
    # two trees compared would time different cloths
    lead = sims[1]
    frames = round(2.0 * lead.params.frames_per_sec) if frame is None else frame
    info = {**info, "frame": frames}
    for _ in range(frames - 1):
        lead.step()
    for sim in sims.values():
        sim.state.positions[:] = lead.state.positions
        sim.state.last_positions[:] = lead.state.last_positions
        sim.step()  # a list of this state's pairs
    stages = {}
    for t, sim in sims.items():
        copy = Copy(sim)
        sol, s = copy.solver, copy.scratch
        knobs, springs, points, lists = sol.knobs(sim.params), sol.springs, sol.points, sol.lists
        f_springs, f_provot, f_self, f_drift = WRAPPED[t > 1]
        steps = sim.params.simulation_steps
        reach = 2.0 * points.thickness
        n = s.P.shape[1]
        slots = int(springs.count.sum())

        def rebuild(s=s, points=points, steps=steps, lists=lists, f_self=f_self):
            lists.meta[VALID] = 0
            f_self(s.P, points, steps, lists, lists.pairs)

        # a list built on the copy itself: every call below starts with no drift
        copy.reset()
        rebuild()
        stages[t] = (copy, {
            "springs and Verlet": (lambda s=s, points=points, knobs=knobs, springs=springs, f=f_springs:
                                   f(s.P, s.L, points.free, knobs, springs, s.F, s.masks), 200, slots, "springs"),
            "Provot": (lambda s=s, knobs=knobs, springs=springs, f=f_provot: f(s.P, springs, knobs.enabled, s.masks),
                       200, slots, "springs"),
            "self-collision, list just built": (lambda s=s, points=points, steps=steps, lists=lists, f=f_self:
                                                f(s.P, points, steps, lists, lists.pairs), 50, n, "points"),
            "drift test and its copy": (lambda s=s, lists=lists, reach=reach, f=f_drift: f(s.P, lists, reach),
                                        200, n, "points"),
            "cell sort of a build": (lambda s=s, points=points, lists=lists, reach=reach:
                                     _cells(s.P, 1.2 * reach, points.span, lists), 50, n, "points"),
            "self-collision with a build": (rebuild, 20, n, "points")})
    # a build's passes over its pairs, on one thread, on the list of the one-thread copy
    copy, calls = stages[1]
    sol = copy.solver
    lists, points, s = sol.lists, sol.points, copy.scratch
    reach = 2.0 * points.thickness
    # the parts of self-collision between builds, on that list as built: the
    # stencil's every block, the pairs that touched at the build, those of the
    # next seven slack buckets (none of which touches yet: their checks alone)
    # and the application of the pushes
    copy.reset()
    wide2 = widened2(reach, _extent(s.P, lists, reach))
    touching, later = int(lists.meta[BUCKET]), int(lists.meta[BUCKET + 7])
    inv_steps = 1.0 / lead.params.simulation_steps
    stencil = int(sum(s.P.shape[1] - o for o in lists.near_offset))
    for part, (stage, work, unit) in enumerate((
            ("between builds: near stencil, every block", stencil, "pairs"),
            ("between builds: pairs that touched at the build", touching, "pairs"),
            ("between builds: pairs of the next 7 buckets", later - touching, "pairs"),
            ("between builds: pushes applied", s.P.shape[1], "points"))):
        calls[stage] = (lambda s=s, part=part: _between(s.P, points.free, lists, reach, wide2, inv_steps, part),
                        200, work, unit)
    radius = reach + 0.001 * lists.meta[SKIN] * reach
    found = np.empty((2, 40 * s.P.shape[1] + 64), dtype=np.int32)
    listed = build_list(s.P, points.rest, reach, radius, points.span, lists, found)
    if 0 <= listed <= found.shape[1]:
        labels = np.empty(found.shape[1], dtype=np.int8)
        scale = (SLACK_BUCKETS - 1) / (radius * radius - reach * reach)
        segments = np.array([[0, listed]], dtype=np.int64)
        meta = lists.meta.copy()
        rows = rows_buffer(s.P.shape[1])
        _labels(s.P, rows, reach, found, listed, labels, scale)
        calls.update({
            "build: cell sort and query": (lambda s=s, points=points, lists=lists, found=found:
                                           build_list(s.P, points.rest, reach, radius, points.span, lists, found),
                                           20, listed, "pairs"),
            "build: labels": (lambda s=s: _labels(s.P, rows, reach, found, listed, labels, scale), 50, listed,
                              "pairs"),
            "build: slack sort": (lambda: _slack_sort(found, labels, segments, meta), 50, listed, "pairs")})
    # rounds interleave the thread counts, so a slow spell of the machine falls on both
    best: dict = {}
    for _ in range(rounds):
        for t, (copy, calls) in stages.items():
            for stage, (call, count, _, _) in calls.items():
                us = best_us(call, copy, count, 1)
                best[t, stage] = min(best.get((t, stage), float("inf")), us)
    for t, (copy, calls) in stages.items():
        for stage, (_, _, work, unit) in calls.items():
            line(stage, "selfCollision", f"{size}x{size}", t, best[t, stage], work, unit, info)
    substeps = frames * lead.params.simulation_steps
    emit({"bench": "stage", "stage": "list", "scene": "selfCollision", "grid": f"{size}x{size}",
          "pairs": int(lead.solver.lists.meta[PAIRS]),
          "rebuilds_per_100_substeps": round(100.0 * lead.neighbour_list_rebuilds / substeps, 2), **info})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=int, default=100)
    ap.add_argument("--frame", type=int, default=None,
                    help="time the cloth after this many frames (default: the whole 2 s settle)")
    ap.add_argument("--rounds", type=int, default=5)
    args = ap.parse_args()
    if args.frame is not None and args.frame < 1:
        ap.error(f"--frame: expected a number of frames of 1 or more, got {args.frame}")
    info = machine()
    spring_stages(args.rounds, info)
    general_stages(args.rounds, info)
    piled_stages(args.size, args.rounds, info, args.frame)


if __name__ == "__main__":
    main()
