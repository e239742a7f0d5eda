"""Boxes: oriented solids that no point may enter, with CS184 friction.

A box is a row of float64 rows (T, K, 17 + CARRY) (see :mod:`.motion_rows`):
its centre (3) and its axes (a rotation, 9, row-major: the columns are the
box's axes) at the end of the substep, its half sizes (3), friction and
margin, then how it moved over the substep. A point's segment from its last
position (carried along by the box's motion) to where it is now is tested
against the box in the box's own frame, so a point that moves farther than
the box is thick in one substep is still stopped at the face it met.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence

import numpy as np
from numba import njit

from ...motion import rotation_matrices
from ..blend import write_point
from ..shared import KERNEL_OPTIONS
from .motion_rows import carry_of, carry_point, frame_poses, moving_rows, stack_slots

COLUMNS = 17
"""centre, axes, half sizes, friction, margin; the carry follows"""


def pack(boxes: Sequence, t0: float = 0.0, dt: float = 0.0, substeps: int = 1) -> np.ndarray | None:
    """Rows from objects with center, size, rotate, friction, margin and animation
    (or None) for a frame of ``substeps`` substeps of ``dt`` [s] from ``t0``; None
    when there are none, so that :func:`collide_boxes` is not compiled."""
    if not boxes:
        return None
    out = []
    for b in boxes:
        R, o, carry = frame_poses(getattr(b, "animation", None), b.center, t0, dt, substeps)
        half = b.size
        out.append(moving_rows(R, o, carry, points=b.center, frames=_axes(tuple(b.rotate)),
                               fixed=(0.5 * half[0], 0.5 * half[1], 0.5 * half[2], b.friction, b.margin)))
    return stack_slots(out)


@functools.lru_cache(maxsize=256)
def _axes(rotate: tuple) -> np.ndarray:
    """a box's own rotation, once per angles (the control is made every frame)"""
    return rotation_matrices(rotate)


TINY = 1e-300
"""stands in for a zero coordinate change in the slab test: the entry times stay
finite (fastmath assumes no infinities) and still order right"""


@njit(cache=True, inline="always")
def _slab(a0, a1, h):
    """entry and exit times (lo, hi) of the segment a0 -> a1 along one axis through
    the slab |a| < h; both finite"""
    d = a1 - a0
    d = d if abs(d) > TINY else TINY
    ta = (-h - a0) / d
    tb = (h - a0) / d
    return min(ta, tb), max(ta, tb)


@njit(cache=True, inline="always")
def _onto(a0, a1, h, margin, keep):
    """the coordinate along the face axis of a point that entered through the face on
    a0's side: a1 put on the face, margin off it (or as far as a0 was, if nearer: a
    point resting within the margin must not bounce off it), then back toward a0 by
    keep (1 - friction)"""
    face = np.copysign(h + min(margin, abs(a0) - h), a0)
    return a0 + keep * (face - a0)


@njit(cache=True, inline="always")
def _place(u0, v0, w0, u1, v1, w1, hu, hv, hw, margin, keep):
    """(hit, u, v, w): where a point that went from q0 to q1 (box frame) ends. Into the
    box from outside: at the face its segment met (:func:`_onto`; the other
    coordinates by the friction rule); inside already and still: out through the
    nearest face, margin outside, with no friction; anything else: no hit."""
    outside0 = (abs(u0) >= hu) | (abs(v0) >= hv) | (abs(w0) >= hw)
    inside1 = (abs(u1) < hu) & (abs(v1) < hv) & (abs(w1) < hw)
    lo_u, hi_u = _slab(u0, u1, hu)
    lo_v, hi_v = _slab(v0, v1, hv)
    lo_w, hi_w = _slab(w0, w1, hw)
    t_in = max(lo_u, max(lo_v, lo_w))
    t_out = min(hi_u, min(hi_v, hi_w))
    entered = outside0 & (t_in <= t_out) & (t_in <= 1.0)
    on_u = lo_u >= t_in
    on_v = (not on_u) & (lo_v >= t_in)
    on_w = (not on_u) & (not on_v)
    if entered:
        u = _onto(u0, u1, hu, margin, keep) if on_u else u0 + keep * (u1 - u0)
        v = _onto(v0, v1, hv, margin, keep) if on_v else v0 + keep * (v1 - v0)
        w = _onto(w0, w1, hw, margin, keep) if on_w else w0 + keep * (w1 - w0)
        return True, u, v, w
    if outside0 or not inside1:
        return False, u1, v1, w1
    gu, gv, gw = hu - abs(u1), hv - abs(v1), hw - abs(w1)
    if gu <= gv and gu <= gw:
        return True, (hu + margin if u1 > 0.0 else -hu - margin), v1, w1
    if gv <= gw:
        return True, u1, (hv + margin if v1 > 0.0 else -hv - margin), w1
    return True, u1, v1, (hw + margin if w1 > 0.0 else -hw - margin)


@njit(**KERNEL_OPTIONS)
def _boxes_pass(P, R, free, boxes, lo, hi, s, carry, friction):
    """Points ``lo:hi`` of P against every box, from their reference positions R:
    last positions, carried by each box's motion over the substep where ``carry``,
    and the friction rule where ``friction`` (see the two kernels).

    Two passes a box. A branch-free one over every point (:func:`_common`, it
    vectorises) places the common case and marks the rest whose segment's
    bounding box, in the box's frame, overlaps the box (near an edge or
    corner, a fast point, a point inside from before); the second places the
    marked few (:func:`_place`)."""
    rows = boxes[min(s, boxes.shape[0] - 1)]
    marked = np.empty(max(hi - lo, 0), dtype=np.bool_)
    for k in range(rows.shape[0]):
        row = rows[k]
        aligned = row[3] == 1.0 and row[7] == 1.0 and row[11] == 1.0
        if _common(P, R, free, row, lo, marked, carry, friction, aligned) == 0:
            continue  # none marked: the second pass has nothing to do
        cx, cy, cz = row[0], row[1], row[2]
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = (row[3], row[4], row[5], row[6], row[7], row[8],
                                                        row[9], row[10], row[11])
        a = carry_of(row, COLUMNS)
        keep = 1.0 - row[15] if friction else 0.0
        for q in range(marked.shape[0]):
            if not marked[q]:
                continue
            p = lo + q
            mx, my, mz = R[0, p], R[1, p], R[2, p]
            if carry:
                mx, my, mz = carry_point(a, mx, my, mz)
            dx, dy, dz = P[0, p] - cx, P[1, p] - cy, P[2, p] - cz
            ex, ey, ez = mx - cx, my - cy, mz - cz
            hit, fu, fv, fw = _place(r00 * ex + r10 * ey + r20 * ez, r01 * ex + r11 * ey + r21 * ez,
                                     r02 * ex + r12 * ey + r22 * ez, r00 * dx + r10 * dy + r20 * dz,
                                     r01 * dx + r11 * dy + r21 * dz, r02 * dx + r12 * dy + r22 * dz,
                                     row[12], row[13], row[14], row[16], keep)
            if hit:
                P[0, p] = cx + r00 * fu + r01 * fv + r02 * fw
                P[1, p] = cy + r10 * fu + r11 * fv + r12 * fw
                P[2, p] = cz + r20 * fu + r21 * fv + r22 * fw


@njit(**KERNEL_OPTIONS)
def _common(P, R, free, row, lo, marked, carry, friction, aligned):
    """The vector pass of :func:`_boxes_pass` for the box of ``row`` over points
    ``lo:lo + len(marked)``: a point that went in through the one face its
    reference position was outside of (a cloth resting on a box crosses its
    face every substep) is placed; ``marked`` is set for the others that end
    inside, and, where some point moved farther than the box's thinnest side,
    for those whose segment's bounding box meets the box (:func:`_mark_through`).
    ``aligned``: the box's axes are the world's, and the loop skips the turns
    into and out of its frame. Returns how many points it marked."""
    n = marked.shape[0]
    x, y, z = P[0, lo:lo + n], P[1, lo:lo + n], P[2, lo:lo + n]
    rx, ry, rz = R[0, lo:lo + n], R[1, lo:lo + n], R[2, lo:lo + n]
    fr = free[lo:lo + n]
    cx, cy, cz = row[0], row[1], row[2]
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = (row[3], row[4], row[5], row[6], row[7], row[8],
                                                    row[9], row[10], row[11])
    hu, hv, hw = row[12], row[13], row[14]
    keep = 1.0 - row[15] if friction else 0.0
    margin = row[16]
    a = carry_of(row, COLUMNS)
    # a point that passed right through ends outside: only a move longer than the
    # box's thinnest side can, so the points are looked at again only after one
    thinnest2 = 4.0 * min(hu, min(hv, hw)) ** 2
    far = 0
    count = 0
    for p in range(n):
        mx, my, mz = rx[p], ry[p], rz[p]
        if carry:
            mx, my, mz = carry_point(a, mx, my, mz)
        xp, yp, zp = x[p], y[p], z[p]
        dx, dy, dz = xp - cx, yp - cy, zp - cz
        ex, ey, ez = mx - cx, my - cy, mz - cz
        if aligned:
            u1, v1, w1, u0, v0, w0 = dx, dy, dz, ex, ey, ez
        else:
            u1 = r00 * dx + r10 * dy + r20 * dz
            u0 = r00 * ex + r10 * ey + r20 * ez
            v1 = r01 * dx + r11 * dy + r21 * dz
            v0 = r01 * ex + r11 * ey + r21 * ez
            w1 = r02 * dx + r12 * dy + r22 * dz
            w0 = r02 * ex + r12 * ey + r22 * ez
        out_u, out_v, out_w = abs(u0) >= hu, abs(v0) >= hv, abs(w0) >= hw
        inside1 = (abs(u1) < hu) & (abs(v1) < hv) & (abs(w1) < hw)
        simple = inside1 & (np.int32(out_u) + np.int32(out_v) + np.int32(out_w) == 1) & (fr[p] != 0.0)
        fu = _onto(u0, u1, hu, margin, keep) if out_u else u0 + keep * (u1 - u0)
        fv = _onto(v0, v1, hv, margin, keep) if out_v else v0 + keep * (v1 - v0)
        fw = _onto(w0, w1, hw, margin, keep) if out_w else w0 + keep * (w1 - w0)
        if aligned:
            nx, ny, nz = cx + fu, cy + fv, cz + fw
        else:
            nx = cx + r00 * fu + r01 * fv + r02 * fw
            ny = cy + r10 * fu + r11 * fv + r12 * fw
            nz = cz + r20 * fu + r21 * fv + r22 * fw
        write_point((x, y, z), p, simple, (nx, ny, nz), (xp, yp, zp))
        # the rest that end inside: near an edge or corner, or inside from before
        mark = inside1 & (fr[p] != 0.0) & (simple ^ True)
        marked[p] = mark
        count += np.int64(mark)
        du, dv, dw = u1 - u0, v1 - v0, w1 - w0
        far += np.int64(du * du + dv * dv + dw * dw >= thinnest2)
    if far > 0:
        count += _mark_through(P, R, free, row, lo, marked, carry)
    return count


@njit(**KERNEL_OPTIONS)
def _mark_through(P, R, free, row, lo, marked, carry):
    """Also mark, for the box of ``row``, every free point whose segment's bounding
    box in the box's frame meets the box: those that may have passed through it
    in one substep (a fast point, a thin box); returns how many it marked (some
    perhaps marked already: the caller only asks whether any are)."""
    n = marked.shape[0]
    count = 0
    cx, cy, cz = row[0], row[1], row[2]
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = (row[3], row[4], row[5], row[6], row[7], row[8],
                                                    row[9], row[10], row[11])
    hu, hv, hw = row[12], row[13], row[14]
    a = carry_of(row, COLUMNS)
    for q in range(n):
        p = lo + q
        mx, my, mz = R[0, p], R[1, p], R[2, p]
        if carry:
            mx, my, mz = carry_point(a, mx, my, mz)
        dx, dy, dz = P[0, p] - cx, P[1, p] - cy, P[2, p] - cz
        ex, ey, ez = mx - cx, my - cy, mz - cz
        u1, u0 = r00 * dx + r10 * dy + r20 * dz, r00 * ex + r10 * ey + r20 * ez
        v1, v0 = r01 * dx + r11 * dy + r21 * dz, r01 * ex + r11 * ey + r21 * ez
        w1, w0 = r02 * dx + r12 * dy + r22 * dz, r02 * ex + r12 * ey + r22 * ez
        inside1 = (abs(u1) < hu) & (abs(v1) < hv) & (abs(w1) < hw)
        through = ((min(u0, u1) < hu) & (max(u0, u1) > -hu) & (min(v0, v1) < hv) & (max(v0, v1) > -hv)
                   & (min(w0, w1) < hw) & (max(w0, w1) > -hw) & (free[p] != 0.0) & (inside1 ^ True))
        marked[q] = marked[q] | through
        count += np.int64(through)
    return count


@njit(**KERNEL_OPTIONS)
def collide_boxes(P, L, free, boxes, lo, hi, s):
    """Points ``lo:hi`` that entered a box over substep ``s`` (their segment from the
    last position, carried by the box's motion) are put at the face they met,
    margin outside, then moved back toward that carried last position by the
    friction. ``boxes`` None: nothing (pruned when numba compiles it)."""
    if boxes is None:
        return
    # no box moves (one slot): the carry is the identity, and is not computed
    _boxes_pass(P, L, free, boxes, lo, hi, s, boxes.shape[0] > 1, True)


@njit(**KERNEL_OPTIONS)
def settle_boxes(P, Q, free, boxes, lo, hi, s):
    """Points ``lo:hi`` that a later pass moved from Q (after the colliders) into a
    box are put back at the face they crossed, margin outside, with no friction."""
    if boxes is None:
        return
    _boxes_pass(P, Q, free, boxes, lo, hi, s, False, False)
