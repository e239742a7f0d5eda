"""The list build: every pair within the list radius, found from the sorted cells.

The timings behind its choices are in docs/performance.md ('List build').
"""

from __future__ import annotations

import numpy as np
from numba import njit

from numba.cpython.unsafe.numbers import trailing_zeros

from ..shared import EXACT_OPTIONS, pop_lowest
from ..simd import LANES, compress_store, has_compress, inside
from .buffers import NEAR, WIDE
from .drift import widened2
from .hashgrid import X_SPLIT, sort_into_cells

NARROW = 16
"""candidates tested together in a range of at most LONG_RANGE slots"""

LONG_RANGE = 48
"""candidate ranges longer than this are tested WIDE slots at a time: that is
faster than NARROW on a piled-up 100x100 cloth, where ranges hold about a
hundred slots; on the ranges of a 50x50 cloth (under 16 slots) and of a
hanging 100x100 one (about 30) NARROW is faster (figures:
docs/performance.md, 'List build')"""

COMPRESS = has_compress()
"""whether the list build appends a chunk's pairs with AVX-512's compress
(:func:`_put_compressed`) or bit by bit (:func:`_put`); fixed when this module
is imported"""

PUT_ROOM = LANES if COMPRESS else 2
"""pairs past its count a direct append may write: see :func:`query_points`"""


@njit(**EXACT_OPTIONS)
def build_list(P, rest, reach, radius, span, lists, pairs):
    """Every pair of points closer than ``radius`` and not closer than ``reach`` at
    rest, each pair once, into ``pairs`` (2, capacity); returns how many there
    are, which may exceed the capacity: then only the first ones were stored.
    Pairs ``(dr, di)`` apart on the grid of ``lists.meta[COLS]`` columns are
    left out where ``lists.near_table[dr, di + NEAR]`` is set: the near stencil
    checks them. ``lists`` is the :class:`~.buffers.NeighbourList` whose cell
    grid is filled.
    Returns -1 when the points are not finite or spread wider than ``span``.
    """
    grid = sort_into_cells(P, radius, span, lists, 0)
    if grid[3] == 0.0:
        return -1
    # the same argument types as the substep's call (no constants): one compile serves both
    zero = np.int64(0)
    return query_points(grid, reach, radius, rest, lists, zero, np.int64(P.shape[1]), pairs, zero,
                        np.int64(pairs.shape[1]))


@njit(**EXACT_OPTIONS)
def query_points(grid, reach, radius, rest, lists, first, stop, pairs, base, capacity):
    """The list pairs (pk, q) of points ``first <= pk < stop`` from the sorted
    cells of :func:`sort_into_cells` into ``pairs[:, base:base + capacity]``;
    returns how many there are, which may exceed the capacity. ``rest`` (N, 3)
    is the rest layout.

    The rows and columns of cells each point searches come from ``search``,
    filled by the cell sort; each pair is found once, from the point whose
    slot comes first, so a point skips the rows of cells before its own.

    Each row of cells a point searches is tested NARROW or WIDE slots at a
    time, in vector code (:func:`_inside`) that only sets a bit per
    candidate inside the radius and not one of the grid neighbours that
    ``near_metric`` (:func:`grid_metric`) marks as never listed. A range of a
    50x50 cloth holds a few slots, and a loop over exactly those ended in a
    mispredicted branch per range, which the fixed width has not. Slots past
    the range are read (``sorted_pos`` is padded) and masked out. The test
    runs in single precision, on positions from the grid's corner, with the
    radius widened by more than the rounding of either end can move them: no
    pair inside the radius is missed, and a pair a hair outside may be
    listed, which only costs its check.

    A chunk with no bit is skipped. Where the rest layout lets no further
    test reject a pair (``near_metric`` exact) and the pairs array has room,
    the bits of the others go straight into it (:func:`_put_compressed` or
    :func:`_put`), without a branch per bit; otherwise each goes through the
    exact tests and the capacity check (:func:`_put_checked`). Most chunks
    hold no pair even on a piled-up cloth, and the skip made every build
    timed shorter, hanging, falling or piled, with either append
    (docs/performance.md, 'List build'). The ranges are walked with unsigned
    indices: with signed ones numba adds a negative-index wraparound that
    turns the loads into gathers.
    """
    # the copy of the cell grid the sort filled (see GRID_COPIES)
    g = np.int64(grid[7])
    cell_start, search, slot, order = lists.cell_start[g], lists.search[g], lists.slot[g], lists.order[g]
    sorted_pos, near_table, near_metric = lists.sorted_pos[g], lists.near_table, lists.near_metric
    size = grid[3]
    nx, ny, nz = np.int64(grid[4]), np.int64(grid[5]), np.int64(grid[6])
    # each coordinate from the corner is rounded by at most extent * 2**-24
    extent = max(nx * size / X_SPLIT, ny * size, nz * size)
    f32 = np.float32
    metric = (widened2(radius, extent), f32(near_metric[0]), f32(near_metric[1]), f32(near_metric[2]))
    sx, sy, sz, grid_row, grid_col = sorted_pos[0], sorted_pos[1], sorted_pos[2], sorted_pos[3], sorted_pos[4]
    columns = (sx, sy, sz, grid_row, grid_col)
    reach2 = reach * reach
    exact = near_metric[3] != 0.0
    found = 0
    # rows of cells after the point's own, as offsets from it: the next one
    # along y, and the next layer along z below, at and above the point's row
    layer = ny * nx
    rows = (np.int64(0), nx, layer - nx, layer, layer + nx)
    # points in index order, so the list is sorted by its first point and the
    # substep's pass over it walks the cloth in memory order
    for pk in range(first, stop):
        p = np.uint64(pk)
        k = slot[p]
        own = (sx[k], sy[k], sz[k], grid_row[k], grid_col[k])
        row_of, ix0, ix1, bits = search[1, p], search[2, p], search[3, p], np.uint64(search[4, p])
        while bits != 0:
            r, bits = pop_lowest(bits)
            row = np.uint64(row_of + rows[r])
            # each pair once: in the point's own row only the slots after its own
            lo = cell_start[row + np.uint64(ix0)]
            lo = max(lo, k + 1) if r == 0 else lo
            hi = cell_start[row + np.uint64(ix1)]
            direct = exact and found + (hi - lo) + PUT_ROOM <= capacity
            if hi - lo <= LONG_RANGE:
                found = _scan(own, columns, k, lo, hi, NARROW, metric, direct, order, pairs,
                              pk, base, found, capacity, exact, rest, reach2, near_table)
            else:
                found = _scan(own, columns, k, lo, hi, WIDE, metric, direct, order, pairs,
                              pk, base, found, capacity, exact, rest, reach2, near_table)
    return found


@njit(**EXACT_OPTIONS, inline="always")
def _scan(own, columns, k, lo, hi, width, metric, direct, order, pairs, pk, base, found, capacity,
          exact, rest, reach2, near_table):
    """The pairs of the point in slot k (point pk) with slots ``lo:hi``, ``width`` at
    a time, appended after the ``found`` ones; returns the new count. See
    :func:`query_points`: ``own`` is the point's column of ``sorted_pos``,
    ``columns`` its rows, ``metric`` (radius², the :func:`grid_metric`), all
    in single precision."""
    x, y, z, gr, gc = own
    sx, sy, sz, grid_row, grid_col = columns
    radius2, wr2, wc2, rho2 = metric
    for at in range(lo, hi, width):
        mask = _inside(x, y, z, gr, gc, sx, sy, sz, grid_row, grid_col, at, hi, width, radius2, wr2,
                       wc2, rho2)
        if mask == 0:
            continue
        if direct:
            found = _put_direct(mask, at, order, pairs, pk, base + found, width) - base
        else:
            found = _put_checked(mask, at, order, pairs, pk, base, found, capacity, exact, rest,
                                 grid_row, grid_col, k, reach2, near_table)
    return found


@njit(**EXACT_OPTIONS, inline="always")
def _inside(x, y, z, gr, gc, sx, sy, sz, grid_row, grid_col, at, hi, width, radius2, wr2, wc2, rho2):
    """A bit per slot ``at <= q < min(at + width, hi)`` that lies inside the radius of
    the point at (x, y, z), grid row gr and column gc, and is not a grid
    neighbour inside the ellipse of :func:`grid_metric`. ``width`` (a multiple
    of LANES, at most 64) slots are read, whatever ``hi``. All in single
    precision, LANES slots at a time (:func:`clothsim.solver.simd.inside`),
    whose comparison becomes the mask directly: a loop that ored a shifted
    bit per slot made LLVM fold the lanes in a chain of shuffles."""
    mask = np.uint64(0)
    for c in range(0, width, LANES):
        bits = inside(sx, sy, sz, grid_row, grid_col, np.uint64(at + c), x, y, z, gr, gc, radius2, wr2, wc2,
                      rho2)
        mask |= bits << np.uint64(c)
    # the slots before hi, masked after the loop: a 64-bit comparison in it
    # would halve the single-precision lanes
    valid = np.uint64(min(hi - at, width))
    return mask & ((np.uint64(2) << (valid - np.uint64(1))) - np.uint64(1))


@njit(**EXACT_OPTIONS, inline="always")
def _put(mask, at, order, pairs, pk, end, width):
    """Append the pairs (pk, point in slot ``at + j``) of the bits j of ``mask`` at
    ``pairs[:, end:]``; returns the new end. The first two are written
    whether their bit is there or not, and counted only if it is: most masks
    that are not skipped hold one or two bits, and a loop over them ended in
    a mispredicted branch. The caller leaves room for two pairs more than the
    bits (PUT_ROOM), and ``order`` a slot past the points (a mask with one
    bit reads slot ``at`` for its second). ``width``: the bits the mask may
    hold (unused here)."""
    j = np.int64(trailing_zeros(mask)) & 63
    pairs[0, end] = pk
    pairs[1, end] = order[np.uint64(at + j)]
    end += 1 if mask != 0 else 0
    mask &= mask - np.uint64(1)
    j = np.int64(trailing_zeros(mask)) & 63
    pairs[0, end] = pk
    pairs[1, end] = order[np.uint64(at + j)]
    end += 1 if mask != 0 else 0
    mask &= mask - np.uint64(1)
    while mask != 0:
        j, mask = pop_lowest(mask)
        pairs[0, end] = pk
        pairs[1, end] = order[np.uint64(at + j)]
        end += 1
    return end


@njit(**EXACT_OPTIONS, inline="always")
def _put_compressed(mask, at, order, pairs, pk, end, width):
    """:func:`_put` with AVX-512's compress, LANES bits of the ``width`` at a time: all
    LANES points of the slots are loaded, the chosen ones packed to the front
    and stored with pk beside each, and the end moves on by their number. No
    branch depends on the bits, so none is mispredicted however many are
    set. Up to LANES pairs past the new end are overwritten (PUT_ROOM), and
    ``order`` is read up to ``width`` slots past ``at`` (PAD)."""
    e = np.uint64(end)
    for c in range(0, width, LANES):
        for j in range(LANES):
            pairs[0, e + np.uint64(j)] = pk
        bits = (mask >> np.uint64(c)) & np.uint64((1 << LANES) - 1)
        compress_store(order, np.uint64(at + c), pairs, np.uint64(1), e, bits)
        e += np.uint64(_count_bits(bits))
    return np.int64(e)


@njit(cache=True, inline="always")
def _count_bits(mask):
    """The set bits of ``mask``: LLVM turns this loop into one popcount."""
    c = 0
    while mask != 0:
        mask &= mask - np.uint64(1)
        c += 1
    return c


_put_direct = _put_compressed if COMPRESS else _put


@njit(**EXACT_OPTIONS, inline="always")
def _put_checked(mask, at, order, pairs, pk, base, found, capacity, exact, rest, grid_row, grid_col, k,
                 reach2, near_table):
    """:func:`_put` one bit at a time, each pair stored while there is room and,
    unless ``exact``, only if it was not closer than the reach at rest and
    is not in the near stencil; returns the new count."""
    while mask != 0:
        j, mask = pop_lowest(mask)
        q = np.uint64(at + j)
        pq = order[q]
        if not exact:
            ex = rest[pk, 0] - rest[pq, 0]
            ey = rest[pk, 1] - rest[pq, 1]
            ez = rest[pk, 2] - rest[pq, 2]
            if ex * ex + ey * ey + ez * ez < reach2:
                continue
            dr = np.int64(grid_row[q] - grid_row[k])
            di = np.int64(grid_col[q] - grid_col[k])
            if dr < 0 or (dr == 0 and di < 0):
                dr, di = -dr, -di
            if dr <= NEAR and abs(di) <= NEAR and near_table[dr, di + NEAR] != 0:
                continue
        if found < capacity:
            pairs[0, base + found] = pk
            pairs[1, base + found] = pq
        found += 1
    return found
