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

from collections.abc import Sequence

import numpy as np
from numba import njit

from ...motion import rotation_matrices, slot_poses
from ..shared import EXACT_OPTIONS
from .motion_rows import carried, carry_columns, stack_slots

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
        R, o, Rb, ob = slot_poses(getattr(b, "animation", None), b.center, t0, dt, substeps)
        centre = R @ np.asarray(b.center, dtype=np.float64) + o
        axes = R @ rotation_matrices(b.rotate)
        fixed = np.broadcast_to(np.array([*(0.5 * np.asarray(b.size, dtype=np.float64)), b.friction, b.margin]),
                                (len(R), 5))
        out.append(np.concatenate([centre, axes.reshape(-1, 9), fixed, carry_columns(R, o, Rb, ob)], axis=1))
    return stack_slots(out)


@njit(cache=True, inline="always")
def _local(row, x, y, z):
    """(x, y, z) [m] in the frame of the box of ``row``"""
    dx, dy, dz = x - row[0], y - row[1], z - row[2]
    return (row[3] * dx + row[6] * dy + row[9] * dz,
            row[4] * dx + row[7] * dy + row[10] * dz,
            row[5] * dx + row[8] * dy + row[11] * dz)


@njit(cache=True, inline="always")
def _world(row, u, v, w):
    return (row[0] + row[3] * u + row[4] * v + row[5] * w,
            row[1] + row[6] * u + row[7] * v + row[8] * w,
            row[2] + row[9] * u + row[10] * v + row[11] * w)


@njit(cache=True, inline="always")
def _resolve(q0, q1, half, margin, keep, out):
    """Whether a point that went from ``q0`` to ``q1`` (box frame, (3,) each) hit the
    box, and if so where it ends, in ``out``: ``q1`` put on the face its segment
    entered, ``margin`` outside it (or as far as q0 was, if nearer), then moved back toward q0 by ``keep``
    (1 - friction); a point that was inside already goes to the nearest face,
    margin outside, with no friction."""
    outside0 = False
    for c in range(3):
        if abs(q0[c]) >= half[c]:
            outside0 = True
    if outside0:
        t_in, t_out, axis = 0.0, 1.0, -1
        for c in range(3):
            d = q1[c] - q0[c]
            if d == 0.0:
                if abs(q0[c]) >= half[c]:
                    return False
                continue
            ta = (-half[c] - q0[c]) / d
            tb = (half[c] - q0[c]) / d
            lo, hi = min(ta, tb), max(ta, tb)
            if lo > t_in or axis < 0 and lo >= t_in:
                t_in, axis = lo, c
            t_out = min(t_out, hi)
        if axis < 0 or t_in > t_out or not t_in <= 1.0:
            return False
        # the face the segment met decides where the point goes: the current
        # position put on that face, as the plane does, so that the friction
        # alone (not the segment) takes the tangential motion away
        # ... and ``margin`` off it, or as far off as it came from if that was
        # nearer: a point resting within the margin must not bounce off it
        for c in range(3):
            out[c] = q1[c]
        off = min(margin, abs(q0[axis]) - half[axis])
        out[axis] = (1.0 if q0[axis] > 0.0 else -1.0) * (half[axis] + off)
        for c in range(3):
            out[c] = q0[c] + keep * (out[c] - q0[c])
        return True
    inside1 = True
    for c in range(3):
        if not abs(q1[c]) < half[c]:
            inside1 = False
    if not inside1:
        return False
    axis, room = 0, np.inf
    for c in range(3):
        gap = half[c] - abs(q1[c])
        if gap < room:
            axis, room = c, gap
    for c in range(3):
        out[c] = q1[c]
    out[axis] = (1.0 if q1[axis] > 0.0 else -1.0) * (half[axis] + margin)
    return True


@njit(**EXACT_OPTIONS)
def _boxes_pass(P, R, free, boxes, lo, hi, s, with_motion):
    """Points ``lo:hi`` of P against every box, from their reference positions R
    (last positions carried by each box's motion and with friction, or with
    neither: see the two kernels)."""
    rows = boxes[min(s, boxes.shape[0] - 1)]
    q0, q1, half, out = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    for k in range(rows.shape[0]):
        row = rows[k]
        half[0], half[1], half[2] = row[12], row[13], row[14]
        keep = 1.0 - row[15] if with_motion else 0.0
        margin = row[16]
        for p in range(lo, hi):
            if free[p] == 0.0:
                continue
            rx, ry, rz = R[0, p], R[1, p], R[2, p]
            if with_motion:
                rx, ry, rz = carried(row, COLUMNS, rx, ry, rz)
            q1[0], q1[1], q1[2] = _local(row, P[0, p], P[1, p], P[2, p])
            q0[0], q0[1], q0[2] = _local(row, rx, ry, rz)
            if not (np.isfinite(q0[0] + q0[1] + q0[2] + q1[0] + q1[1] + q1[2])):
                continue
            # the segment's box misses the box: the common case, decided at once
            miss = False
            for c in range(3):
                if min(q0[c], q1[c]) >= half[c] or max(q0[c], q1[c]) <= -half[c]:
                    miss = True
            if miss:
                continue
            if _resolve(q0, q1, half, margin, keep, out):
                P[0, p], P[1, p], P[2, p] = _world(row, out[0], out[1], out[2])


@njit(**EXACT_OPTIONS)
def collide_boxes(P, L, free, boxes, lo, hi, s):
    """Points ``lo:hi`` that entered a box over substep ``s`` (their segment from the
    last position, carried by the box's motion) are put at the face they met,
    margin outside, then moved back toward that carried last position by the
    friction. ``boxes`` None: nothing (pruned when numba compiles it)."""
    if boxes is None:
        return
    _boxes_pass(P, L, free, boxes, lo, hi, s, True)


@njit(**EXACT_OPTIONS)
def settle_boxes(P, Q, free, boxes, lo, hi, s):
    """Points ``lo:hi`` that a later pass moved from Q (after the colliders) into a
    box are put back at the face they crossed, margin outside, with no friction."""
    if boxes is None:
        return
    _boxes_pass(P, Q, free, boxes, lo, hi, s, False)
