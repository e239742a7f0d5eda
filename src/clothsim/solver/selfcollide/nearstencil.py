"""The near stencil: grid offsets whose pairs sit inside the list radius at rest, checked every substep.

The timings behind its choices are in docs/performance.md ('Near stencil';
those of the rest layout's metric, which serves the list build, in 'List
build').
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..shared import BLOCK, KERNEL_OPTIONS, gap2, pop_lowest
from ..simd import LANES, close_lanes
from .buffers import NEAR, NeighbourList
from .listbuild import build_list
from .pushes import push_pair

SKIN_FACTOR = 0.35
"""skin of the neighbour list as a fraction of the reach: larger lists, rarer
rebuilds. The piled 100x100 cloth ran fastest with 0.35 of the skins from
0.3 to 0.5, and the piled 200x200 one and the meshes of 10,000 points ran
faster with it than with 0.5: each build finds fewer pairs and each substep
checks fewer, which repays the more frequent builds (figures:
docs/performance.md, 'A narrower skin for fine cloths')"""

COARSE_SKIN = 0.75
"""the skin of a coarse cloth: see :func:`skin_factor`"""

COARSE_OFFSETS = 4
"""grid offsets (each pair once) a cloth's stencil may take in at COARSE_SKIN
for the cloth to count as coarse"""

METRIC_GAP = 1e-4
"""least relative gap between the grid offsets inside and outside the ellipse of
:func:`grid_metric`: single precision tells them apart to about 1e-7"""


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
    sphere rebuilt its list 5.0 times per 100 substeps instead of 7.4, for
    two more stencil offsets, and self-collision got cheaper. A finer one
    takes SKIN_FACTOR: at 100x100 the wider skin took rings of grid
    neighbours into the stencil and made self-collision slower, at 200x200
    more so, as offsets past NEAR went into the list for good.
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
    mask (9 MB) outgrew the cache.
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
    half the candidates inside the radius.
    rho² lies halfway between the nominal squared distances of the farthest
    marked offset inside it and the nearest offset not marked, so the ellipse
    holds only marked offsets, also when the build tests it in single
    precision; zeros drop nothing.

    ``exact`` is 1 when the ellipse holds every marked offset and every pair
    closer than ``reach`` at rest: the exact tests can then reject nothing
    the first test let through, and the build skips them. Both are
    properties of the rest layout, checked here once: a regular grid passes,
    a cloth whose rest layout is warped may not.
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
    metric[3] = marked_inside and close_at_rest_inside(rest, cols, reach, metric)
    return metric


def close_at_rest_inside(rest: np.ndarray, cols: int, reach: float, metric: np.ndarray) -> bool:
    """Whether every pair closer than ``reach`` at rest lies inside the ellipse of
    ``metric``: a search of the rest layout itself, with the list's own build."""
    n = len(rest)
    x = NeighbourList.allocate(n, cols)
    P = np.ascontiguousarray(rest.T)
    pairs = x.pairs
    while True:
        # radius reach and no rest test: every pair closer than reach, each once
        found = build_list(P, rest, 0.0, reach, np.inf, x, pairs)
        if found <= pairs.shape[1]:
            break
        pairs = np.zeros((2, 2 * found), dtype=np.int32)
    a, b = pairs[:, :found].astype(np.int64)
    dr, di = a // cols - b // cols, a % cols - b % cols
    return bool(np.all(dr * dr * metric[0] + di * di * metric[1] < metric[2]))


NEAR_LEVELS = 32
"""steps of squared distance between the reach and the list radius in which the
stencil notes how far past the reach each block's closest pair was"""


@njit(**KERNEL_OPTIONS)
def near_pushes(P, reach, lists, part, parts, fresh, reachable, scale, wide2, single):
    """Add the pushes of the near-stencil pairs closer than ``reach`` to ``push``
    and ``count``, noting their ends in ``touched`` (see :func:`push_pair`);
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
    (:func:`drift_bound`) cannot have brought any of its pairs within reach:
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
    # the stencil and part ``part``'s scratch of the :class:`~.buffers.NeighbourList`
    offsets, weight, level, Q = lists.near_offset, lists.near_weight, lists.near_level, lists.pos32
    push, count, touched, masks = lists.push[part], lists.count[part], lists.touched[part], lists.near_masks[part]
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
        # views made once per offset, unsigned indices into them: made per
        # block, the views cost a visible share of the check on a small cloth
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
                push_pair(P, a, a + o, reach, push, count, touched, hits)
                hits += 1
    return hits
