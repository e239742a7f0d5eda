"""The hinted points of a mesh pass, decided by their triangles' clear prisms, four at a time.

A cloth resting on a mesh crosses the same triangle at each point in contact,
substep after substep: :mod:`.mesh` keeps that triangle as the point's hint,
and the triangle's clear prism (:mod:`.meshprism`) settles the point's
segment without a search wherever both its ends lie in it. Per point that is
a hundred or two floating-point operations (the turns into the mesh's frame,
six prism sides, the heights over the triangle's plane and the placement) on a
triangle's rows read from wherever the hint points.

In scalar code each such point cost some 60 ns. Here the hinted points go
in blocks of BLOCK: their positions and their triangles' rows are copied
into a scratch, one row per quantity (``S_*``), and one loop without
branches (:func:`_decide`) runs over the block's columns, which LLVM turns
into vector code (four points at once with AVX2). A triangle's prism and
its plane sit side by side in one row of ``mesh_prisms`` (192 bytes),
which the copy reads whole, eight points at a time, and turns into the
scratch's columns in registers (:func:`..simd.rows_to_columns`). Every test is made for
every point and the outcome selected, so the answer is the scalar tests',
to the bit: the same operations in the same order, without fastmath, but for
the search's crossing test on the hinted triangle, which the heights of the
segment's ends tell wherever they stand beyond the rounding of that test
(:func:`_by_heights`); nearer the plane the point goes to the search.

The scratch is one flat array indexed ``row * BLOCK + column`` with BLOCK a
constant: LLVM then sees every read as one object at fixed offsets, and the
results go to a second array, so the vector loop needs a single overlap
test (with a row per quantity as separate arrays it needed more than LLVM
allows, and stayed scalar).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..shared import EXACT_OPTIONS, renamed
from ..simd import ROWS8, rows_to_columns
from .meshgrid import put_off
from .meshpose import is_rest, to_rest, to_world
from .meshprism import P_DOWN, P_NORMAL, P_OFFSET, P_ROUNDING, P_UP, ROW_FIELDS

BLOCK = 64
"""hinted points decided together: the scratch (30 x 64 doubles, 15 KB) stays in L1"""

PAD = 8
"""a block's columns are decided in whole multiples of PAD (the last block padded with
its last point again): the vector loops then end without a scalar remainder, which
cost some 35 ns a column (eight doubles a vector with AVX-512; a divisor of BLOCK)"""

S_LAST, S_NOW, S_PRISM = 0, 3, 6
S_ROWS = S_PRISM + ROW_FIELDS
"""the scratch's rows: a point's last (or reference) position (3) and its position
now (3), world frame [m]; its triangle's row of ``mesh_prisms``: the prism (14), the
triangle's plane (4), its rounding bound, zeros"""

O_X, O_ROUTE, O_ROWS = 0, 3, 4
"""the results' rows: where a placed point goes (3, world frame [m]); its route"""


@njit(**EXACT_OPTIONS, inline="always")
def _at(row, j):
    """the flat scratch index of ``row``, column j: unsigned, so that numba adds no
    wrap-around select for a negative index (j is never negative)"""
    return np.uint64(row * BLOCK + j)


@njit(**EXACT_OPTIONS, inline="always")
def _by_heights(heights, slack, bound, entry_only):
    """(crosses, told) for a segment with both ends in a triangle's prism: whether it
    crosses the triangle as the search's test (:func:`.mesh._hit`, ``s <= 1``) says,
    and whether that is told here. ``heights``: the start's and the end's heights
    over the plane [m] (n . q - offset) and the end's as start + n . (end - start),
    as the search makes them; ``slack`` the search's plane slack, ``bound`` the
    triangle's rounding bound (:func:`.meshprism.rounding_heights`).

    The search first tests the plane with the slack, which is made here as it
    makes it: a segment it rejects crosses nothing. One it lets through crosses
    where its ends lie on the two sides (for a closed mesh, only going in): both
    in the prism, its crossing with the plane lies inside the triangle, more than
    the prism's inset from its edges, far beyond the test's barycentric slack,
    and the test's signs of the area times each height are those of the heights
    wherever both ends stand more than ``bound`` off the plane. Nearer than
    that, it is not told (the search decides)."""
    h0, h1, h1s = heights
    if entry_only:
        plane = (h0 >= -slack) & (h1s <= slack)
    else:
        plane = ((h0 > slack) & (h1s > slack) | (h0 < -slack) & (h1s < -slack)) ^ True
    going_in = (h0 > bound) & (h1 < -bound)
    going_out = (h0 < -bound) & (h1 > bound)
    sides = going_in if entry_only else going_in | going_out
    off = ((h0 > bound) | (h0 < -bound)) & ((h1 > bound) | (h1 < -bound))
    return plane & sides, (plane ^ True) | off


@njit(**EXACT_OPTIONS, inline="always")
def _in_prism(S, j, x, y, z):
    """whether (x, y, z) (rest frame) lies within the three sides of column j's prism"""
    a, b, c = S_PRISM, S_PRISM + 4, S_PRISM + 8
    return ((S[_at(a, j)] * x + S[_at(a + 1, j)] * y + S[_at(a + 2, j)] * z >= S[_at(a + 3, j)])
            & (S[_at(b, j)] * x + S[_at(b + 1, j)] * y + S[_at(b + 2, j)] * z >= S[_at(b + 3, j)])
            & (S[_at(c, j)] * x + S[_at(c + 1, j)] * y + S[_at(c + 2, j)] * z >= S[_at(c + 3, j)]))


@njit(**EXACT_OPTIONS)
def _decide(S, O, count, frames, tiny, closed, placing):
    """The first ``count`` columns of the scratch S decided: O's route row 1 where the
    segment meets no triangle and, for a closed mesh, ends outside; 2 where it
    crosses the hinted triangle first and the placement (``placing``: margin [m],
    keep = 1 - friction, whether the friction rule applies), friction and all,
    ends in the triangle's clear prism on the side it came from, so that it
    crosses nothing and ends outside (O's rows O_X.. then hold where it goes,
    world frame [m]); 0 where the prism cannot tell (an end outside it, a
    placement on the triangle within rounding, an end within the triangle's
    rounding bound of its plane), for the search. ``frames``: the mesh's poses
    (before, now); ``tiny``: the plane slack of its grid [m].

    Where it tells, the answer is the search's: the crossing the search's test on
    the triangle finds (:func:`_by_heights`), and no other triangle that the
    search could find first. A
    placement nearer the plane than the slack (a point resting on the surface
    stays as near as it was) is taken only where a search after it, from the
    last position, would not find the triangle again (the search would then
    leave the point where it was), and where it is beyond the rounding of its
    height (the inside test finds it outside)."""
    before, now = frames
    margin, keep, friction = placing
    for j in range(count):
        x0, y0, z0 = to_rest(before, S[_at(S_LAST, j)], S[_at(S_LAST + 1, j)], S[_at(S_LAST + 2, j)])
        x1, y1, z1 = to_rest(now, S[_at(S_NOW, j)], S[_at(S_NOW + 1, j)], S[_at(S_NOW + 2, j)])
        inside = _in_prism(S, j, x0, y0, z0) & _in_prism(S, j, x1, y1, z1)
        up, down = S[_at(S_PRISM + P_UP, j)], S[_at(S_PRISM + P_DOWN, j)]
        nx, ny, nz = S[_at(S_PRISM + P_NORMAL, j)], S[_at(S_PRISM + P_NORMAL + 1, j)], S[_at(S_PRISM + P_NORMAL + 2, j)]
        w = S[_at(S_PRISM + P_OFFSET, j)]
        h0 = nx * x0 + ny * y0 + nz * z0 - w
        h1 = nx * x1 + ny * y1 + nz * z1 - w
        nothing = (h0 > tiny) & (h0 <= up) & (h1 > tiny) & (h1 <= up)
        if closed:
            # only entries count: a start on the plane (within the slack) is the search's to judge
            side, room = 1.0, up
            start = (h0 >= -tiny) & (h0 <= up)
        else:
            above = h0 > tiny
            side = 1.0 if above else -1.0
            room = up if above else down
            start = (side * h0 > tiny) & (side * h0 <= room)
            nothing = nothing | (start & (side * h1 > tiny) & (side * h1 <= room))
        dx, dy, dz = x1 - x0, y1 - y0, z1 - z0
        slack = tiny + 1e-12 * (abs(x0) + abs(y0) + abs(z0) + abs(dx) + abs(dy) + abs(dz))
        # the crossing of the hinted triangle, told by the ends' heights where both lie
        # in its prism and beyond the rounding bound (see _by_heights)
        bound = S[_at(S_PRISM + P_ROUNDING, j)]
        # (where it is not told, crosses is False: the point is not placed here, and the
        # search decides it)
        crosses, _ = _by_heights((h0, h1, h0 + (nx * dx + ny * dy + nz * dz)), slack, bound, closed)
        # the search's placement, then the friction rule, as the kernels make them
        x, y, z = put_off((nx, ny, nz, w), (x0, y0, z0, x1, y1, z1), margin)
        if friction:
            x, y, z = x0 + keep * (x - x0), y0 + keep * (y - y0), z0 + keep * (z - z0)
        hx = nx * x + ny * y + nz * z - w
        hc = side * hx
        ex, ey, ez = x - x0, y - y0, z - z0
        slack = tiny + 1e-12 * (abs(x0) + abs(y0) + abs(z0) + abs(ex) + abs(ey) + abs(ez))
        again, told = _by_heights((h0, hx, h0 + (nx * ex + ny * ey + nz * ez)), slack, bound, closed)
        clear = (hc > tiny) | ((hc > 1e-13 * (abs(x) + abs(y) + abs(z))) & (again ^ True))
        sure = told | (hc > tiny)  # the second crossing counts only so near the plane
        placed = inside & (nothing ^ True) & start & crosses & (hc <= room) & clear
        wx, wy, wz = to_world(now, x, y, z)
        O[_at(O_X, j)] = wx
        O[_at(O_X + 1, j)] = wy
        O[_at(O_X + 2, j)] = wz
        O[_at(O_ROUTE, j)] = 1.0 if inside & nothing else (2.0 if placed & sure else 0.0)


@njit(**EXACT_OPTIONS, inline="always")
def _as_is(frame, x, y, z):
    """(x, y, z) unturned: the turns of a mesh in its rest pose"""
    return x, y, z


_decide_still = njit(**EXACT_OPTIONS)(renamed(_decide.py_func, "_decide_still", to_rest=_as_is, to_world=_as_is))
""":func:`_decide` for a mesh in its rest pose in both frames (:func:`.meshpose.is_rest`),
without the turns into its frame and back, which give the same coordinates there
(x - 0 = x, 1x + 0y + 0z = x, but for the sign of a zero) and which LLVM, without
fastmath, cannot drop itself"""


@njit(**EXACT_OPTIONS)
def _gather(S, P, L, prisms, hints, k, which, lo, tri):
    """Column j of the scratch S filled for point ``lo + which[j]`` (all of ``which``, at
    most BLOCK): its positions from L and P (3, N) and its hinted triangle's row of
    ``prisms`` (``mesh_prisms``: the prism and the triangle's plane). ``tri`` (BLOCK,) uint64
    is room for the triangles' numbers. Eight points' rows at a time are read
    whole and turned into columns in registers (:func:`..simd.rows_to_columns`):
    a copy one double at a time, even as a vector loop, gathered each of a
    point's doubles on its own and took twice as long. A remainder of fewer than eight
    columns (none where the caller pads to PAD) is copied one double at a time."""
    m = which.shape[0]
    for j in range(m):
        p = np.uint64(lo + which[j])  # unsigned indices: no wrap-around selects
        tri[j] = np.uint64(hints[k, p])
        S[_at(S_LAST, j)], S[_at(S_LAST + 1, j)], S[_at(S_LAST + 2, j)] = L[0, p], L[1, p], L[2, p]
        S[_at(S_NOW, j)], S[_at(S_NOW + 1, j)], S[_at(S_NOW + 2, j)] = P[0, p], P[1, p], P[2, p]
    whole = m // ROWS8 * ROWS8
    for j in range(0, whole, ROWS8):
        rows_to_columns(prisms, tri, j, S, S_PRISM * BLOCK + j, BLOCK)
    for c in range(ROW_FIELDS):
        for j in range(whole, m):
            S[_at(S_PRISM + c, j)] = prisms[tri[j], np.uint64(c)]


@njit(**EXACT_OPTIONS)
def hint_pass(P, L, mesh, frames, G, placing, lo, marks):
    """The points that ``marks`` (need, listed) lists (``lo`` + each number of
    ``listed``, ascending, each in 0..len(need) - 1) and that have a hint, all
    decided by it (:func:`_decide`) before any search: a placed one written to ``P``.
    Returns how many points are left to the search, their numbers moved to the front
    of ``listed``: those without a hint, in their order, then those whose prism could
    not tell (``need`` is not written: the kernels' loops take that list). ``mesh``: (prisms, hints, k, first,
    last, hinted, closed): ``mesh_prisms`` and the hints, the mesh's number, the rows
    holding its triangles (a hint outside them is not tried), the points that keep
    hints (below ``hinted``) and the closed flag; ``frames`` (before, now) as for
    :func:`_decide`; ``G`` the grid's scalars (its plane slack last). Rows narrower
    than ROW_FIELDS (not made by :func:`.meshprism.pack_prisms`) decide nothing:
    the copy reads whole rows."""
    prisms, hints, k, first, last, hinted, closed = mesh
    need, listed = marks
    count = listed.shape[0]
    n = min(need.shape[0], max(hinted - lo, 0))  # the points below keep hints
    if first >= last or n <= 0 or prisms.shape[1] < ROW_FIELDS:
        return count
    which = np.empty(count + PAD, dtype=np.int64)
    m = 0
    left = 0  # the points without a hint, moved up in listed (left <= i)
    for i in range(count):
        q = listed[i]
        h = hints[k, lo + min(q, n - 1)]
        has = (q < n) & (h >= first) & (h < last)
        which[m] = q
        m += np.int64(has)
        listed[left] = q
        left += np.int64(has ^ True)
    if m == 0:
        return left
    which[m:m + PAD] = which[m - 1]  # the last block's padding: its last point again
    still = is_rest(frames[0]) and is_rest(frames[1])
    S = np.empty(S_ROWS * BLOCK)
    O = np.empty(O_ROWS * BLOCK)
    tri = np.empty(BLOCK, dtype=np.uint64)
    for b in range(0, m, BLOCK):
        real = min(BLOCK, m - b)
        block = which[b:b + min(BLOCK, (real + PAD - 1) // PAD * PAD)]
        _gather(S, P, L, prisms, hints, k, block, lo, tri)
        if still:
            _decide_still(S, O, block.shape[0], frames, G[13], closed, placing)
        else:
            _decide(S, O, block.shape[0], frames, G[13], closed, placing)
        for j in range(real):
            q = block[j]
            p = np.uint64(lo + q)
            route = O[_at(O_ROUTE, j)]
            placed = route == 2.0
            P[0, p] = O[_at(O_X, j)] if placed else P[0, p]
            P[1, p] = O[_at(O_X + 1, j)] if placed else P[1, p]
            P[2, p] = O[_at(O_X + 2, j)] if placed else P[2, p]
            listed[left] = q  # kept where the prism could not tell: the search's
            left += np.int64(route == 0.0)
    return left
