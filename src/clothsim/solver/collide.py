"""Collisions with spheres and planes, with CS184 friction.

A collider is a row of a float64 array: spheres ``(cx, cy, cz, r, friction)``,
planes ``(px, py, pz, nx, ny, nz, friction)`` with a unit normal.
"""

from __future__ import annotations

import numpy as np
from numba import njit

PLANE_OFFSET = 1e-4
"""distance from the plane at which a point that crossed it is put back [m]"""


@njit(cache=True, fastmath=True, boundscheck=False)
def collide_spheres(pos, last, pinned, spheres):
    """A point inside a sphere goes to the surface along the ray from the centre,
    then back toward its last position by the friction: last + (1-f)(surface-last)."""
    for k in range(spheres.shape[0]):
        cx, cy, cz, r, fr = spheres[k, 0], spheres[k, 1], spheres[k, 2], spheres[k, 3], spheres[k, 4]
        r2 = r * r
        keep = 1.0 - fr
        for p in range(pos.shape[0]):
            if pinned[p]:
                continue
            dx = pos[p, 0] - cx
            dy = pos[p, 1] - cy
            dz = pos[p, 2] - cz
            d2 = dx * dx + dy * dy + dz * dz
            if d2 >= r2 or d2 == 0.0:
                continue
            s = r / np.sqrt(d2)
            sx, sy, sz = cx + dx * s, cy + dy * s, cz + dz * s
            pos[p, 0] = last[p, 0] + keep * (sx - last[p, 0])
            pos[p, 1] = last[p, 1] + keep * (sy - last[p, 1])
            pos[p, 2] = last[p, 2] + keep * (sz - last[p, 2])


@njit(cache=True, fastmath=True, boundscheck=False)
def collide_planes(pos, last, pinned, planes):
    """A point that crossed a plane since the last substep is put back on its old
    side, PLANE_OFFSET off the plane, then moved toward its last position by friction."""
    for k in range(planes.shape[0]):
        px, py, pz = planes[k, 0], planes[k, 1], planes[k, 2]
        nx, ny, nz = planes[k, 3], planes[k, 4], planes[k, 5]
        keep = 1.0 - planes[k, 6]
        for p in range(pos.shape[0]):
            if pinned[p]:
                continue
            d_now = (pos[p, 0] - px) * nx + (pos[p, 1] - py) * ny + (pos[p, 2] - pz) * nz
            d_last = (last[p, 0] - px) * nx + (last[p, 1] - py) * ny + (last[p, 2] - pz) * nz
            side = 1.0 if d_last >= 0.0 else -1.0
            if d_now * side > 0.0:
                continue
            # tangent point on the plane, lifted to the old side
            move = side * PLANE_OFFSET - d_now
            tx = pos[p, 0] + move * nx
            ty = pos[p, 1] + move * ny
            tz = pos[p, 2] + move * nz
            pos[p, 0] = last[p, 0] + keep * (tx - last[p, 0])
            pos[p, 1] = last[p, 1] + keep * (ty - last[p, 1])
            pos[p, 2] = last[p, 2] + keep * (tz - last[p, 2])
