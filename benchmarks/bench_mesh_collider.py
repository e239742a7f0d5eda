"""The mesh collider's cost per substep: a 50x50 cloth draped just above an icosphere.

The cloth (2,500 points, 1.5 m square) lies over a ball of radius 0.5 m made
of 20,480 triangles (icosphere, 5 subdivisions): over the ball each point is
a few millimetres off its surface and falls a little this substep, some
through it; beyond the ball's rim the cloth hangs down past its side. The
ball is closed and static. Prints one JSON line: the CPU, the microseconds
of one :func:`collide_meshes` call over all points (best of several repeats of
many calls, each on the same positions copied in just before it) and the triangles tested
per point, with the time :func:`pack_meshes` takes.

That cloth keeps no hints (each point's last crossed triangle, whose clear
prism settles a resting point's segment without a search): it times the
search. A cloth draped on a mesh is timed too, as a run meets it:
``sphere.json`` (50x50) with its sphere replaced by a closed icosphere of the
same subdivisions, centre, radius and friction, run 1.5 s on one thread;
from there one substep's springs and Verlet step, then the collider pass
(``drape_collide_us``) on those positions and the settle pass
(``drape_settle_us``) on what the Provot pass makes of them, with the hints the
run kept and with none (``..._no_hints_us``; the positions are the same to the
bit), and how many points each pass moved. ``call_us`` is what calling a kernel
from Python costs (a control with no poses, which returns at once): the
substep's compiled call does not pay it, and ``drape_us``, both passes, is
their sum less two of it.

Beside them, in the same rounds (the collider timings, then the cloth timings,
so a slow spell of the machine falls on both), what a 50x50 grid cloth with no
collider and no self-collision costs per substep (``cloth_substep_us``, the
whole substep on one thread) and the part of it its springs take
(``springs_us``: that run less the same run with every spring kind off);
each the best of the rounds.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import trimesh

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import emit, machine  # noqa: E402

import clothsim  # noqa: E402
from clothsim import Simulation  # noqa: E402
from clothsim.scene import parse_scene  # noqa: E402
from clothsim.solver.colliders.mesh import (  # noqa: E402
    collide_meshes,
    count_tests,
    pack_meshes,
    pose_rows,
    settle_meshes,
)
from clothsim.solver.groups import Control  # noqa: E402
from clothsim.solver.provot import provot  # noqa: E402
from clothsim.solver.springs import integrate  # noqa: E402
from clothsim.solver.step import _gather_planes  # noqa: E402
from clothsim.standard_scenes import scene_path  # noqa: E402

CLOTH = Path(clothsim.__file__).resolve().parent / "scenes" / "pinned2.json"
"""a 50x50 cloth hanging from two corners, no collider"""


def Ctl(**mesh_fields):
    """the solver's own Control with only the mesh fields set: a kernel compiled for a
    named tuple of this module would go into numba's cache with it, and a process that
    cannot import this module could not load that cache any more"""
    return Control(handle=-1, handle_pos=np.zeros(3), spheres=None, planes=None, boxes=None, moved_points=None,
                   moved_to=None, wind=None, **mesh_fields)


def draped(n=50, side=1.5, radius=0.5, gap=0.004, drop=0.006, seed=0):
    """(L, P) (3, n*n) [m]: last positions ``gap`` off the ball (or hanging past
    it), positions now up to ``drop`` lower"""
    u = np.linspace(-side / 2, side / 2, n)
    x, y = np.meshgrid(u, u)
    r = np.hypot(x, y)
    over = r < radius
    z = np.where(over, np.sqrt(np.maximum(radius ** 2 - r ** 2, 0.0)), -(r - radius) * 2.0) + gap
    L = np.stack([x.ravel(), y.ravel(), z.ravel()])
    P = L.copy()
    P[2] -= np.random.default_rng(seed).uniform(0.0, drop, n * n)
    return np.ascontiguousarray(L), np.ascontiguousarray(P)


def bare_cloth(springs: bool) -> Simulation:
    """the 50x50 cloth of CLOTH on one thread, self-collision off (springs off too
    where ``springs`` is false), stepped once so that it is compiled"""
    sim = Simulation.from_file(CLOTH, threads=1)
    sim.params.self_collision = False
    if not springs:
        sim.params.enable_structural = sim.params.enable_shearing = sim.params.enable_bending = False
    sim.step()
    return sim


def substep_us(sim: Simulation, frames: int) -> float:
    """microseconds per substep over ``frames`` frames"""
    t = time.perf_counter()
    for _ in range(frames):
        sim.step()
    return (time.perf_counter() - t) / (frames * sim.params.simulation_steps) * 1e6


class Drape:
    """A 50x50 cloth draped on a mesh ball as a run leaves it, and its next substep's
    collider and settle passes, each timed from the same positions, with or without hints."""

    def __init__(self, subdivisions: int, folder: Path):
        scene = json.loads(scene_path("sphere").read_text())
        sphere = scene.pop("sphere")
        trimesh.creation.icosphere(subdivisions=subdivisions, radius=1.0).export(folder / "ball.obj")
        scene["mesh"] = {"path": "ball.obj", "friction": sphere["friction"],
                         "transform": {"scale": sphere["radius"], "translate": sphere["origin"]}}
        sim = Simulation(parse_scene(scene, str(folder / "drape.json")), threads=1)
        sim.run(1.5)
        solver, knobs = sim.solver, sim.solver.knobs(sim.params)
        self.ctl = sim.control
        self.none = self.ctl._replace(mesh_hints=np.full((1, 0), -1, np.int32))
        self.hints = self.ctl.mesh_hints.copy()
        P, L = np.zeros_like(solver.scratch.P), np.zeros_like(solver.scratch.L)
        _gather_planes(sim.state.positions, P, solver.points.order)
        _gather_planes(sim.state.last_positions, L, solver.points.order)
        self.free = solver.points.free
        n = P.shape[1]
        self.span = np.int64(0), np.int64(n), np.int64(0)
        integrate(P, L, self.free, knobs, solver.springs, solver.scratch.F[0], self.span[0], self.span[1],
                  self.span[0])
        # the step wrote the new positions over the last ones: the substep's positions
        # before the colliders, and its last ones
        self.before, self.L = L, P
        self.Q = P.copy()
        collide_meshes(self.Q, L, self.free, self.ctl._replace(mesh_hints=self.hints.copy()), *self.span)
        self.after = self.Q.copy()
        provot(self.after, solver.springs, knobs.enabled, solver.scratch.masks[0], self.span[0], self.span[1], False)
        self.collided = int(np.any(self.Q != self.before, axis=0).sum())
        self.settled = int(np.any(self.after != self.Q, axis=0).sum())

    def time(self, settle: bool, hints: bool, calls: int, call_only: bool = False) -> float:
        """seconds per call of one pass over all points (``call_only``: of the call alone,
        with a control of no poses, which returns at once: what calling the kernel
        from Python costs, which a substep's compiled call does not pay), each from the
        same positions and hints (:func:`warm_calls`)"""
        start = self.after if settle else self.before
        ctl = self.ctl._replace(mesh_hints=self.hints.copy()) if hints else self.none
        if call_only:
            ctl = ctl._replace(meshes=ctl.meshes[:0])
        if settle:
            def call(P):
                settle_meshes(P, self.Q, self.free, ctl, *self.span)
        else:
            def call(P):
                collide_meshes(P, self.L, self.free, ctl, *self.span)
        return warm_calls(call, start, calls, (ctl.mesh_hints, self.hints) if hints else None)


def warm_calls(call, start: np.ndarray, calls: int, hints=None) -> float:
    """Seconds per ``call(P)``, each on positions ``start`` copied into one array P just
    before it (and ``hints``, a pair (the control's array, its first values), copied
    back too), so that the pass finds them in the cache as a substep does: its
    springs and Verlet step have just written them. The copies are timed alone and
    taken off. (Calls on a fresh copy each, made ahead, read every position from
    the L3 cache or memory: on the Xeon of docs/performance.md that added some 6 us
    to the draped cloth's two passes.)"""
    P = start.copy()
    kept, first = hints if hints is not None else (np.zeros(0), np.zeros(0))

    def copies(with_call: bool) -> float:
        t = time.perf_counter()
        for _ in range(calls):
            np.copyto(P, start)
            np.copyto(kept, first)
            if with_call:
                call(P)
        return time.perf_counter() - t

    alone = copies(False)
    return max(copies(True) - alone, 0.0) / calls


DRAPE_CASES = {"drape_collide_us": (False, True, False), "drape_collide_no_hints_us": (False, False, False),
               "drape_settle_us": (True, True, False), "drape_settle_no_hints_us": (True, False, False),
               "call_us": (False, True, True)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--subdivisions", type=int, default=5)
    ap.add_argument("--calls", type=int, default=200)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--frames", type=int, default=4, help="frames of the bare cloth per round")
    args = ap.parse_args()
    ball = trimesh.creation.icosphere(subdivisions=args.subdivisions, radius=0.5)
    shape = SimpleNamespace(vertices=ball.vertices, triangles=ball.faces, closed=True)
    pack_meshes([shape])  # compiles the build
    t = time.perf_counter()
    packed = pack_meshes([shape])
    pack_s = time.perf_counter() - t
    eye = np.eye(3)
    ctl = Ctl(meshes=pose_rows(eye, np.zeros(3), eye, np.zeros(3), 0.3, 1e-3)[None, None], **packed)
    L, P0 = draped()
    free = np.ones(P0.shape[1])
    lo, hi, s = np.int64(0), np.int64(P0.shape[1]), np.int64(0)
    collide_meshes(P0.copy(), L, free, ctl, lo, hi, s)  # compiles
    cloth, bare = bare_cloth(True), bare_cloth(False)
    drape = Drape(args.subdivisions, Path(tempfile.mkdtemp()))
    drape_s = dict.fromkeys(DRAPE_CASES, np.inf)
    best, cloth_us, bare_us = np.inf, np.inf, np.inf
    for _ in range(args.repeats):
        best = min(best, warm_calls(lambda P: collide_meshes(P, L, free, ctl, lo, hi, s), P0, args.calls))
        for name, (settle, hints, call_only) in DRAPE_CASES.items():
            drape_s[name] = min(drape_s[name], drape.time(settle, hints, args.calls, call_only))
        cloth_us = min(cloth_us, substep_us(cloth, args.frames))
        bare_us = min(bare_us, substep_us(bare, args.frames))
    tested = np.zeros(P0.shape[1], dtype=np.int64)
    count_tests(P0, L, free, ctl, lo, hi, s, tested)
    P = P0.copy()
    collide_meshes(P, L, free, ctl, lo, hi, s)
    moved = int(np.any(P != P0, axis=0).sum())
    g = packed["mesh_grid"][0]
    emit({"bench": "mesh_collider", **machine(), "points": int(P0.shape[1]), "triangles": int(len(ball.faces)),
          "grid_dims": [int(v) for v in g[5:8]], "cell_m": round(float(g[3]), 5),
          "list_entries": int(packed["mesh_cells"][-1]), "pack_ms": round(pack_s * 1e3, 2),
          "us_per_substep": round(best * 1e6, 2), "cloth_substep_us": round(cloth_us, 2),
          "springs_us": round(cloth_us - bare_us, 2), "tested_mean": round(float(tested.mean()), 2),
          "tested_median": float(np.median(tested)), "tested_max": int(tested.max()), "points_moved": moved,
          **{name: round(v * 1e6, 2) for name, v in drape_s.items()},
          "drape_us": round((drape_s["drape_collide_us"] + drape_s["drape_settle_us"] - 2 * drape_s["call_us"]) * 1e6,
                            2),
          "drape_collided": drape.collided, "drape_settled": drape.settled})


if __name__ == "__main__":
    main()
