"""Self-collision: a spatial hash feeding a neighbour list with a skin.

Every pair closer than ``reach = 2*thickness`` is pushed apart. Finding those
pairs with a spatial hash costs far more than pushing them, and between two
substeps the points barely move relative to each other. So the hash is asked
for every pair within ``reach + skin`` (a neighbour list, as in molecular
dynamics), and each substep only tests the listed pairs. The list is rebuilt
as soon as any point may have come within ``reach`` of a point not listed:
when the displacements since the build may differ by ``skin`` between two
points (not while every displacement lies within ``skin/2`` of one centre,
see :func:`_drift_bound`). Two unlisted points started at least
``reach + skin`` apart and their displacements differ by less than
``skin``, so they are still farther apart than ``reach``; the pairs found
are exactly those a hash rebuilt every substep would find. The same bound,
taken below ``skin``, spares most listed pairs their test: one that started
farther past the reach than the displacements can differ by cannot touch
yet, and the list is kept sorted by that slack (:func:`_sort_by_slack`).

The spatial hash is a dense grid of cells over the cloth's bounding box (a
perfect hash: no two cells share a bucket, so no key is checked), filled
by a counting sort, so a rebuild is a few linear passes. A point looks in
every cell that its search sphere overlaps, its own and the adjacent ones,
so no pair is missed at a cell border; cells adjacent along x are adjacent
in memory, so each row of them is one range of candidates.
Pairs already closer than ``reach`` at rest (neighbours on a fine grid) never
enter the list: the C++ course code pushes them apart, and its fine cloths
then fight their own springs and boil.

Positions are (3, N) coordinate planes; ``rest`` is the (N, 3) start layout.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from numba.cpython.unsafe.numbers import trailing_zeros

from .grid import BLOCK, KERNEL_OPTIONS, gap2, pop_lowest
from .simd import LANES, close_lanes, compress_store, has_compress, inside

EXACT_OPTIONS = dict(cache=True, boundscheck=False, error_model="numpy")
"""for the kernels that test for NaN before turning coordinates into cell
indices: fastmath would let LLVM drop the test, also where one of them is
inlined into another, and a NaN index could then reach memory"""

SKIN_FACTOR = 0.5
"""skin of the neighbour list as a fraction of the reach: larger lists, rarer rebuilds"""

COARSE_SKIN = 0.75
"""the skin of a coarse cloth: see :func:`skin_factor`"""

COARSE_OFFSETS = 4
"""grid offsets (each pair once) a cloth's stencil may take in at COARSE_SKIN
for the cloth to count as coarse"""

CELL_FACTOR = 2.0
"""cell size over the search radius: each point then looks in 2x2 rows of cells
(at least 2: the ``search`` bits of :func:`_sort_into_cells` take a sphere to
reach at most one cell past its own along y and z)"""

X_SPLIT = 4
"""cells are this many times narrower along x: a row of cells is one range of
memory, so narrow cells only trim the range to the search sphere's width
(the list build took 16% less time on a piled-up 100x100 cloth, 32% on a flat
200x200 one, than with cubic cells; 6 and 8 gained no more)"""

SEARCH_ROWS = 5
"""the rows of ``search``: a point's cell, the first cell of its row of cells,
the first and one past the last column of cells its search sphere overlaps,
and a bit per row of cells :func:`query_points` may search (its ``rows``):
the point's own (always), the next along y, and those of the next layer
along z below, at and above the point's row. The query walks the set bits:
tested one by one, the rows' conditions cost a mispredicted branch or two
per point, and the build took 5% longer"""

CELLS_PER_POINT = 8
"""most grid cells per point; a cloth spread wider gets coarser cells"""

NEAR = 5
"""grid offsets up to this many rows and columns may be checked as a stencil"""

SPARSE_PAIRS = 64
"""when no part pushed more pairs than this, only their ends are moved, not
every point: see :func:`apply_sparse`"""

METRIC_GAP = 1e-4
"""least relative gap between the grid offsets inside and outside the ellipse of
:func:`grid_metric`: single precision tells them apart to about 1e-7"""

DENSE_LIST = 0.4
"""pairs per point of the last list above which the list build, where it has no
compress (see COMPRESS), no longer tests a chunk's bits for none before
writing them: see :func:`query_points`"""

DENSE_COMPRESSED = 1.0
"""DENSE_LIST where the build appends with the compress: a piled-up 50x50 cloth
(1.4 pairs a point) built its list 13% faster without the test, a hanging
100x100 one (0.26) a fifth slower"""

QUERY_SHARES = 4
"""shares of the list build per thread, where there is more than one"""

NARROW = 16
"""candidates tested together in a range of at most LONG_RANGE slots"""

WIDE = 64
"""candidates tested together in a longer range: one bit each in a 64-bit word"""

LONG_RANGE = 48
"""candidate ranges longer than this are tested WIDE slots at a time: on a
piled-up 100x100 cloth, where ranges hold about a hundred slots, that took
a fifth less time than NARROW; on the ranges of a 50x50 cloth (under 16
slots) and of a hanging 100x100 one (about 30) NARROW is faster"""

PAD = WIDE
"""columns past the last slot of ``sorted_pos`` and ``order``: a chunk of
candidates may read that far beyond its range, and masks those slots out"""

COMPRESS = has_compress()
"""whether the list build appends a chunk's pairs with AVX-512's compress
(:func:`_put_compressed`) or bit by bit (:func:`_put`); fixed when this module
is imported"""

PUT_ROOM = LANES if COMPRESS else 2
"""pairs past its count a direct append may write: see :func:`query_points`"""

# fields of the ``meta`` int64 array that carries the list's state between calls
# (SKIN: the skin in thousandths of the reach)
PAIRS, VALID, REBUILDS, COLS, SKIN, BUCKET = 0, 1, 2, 3, 4, 5
SLACK_BUCKETS = 16
"""buckets of the list by how far past the reach a pair was at the build: see
:func:`_sort_by_slack`. A substep checks its last reachable bucket whole: on
the piling 50x50 cloth it checked 6% fewer pairs than with 8 buckets, and the
sort costs the same"""
META_SIZE = BUCKET + SLACK_BUCKETS  # BUCKET + j: where slack bucket j ends in the list


def grid_spacing(rest: np.ndarray, rows: int, cols: int) -> tuple[float, float]:
    """The median distances at rest between neighbours along a column (row
    spacing) and along a row (column spacing); at least 2 rows and columns."""
    r, i = np.divmod(np.arange(rows * cols), cols)
    right, down = np.flatnonzero(i + 1 < cols), np.flatnonzero(r + 1 < rows)
    wc = np.median(np.linalg.norm(rest[right + 1] - rest[right], axis=1))
    wr = np.median(np.linalg.norm(rest[down + cols] - rest[down], axis=1))
    return float(wr), float(wc)


def skin_factor(rest: np.ndarray, rows: int, cols: int, thickness: float) -> float:
    """The list's skin for this cloth, as a fraction of the reach.

    A wider skin means rarer rebuilds but a wider list radius, and every grid
    offset inside that radius at rest joins the near stencil, a pass over the
    cloth per offset and substep. A coarse cloth (at most COARSE_OFFSETS
    offsets inside even COARSE_SKIN: its rows, columns and diagonals, as in
    every standard scene) takes COARSE_SKIN: at 50x50 the cloth on the
    sphere rebuilt its list 5.0 times per 100 substeps instead of 7.4 and
    self-collision cost 10.7 us a substep instead of 13.4. A finer one keeps
    SKIN_FACTOR: at 100x100 the wider skin took rings of grid neighbours
    into the stencil and cost 2-5%, at 200x200 half again, as offsets past
    NEAR went into the list for good.
    """
    if rows < 2 or cols < 2:
        return SKIN_FACTOR
    wr, wc = grid_spacing(rest, rows, cols)
    radius = 2.0 * thickness * (1.0 + COARSE_SKIN)
    dr, di = np.meshgrid(np.arange(NEAR + 2), np.arange(-NEAR - 1, NEAR + 2), indexing="ij")
    inside = (np.hypot(dr * wr, di * wc) < radius) & ((dr > 0) | (di > 0))
    return COARSE_SKIN if inside.sum() <= COARSE_OFFSETS else SKIN_FACTOR


def near_stencil(rest: np.ndarray, rows: int, cols: int, thickness: float,
                 skin: float = SKIN_FACTOR) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The grid offsets whose pairs sit inside the list radius at rest, the reach
    plus ``skin`` times the reach.

    Such pairs (grid neighbours on a fine cloth) fill most of the list and
    would stay in it for good, so they are checked every substep as a
    stencil, a vectorised loop over contiguous memory, instead; the list
    leaves them out. Returns the flat offsets (S,), a uint8 mask (S, N) that
    is 1 where the pair exists and is not closer than the reach at rest
    (those are never pushed), a (NEAR+1, 2*NEAR+1) table of the (dr, di)
    taken, and the :func:`grid_metric` of the offsets the list never holds.
    One byte per pair: a 200x200 cloth has 28 offsets, and as float64 the
    mask (9 MB) outgrew the cache; the stencil took 2.9 times as long.
    """
    n = rows * cols
    reach = 2.0 * thickness
    radius = reach * (1.0 + skin)
    r, i = np.divmod(np.arange(n), cols)
    offsets, weights = [], []
    table = np.zeros((NEAR + 1, 2 * NEAR + 1), dtype=np.int64)
    never = np.zeros_like(table, dtype=bool)  # offsets whose pairs never enter the list
    for dr in range(NEAR + 1):
        for di in range(-NEAR, NEAR + 1):
            if dr == 0 and di <= 0:
                continue  # each pair once
            p = np.flatnonzero((r + dr < rows) & (i + di >= 0) & (i + di < cols))
            if len(p) == 0:
                continue
            d = np.linalg.norm(rest[p + dr * cols + di] - rest[p], axis=1)
            if np.median(d) >= radius:
                continue  # apart at rest: the list finds them when they come close
            w = np.zeros(n, dtype=np.uint8)
            w[p] = d >= reach
            never[dr, di + NEAR] = True
            if not w.any():
                continue  # all closer than the reach at rest: never pushed
            offsets.append(dr * cols + di)
            weights.append(w)
            table[dr, di + NEAR] = 1
    return (np.array(offsets, dtype=np.int64),
            np.array(weights, dtype=np.uint8).reshape(len(offsets), n), table,
            grid_metric(rest, rows, cols, never, reach))


def grid_metric(rest: np.ndarray, rows: int, cols: int, never: np.ndarray,
                reach: float) -> np.ndarray:
    """(row spacing², column spacing², rho², exact) such that every grid offset
    (dr, di) with ``(dr*row spacing)² + (di*column spacing)² < rho²`` is marked
    in ``never`` (NEAR+1, 2*NEAR+1): its pairs never enter the list.

    The list build then drops such candidates in its vectorised first test,
    from their grid rows and columns, instead of sending them through the
    exact tests, which reject them anyway: on a 100x100 cloth they were over
    half the candidates inside the radius and the build took 13% longer.
    rho² lies halfway between the nominal squared distances of the farthest
    marked offset inside it and the nearest offset not marked, so the ellipse
    holds only marked offsets, also when the build tests it in single
    precision; zeros drop nothing.

    ``exact`` is 1 when the ellipse holds every marked offset and every pair
    closer than ``reach`` at rest: the exact tests can then reject nothing
    the first test let through, and the build skips them (a quarter of its
    time on a piled-up 100x100 cloth). Both are properties of the rest
    layout, checked here once: a regular grid passes, a cloth whose rest
    layout is warped may not.
    """
    metric = np.zeros(4)
    if rows < 2 or cols < 2 or not never.any():
        return metric
    wr, wc = grid_spacing(rest, rows, cols)
    wr2, wc2 = wr * wr, wc * wc
    unmarked = np.inf
    for dr in range(NEAR + 2):  # one ring past the table: no offset there is marked
        for di in range(-NEAR - 1, NEAR + 2):
            if dr == 0 and di <= 0:
                continue
            if not (dr <= NEAR and abs(di) <= NEAR and never[dr, di + NEAR]):
                unmarked = min(unmarked, dr * dr * wr2 + di * di * wc2)
    dr, di = np.nonzero(never)
    marked = dr * dr * wr2 + (di - NEAR) ** 2 * wc2
    below = marked[marked < unmarked]
    marked_below = below.max() if len(below) else 0.0
    if unmarked - marked_below < METRIC_GAP * unmarked:
        return metric  # no room for single precision between them: drop nothing
    rho2 = 0.5 * (marked_below + unmarked)
    marked_inside = bool(np.all(marked < rho2))
    metric[:3] = wr2, wc2, rho2
    metric[3] = marked_inside and _close_at_rest_inside(rest, cols, reach, metric)
    return metric


def _close_at_rest_inside(rest: np.ndarray, cols: int, reach: float, metric: np.ndarray) -> bool:
    """Whether every pair closer than ``reach`` at rest lies inside the ellipse of
    ``metric``: a search of the rest layout itself, with the list's own build."""
    n = len(rest)
    x = NeighbourList(n, cols)
    P = np.ascontiguousarray(rest.T)
    while True:
        # radius reach and no rest test: every pair closer than reach, each once
        found = build_list(P, rest, 0.0, reach, np.inf, *x.buffers()[:5], x.pairs, cols, x.near_table,
                           x.near_metric)
        if found <= x.pairs.shape[1]:
            break
        x.pairs = np.zeros((2, 2 * found), dtype=np.int32)
    a, b = x.pairs[:, :found].astype(np.int64)
    dr, di = a // cols - b // cols, a % cols - b % cols
    return bool(np.all(dr * dr * metric[0] + di * di * metric[1] < metric[2]))


class NeighbourList:
    """The buffers of the cell grid and the neighbour list, allocated once per cloth."""

    def __init__(self, num_points: int, cols: int | None = None,
                 near: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None,
                 parts: int = 1, skin: float = SKIN_FACTOR) -> None:
        """``cols`` and ``near`` (from :func:`near_stencil`, with the same ``skin``)
        describe the cloth's grid; without them every pair goes through the
        list. ``parts``: how many threads may share the work; each has its own
        scratch and pushes. ``skin``: see :func:`skin_factor`."""
        n = num_points
        self.cell_start = np.zeros(max(CELLS_PER_POINT * n, 64) + 1, dtype=np.int64)
        self.search = np.zeros((SEARCH_ROWS, n), dtype=np.int64)  # see _sort_into_cells
        self.order = np.zeros(n + PAD, dtype=np.int32)  # past the points: see _put, _put_compressed
        self.slot = np.zeros(n, dtype=np.int64)
        # per slot: position from the grid's corner, grid row and column, in single precision
        self.sorted_pos = np.zeros((5, n + PAD), dtype=np.float32)
        # the positions at the build, in single precision from ``frame``'s origin
        self.reference = np.zeros((3, n), dtype=np.float32)
        # the build's origin (x, y, z) and the largest magnitude of a coordinate of reference
        self.frame = np.zeros(4)
        self.centres = np.zeros((2, 3))  # of the drift test: see _drift_bound
        self.pairs = np.zeros((2, 4 * n), dtype=np.int32)
        self.push = np.zeros((parts, 3, n))
        self.count = np.zeros((parts, n))
        self.meta = np.zeros(META_SIZE, dtype=np.int64)
        self.meta[COLS] = n if cols is None else cols
        self.meta[SKIN] = round(1000 * skin)
        if near is None:
            near = (np.zeros(0, np.int64), np.zeros((0, n), np.uint8),
                    np.zeros((NEAR + 1, 2 * NEAR + 1), np.int64), np.zeros(4))
        self.near_offset, weight, self.near_table, self.near_metric = near
        # padded: the single-precision stencil reads up to PAD pairs past the points
        self.near_weight = np.zeros((len(weight), n + PAD), dtype=np.uint8)
        self.near_weight[:, :n] = weight
        self.near_masks = np.zeros((parts, n // BLOCK + 2), dtype=np.uint64)
        # the positions in single precision from frame's origin (see self_collide), and
        # the bits (as of a float32) of each part's largest magnitude of a coordinate
        self.pos32 = np.zeros((3, n + PAD), dtype=np.float32)
        self.extent32 = np.zeros(parts, dtype=np.int32)
        # per offset and block of the stencil: slack level of its closest pair at the build
        self.near_level = np.zeros((len(self.near_offset), n // BLOCK + 1), dtype=np.int32)
        # ends of pushed pairs, and a spare pair that pair_pushes may overwrite
        self.touched = np.zeros((parts, 2 * SPARSE_PAIRS + 2), dtype=np.int64)
        # pairs found per share of the list build, pairs pushed per part
        self.tally = np.zeros((parts * (QUERY_SHARES if parts > 1 else 1), 2), dtype=np.int64)

    def buffers(self) -> tuple:
        """what :func:`self_collide` takes after ``thickness, simulation_steps, span``"""
        return (self.cell_start, self.search, self.order, self.slot, self.sorted_pos,
                self.reference, self.frame, self.centres, self.pairs, self.push, self.count, self.meta,
                self.near_offset, self.near_weight, self.near_table, self.near_metric,
                self.near_masks, self.near_level, self.pos32, self.extent32, self.touched,
                self.tally)

    @property
    def rebuilds(self) -> int:
        return int(self.meta[REBUILDS])


@njit(cache=True, inline="always")
def widened2(radius, extent):
    """The square of ``radius`` widened past the rounding of single-precision
    coordinates of magnitude up to ``extent`` (each rounded by at most
    extent * 2**-24, their differences by a hair more), as a float32 rounded
    up: a pair closer than ``radius`` always tests closer in single precision."""
    wide = radius * (1.0 + 2.0 ** -18) + 4.0 * extent * 2.0 ** -23
    return np.float32(wide * wide * (1.0 + 2.0 ** -18))


@njit(**EXACT_OPTIONS)
def _sort_into_cells(P, radius, span, cols, cell_start, search, order, slot, sorted_pos):
    """Counting-sort the points into a dense grid of cells over their bounding box.

    Cells are ``CELL_FACTOR * radius`` wide where the buffer allows, coarser where the
    cloth is spread wider, and X_SPLIT times narrower along x. Cell (ix, iy, iz) is
    number ``(iz*ny + iy)*nx + ix``, so cells next to each other along x are next
    to each other in the sorted order and a query reads a row of them as one
    range. Afterwards cell c holds slots ``cell_start[c] : cell_start[c+1]``,
    ``order[k]`` is the point in slot k, ``slot`` the inverse, and the point's
    position from the grid's corner and its row and column on a grid of
    ``cols`` columns are copied to column k of ``sorted_pos`` (5, N + PAD),
    in single precision: the query's first test reads them, and in single
    precision it does twice as many at once (see :func:`query_points`).

    ``search`` (SEARCH_ROWS, N) gets each point's cell and the rows and columns
    of cells its search sphere overlaps (see :func:`query_points`), worked
    out here in a loop that vectorises: worked out per point in the query,
    with a loop over the rows, they took a third of its time.

    Returns the grid (x0, y0, z0, cell size, nx, ny, nz), or cell size 0 when
    the points are not finite or spread wider than ``span``: no list then.
    """
    n = P.shape[1]
    lo = np.empty(3)
    hi = np.empty(3)
    grid = np.zeros(7)
    if not _bounds(P, lo, hi):
        return grid
    ext = max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2])
    if not ext <= span:
        return grid
    size = CELL_FACTOR * radius
    budget = cell_start.shape[0] - 1
    while True:
        nx = np.int64((hi[0] - lo[0]) * X_SPLIT / size) + 1
        ny = np.int64((hi[1] - lo[1]) / size) + 1
        nz = np.int64((hi[2] - lo[2]) / size) + 1
        if nx * ny * nz <= budget:
            break
        size *= 1.25
    cells = nx * ny * nz
    inv = 1.0 / size
    inv_x = X_SPLIT / size
    cell_start[:cells + 1] = 0
    x, y, z = P[0], P[1], P[2]
    x0, y0, z0 = lo[0], lo[1], lo[2]
    cell_of, row_of, first_x, past_x, rows = search[0], search[1], search[2], search[3], search[4]
    for p in range(n):  # apart from the counting below, which does not vectorise
        ix = max(min(np.int64((x[p] - x0) * inv_x), nx - 1), 0)
        iy = max(min(np.int64((y[p] - y0) * inv), ny - 1), 0)
        iz = max(min(np.int64((z[p] - z0) * inv), nz - 1), 0)
        row_of[p] = (iz * ny + iy) * nx
        cell_of[p] = row_of[p] + ix
        # the search sphere's cells: a cell is at least 2 radii wide, so at most
        # one more along y (or, where a coordinate rounds onto a border, one on
        # each side) and the next one along z; the cells below along z hold
        # only slots before the point's own (see query_points). Clamping at 0
        # before the truncation floors the negative values
        first_x[p] = np.int64(max((x[p] - radius - x0) * inv_x, 0.0))
        past_x[p] = min(np.int64((x[p] + radius - x0) * inv_x), nx - 1) + 1
        up = min(np.int64((y[p] + radius - y0) * inv), ny - 1) > iy
        down = np.int64(max((y[p] - radius - y0) * inv, 0.0)) < iy
        far = min(np.int64((z[p] + radius - z0) * inv), nz - 1) > iz
        rows[p] = (1 | (2 if up else 0) | (4 if far and down else 0) | (8 if far else 0)
                   | (16 if far and up else 0))
    for p in range(n):
        cell_start[cell_of[p] + 1] += 1
    for c in range(1, cells + 1):
        cell_start[c] += cell_start[c - 1]
    # place each point at the end of its cell's remaining room, from the last
    # point down, so slots keep point order; then shift the starts back
    for p in range(n - 1, -1, -1):
        c = cell_of[p] + 1
        cell_start[c] -= 1
        slot[p] = cell_start[c]
    for c in range(cells):
        cell_start[c] = cell_start[c + 1]
    cell_start[cells] = n
    # walked row by row of the cloth, so each point's row and column come from the
    # loops: dividing them out per candidate pair cost 5-10% of the build, and
    # counting them along in one loop chained every point to the last (13 us
    # instead of 4.6 at 50x50)
    sx, sy, sz, grid_row, grid_col = sorted_pos[0], sorted_pos[1], sorted_pos[2], sorted_pos[3], sorted_pos[4]
    for first in range(0, n, cols):
        row = np.float32(first // cols)
        for i in range(min(cols, n - first)):
            p = first + i
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
def _bounds(P, lo, hi):
    """The box of the (3, N) points into ``lo`` and ``hi``; False if any coordinate is
    not finite. Works on the bits: flipping the magnitude bits of negative
    numbers orders doubles as integers, and a min or max of integers
    vectorises where one of doubles does not (5x faster at 50x50)."""
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


@njit(**EXACT_OPTIONS)
def build_list(P, rest, reach, radius, span, cell_start, search, order, slot, sorted_pos, pairs,
               cols, near_table, near_metric, sparse=True):
    """Every pair of points closer than ``radius`` and not closer than ``reach`` at
    rest, each pair once, into ``pairs`` (2, capacity); returns how many there
    are, which may exceed the capacity: then only the first ones were stored.
    Pairs ``(dr, di)`` apart on a grid of ``cols`` columns are left out where
    ``near_table[dr, di + NEAR]`` is set: the near stencil checks them.
    Returns -1 when the points are not finite or spread wider than ``span``.
    ``near_metric`` is the :func:`grid_metric` of the offsets the list never
    holds.
    """
    grid = _sort_into_cells(P, radius, span, cols, cell_start, search, order, slot, sorted_pos)
    if grid[3] == 0.0:
        return -1
    return query_points(grid, reach, radius, rest, cell_start, search, slot, order, sorted_pos, near_table,
                        near_metric, 0, P.shape[1], pairs, 0, pairs.shape[1], sparse)


@njit(**EXACT_OPTIONS)
def query_points(grid, reach, radius, rest, cell_start, search, slot, order, sorted_pos, near_table,
                 near_metric, first, stop, pairs, base, capacity, sparse):
    """The list pairs (pk, q) of points ``first <= pk < stop`` from the sorted
    cells of :func:`_sort_into_cells` into ``pairs[:, base:base + capacity]``;
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
    mispredicted branch per range: the fixed width took a quarter to a third
    less time. Slots past the range are read (``sorted_pos`` is padded) and
    masked out. The test runs in single precision, on positions from the
    grid's corner, with the radius widened by more than the rounding of
    either end can move them: no pair inside the radius is missed, and a
    pair a hair outside may be listed, which only costs its check.

    Where the rest layout lets no further test reject a pair (``near_metric``
    exact) and the pairs array has room, the bits go straight into it
    (:func:`_put_compressed` or :func:`_put`), without a branch per bit;
    otherwise each goes through the exact tests and the capacity check
    (:func:`_put_checked`). A ``sparse`` build first skips the chunks with no
    bit: a build on a hanging cloth (few pairs per point), where that branch
    is nearly always right. In a crowded build it was wrong about as often as
    not, and leaving it out made the build a fifth faster with the scalar
    append, 13% with the compress (see DENSE_LIST, DENSE_COMPRESSED). The
    ranges are walked with unsigned indices: with signed ones numba adds a
    negative-index wraparound that turns the loads into gathers.
    """
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
                found = _scan(own, columns, k, lo, hi, NARROW, metric, sparse, direct, order, pairs,
                              pk, base, found, capacity, exact, rest, reach2, near_table)
            else:
                found = _scan(own, columns, k, lo, hi, WIDE, metric, sparse, direct, order, pairs,
                              pk, base, found, capacity, exact, rest, reach2, near_table)
    return found


@njit(**EXACT_OPTIONS, inline="always")
def _scan(own, columns, k, lo, hi, width, metric, sparse, direct, order, pairs, pk, base, found, capacity,
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
        if sparse and mask == 0:
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
    precision, LANES slots at a time (:func:`clothsim.solver.simd.inside`):
    as a loop that ored a shifted bit per slot the build took an eighth
    longer."""
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
    hold none, one or two bits, and a loop over them ended in a mispredicted
    branch. The caller leaves room for two pairs more than the bits
    (PUT_ROOM), and ``order`` a slot past the points (an empty mask reads
    slot ``at``). ``width``: the bits the mask may hold (unused here)."""
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
    branch depends on the bits; on a piled-up 50x50 cloth the build took 15%
    less time. Up to LANES pairs past the new end are overwritten (PUT_ROOM),
    and ``order`` is read up to ``width`` slots past ``at`` (PAD)."""
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


@njit(cache=True, inline="always")
def part_range(n, parts, t):
    """Items ``lo:hi`` of part t when n items are cut into ``parts`` nearly equal ranges."""
    return t * n // parts, (t + 1) * n // parts


DRIFT_OPTIONS = dict(cache=True, boundscheck=False, error_model="numpy",
                     fastmath={"reassoc", "contract", "nsz", "arcp"})
"""fastmath without the no-NaN and no-inf assumptions: the sums vectorise, and a
non-finite displacement still counts as drifted"""

DRIFT_SAMPLE = 512
"""about this many points, evenly spread over the cloth, choose the centres of
the drift test"""


DRIFT_LEVELS = 256
"""steps in which :func:`_drift_bound` measures the squared distance of a
displacement from its centre, up to (skin/2)²"""


@njit(**DRIFT_OPTIONS)
def _drift_bound(Q, reference, skin, centres, spread):
    """A bound B below ``skin`` on how much closer any two points may have come
    since the list was built, or inf when two may have come closer by ``skin``.
    ``Q`` and ``reference`` hold the positions now and at the build, in single
    precision from one origin, each coordinate rounded by less than ``spread``
    (the sum of their largest magnitudes) times 2**-24.

    If every displacement d lies within B/2 of one centre c, any two differ
    by less than B; this holds for any c, so c need not be exact. Two
    centres are tried in one pass: the mean of a sample of the displacements
    (tight when the whole cloth moves alike) and the middle of their box
    (tight when part of the cloth moves and the rest stays, a cloth falling
    onto the floor). The pass takes the largest squared distance from each
    centre in DRIFT_LEVELS steps, as integers: a maximum of floats does not
    vectorise without assuming no NaN, and a NaN must count as drifted. It
    reads single precision, sixteen points at a time: in double precision the
    test took 0.6 us longer a substep at 50x50. B is widened past what the
    rounding may hide.

    ``centres`` (2, 3) keeps the last centres chosen, and they are tried
    first: choosing them from the sample cost half again as much as the
    pass, and the displacements change little from one substep to the
    next, so old centres mostly still hold. Only when neither does are
    new ones chosen and tried.
    """
    level = _level_both(Q, reference, skin, centres)
    if level >= DRIFT_LEVELS:
        _choose_centres(Q, reference, centres)
        level = _level_both(Q, reference, skin, centres)
        if level >= DRIFT_LEVELS:
            return np.inf
    # every squared distance from the centre is below (level + 1) steps of (skin/2)²
    bound = skin * np.sqrt((level + 1.0) / DRIFT_LEVELS)
    largest = 0.0
    for c in range(3):
        largest = max(largest, abs(centres[0, c]), abs(centres[1, c]))
    # a displacement is rounded by (spread + its magnitude) * 2**-24 per coordinate, a
    # centre by its magnitude * 2**-24, the distance between them relatively by a few
    # 2**-24: far less than this
    return bound * (1.0 + 2.0 ** -18) + (spread + skin + 2.0 * largest) * 2.0 ** -18


@njit(**DRIFT_OPTIONS)
def _choose_centres(Q, reference, centres):
    """The mean and the box middle of a sample of the displacements, into ``centres``."""
    n = reference.shape[1]
    step = max(1, n // DRIFT_SAMPLE)
    for c in range(3):
        s, lo, hi = 0.0, np.inf, -np.inf
        x, r = Q[c], reference[c]
        k = 0
        for p in range(0, n, step):
            d = np.float64(x[p] - r[p])
            s += d
            lo = d if d < lo else lo
            hi = d if d > hi else hi
            k += 1
        centres[0, c] = s / k
        centres[1, c] = 0.5 * (lo + hi)


@njit(**DRIFT_OPTIONS)
def _level_both(Q, reference, skin, centres):
    """How many DRIFT_LEVELS steps of (skin/2)² the displacements reach from the
    better of the two centres: DRIFT_LEVELS when one lies at skin/2 or farther
    from both, or is not finite."""
    n = reference.shape[1]
    f32 = np.float32
    scale = f32(DRIFT_LEVELS / (0.25 * skin * skin))
    top = f32(DRIFT_LEVELS)
    m0, m1, m2 = f32(centres[0, 0]), f32(centres[0, 1]), f32(centres[0, 2])
    c0, c1, c2 = f32(centres[1, 0]), f32(centres[1, 1]), f32(centres[1, 2])
    x, y, z = Q[0], Q[1], Q[2]
    rx, ry, rz = reference[0], reference[1], reference[2]
    cap = np.int32(DRIFT_LEVELS)
    worst_mean = np.int32(0)
    worst_mid = np.int32(0)
    for p in range(n):
        dx = x[p] - rx[p]
        dy = y[p] - ry[p]
        dz = z[p] - rz[p]
        a = ((dx - m0) * (dx - m0) + (dy - m1) * (dy - m1) + (dz - m2) * (dz - m2)) * scale
        b = ((dx - c0) * (dx - c0) + (dy - c1) * (dy - c1) + (dz - c2) * (dz - c2)) * scale
        la = np.int32(a) if a < top else cap  # NaN and inf take the top step
        lb = np.int32(b) if b < top else cap
        worst_mean = la if la > worst_mean else worst_mean
        worst_mid = lb if lb > worst_mid else worst_mid
    return min(worst_mean, worst_mid)


@njit(**EXACT_OPTIONS, inline="always")
def self_collide(P, rest, free, thickness, simulation_steps, span, cell_start, search, order, slot,
                 sorted_pos, reference, frame, centres, pairs, push, count, meta, near_offset,
                 near_weight, near_table, near_metric, near_masks, near_level, pos32, extent32,
                 touched, tally):
    """Push apart pairs closer than 2*thickness (Jacobi: all from the same positions).

    Each pair pushes both ends; a point's pushes are averaged over its
    colliding neighbours and divided by ``simulation_steps``; pinned points
    (``free`` 0) stay. Returns (pairs array, number of colliding pairs); the
    array is a new one after each build (see :func:`_sort_by_slack`). When
    the points are spread wider than ``span`` [m] (a run that blew up) no
    list is built and nothing is pushed.

    The work is cut into as many parts as the buffers have (``push.shape[0]``),
    each with its own pushes, summed at the end. Inlined into a
    ``parallel=True`` caller the parts run on threads (``prange``); called
    from serial code they run one after another. The result depends on the
    number of parts (the order of the sums), not on the threads.
    """
    n = P.shape[1]
    parts = push.shape[0]
    reach = 2.0 * thickness
    skin = 0.001 * meta[SKIN] * reach
    # the positions in single precision, from the last build's origin: the drift
    # test, the near stencil and the pairs that rarely touch read them (see
    # _drift_bound, near_pushes, pair_pushes)
    extent = _single(P, frame, pos32, extent32)
    bound = np.inf if meta[VALID] == 0 else _drift_bound(pos32, reference, skin, centres,
                                                         extent + frame[3])
    fresh = not bound < skin
    if fresh:
        radius = reach + skin
        grid = _sort_into_cells(P, radius, span, meta[COLS], cell_start, search, order, slot,
                                sorted_pos)
        if grid[3] == 0.0:
            meta[VALID] = 0
            return pairs, 0
        # the points are cut into more shares than parts, dealt out in turn: the
        # cost of a share depends on how crowded its part of the cloth is
        shares = tally.shape[0]
        size = pairs.shape[1] // shares
        # skip a chunk with no pair before appending only where the last list's
        # density says chunks are mostly empty
        sparse = meta[PAIRS] < (DENSE_COMPRESSED if COMPRESS else DENSE_LIST) * n
        while True:  # once more with room for twice the largest share when one overflowed
            for t in prange(parts):
                for j in range(t, shares, parts):
                    lo, hi = part_range(n, shares, j)
                    tally[j, 0] = query_points(grid, reach, radius, rest, cell_start, search, slot,
                                               order, sorted_pos, near_table, near_metric, lo, hi,
                                               pairs, j * size, size, sparse)
            most = 0
            for j in range(shares):
                most = max(most, tally[j, 0])
            if most <= size:
                break
            size = 2 * most
            pairs = np.empty((2, shares * size), dtype=np.int32)
        meta[PAIRS] = _close_up(pairs, tally, size)
        frame[:3] = P[:, 0]
        extent = _single(P, frame, pos32, extent32)
        frame[3] = extent
        _copy(pos32[:, :n], reference)
        centres[:] = 0.0
        meta[VALID] = 1
        meta[REBUILDS] += 1
    if meta[VALID] == 0:
        return pairs, 0
    listed = meta[PAIRS]
    # a new list is labelled and sorted by slack (a pass of its own, with no
    # branch: in one with the pushes, as it was, the substep of a build took
    # 6.6 us longer at 50x50); every substep then checks the pairs whose slack
    # the drift bound reaches, on the substep of a build the touching ones.
    # Slack is measured in squared distance past the reach's square (no square
    # root per pair), in steps of the span up to the list radius's square
    span2 = (reach + skin) ** 2 - reach * reach
    reachable = ((reach + bound) ** 2 - reach * reach) * (1.0 + 1e-6) / span2
    if fresh:
        labels = np.empty(listed, dtype=np.int8)
        for t in prange(parts):
            k0, k1 = part_range(listed, parts, t)
            label_pairs(P, reach, pairs, k0, k1, labels, (SLACK_BUCKETS - 1) / span2)
        pairs = _sort_by_slack(pairs, labels, listed, meta, parts)
    # bucket 0, the pairs that touched at the build, is pushed without a branch
    # per pair: those pairs hover about the reach, and the branch on whether
    # one touches was mispredicted about as often as not
    touching = meta[BUCKET]
    # the pairs that rarely touch and, between builds, the near stencil are first
    # tested in single precision (see near_pushes)
    wide2 = widened2(reach, extent)
    checked = touching if fresh else _checked(meta, reachable * (SLACK_BUCKETS - 1))
    for t in prange(parts):
        h = near_pushes(P, reach, near_offset, near_weight, push[t], count[t], touched[t],
                        near_masks[t], t, parts, near_level, fresh, reachable * NEAR_LEVELS,
                        NEAR_LEVELS / span2, pos32, wide2, not fresh)
        k0, k1 = part_range(checked, parts, t)
        tally[t, 1] = h + pair_pushes(P, reach, pairs, k0, max(k0, min(k1, touching)), k1, push[t],
                                      count[t], touched[t], h, pos32, wide2)
    hits, most = 0, 0
    for t in range(parts):
        hits += tally[t, 1]
        most = max(most, tally[t, 1])
    if hits > 0:
        inv_steps = 1.0 / simulation_steps
        if most <= SPARSE_PAIRS:
            apply_sparse(P, push, count, free, inv_steps, touched, tally)
        else:
            for t in prange(parts):
                lo, hi = part_range(n, parts, t)
                apply_pushes(P, push, count, free, inv_steps, lo, hi)
    return pairs, hits


@njit(**EXACT_OPTIONS)
def _close_up(pairs, tally, size):
    """Move each share's pairs (share j's from ``j * size``) into one run; returns their number."""
    total = tally[0, 0]
    for t in range(1, tally.shape[0]):
        base = t * size
        for j in range(tally[t, 0]):
            pairs[0, total + j] = pairs[0, base + j]
            pairs[1, total + j] = pairs[1, base + j]
        total += tally[t, 0]
    return total


@njit(**KERNEL_OPTIONS)
def _copy(src, dst):
    for c in range(src.shape[0]):
        a, b = src[c], dst[c]
        for p in range(a.shape[0]):
            b[p] = a[p]


@njit(**EXACT_OPTIONS)
def pair_pushes(P, reach, pairs, k0, sure, k1, push, count, touched, before, Q, wide2):
    """Add the pushes of listed pairs ``k0:k1`` closer than ``reach`` to ``push`` (3, N)
    and ``count`` (N,), noting their ends in ``touched`` after those of the
    ``before`` pairs pushed already (see :func:`_push`); returns how many
    pairs that was.

    Pairs ``k0:sure`` are pushed without a branch on whether they touch:
    every one adds its push, zero where it does not. That costs a square
    root and the stores for each, and pays where about half of them touch
    and the branch would be mispredicted as often: on the pairs that
    touched at the build, the pair pass of a piling 50x50 cloth took a
    sixth less time. Pairs ``sure:k1`` rarely touch and keep the branch;
    they are first tested on ``Q``, the positions in single precision,
    against ``wide2`` (see :func:`near_pushes`): half the memory to gather
    from, and the pass took 3% less time at 50x50.
    """
    reach2 = reach * reach
    x, y, z = P[0], P[1], P[2]
    hits = 0
    room = touched.shape[0] // 2 - 1
    for k in range(k0, sure):
        # unsigned: a signed index costs a negative-index check per access, 12-20% here
        a = np.uint64(pairs[0, k])
        b = np.uint64(pairs[1, k])
        dx = x[a] - x[b]
        dy = y[a] - y[b]
        dz = z[a] - z[b]
        d2 = dx * dx + dy * dy + dz * dz
        close = (d2 < reach2) & (d2 != 0.0)
        d = np.sqrt(d2 if close else reach2)  # the push of a pair at the reach is zero
        _add_push(push, count, a, b, dx, dy, dz, (reach - d) / d, 1.0 if close else 0.0)
        # noted whether it touches or not: the next pair that does overwrites it
        at = min(before + hits, room)
        touched[2 * at] = a
        touched[2 * at + 1] = b
        hits += 1 if close else 0
    qx, qy, qz = Q[0], Q[1], Q[2]
    for k in range(sure, k1):
        a = np.uint64(pairs[0, k])
        b = np.uint64(pairs[1, k])
        if not gap2(qx, qy, qz, a, qx, qy, qz, b) < wide2:
            continue
        d2 = gap2(x, y, z, a, x, y, z, b)
        if not ((d2 < reach2) & (d2 != 0.0)):
            continue
        _push(P, a, b, reach, push, count, touched, before + hits)
        hits += 1
    return hits


@njit(**EXACT_OPTIONS)
def label_pairs(P, reach, pairs, k0, k1, labels, scale):
    """The slack bucket of listed pairs ``k0:k1`` into ``labels``: 0 if the pair is
    closer than ``reach``, else 1 + its squared distance past the reach's
    square times ``scale``, at most SLACK_BUCKETS - 1. See
    :func:`_sort_by_slack`. A pass of its own, without the pushes: it has no
    branch, and the pairs that touch, bucket 0, are pushed after the sort
    like those of any substep."""
    reach2 = reach * reach
    x, y, z = P[0], P[1], P[2]
    last = np.float64(SLACK_BUCKETS - 1)
    for k in range(k0, k1):
        a = np.uint64(pairs[0, k])
        b = np.uint64(pairs[1, k])
        d2 = gap2(x, y, z, a, x, y, z, b)
        steps = min(1.0 + (d2 - reach2) * scale, last)
        labels[k] = np.int8(0 if d2 < reach2 else steps)


SORT_LANES = 8
"""runs of the list each part of :func:`_sort_by_slack` walks side by side: on a
list of 75,000 pairs 8 took 104 us, 4 took 117, 2 took 167 and one 206"""


@njit(**EXACT_OPTIONS, inline="always")
def _sort_by_slack(pairs, labels, listed, meta, parts):
    """The list's first ``listed`` pairs ordered by their ``labels`` (slack buckets),
    keeping the order within a bucket, in a new array as large as ``pairs``
    (copying them back took a fifth of the sort); where each bucket ends goes
    into ``meta[BUCKET:]``.

    A pair of the list started ``slack`` past the reach, and it cannot touch
    before two points have come closer by that much; :func:`_drift_bound`
    bounds by how much any two have, so each substep only checks the buckets
    that bound reaches (see :func:`self_collide`). Pairs that touched at the
    build come first: every substep checks them, without a branch (see
    :func:`pair_pushes`). Runs once after each build; its scratch is
    allocated here, as the list may have grown.

    A counting sort cut into ``parts`` (``prange`` where inlined into
    parallel code), each walking SORT_LANES runs of its range side by side
    with a counter row per run: a single run's next count or place waits on
    the store of its last whenever two labels in a row are alike. Its loops
    are inlined here, where ``out`` is allocated: compiled apart, each store
    into ``out`` might have changed a counter, which was then read again, and
    the sort took half again as long.
    """
    runs = parts * SORT_LANES
    at = np.zeros((runs, SLACK_BUCKETS), dtype=np.int64)
    for t in prange(parts):
        lo, hi = part_range(listed, parts, t)
        _count_runs(labels, lo, hi, at[t * SORT_LANES:(t + 1) * SORT_LANES])
    # run r's pairs of bucket j go after bucket j's pairs of the runs before it
    total = 0
    for j in range(SLACK_BUCKETS):
        for r in range(runs):
            c = at[r, j]
            at[r, j] = total
            total += c
        meta[BUCKET + j] = total
    out = np.empty_like(pairs)
    for t in prange(parts):
        lo, hi = part_range(listed, parts, t)
        _place_runs(pairs, labels, lo, hi, at[t * SORT_LANES:(t + 1) * SORT_LANES], out)
    return out


@njit(**EXACT_OPTIONS, inline="always")
def _count_runs(labels, lo, hi, at):
    """Labels ``lo:hi`` cut into SORT_LANES runs, walked side by side, each run
    counting into its row of ``at``; what is left over goes to the last run."""
    size = (hi - lo) // SORT_LANES
    for i in range(size):
        for r in range(SORT_LANES):
            at[r, labels[lo + r * size + i]] += 1
    for k in range(lo + SORT_LANES * size, hi):
        at[SORT_LANES - 1, labels[k]] += 1


@njit(**EXACT_OPTIONS, inline="always")
def _place_runs(pairs, labels, lo, hi, at, out):
    """The runs of :func:`_count_runs` again, each pair put into ``out`` at the next
    place its run's row of ``at`` holds for its label."""
    size = (hi - lo) // SORT_LANES
    for i in range(size):
        for r in range(SORT_LANES):
            _place(pairs, labels, lo + r * size + i, at, r, out)
    for k in range(lo + SORT_LANES * size, hi):
        _place(pairs, labels, k, at, SORT_LANES - 1, out)


@njit(**EXACT_OPTIONS, inline="always")
def _place(pairs, labels, k, at, r, out):
    """Put pair k into ``out`` at the next place row r of ``at`` holds for its label."""
    j = labels[k]
    out[0, at[r, j]] = pairs[0, k]
    out[1, at[r, j]] = pairs[1, k]
    at[r, j] += 1


@njit(cache=True, inline="always")
def _checked(meta, reachable):
    """How many pairs from the front of the list a substep checks: the buckets
    whose least slack lies below ``reachable`` (in the steps of :func:`pair_pushes`)."""
    top = min(np.int64(reachable) + 1, SLACK_BUCKETS - 1)
    return meta[BUCKET + top]


@njit(**EXACT_OPTIONS, inline="always")
def _push(P, a, b, reach, push, count, touched, k):
    """Add the push of the pair (a, b), closer than ``reach``, to both ends: each
    goes to ``reach`` from the other's place. The ``k``-th pair a part pushes
    notes its ends in ``touched[2k:2k + 2]`` while there is room."""
    dx = P[0, a] - P[0, b]
    dy = P[1, a] - P[1, b]
    dz = P[2, a] - P[2, b]
    d = np.sqrt(dx * dx + dy * dy + dz * dz)
    _add_push(push, count, a, b, dx, dy, dz, (reach - d) / d, 1.0)
    if 2 * k < touched.shape[0]:
        touched[2 * k] = a
        touched[2 * k + 1] = b


@njit(cache=True, inline="always")
def _add_push(push, count, a, b, dx, dy, dz, s, one):
    """Add (dx, dy, dz) * s to a's push and take it from b's; ``one`` to each count."""
    push[0, a] += dx * s
    push[1, a] += dy * s
    push[2, a] += dz * s
    push[0, b] -= dx * s
    push[1, b] -= dy * s
    push[2, b] -= dz * s
    count[a] += one
    count[b] += one


@njit(**KERNEL_OPTIONS)
def apply_sparse(P, push, count, free, inv_steps, touched, tally):
    """:func:`apply_pushes` for the ends of the pushed pairs only, when each part
    noted all of its pairs in ``touched`` (``tally[t, 1]`` pairs in part t).

    A hanging cloth pushes a few pairs in a substep, and a pass over every
    point cost as much as the near stencil. A point noted again has been
    applied and zeroed by then, so applying it again moves it by nothing.
    Each end is moved by plain scalar code: :func:`apply_pushes` over a
    range of one point cost 50 ns an end in the views it makes, as much as
    the full pass once a drape pushed some 30 pairs.
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
    pairs and divided by the substeps; sums the parts' pushes into part 0 first.
    The pushes and counts are left at zero for the next substep: a separate pass
    to clear them would run every substep, this one only when something collided.
    One loop moves and clears each point (a loop per coordinate took 40% longer
    at 50x50)."""
    parts = push.shape[0]
    m = hi - lo
    c0 = count[0, lo:]
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
    x, y, z = P[0, lo:], P[1, lo:], P[2, lo:]
    px, py, pz = push[0, 0, lo:], push[0, 1, lo:], push[0, 2, lo:]
    fr = free[lo:]
    for p in range(m):
        weight = fr[p] * inv_steps / max(c0[p], 1.0)
        x[p] += px[p] * weight
        y[p] += py[p] * weight
        z[p] += pz[p] * weight
        px[p] = 0.0
        py[p] = 0.0
        pz[p] = 0.0
        c0[p] = 0.0


NEAR_LEVELS = 32
"""steps of squared distance between the reach and the list radius in which the
stencil notes how far past the reach each block's closest pair was"""


@njit(**KERNEL_OPTIONS)
def near_pushes(P, reach, offsets, weight, push, count, touched, masks, part, parts, level, fresh, reachable,
                scale, Q, wide2, single):
    """Add the pushes of the near-stencil pairs closer than ``reach`` to ``push``
    and ``count``, noting their ends in ``touched`` (see :func:`_push`);
    returns how many pairs that was. Only part ``part`` of
    ``parts`` of each offset's blocks is taken.

    As in the Provot pass, a whole offset set is first only checked, block by
    block of BLOCK pairs (no square root, no stores per pair), setting a bit
    in ``masks`` per pair inside the reach; then only those pairs are pushed.

    On the substep of a build (``fresh``) each block notes in ``level`` (S,
    blocks) how far its closest pair was past the reach: its squared
    distance less the reach's, times ``scale``, rounded toward zero (0 or
    less for a pair within reach, NEAR_LEVELS at most). Later a block is
    skipped while that level is at least ``reachable``, where the drift bound
    (:func:`_drift_bound`) cannot have brought any of its pairs within reach:
    on a piled-up 50x50 cloth the diagonal neighbours' blocks, half the
    stencil, sat about half a skin past it. Integer levels, as their minimum
    vectorises where one of doubles does not.

    With ``single`` the check reads ``Q``, the positions in single precision
    (:func:`_to_single`), against ``wide2``, the squared reach widened past
    their rounding, LANES pairs at a time (:func:`clothsim.solver.simd.close_lanes`),
    reading up to PAD slots past the points (``Q`` and ``weight`` are padded).
    Each pair it lets through is tested again in double precision before it
    is pushed. The substep of a build, which notes the levels, checks in
    double precision.
    """
    n = P.shape[1]
    reach2 = reach * reach
    top = np.float64(NEAR_LEVELS)
    cap = np.int32(NEAR_LEVELS)
    x, y, z = P[0], P[1], P[2]
    hits = 0
    for s in range(offsets.shape[0]):
        o = offsets[s]
        m = n - o
        ws = weight[s]
        nblocks = (m + BLOCK - 1) // BLOCK
        first = part * nblocks // parts * BLOCK
        stop = min((part + 1) * nblocks // parts * BLOCK, m)
        # views made once per offset, unsigned indices into them: views made
        # per block cost a tenth of the check on a 50x50 cloth
        xb, yb, zb = x[o:], y[o:], z[o:]
        qx, qy, qz = Q[0], Q[1], Q[2]
        blocks = 0
        for lo in range(first, stop, BLOCK):
            nb = min(BLOCK, m - lo)
            start = np.uint64(lo)
            mask = np.uint64(0)  # an or of shifted selects vectorises
            if single:
                if level[s, lo // BLOCK] < reachable:
                    for c in range(0, BLOCK, LANES):
                        mask |= close_lanes(qx, qy, qz, ws, start + np.uint64(c), start + np.uint64(c + o),
                                            wide2) << np.uint64(c)
                    if nb < BLOCK:  # past the pairs: read (the buffers are padded), not taken
                        mask &= (np.uint64(1) << np.uint64(nb)) - np.uint64(1)
            elif fresh or level[s, lo // BLOCK] < reachable:
                least = cap
                for p in range(nb):
                    q = start + np.uint64(p)
                    d2 = gap2(x, y, z, q, xb, yb, zb, q)
                    close = (ws[q] != 0) & (d2 < reach2) & (d2 > 0.0)
                    mask |= np.uint64(1 if close else 0) << np.uint64(p)
                    if fresh:  # loop-invariant: LLVM keeps a loop without it
                        steps = (d2 - reach2) * scale
                        lv = np.int32(steps) if steps < top else cap
                        lv = lv if ws[q] != 0 else cap
                        least = lv if lv < least else least
                if fresh:
                    level[s, lo // BLOCK] = least
            masks[blocks] = mask
            blocks += 1
        for b in range(blocks):
            mask = masks[b]
            while mask != 0:
                j, mask = pop_lowest(mask)
                a = first + b * BLOCK + j
                if single:
                    d2 = gap2(x, y, z, a, x, y, z, a + o)
                    if not ((d2 < reach2) & (d2 > 0.0)):
                        continue
                _push(P, a, a + o, reach, push, count, touched, hits)
                hits += 1
    return hits


@njit(**EXACT_OPTIONS, inline="always")
def _single(P, frame, Q, extent):
    """P from the origin ``frame[:3]`` in single precision into ``Q``, cut into as many
    parts as ``extent`` has (``prange`` where inlined into parallel code),
    each noting the bits of its largest magnitude there; returns the largest."""
    parts = extent.shape[0]
    n = P.shape[1]
    for t in prange(parts):
        lo, hi = part_range(n, parts, t)
        extent[t] = _to_single(P, frame[0], frame[1], frame[2], Q, lo, hi)
    return np.float64(extent.view(np.float32).max())


@njit(**KERNEL_OPTIONS)
def _to_single(P, ox, oy, oz, Q, lo, hi):
    """Points ``lo:hi`` of P from (ox, oy, oz) in single precision into ``Q``; returns
    the bits of the largest magnitude so written, as an int32. The magnitudes
    are taken on the bits, whose order is theirs: a maximum of floats does
    not vectorise, and the pass took six times as long."""
    most = np.int32(0)
    m = hi - lo
    for c in range(3):
        # views from lo: indexed from lo into the whole planes, the loop ran
        # scalar inside the substep (4.8 us instead of 0.7 at 50x50)
        x, q = P[c, lo:hi], Q[c, lo:hi]
        bits = q.view(np.int32)
        o = ox if c == 0 else (oy if c == 1 else oz)
        for p in range(m):
            q[p] = np.float32(x[p] - o)
            most = max(most, bits[p] & np.int32(0x7FFFFFFF))
    return most
