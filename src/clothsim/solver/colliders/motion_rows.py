"""The columns every moving collider's row ends with: how the collider moved over a substep.

A collider's rows are float64 (T, K, C): slot s (row ``min(s, T-1)``) is
collider k at the end of substep s of the frame; T is 1 when no collider of
the kind moves. The last CARRY columns of a row are the rigid map
``x -> A @ x + b`` (A row-major) that takes a point fixed to the collider at
the start of the substep to where it is at the end: the CS184 friction rule
is applied to a point's last position carried so, which is how a moving
collider drags the cloth along.
"""

from __future__ import annotations

import numpy as np
from numba import njit

CARRY = 12
"""A (9, row-major) and b (3)"""


def key_array(animation) -> np.ndarray:
    """An animation's keys as rows (t, translate (3), rotate (3) [degrees]), float64
    (K, 7), kept on the animation (it is frozen: its keys never change)."""
    cached = animation.__dict__.get("_key_array")
    if cached is None:
        cached = np.array([(k.t, *k.translate, *k.rotate) for k in animation.keys], dtype=np.float64)
        animation.__dict__["_key_array"] = cached
    return cached


def frame_poses(animation, pivot, t0: float, dt: float, substeps: int):
    """(R_now (T, 3, 3), o_now (T, 3), carry (T, CARRY)) of one frame's substeps, as
    :func:`clothsim.motion.slot_poses` gives them but sampled in compiled code:
    a frame's control is made anew every frame, and numpy's small calls cost
    more than the substeps' collisions. T is 1 for no animation or a still one,
    and at least 2 for a moving one, also in a frame of one substep: the kernels
    take T > 1 to mean that a collider moves."""
    R, o, carry = frame_poses_both(animation, pivot, t0, dt, substeps)
    if carry.shape[0] == 1 and animation is not None and not animation.is_still:
        # a moving collider's frame of one substep: two slots, the same twice, so
        # that T > 1 still tells the kernels it moves (they then apply its carry)
        return R[1:].repeat(2, axis=0), o[1:].repeat(2, axis=0), carry.repeat(2, axis=0)
    return R[1:], o[1:], carry


def frame_poses_both(animation, pivot, t0: float, dt: float, substeps: int):
    """(R (T+1, 3, 3), o (T+1, 3), carry (T, CARRY)): as :func:`frame_poses`, with
    the poses at the start of the frame's first substep too (R[s] before substep
    s, R[s+1] after it)."""
    if animation is None:
        return _REST
    keys = key_array(animation)
    if animation.is_still:
        R, o, carry = _sample(keys, bool(animation.loop), np.asarray(pivot, dtype=np.float64), keys[0, 0], 0.0, 1)
        carry[:] = _IDENTITY
        return R[1:].repeat(2, axis=0), o[1:].repeat(2, axis=0), carry
    return _sample(keys, bool(animation.loop), np.asarray(pivot, dtype=np.float64), float(t0), float(dt),
                   int(substeps))


_IDENTITY = np.concatenate([np.eye(3).ravel(), np.zeros(3)])
_REST = (np.eye(3)[None].repeat(2, axis=0), np.zeros((2, 3)), _IDENTITY[None].copy())
for _a in _REST:
    _a.setflags(write=False)


@njit(cache=True, boundscheck=False)
def _offset(keys, loop, t, out):
    """translation and angles [degrees] at time t into out (6,): linear between keys,
    held outside them, or repeating the keys' span when ``loop``"""
    n = keys.shape[0]
    first, last = keys[0, 0], keys[n - 1, 0]
    if loop and n > 1 and last > first and t > last:
        t = first + (t - first) % (last - first)
    if not t > first:
        out[:] = keys[0, 1:]
        return
    if not t < last:
        out[:] = keys[n - 1, 1:]
        return
    k = 1
    while keys[k, 0] < t:
        k += 1
    w = (t - keys[k - 1, 0]) / (keys[k, 0] - keys[k - 1, 0])
    for c in range(6):
        out[c] = keys[k - 1, c + 1] + w * (keys[k, c + 1] - keys[k - 1, c + 1])


@njit(cache=True, boundscheck=False)
def _rotation(deg, R):
    """Rz @ Ry @ Rx of the angles deg[3:6] [degrees] into R (3, 3)"""
    ax, ay, az = np.radians(deg[3]), np.radians(deg[4]), np.radians(deg[5])
    cx, sx, cy, sy, cz, sz = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay), np.cos(az), np.sin(az)
    R[0, 0], R[0, 1], R[0, 2] = cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx
    R[1, 0], R[1, 1], R[1, 2] = sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx
    R[2, 0], R[2, 1], R[2, 2] = -sy, cy * sx, cy * cx


@njit(cache=True, boundscheck=False)
def _sample(keys, loop, pivot, t0, dt, substeps):
    T = substeps
    R = np.empty((T + 1, 3, 3))
    o = np.empty((T + 1, 3))
    off = np.empty(6)
    for s in range(T + 1):
        _offset(keys, loop, t0 + s * dt, off)
        _rotation(off, R[s])
        for c in range(3):
            o[s, c] = pivot[c] + off[c] - (R[s, c, 0] * pivot[0] + R[s, c, 1] * pivot[1] + R[s, c, 2] * pivot[2])
    carry = np.empty((T, CARRY))
    for s in range(T):
        # A = R_now @ R_before^T, b = o_now - A @ o_before
        for i in range(3):
            for j in range(3):
                carry[s, 3 * i + j] = (R[s + 1, i, 0] * R[s, j, 0] + R[s + 1, i, 1] * R[s, j, 1]
                                       + R[s + 1, i, 2] * R[s, j, 2])
        for i in range(3):
            carry[s, 9 + i] = o[s + 1, i] - (carry[s, 3 * i] * o[s, 0] + carry[s, 3 * i + 1] * o[s, 1]
                                             + carry[s, 3 * i + 2] * o[s, 2])
    return R, o, carry


def moving_rows(R, o, carry, points=(), directions=(), frames=(), fixed=()) -> np.ndarray:
    """A collider's rows (T, C) from its frame's poses (:func:`frame_poses`): each of
    ``points`` (3 each) posed, ``R @ p + o``; each of ``directions`` turned, ``R @ v``;
    each of ``frames`` (3x3 each) turned, ``R @ F`` row-major; then ``fixed`` as
    they are; then the carry columns. Compiled: it runs every frame."""
    f64 = np.float64
    return _rows(R, o, carry, np.asarray(points, dtype=f64).reshape(-1, 3),
                 np.asarray(directions, dtype=f64).reshape(-1, 3), np.asarray(frames, dtype=f64).reshape(-1, 3, 3),
                 np.asarray(fixed, dtype=f64).reshape(-1))


@njit(cache=True, boundscheck=False)
def _rows(R, o, carry, spots, directions, frames, fixed):
    T = R.shape[0]
    C = 3 * spots.shape[0] + 3 * directions.shape[0] + 9 * frames.shape[0] + fixed.shape[0] + CARRY
    out = np.empty((T, C))
    for t in range(T):
        c = 0
        for k in range(spots.shape[0]):
            for i in range(3):
                out[t, c + i] = o[t, i] + R[t, i, 0] * spots[k, 0] + R[t, i, 1] * spots[k, 1] + R[t, i, 2] * spots[k, 2]
            c += 3
        for k in range(directions.shape[0]):
            for i in range(3):
                out[t, c + i] = R[t, i, 0] * directions[k, 0] + R[t, i, 1] * directions[k, 1] + R[t, i, 2] * directions[k, 2]
            c += 3
        for k in range(frames.shape[0]):
            for i in range(3):
                for j in range(3):
                    out[t, c + 3 * i + j] = (R[t, i, 0] * frames[k, 0, j] + R[t, i, 1] * frames[k, 1, j]
                                             + R[t, i, 2] * frames[k, 2, j])
            c += 9
        for k in range(fixed.shape[0]):
            out[t, c + k] = fixed[k]
        c += fixed.shape[0]
        for k in range(CARRY):
            out[t, c + k] = carry[t, k]
    return out


def stack_slots(per_collider: list[np.ndarray]) -> np.ndarray:
    """Rows (T, K, C) from each collider's (T_k, C) slots, T_k 1 or T: a still
    collider's one slot serves every substep."""
    if len(per_collider) == 1:
        return per_collider[0][:, None, :]
    T = max(r.shape[0] for r in per_collider)
    return np.ascontiguousarray(np.stack([np.broadcast_to(r, (T, r.shape[1])) for r in per_collider], axis=1))


@njit(cache=True, inline="always")
def carry_of(row, c):
    """The carry columns that start at column c of ``row`` as 12 scalars: read into
    locals before a loop over the points, so that LLVM needs not prove the
    positions written there never alias the rows (and then vectorises)."""
    return (row[c], row[c + 1], row[c + 2], row[c + 3], row[c + 4], row[c + 5], row[c + 6], row[c + 7],
            row[c + 8], row[c + 9], row[c + 10], row[c + 11])


@njit(cache=True, inline="always")
def carry_point(a, x, y, z):
    """The point (x, y, z) moved by the carry ``a`` of :func:`carry_of`."""
    return (a[0] * x + a[1] * y + a[2] * z + a[9],
            a[3] * x + a[4] * y + a[5] * z + a[10],
            a[6] * x + a[7] * y + a[8] * z + a[11])
