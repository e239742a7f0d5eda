"""Planes: points that crossed one are put back on their old side, with CS184 friction.

A plane is a row ``(px, py, pz, nx, ny, nz, friction, carry...)`` of float64
rows (T, K, 7 + CARRY) (see :mod:`.motion_rows`): a point of it and its unit
normal at the end of the substep, and how it moved over it. Positions are
(3, N) coordinate planes. Each loop is a branch-free select so that it
vectorises.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit

from ..blend import write_point
from ..shared import KERNEL_OPTIONS
from .motion_rows import carry_of, carry_point, frame_poses, moving_rows, stack_slots

PLANE_OFFSET = 1e-4
"""distance from the plane at which a point that crossed it is put back [m]"""


def pack(planes: Sequence, t0: float = 0.0, dt: float = 0.0, substeps: int = 1) -> np.ndarray | None:
    """Rows from objects with point, normal, friction and animation (or None) for a
    frame of ``substeps`` substeps of ``dt`` [s] from ``t0``; None when there are
    none, so that :func:`collide_planes` is not compiled. A moving plane turns
    about its ``point``."""
    if not planes:
        return None
    out = []
    for p in planes:
        R, o, carry = frame_poses(getattr(p, "animation", None), p.point, t0, dt, substeps)
        out.append(moving_rows(R, o, carry, points=p.point, directions=p.normal, fixed=(p.friction,)))
    return stack_slots(out)


@njit(**KERNEL_OPTIONS)
def collide_planes(P, L, free, planes, lo, hi, s):
    """Points ``lo:hi`` that crossed a plane over substep ``s`` are put back on their
    old side, PLANE_OFFSET off the plane, then moved toward their last position
    (carried along by the plane's motion) by friction.
    ``planes`` None: nothing (the branch is pruned when numba compiles it)."""
    if planes is None:
        return
    rows = planes[min(s, planes.shape[0] - 1)]
    moving = planes.shape[0] > 1
    x, y, z = P[0, lo:hi], P[1, lo:hi], P[2, lo:hi]
    lx, ly, lz = L[0, lo:], L[1, lo:], L[2, lo:]
    free = free[lo:]
    for k in range(rows.shape[0]):
        row = rows[k]
        px, py, pz = row[0], row[1], row[2]
        nx, ny, nz = row[3], row[4], row[5]
        keep = 1.0 - row[6]
        if not moving:  # the course code's loop, to the bit: no carry in its sums
            for p in range(x.shape[0]):
                # whole stores, not masked ones (see ..blend); the test
                # without short cuts, so that free[p] is read for every point
                xp, yp, zp = x[p], y[p], z[p]
                d_now = (xp - px) * nx + (yp - py) * ny + (zp - pz) * nz
                d_last = (lx[p] - px) * nx + (ly[p] - py) * ny + (lz[p] - pz) * nz
                side = 1.0 if d_last >= 0.0 else -1.0
                hit = (d_now * side <= 0.0) & (free[p] != 0.0)
                # tangent point on the plane, lifted to the old side
                move = side * PLANE_OFFSET - d_now
                tx = lx[p] + keep * (xp + move * nx - lx[p])
                ty = ly[p] + keep * (yp + move * ny - ly[p])
                tz = lz[p] + keep * (zp + move * nz - lz[p])
                write_point((x, y, z), p, hit, (tx, ty, tz), (xp, yp, zp))
            continue
        a = carry_of(row, 7)
        for p in range(x.shape[0]):
            xp, yp, zp = x[p], y[p], z[p]
            mx, my, mz = carry_point(a, lx[p], ly[p], lz[p])
            d_now = (xp - px) * nx + (yp - py) * ny + (zp - pz) * nz
            d_last = (mx - px) * nx + (my - py) * ny + (mz - pz) * nz
            side = 1.0 if d_last >= 0.0 else -1.0
            hit = (d_now * side <= 0.0) & (free[p] != 0.0)
            move = side * PLANE_OFFSET - d_now
            tx = mx + keep * (xp + move * nx - mx)
            ty = my + keep * (yp + move * ny - my)
            tz = mz + keep * (zp + move * nz - mz)
            write_point((x, y, z), p, hit, (tx, ty, tz), (xp, yp, zp))
