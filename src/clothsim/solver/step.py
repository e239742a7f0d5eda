"""One frame of substeps in a single compiled call."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit

from .collide import collide_planes, collide_spheres
from .grid import integrate, provot
from .self_collide import self_collide


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


@njit(cache=True, boundscheck=False)
def advance(pos, last, rest, free, gravity, k_over_m, enabled, keep, dt, substeps, simulation_steps,
            start, end, count, valid, rest_length, limit, share, runs, run_span, spheres, planes,
            self_collision, thickness, span, P, L, F, c, over, lists, handle, handle_pos, center):
    """Run ``substeps`` substeps on ``pos``/``last`` (N, 3) in place.

    Returns (largest squared distance of a point from ``center`` afterwards,
    inf when the state is no longer finite; the neighbour-list pairs array,
    replaced when it grew). ``lists`` is the tuple of self-collision buffers,
    ``NeighbourList.buffers()``; ``span`` [m] is the spread of the points
    beyond which the run has blown up and self-collision stops looking.

    Order per substep, as in the CS184 course code: forces, Verlet,
    self-collision, sphere and plane collisions, then the Provot pass.
    ``handle`` (or -1) is a point held at ``handle_pos`` by the user's grab:
    it moves kinematically. The kernels work on (3, N) coordinate planes
    ``P`` (positions) and ``L`` (last positions); ``F``, ``c`` and ``over``
    are the scratch of :func:`integrate` and :func:`provot`.
    """
    (cell_start, cell_of, order, slot, sorted_pos, candidates, reference, pairs, push, contacts, meta,
     near_offset, near_weight, near_table, near_flags, near_scratch) = lists
    _to_planes(pos, P)
    _to_planes(last, L)
    dt2 = dt * dt
    for _ in range(substeps):
        integrate(P, L, gravity, k_over_m, free, keep, dt2, start, end, count, valid, rest_length, F)
        if handle >= 0:
            _hold(P, handle, handle_pos)
        if self_collision:
            pairs, _ = self_collide(P, rest, free, thickness, simulation_steps, span, cell_start,
                                    cell_of, order, slot, sorted_pos, candidates, reference, pairs, push,
                                    contacts, meta, near_offset, near_weight, near_table,
                                    near_flags, near_scratch)
        collide_spheres(P, L, free, spheres)
        collide_planes(P, L, free, planes)
        provot(P, enabled, start, end, count, limit, share, runs, run_span, c, over)
        if handle >= 0:
            _hold(P, handle, handle_pos)
    _from_planes(P, pos)
    _from_planes(L, last)
    return _farthest(P, center), pairs


@njit(cache=True, inline="always")
def _hold(P, handle, target):
    P[0, handle] = target[0]
    P[1, handle] = target[1]
    P[2, handle] = target[2]
