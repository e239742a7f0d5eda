"""The first pass of a mesh collider's kernels: which points they must look at.

Most of a cloth is far from a mesh collider's surface, and a point's own
tests in the per-point loop of :mod:`.mesh` would cost each of them
mispredicted branches. :func:`look` makes those first tests for every point
at once, without branches, in a loop LLVM turns into vector code: pinned or
not finite, a segment whose box misses the mesh's box, or a short segment
ending in a quiet cell (no triangle in it or its neighbours, and, for a
closed mesh, outside). The points left are listed, in ascending order, for
the hint pass (:mod:`.meshhint`) and the search.

The settle pass tests the segments from the positions after the collider
pass to those after a later pass, which leaves most points where they were:
:func:`look_settle` finds those that moved first and, where they are few,
flags them alone.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..shared import EXACT_OPTIONS, pop_lowest
from ..simd import FLAGS8, flagged_lanes, has_compress, kept_lanes
from .meshgrid import INSIDE_BITS, NEAR
from .meshpose import is_rest
from .meshpose import to_rest as _to_rest


@njit(**EXACT_OPTIONS, inline="always")
def _clamped_cell(v, origin, inv_h, n):
    """:func:`.meshgrid.cell_coord` without branches (selects), for the vector pass:
    the cell number along one axis clamped to 0..n-1, 0 for NaN."""
    f = (v - origin) * inv_h
    f = f if f > 0.0 else 0.0
    f = f if f < n - 1.0 else n - 1.0
    return np.int32(f)


@njit(**EXACT_OPTIONS, inline="always")
def _flag(q, segment, here, bounds, need, cell):
    """The tests of :func:`look` for point q, its segment (x0, y0, z0, x1, y1, z1)
    in the mesh's rest frame: ``need[q]`` as :func:`look` says, ``cell[q]`` the cell
    of its end where the move is short on every axis (-1 where not). ``here``: the
    point views (lx, ly, lz, px, py, pz, free) from the first point; ``bounds``:
    (reach, short, moved, the grid's origin (3), its far corner (3), 1/h, its
    counts as floats (3) and as int32 (2))."""
    x0, y0, z0, x1, y1, z1 = segment
    lx, ly, lz, px, py, pz, fr = here
    reach, short, moved, ox, oy, oz, hx, hy, hz, inv, nx, ny, nz, inx, iny = bounds
    finite = (np.isfinite(x0) & np.isfinite(y0) & np.isfinite(z0) & np.isfinite(x1) & np.isfinite(y1)
              & np.isfinite(z1))
    meets = ((_larger(x0, x1) + reach >= ox) & (_smaller(x0, x1) - reach <= hx)
             & (_larger(y0, y1) + reach >= oy) & (_smaller(y0, y1) - reach <= hy)
             & (_larger(z0, z1) + reach >= oz) & (_smaller(z0, z1) - reach <= hz))
    ix, iy, iz = _clamped_cell(x1, ox, inv, nx), _clamped_cell(y1, oy, inv, ny), _clamped_cell(z1, oz, inv, nz)
    short_move = (abs(x1 - x0) < short) & (abs(y1 - y0) < short) & (abs(z1 - z0) < short)
    need[q] = ((fr[q] != 0.0) & finite & meets
               & ((not moved) | (lx[q] != px[q]) | (ly[q] != py[q]) | (lz[q] != pz[q])))
    cell[q] = (iz * iny + iy) * inx + ix if short_move else np.int32(-1)


@njit(**EXACT_OPTIONS)
def look(P, L, free, lo, frames, G, limits, items, need, listed):
    """The kernels' vector pass over points ``lo:lo + len(need)`` for one mesh in the
    poses ``frames`` (before, now; :func:`.meshpose.frame`): the numbers of the points that the
    per-point loop must look at (from 0 at ``lo``, ascending) in the first entries of
    ``listed`` (as long as ``need``), ``need`` set for each of them, and their count (the
    kernels read ``need`` only through ``listed``: a point not listed may keep its flag,
    see :func:`_walk_compressed`). The rest are pinned, not finite,
    with a segment whose box misses the mesh's box grown by the reach, or
    (as :func:`.mesh._clear` says) with a segment shorter than ``short`` on every axis that ends in a
    cell without NEAR (and, for a closed mesh, whose centre is not inside), or, where
    ``moved``, that are where they were (``L`` is then the positions before a later
    pass); ``limits`` is (reach, short [m], closed, moved); ``G`` the grid's scalars
    (:func:`.mesh._grid_scalars`), ``items`` the cells' status entries among them. The loop's own first
    tests, made here without branches for every point at once, so that the points
    far from the surface, most of a cloth, cost no mispredicted branch. A mesh that
    stands in its rest pose in both frames (a still mesh, whose file placed it) is
    read as it is: the turns would give the same coordinates (x - 0 = x, 1x + 0y +
    0z = x) and the same outcome (a non-finite coordinate fails the finite test
    either way), and the loop runs in three quarters of the time."""
    before, now = frames
    plain = is_rest(before) and is_rest(now)
    reach, short, closed, moved = limits
    ox, oy, oz, hx, hy, hz, _, inv, nx, ny, nz, _, s0f, _ = G
    inx, iny, s0 = np.int32(nx), np.int32(ny), int(s0f)
    n = need.shape[0]
    # views from lo, indexed from 0 by the loop: numba then knows no index is negative
    # and emits plain vector loads, not a wrap-around select per access
    lx, ly, lz = L[0, lo:lo + n], L[1, lo:lo + n], L[2, lo:lo + n]
    px, py, pz = P[0, lo:lo + n], P[1, lo:lo + n], P[2, lo:lo + n]
    fr = free[lo:lo + n]
    cell = np.empty(n, dtype=np.int32)
    here = (lx, ly, lz, px, py, pz, fr)
    bounds = (reach, short, moved, ox, oy, oz, hx, hy, hz, inv, nx, ny, nz, inx, iny)
    # two loops, not one with the test inside: LLVM kept that test in the loop
    # and read the positions there through masked loads
    if plain:
        for q in range(n):  # vectorised: no gather in it
            _flag(q, (lx[q], ly[q], lz[q], px[q], py[q], pz[q]), here, bounds, need, cell)
    else:
        for q in range(n):
            x0, y0, z0 = _to_rest(before, lx[q], ly[q], lz[q])
            x1, y1, z1 = _to_rest(now, px[q], py[q], pz[q])
            _flag(q, (x0, y0, z0, x1, y1, z1), here, bounds, need, cell)
    return _walk(need, cell, (items, s0, closed), listed)


@njit(**EXACT_OPTIONS, inline="always")
def _walk_words(need, cell, status, listed):
    """The end of :func:`look`: the cells' status entries (``status``: items, the first
    one's index, closed) read for the points still in question (:func:`_busy`),
    their flags eight at a time (one byte each, 0 or 1), a word of none skipped at
    once; those still in question listed. Returns their count."""
    items, s0, closed = status
    n = need.shape[0]
    count = 0
    whole = n // 8 * 8
    words = need[:whole].view(np.uint64)
    for w in range(words.shape[0]):
        bits = words[w]
        while bits:
            b, bits = pop_lowest(bits)
            q = w * 8 + b // 8
            need[q] = _busy(q, items, s0, closed, need, cell)
            listed[count] = q
            count += np.int64(need[q])
    for q in range(whole, n):
        need[q] = _busy(q, items, s0, closed, need, cell)
        listed[count] = q
        count += np.int64(need[q])
    return count


@njit(**EXACT_OPTIONS, inline="always")
def _walk_compressed(need, cell, status, listed):
    """:func:`_walk_words` with AVX-512's compress: the flagged points listed first,
    eight flags at a time and no branch (the walk over a word's bits mispredicted
    its end for most words), then their cells and status entries read eight at a
    time by two gathers, and those still in question kept by a second compress
    (:func:`..simd.kept_lanes`; read one by one, with each point appended,
    they took nearly half the look's time: docs/performance.md). The same list
    and count; the flags of the
    points it drops are left set, where :func:`_walk_words` clears them: the
    kernels read the flags only through the list."""
    items, s0, closed = status
    n = need.shape[0]
    flagged = 0
    whole = n // FLAGS8 * FLAGS8
    for at in range(0, whole, FLAGS8):
        # writes listed[flagged:flagged + 8], within listed: flagged <= at
        flagged += flagged_lanes(need, at, listed, flagged)
    for q in range(whole, n):
        listed[flagged] = q
        flagged += np.int64(need[q])
    keep = NEAR | (INSIDE_BITS if closed else 0)
    count = 0
    whole = flagged // FLAGS8 * FLAGS8
    for i in range(0, whole, FLAGS8):
        # writes listed[count:count + 8] after reading listed[i:i + 8], count <= i
        count += kept_lanes(listed, i, cell, items, s0, keep, listed, count)
    for i in range(whole, flagged):
        q = listed[i]
        c = cell[q]
        st = items[np.uint64(s0 + (c if c > 0 else 0))]
        listed[count] = q
        count += np.int64((c < 0) | ((st & keep) != 0))
    return count


COMPRESS = has_compress()
"""whether :func:`look` lists its points with AVX-512's compress (:func:`_walk_compressed`)"""

_walk = _walk_compressed if COMPRESS else _walk_words


FEW_MOVED = 5
"""the settle pass looks at the points that moved one by one where at most one in
FEW_MOVED did: :func:`_look_moved`"""


@njit(**EXACT_OPTIONS, inline="always")
def _busy(q, items, s0, closed, need, cell):
    """``need[q]``, but False where point q's cell (``cell[q]``, -1 for none) is quiet:
    no NEAR bit in its status entry (``items[s0 + cell]``) and, for a closed mesh,
    its centre not inside."""
    if need[q] and cell[q] >= 0:
        st = items[np.uint64(s0 + cell[q])]  # unsigned: no wrap-around select
        return not ((st & NEAR) == 0 and not (closed and (st & INSIDE_BITS) != 0))
    return need[q]


@njit(**EXACT_OPTIONS)
def _moved(here, moving):
    """How many free points moved (``here`` as for :func:`_flag`: L the positions
    before a later pass), each marked 1 in ``moving`` (uint8, a multiple of 8 long;
    the rest 0)."""
    lx, ly, lz, px, py, pz, fr = here
    n = fr.shape[0]
    count = 0
    for q in range(n):  # vectorised
        m = (fr[q] != 0.0) & ((lx[q] != px[q]) | (ly[q] != py[q]) | (lz[q] != pz[q]))
        moving[q] = np.uint8(m)
        count += np.int64(m)
    for q in range(n, moving.shape[0]):
        moving[q] = 0
    return count


@njit(**EXACT_OPTIONS)
def look_settle(P, L, free, lo, frames, G, limits, items, marks, known):
    """:func:`look` where ``moved`` (the settle pass: ``L`` the positions before a later
    pass, which most points left where they were): where at most one point in
    FEW_MOVED moved, :func:`_look_moved` flags those alone, with the same
    outcome, and lists at once those that ``known`` gives a hint. ``marks``: (need,
    listed) as :func:`look` takes them. ``known``: (hints
    (K, M) int32, the mesh's row k in it, the first and end rows of its triangles,
    the points below which keep hints); the hints of :func:`.meshhint.hint_pass`."""
    before, now = frames
    reach, short, closed, moved = limits
    need, listed = marks
    ox, oy, oz, hx, hy, hz, _, inv, nx, ny, nz, _, s0f, _ = G
    n = need.shape[0]
    lx, ly, lz = L[0, lo:lo + n], L[1, lo:lo + n], L[2, lo:lo + n]
    px, py, pz = P[0, lo:lo + n], P[1, lo:lo + n], P[2, lo:lo + n]
    here = (lx, ly, lz, px, py, pz, free[lo:lo + n])
    moving = np.empty(((n + 7) // 8) * 8, dtype=np.uint8)
    if not moved or _moved(here, moving) * FEW_MOVED > n:
        return look(P, L, free, lo, frames, G, limits, items, need, listed)
    plain = is_rest(before) and is_rest(now)
    bounds = (reach, short, moved, ox, oy, oz, hx, hy, hz, inv, nx, ny, nz, np.int32(nx), np.int32(ny))
    hints, k, first, last, hinted = known
    kept = min(max(hinted - lo, 0), n, hints.shape[1] - lo) if 0 <= k < hints.shape[0] else 0
    cell = np.empty(n, dtype=np.int32)
    return _look_moved(frames, plain, here, bounds, (items, int(s0f), closed), moving, need, cell, listed,
                       (hints, k, lo, first, last, kept))


@njit(**EXACT_OPTIONS)
def _look_moved(frames, plain, here, bounds, status, moving, need, cell, listed, known):
    """:func:`look` for the points that ``moving`` marks, the only ones whose ``need``
    can be set where ``moved``: each flagged alone, eight marks read at once, so that
    a settle pass after which few points moved reads the rest once (a vector loop
    over every point's tests took four times as long). The same flags, list and
    count as :func:`look`'s loops, but for the points with a hint in ``known``
    ((hints, k, lo, first, end, the points from lo that keep them)), listed as they
    are: the hint pass decides most of them, with the search's answer (a point
    this pass would not list meets no triangle, and its segment is not the search's
    to move), and the search's own first tests, made again for the rest, are
    these."""
    before, now = frames
    lx, ly, lz, px, py, pz, _ = here
    items, s0, closed = status
    hints, k, lo, first, last, kept = known
    need[:] = False
    words = moving.view(np.uint64)
    count = 0
    for w in range(words.shape[0]):
        bits = words[w]
        while bits:
            b, bits = pop_lowest(bits)
            q = w * 8 + b // 8  # each mark is one byte, 0 or 1
            listed[count] = q
            if q < kept and first <= hints[k, lo + q] < last:
                need[q] = True
                count += 1
                continue
            if plain:
                segment = (lx[q], ly[q], lz[q], px[q], py[q], pz[q])
            else:
                x0, y0, z0 = _to_rest(before, lx[q], ly[q], lz[q])
                x1, y1, z1 = _to_rest(now, px[q], py[q], pz[q])
                segment = (x0, y0, z0, x1, y1, z1)
            _flag(q, segment, here, bounds, need, cell)
            need[q] = _busy(q, items, s0, closed, need, cell)
            count += np.int64(need[q])
    return count


@njit(**EXACT_OPTIONS, inline="always")
def _larger(a, b):
    """a or b, the larger (b for NaN): a select, where the builtin max keeps Python's
    rule for NaN and vectorises worse"""
    return a if a > b else b


@njit(**EXACT_OPTIONS, inline="always")
def _smaller(a, b):
    """a or b, the smaller (b for NaN)"""
    return a if a < b else b
