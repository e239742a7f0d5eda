"""One frame of substeps in a single compiled call."""

from __future__ import annotations

import types
from collections.abc import Sequence

import numba
import numpy as np
from numba import njit, prange

from .collide import collide_planes, collide_spheres
from .grid import CHUNK, has_springs, integrate, integrate_range, provot, verlet_gather
from .self_collide import self_collide


PARALLEL_MIN_POINTS = 5000
"""cloths with fewer points run on one thread unless asked: each parallel
region costs about a microsecond to start"""


def parts_for(num_points: int, threads: int | None = None) -> int:
    """How many parts a cloth's substep is cut into: ``threads``, or by default
    numba's thread count for cloths of PARALLEL_MIN_POINTS points and more."""
    if threads is None:
        return 1 if num_points < PARALLEL_MIN_POINTS else int(numba.get_num_threads())
    if threads < 1:
        raise ValueError(f"threads must be at least 1, not {threads}")
    return int(threads)


def pack_spheres(spheres: Sequence) -> np.ndarray:
    """Rows (cx, cy, cz, r, friction) from objects with origin, radius, friction."""
    out = np.zeros((len(spheres), 5))
    for k, s in enumerate(spheres):
        out[k] = (*s.origin, s.radius, s.friction)
    return out


def pack_planes(planes: Sequence) -> np.ndarray:
    """Rows (px, py, pz, nx, ny, nz, friction) from objects with point, normal, friction."""
    out = np.zeros((len(planes), 7))
    for k, p in enumerate(planes):
        out[k] = (*p.point, *p.normal, p.friction)
    return out


@njit(cache=True, boundscheck=False)
def _farthest(P, center):
    """Largest squared distance from ``center``; inf if any coordinate is not finite.
    Compiled without fastmath, which would let LLVM assume the check away."""
    worst = 0.0
    for p in range(P.shape[1]):
        dx = P[0, p] - center[0]
        dy = P[1, p] - center[1]
        dz = P[2, p] - center[2]
        d2 = dx * dx + dy * dy + dz * dz
        if not np.isfinite(d2):
            return np.inf
        if d2 > worst:
            worst = d2
    return worst


@njit(cache=True, boundscheck=False)
def _to_planes(pos, P):
    for p in range(pos.shape[0]):
        for c in range(3):
            P[c, p] = pos[p, c]


@njit(cache=True, boundscheck=False)
def _from_planes(P, pos):
    for p in range(pos.shape[0]):
        for c in range(3):
            pos[p, c] = P[c, p]


def _advance(pos, last, rest, free, gravity, k_over_m, enabled, keep, dt, substeps, simulation_steps,
             start, end, count, valid, rest_length, limit, batch, share, spheres, planes,
             self_collision, thickness, span, P, L, F, masks, lists, handle, handle_pos, center):
    """Run ``substeps`` substeps on ``pos``/``last`` (N, 3) in place.

    Returns (largest squared distance of a point from ``center`` afterwards,
    inf when the state is no longer finite; the neighbour-list pairs array,
    a new one after each build). ``lists`` is the tuple of self-collision buffers,
    ``NeighbourList.buffers()``; ``span`` [m] is the spread of the points
    beyond which the run has blown up and self-collision stops looking.

    Order per substep, as in the CS184 course code: forces, Verlet,
    self-collision, sphere and plane collisions, then the Provot pass.
    ``handle`` (or -1) is a point held at ``handle_pos`` by the user's grab:
    it moves kinematically. The kernels work on (3, N) coordinate planes
    ``P`` (positions) and ``L`` (last positions); ``F`` is the scratch of
    :func:`integrate`, ``masks[t]`` that of :func:`provot` in part t.

    The substep is cut into as many parts as the neighbour list has
    (``NeighbourList(parts=...)``): ranges of points, each moved, collided and
    constrained by one part; the Provot pass then takes the springs across
    the cuts. This body is compiled twice: as :func:`advance`, which runs the
    parts one after another, and as :func:`advance_parallel`, where each
    ``prange`` hands them to threads.
    """
    (cell_start, search, order, slot, sorted_pos, reference, frame, centres, pairs, push, contacts,
     meta, near_offset, near_weight, near_table, near_metric, near_masks, near_level, pos32, extent32,
     touched, tally) = lists
    parts = push.shape[0]
    _to_planes(pos, P)
    _to_planes(last, L)
    dt2 = dt * dt
    n = P.shape[1]
    # a part's last springs reach into the next part's first points: those are
    # moved only once every part has its forces
    held = (end.max() + CHUNK - 1) // CHUNK * CHUNK
    springs = has_springs(k_over_m)
    for _ in range(substeps):
        if parts == 1:
            integrate(P, L, gravity, k_over_m, free, keep, dt2, start, end, count, valid, rest_length, F)
        else:
            for t in prange(parts):
                lo, hi = _chunk_range(n, parts, t)
                integrate_range(P, L, gravity, k_over_m, free, keep, dt2, start, end, count, valid,
                                rest_length, F, lo, hi, lo if t == 0 else min(lo + held, hi))
            for t in range(1, parts):
                lo, hi = _chunk_range(n, parts, t)
                for q in range(lo, min(lo + held, hi), CHUNK):
                    verlet_gather(P, L, gravity, free, keep, dt2, start, end, F, q, min(q + CHUNK, hi), springs)
        if handle >= 0:
            _hold(P, handle, handle_pos)
        if self_collision:
            pairs, _ = self_collide(P, rest, free, thickness, simulation_steps, span, cell_start,
                                    search, order, slot, sorted_pos, reference, frame, centres,
                                    pairs, push, contacts, meta, near_offset, near_weight, near_table,
                                    near_metric, near_masks, near_level, pos32, extent32,
                                    touched, tally)
        if parts == 1:
            collide_spheres(P, L, free, spheres, 0, n)
            collide_planes(P, L, free, planes, 0, n)
            provot(P, enabled, start, end, count, limit, batch, share, masks[0], 0, n,
                   False)
        else:
            for t in prange(parts):
                lo, hi = _chunk_range(n, parts, t)
                collide_spheres(P, L, free, spheres, lo, hi)
                collide_planes(P, L, free, planes, lo, hi)
                provot(P, enabled, start, end, count, limit, batch, share, masks[t],
                       lo, hi, False)
            for t in range(1, parts):
                lo, _ = _chunk_range(n, parts, t)
                provot(P, enabled, start, end, count, limit, batch, share, masks[0],
                       lo, lo, True)
        if handle >= 0:
            _hold(P, handle, handle_pos)
    _from_planes(P, pos)
    _from_planes(L, last)
    return _farthest(P, center), pairs


def _renamed(f, name: str):
    """A copy of function f under another name: numba caches compiled code by
    the function's name, and the serial and parallel builds of one body must
    not share a cache entry."""
    g = types.FunctionType(f.__code__, f.__globals__, name, f.__defaults__, f.__closure__)
    g.__qualname__ = name
    g.__module__ = f.__module__
    g.__doc__ = f.__doc__
    return g


ADVANCE_OPTIONS = dict(cache=True, boundscheck=False, error_model="numpy")
advance = njit(**ADVANCE_OPTIONS)(_renamed(_advance, "advance"))
advance_parallel = njit(**ADVANCE_OPTIONS, parallel=True)(_renamed(_advance, "advance_parallel"))


@njit(cache=True, inline="always")
def _chunk_range(n, parts, t):
    """Points ``lo:hi`` of part t of ``parts``, cut at multiples of CHUNK."""
    size = ((n + parts - 1) // parts + CHUNK - 1) // CHUNK * CHUNK
    return min(t * size, n), min((t + 1) * size, n)


@njit(cache=True, inline="always")
def _hold(P, handle, target):
    P[0, handle] = target[0]
    P[1, handle] = target[1]
    P[2, handle] = target[2]
