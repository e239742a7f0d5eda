"""Spheres: points inside are put on the surface, with CS184 friction.

A sphere is a row ``(cx, cy, cz, r, friction, carry...)`` of float64 rows
(T, K, 5 + CARRY) (see :mod:`.motion_rows`): its centre at the end of the
substep and how it moved over it. Positions are (3, N) coordinate planes
(see :mod:`clothsim.solver.springs`). Each loop is a branch-free select so
that it vectorises.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit

from ..shared import KERNEL_OPTIONS
from .motion_rows import carry_of, carry_point, frame_poses, moving_rows, stack_slots


def pack(spheres: Sequence, t0: float = 0.0, dt: float = 0.0, substeps: int = 1) -> np.ndarray | None:
    """Rows from objects with origin, radius, friction and animation (or None) for a
    frame of ``substeps`` substeps of ``dt`` [s] from time ``t0``; None when there
    are none, so that :func:`collide_spheres` is not compiled."""
    if not spheres:
        return None
    out = []
    for s in spheres:
        R, o, carry = frame_poses(getattr(s, "animation", None), s.origin, t0, dt, substeps)
        out.append(moving_rows(R, o, carry, points=s.origin, fixed=(s.radius, s.friction)))
    return stack_slots(out)


@njit(**KERNEL_OPTIONS)
def collide_spheres(P, L, free, spheres, lo, hi, s):
    """Points ``lo:hi`` inside a sphere go to the surface along the ray from the centre,
    then back toward their last position by the friction: last + (1-f)(surface-last),
    where "last" is carried along by the sphere's motion over substep ``s``
    (unmoved while no sphere moves, as in CS184).
    ``spheres`` None: nothing (the branch is pruned when numba compiles it)."""
    if spheres is None:
        return
    rows = spheres[min(s, spheres.shape[0] - 1)]
    moving = spheres.shape[0] > 1
    x, y, z = P[0, lo:hi], P[1, lo:hi], P[2, lo:hi]
    lx, ly, lz = L[0, lo:], L[1, lo:], L[2, lo:]
    free = free[lo:]
    for k in range(rows.shape[0]):
        row = rows[k]
        cx, cy, cz, r, fr = row[0], row[1], row[2], row[3], row[4]
        r2 = r * r
        keep = 1.0 - fr
        if not moving:  # the course code's loop, to the bit: no carry in its sums
            for p in range(x.shape[0]):
                dx = x[p] - cx
                dy = y[p] - cy
                dz = z[p] - cz
                d2 = dx * dx + dy * dy + dz * dz
                hit = d2 < r2 and d2 > 0.0 and free[p] != 0.0
                f = r / np.sqrt(d2 if hit else 1.0)
                nx = lx[p] + keep * (cx + dx * f - lx[p])
                ny = ly[p] + keep * (cy + dy * f - ly[p])
                nz = lz[p] + keep * (cz + dz * f - lz[p])
                x[p] = nx if hit else x[p]
                y[p] = ny if hit else y[p]
                z[p] = nz if hit else z[p]
            continue
        a = carry_of(row, 5)
        for p in range(x.shape[0]):
            dx = x[p] - cx
            dy = y[p] - cy
            dz = z[p] - cz
            d2 = dx * dx + dy * dy + dz * dz
            hit = d2 < r2 and d2 > 0.0 and free[p] != 0.0
            f = r / np.sqrt(d2 if hit else 1.0)
            mx, my, mz = carry_point(a, lx[p], ly[p], lz[p])
            nx = mx + keep * (cx + dx * f - mx)
            ny = my + keep * (cy + dy * f - my)
            nz = mz + keep * (cz + dz * f - mz)
            x[p] = nx if hit else x[p]
            y[p] = ny if hit else y[p]
            z[p] = nz if hit else z[p]
