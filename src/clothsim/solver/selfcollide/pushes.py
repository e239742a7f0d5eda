"""The pushes: pairs closer than the reach pushed apart, and the points moved by their pushes.

The timings behind their choices are in docs/performance.md ('Pushes').
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..shared import EXACT_OPTIONS, KERNEL_OPTIONS, gap2

@njit(**EXACT_OPTIONS)
def pair_pushes(P, reach, pairs, k0, sure, k1, lists, part, before, wide2):
    """Add the pushes of listed pairs ``k0:k1`` closer than ``reach`` to ``push`` (3, N)
    and ``count`` (N,), noting their ends in ``touched`` after those of the
    ``before`` pairs pushed already (see :func:`push_pair`); returns how many
    pairs that was.

    Pairs ``k0:sure`` are pushed without a branch on whether they touch:
    every one adds its push, zero where it does not. That costs a square
    root and the stores for each, and pays where about half of them touch
    and the branch would be mispredicted as often, as on the pairs that
    touched at the build. Pairs ``sure:k1`` rarely touch and keep the
    branch; they are first tested on ``Q``, the positions in single
    precision, against ``wide2`` (see :func:`near_pushes`): half the memory
    to gather from.
    """
    # part ``part``'s scratch of the :class:`~.buffers.NeighbourList`, and the
    # positions in single precision
    push, count, touched, Q = lists.push[part], lists.count[part], lists.touched[part], lists.pos32
    reach2 = reach * reach
    x, y, z = P[0], P[1], P[2]
    hits = 0
    room = touched.shape[0] // 2 - 1
    for k in range(k0, sure):
        # unsigned: a signed index costs a negative-index check per access
        q = np.uint64(k)
        a = np.uint64(pairs[0, q])
        b = np.uint64(pairs[1, q])
        dx = x[a] - x[b]
        dy = y[a] - y[b]
        dz = z[a] - z[b]
        d2 = dx * dx + dy * dy + dz * dz
        close = (d2 < reach2) & (d2 != 0.0)
        d = np.sqrt(d2 if close else reach2)  # the push of a pair at the reach is zero
        add_push(push, count, a, b, dx, dy, dz, (reach - d) / d, 1.0 if close else 0.0)
        # noted whether it touches or not: the next pair that does overwrites it
        at = np.uint64(2 * min(before + hits, room))
        touched[at] = a
        touched[at + np.uint64(1)] = b
        hits += 1 if close else 0
    qx, qy, qz = Q[0], Q[1], Q[2]
    for k in range(sure, k1):
        q = np.uint64(k)
        a = np.uint64(pairs[0, q])
        b = np.uint64(pairs[1, q])
        if not gap2(qx, qy, qz, a, qx, qy, qz, b) < wide2:
            continue
        d2 = gap2(x, y, z, a, x, y, z, b)
        if not ((d2 < reach2) & (d2 != 0.0)):
            continue
        push_pair(P, a, b, reach, push, count, touched, before + hits)
        hits += 1
    return hits


@njit(**EXACT_OPTIONS, inline="always")
def push_pair(P, a, b, reach, push, count, touched, k):
    """Add the push of the pair (a, b), closer than ``reach``, to both ends: each
    goes to ``reach`` from the other's place. The ``k``-th pair a part pushes
    notes its ends in ``touched[2k:2k + 2]`` while there is room."""
    dx = P[0, a] - P[0, b]
    dy = P[1, a] - P[1, b]
    dz = P[2, a] - P[2, b]
    d = np.sqrt(dx * dx + dy * dy + dz * dz)
    add_push(push, count, a, b, dx, dy, dz, (reach - d) / d, 1.0)
    if 2 * k < touched.shape[0]:
        at = np.uint64(2 * k)
        touched[at] = a
        touched[at + np.uint64(1)] = b


@njit(cache=True, inline="always")
def add_push(push, count, a, b, dx, dy, dz, s, one):
    """Add (dx, dy, dz) * s to a's push and take it from b's; ``one`` to each count.
    The push is rounded to the buffers' single precision (:data:`~.buffers.PUSH_DTYPE`)
    before it is added, so that the sums stay in single precision: no conversion
    of what is read to double and back."""
    px, py, pz = np.float32(dx * s), np.float32(dy * s), np.float32(dz * s)
    push[0, a] += px
    push[1, a] += py
    push[2, a] += pz
    push[0, b] -= px
    push[1, b] -= py
    push[2, b] -= pz
    count[a] += np.float32(one)
    count[b] += np.float32(one)


@njit(**KERNEL_OPTIONS)
def apply_sparse(P, push, count, free, inv_steps, touched, tally):
    """:func:`apply_pushes` for the ends of the pushed pairs only, when each part
    noted all of its pairs in ``touched`` (``tally[t, 1]`` pairs in part t).

    A hanging cloth pushes a few pairs in a substep, and a pass over every
    point then costs far more than moving their ends. A point noted again
    has been applied and zeroed by then, so applying it again moves it by
    nothing.
    Each end is moved by plain scalar code: :func:`apply_pushes` over a
    range of one point spent most of its time making its array views.
    """
    parts = push.shape[0]
    for t in range(parts):
        ends = touched[t]
        for k in range(2 * tally[t, 1]):
            a = ends[k]
            c = count[0, a]
            for u in range(1, parts):
                c += count[u, a]
                count[u, a] = 0.0
            weight = free[a] * inv_steps / max(c, 1.0)
            count[0, a] = 0.0
            for d in range(3):
                s = push[0, d, a]
                push[0, d, a] = 0.0
                for u in range(1, parts):
                    s += push[u, d, a]
                    push[u, d, a] = 0.0
                P[d, a] += s * weight


@njit(**KERNEL_OPTIONS)
def apply_pushes(P, push, count, free, inv_steps, lo, hi):
    """Move points ``lo:hi`` by their summed pushes, averaged over their colliding
    pairs and divided by the substeps; sums the parts' pushes into part 0 first,
    or, with two parts (two threads), in the same loop: on a piled 100x100 cloth
    the four passes and one took 1.6 times as long as the one.
    The pushes and counts are left at zero for the next substep: a separate pass
    to clear them would run every substep, this one only when something collided.
    One loop moves and clears each point, not a loop per coordinate."""
    parts = push.shape[0]
    m = hi - lo
    x, y, z = P[0, lo:], P[1, lo:], P[2, lo:]
    px, py, pz = push[0, 0, lo:], push[0, 1, lo:], push[0, 2, lo:]
    c0 = count[0, lo:]
    fr = free[lo:]
    if parts == 2:
        # two threads: the other part's pushes summed in the same loop, one pass
        # over the eight planes instead of four passes and one
        qx, qy, qz, c1 = push[1, 0, lo:], push[1, 1, lo:], push[1, 2, lo:], count[1, lo:]
        for p in range(m):
            weight = fr[p] * inv_steps / max(c0[p] + c1[p], 1.0)
            x[p] += (px[p] + qx[p]) * weight
            y[p] += (py[p] + qy[p]) * weight
            z[p] += (pz[p] + qz[p]) * weight
            px[p] = 0.0
            py[p] = 0.0
            pz[p] = 0.0
            c0[p] = 0.0
            qx[p] = 0.0
            qy[p] = 0.0
            qz[p] = 0.0
            c1[p] = 0.0
        return
    for t in range(1, parts):
        ct = count[t, lo:]
        for p in range(m):
            c0[p] += ct[p]
            ct[p] = 0.0
        for c in range(3):
            p0, pt = push[0, c, lo:], push[t, c, lo:]
            for p in range(m):
                p0[p] += pt[p]
                pt[p] = 0.0
    for p in range(m):
        weight = fr[p] * inv_steps / max(c0[p], 1.0)
        x[p] += px[p] * weight
        y[p] += py[p] * weight
        z[p] += pz[p] * weight
        px[p] = 0.0
        py[p] = 0.0
        pz[p] = 0.0
        c0[p] = 0.0
