"""Handles: points of a cloth moved by an animation instead of pinned in place.

A handle's points are pinned in the model (no force, collider or constraint
moves them); each substep puts them where their animation carries their
start positions. They reach the kernels as the control's ``moved_points``
(int64 (H,), every handle's points) and ``moved_to`` (float64 (T, H, 3):
where they are at the end of each substep of the frame; T is 1 when no
handle moves).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit

from .colliders.motion_rows import frame_poses


def pack_handles(handles: Sequence, t0: float = 0.0, dt: float = 0.0,
                 substeps: int = 1) -> tuple[np.ndarray | None, np.ndarray | None]:
    """(moved_points, moved_to) from objects with ``points`` (int64 indices),
    ``start`` ((H, 3) [m]), ``pivot`` ((3,) [m]) and ``animation``; (None, None)
    for no handles, so that :func:`place_handles` is not compiled."""
    if not handles:
        return None, None
    slots = []
    for h in handles:
        R, o, _ = frame_poses(h.animation, h.pivot, t0, dt, substeps)
        slots.append(np.einsum("tij,hj->thi", R, np.asarray(h.start, dtype=np.float64)) + o[:, None, :])
    T = max(len(s) for s in slots)
    moved_to = np.concatenate([np.broadcast_to(s, (T,) + s.shape[1:]) for s in slots], axis=1)
    points = np.concatenate([np.asarray(h.points, dtype=np.int64) for h in handles])
    return points, np.ascontiguousarray(moved_to)


@njit(cache=True, boundscheck=False)
def place_handles(P, moved_points, moved_to, s):
    """Put the handles' ``moved_points`` of the (3, N) positions P where ``moved_to`` says
    substep ``s`` ends for them (the control's fields). ``moved_points`` None: nothing
    (numba prunes a branch on an argument that is None, not on a field)."""
    if moved_points is None:
        return
    to = moved_to[min(s, moved_to.shape[0] - 1)]
    for h in range(moved_points.shape[0]):
        p = moved_points[h]
        P[0, p] = to[h, 0]
        P[1, p] = to[h, 1]
        P[2, p] = to[h, 2]
