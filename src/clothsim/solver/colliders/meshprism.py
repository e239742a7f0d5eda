"""Each mesh triangle's clear prism: where a point's path is known to meet that triangle first.

A cloth resting on a mesh crosses its surface at almost every point in
contact, every substep, and each such point's search tries the triangles of
the cells its segment passes, their planes and Moller-Trumbore tests: that
search was most of what a draped cloth paid. Yet a resting point crosses
the same triangle substep after substep. :func:`pack_prisms` gives every
triangle T of ``mesh_tris`` a row of ``mesh_prisms`` float64 (T, ROW_FIELDS):

- three edge planes in T's plane, inward unit normals m and offsets d [m],
  the offsets moved in by the inset (:func:`_inset`): a point q lies over T,
  away from its edges, where ``m . q >= d`` for all three (the prism over T
  along its normal, a little narrower than T);
- ``up`` and ``down`` [m]: how far above and below T's plane (``n . q -
  offset`` as in ``mesh_tris``) the prism over the whole of T holds no point
  of any other triangle of the mesh (the prism half an inset wider here), less
  the inset; capped at PRISM_CAP
  cells of the mesh's grid, 0 where another triangle reaches T's plane inside
  it (a mesh that cuts itself, a triangle given twice).
- then T's plane as in ``mesh_tris`` (its unit normal and offset, from column
  P_NORMAL), the height within which rounding could put a point on either side
  of T's plane as the search's crossing test sees it (P_ROUNDING,
  :func:`rounding_heights`), and zeros: the hint pass reads all it needs of a
  triangle as one row of 192 bytes.

A segment whose ends both lie in the narrower prism, between ``-down`` and
``up``, can meet no triangle but T, and none that a search's slack would
widen into it: it crosses T where the search's own test on T says so, and
nothing otherwise; above T it is outside a closed mesh (that part of the
prism is free of the surface and touches T's outer side). The kernels of
:mod:`.mesh` try that first for a point's last crossed triangle, its hint.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..shared import EXACT_OPTIONS
from ..simd import ROW_WIDTH
from .meshgrid import (G_CELL0, G_DIMS, G_H, G_HI, G_INV_H, G_NTRI, G_ORIGIN, G_TRI0, T_NORMAL, T_OFFSET,
                       cell_coord, plane_slack)

PRISM_FIELDS = 14
P_UP, P_DOWN = 12, 13
"""the columns of a row of ``mesh_prisms``: three edge planes (m (3), d each), up, down"""

P_NORMAL, P_OFFSET, P_ROUNDING = PRISM_FIELDS, PRISM_FIELDS + 3, PRISM_FIELDS + 4
"""the columns after the prism: the triangle's unit normal (3) and offset, as in
``mesh_tris``, then how far [m] a point's computed height over the triangle's
plane may be from the side the Moller-Trumbore test puts it on, for points in the
prism (:func:`rounding_heights`)"""

ROW_FIELDS = ROW_WIDTH
"""the columns of a row of ``mesh_prisms``: the prism, the plane, the rounding bound,
zeros; 192 bytes, which the hint pass reads as three whole vectors
(:func:`..simd.rows_to_columns`)"""

ROUNDING_FACTOR = 64.0
"""the safety factor of :func:`rounding_heights` over the few roundings each product
and sum of the tests it bounds can make"""

EDGE_INSET = 1e-5
"""how far the prism's sides stand inside the triangle's edges, in units of its
longest edge (plus WIDE_INSET of the mesh's size): far beyond the searches'
barycentric slack (1e-9 of a triangle) and the rounding of the tests, so a
segment in the prism never reaches a neighbour as the search sees it"""

WIDE_INSET = 1e-8
"""the part of the inset in units of the mesh's size: the barycentric slack of the
largest triangle beside a small one"""

PRISM_CAP = 1.0
"""the most ``up`` and ``down`` are, in cells of the mesh's grid: far more than a
resting point's height over the surface, and it bounds the cells read to build them"""


# --- building ----------------------------------------------------------------------

@njit(**EXACT_OPTIONS)
def _clip(poly, count, spare, a, b, c, d):
    """Clip the convex polygon ``poly[:count]`` (rows of 3) to ``a x + b y + c z >= d``
    into ``spare``; returns the new count."""
    out = 0
    for i in range(count):
        j = i + 1 if i + 1 < count else 0
        si = a * poly[i, 0] + b * poly[i, 1] + c * poly[i, 2] - d
        sj = a * poly[j, 0] + b * poly[j, 1] + c * poly[j, 2] - d
        if si >= 0.0:
            spare[out] = poly[i]
            out += 1
        if (si >= 0.0) != (sj >= 0.0):
            f = si / (si - sj)
            for k in range(3):
                spare[out, k] = poly[i, k] + f * (poly[j, k] - poly[i, k])
            out += 1
    return out


@njit(**EXACT_OPTIONS)
def _edge_planes(tris, t, wide, out):
    """The inward edge planes of triangle t into ``out[0:12]``, through its edges, and
    the inset [m] (EDGE_INSET of its longest edge plus ``wide``); 0 for a zero-area
    triangle or a sliver whose corners stand nearer their opposite edges than four
    insets (it gets no prism)."""
    nx, ny, nz = tris[t, T_NORMAL], tris[t, T_NORMAL + 1], tris[t, T_NORMAL + 2]
    longest = 0.0
    for e in range(3):
        a, b = 3 * e, 3 * ((e + 1) % 3)
        ex, ey, ez = tris[t, b] - tris[t, a], tris[t, b + 1] - tris[t, a + 1], tris[t, b + 2] - tris[t, a + 2]
        longest = max(longest, np.sqrt(ex * ex + ey * ey + ez * ez))
        mx, my, mz = ny * ez - nz * ey, nz * ex - nx * ez, nx * ey - ny * ex  # n x edge points inward
        length = np.sqrt(mx * mx + my * my + mz * mz)
        if not length > 0.0:
            return 0.0
        mx, my, mz = mx / length, my / length, mz / length
        out[4 * e], out[4 * e + 1], out[4 * e + 2] = mx, my, mz
        out[4 * e + 3] = mx * tris[t, a] + my * tris[t, a + 1] + mz * tris[t, a + 2]
    inset = EDGE_INSET * longest + wide
    for e in range(3):
        c = 3 * ((e + 2) % 3)
        if not (out[4 * e] * tris[t, c] + out[4 * e + 1] * tris[t, c + 1] + out[4 * e + 2] * tris[t, c + 2]
                - out[4 * e + 3] > 4.0 * inset):
            return 0.0
    return inset


@njit(**EXACT_OPTIONS)
def _beside(tris, t, u, edges, inset, cap, band):
    """Whether triangle u surely leaves T's prism free below the cap: all its corners
    outside one of T's edge planes (half the ``inset`` in), or all more than ``cap`` +
    ``band`` [m] above or below T's plane; the cheap test before the clip."""
    pnx, pny, pnz, w = tris[t, T_NORMAL], tris[t, T_NORMAL + 1], tris[t, T_NORMAL + 2], tris[t, T_OFFSET]
    high, low, out0, out1, out2 = 0, 0, 0, 0, 0
    for k in range(3):
        x, y, z = tris[u, 3 * k], tris[u, 3 * k + 1], tris[u, 3 * k + 2]
        h = pnx * x + pny * y + pnz * z - w
        high += h > cap + band
        low += h < -cap - band
        out0 += edges[0] * x + edges[1] * y + edges[2] * z < edges[3] + 0.5 * inset
        out1 += edges[4] * x + edges[5] * y + edges[6] * z < edges[7] + 0.5 * inset
        out2 += edges[8] * x + edges[9] * y + edges[10] * z < edges[11] + 0.5 * inset
    return high == 3 or low == 3 or out0 == 3 or out1 == 3 or out2 == 3


@njit(**EXACT_OPTIONS)
def _clearance(tris, t, u, edges, inset, poly, spare, band):
    """(how far above, how far below) T's plane [m] triangle u leaves T's prism free,
    less ``band``: inf on a side u does not reach, 0 where u reaches within ``band`` of
    the plane inside it. The prism here stands half the ``inset`` [m] inside T's
    edges (``edges``, through them), so that the neighbours that share an edge or a
    corner with T stay out of it, and half an inset outside the one the kernels
    test: farther than any slack the search gives a triangle."""
    count = 3
    for k in range(3):
        poly[k, 0], poly[k, 1], poly[k, 2] = tris[u, 3 * k], tris[u, 3 * k + 1], tris[u, 3 * k + 2]
    for e in range(3):
        count = _clip(poly, count, spare, edges[4 * e], edges[4 * e + 1], edges[4 * e + 2],
                      edges[4 * e + 3] + 0.5 * inset)
        poly, spare = spare, poly
        if count == 0:
            return np.inf, np.inf
    pnx, pny, pnz, w = tris[t, T_NORMAL], tris[t, T_NORMAL + 1], tris[t, T_NORMAL + 2], tris[t, T_OFFSET]
    hmin, hmax = np.inf, -np.inf
    for k in range(count):
        hv = pnx * poly[k, 0] + pny * poly[k, 1] + pnz * poly[k, 2] - w
        hmin, hmax = min(hmin, hv), max(hmax, hv)
    up = max(hmin - band, 0.0) if hmax >= -band else np.inf
    down = max(-hmax - band, 0.0) if hmin <= band else np.inf
    return up, down


@njit(**EXACT_OPTIONS)
def _fill_prisms(tris, g, cells, items, prisms):
    """The prism rows of the triangles of grid row ``g``'s mesh: each triangle against
    every triangle listed in the cells its capped prism's box overlaps (a triangle
    that reaches into the prism is listed in the cell that holds such a point)."""
    t0, nt = int(g[G_TRI0]), int(g[G_NTRI])
    ox, oy, oz, h, inv = g[G_ORIGIN], g[G_ORIGIN + 1], g[G_ORIGIN + 2], g[G_H], g[G_INV_H]
    nx, ny, nz = g[G_DIMS], g[G_DIMS + 1], g[G_DIMS + 2]
    inx, iny = int(nx), int(ny)
    c0 = int(g[G_CELL0])
    cap = PRISM_CAP * h
    extent = max(g[G_HI] - ox, g[G_HI + 1] - oy, g[G_HI + 2] - oz)
    wide = WIDE_INSET * (max(extent, 0.0) + h)
    slack = plane_slack(g)
    poly, spare = np.empty((8, 3)), np.empty((8, 3))
    edges = np.empty(12)
    lo, hi = np.empty(3), np.empty(3)
    for t in range(max(t0, 0), min(t0 + nt, tris.shape[0], prisms.shape[0])):
        prisms[t, :PRISM_FIELDS] = 0.0
        prisms[t, 3] = np.inf
        inset = _edge_planes(tris, t, wide, edges)
        if not inset > 0.0:
            continue
        band = inset + 4.0 * slack
        up, down = cap, cap
        lo[:], hi[:] = np.inf, -np.inf
        for k in range(3):
            for a in range(3):
                v, d = tris[t, 3 * k + a], cap * abs(tris[t, T_NORMAL + a])
                lo[a], hi[a] = min(lo[a], v - d), max(hi[a], v + d)
        ix0, ix1 = cell_coord(lo[0], ox, inv, nx), cell_coord(hi[0], ox, inv, nx)
        iy0, iy1 = cell_coord(lo[1], oy, inv, ny), cell_coord(hi[1], oy, inv, ny)
        iz0, iz1 = cell_coord(lo[2], oz, inv, nz), cell_coord(hi[2], oz, inv, nz)
        for iz in range(iz0, iz1 + 1):
            for iy in range(iy0, iy1 + 1):
                base = c0 + (iz * iny + iy) * inx
                for j in range(cells[base + ix0], cells[base + ix1 + 1]):
                    u = items[j]
                    if u != t and not _beside(tris, t, u, edges, inset, cap, band):
                        a, b = _clearance(tris, t, u, edges, inset, poly, spare, band)
                        up, down = min(up, a), min(down, b)
        for e in range(3):
            prisms[t, 4 * e:4 * e + 3] = edges[4 * e:4 * e + 3]
            prisms[t, 4 * e + 3] = edges[4 * e + 3] + inset
        prisms[t, P_UP], prisms[t, P_DOWN] = up, down


def pack_prisms(packed: dict) -> np.ndarray:
    """``mesh_prisms`` (T, ROW_FIELDS) for the arrays of :func:`.meshgrid.pack_grids`
    (an edge plane no point lies over, for a triangle without a prism), each row
    followed by its triangle's plane and rounding bound."""
    tris = packed["mesh_tris"]
    prisms = np.zeros((tris.shape[0], ROW_FIELDS))
    prisms[:, 3] = np.inf
    prisms[:, P_NORMAL:P_NORMAL + 3] = tris[:, T_NORMAL:T_NORMAL + 3]
    prisms[:, P_OFFSET] = tris[:, T_OFFSET]
    for g in packed["mesh_grid"]:
        _fill_prisms(tris, g, packed["mesh_cells"], packed["mesh_items"], prisms)
        t0, t1 = max(int(g[G_TRI0]), 0), min(int(g[G_TRI0] + g[G_NTRI]), tris.shape[0])
        prisms[t0:t1, P_ROUNDING] = rounding_heights(tris[t0:t1], PRISM_CAP * g[G_H])
    return prisms


def rounding_heights(tris: np.ndarray, cap: float) -> np.ndarray:
    """For each row of ``tris`` (``mesh_tris``, rest frame [m]) a height [m] beyond
    which a point's height over the triangle's plane, as the hint pass computes it
    (n . q - offset), has the sign that the Moller-Trumbore test of the search gives
    it, for any segment with both ends in the triangle's prism no more than ``cap``
    [m] off its plane: inf where the triangle has no area.

    The test's products are of the edges, the offset of a point from a corner and
    the segment, each rounded relative to its size (eps); its verdict on a side
    turns on twice the area times a height, so its error, in height, is eps times
    those sizes times L^2 / (2 area) (L the longest edge; bounded for a triangle
    with a prism, which slivers do not get). The height the hint pass computes
    is off by eps times the point's coordinates. ROUNDING_FACTOR times the sum
    of both is the bound."""
    eps = np.finfo(np.float64).eps
    a, b, c = tris[:, 0:3], tris[:, 3:6], tris[:, 6:9]
    longest = np.sqrt(np.max([np.sum((b - a) ** 2, axis=1), np.sum((c - b) ** 2, axis=1),
                              np.sum((a - c) ** 2, axis=1)], axis=0))
    twice_area = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        shape = np.where(twice_area > 0.0, longest * longest / twice_area, np.inf)
    reach = longest + 2.0 * cap  # a point's offset from a corner, a segment in the prism
    size = 3.0 * (np.max(np.abs(tris[:, 0:9]), axis=1) + reach)  # a point's coordinates, summed
    bound = ROUNDING_FACTOR * eps * (size + 3.0 * shape * reach)
    return np.where(np.isfinite(bound), bound, np.inf)
