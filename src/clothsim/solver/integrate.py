"""Forces (gravity, Hooke springs) and the damped Verlet update."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, fastmath=True, boundscheck=False, inline="always")
def _spring_force(pos, acc, a, b, rest, k):
    """Hooke's law along the spring a-b, added to a and subtracted from b."""
    dx = pos[b, 0] - pos[a, 0]
    dy = pos[b, 1] - pos[a, 1]
    dz = pos[b, 2] - pos[a, 2]
    length = np.sqrt(dx * dx + dy * dy + dz * dz)
    if length == 0.0:
        return
    f = k * (length - rest) / length
    fx, fy, fz = f * dx, f * dy, f * dz
    acc[a, 0] += fx
    acc[a, 1] += fy
    acc[a, 2] += fz
    acc[b, 0] -= fx
    acc[b, 1] -= fy
    acc[b, 2] -= fz


@njit(cache=True, fastmath=True, boundscheck=False)
def accumulate_accelerations(pos, acc, gravity, spring_a, spring_b, spring_rest, kind_start, k_over_m):
    """acc <- gravity + spring forces / mass [m/s²].

    Springs are grouped by kind: kind k spans ``kind_start[k] : kind_start[k+1]``.
    ``k_over_m[k]`` is its spring constant divided by the point mass, 0 when the
    kind is disabled; uniform masses let one division serve all springs.
    """
    gx, gy, gz = gravity[0], gravity[1], gravity[2]
    for p in range(pos.shape[0]):
        acc[p, 0] = gx
        acc[p, 1] = gy
        acc[p, 2] = gz
    for kind in range(k_over_m.shape[0]):
        k = k_over_m[kind]
        if k == 0.0:
            continue
        for s in range(kind_start[kind], kind_start[kind + 1]):
            _spring_force(pos, acc, spring_a[s], spring_b[s], spring_rest[s], k)


@njit(cache=True, fastmath=True, boundscheck=False)
def verlet(pos, last, acc, pinned, keep, dt2):
    """x' = x + keep*(x - x_prev) + a dt², keep = 1 - damping/100; pinned points stay."""
    for p in range(pos.shape[0]):
        if pinned[p]:
            continue
        for c in range(3):
            x = pos[p, c]
            pos[p, c] = x + keep * (x - last[p, c]) + acc[p, c] * dt2
            last[p, c] = x
