"""Each mesh cell's clear side: a half-space of the cell that no triangle reaches.

Most points near a mesh do not cross it in a substep, and proving so by
testing each triangle of their cells costs more than the rest of the
substep. :func:`pack_meshes` adds to the grid of :mod:`.meshgrid` one row per
cell that holds triangles, ``mesh_slabs`` float64 (S, 4): a unit normal n and
an offset w [m] such that every point of every triangle listed in the cell
lies below the plane, ``n . x <= w - pad``. The cell's part above it,
``n . x >= w``, is then free of the surface, and for a closed mesh it is
outside the solid (checked at build time; a cell whose part above is inside,
or empty, gets no row). A segment whose ends both lie there, with its box
grown by the search's reach inside the one cell, meets no triangle and ends
outside: :func:`clear_side` decides that at the cost of two dot products, and
the kernels of :mod:`.mesh` then skip the search.

n is the mean of the unit normals of the cell's triangles, so on a smooth
surface the plane lies just above the surface (by how much the surface bends
within one triangle's reach): a point resting within that height goes the
full way. A cell's row is found by its status entry (see :mod:`.meshgrid`):
``status >> SLAB_SHIFT`` is its row plus one, 0 for none.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit

from ..shared import EXACT_OPTIONS
from .meshgrid import (CELL_PAD, G_CELL0, G_CLOSED, G_DIMS, G_H, G_HI, G_INV_H, G_ORIGIN, G_STATUS0, HOLDS,
                       INSIDE_BITS, T_NORMAL, _ray_x_crossing, cell_coord, pack_grids)
from .meshpose import to_rest
from .meshprism import pack_prisms

SLAB_SHIFT = 4
"""the status bits below a cell's slab number (inside flag, NEAR, HOLDS)"""

MAX_SLABS = 1 << 27
"""most slab rows over all meshes (the status entries are int32)"""


@njit(**EXACT_OPTIONS, inline="always")
def _strict_cell(v, origin, inv_h, n):
    """The cell number along one axis of ``v`` [m], or -1 outside 0..n-1 (and for NaN)."""
    f = (v - origin) * inv_h
    if not (f >= 0.0 and f < n):
        return -1
    return int(f)


@njit(**EXACT_OPTIONS, inline="always")
def _slab_holds(items, slabs, s0, local, x0, y0, z0, x1, y1, z1):
    """Whether both ends lie on the clear side of the cell ``local`` (status entry
    ``items[s0 + local]``), or the cell holds no triangle."""
    st = items[s0 + local]
    r = st >> SLAB_SHIFT
    if r == 0:
        return (st & HOLDS) == 0
    if r > slabs.shape[0]:
        return False
    a, b, c, w = slabs[r - 1, 0], slabs[r - 1, 1], slabs[r - 1, 2], slabs[r - 1, 3]
    return a * x0 + b * y0 + c * z0 >= w and a * x1 + b * y1 + c * z1 >= w


@njit(**EXACT_OPTIONS, inline="always")
def clear_side(items, slabs, G, x0, y0, z0, x1, y1, z1, closed):
    """Whether the segment q0 -> q1 (rest frame, finite) of the mesh of grid scalars
    ``G`` (see :func:`.mesh._grid_scalars`) lies in the grid, meets at most two cells
    along each axis and lies on the clear side of each of them that holds triangles
    (both ends do, so the whole segment does): then it meets no triangle, and is at
    least the slab's pad away from every one. For a closed mesh q1 must then be
    outside the solid: on its cell's clear side, or in a cell without triangles
    whose centre is outside."""
    ox, oy, oz, _, _, _, _, inv, nx, ny, nz, _, s0f, _ = G
    ax, bx = _strict_cell(x0, ox, inv, nx), _strict_cell(x1, ox, inv, nx)
    ay, by = _strict_cell(y0, oy, inv, ny), _strict_cell(y1, oy, inv, ny)
    az, bz = _strict_cell(z0, oz, inv, nz), _strict_cell(z1, oz, inv, nz)
    if ax < 0 or bx < 0 or ay < 0 or by < 0 or az < 0 or bz < 0:
        return False
    inx, iny, s0 = int(nx), int(ny), int(s0f)
    end = (bz * iny + by) * inx + bx
    if closed and (items[s0 + end] >> SLAB_SHIFT) == 0 and (items[s0 + end] & INSIDE_BITS) != 0:
        return False
    if ax == bx and ay == by and az == bz:  # the common case: one cell
        return _slab_holds(items, slabs, s0, end, x0, y0, z0, x1, y1, z1)
    if abs(ax - bx) > 1 or abs(ay - by) > 1 or abs(az - bz) > 1:
        return False
    return _cells_hold(items, slabs, s0, (inx, iny),
                       (min(ax, bx), max(ax, bx), min(ay, by), max(ay, by), min(az, bz), max(az, bz)),
                       (x0, y0, z0, x1, y1, z1))


@njit(**EXACT_OPTIONS)
def clear_sides(todo, count, ends, frames, grid, closed, masks):
    """:func:`clear_side` for the segments of points ``lo + todo[:count]`` that lie in one
    cell: bit j of ``masks[w]`` (uint64) is set where that of ``todo[64 w + j]``
    does and :func:`clear_side` finds it clear; a segment that meets more than one
    cell is left unset, for :func:`clear_side` itself. ``ends``: (L, P, lo), the
    segments' starts and ends (3, N) [m, world]; ``frames``: the mesh's poses (before,
    now; :func:`.meshpose.frame`); ``grid``: (items, slabs, G) as :func:`clear_side`
    takes them. The same tests in the same arithmetic, made for every point without a
    branch and or-ed into a word, sixty-four points a word, so that LLVM turns the
    loop into vector code that gathers the points, their status entries and slab
    rows (one by one in the kernels' loop, the test cost a third of it for the
    points hovering near a mesh: docs/performance.md). The turns into the rest
    frame are made for a mesh in its rest pose too: they change no comparison."""
    L, P, lo = ends
    before, now = frames
    items, slabs, G = grid
    ox, oy, oz, _, _, _, _, inv, nx, ny, nz, _, s0f, _ = G
    inx, iny, s0 = np.int64(nx), np.int64(ny), np.int64(s0f)
    rows = slabs.shape[0]
    if rows == 0:  # no cell has a clear side: clear_side decides every segment
        masks[:(count + 63) // 64] = 0
        return
    for w in range((count + 63) // 64):
        mask = np.uint64(0)
        for j in range(min(64, count - 64 * w)):
            # unsigned indices: no wrap-around selects in the vector code
            p = np.uint64(lo + todo[np.uint64(64 * w + j)])
            x0, y0, z0 = to_rest(before, L[0, p], L[1, p], L[2, p])
            x1, y1, z1 = to_rest(now, P[0, p], P[1, p], P[2, p])
            fx0, fy0, fz0 = (x0 - ox) * inv, (y0 - oy) * inv, (z0 - oz) * inv
            fx1, fy1, fz1 = (x1 - ox) * inv, (y1 - oy) * inv, (z1 - oz) * inv
            # _strict_cell's test for all six, each cell then read where it passes
            inside = ((fx0 >= 0.0) & (fx0 < nx) & (fy0 >= 0.0) & (fy0 < ny) & (fz0 >= 0.0) & (fz0 < nz)
                      & (fx1 >= 0.0) & (fx1 < nx) & (fy1 >= 0.0) & (fy1 < ny) & (fz1 >= 0.0) & (fz1 < nz))
            ax, ay, az = _whole(fx0, inside), _whole(fy0, inside), _whole(fz0, inside)
            bx, by, bz = _whole(fx1, inside), _whole(fy1, inside), _whole(fz1, inside)
            st = items[np.uint64(s0 + (bz * iny + by) * inx + bx)]
            r = np.int64(st >> SLAB_SHIFT)
            solid = closed & (r == 0) & ((st & INSIDE_BITS) != 0)
            k = np.uint64(min(max(r - 1, 0), rows - 1))  # any row where there is none: not used
            a, b, c, h = slabs[k, 0], slabs[k, 1], slabs[k, 2], slabs[k, 3]
            holds = (((r == 0) & ((st & HOLDS) == 0))
                     | ((r > 0) & (r <= rows) & (a * x0 + b * y0 + c * z0 >= h) & (a * x1 + b * y1 + c * z1 >= h)))
            one = (ax == bx) & (ay == by) & (az == bz)
            clear = inside & one & (solid ^ True) & holds
            mask |= np.uint64(1 if clear else 0) << np.uint64(j)
        masks[w] = mask


@njit(**EXACT_OPTIONS, inline="always")
def _whole(f, inside):
    """the cell number of a coordinate's grid position ``f`` that lies in the grid, or 0"""
    return np.int64(f if inside else 0.0)


@njit(**EXACT_OPTIONS)
def _cells_hold(items, slabs, s0, dims, span, seg):
    """:func:`_slab_holds` for the segment ``seg`` (x0, y0, z0, x1, y1, z1) in every cell
    of the inclusive ranges ``span`` (ix0, ix1, iy0, iy1, iz0, iz1) of a grid ``dims``
    (nx, ny) cells across: a call of its own, out of the kernels' loops, for a
    segment that crosses a cell face."""
    inx, iny = dims
    ix0, ix1, iy0, iy1, iz0, iz1 = span
    x0, y0, z0, x1, y1, z1 = seg
    for iz in range(iz0, iz1 + 1):
        for iy in range(iy0, iy1 + 1):
            for ix in range(ix0, ix1 + 1):
                if not _slab_holds(items, slabs, s0, (iz * iny + iy) * inx + ix, x0, y0, z0, x1, y1, z1):
                    return False
    return True


@njit(**EXACT_OPTIONS)
def _outside_by_ray(tris, g, cells, items, px, py, pz):
    """Whether (px, py, pz), in the mesh's grid, is outside the closed mesh of grid row
    ``g``: the parity of the crossings of the line along x through it, counted below
    px. A crossing lies in a cell of the line's row of cells, whose list holds its
    triangle; it is counted only in the cell that holds its x, so once."""
    nx, ny, nz = int(g[G_DIMS]), int(g[G_DIMS + 1]), int(g[G_DIMS + 2])
    ox, oy, oz, inv = g[G_ORIGIN], g[G_ORIGIN + 1], g[G_ORIGIN + 2], g[G_INV_H]
    iy, iz = cell_coord(py, oy, inv, ny), cell_coord(pz, oz, inv, nz)
    row = int(g[G_CELL0]) + (iz * ny + iy) * nx
    odd = 0
    for ix in range(nx):
        for m in range(cells[row + ix], cells[row + ix + 1]):
            x = _ray_x_crossing(tris, items[m], py, pz)
            if np.isfinite(x) and cell_coord(x, ox, inv, nx) == ix:
                if x == px:
                    return False
                if x < px:
                    odd ^= 1
    return odd == 0


@njit(**EXACT_OPTIONS)
def _fill_slabs(tris, g, cells, items, slabs, first):
    """The slab rows of the cells of grid row ``g`` from row ``first`` of ``slabs`` (S, 4)
    on, and their numbers in the cells' status entries; returns the next free row."""
    nx, ny, nz = int(g[G_DIMS]), int(g[G_DIMS + 1]), int(g[G_DIMS + 2])
    c0, s0 = int(g[G_CELL0]), int(g[G_STATUS0])
    ox, oy, oz, h = g[G_ORIGIN], g[G_ORIGIN + 1], g[G_ORIGIN + 2], g[G_H]
    extent = max(g[G_HI] - ox, g[G_HI + 1] - oy, g[G_HI + 2] - oz)
    pad = CELL_PAD * (max(extent, 0.0) + h)
    closed = g[G_CLOSED] != 0.0
    r = first
    for iz in range(nz):
        for iy in range(ny):
            for ix in range(nx):
                local = (iz * ny + iy) * nx + ix
                j0, j1 = cells[c0 + local], cells[c0 + local + 1]
                if j0 == j1 or r >= slabs.shape[0]:
                    continue
                a, b, c = 0.0, 0.0, 0.0
                for j in range(j0, j1):
                    t = items[j]
                    a += tris[t, T_NORMAL]
                    b += tris[t, T_NORMAL + 1]
                    c += tris[t, T_NORMAL + 2]
                length = np.sqrt(a * a + b * b + c * c)
                if not length > 0.25 * (j1 - j0):  # normals that disagree: no clear side worth having
                    continue
                a, b, c = a / length, b / length, c / length
                w = -np.inf
                for j in range(j0, j1):
                    t = items[j]
                    for k in range(3):
                        w = max(w, a * tris[t, 3 * k] + b * tris[t, 3 * k + 1] + c * tris[t, 3 * k + 2])
                w += pad
                # the cell's corner farthest along n, pulled toward the centre: in the clear part?
                cx, cy, cz = ox + (ix + 0.5) * h, oy + (iy + 0.5) * h, oz + (iz + 0.5) * h
                sx = cx + 0.45 * h * (1.0 if a > 0.0 else -1.0)
                sy = cy + 0.45 * h * (1.0 if b > 0.0 else -1.0)
                sz = cz + 0.45 * h * (1.0 if c > 0.0 else -1.0)
                if not a * sx + b * sy + c * sz > w:
                    continue
                if closed and not _outside_by_ray(tris, g, cells, items, sx, sy, sz):
                    continue
                slabs[r, 0], slabs[r, 1], slabs[r, 2], slabs[r, 3] = a, b, c, w
                r += 1
                items[s0 + local] |= np.int32(r << SLAB_SHIFT)
    return r


def pack_meshes(shapes: Sequence) -> dict | None:
    """The mesh fields of the solver's control group from objects with ``vertices``
    (V, 3) [m] in the rest pose, ``triangles`` (F, 3) and ``closed``; None when there
    are none: the grid's arrays (:func:`.meshgrid.pack_grids`), ``mesh_slabs``, the
    triangles' ``mesh_prisms`` (:mod:`.meshprism`) and ``mesh_hints`` int32 (K, 0):
    no point's hint kept (:func:`.mesh.with_hints` gives room for them)."""
    packed = pack_grids(shapes)
    if packed is None:
        return None
    cells, items = packed["mesh_cells"], packed["mesh_items"]
    busy = int(np.count_nonzero(np.diff(cells)))
    slabs = np.zeros((min(busy, MAX_SLABS), 4))
    used = 0
    for g in packed["mesh_grid"]:
        used = _fill_slabs(packed["mesh_tris"], g, cells, items, slabs, np.int64(used))
    packed["mesh_slabs"] = slabs[:used].copy()
    packed["mesh_prisms"] = pack_prisms(packed)
    packed["mesh_hints"] = np.full((len(packed["mesh_grid"]), 0), -1, dtype=np.int32)
    return packed
