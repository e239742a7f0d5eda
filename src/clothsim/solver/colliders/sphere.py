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


SPHERE_OFFSET = 1e-4
"""distance outside the sphere at which a point that went through it is put [m]"""

SPHERE_SETTLE = 1e-3
"""depth [m] beyond which a point that a later pass (Provot's) pulled into a
sphere is put back on its surface: the standard sphere scenes at their own
substep count never reach a quarter of it, so they are left to the bit"""


@njit(**KERNEL_OPTIONS)
def collide_spheres(P, L, free, spheres, lo, hi, s):
    """Points ``lo:hi`` inside a sphere go to the surface along the ray from the centre,
    then back toward their last position by the friction: last + (1-f)(surface-last),
    where "last" is carried along by the sphere's motion over substep ``s``
    (unmoved while no sphere moves, as in CS184).

    The radial rule holds while the point's segment from its last position
    entered the sphere on its own side. A point whose segment went through the
    whole sphere (both ends outside), or that ends past the centre as seen from
    its last position, is flagged in the same loop and left for
    :func:`_through`, which puts it at the segment's entry instead: the
    flags are rare, so the loop stays a branch-free select that vectorises.
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
        in2 = max(r - SPHERE_SETTLE, 0.0) ** 2
        keep = 1.0 - fr
        flagged = 0
        if not moving:  # the course code's loop, to the bit: no carry in its sums
            for p in range(x.shape[0]):
                dx = x[p] - cx
                dy = y[p] - cy
                dz = z[p] - cz
                d2 = dx * dx + dy * dy + dz * dz
                through = _flag(dx, dy, dz, d2, lx[p] - cx, ly[p] - cy, lz[p] - cz, r2, in2) and free[p] != 0.0
                hit = d2 < r2 and d2 > 0.0 and free[p] != 0.0 and not through
                flagged += through
                f = r / np.sqrt(d2 if hit else 1.0)
                nx = lx[p] + keep * (cx + dx * f - lx[p])
                ny = ly[p] + keep * (cy + dy * f - ly[p])
                nz = lz[p] + keep * (cz + dz * f - lz[p])
                x[p] = nx if hit else x[p]
                y[p] = ny if hit else y[p]
                z[p] = nz if hit else z[p]
            if flagged:
                _through(x, y, z, lx, ly, lz, free, row, False, keep)
            continue
        a = carry_of(row, 5)
        for p in range(x.shape[0]):
            dx = x[p] - cx
            dy = y[p] - cy
            dz = z[p] - cz
            d2 = dx * dx + dy * dy + dz * dz
            mx, my, mz = carry_point(a, lx[p], ly[p], lz[p])
            through = _flag(dx, dy, dz, d2, mx - cx, my - cy, mz - cz, r2, in2) and free[p] != 0.0
            hit = d2 < r2 and d2 > 0.0 and free[p] != 0.0 and not through
            flagged += through
            f = r / np.sqrt(d2 if hit else 1.0)
            nx = mx + keep * (cx + dx * f - mx)
            ny = my + keep * (cy + dy * f - my)
            nz = mz + keep * (cz + dz * f - mz)
            x[p] = nx if hit else x[p]
            y[p] = ny if hit else y[p]
            z[p] = nz if hit else z[p]
        if flagged:
            _through(x, y, z, lx, ly, lz, free, row, True, keep)


@njit(**KERNEL_OPTIONS, inline="always")
def _flag(dx, dy, dz, d2, ex, ey, ez, r2, in2):
    """Whether the segment from last (centre + e) to now (centre + d) needs the
    entry rule: it ends inside past the centre (d.e < 0), or both ends are
    outside and the segment passes deeper than SPHERE_SETTLE (within
    sqrt(in2) of the centre: a point that slides past the surface through a
    sliver of it is left alone). No division, no branch: it runs in the
    vectorised loop for every point."""
    de = dx * ex + dy * ey + dz * ez
    e2 = ex * ex + ey * ey + ez * ez
    # the segment's direction u = d - e; its nearest point to the centre lies
    # strictly between the ends when 0 < -e.u < u.u, and is within r when
    # |e|^2 u.u - (e.u)^2 < in2 u.u
    eu = de - e2
    uu = d2 - 2.0 * de + e2
    past = d2 < r2 and de < 0.0
    across = (d2 >= r2 and e2 >= r2 and eu < 0.0 and -eu < uu
              and e2 * uu - eu * eu < in2 * uu)
    return past or across


@njit(**KERNEL_OPTIONS)
def _through(x, y, z, lx, ly, lz, free, row, moving, keep):
    """The flagged points of :func:`collide_spheres` (found again by the same
    test, on positions that the loop left as they were) go to where their
    segment first meets the sphere, SPHERE_OFFSET outside, or, where the last
    position was itself inside, to the surface nearest it; then the friction
    rule, toward the (carried) last position: ``keep`` is 1 - friction (1 for
    none)."""
    cx, cy, cz, r = row[0], row[1], row[2], row[3]
    r2 = r * r
    in2 = max(r - SPHERE_SETTLE, 0.0) ** 2
    a = carry_of(row, 5)
    for p in range(x.shape[0]):
        if free[p] == 0.0:
            continue
        mx, my, mz = lx[p], ly[p], lz[p]
        if moving:
            mx, my, mz = carry_point(a, mx, my, mz)
        dx, dy, dz = x[p] - cx, y[p] - cy, z[p] - cz
        ex, ey, ez = mx - cx, my - cy, mz - cz
        d2 = dx * dx + dy * dy + dz * dz
        if not _flag(dx, dy, dz, d2, ex, ey, ez, r2, in2):
            continue
        e2 = ex * ex + ey * ey + ez * ez
        if e2 >= r2:
            # first root of |e + t u|^2 = r^2, u = d - e
            ux, uy, uz = dx - ex, dy - ey, dz - ez
            uu = ux * ux + uy * uy + uz * uz
            eu = ex * ux + ey * uy + ez * uz
            t = (-eu - np.sqrt(max(eu * eu - uu * (e2 - r2), 0.0))) / uu
            sx, sy, sz = ex + t * ux, ey + t * uy, ez + t * uz
        else:
            sx, sy, sz = ex, ey, ez
        n = np.sqrt(sx * sx + sy * sy + sz * sz)
        if not n > 0.0:
            continue
        f = (r + SPHERE_OFFSET) / n
        x[p] = mx + keep * (cx + sx * f - mx)
        y[p] = my + keep * (cy + sy * f - my)
        z[p] = mz + keep * (cz + sz * f - mz)


@njit(**KERNEL_OPTIONS)
def settle_spheres(P, Q, free, spheres, lo, hi, s):
    """Points ``lo:hi`` that a later pass moved from Q (after the colliders)
    deeper than SPHERE_SETTLE into a sphere (at its pose at the end of substep
    ``s``) go out along the ray from the centre to the surface, with no
    friction; shallower ones stay to the bit. One that the pass moved past the
    centre, or through the sphere, goes back along its segment from Q to
    where it entered, as in :func:`collide_spheres`."""
    if spheres is None:
        return
    rows = spheres[min(s, spheres.shape[0] - 1)]
    x, y, z = P[0, lo:hi], P[1, lo:hi], P[2, lo:hi]
    qx, qy, qz = Q[0, lo:], Q[1, lo:], Q[2, lo:]
    free = free[lo:]
    for k in range(rows.shape[0]):
        row = rows[k]
        cx, cy, cz, r = row[0], row[1], row[2], row[3]
        r2 = r * r
        in2 = max(r - SPHERE_SETTLE, 0.0) ** 2
        flagged = 0
        for p in range(x.shape[0]):
            dx = x[p] - cx
            dy = y[p] - cy
            dz = z[p] - cz
            d2 = dx * dx + dy * dy + dz * dz
            through = _flag(dx, dy, dz, d2, qx[p] - cx, qy[p] - cy, qz[p] - cz, r2, in2) and free[p] != 0.0
            deep = d2 < in2 and d2 > 0.0 and free[p] != 0.0 and not through
            flagged += through
            f = r / np.sqrt(d2 if deep else 1.0)
            x[p] = cx + dx * f if deep else x[p]
            y[p] = cy + dy * f if deep else y[p]
            z[p] = cz + dz * f if deep else z[p]
        if flagged:
            _through(x, y, z, qx, qy, qz, free, row, False, 1.0)
