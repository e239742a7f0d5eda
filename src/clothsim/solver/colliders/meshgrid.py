"""Triangle-mesh colliders packed into plain arrays: the triangles and a uniform grid per mesh.

:func:`pack_grids` turns the scene's meshes (in their rest pose) into the
arrays the kernels of :mod:`.mesh` read (:func:`.meshslab.pack_meshes` adds
each cell's clear side):

``mesh_tris`` float64 (T, TRI_FIELDS)
    the corners (ax, ay, az, bx, by, bz, cx, cy, cz) [m] of every triangle of
    every mesh, one mesh after another (each mesh's in the Morton order of their
    centroids, not the file's), then its plane: the unit normal
    (b-a) x (c-a) / |...| (at T_NORMAL, three values; zero for a zero-area
    triangle) and its offset n . a [m] (at T_OFFSET), so a point's signed
    distance from the plane is n . x - offset. A closed mesh is wound so that its
    signed volume is positive: each normal points out of the solid.
``mesh_grid`` float64 (K, GRID_FIELDS)
    one row per mesh, the fields at the indices named ``G_*`` below: the grid's
    corner (the low corner of the mesh's box) [m], its cell size h [m] and 1/h,
    its dims (nx, ny, nz), its first cell in ``mesh_cells``, its first triangle
    in ``mesh_tris`` and their count, the closed flag (1.0 or 0.0), the high
    corner of the mesh's box [m], and where its cells' inside flags start in
    ``mesh_items`` (-1 for an open mesh).
``mesh_cells`` int64 (C + 1,)
    CSR starts: cell c of mesh k is number ``mesh_grid[k, G_CELL0] + (iz*ny + iy)*nx + ix``
    and holds the triangles ``mesh_items[mesh_cells[c]:mesh_cells[c + 1]]``.
``mesh_items`` int32 (mesh_cells[-1] + C,)
    first the cells' triangle lists (global triangle numbers, rows of
    ``mesh_tris``): a triangle is listed in every cell its bounding box
    overlaps and its plane passes through (the cell grown by CELL_PAD). Then,
    for each mesh, one status entry per cell (from ``G_STATUS0``): its low two
    bits (``& INSIDE_BITS``) for a closed mesh 1 when the cell's centre is
    inside the solid, 0 when outside, 2 when the centre lies on the surface
    (unknown; the inside test of that cell then answers 'outside'), 0 for an
    open mesh; plus HOLDS when the cell holds a triangle and NEAR when it or
    one of its 26 neighbours does; above these bits (from ``meshslab.SLAB_SHIFT``) the cell's row in
    ``mesh_slabs`` plus one. A segment shorter than a cell that ends in a cell
    without NEAR meets no triangle: the kernels skip it at the cost of one read.

The cell size is CELL_OVER_EDGE times the mean edge length, enlarged where the
grid would have more than MAX_CELLS cells or its lists more than MAX_ITEMS
entries, so no mesh, however large or degenerate, makes a huge array.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit

from ..shared import EXACT_OPTIONS

CELL_OVER_EDGE = 0.5
"""cell size over the mean edge length of the mesh's triangles: at half an edge a
cell of a smooth mesh holds about four triangles and a short segment meets one
or two cells (at one edge, seven and two cells), which halves the triangles a
point near the surface tries; the results do not depend on it"""

MAX_CELLS = 1 << 22
"""most cells of one mesh's grid; a larger mesh gets coarser cells"""

MAX_ITEMS = 1 << 24
"""most entries of one mesh's cell lists; a mesh whose triangles would fill
more (a few huge triangles among tiny ones) gets coarser cells"""

TRI_FIELDS = 13
T_NORMAL, T_OFFSET = 9, 12
"""the columns of a row of ``mesh_tris``: the corners (9), the unit normal (3), the offset"""

GRID_FIELDS = 16
G_ORIGIN, G_H, G_INV_H, G_DIMS, G_CELL0, G_TRI0, G_NTRI, G_CLOSED, G_HI, G_STATUS0 = 0, 3, 4, 5, 8, 9, 10, 11, 12, 15
"""indices of the fields of a row of ``mesh_grid`` (G_ORIGIN, G_DIMS and G_HI start three values)"""

UNKNOWN = 2
"""a cell's inside flag when its centre lies on the surface"""

INSIDE_BITS = 3
"""the bits of a cell's status that hold its inside flag"""

NEAR = 4
"""the bit of a cell's status set when the cell or a neighbour holds a triangle"""

HOLDS = 8
"""the bit of a cell's status set when the cell holds a triangle"""

CELL_PAD = 1e-5
"""how far (in units of the mesh's size plus a cell) a cell is grown before the test
of a triangle's plane against it: well beyond the kernels' reach (WALK_REACH) and
the rounding of the test, so no triangle is left out of a cell it touches"""


PLANE_SLACK = 1e-6
"""a triangle's plane is taken to separate two points only where both are more than
this many cell sizes (plus rounding of their coordinates) off it on one side; the
exact test decides the rest"""

BARY_TOL = 1e-9
"""slack on a triangle's barycentric bounds in the crossing tests, so that a segment
through an edge or corner shared by two triangles crosses at least one of them"""


@njit(**EXACT_OPTIONS, inline="always")
def put_off(plane, seg, margin):
    """Where a point whose move q0 -> q1 (``seg``: x0, y0, z0, x1, y1, z1) crossed a
    triangle of ``plane`` (nx, ny, nz, offset [m]) goes: q1 put on the plane, as a
    plane collider puts it, then ``margin`` [m] off it on the side q0 came from, or
    only as far as q0 was if that is nearer (a point resting within the margin must
    not bounce off it). Friction alone (the caller's) takes tangential motion
    away, not the segment. The search and the hint blocks both place with it."""
    nx, ny, nz, w = plane
    x0, y0, z0, x1, y1, z1 = seg
    side = 1.0 if (x1 - x0) * nx + (y1 - y0) * ny + (z1 - z0) * nz < 0.0 else -1.0
    d0 = abs(x0 * nx + y0 * ny + z0 * nz - w)
    d1 = x1 * nx + y1 * ny + z1 * nz - w
    off = side * min(margin, d0) - d1
    return x1 + off * nx, y1 + off * ny, z1 + off * nz


@njit(**EXACT_OPTIONS, inline="always")
def plane_slack(g):
    """PLANE_SLACK [m] for grid row ``g``, with the rounding of coordinates as large
    as its box's: the searches' margin on each triangle's plane."""
    big = max(abs(g[G_ORIGIN]), abs(g[G_ORIGIN + 1]), abs(g[G_ORIGIN + 2]),
              abs(g[G_HI]), abs(g[G_HI + 1]), abs(g[G_HI + 2]))
    return PLANE_SLACK * g[G_H] + 1e-12 * big


# --- cells -----------------------------------------------------------------------

@njit(**EXACT_OPTIONS, inline="always")
def cell_coord(v, origin, inv_h, n):
    """The cell number along one axis of the coordinate ``v`` [m], clamped to 0..n-1;
    0 for NaN (the comparisons are false): never out of range, whatever ``v``."""
    f = (v - origin) * inv_h
    if not f > 0.0:
        return 0
    if f >= n - 1.0:
        return int(n) - 1
    return int(f)


@njit(**EXACT_OPTIONS)
def _tri_cells(tris, t, g):
    """The clamped cell ranges (ix0, ix1, iy0, iy1, iz0, iz1), inclusive, of the
    bounding box of triangle ``t`` in the grid row ``g``."""
    o0, o1, o2, inv = g[G_ORIGIN], g[G_ORIGIN + 1], g[G_ORIGIN + 2], g[G_INV_H]
    nx, ny, nz = g[G_DIMS], g[G_DIMS + 1], g[G_DIMS + 2]
    r = tris[t]
    x0, x1 = min(r[0], r[3], r[6]), max(r[0], r[3], r[6])
    y0, y1 = min(r[1], r[4], r[7]), max(r[1], r[4], r[7])
    z0, z1 = min(r[2], r[5], r[8]), max(r[2], r[5], r[8])
    return (cell_coord(x0, o0, inv, nx), cell_coord(x1, o0, inv, nx),
            cell_coord(y0, o1, inv, ny), cell_coord(y1, o1, inv, ny),
            cell_coord(z0, o2, inv, nz), cell_coord(z1, o2, inv, nz))


@njit(**EXACT_OPTIONS, inline="always")
def _plane_meets(tris, t, g, ix, iy, iz, pad):
    """Whether the plane of triangle ``t`` passes through cell (ix, iy, iz) of grid row
    ``g`` grown by ``pad`` [m] on every side: the distance of the cell's centre from
    the plane against the cell's half-extent along the normal. True for a zero-area
    triangle (normal zero), so that nothing finite is ever left out."""
    h = g[G_H]
    cx = g[G_ORIGIN] + (ix + 0.5) * h
    cy = g[G_ORIGIN + 1] + (iy + 0.5) * h
    cz = g[G_ORIGIN + 2] + (iz + 0.5) * h
    nx, ny, nz = tris[t, 9], tris[t, 10], tris[t, 11]
    d = abs(nx * cx + ny * cy + nz * cz - tris[t, 12])
    return not d > (0.5 * h + pad) * (abs(nx) + abs(ny) + abs(nz))


@njit(**EXACT_OPTIONS, inline="always")
def _cell_pad(g):
    """CELL_PAD [m] for grid row ``g``"""
    extent = max(g[G_HI] - g[G_ORIGIN], g[G_HI + 1] - g[G_ORIGIN + 1], g[G_HI + 2] - g[G_ORIGIN + 2])
    return CELL_PAD * (max(extent, 0.0) + g[G_H])


@njit(**EXACT_OPTIONS)
def _count_items(tris, g):
    """How many list entries the grid row ``g`` makes of its mesh's triangles."""
    total = 0
    t0, nt = int(g[G_TRI0]), int(g[G_NTRI])
    pad = _cell_pad(g)
    for t in range(t0, t0 + nt):
        ix0, ix1, iy0, iy1, iz0, iz1 = _tri_cells(tris, t, g)
        for iz in range(iz0, iz1 + 1):
            for iy in range(iy0, iy1 + 1):
                for ix in range(ix0, ix1 + 1):
                    total += _plane_meets(tris, t, g, ix, iy, iz, pad)
    return total


@njit(**EXACT_OPTIONS)
def _fill_cells(tris, g, cells, items, item0):
    """The CSR lists of the grid row ``g`` by a counting pass and a fill pass: writes
    ``cells[c0:c0 + ncells + 1]`` (starts, offset by ``item0``) and the entries of
    ``items`` from ``item0`` on."""
    nx, ny, nz = int(g[G_DIMS]), int(g[G_DIMS + 1]), int(g[G_DIMS + 2])
    c0, t0, nt = int(g[G_CELL0]), int(g[G_TRI0]), int(g[G_NTRI])
    ncells = nx * ny * nz
    pad = _cell_pad(g)
    count = np.zeros(ncells + 1, dtype=np.int64)
    for t in range(t0, t0 + nt):
        ix0, ix1, iy0, iy1, iz0, iz1 = _tri_cells(tris, t, g)
        for iz in range(iz0, iz1 + 1):
            for iy in range(iy0, iy1 + 1):
                for ix in range(ix0, ix1 + 1):
                    if _plane_meets(tris, t, g, ix, iy, iz, pad):
                        count[(iz * ny + iy) * nx + ix + 1] += 1
    for c in range(ncells):
        count[c + 1] += count[c]
    for c in range(ncells + 1):
        cells[c0 + c] = item0 + count[c]
    for t in range(t0, t0 + nt):
        ix0, ix1, iy0, iy1, iz0, iz1 = _tri_cells(tris, t, g)
        for iz in range(iz0, iz1 + 1):
            for iy in range(iy0, iy1 + 1):
                for ix in range(ix0, ix1 + 1):
                    if _plane_meets(tris, t, g, ix, iy, iz, pad):
                        c = (iz * ny + iy) * nx + ix
                        items[item0 + count[c]] = t
                        count[c] += 1


# --- inside flags of the cells of a closed mesh --------------------------------------

@njit(**EXACT_OPTIONS, inline="always")
def _edge_side(uy, uz, vy, vz, py, pz):
    """The side of point p of the line through u and v in the (y, z) plane, as +1 or
    -1, never 0: computed in one order of the ends whichever way the edge is walked
    (so two triangles sharing the edge see it the same), and with p moved by
    (eps, eps^2) when it lies on the line (simulation of simplicity)."""
    flip = 1.0
    if uy > vy or (uy == vy and uz > vz):
        uy, uz, vy, vz = vy, vz, uy, uz
        flip = -1.0
    e = (vy - uy) * (pz - uz) - (vz - uz) * (py - uy)
    if e == 0.0:
        # d/d(eps) of the cross product with p + (eps, eps^2): -(vz - uz), then (vy - uy)
        e = -(vz - uz) if vz != uz else (vy - uy)
    return flip if e > 0.0 else -flip


@njit(**EXACT_OPTIONS)
def _ray_x_crossing(tris, t, py, pz):
    """Where the line y = py, z = pz, along x, crosses triangle ``t``: its x [m], or
    NaN when it misses. A line through an edge or corner is counted in exactly the
    triangles a consistent perturbation of it crosses, so along a closed mesh the
    parity of the crossings is exact."""
    r = tris[t]
    area = (r[4] - r[1]) * (r[8] - r[2]) - (r[5] - r[2]) * (r[7] - r[1])
    if area == 0.0 or not np.isfinite(area):
        return np.nan
    s = 1.0 if area > 0.0 else -1.0
    if _edge_side(r[1], r[2], r[4], r[5], py, pz) != s:
        return np.nan
    if _edge_side(r[4], r[5], r[7], r[8], py, pz) != s:
        return np.nan
    if _edge_side(r[7], r[8], r[1], r[2], py, pz) != s:
        return np.nan
    # the plane's normal (b-a) x (c-a); its x part is the projected area, not 0
    e1x, e1y, e1z = r[3] - r[0], r[4] - r[1], r[5] - r[2]
    e2x, e2y, e2z = r[6] - r[0], r[7] - r[1], r[8] - r[2]
    ny = e1z * e2x - e1x * e2z
    nz = e1x * e2y - e1y * e2x
    return r[0] - (ny * (py - r[1]) + nz * (pz - r[2])) / area


@njit(**EXACT_OPTIONS)
def _fill_status(tris, g, cells, items, status0):
    """The inside flag of every cell of the closed mesh of grid row ``g``, written to
    ``items[status0:]``: for each row of cells along x, the crossings of the line
    through their centres, counted from the grid's low end (a triangle's crossing
    only in the cell that holds its x, so once)."""
    nx, ny, nz = int(g[G_DIMS]), int(g[G_DIMS + 1]), int(g[G_DIMS + 2])
    c0 = int(g[G_CELL0])
    ox, oy, oz, h, inv = g[G_ORIGIN], g[G_ORIGIN + 1], g[G_ORIGIN + 2], g[G_H], g[G_INV_H]
    xs = np.empty(64)
    for iz in range(nz):
        pz = oz + (iz + 0.5) * h
        for iy in range(ny):
            py = oy + (iy + 0.5) * h
            n = 0
            row = c0 + (iz * ny + iy) * nx
            for ix in range(nx):
                for m in range(cells[row + ix], cells[row + ix + 1]):
                    x = _ray_x_crossing(tris, items[m], py, pz)
                    if np.isfinite(x) and cell_coord(x, ox, inv, nx) == ix:
                        if n == xs.shape[0]:
                            grown = np.empty(2 * n)
                            grown[:n] = xs
                            xs = grown
                        xs[n] = x
                        n += 1
            for ix in range(nx):
                px = ox + (ix + 0.5) * h
                odd = 0
                flag = 0
                for m in range(n):
                    if abs(xs[m] - px) <= 1e-12 * h:
                        flag = UNKNOWN
                    elif xs[m] < px:
                        odd ^= 1
                items[status0 + (iz * ny + iy) * nx + ix] = flag if flag else odd


# --- packing ------------------------------------------------------------------

def _spread_bits(v: np.ndarray) -> np.ndarray:
    """10-bit integers with two zero bits put after each bit (for a Morton code)"""
    v = v.astype(np.uint64) & np.uint64(0x3FF)
    v = (v | (v << np.uint64(16))) & np.uint64(0x030000FF)
    v = (v | (v << np.uint64(8))) & np.uint64(0x0300F00F)
    v = (v | (v << np.uint64(4))) & np.uint64(0x030C30C3)
    v = (v | (v << np.uint64(2))) & np.uint64(0x09249249)
    return v


def _near_first(tris: np.ndarray) -> np.ndarray:
    """The triangles in the Morton order of their centroids: triangles that share a
    cell lie near in memory, so a point's search reads few cache lines."""
    if len(tris) < 2:
        return tris
    centre = (tris[:, 0:3] + tris[:, 3:6] + tris[:, 6:9]) / 3.0
    lo, hi = centre.min(axis=0), centre.max(axis=0)
    q = np.floor((centre - lo) / np.maximum(hi - lo, 1e-300) * 1023.0).clip(0, 1023)
    code = _spread_bits(q[:, 0]) | (_spread_bits(q[:, 1]) << np.uint64(1)) | (_spread_bits(q[:, 2]) << np.uint64(2))
    return tris[np.argsort(code, kind="stable")]


def _mesh_triangles(shape) -> tuple[np.ndarray, bool]:
    """(the (F, 9) corners, closed) of one shape, checked; a closed mesh wound outward;
    in the order of :func:`_near_first`."""
    v = np.asarray(shape.vertices, dtype=np.float64)
    f = np.asarray(shape.triangles, dtype=np.int64)
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3:
        raise ValueError("a mesh collider needs vertices (V, 3) and triangles (F, 3)")
    if not np.all(np.isfinite(v)):
        raise ValueError("a mesh collider's vertices must be finite")
    if f.size and (f.min() < 0 or f.max() >= len(v)):
        raise ValueError("a mesh collider's triangles name vertices it does not have")
    tris = v[f].reshape(-1, 9)
    closed = bool(shape.closed)
    if closed and len(tris):
        a, b, c = tris[:, 0:3], tris[:, 3:6], tris[:, 6:9]
        if np.einsum("ij,ij->", a, np.cross(b, c)) < 0.0:
            tris = np.concatenate([a, c, b], axis=1)
    return _near_first(tris), closed


def _with_planes(tris: np.ndarray) -> np.ndarray:
    """(F, TRI_FIELDS) rows from (F, 9) corners: each triangle's unit normal and offset
    added (zero for a zero-area triangle, which no kernel then crosses)"""
    a, b, c = tris[:, 0:3], tris[:, 3:6], tris[:, 6:9]
    n = np.cross(b - a, c - a)
    length = np.linalg.norm(n, axis=1)
    ok = length > 0.0
    n[ok] /= length[ok, None]
    n[~ok] = 0.0
    out = np.empty((len(tris), TRI_FIELDS))
    out[:, 0:9], out[:, T_NORMAL:T_NORMAL + 3] = tris, n
    out[:, T_OFFSET] = np.einsum("ij,ij->i", n, a)
    return out


def _grid_row(rows: np.ndarray, closed: bool, tri0: int) -> np.ndarray:
    """A grid row for one mesh's triangles (``rows`` (F, TRI_FIELDS), with their planes;
    cell offsets left for the caller), its cell size from the mean edge length,
    coarser where the caps ask for it."""
    tris = rows[:, :9]
    g = np.zeros(GRID_FIELDS)
    g[G_TRI0], g[G_NTRI], g[G_CLOSED], g[G_STATUS0] = tri0, len(tris), float(closed), -1.0
    if not len(tris):  # an inverted box: every query misses it
        g[G_ORIGIN:G_ORIGIN + 3], g[G_HI:G_HI + 3] = 1.0, -1.0
        g[G_H], g[G_INV_H], g[G_DIMS:G_DIMS + 3] = 1.0, 1.0, 1.0
        return g
    pts = tris.reshape(-1, 3)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    extent = hi - lo
    edges = np.linalg.norm((tris - tris[:, [3, 4, 5, 6, 7, 8, 0, 1, 2]]).reshape(-1, 3, 3), axis=2)
    h = CELL_OVER_EDGE * float(edges.mean())
    h = max(h, 1e-6 * float(extent.max()), 1e-9)
    g[G_ORIGIN:G_ORIGIN + 3], g[G_HI:G_HI + 3] = lo, hi
    while True:
        dims = np.floor(extent / h) + 1.0
        ncells = float(np.prod(dims))
        if ncells > MAX_CELLS:
            h *= (ncells / MAX_CELLS) ** (1.0 / 3.0) * 1.01
            continue
        g[G_H], g[G_INV_H], g[G_DIMS:G_DIMS + 3] = h, 1.0 / h, dims
        g[G_TRI0] = 0.0  # counted on this mesh's triangles alone
        if _count_items(rows, g) > MAX_ITEMS:
            h *= 2.0
            continue
        g[G_TRI0] = tri0
        return g


def _mark_near(g: np.ndarray, cells: np.ndarray, status: np.ndarray) -> None:
    """Sets HOLDS in ``status`` (the cells of grid row ``g``) for every cell that holds a
    triangle, and NEAR for those and every cell that touches one (faces, edges or
    corners)."""
    nx, ny, nz = (int(v) for v in g[G_DIMS:G_DIMS + 3])
    c0 = int(g[G_CELL0])
    busy = (np.diff(cells[c0:c0 + nx * ny * nz + 1]) > 0).reshape(nz, ny, nx)
    status |= np.where(busy.ravel(), HOLDS, 0).astype(status.dtype)
    for axis in range(3):  # dilation by one cell, one axis at a time
        grown = busy.copy()
        lo = [slice(None)] * 3
        hi = [slice(None)] * 3
        lo[axis], hi[axis] = slice(None, -1), slice(1, None)
        grown[tuple(lo)] |= busy[tuple(hi)]
        grown[tuple(hi)] |= busy[tuple(lo)]
        busy = grown
    status |= np.where(busy.ravel(), NEAR, 0).astype(status.dtype)


def pack_grids(shapes: Sequence) -> dict | None:
    """The mesh fields of the solver's control group from objects with ``vertices``
    (V, 3) [m] in the rest pose, ``triangles`` (F, 3) and ``closed``; None when there
    are none. Keys ``mesh_tris``, ``mesh_grid``, ``mesh_cells``, ``mesh_items``:
    see the module's docstring for their layout."""
    if not shapes:
        return None
    parts, rows = [], []
    tri0 = 0
    for shape in shapes:
        corners, closed = _mesh_triangles(shape)
        tris = _with_planes(corners)
        rows.append(_grid_row(tris, closed, tri0))
        parts.append(tris)
        tri0 += len(tris)
    mesh_tris = np.concatenate(parts, axis=0) if tri0 else np.zeros((0, TRI_FIELDS))
    grid = np.stack(rows)
    ncells = [int(np.prod(g[G_DIMS:G_DIMS + 3])) for g in grid]
    nitems = [_count_items(mesh_tris, g) for g in grid]
    grid[:, G_CELL0] = np.concatenate([[0], np.cumsum(ncells)[:-1]])
    cells = np.zeros(sum(ncells) + 1, dtype=np.int64)
    items = np.zeros(sum(nitems) + sum(ncells), dtype=np.int32)
    item0, status0 = 0, sum(nitems)
    for k, g in enumerate(grid):
        _fill_cells(mesh_tris, g, cells, items, np.int64(item0))
        item0 += nitems[k]
        g[G_STATUS0] = status0
        if g[G_CLOSED]:
            _fill_status(mesh_tris, g, cells, items, np.int64(status0))
        _mark_near(g, cells, items[status0:status0 + ncells[k]])
        status0 += ncells[k]
    return dict(mesh_tris=mesh_tris, mesh_grid=grid, mesh_cells=cells, mesh_items=items)
