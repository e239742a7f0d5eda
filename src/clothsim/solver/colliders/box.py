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
from .box_lanes import (ALIGNED_LANES, STILL_LANES, TURNED_LANES, aligned_lanes, sliding_lanes,
                        sliding_turned_lanes, still_lanes, turned_lanes)
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
def _face(a0, reach):
    """where a point that entered through the face on its reference coordinate a0's
    side goes along that axis: on the face, margin off it, or as far as a0 was if
    nearer (a point resting within the margin must not bounce off it); that is,
    a0 clamped to ``reach`` (lo, hi), the slab widened by the margin"""
    return min(max(a0, reach[0]), reach[1])


@njit(cache=True, inline="always")
def _axis(a0, a1, c, h, reach, keep):
    """(out, a, d): one coordinate of the vector pass's rule, for a point from a0 to
    a1 along an axis of a box centred at c with half size h: out, whether a0
    lies outside the slab |a - c| < h; a, where the point ends if it entered
    through the face on a0's side (out: :func:`_face`, ``reach`` the slab
    widened by the margin) or through another (a1 itself), moved back
    toward a0 by keep (1 - friction); d, the move a1 - a0. The aligned box's
    pass calls it in the world's coordinates, c its centre's."""
    d = a1 - a0
    out = abs(a0 - c) >= h
    return out, a0 + keep * ((_face(a0, reach) - a0) if out else d), d


@njit(cache=True, inline="always")
def _write_or_mark(planes, marked, p, inside, outs, far, new, old):
    """The end of the vector pass's rule for point p of ``planes`` (x, y, z; m):
    where it ends ``inside`` (and is free) having been outside along exactly
    one axis (``outs``, three flags), and moved no farther than the box's
    thinnest side (not ``far``), it is written ``new``; ``marked[p]`` is set
    for the scalar pass where it ends inside otherwise (near an edge or
    corner, or inside from before) or moved farther (it may have passed
    through). Returns 1 where marked, else 0."""
    out_u, out_v, out_w = outs
    one = (out_u ^ out_v ^ out_w) & ((out_u & out_v & out_w) ^ True)
    simple = inside & one & (far ^ True)
    write_point(planes, p, simple, new, old)
    mark = (inside & (one ^ True)) | far
    marked[p] = mark
    return np.int64(mark)


@njit(cache=True, inline="always")
def _place(u0, v0, w0, u1, v1, w1, hu, hv, hw, margin, keep):
    """(hit, u, v, w): where a point that went from q0 to q1 (box frame) ends. Into the
    box from outside: at the face its segment met (:func:`_face`; the other
    coordinates by the friction rule); inside already and still: out through the
    nearest face, margin outside, with no friction; anything else: no hit."""
    outside0 = (abs(u0) >= hu) | (abs(v0) >= hv) | (abs(w0) >= hw)
    inside1 = (abs(u1) < hu) & (abs(v1) < hv) & (abs(w1) < hw)
    lo_u, hi_u = _slab(u0, u1, hu)
    lo_v, hi_v = _slab(v0, v1, hv)
    lo_w, hi_w = _slab(w0, w1, hw)
    t_in = max(lo_u, max(lo_v, lo_w))
    t_out = min(hi_u, min(hi_v, hi_w))
    # the line meets the box over [t_in, t_out]; the segment from outside enters it
    # only ahead of its start (not where the line behind it passes through)
    entered = outside0 & (t_in <= t_out) & (t_in <= 1.0) & (t_in >= 0.0)
    on_u = lo_u >= t_in
    on_v = (not on_u) & (lo_v >= t_in)
    on_w = (not on_u) & (not on_v)
    if entered:
        u = u0 + keep * ((_face(u0, (-hu - margin, hu + margin)) if on_u else u1) - u0)
        v = v0 + keep * ((_face(v0, (-hv - margin, hv + margin)) if on_v else v1) - v0)
        w = w0 + keep * ((_face(w0, (-hw - margin, hw + margin)) if on_w else w1) - w0)
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

    Two passes a box. A vector one over every point (:func:`_common`, a few
    at a time, :mod:`.box_lanes`) places the common case and marks the rest that end inside
    (near an edge or corner, or inside from before) and those that moved
    farther than the box's thinnest side (they may have gone through it);
    the second places the marked few (:func:`_place`), exactly."""
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
    inside, and for those that moved farther than the box's thinnest side
    (only such a move can go right through the box and end outside).
    ``aligned``: the box's axes are the world's (at the end of the substep). A
    box whose axes are the world's and whose references are not carried (a
    still box, or any box's settle, ``carry`` False) or only slide takes a loop
    of its own, without the turns into and out of its frame
    (:func:`_aligned_loop`); any other, the general one (:func:`_turned_loop`):
    written as branches inside one loop, LLVM computed both sides for every
    point. Returns how many points it marked."""
    n = marked.shape[0]
    planes = (P[0, lo:lo + n], P[1, lo:lo + n], P[2, lo:lo + n])
    refs = (R[0, lo:lo + n], R[1, lo:lo + n], R[2, lo:lo + n])
    fr = free[lo:lo + n]
    box_ = (row[0], row[1], row[2], row[3], row[4], row[5], row[6], row[7], row[8], row[9], row[10], row[11],
            row[12], row[13], row[14], 1.0 - row[15] if friction else 0.0, row[16])
    if not carry:  # a still box, or the settle's references (of the substep's end)
        if aligned:
            return _aligned_loop(planes, refs, fr, marked, box_, None)
        return _turned_loop(planes, refs, fr, marked, box_, None, None)
    a = carry_of(row, COLUMNS)
    if _slides(a):
        shift = (a[9], a[10], a[11])
        if aligned:
            return _aligned_loop(planes, refs, fr, marked, box_, shift)
        return _turned_loop(planes, refs, fr, marked, box_, a, shift)
    return _turned_loop(planes, refs, fr, marked, box_, a, None)


@njit(**KERNEL_OPTIONS, inline="always")
def turns_about_y(m):
    """whether the turn of the map or rotation ``m`` (its first nine numbers, row-major)
    is about the y axis alone: its y row and column those of the identity, to
    the bit (a box standing on the floor, turned and turning about the vertical)"""
    return m[1] == 0.0 and m[3] == 0.0 and m[5] == 0.0 and m[7] == 0.0 and m[4] == 1.0


@njit(**KERNEL_OPTIONS, inline="always")
def yaw_map(m):
    """the YAW_MAP numbers of the map ``m`` of 12 (:func:`.motion_rows.carry_of`)
    whose turn is about y (:func:`turns_about_y`): what
    :meth:`.lanes.Lanes.affine` reads of it"""
    return (m[0], m[2], m[6], m[8], m[9], m[10], m[11])


@njit(**KERNEL_OPTIONS, inline="always")
def _slides(a):
    """whether the carry ``a`` (:func:`.motion_rows.carry_of`) only slides: its turn
    is the identity, to the bit"""
    return (a[0] == 1.0 and a[4] == 1.0 and a[8] == 1.0 and a[1] == 0.0 and a[2] == 0.0 and a[3] == 0.0
            and a[5] == 0.0 and a[6] == 0.0 and a[7] == 0.0)


@njit(**KERNEL_OPTIONS, inline="always")
def _thinnest2(box_):
    """the square of the box's thinnest side: a point that passed right through it
    ends outside, and only a move longer than that can"""
    return 4.0 * min(box_[12], min(box_[13], box_[14])) ** 2


@njit(**KERNEL_OPTIONS)
def _aligned_loop(planes, refs, fr, marked, box_, shift):
    """:func:`_common`'s loop for a box whose axes are the world's (``box_``:
    centre (3), axes (9), half sizes (3), 1 - friction, margin) and that stands
    still (``shift`` None) or only slides by ``shift`` (3 floats [m], which
    carries the references): the rule in world coordinates about the centre,
    ALIGNED_LANES points at a time in the vector code of
    :func:`.box_lanes.aligned_lanes` (or :func:`.box_lanes.sliding_lanes`),
    which skips a run that no rule touches, the last few one by one in the
    same arithmetic. Returns how many it marked."""
    x, y, z = planes
    rx, ry, rz = refs
    cx, cy, cz = box_[0], box_[1], box_[2]
    hu, hv, hw, keep, margin = box_[12], box_[13], box_[14], box_[15], box_[16]
    reach_u = (cx - (hu + margin), cx + (hu + margin))
    reach_v = (cy - (hv + margin), cy + (hv + margin))
    reach_w = (cz - (hw + margin), cz + (hw + margin))
    thinnest2 = _thinnest2(box_)
    count = 0
    n = marked.shape[0]
    full = n - n % ALIGNED_LANES
    lanes_box = (cx, cy, cz, hu, hv, hw) + reach_u + reach_v + reach_w + (keep, thinnest2)
    for q in range(0, full, ALIGNED_LANES):
        if shift is None:
            count += aligned_lanes(planes, refs, fr, marked, q, lanes_box)
        else:
            count += sliding_lanes(planes, refs, fr, marked, q, lanes_box, shift)
    for p in range(full, n):
        mx, my, mz = rx[p], ry[p], rz[p]
        if shift is not None:
            mx, my, mz = mx + shift[0], my + shift[1], mz + shift[2]
        xp, yp, zp = x[p], y[p], z[p]
        free_ = fr[p] != 0.0
        inside = (abs(xp - cx) < hu) & (abs(yp - cy) < hv) & (abs(zp - cz) < hw) & free_
        out_u, nx, du = _axis(mx, xp, cx, hu, reach_u, keep)
        out_v, ny, dv = _axis(my, yp, cy, hv, reach_v, keep)
        out_w, nz, dw = _axis(mz, zp, cz, hw, reach_w, keep)
        far = (du * du + dv * dv + dw * dw >= thinnest2) & free_
        count += _write_or_mark(planes, marked, p, inside, (out_u, out_v, out_w), far, (nx, ny, nz),
                                (xp, yp, zp))
    return count


@njit(**KERNEL_OPTIONS, inline="always")
def _frame_maps(box_, a):
    """(ref, end, back): three affine maps in the 12 numbers of
    :func:`.motion_rows.carry_of`, for ``box_`` (see :func:`_aligned_loop`) and its
    carry ``a``: a reference position carried and turned into the box's frame
    (the carry composed with the turn, one map instead of two), a position
    turned into the box's frame, and a point of the box's frame back into
    the world's."""
    cx, cy, cz, r00, r01, r02, r10, r11, r12, r20, r21, r22 = box_[:12]
    tx, ty, tz = a[9] - cx, a[10] - cy, a[11] - cz
    ref = (r00 * a[0] + r10 * a[3] + r20 * a[6], r00 * a[1] + r10 * a[4] + r20 * a[7],
           r00 * a[2] + r10 * a[5] + r20 * a[8],
           r01 * a[0] + r11 * a[3] + r21 * a[6], r01 * a[1] + r11 * a[4] + r21 * a[7],
           r01 * a[2] + r11 * a[5] + r21 * a[8],
           r02 * a[0] + r12 * a[3] + r22 * a[6], r02 * a[1] + r12 * a[4] + r22 * a[7],
           r02 * a[2] + r12 * a[5] + r22 * a[8],
           r00 * tx + r10 * ty + r20 * tz, r01 * tx + r11 * ty + r21 * tz, r02 * tx + r12 * ty + r22 * tz)
    end = (r00, r10, r20, r01, r11, r21, r02, r12, r22,
           -(r00 * cx + r10 * cy + r20 * cz), -(r01 * cx + r11 * cy + r21 * cz), -(r02 * cx + r12 * cy + r22 * cz))
    back = (r00, r01, r02, r10, r11, r12, r20, r21, r22, cx, cy, cz)
    return ref, end, back


_STAY = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
"""the carry of references that stay where they are (:func:`.motion_rows.carry_of`)"""


@njit(**KERNEL_OPTIONS)
def _turned_loop(planes, refs, fr, marked, box_, a, shift):
    """:func:`_common`'s loop for any box: each reference position carried by the
    box's motion ``a`` (:func:`.motion_rows.carry_of`) and turned into the
    box's frame in one map, the end turned too, the rule there, and the
    result turned back (:func:`_frame_maps`); TURNED_LANES at a time in
    :func:`.box_lanes.turned_lanes`, the last few one by one. ``a`` None: the
    references stay where they are (a still box, or the settle's), and the
    far test takes the move in the world's frame, which the turn keeps
    (:func:`.box_lanes.still_lanes`, STILL_LANES at a time, which then turns
    the references only where a run's rule runs). ``shift`` (3 floats [m]), a
    box that only slides, by ``shift`` (``a``'s turn is the identity): the
    same, the far test taking the move from the reference carried by the
    slide. Returns as :func:`_aligned_loop`."""
    x, y, z = planes
    rx, ry, rz = refs
    hu, hv, hw, keep, margin = box_[12], box_[13], box_[14], box_[15], box_[16]
    ref, end, back = _frame_maps(box_, _STAY if a is None else a)
    reach_u = (-(hu + margin), hu + margin)
    reach_v = (-(hv + margin), hv + margin)
    reach_w = (-(hw + margin), hw + margin)
    thinnest2 = _thinnest2(box_)
    n = marked.shape[0]
    width = STILL_LANES if a is None or shift is not None else TURNED_LANES
    full = n - n % width
    lanes_box = (0.0, 0.0, 0.0, hu, hv, hw) + reach_u + reach_v + reach_w + (keep, thinnest2)
    if turns_about_y(box_[3:12]) and (a is None or turns_about_y(a)):
        maps = (yaw_map(ref), yaw_map(end), yaw_map(back))
        count = _turned_runs(planes, refs, fr, marked, lanes_box, maps, a, shift, full, width)
    else:
        count = _turned_runs(planes, refs, fr, marked, lanes_box, (ref, end, back), a, shift, full, width)
    for p in range(full, n):
        u0, v0, w0 = carry_point(ref, rx[p], ry[p], rz[p])
        xp, yp, zp = x[p], y[p], z[p]
        u1, v1, w1 = carry_point(end, xp, yp, zp)
        free_ = fr[p] != 0.0
        inside = (abs(u1) < hu) & (abs(v1) < hv) & (abs(w1) < hw) & free_
        out_u, fu, du = _axis(u0, u1, 0.0, hu, reach_u, keep)
        out_v, fv, dv = _axis(v0, v1, 0.0, hv, reach_v, keep)
        out_w, fw, dw = _axis(w0, w1, 0.0, hw, reach_w, keep)
        if a is None:  # as still_lanes: the move in the world's frame
            du, dv, dw = xp - rx[p], yp - ry[p], zp - rz[p]
        elif shift is not None:  # from the reference carried by the slide
            du, dv, dw = xp - (rx[p] + shift[0]), yp - (ry[p] + shift[1]), zp - (rz[p] + shift[2])
        far = (du * du + dv * dv + dw * dw >= thinnest2) & free_
        count += _write_or_mark(planes, marked, p, inside, (out_u, out_v, out_w), far, carry_point(back, fu, fv, fw),
                                (xp, yp, zp))
    return count


@njit(**KERNEL_OPTIONS, inline="always")
def _turned_runs(planes, refs, fr, marked, lanes_box, maps, a, shift, full, width):
    """The runs of :func:`_turned_loop` over points ``0:full``, ``width`` at a
    time, with the maps (ref, end, back) as it made them: each of 12 numbers,
    or, where the box's axes and its carry's turn are turned about y alone,
    of YAW_MAP (:func:`yaw_map`), which spares the lanes the zero terms. Returns
    how many they marked. numba inlines it into :func:`_turned_loop`, where the
    loop stood before, so that it compiles with its caller whatever the
    cache already holds."""
    ref, end, back = maps
    count = 0
    for q in range(0, full, width):
        if a is None:
            count += still_lanes(planes, refs, fr, marked, q, lanes_box, ref, end, back)
        elif shift is not None:
            count += sliding_turned_lanes(planes, refs, fr, marked, q, lanes_box, ref, end, back, shift)
        else:
            count += turned_lanes(planes, refs, fr, marked, q, lanes_box, ref, end, back)
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
    box are put back at Q, where the colliders left them, outside it (the
    friction rule with its keep at 0); one that was inside already goes out
    through the nearest face, margin outside."""
    if boxes is None:
        return
    _boxes_pass(P, Q, free, boxes, lo, hi, s, False, False)
