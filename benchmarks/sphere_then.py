"""The still sphere's kernel as it stood at `c978e85`, before the moving world.

Issue 21 asks that "a box or an animated sphere costs no more than a sphere
does today": this is that sphere, the yardstick, kept so that
``bench_world.py --kernels`` can time it beside today's kernels on one state.
It puts a point inside the sphere on its surface along the ray from the
centre, then back toward its last position by the friction, with no test of
how far the point moved and with stores that keep a point outside as it was.
Same compile options as the package's kernels.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from clothsim.solver.shared import KERNEL_OPTIONS


def pack(spheres) -> np.ndarray:
    """Rows (cx, cy, cz, r, friction), (K, 5), from objects with origin, radius, friction."""
    out = np.zeros((len(spheres), 5))
    for k, s in enumerate(spheres):
        out[k] = (*s.origin, s.radius, s.friction)
    return out


@njit(**KERNEL_OPTIONS)
def collide_spheres(P, L, free, spheres, lo, hi, s):
    """Points ``lo:hi`` of P (3, N) [m] inside a sphere of ``spheres`` go to its
    surface, then back toward their last position L by the friction. ``s`` (the
    substep) is taken as today's kernels take it, and not read."""
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
            f = r / np.sqrt(d2 if hit else 1.0)
            nx = lx[p] + keep * (cx + dx * f - lx[p])
            ny = ly[p] + keep * (cy + dy * f - ly[p])
            nz = lz[p] + keep * (cz + dz * f - lz[p])
            x[p] = nx if hit else x[p]
            y[p] = ny if hit else y[p]
            z[p] = nz if hit else z[p]
