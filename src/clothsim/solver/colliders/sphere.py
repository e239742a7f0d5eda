"""Spheres: points inside are put on the surface, with CS184 friction.

A sphere is a row ``(cx, cy, cz, r, friction)`` of a float64 array, (K, 5);
positions are (3, N) coordinate planes (see :mod:`clothsim.solver.springs`).
The loop is a branch-free select so that it vectorises.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit

from ..shared import KERNEL_OPTIONS


def pack(spheres: Sequence) -> np.ndarray | None:
    """Rows (cx, cy, cz, r, friction) from objects with origin, radius, friction;
    None when there are none, so that :func:`collide_spheres` is not compiled."""
    if not spheres:
        return None
    out = np.zeros((len(spheres), 5))
    for k, s in enumerate(spheres):
        out[k] = (*s.origin, s.radius, s.friction)
    return out


@njit(**KERNEL_OPTIONS)
def collide_spheres(P, L, free, spheres, lo, hi):
    """Points ``lo:hi`` inside a sphere go to the surface along the ray from the centre,
    then back toward their last position by the friction: last + (1-f)(surface-last).
    ``spheres`` None: nothing (the branch is pruned when numba compiles it)."""
    if spheres is None:
        return
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
