"""What the moving world costs a 50x50 cloth per substep, side by side.

Each case is ``sphere.json`` (50x50, self-collision on, one thread) with its
collider swapped: the still sphere of today; the same sphere spinning; a box
(a table under the cloth); the same box turned 20° about y; the same box
tilted about all three axes; the box sliding; the box sliding and turning;
the sphere with a 5 m/s wind; no collider at all (what the rest of the
substep costs). Cases run in
interleaved rounds, alternating their order, one second of simulated time
each from the same start; a line per case gives the best and median
substeps/s and microseconds a substep, and how much more than the still
sphere's substep it costs.

The cloth does not meet a box as it meets a sphere (it folds at the box's
edges, and self-collision then has more to do), so whole substeps compare
scenes, not colliders. ``--kernels`` times the collider kernels alone instead,
each on the cloth of its own case after 1.5 s (draped on the sphere, lying
on the box) one substep's fall further, called on a fresh copy of it many
times from a compiled loop, as the substep calls them (from Python each call
would add numba's dispatch), the copy's own time taken off, the positions on
cache lines as the solver's are; best of the rounds: the still sphere,
the spinning sphere (on the still one's cloth), the box, the turned box (on
its own cloth), the box sliding, the box sliding and turning about y, the
tilted box (on its own cloth), the box sliding and turning about x and y
(its turns take the maps of twelve numbers, as the tilted box's do), the wind (its
pass over the triangles: the grid path's stencils, and the general path's
loop over a triangle list), per call of one substep; and the still sphere's
kernel as it stood at `c978e85` (``sphere_then.py``), the sphere issue 21
measures a box and an animated sphere against. Each line gives the kernel's
cost as a multiple of today's still sphere (``of_sphere``) and of that one
(``of_sphere_then``).

    python benchmarks/bench_world.py [--rounds 5] [--seconds 1] [--kernels]
"""

from __future__ import annotations

import argparse
import copy
import json
import statistics
import time

from common import emit, machine

from clothsim import Simulation
from clothsim.scene import parse_scene
from clothsim.standard_scenes import scene_path

SPIN = {"keys": [{"t": 0}, {"t": 4, "rotate": [0, 360, 0]}], "loop": True}
SLOT = 3
"""the substep of a frame the kernels are timed at (``--kernels``)"""
TURN = [0, 20, 0]
"""[degrees] the turned box's own rotation: its axes are not the world's, so its
pass turns every point into its frame, as a moving box's does (about y alone,
with the maps of a turn about y, :func:`clothsim.solver.colliders.box.yaw_map`)"""
TILT = [8, 20, 5]
"""[degrees] the tilted box's own rotation, about all three axes: its pass takes
the maps of twelve numbers"""
SLIDE_ONLY = {"keys": [{"t": 0}, {"t": 2, "translate": [0.2, 0, 0]}], "loop": True}
SLIDE = {"keys": [{"t": 0}, {"t": 2, "translate": [0.2, 0, 0], "rotate": [0, 30, 0]}], "loop": True}


def cases(base: dict) -> dict[str, dict]:
    sphere = base["sphere"]
    box = {"center": sphere["origin"], "size": [0.6, 0.2, 0.6], "friction": sphere["friction"]}
    out = {"sphere": base}
    out["spinning sphere"] = {**base, "sphere": {**sphere, "animation": SPIN}}
    no_sphere = {k: v for k, v in base.items() if k != "sphere"}
    out["box"] = {**no_sphere, "box": box}
    out["turned box"] = {**no_sphere, "box": {**box, "rotate": TURN}}
    out["tilted box"] = {**no_sphere, "box": {**box, "rotate": TILT}}
    out["sliding box"] = {**no_sphere, "box": {**box, "animation": SLIDE_ONLY}}
    out["moving box"] = {**no_sphere, "box": {**box, "animation": SLIDE}}
    out["sphere + wind"] = {**base, "wind": {"velocity": [5.0, 0.0, 0.0]}}
    out["no collider"] = no_sphere
    return {name: copy.deepcopy(scene) for name, scene in out.items()}


def run_once(sim: Simulation, seconds: float) -> float:
    """substeps/s over ``seconds`` of simulated time from the start"""
    sim.reset()
    frames = int(round(seconds * sim.params.frames_per_sec))
    t0 = time.perf_counter()
    for _ in range(frames):
        sim.step()
    return frames * sim.params.simulation_steps / (time.perf_counter() - t0)


def _settled(scene: dict):
    """(P, L, free, sim): the (3, N) positions of ``scene``'s cloth after 1.5 s, one
    substep's fall more (so that the points resting on the collider cross it again),
    and its last positions, each array starting on a cache line as the solver's do"""
    from clothsim.solver.shared import on_lines

    sim = Simulation(parse_scene(scene, "bench"), threads=1)
    sim.run(1.5)
    P, L = on_lines(sim.state.positions.T.shape), on_lines(sim.state.positions.T.shape)
    P[:] = sim.state.positions.T
    L[:] = sim.state.last_positions.T
    P[1] -= 9.8 * sim.params.dt ** 2
    return P, L, sim.solver.points.free, sim


def _calls(kernel):
    """A compiled loop of ``reps`` calls of ``kernel(P, *rest)``, each on a fresh
    copy of ``start`` in ``P`` (None: the copies alone). The substep calls
    its kernels from compiled code: timed from Python, each call would also
    pay numba's dispatch, a microsecond or two, which differs with the
    arguments."""
    from numba import njit

    if kernel is None:
        @njit
        def copies(P, start, reps, rest):
            for _ in range(reps):
                P[:, :] = start
        return copies

    @njit
    def calls(P, start, reps, rest):
        for _ in range(reps):
            P[:, :] = start
            kernel(P, *rest)
    return calls


def kernel_times(rounds: int, calls: int = 2000) -> None:
    import numpy as np
    import sphere_then

    from clothsim.motion import Animation, Keyframe
    from clothsim.solver.colliders import box, sphere
    from clothsim.solver.shared import on_lines
    from clothsim.solver.wind import blow, blow_grid, pack_wind, wind_buffer
    from clothsim.world_spec import WindSpec

    base = json.loads(scene_path("sphere").read_text())
    scenes = cases(base)
    on_sphere = _settled(scenes["sphere"])
    on_box = _settled(scenes["box"])
    on_turned = _settled(scenes["turned box"])
    on_tilted = _settled(scenes["tilted box"])
    sim = on_sphere[3]
    dt, steps = sim.params.dt, sim.params.simulation_steps
    spin = Animation((Keyframe(0.0), Keyframe(4.0, rotate=(0.0, 360.0, 0.0))), loop=True)
    # the timed substep is slot SLOT of a frame from the state's time: the box starts
    # moving as it begins, standing where the cloth settled on it. Started with the
    # frame, it would have moved into the cloth over the substeps before, with no
    # cloth following, and the kernel would time pushing some 170 points back out
    start = 1.5 + SLOT * dt
    slide = Animation((Keyframe(start), Keyframe(start + 2.0, (0.2, 0.0, 0.0), (0.0, 30.0, 0.0))))
    s0, b0 = sim.spheres[0], on_box[3].boxes[0]
    moving_sphere = type(s0)(s0.origin, s0.radius, s0.friction, spin)
    moving_box = type(b0)(b0.center, b0.size, b0.friction, animation=slide)
    sliding_box = type(b0)(b0.center, b0.size, b0.friction,
                           animation=Animation((Keyframe(start), Keyframe(start + 2.0, (0.2, 0.0, 0.0)))))
    rocking = Animation((Keyframe(start), Keyframe(start + 2.0, (0.2, 0.0, 0.0), (5.0, 30.0, 0.0))))
    rocking_box = type(b0)(b0.center, b0.size, b0.friction, animation=rocking)
    work = {"sphere": (sphere.collide_spheres, sphere.pack([s0], 1.5, dt, steps), on_sphere),
            "spinning sphere": (sphere.collide_spheres, sphere.pack([moving_sphere], 1.5, dt, steps), on_sphere),
            "box": (box.collide_boxes, box.pack([b0], 1.5, dt, steps), on_box),
            "turned box": (box.collide_boxes, box.pack([on_turned[3].boxes[0]], 1.5, dt, steps), on_turned),
            "sliding box": (box.collide_boxes, box.pack([sliding_box], 1.5, dt, steps), on_box),
            "moving box": (box.collide_boxes, box.pack([moving_box], 1.5, dt, steps), on_box),
            "tilted box": (box.collide_boxes, box.pack([on_tilted[3].boxes[0]], 1.5, dt, steps), on_tilted),
            "rocking box": (box.collide_boxes, box.pack([rocking_box], 1.5, dt, steps), on_box),
            "sphere at c978e85": (sphere_then.collide_spheres, sphere_then.pack([s0]), on_sphere)}
    wind = pack_wind(WindSpec((5.0, 0.0, 0.0)), 1.5, dt)
    knobs = sim.solver.knobs(sim.params)
    n = on_sphere[0].shape[1]
    W = np.zeros((3, n))
    zero, count, slot = np.int64(0), np.int64(n), np.int64(SLOT)

    cols = sim.model.cloths[0].grid[1]
    T = wind_buffer(n, cols)
    weight = sim.solver.springs.valid[0]

    def args(name):
        """the arguments after the positions of case ``name``'s kernel, and the
        positions it starts from"""
        if name in ("wind", "wind, triangle list"):
            P0, L = on_sphere[0], on_sphere[1]
            if name == "wind":  # the grid path's stencils, as the substep runs it
                return blow_grid, P0, (L, sim.solver.points.free, weight, knobs.inv_mass, knobs.dt2, wind, T, slot,
                                       cols)
            return blow, P0, (L, sim.solver.points, knobs.inv_mass, knobs.dt2, wind, W, slot)
        kernel, rows, (P0, L, free, _) = work[name]
        return kernel, P0, (L, free, rows, zero, count, slot)

    names = [*work, "wind", "wind, triangle list"]
    cases_ = {name: args(name) for name in names}
    loops = {name: _calls(cases_[name][0]) for name in names}
    starts = {name: cases_[name][1] for name in names}
    P = on_lines(on_sphere[0].shape)
    copies = _calls(None)
    copies(P, starts["sphere"], 1, ())  # compile
    for name in names:
        loops[name](P, starts[name], 1, cases_[name][2])
    order = ["copy", *names]
    best = {name: np.inf for name in order}
    for r in range(rounds):
        for name in (order if r % 2 == 0 else order[::-1]):
            loop, start, rest = (copies, starts["sphere"], ()) if name == "copy" else (loops[name], starts[name],
                                                                                     cases_[name][2])
            t0 = time.perf_counter()
            loop(P, start, calls, rest)
            best[name] = min(best[name], (time.perf_counter() - t0) / calls)
    sphere_us = (best["sphere"] - best["copy"]) * 1e6
    then_us = (best["sphere at c978e85"] - best["copy"]) * 1e6
    for name in names:
        us = (best[name] - best["copy"]) * 1e6
        emit({"bench": "world-kernels", "case": name, "points": n, "us_per_substep": round(us, 2),
              "of_sphere": round(us / sphere_us, 2), "of_sphere_then": round(us / then_us, 2), **machine()})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--seconds", type=float, default=1.0)
    ap.add_argument("--kernels", action="store_true", help="the collider kernels alone, on one state")
    args = ap.parse_args()
    if args.kernels:
        kernel_times(args.rounds)
        return
    base = json.loads(scene_path("sphere").read_text())
    sims = {name: Simulation(parse_scene(scene, "bench"), threads=1) for name, scene in cases(base).items()}
    for sim in sims.values():  # compile and warm up
        sim.run(0.05)
    rates: dict[str, list[float]] = {name: [] for name in sims}
    names = list(sims)
    for r in range(args.rounds):
        for name in (names if r % 2 == 0 else names[::-1]):
            rates[name].append(run_once(sims[name], args.seconds))
    best_sphere = max(rates["sphere"])
    for name in names:
        best = max(rates[name])
        emit({"bench": "world", "case": name, "points": 2500, "threads": 1, "rounds": args.rounds,
              "substeps_per_s_best": round(best), "substeps_per_s_median": round(statistics.median(rates[name])),
              "us_per_substep_best": round(1e6 / best, 2),
              "us_more_than_sphere": round(1e6 / best - 1e6 / best_sphere, 2), **machine()})


if __name__ == "__main__":
    main()
