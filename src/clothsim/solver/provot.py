"""Provot's stretch limit: no spring longer than MAX_STRETCH times its rest length."""

from __future__ import annotations

import numpy as np
from numba import njit

from .provot_lanes import over_word
from .shared import BLOCK, KERNEL_OPTIONS, divided_by_length, gap2, pop_lowest

MAX_STRETCH = 1.1
"""Provot: no spring longer than this times its rest length"""


@njit(**KERNEL_OPTIONS)
def provot(P, springs, enabled, masks, lo, hi, crossing):
    """Shorten every enabled spring longer than its limit (1.1x rest) back to it.

    ``springs`` is the cloth's :class:`~clothsim.solver.springs.GridSprings`,
    ``enabled`` (6,) bool which of its sets take part.

    Only the springs with both ends in points ``lo:hi`` are taken, or with
    ``crossing`` those with one end before ``lo`` and one from ``lo`` on. A
    thread then owns its part of the cloth; the springs across a cut
    between two parts are shortened afterwards. ``0, N, False`` takes all.

    One Gauss-Seidel pass over each set in two batches of springs that share
    no point (every other row of a vertical set, every other spring of a row
    for a horizontal one): within a batch that gives the same result as any
    sequential order.

    Few springs are over the limit at any time (a mean of 4 to 8 in each
    block of BLOCK that has one, in the standard scenes). So the whole set is
    first checked without square roots, a bit per spring over, a word per
    BLOCK springs (:func:`check_set`), and then only those springs are corrected, one by
    one, which spares the mostly wasted work of correcting whole flagged
    blocks as vectors (figures: docs/performance.md, 'Provot'). The check
    serves both batches: a spring of the second batch can only have changed
    its length if a correction of the first moved one of its ends, and those
    (the springs ``o`` before and after, ``o`` the set's offset) are marked
    and checked again. Checking each batch on its own walked a horizontal set
    twice. ``masks`` is uint64 scratch, (2, words), a word per BLOCK springs
    of a set.
    """
    start, end, count = springs.start, springs.end, springs.count
    limit, batch, share = springs.limit, springs.batch, springs.share
    x, y, z = P[0], P[1], P[2]
    found, again = masks[0], masks[1]
    for s in range(6):
        if not enabled[s]:
            continue
        oa, ob = start[s], end[s]
        o = ob - oa
        # springs p of this set with both ends inside, or across the cut at lo
        plo, phi = (lo - ob, lo - oa) if crossing else (lo - oa, hi - ob)
        first, stop = max(plo, 0), min(phi, count[s])
        lim_s, batch_s, wa, wb = limit[s], batch[s], share[s, 0], share[s, 1]
        words = check_set((x, y, z), oa, ob, lim_s, first, stop, found, again)
        for w in range(words):
            mask = found[w]
            while mask != 0:
                j, mask = pop_lowest(mask)
                p = first + w * BLOCK + j
                if batch_s[p] != 0:
                    continue
                shorten(P, oa + p, ob + p, lim_s[p], wa[p], wb[p])
                for j in (p - o - first, p + o - first):
                    if 0 <= j < stop - first:
                        again[j // BLOCK] |= np.uint64(1) << np.uint64(j % BLOCK)
        for w in range(words):
            mask = found[w] | again[w]
            while mask != 0:
                j, mask = pop_lowest(mask)
                p = first + w * BLOCK + j
                if batch_s[p] == 0:
                    continue
                a, b = oa + p, ob + p
                if gap2(x, y, z, a, x, y, z, b) > lim_s[p] * lim_s[p]:
                    shorten(P, a, b, lim_s[p], wa[p], wb[p])


@njit(**KERNEL_OPTIONS, inline="always")
def check_set(planes, oa, ob, lim_s, first, stop, found, again):
    """The check of springs ``first:stop`` of a set joining point ``oa + p`` to
    ``ob + p`` of ``planes`` (x, y, z) [m], each against its limit ``lim_s[p]``
    [m]: a bit per spring over it into ``found``, a word per BLOCK springs from
    ``first``, the same words of ``again`` cleared. The whole blocks as
    vector comparisons' bytes (:func:`.provot_lanes.over_word`), the last few
    in a loop. Returns the count of words."""
    x, y, z = planes
    words = 0
    full = stop - max(stop - first, 0) % BLOCK  # the blocks of BLOCK whole springs end here
    for q in range(first, full, BLOCK):
        found[words] = over_word(planes, oa, ob, lim_s, q)
        again[words] = 0
        words += 1
    for q in range(max(full, first), stop, BLOCK):  # the last few, if any
        n = stop - q
        xa, ya, za = x[oa + q:], y[oa + q:], z[oa + q:]
        xb, yb, zb = x[ob + q:], y[ob + q:], z[ob + q:]
        lim = lim_s[q:]
        mask = np.uint64(0)  # an or of shifted selects vectorises
        for p in range(n):
            over = gap2(xa, ya, za, p, xb, yb, zb, p) > lim[p] * lim[p]
            mask |= np.uint64(1 if over else 0) << np.uint64(p)
        found[words] = mask
        again[words] = 0
        words += 1
    return words


@njit(**KERNEL_OPTIONS, inline="always")
def shorten(P, a, b, lim, wa, wb):
    """Shorten the spring from point a to point b to ``lim``, moving a by ``wa`` and b
    by ``wb`` of the correction."""
    dx = P[0, b] - P[0, a]
    dy = P[1, b] - P[1, a]
    dz = P[2, b] - P[2, a]
    e = 1.0 - divided_by_length(lim, dx * dx + dy * dy + dz * dz)
    ea = e * wa
    eb = e * wb
    P[0, a] += ea * dx
    P[1, a] += ea * dy
    P[2, a] += ea * dz
    P[0, b] -= eb * dx
    P[1, b] -= eb * dy
    P[2, b] -= eb * dz
