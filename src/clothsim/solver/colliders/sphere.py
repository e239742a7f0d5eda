"""Spheres: points inside are put on the surface, with CS184 friction.

A sphere is a row ``(cx, cy, cz, r, friction, carry...)`` of float64 rows
(T, K, 5 + CARRY) (see :mod:`.motion_rows`): its centre at the end of the
substep and how it moved over it. Positions are (3, N) coordinate planes
(see :mod:`clothsim.solver.springs`). The loop over all the points takes
them a few at a time in vector code of our own (:mod:`.sphere_lanes`), which
skips a run with none inside; the rare points that moved far
enough to have gone through a sphere, and those that Provot's pass left
deeper than SPHERE_SETTLE, are taken in scalar passes that run only when
there are any.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit

from ..blend import write_point
from ..shared import KERNEL_OPTIONS
from .sphere_lanes import LANES, carried_lanes, still_lanes
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
sphere is put back on its surface: the standard still-sphere scenes at their
own substep count never reach a quarter of it, so they are left to the bit"""


@njit(**KERNEL_OPTIONS, inline="always")
def _far2(r):
    """(squared radius of the sphere SPHERE_SETTLE inside the surface, squared
    length of a substep's move beyond which its segment may need the entry
    rule). A segment from a last position no deeper than SPHERE_SETTLE that
    ends past the centre is longer than that inner radius; one that starts and
    ends outside and dips deeper than SPHERE_SETTLE is longer than the chord
    at that depth: a move shorter than both needs no more than the radial rule."""
    inner = max(r - SPHERE_SETTLE, 0.0)
    in2 = inner * inner
    return in2, min(in2, 4.0 * (r * r - in2))


@njit(**KERNEL_OPTIONS)
def collide_spheres(P, L, free, spheres, lo, hi, s):
    """Points ``lo:hi`` inside a sphere go to the surface along the ray from the centre,
    then back toward their last position by the friction: last + (1-f)(surface-last),
    where "last" is carried along by the sphere's motion over substep ``s``
    (unmoved while no sphere moves, as in CS184).

    That radial rule holds while the point's segment from its last position
    entered the sphere on its own side. A point that moved farther over the
    substep than :func:`_far2` allows (at the standard scenes' substep counts,
    none does) is left as it is by the loop, and :func:`_far` tests its
    segment: one that went through the whole sphere, or that ends past the
    centre as seen from its last position, goes to where the segment entered.
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
        far2 = _far2(row[3])[1]
        if moving:
            fast = _carried_rule(x, y, z, lx, ly, lz, free, row, far2)
        else:  # the course code's sums, to the bit: no carry in them
            fast = _still_rule(x, y, z, lx, ly, lz, free, row, far2)
        if fast:
            _far(x, y, z, lx, ly, lz, free, row, moving)


@njit(**KERNEL_OPTIONS)
def _still_rule(x, y, z, lx, ly, lz, free, row, far2):
    """The loop of :func:`collide_spheres` for a still sphere ``row``: the rule of
    :func:`_carried_point` on the last positions as they are, LANES points at a
    time in :func:`.sphere_lanes.still_lanes` (which skips a run with none
    inside), the last few one by one; returns how many points moved farther
    than ``far2`` allows."""
    fast = 0
    sphere = _rule_of(row, far2)
    n = x.shape[0]
    full = n - n % LANES
    for q in range(0, full, LANES):
        fast += still_lanes((x, y, z), (lx, ly, lz), free, q, sphere)
    for p in range(full, n):
        fast += _carried_point((x, y, z), p, (lx[p], ly[p], lz[p]), free[p], sphere)
    return fast


@njit(**KERNEL_OPTIONS)
def _carried_rule(x, y, z, lx, ly, lz, free, row, far2):
    """The loop of :func:`collide_spheres` for a moving sphere ``row``, its last
    positions carried by the sphere's motion; returns how many points moved
    farther than ``far2`` allows. Apart from :func:`_still_rule`, so that neither
    compiled loop tests which it is, and the still one reads no carry. LANES
    points at a time in the vector code of
    :func:`.sphere_lanes.carried_lanes`, which skips the rule's square root,
    division and stores where none of the run is inside, and the carry too
    where none may have moved too far (:func:`carry_screen`); the last few
    one by one (:func:`_carried_point`), in the same arithmetic."""
    fast = 0
    a = carry_of(row, 5)
    sphere = _rule_of(row, far2)
    screen = carry_screen(a, row, far2)
    n = x.shape[0]
    full = n - n % LANES
    for q in range(0, full, LANES):
        fast += carried_lanes((x, y, z), (lx, ly, lz), free, q, sphere, a, screen)
    for p in range(full, n):
        fast += _carried_point((x, y, z), p, carry_point(a, lx[p], ly[p], lz[p]), free[p], sphere)
    return fast


SCREEN_REACH = 1e4
"""[m] the farthest from a moving sphere's centre that :func:`carry_screen` vouches
for. The carry's rounding grows with the points' coordinates; within this
reach of a centre anywhere a scene may put one, it stays far below the
screen's margin"""


@njit(cache=True, inline="always")
def carry_screen(a, row, far2):
    """(reach2, move2) for :func:`.sphere_lanes.carried_lanes`: a point p within
    sqrt(reach2) of the sphere's centre c, that moved by u0 from its last
    position l with |u0|² <= move2, is within sqrt(far2) = F of its carried
    last position m = A l + t (the carry ``a``), so the loop's far test is
    false for it.

    Proof: m - l = (A - I)(l - c) + (A - I)c + t, so with θ >= |A - I| (the
    Frobenius norm) and e = |(A - I)c + t|, |m - l| <= θ(|u0| + |p - c|) + e
    and |p - m| <= (1 + θ)|u0| + θ|p - c| + e. Asking θ|p - c| <= F/4 and
    (1 + θ)|u0| + e <= 3F/4 bounds it by F. Both squares are taken a millionth
    short, far more than their rounding; move2 is -1 (no point vouched for)
    where e alone reaches 3F/4, and reach2 at most SCREEN_REACH²."""
    theta2 = 0.0
    for i in range(3):
        for j in range(3):
            g = a[3 * i + j] - (1.0 if i == j else 0.0)
            theta2 += g * g
    theta = np.sqrt(theta2)
    e2 = 0.0
    for i in range(3):
        g = (a[3 * i] - (1.0 if i == 0 else 0.0)) * row[0] + (a[3 * i + 1] - (1.0 if i == 1 else 0.0)) * row[1] \
            + (a[3 * i + 2] - (1.0 if i == 2 else 0.0)) * row[2] + a[9 + i]
        e2 += g * g
    big = np.sqrt(far2)
    short = 1.0 - 1e-6
    reach = SCREEN_REACH if 4.0 * theta * SCREEN_REACH <= big else big / (4.0 * theta)
    left = 0.75 * big - np.sqrt(e2)
    move2 = (left / (1.0 + theta)) ** 2 * short if left > 0.0 else -1.0
    return reach * reach * short, move2


@njit(**KERNEL_OPTIONS, inline="always")
def _rule_of(row, far2):
    """What :func:`_carried_point` reads of a sphere's ``row``, read into locals once:
    (cx, cy, cz, r, r^2, 1 - friction, far2)."""
    r = row[3]
    return row[0], row[1], row[2], r, r * r, 1.0 - row[4], far2


@njit(**KERNEL_OPTIONS, inline="always")
def _carried_point(planes, p, last, fp, sphere):
    """The still loop's rule for point p of ``planes`` (x, y, z) [m] with its carried
    last position ``last`` (3 floats) and free weight ``fp``, against ``sphere``
    (cx, cy, cz, r, r^2, 1 - friction, far2): the point written (whole stores, see
    ..blend) where it is inside and moved no farther than far2 allows; returns
    whether it moved farther (1) or not (0)."""
    x, y, z = planes
    cx, cy, cz, r, r2, keep, far2 = sphere
    mx, my, mz = last
    xp, yp, zp = x[p], y[p], z[p]
    dx = xp - cx
    dy = yp - cy
    dz = zp - cz
    d2 = dx * dx + dy * dy + dz * dz
    ux = xp - mx
    uy = yp - my
    uz = zp - mz
    far = ux * ux + uy * uy + uz * uz > far2
    hit = (d2 < r2) & (d2 > 0.0) & (fp != 0.0) & (not far)
    f = r / np.sqrt(d2 if hit else 1.0)
    nx = mx + keep * (cx + dx * f - mx)
    ny = my + keep * (cy + dy * f - my)
    nz = mz + keep * (cz + dz * f - mz)
    write_point(planes, p, hit, (nx, ny, nz), (xp, yp, zp))
    return np.int64(far)


@njit(**KERNEL_OPTIONS, inline="always")
def _through(dx, dy, dz, d2, ex, ey, ez, r2, in2):
    """Whether the segment from last (centre + e) to now (centre + d) needs the
    entry rule: it ends inside past the centre (d.e < 0), or both ends are
    outside and the segment passes deeper than SPHERE_SETTLE (within
    sqrt(in2) of the centre: a point that slides past the surface through a
    sliver of it is left alone)."""
    de = dx * ex + dy * ey + dz * ez
    e2 = ex * ex + ey * ey + ez * ez
    # the segment's direction u = d - e; its nearest point to the centre lies
    # strictly between the ends when 0 < -e.u < u.u, and is within sqrt(in2)
    # when |e|^2 u.u - (e.u)^2 < in2 u.u
    eu = de - e2
    uu = d2 - 2.0 * de + e2
    past = d2 < r2 and de < 0.0
    across = (d2 >= r2 and e2 >= r2 and eu < 0.0 and -eu < uu
              and e2 * uu - eu * eu < in2 * uu)
    return past or across


@njit(**KERNEL_OPTIONS, inline="always")
def _entry(ex, ey, ez, dx, dy, dz, r2):
    """Where the segment from centre + e to centre + d first meets the sphere,
    from the centre; from a start inside, the surface point nearest it is
    taken (a direction: the caller scales it to the surface)"""
    e2 = ex * ex + ey * ey + ez * ez
    if not e2 >= r2:
        return ex, ey, ez
    # first root of |e + t u|^2 = r^2, u = d - e
    ux, uy, uz = dx - ex, dy - ey, dz - ez
    uu = ux * ux + uy * uy + uz * uz
    eu = ex * ux + ey * uy + ez * uz
    t = (-eu - np.sqrt(max(eu * eu - uu * (e2 - r2), 0.0))) / max(uu, 1e-300)
    return ex + t * ux, ey + t * uy, ez + t * uz


@njit(**KERNEL_OPTIONS)
def _far(x, y, z, lx, ly, lz, free, row, moving):
    """The points of :func:`collide_spheres` that moved too far for its loop
    (found again by its test, on positions that the loop left as they were):
    one whose segment from its (carried) last position went through the sphere
    or ends past the centre goes to where that segment first meets the sphere,
    SPHERE_OFFSET outside (or, where the last position was itself inside, to
    the surface nearest it); one that is only inside takes the radial rule;
    then the friction rule toward the last position, as in the loop."""
    cx, cy, cz, r = row[0], row[1], row[2], row[3]
    r2 = r * r
    in2, far2 = _far2(r)
    keep = 1.0 - row[4]
    a = carry_of(row, 5)
    for p in range(x.shape[0]):
        mx, my, mz = lx[p], ly[p], lz[p]
        if moving:
            mx, my, mz = carry_point(a, mx, my, mz)
        dx, dy, dz = x[p] - cx, y[p] - cy, z[p] - cz
        ux, uy, uz = x[p] - mx, y[p] - my, z[p] - mz
        if free[p] == 0.0 or not ux * ux + uy * uy + uz * uz > far2:
            continue
        ex, ey, ez = mx - cx, my - cy, mz - cz
        d2 = dx * dx + dy * dy + dz * dz
        if _through(dx, dy, dz, d2, ex, ey, ez, r2, in2):
            sx, sy, sz = _entry(ex, ey, ez, dx, dy, dz, r2)
            reach = r + SPHERE_OFFSET
        elif d2 < r2 and d2 > 0.0:
            sx, sy, sz = dx, dy, dz
            reach = r
        else:
            continue
        n = np.sqrt(sx * sx + sy * sy + sz * sz)
        if not n > 0.0:
            continue
        f = reach / n
        x[p] = mx + keep * (cx + sx * f - mx)
        y[p] = my + keep * (cy + sy * f - my)
        z[p] = mz + keep * (cz + sz * f - mz)


@njit(**KERNEL_OPTIONS)
def settle_spheres(P, L, free, spheres, lo, hi, s):
    """Points ``lo:hi`` that a later pass (Provot's) left deeper than
    SPHERE_SETTLE inside a sphere (at its pose at the end of substep ``s``) go
    out to its surface, with no friction: along the ray from the centre, or,
    where the point now lies past the centre as seen from its (carried) last
    position ``L``, back along that segment to where it entered, as in
    :func:`collide_spheres`. Shallower points stay to the bit, and the loop
    that looks for deep ones only reads the positions."""
    if spheres is None:
        return
    rows = spheres[min(s, spheres.shape[0] - 1)]
    moving = spheres.shape[0] > 1
    x, y, z = P[0, lo:hi], P[1, lo:hi], P[2, lo:hi]
    lx, ly, lz = L[0, lo:], L[1, lo:], L[2, lo:]
    free = free[lo:]
    for k in range(rows.shape[0]):
        row = rows[k]
        cx, cy, cz = row[0], row[1], row[2]
        in2 = _far2(row[3])[0]
        deep = 0
        for p in range(x.shape[0]):
            dx = x[p] - cx
            dy = y[p] - cy
            dz = z[p] - cz
            deep += dx * dx + dy * dy + dz * dz < in2
        if deep:
            _settle_deep(x, y, z, lx, ly, lz, free, row, moving)


@njit(**KERNEL_OPTIONS)
def _settle_deep(x, y, z, lx, ly, lz, free, row, moving):
    cx, cy, cz, r = row[0], row[1], row[2], row[3]
    r2 = r * r
    in2 = _far2(r)[0]
    a = carry_of(row, 5)
    for p in range(x.shape[0]):
        dx, dy, dz = x[p] - cx, y[p] - cy, z[p] - cz
        d2 = dx * dx + dy * dy + dz * dz
        if free[p] == 0.0 or not (d2 < in2 and d2 > 0.0):
            continue
        mx, my, mz = lx[p], ly[p], lz[p]
        if moving:
            mx, my, mz = carry_point(a, mx, my, mz)
        ex, ey, ez = mx - cx, my - cy, mz - cz
        if dx * ex + dy * ey + dz * ez < 0.0:
            sx, sy, sz = _entry(ex, ey, ez, dx, dy, dz, r2)
            reach = r + SPHERE_OFFSET
        else:
            sx, sy, sz = dx, dy, dz
            reach = r
        n = np.sqrt(sx * sx + sy * sy + sz * sz)
        if n > 0.0:
            x[p] = cx + sx * (reach / n)
            y[p] = cy + sy * (reach / n)
            z[p] = cz + sz * (reach / n)
