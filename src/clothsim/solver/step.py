"""One frame of substeps in a single compiled call."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit

from .collide import collide_planes, collide_spheres
from .constrain import provot
from .integrate import accumulate_accelerations, verlet
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


@njit(cache=True, fastmath=True, boundscheck=False)
def _farthest(pos, center):
    """Largest squared distance from ``center``; inf if any coordinate is not finite."""
    worst = 0.0
    for p in range(pos.shape[0]):
        dx = pos[p, 0] - center[0]
        dy = pos[p, 1] - center[1]
        dz = pos[p, 2] - center[2]
        d2 = dx * dx + dy * dy + dz * dz
        if not np.isfinite(d2):
            return np.inf
        if d2 > worst:
            worst = d2
    return worst


@njit(cache=True, fastmath=False, boundscheck=False)
def advance(pos, last, acc, rest, pinned, spring_a, spring_b, spring_rest, kind_start,
            k_over_m, enabled, gravity, keep, dt, substeps, simulation_steps, spheres, planes,
            self_collision, thickness, cell_size, bucket_start, order, sorted_pos, sorted_rest, sorted_cell,
            push, count, handle, handle_pos, center):
    """Run ``substeps`` substeps in place; return the largest squared distance of a
    point from ``center`` afterwards (inf when the state is no longer finite).

    Order per substep, as in the CS184 course code: forces, Verlet, self-collision,
    sphere and plane collisions, then the Provot pass. ``handle`` (or -1) is a
    point held at ``handle_pos`` by the user's grab: it moves kinematically.
    """
    dt2 = dt * dt
    for _ in range(substeps):
        accumulate_accelerations(pos, acc, gravity, spring_a, spring_b, spring_rest, kind_start, k_over_m)
        verlet(pos, last, acc, pinned, keep, dt2)
        if handle >= 0:
            _hold(pos, handle, handle_pos)
        if self_collision:
            self_collide(pos, rest, pinned, thickness, cell_size, simulation_steps,
                         bucket_start, order, sorted_pos, sorted_rest, sorted_cell, push, count)
        collide_spheres(pos, last, pinned, spheres)
        collide_planes(pos, last, pinned, planes)
        provot(pos, pinned, spring_a, spring_b, spring_rest, kind_start, enabled)
        if handle >= 0:
            _hold(pos, handle, handle_pos)
    return _farthest(pos, center)


@njit(cache=True, inline="always")
def _hold(pos, handle, target):
    pos[handle, 0] = target[0]
    pos[handle, 1] = target[1]
    pos[handle, 2] = target[2]
