"""Provot's rule: no enabled spring longer than 110% of its rest length."""

from __future__ import annotations

import numpy as np
from numba import njit

MAX_STRETCH = 1.1


@njit(cache=True, fastmath=True, boundscheck=False, inline="always")
def _limit_spring(pos, pinned, a, b, rest):
    """Shorten one spring to MAX_STRETCH*rest if it is longer."""
    pa = pinned[a]
    pb = pinned[b]
    if pa and pb:
        return
    dx = pos[b, 0] - pos[a, 0]
    dy = pos[b, 1] - pos[a, 1]
    dz = pos[b, 2] - pos[a, 2]
    l2 = dx * dx + dy * dy + dz * dz
    limit = MAX_STRETCH * rest
    if l2 <= limit * limit:
        return
    length = np.sqrt(l2)
    excess = (length - limit) / length
    ca = 0.0 if pa else (excess if pb else 0.5 * excess)
    cb = 0.0 if pb else (excess if pa else 0.5 * excess)
    pos[a, 0] += dx * ca
    pos[a, 1] += dy * ca
    pos[a, 2] += dz * ca
    pos[b, 0] -= dx * cb
    pos[b, 1] -= dy * cb
    pos[b, 2] -= dz * cb


@njit(cache=True, fastmath=True, boundscheck=False)
def provot(pos, pinned, spring_a, spring_b, spring_rest, kind_start, enabled):
    """Shorten over-stretched springs in place, in spring order (Gauss-Seidel).

    The correction goes half to each end, all of it to the free end when the
    other is pinned, and nowhere when both are pinned. Kind k spans
    ``kind_start[k] : kind_start[k+1]``; disabled kinds are skipped.
    """
    for kind in range(enabled.shape[0]):
        if enabled[kind]:
            for s in range(kind_start[kind], kind_start[kind + 1]):
                _limit_spring(pos, pinned, spring_a[s], spring_b[s], spring_rest[s])
