"""Planes: points that crossed one are put back on their old side, with CS184 friction.

A plane is a row ``(px, py, pz, nx, ny, nz, friction)`` of a float64 array,
(K, 7), with a unit normal; positions are (3, N) coordinate planes. The loop
is a branch-free select so that it vectorises.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit

from ..shared import KERNEL_OPTIONS

PLANE_OFFSET = 1e-4
"""distance from the plane at which a point that crossed it is put back [m]"""


def pack(planes: Sequence) -> np.ndarray | None:
    """Rows (px, py, pz, nx, ny, nz, friction) from objects with point, normal,
    friction; None when there are none, so that :func:`collide_planes` is not compiled."""
    if not planes:
        return None
    out = np.zeros((len(planes), 7))
    for k, p in enumerate(planes):
        out[k] = (*p.point, *p.normal, p.friction)
    return out


@njit(**KERNEL_OPTIONS)
def collide_planes(P, L, free, planes, lo, hi):
    """Points ``lo:hi`` that crossed a plane since the last substep are put back on their
    old side, PLANE_OFFSET off the plane, then moved toward their last position by friction.
    ``planes`` None: nothing (the branch is pruned when numba compiles it)."""
    if planes is None:
        return
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
