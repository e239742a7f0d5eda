"""Self-collision through a spatial hash rebuilt every substep.

The hash is a counting sort of the points by hashed cell, so a rebuild is
three linear passes with no allocation. A point looks only in the cells that
its collision sphere (radius ``2*thickness``) overlaps, its own and the
adjacent ones, so no pair is missed at a cell border.
"""

from __future__ import annotations

import numpy as np
from numba import njit


def table_size(num_points: int) -> int:
    """Power of two at least twice the point count, so buckets stay short."""
    size = 1
    while size < 2 * num_points:
        size *= 2
    return size


@njit(cache=True, inline="always")
def _bucket(cx, cy, cz, mask):
    h = (cx * 73856093) ^ (cy * 19349663) ^ (cz * 83492791)
    return h & mask


@njit(cache=True, fastmath=True, boundscheck=False)
def build_hash(pos, rest, inv_cell, bucket_start, order, sorted_pos, sorted_rest, sorted_cell):
    """Counting-sort the points by hashed cell.

    Afterwards bucket b holds sorted slots ``bucket_start[b] : bucket_start[b+1]``;
    ``order[k]`` is the point in slot k, and its position, rest position and cell
    are copied to slot k so that a neighbour query reads contiguous memory.
    """
    n = pos.shape[0]
    mask = bucket_start.shape[0] - 2
    bucket_start[:] = 0
    for p in range(n):
        cx = np.int64(np.floor(pos[p, 0] * inv_cell))
        cy = np.int64(np.floor(pos[p, 1] * inv_cell))
        cz = np.int64(np.floor(pos[p, 2] * inv_cell))
        sorted_cell[p, 0] = cx  # staged by point index, moved to slots below
        sorted_cell[p, 1] = cy
        sorted_cell[p, 2] = cz
        bucket_start[_bucket(cx, cy, cz, mask) + 1] += 1
    for t in range(1, bucket_start.shape[0]):
        bucket_start[t] += bucket_start[t - 1]
    # fill each bucket from its end downward; afterwards bucket_start[b + 1] holds start(b)
    for p in range(n):
        b = _bucket(sorted_cell[p, 0], sorted_cell[p, 1], sorted_cell[p, 2], mask)
        bucket_start[b + 1] -= 1
        order[bucket_start[b + 1]] = p
    last = bucket_start.shape[0] - 1
    for t in range(last):
        bucket_start[t] = bucket_start[t + 1]
    bucket_start[last] = n
    for k in range(n):
        p = order[k]
        for c in range(3):
            sorted_pos[k, c] = pos[p, c]
            sorted_rest[k, c] = rest[p, c]
    for k in range(n):
        p = order[k]
        sorted_cell[k, 0] = np.int64(np.floor(pos[p, 0] * inv_cell))
        sorted_cell[k, 1] = np.int64(np.floor(pos[p, 1] * inv_cell))
        sorted_cell[k, 2] = np.int64(np.floor(pos[p, 2] * inv_cell))


@njit(cache=True, fastmath=True, boundscheck=False)
def self_collide(pos, rest, pinned, thickness, cell_size, simulation_steps,
                 bucket_start, order, sorted_pos, sorted_rest, sorted_cell, push, count):
    """Push apart pairs closer than 2*thickness (Jacobi: all from the same positions).

    Each pair is found once, from its lower sorted slot, and pushes both ends;
    a point's pushes are averaged over its colliding neighbours and divided by
    ``simulation_steps``. Pairs already closer than 2*thickness at rest
    (neighbours on a fine grid) are left alone, otherwise such a cloth fights
    its own springs and boils. Returns the number of colliding pairs.
    """
    n = pos.shape[0]
    inv_cell = 1.0 / cell_size
    build_hash(pos, rest, inv_cell, bucket_start, order, sorted_pos, sorted_rest, sorted_cell)
    mask = bucket_start.shape[0] - 2
    reach = 2.0 * thickness
    reach2 = reach * reach
    push[:] = 0.0
    count[:] = 0
    pairs = 0
    for k in range(n):
        x, y, z = sorted_pos[k, 0], sorted_pos[k, 1], sorted_pos[k, 2]
        rx0, ry0, rz0 = sorted_rest[k, 0], sorted_rest[k, 1], sorted_rest[k, 2]
        x0 = np.int64(np.floor((x - reach) * inv_cell))
        x1 = np.int64(np.floor((x + reach) * inv_cell))
        y0 = np.int64(np.floor((y - reach) * inv_cell))
        y1 = np.int64(np.floor((y + reach) * inv_cell))
        z0 = np.int64(np.floor((z - reach) * inv_cell))
        z1 = np.int64(np.floor((z + reach) * inv_cell))
        for cx in range(x0, x1 + 1):
            for cy in range(y0, y1 + 1):
                for cz in range(z0, z1 + 1):
                    b = _bucket(cx, cy, cz, mask)
                    for q in range(max(bucket_start[b], k + 1), bucket_start[b + 1]):
                        dx = x - sorted_pos[q, 0]
                        dy = y - sorted_pos[q, 1]
                        dz = z - sorted_pos[q, 2]
                        d2 = dx * dx + dy * dy + dz * dz
                        if d2 >= reach2 or d2 == 0.0:
                            continue
                        if sorted_cell[q, 0] != cx or sorted_cell[q, 1] != cy or sorted_cell[q, 2] != cz:
                            continue  # another cell hashed into this bucket; seen from its own cell
                        rx = rx0 - sorted_rest[q, 0]
                        ry = ry0 - sorted_rest[q, 1]
                        rz = rz0 - sorted_rest[q, 2]
                        if rx * rx + ry * ry + rz * rz < reach2:
                            continue
                        d = np.sqrt(d2)
                        s = (reach - d) / d
                        push[k, 0] += dx * s
                        push[k, 1] += dy * s
                        push[k, 2] += dz * s
                        push[q, 0] -= dx * s
                        push[q, 1] -= dy * s
                        push[q, 2] -= dz * s
                        count[k] += 1
                        count[q] += 1
                        pairs += 1
    inv_steps = 1.0 / simulation_steps
    for k in range(n):
        p = order[k]
        if count[k] == 0 or pinned[p]:
            continue
        scale = inv_steps / count[k]
        pos[p, 0] += push[k, 0] * scale
        pos[p, 1] += push[k, 1] * scale
        pos[p, 2] += push[k, 2] * scale
    return pairs
