"""Self-collision: a spatial hash feeding a neighbour list with a skin.

Every pair closer than ``reach = 2*thickness`` is pushed apart. Finding those
pairs with a spatial hash costs far more than pushing them, and between two
substeps the points barely move relative to each other. So the hash is asked
for every pair within ``reach + skin`` (a neighbour list, as in molecular
dynamics), and each substep only tests the listed pairs. The list is rebuilt
as soon as any point may have come within ``reach`` of a point not listed:
when, after taking out the cloth's mean motion since the build, some point
has moved more than ``skin/2``. Two unlisted points started at least
``reach + skin`` apart and each moved less than ``skin/2`` relative to the
common motion, so they are still farther apart than ``reach``; the pairs
found are exactly those a hash rebuilt every substep would find.

The hash is a counting sort of the points by hashed cell, so a rebuild is a
few linear passes. A point looks in every cell that its search sphere
overlaps, its own and the adjacent ones, so no pair is missed at a cell border.
Pairs already closer than ``reach`` at rest (neighbours on a fine grid) never
enter the list: the C++ course code pushes them apart, and its fine cloths
then fight their own springs and boil.

Positions are (3, N) coordinate planes; ``rest`` is the (N, 3) start layout.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .grid import KERNEL_OPTIONS

SKIN_FACTOR = 0.5
"""skin of the neighbour list as a fraction of the reach: larger lists, rarer rebuilds"""

CELL_FACTOR = 2.0
"""hash cell size over the search radius: each point then looks in 2x2x2 cells"""

# fields of the ``meta`` int64 array that carries the list's state between calls
PAIRS, VALID, REBUILDS = 0, 1, 2
META_SIZE = 3


def table_size(num_points: int) -> int:
    """Power of two at least twice the point count, so buckets stay short."""
    size = 1
    while size < 2 * num_points:
        size *= 2
    return size


class NeighbourList:
    """The buffers of the hash and the neighbour list, allocated once per cloth."""

    def __init__(self, num_points: int) -> None:
        n = num_points
        self.bucket_start = np.zeros(table_size(n) + 1, dtype=np.int64)
        self.order = np.zeros(n, dtype=np.int64)
        self.sorted_pos = np.zeros((n, 6))  # position and rest position per slot
        self.sorted_key = np.zeros(n, dtype=np.int64)
        self.reference = np.zeros((3, n))
        self.pairs = np.zeros((2, 4 * n), dtype=np.int32)
        self.push = np.zeros((3, n))
        self.count = np.zeros(n)
        self.meta = np.zeros(META_SIZE, dtype=np.int64)

    @property
    def num_pairs(self) -> int:
        """pairs within reach + skin at the last rebuild"""
        return int(self.meta[PAIRS])

    @property
    def rebuilds(self) -> int:
        return int(self.meta[REBUILDS])


@njit(cache=True, inline="always")
def _bucket(cx, cy, cz, mask):
    h = (cx * 73856093) ^ (cy * 19349663) ^ (cz * 83492791)
    return h & mask


@njit(cache=True, inline="always")
def _cell_key(cx, cy, cz):
    """One integer per cell, unique while |cell index| < 2**20 on every axis."""
    return (cx & 0x1FFFFF) | ((cy & 0x1FFFFF) << 21) | ((cz & 0x1FFFFF) << 42)


@njit(**KERNEL_OPTIONS)
def _sort_into_cells(P, rest, inv_cell, bucket_start, order, sorted_pos, sorted_key):
    """Counting-sort the points by hashed cell.

    Afterwards bucket b holds sorted slots ``bucket_start[b] : bucket_start[b+1]``;
    ``order[k]`` is the point in slot k, and its position, rest position and
    cell key are copied to slot k so that a neighbour query reads contiguous
    memory. Returns the inverse of ``order``: the slot of each point.
    """
    n = P.shape[1]
    mask = bucket_start.shape[0] - 2
    bucket_start[:] = 0
    for p in range(n):
        cx = np.int64(np.floor(P[0, p] * inv_cell))
        cy = np.int64(np.floor(P[1, p] * inv_cell))
        cz = np.int64(np.floor(P[2, p] * inv_cell))
        order[p] = _bucket(cx, cy, cz, mask)  # staged here, replaced by the slot order below
        sorted_key[p] = _cell_key(cx, cy, cz)
        bucket_start[order[p] + 1] += 1
    for t in range(1, bucket_start.shape[0]):
        bucket_start[t] += bucket_start[t - 1]
    # place each point at the end of its bucket's remaining room, from the last point
    # down, so slots keep point order; afterwards bucket_start[b + 1] holds start(b)
    slot = np.empty(n, dtype=np.int64)
    for p in range(n - 1, -1, -1):
        b = order[p]
        bucket_start[b + 1] -= 1
        slot[p] = bucket_start[b + 1]
    last = bucket_start.shape[0] - 1
    for t in range(last):
        bucket_start[t] = bucket_start[t + 1]
    bucket_start[last] = n
    keys = sorted_key.copy()
    for p in range(n):
        k = slot[p]
        order[k] = p
        sorted_key[k] = keys[p]
        for c in range(3):
            sorted_pos[k, c] = P[c, p]
            sorted_pos[k, 3 + c] = rest[p, c]
    return slot


@njit(**KERNEL_OPTIONS)
def build_list(P, rest, reach, radius, cell, bucket_start, order, sorted_pos, sorted_key, pairs):
    """Every pair of points closer than ``radius`` and not closer than ``reach`` at
    rest, each pair once, into ``pairs`` (2, capacity); returns how many there
    are, which may exceed the capacity: then only the first ones were stored.
    """
    n = P.shape[1]
    inv_cell = 1.0 / cell
    slot_of = _sort_into_cells(P, rest, inv_cell, bucket_start, order, sorted_pos, sorted_key)
    mask = bucket_start.shape[0] - 2
    radius2 = radius * radius
    reach2 = reach * reach
    capacity = pairs.shape[1]
    found = 0
    # points in index order, so the list is sorted by its first point and the
    # substep's pass over it walks the cloth in memory order
    for pk in range(n):
        k = slot_of[pk]
        x, y, z = sorted_pos[k, 0], sorted_pos[k, 1], sorted_pos[k, 2]
        rx, ry, rz = sorted_pos[k, 3], sorted_pos[k, 4], sorted_pos[k, 5]
        x0 = np.int64(np.floor((x - radius) * inv_cell))
        x1 = np.int64(np.floor((x + radius) * inv_cell))
        y0 = np.int64(np.floor((y - radius) * inv_cell))
        y1 = np.int64(np.floor((y + radius) * inv_cell))
        z0 = np.int64(np.floor((z - radius) * inv_cell))
        z1 = np.int64(np.floor((z + radius) * inv_cell))
        for cx in range(x0, x1 + 1):
            for cy in range(y0, y1 + 1):
                for cz in range(z0, z1 + 1):
                    b = _bucket(cx, cy, cz, mask)
                    key = _cell_key(cx, cy, cz)
                    for q in range(max(bucket_start[b], k + 1), bucket_start[b + 1]):
                        dx = x - sorted_pos[q, 0]
                        dy = y - sorted_pos[q, 1]
                        dz = z - sorted_pos[q, 2]
                        if dx * dx + dy * dy + dz * dz >= radius2 or sorted_key[q] != key:
                            continue  # too far, or another cell hashed into this bucket
                        ex = rx - sorted_pos[q, 3]
                        ey = ry - sorted_pos[q, 4]
                        ez = rz - sorted_pos[q, 5]
                        if ex * ex + ey * ey + ez * ez < reach2:
                            continue
                        if found < capacity:
                            pairs[0, found] = pk
                            pairs[1, found] = order[q]
                        found += 1
    return found


@njit(**KERNEL_OPTIONS)
def _drifted(P, reference, limit):
    """Whether some point moved more than ``limit`` since the list was built,
    after the cloth's mean motion is taken out."""
    n = P.shape[1]
    mean = np.zeros(3)
    for c in range(3):
        s = 0.0
        x, r = P[c], reference[c]
        for p in range(n):
            s += x[p] - r[p]
        mean[c] = s / n
    worst = 0.0
    mx, my, mz = mean[0], mean[1], mean[2]
    x, y, z = P[0], P[1], P[2]
    rx, ry, rz = reference[0], reference[1], reference[2]
    for p in range(n):
        dx = x[p] - rx[p] - mx
        dy = y[p] - ry[p] - my
        dz = z[p] - rz[p] - mz
        worst = max(worst, dx * dx + dy * dy + dz * dz)
    return not worst <= limit * limit  # NaN counts as drifted


@njit(**KERNEL_OPTIONS)
def self_collide(P, rest, free, thickness, simulation_steps, bucket_start, order, sorted_pos,
                 sorted_key, reference, pairs, push, count, meta):
    """Push apart pairs closer than 2*thickness (Jacobi: all from the same positions).

    Each pair pushes both ends; a point's pushes are averaged over its
    colliding neighbours and divided by ``simulation_steps``; pinned points
    (``free`` 0) stay. Returns (pairs array, number of colliding pairs); the
    array is a new one when the list outgrew it.
    """
    n = P.shape[1]
    reach = 2.0 * thickness
    skin = SKIN_FACTOR * reach
    if meta[VALID] == 0 or _drifted(P, reference, 0.5 * skin):
        radius = reach + skin
        found = build_list(P, rest, reach, radius, CELL_FACTOR * radius, bucket_start, order,
                           sorted_pos, sorted_key, pairs)
        if found > pairs.shape[1]:
            pairs = np.empty((2, 2 * found), dtype=np.int32)
            build_list(P, rest, reach, radius, CELL_FACTOR * radius, bucket_start, order,
                       sorted_pos, sorted_key, pairs)
        meta[PAIRS] = found
        reference[:] = P
        meta[VALID] = 1
        meta[REBUILDS] += 1
    push[:] = 0.0
    count[:] = 0.0
    reach2 = reach * reach
    x, y, z = P[0], P[1], P[2]
    hits = 0
    for k in range(meta[PAIRS]):
        a = pairs[0, k]
        b = pairs[1, k]
        dx = x[a] - x[b]
        dy = y[a] - y[b]
        dz = z[a] - z[b]
        d2 = dx * dx + dy * dy + dz * dz
        if d2 >= reach2 or d2 == 0.0:
            continue
        d = np.sqrt(d2)
        s = (reach - d) / d
        push[0, a] += dx * s
        push[1, a] += dy * s
        push[2, a] += dz * s
        push[0, b] -= dx * s
        push[1, b] -= dy * s
        push[2, b] -= dz * s
        count[a] += 1.0
        count[b] += 1.0
        hits += 1
    if hits > 0:
        inv_steps = 1.0 / simulation_steps
        for c in range(3):
            xc, pc = P[c], push[c]
            for p in range(n):
                xc[p] += pc[p] * free[p] * inv_steps / max(count[p], 1.0)
    return pairs, hits
