"""A second process that compiles the substep's kernels while the first builds the model.

numba compiles in one thread, and a first run of a scene spends most of its
time compiling. The substep (:func:`~.step.advance`) calls some twenty
kernels; each is compiled, and saved to the cache, when the first process
types the call. A second process started with the run compiles the same
kernels in the reverse order, so that the first finds the later ones in the
cache when it gets to them: the two cores share the work.

The kernels are called here on a 4x4 cloth with arguments of exactly the
types the substep passes them (numba keys a compiled kernel on its argument
types, a readonly array or an int constant included); a mismatch costs only
time, never a wrong result, since the first process then compiles that
kernel itself. ``tests/test_prewarm.py`` checks that the first process
compiles none of them after a prewarm.

Only the serial substeps are prewarmed (the grid path's and the general
path's, "serial..." and "mesh-serial..." variants): the threaded ones compile
their parts inside numba's parallel lowering, which the kernels' own caches
do not serve.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from numba import njit

from .. import kernel_cache
from .provot import provot

PREWARM = "CLOTHSIM_PREWARM"
"""set to 0 to compile in one process only"""

LOCK_SECONDS = 120.0
"""a prewarm of the same variant started less than this ago is not started again
(the processes of a sweep start together)"""


def start(variant: str) -> subprocess.Popen | None:
    """Start the second process for ``variant`` (see
    :meth:`~.cloth_solver.ClothSolver.variant`) where it can help: a serial
    variant, two or more cores, and not switched off by CLOTHSIM_PREWARM=0.
    It runs detached from the terminal and ends by itself."""
    if os.environ.get(PREWARM, "1") == "0" or not variant.startswith(("serial", "mesh-serial")):
        return None
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cores = os.cpu_count() or 1
    if cores < 2:
        return None
    folder = kernel_cache.cache_dir()
    if folder is None:
        return None
    lock = folder / f"prewarm-{variant}.lock"
    try:
        if lock.exists() and time.time() - lock.stat().st_mtime < LOCK_SECONDS:
            return None
        lock.write_text(str(os.getpid()))
        # the child imports this very package, whatever sys.path the parent had
        env = dict(os.environ)
        top = str(Path(__file__).resolve().parents[2])
        env["PYTHONPATH"] = os.pathsep.join(p for p in (top, env.get("PYTHONPATH")) if p)
        return subprocess.Popen([sys.executable, "-m", "clothsim.solver.prewarm", variant, str(lock)],
                                stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL, start_new_session=True, env=env)
    except OSError:
        return None


def calls(variant: str) -> list:
    """(kernel, arguments) in the reverse of the order the substep types them."""
    from .colliders import collide, has_settle, settle, settle_needs_q
    from .control import make_control
    from .handles import place_handles
    from .wind import blow, blow_grid, wind_buffer
    from .groups import Knobs, Points, Scratch
    from .mesh_pulls import to_rows
    from .selfcollide import NeighbourList
    from .selfcollide.collide import _append, _close_up, _copy_pairs, _even_segments, _share_segments
    from .selfcollide.drift import _keep, _level_both, _to_single, drift_bound
    from .selfcollide.nearstencil import near_pushes
    from .selfcollide.pushes import apply_pushes, apply_sparse, pair_pushes
    from .selfcollide.slack import label_pairs
    from .springs import build_stencil, force_buffer, integrate
    from .step import _farthest, _gather_planes, _scatter_planes
    from ..mesh import vertex_normals

    features = set(variant.split("+")[1:])
    mesh = variant.startswith("mesh-")
    rows = cols = 4
    n = rows * cols
    i, j = np.meshgrid(np.arange(cols), np.arange(rows))
    rest = np.stack([i.ravel() * 0.1, np.ones(n), j.ravel() * 0.1], axis=1)
    pinned = np.zeros(n, dtype=bool)
    triangles = np.array([[0, 1, 4]], dtype=np.int32)
    order = np.arange(n)
    for a in (rest, pinned, triangles, order):
        a.setflags(write=False)  # as the model's arrays are
    springs = build_stencil(rest, pinned, rows, cols)
    points = Points(rest=rest, free=np.ones(n), thickness=0.01, center=np.zeros(3), span=1e3, triangles=triangles,
                    order=order)
    knobs = Knobs(gravity=np.zeros(3), k_over_m=np.ones(6), enabled=np.ones(6, dtype=bool), keep=1.0,
                  dt2=1e-6, simulation_steps=1, self_collision=True, inv_mass=np.ones(n))
    world = _world(features, n)
    control = make_control(-1, np.zeros(3), world, 0.0, 1e-3, 1, world.mesh_shapes)
    scratch = Scratch(P=np.ascontiguousarray(rest.T), L=np.ascontiguousarray(rest.T),
                      F=force_buffer(springs, n), masks=np.zeros((1, 2, 2), dtype=np.uint64),
                      Q=np.zeros((3, n)), W=np.zeros((3, n)))
    lists = NeighbourList.allocate(n, cols)
    P, L, F = scratch.P, scratch.L, scratch.F
    zero, i64 = np.int64(0), np.int64(n)
    f32 = np.float32(1.0)
    out = [(_farthest, (P, points.center)),
           (_provot_both, (P, springs, knobs.enabled, scratch.masks[0], zero, i64)),
           (settle, (P, scratch.Q, L, points.free, control, zero, i64, zero)),
           (settle_needs_q, (control,)),
           (has_settle, (control,)),
           (collide, (P, L, points.free, control, zero, i64, zero))]
    push, count, touched = lists.push, lists.count, lists.touched
    out += [(apply_pushes, (P, push, count, points.free, 1.0, zero, i64)),
            (apply_sparse, (P, push, count, points.free, 1.0, touched, lists.tally)),
            (pair_pushes, (P, 0.02, lists.pairs, zero, zero, zero, lists, zero, zero, f32)),
            (near_pushes, (P, 0.02, lists, zero, np.int64(1), True, 1.0, 1.0, f32, False)),
            (label_pairs, (lists.rows, 0.02, lists.pairs, zero, zero, np.zeros(0, dtype=np.int8), 1.0)),
            (to_rows, (P, lists.rows, zero, i64)),
            (_keep, (lists.pos32, lists.reference, zero, i64)),
            (_close_up, (lists.pairs, lists.tally, zero)),
            (_share_segments, (lists.tally, zero)),
            (_even_segments, (zero, np.int64(1))),
            (_append, (lists.near_pairs, lists.pairs, zero)),
            (_copy_pairs, (lists.pairs, lists.pairs, zero)),
            (drift_bound, (lists.pos32, lists.reference, 0.01, lists.centres, 1.0, np.zeros((1, 2), dtype=np.int32))),
            (_level_both, (lists.pos32, lists.reference, 0.01, lists.centres, zero, i64)),
            (_to_single, (P, 0.0, 0.0, 0.0, lists.pos32, zero, i64))]
    out += [(place_handles, (P, control.moved_points, control.moved_to, zero))]
    wind = None if control.wind is None else control.wind[0]  # the row the substep hands the wind
    if mesh:
        out += [(blow, (P, L, points, knobs.inv_mass, knobs.dt2, wind, scratch.W, zero))]
        out = [(k, a) for k, a in out if k is not _provot_both] + _mesh_calls(rest, pinned, P, L, points)
    else:
        out += [(blow_grid, (P, L, points.free, springs.valid[0], knobs.inv_mass, knobs.dt2, wind,
                             wind_buffer(n, cols), zero, springs.end[1])),
                (integrate, (P, L, points.free, knobs, springs, F, zero, i64, zero))]
    out += [(_gather_planes, (np.zeros((n, 3)), P, points.order)),
            (_scatter_planes, (P, np.zeros((n, 3)), points.order)),
            (vertex_normals, (np.zeros((n, 3)), triangles, np.zeros((n, 3))))]
    return out


def _mesh_calls(rest, pinned, P, L, points) -> list:
    """The general path's own kernels, in the reverse of the order its substep types
    them, with groups of the types a solver of that path makes (see
    :meth:`~.cloth_solver.ClothSolver._mesh_knobs`, :func:`~.meshsprings.build_mesh_springs`,
    :func:`~.mesh_pulls.build_mesh_pulls`)."""
    from ..model import build_model
    from ..scene import ClothSpec
    from .groups import MeshKnobs
    from .mesh_pulls import build_mesh_pulls, pull_step, refresh_constants, rows_buffer, to_rows
    from .meshsprings import build_mesh_springs, mesh_provot

    spec = ClothSpec(width=0.3, height=0.3, num_width_points=4, num_height_points=4, thickness=0.01,
                     orientation=0)
    model = build_model(spec)
    springs, pulls = build_mesh_springs(model, 1), build_mesh_pulls(model)
    n = P.shape[1]
    knobs = MeshKnobs(gravity=np.zeros(3), k_over_m=np.ones((1, 3)).ravel(),
                      enabled=np.ones((1, 3), dtype=bool).ravel(), keep=np.repeat(np.ones(1), n), dt2=1e-6,
                      simulation_steps=1, self_collision=True, inv_mass=np.ones(n))
    R = rows_buffer(n)
    zero, count, s = np.int64(0), np.int64(n), np.int64(len(springs.a))
    return [(mesh_provot, (P, R, springs, knobs.enabled, zero, s)),
            (pull_step, (P, R, L, points.free, knobs, pulls, zero, zero)),
            (to_rows, (P, R, zero, count)),
            (refresh_constants, (pulls, knobs.k_over_m))]


def _world(features: set[str], n: int):
    """A world of one of each thing the variant names (see
    :meth:`~.cloth_solver.ClothSolver.variant`), on the 4x4 cloth of :func:`calls`."""
    from types import SimpleNamespace

    from ..motion import Animation, Keyframe
    from ..scene import PlaneSpec, SphereSpec
    from ..world_spec import BoxSpec, WindSpec
    from .colliders.mesh import pack_meshes

    still = Animation((Keyframe(0.0),))
    tetra = SimpleNamespace(vertices=np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]),
                            triangles=np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]), closed=True,
                            pivot=np.zeros(3), animation=None, friction=0.5, margin=1e-3)
    meshes = [tetra] if "meshes" in features else []
    return SimpleNamespace(
        mesh_colliders=meshes, mesh_shapes=pack_meshes(meshes),
        spheres=[SphereSpec((0.0, 0.0, 0.0), 0.1, 0.3)] if "spheres" in features else [],
        planes=[PlaneSpec((0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 0.5)] if "planes" in features else [],
        boxes=[BoxSpec((0.0, 0.0, 0.0), (0.1, 0.1, 0.1), 0.5)] if "boxes" in features else [],
        handles=[SimpleNamespace(points=np.array([0]), start=np.zeros((1, 3)), pivot=np.zeros(3),
                                 animation=still)] if "handles" in features else [],
        wind=WindSpec((1.0, 0.0, 0.0)) if "wind" in features else None)


@njit(cache=False)
def _provot_both(P, springs, enabled, masks, lo, hi):
    """provot with its switch a constant, both ways, as the substep calls it: a
    call from Python would compile it for a run-time switch instead"""
    provot(P, springs, enabled, masks, lo, hi, False)
    provot(P, springs, enabled, masks, lo, lo, True)


def main(variant: str, lock: str | None = None) -> None:
    try:
        for kernel, args in calls(variant):
            kernel(*args)
    finally:
        if lock is not None:
            Path(lock).unlink(missing_ok=True)


if __name__ == "__main__":
    main(*sys.argv[1:3])
