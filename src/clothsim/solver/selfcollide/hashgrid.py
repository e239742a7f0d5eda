"""The spatial hash: a dense grid of cells over the cloth's box, filled by a counting sort.

The timings behind its choices are in docs/performance.md ('Cell sort').
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..shared import EXACT_OPTIONS
from .buffers import COLS

CELL_FACTOR = 2.0
"""cell size over the search radius: each point then looks in 2x2 rows of cells
(at least 2: the ``search`` bits of :func:`sort_into_cells` take a sphere to
reach at most one cell past its own along y and z)"""

X_SPLIT = 4
"""cells are this many times narrower along x: a row of cells is one range of
memory, so narrow cells only trim the range to the search sphere's width,
which made the list build markedly faster than cubic cells on piled-up and
flat cloths; 6 and 8 gained no more (docs/performance.md, 'Cell sort')"""

SEARCH_ROWS = 5
"""the rows of ``search``: a point's cell, the first cell of its row of cells,
the first and one past the last column of cells its search sphere overlaps,
and a bit per row of cells :func:`query_points` may search (its ``rows``):
the point's own (always), the next along y, and those of the next layer
along z below, at and above the point's row. The query walks the set bits:
tested one by one, the rows' conditions cost a mispredicted branch or two
per point"""

CELLS_PER_POINT = 8
"""most grid cells per point; a cloth spread wider gets coarser cells"""


@njit(**EXACT_OPTIONS, inline="always")
def _cell(v):
    """the whole part of ``v`` (>= 0 and below a grid's count of cells along an axis,
    far under 2**31): converted through int32, which AVX2 does four at a time (it
    has no packed conversion to int64, so the loop would convert one by one)"""
    return np.int64(np.int32(v))


@njit(**EXACT_OPTIONS)
def sort_into_cells(P, radius, span, lists, copy):
    """Counting-sort the points into a dense grid of cells over their bounding box.

    Cells are ``CELL_FACTOR * radius`` wide where the buffer allows, coarser where the
    cloth is spread wider, and X_SPLIT times narrower along x. Cell (ix, iy, iz) is
    number ``(iz*ny + iy)*nx + ix``, so cells next to each other along x are next
    to each other in the sorted order and a query reads a row of them as one
    range. Afterwards cell c holds slots ``cell_start[c] : cell_start[c+1]``,
    ``order[k]`` is the point in slot k, ``slot`` the inverse, and the point's
    position from the grid's corner and its row and column on a grid of
    ``cols`` columns are copied to column k of ``sorted_pos`` (5, N + PAD),
    in single precision (a mesh's two coordinates of ``layout`` in place of the
    row and column, see :mod:`.nearlist`): the query's first test reads them, and in single
    precision it does twice as many at once (see :func:`query_points`).

    ``search`` (SEARCH_ROWS, N) gets each point's cell and the rows and columns
    of cells its search sphere overlaps (see :func:`query_points`), worked
    out here in a loop that vectorises rather than per point in the query,
    with a loop over the rows.

    The arrays are copy ``copy`` of the :class:`~.buffers.NeighbourList`'s
    (see :data:`~.buffers.GRID_COPIES`). Returns the grid (x0, y0, z0, cell
    size, nx, ny, nz, copy), or cell size 0 when the points are not finite or
    spread wider than ``span``: no list then.
    """
    cell_start, search, order, slot = lists.cell_start[copy], lists.search[copy], lists.order[copy], lists.slot[copy]
    sorted_pos, cols = lists.sorted_pos[copy], lists.meta[COLS]
    n = P.shape[1]
    lo = np.empty(3)
    hi = np.empty(3)
    grid = np.zeros(8)
    grid[7] = copy
    if not bounds(P, lo, hi):
        return grid
    ext = max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2])
    if not ext <= span:
        return grid
    size = CELL_FACTOR * radius
    if not size > 0.0:
        return grid  # no radius to search (and no cell size that could grow)
    budget = cell_start.shape[0] - 1
    while True:
        # the counts are floats until they fit: for a tiny radius they would
        # overflow an int64, and a wrapped count would pass the budget test
        fx = np.floor((hi[0] - lo[0]) * X_SPLIT / size) + 1.0
        fy = np.floor((hi[1] - lo[1]) / size) + 1.0
        fz = np.floor((hi[2] - lo[2]) / size) + 1.0
        if fx * fy * fz <= budget:
            break
        size *= 1.25
    nx, ny, nz = np.int64(fx), np.int64(fy), np.int64(fz)
    cells = nx * ny * nz
    inv = 1.0 / size
    inv_x = X_SPLIT / size
    cell_start[:cells + 1] = 0
    x, y, z = P[0], P[1], P[2]
    x0, y0, z0 = lo[0], lo[1], lo[2]
    cell_of, row_of, first_x, past_x, rows = search[0], search[1], search[2], search[3], search[4]
    for p in range(n):  # apart from the counting below, which does not vectorise
        ix = max(min(_cell((x[p] - x0) * inv_x), nx - 1), 0)
        iy = max(min(_cell((y[p] - y0) * inv), ny - 1), 0)
        iz = max(min(_cell((z[p] - z0) * inv), nz - 1), 0)
        row_of[p] = (iz * ny + iy) * nx
        cell_of[p] = row_of[p] + ix
        # the search sphere's cells: a cell is at least 2 radii wide, so at most
        # one more along y (or, where a coordinate rounds onto a border, one on
        # each side) and the next one along z; the cells below along z hold
        # only slots before the point's own (see query_points). Clamping at 0
        # before the truncation floors the negative values
        first_x[p] = _cell(max((x[p] - radius - x0) * inv_x, 0.0))
        past_x[p] = min(_cell((x[p] + radius - x0) * inv_x), nx - 1) + 1
        up = min(_cell((y[p] + radius - y0) * inv), ny - 1) > iy
        down = _cell(max((y[p] - radius - y0) * inv, 0.0)) < iy
        far = min(_cell((z[p] + radius - z0) * inv), nz - 1) > iz
        rows[p] = (1 | (2 if up else 0) | (4 if far and down else 0) | (8 if far else 0)
                   | (16 if far and up else 0))
    # unsigned indices here and below: a signed one costs a negative-index check
    # per access (docs/performance.md, 'Cell sort')
    for p in range(n):
        cell_start[np.uint64(cell_of[p] + 1)] += 1
    for c in range(1, cells + 1):
        cell_start[c] += cell_start[c - 1]
    # place each point at the end of its cell's remaining room, from the last
    # point down, so slots keep point order; then shift the starts back
    for p in range(n - 1, -1, -1):
        c = np.uint64(cell_of[p] + 1)
        cell_start[c] -= 1
        slot[p] = cell_start[c]
    for c in range(cells):
        cell_start[c] = cell_start[c + 1]
    cell_start[cells] = n
    # walked row by row of the cloth, so each point's row and column come from the
    # loops: dividing them out cost two divisions per candidate pair, and
    # counting them along in one loop chained every point to the last
    sx, sy, sz, grid_row, grid_col = sorted_pos[0], sorted_pos[1], sorted_pos[2], sorted_pos[3], sorted_pos[4]
    layout = lists.layout
    if layout.shape[1] == n:  # a mesh: its rest layout stands for the rows and columns
        lu, lv = layout[0], layout[1]
        for q in range(n):
            p = np.uint64(q)
            k = np.uint64(slot[p])
            order[k] = p
            sx[k] = np.float32(x[p] - x0)
            sy[k] = np.float32(y[p] - y0)
            sz[k] = np.float32(z[p] - z0)
            grid_row[k] = lu[p]
            grid_col[k] = lv[p]
    else:
        for first in range(0, n, cols):
            row = np.float32(first // cols)
            for i in range(min(cols, n - first)):
                p = np.uint64(first + i)
                k = np.uint64(slot[p])
                order[k] = p
                sx[k] = np.float32(x[p] - x0)
                sy[k] = np.float32(y[p] - y0)
                sz[k] = np.float32(z[p] - z0)
                grid_row[k] = row
                grid_col[k] = np.float32(i)
    grid[0], grid[1], grid[2], grid[3] = lo[0], lo[1], lo[2], size
    grid[4], grid[5], grid[6] = nx, ny, nz
    return grid


MAGNITUDE = np.int64(0x7FFFFFFFFFFFFFFF)

EXPONENT = np.int64(0x7FF0000000000000)


@njit(cache=True, boundscheck=False, error_model="numpy")
def bounds(P, lo, hi):
    """The box of the (3, N) points into ``lo`` and ``hi``; False if any coordinate is
    not finite. Works on the bits: flipping the magnitude bits of negative
    numbers orders doubles as integers, and a min or max of integers
    vectorises where one of doubles does not."""
    bad = np.int64(0)
    lo_bits, hi_bits = lo.view(np.int64), hi.view(np.int64)
    for c in range(3):
        bits = P[c].view(np.int64)
        a, b = MAGNITUDE, -MAGNITUDE - 1
        for p in range(bits.shape[0]):
            v = bits[p]
            key = v ^ ((v >> 63) & MAGNITUDE)
            a = min(a, key)
            b = max(b, key)
            bad += 1 if (v & EXPONENT) == EXPONENT else 0  # inf or NaN
        lo_bits[c] = a ^ ((a >> 63) & MAGNITUDE)
        hi_bits[c] = b ^ ((b >> 63) & MAGNITUDE)
    return bad == 0
