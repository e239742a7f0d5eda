"""Collisions with spheres and planes, with CS184 friction.

Positions are (3, N) coordinate planes (see :mod:`clothsim.solver.grid`). A
collider is a row of a float64 array: spheres ``(cx, cy, cz, r, friction)``,
planes ``(px, py, pz, nx, ny, nz, friction)`` with a unit normal. The loops
are branch-free selects so that they vectorise.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .grid import KERNEL_OPTIONS

PLANE_OFFSET = 1e-4
"""distance from the plane at which a point that crossed it is put back [m]"""


@njit(**KERNEL_OPTIONS)
def collide_spheres(P, L, free, spheres, lo, hi):
    """Points ``lo:hi`` inside a sphere go to the surface along the ray from the centre,
    then back toward their last position by the friction: last + (1-f)(surface-last)."""
    x, y, z = P[0, lo:hi], P[1, lo:hi], P[2, lo:hi]
    lx, ly, lz = L[0, lo:], L[1, lo:], L[2, lo:]
    free = free[lo:]
    for k in range(spheres.shape[0]):
        cx, cy, cz, r, fr = spheres[k, 0], spheres[k, 1], spheres[k, 2], spheres[k, 3], spheres[k, 4]
        r2 = r * r
        keep = 1.0 - fr
        for p in range(x.shape[0]):
            dx = x[p] - cx
            dy = y[p] - cy
            dz = z[p] - cz
            d2 = dx * dx + dy * dy + dz * dz
            hit = d2 < r2 and d2 > 0.0 and free[p] != 0.0
            s = r / np.sqrt(d2 if hit else 1.0)
            nx = lx[p] + keep * (cx + dx * s - lx[p])
            ny = ly[p] + keep * (cy + dy * s - ly[p])
            nz = lz[p] + keep * (cz + dz * s - lz[p])
            x[p] = nx if hit else x[p]
            y[p] = ny if hit else y[p]
            z[p] = nz if hit else z[p]


@njit(**KERNEL_OPTIONS)
def collide_planes(P, L, free, planes, lo, hi):
    """Points ``lo:hi`` that crossed a plane since the last substep are put back on their
    old side, PLANE_OFFSET off the plane, then moved toward their last position by friction."""
    x, y, z = P[0, lo:hi], P[1, lo:hi], P[2, lo:hi]
    lx, ly, lz = L[0, lo:], L[1, lo:], L[2, lo:]
    free = free[lo:]
    for k in range(planes.shape[0]):
        px, py, pz = planes[k, 0], planes[k, 1], planes[k, 2]
        nx, ny, nz = planes[k, 3], planes[k, 4], planes[k, 5]
        keep = 1.0 - planes[k, 6]
        for p in range(x.shape[0]):
            d_now = (x[p] - px) * nx + (y[p] - py) * ny + (z[p] - pz) * nz
            d_last = (lx[p] - px) * nx + (ly[p] - py) * ny + (lz[p] - pz) * nz
            side = 1.0 if d_last >= 0.0 else -1.0
            hit = d_now * side <= 0.0 and free[p] != 0.0
            # tangent point on the plane, lifted to the old side
            move = side * PLANE_OFFSET - d_now
            tx = lx[p] + keep * (x[p] + move * nx - lx[p])
            ty = ly[p] + keep * (y[p] + move * ny - ly[p])
            tz = lz[p] + keep * (z[p] + move * nz - lz[p])
            x[p] = tx if hit else x[p]
            y[p] = ty if hit else y[p]
            z[p] = tz if hit else z[p]
