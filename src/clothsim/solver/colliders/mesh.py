"""Triangle meshes: a point whose path crosses one is put back on the side it came from.

The meshes are packed once, in their rest pose, by :func:`pack_meshes` (see
:mod:`.meshgrid` for the arrays and their grid). Each substep a mesh k stands
in a rigid pose, a row of ``meshes`` float64 (T, K, POSE_FIELDS) for substep
slot s (row ``min(s, T-1)``): R_now (3x3, row-major), o_now [m], R_before,
o_before [m], friction, margin [m] (see :func:`pose_rows`). A world point is
``x = R @ x_rest + o``; "before" is the pose at the substep's start, "now"
at its end.

:func:`collide_meshes`: a free point's last position, carried by the mesh's
motion, ``q0 = R_before^T (L - o_before)``, and its position now,
``q1 = R_now^T (P - o_now)``, both in the rest frame, make a segment. At its
first crossing with a triangle (normal n) its position now is put on the
triangle's plane and ``margin`` off it on the side it came from (or as far
as q0 was, if nearer: a point resting within the margin does not bounce),
then moved toward q0 by the CS184 friction rule, q0 + (1 - friction)(S - q0),
which is friction relative to the mesh, and taken back to the world by the
now pose. Should that corrected segment q0 -> new cross another triangle
(a crease, where margin off one face is behind the next), the point stays at q0.

Open meshes are two-sided surfaces: every crossing counts. Closed meshes are
solids wound outward (:func:`pack_meshes` winds them): only crossings into
the solid count, so a point inside may leave, and then every point that
ends inside (it started there, or rounding let it slip) is pushed out to the
nearest surface point and ``margin`` beyond it, without friction. The inside
test is exact for any point in the mesh's box at the cost of one cell's
triangles: the inside flag of the point's cell centre, known from
:func:`pack_meshes`, flipped by each crossing of the segment from the point to
that centre (it stays in the cell, so only the cell's triangles can cross
it). Where that segment passes within rounding of an edge or corner the
answer is 'outside' (the point is left as it is that substep).

Each point keeps, per mesh, the triangle it last crossed (``mesh_hints``): a
resting point crosses the same one substep after substep, and that
triangle's clear prism (:mod:`.meshprism`) decides its segment at the cost
of two heights and six dot products, before any search, where it lies in
the prism. The answer is the search's: the prism holds no other triangle,
so a hint, right, stale or wrong, never changes where a point goes. A hint
that could not tell, where the point's own tests or the search then found
no crossing, is dropped (-1): a point that has left the surface and hovers
near it stops paying the hint pass every substep, and its next crossing
gives it a hint again.

:func:`settle_meshes` runs the same crossing test, in the now pose, without
friction, on the segment from the positions after the collider pass to the
positions after a later constraint pass.

All kernels skip points with non-finite coordinates (and meshes with a
non-finite pose), clamp every cell coordinate to the grid and the point range
to the arrays, and skip zero-area triangles, so no input indexes out of
bounds. They compile without fastmath (EXACT_OPTIONS): the NaN tests stay.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..shared import EXACT_OPTIONS
from .meshgrid import (BARY_TOL, G_CELL0, G_CLOSED, G_DIMS, G_H, G_HI, G_INV_H, G_NTRI, G_ORIGIN, G_STATUS0,
                       G_TRI0, INSIDE_BITS, NEAR, T_NORMAL, T_OFFSET, UNKNOWN, cell_coord, plane_slack, put_off)
from .meshhint import hint_pass
from .meshlook import look, look_settle
from .meshpose import frame as _frame
from .meshpose import is_rest
from .meshpose import to_rest as _to_rest
from .meshpose import to_world as _to_world
from .meshslab import clear_side, clear_sides, pack_meshes

POSE_FIELDS = 26
"""a pose row: R_now (9), o_now (3), R_before (9), o_before (3), friction, margin"""

def pose_rows(R_now, o_now, R_before, o_before, friction, margin) -> np.ndarray:
    """Pose rows (..., POSE_FIELDS) from rotations (..., 3, 3), offsets (..., 3) [m],
    frictions and margins [m] (scalars or (...,)): stack them to (T, K, 26) for
    the ``meshes`` field; a static mesh has T = 1 and now == before."""
    Rn, Rb = np.asarray(R_now, dtype=np.float64), np.asarray(R_before, dtype=np.float64)
    on, ob = np.asarray(o_now, dtype=np.float64), np.asarray(o_before, dtype=np.float64)
    lead = np.broadcast_shapes(Rn.shape[:-2], Rb.shape[:-2], on.shape[:-1], ob.shape[:-1],
                               np.shape(friction), np.shape(margin))
    out = np.empty(lead + (POSE_FIELDS,))
    out[..., 0:9] = np.broadcast_to(Rn, lead + (3, 3)).reshape(lead + (9,))
    out[..., 9:12] = np.broadcast_to(on, lead + (3,))
    out[..., 12:21] = np.broadcast_to(Rb, lead + (3, 3)).reshape(lead + (9,))
    out[..., 21:24] = np.broadcast_to(ob, lead + (3,))
    out[..., 24] = friction
    out[..., 25] = margin
    return out


def with_hints(packed: dict, points: int) -> dict:
    """The mesh fields of :func:`pack_meshes` with room for the hints of ``points``
    points (none yet: -1), for a simulation to keep from substep to substep."""
    return {**packed, "mesh_hints": np.full((len(packed["mesh_grid"]), points), -1, dtype=np.int32)}


def pack_poses(colliders, t0: float = 0.0, dt: float = 0.0, substeps: int = 1) -> np.ndarray:
    """The ``meshes`` field for a frame from ``t0`` of ``substeps`` substeps of ``dt``
    [s]: pose rows (T, K, 26) from objects with ``pivot``, ``animation`` (or None),
    ``friction`` and ``margin`` (the scene's mesh colliders)."""
    from .motion_rows import frame_poses_both, stack_slots

    rows = []
    for c in colliders:
        R, o, _ = frame_poses_both(c.animation, c.pivot, t0, dt, substeps)
        rows.append(pose_rows(R[1:], o[1:], R[:-1], o[:-1], c.friction, c.margin))
    return stack_slots(rows)


# --- a mesh's grid row, read once ----------------------------------------------------

@njit(**EXACT_OPTIONS, inline="always")
def _grid_scalars(g):
    """The fields of grid row ``g`` that the searches read, read once per mesh:
    (ox, oy, oz, hix, hiy, hiz, h, 1/h, nx, ny, nz, first cell, first inside flag,
    the plane slack [m] (:func:`.meshgrid.plane_slack`))."""
    return (g[G_ORIGIN], g[G_ORIGIN + 1], g[G_ORIGIN + 2], g[G_HI], g[G_HI + 1], g[G_HI + 2], g[G_H],
            g[G_INV_H], g[G_DIMS], g[G_DIMS + 1], g[G_DIMS + 2], g[G_CELL0], g[G_STATUS0], plane_slack(g))


WALK_REACH = 1e-6
"""how far beyond a segment's box (in units of the mesh's size plus a cell) the
crossing search looks: a crossing lies in the triangle (its bounds widened by
BARY_TOL of its size) and on the segment, so in a cell both boxes overlap; this
covers the widening and the rounding of the walk. Much less than a margin: the
search reads the cells the segment passes, not their neighbours."""


@njit(**EXACT_OPTIONS, inline="always")
def _reach(g):
    """the crossing search's reach [m] for grid row ``g`` (see WALK_REACH)"""
    extent = max(g[G_HI] - g[G_ORIGIN], g[G_HI + 1] - g[G_ORIGIN + 1], g[G_HI + 2] - g[G_ORIGIN + 2])
    return WALK_REACH * (max(extent, 0.0) + g[G_H])


# --- one triangle ------------------------------------------------------------------

@njit(**EXACT_OPTIONS, inline="always")
def _hit(tris, t, x0, y0, z0, dx, dy, dz, tol, entry_only, slack):
    """Where the segment (x0, y0, z0) -> + (dx, dy, dz) crosses triangle ``t``:
    (parameter s in [0, 1], or inf for none; the smallest barycentric coordinate;
    the signed distance of the segment's end from the plane [m]). First the plane: a
    segment whose ends are both more than ``slack`` [m] off it on one side (for
    ``entry_only``, one that starts inside it or ends outside) is rejected at the
    cost of two dot products. Then Moller-Trumbore, its barycentric bounds widened
    by ``tol``; a zero-area triangle, a segment in its plane or a non-entering
    crossing when ``entry_only`` is none."""
    pnx, pny, pnz = tris[t, T_NORMAL], tris[t, T_NORMAL + 1], tris[t, T_NORMAL + 2]
    h0 = pnx * x0 + pny * y0 + pnz * z0 - tris[t, T_OFFSET]
    h1 = h0 + (pnx * dx + pny * dy + pnz * dz)
    if entry_only:
        if h0 < -slack or h1 > slack:
            return np.inf, 0.0, h1
    elif (h0 > slack and h1 > slack) or (h0 < -slack and h1 < -slack):
        return np.inf, 0.0, h1
    ax, ay, az = tris[t, 0], tris[t, 1], tris[t, 2]
    e1x, e1y, e1z = tris[t, 3] - ax, tris[t, 4] - ay, tris[t, 5] - az
    e2x, e2y, e2z = tris[t, 6] - ax, tris[t, 7] - ay, tris[t, 8] - az
    px = dy * e2z - dz * e2y
    py = dz * e2x - dx * e2z
    pz = dx * e2y - dy * e2x
    det = e1x * px + e1y * py + e1z * pz  # -d . ((b-a) x (c-a)): > 0 enters
    if not (det > 0.0 if entry_only else abs(det) > 0.0):
        return np.inf, 0.0, h1
    inv = 1.0 / det
    tx, ty, tz = x0 - ax, y0 - ay, z0 - az
    u = (tx * px + ty * py + tz * pz) * inv
    if not (u >= -tol and u <= 1.0 + tol):
        return np.inf, 0.0, h1
    qx = ty * e1z - tz * e1y
    qy = tz * e1x - tx * e1z
    qz = tx * e1y - ty * e1x
    v = (dx * qx + dy * qy + dz * qz) * inv
    if not (v >= -tol and u + v <= 1.0 + tol):
        return np.inf, 0.0, h1
    s = (e2x * qx + e2y * qy + e2z * qz) * inv
    if not (s >= 0.0 and s <= 1.0):
        return np.inf, 0.0, h1
    return s, min(u, v, 1.0 - u - v), h1


@njit(**EXACT_OPTIONS)
def _closest(tris, t, p):
    """The point of triangle ``t`` nearest to p (by the Voronoi regions of its corners
    and edges); NaN for a zero-area triangle, which then never wins."""
    ax, ay, az = tris[t, 0], tris[t, 1], tris[t, 2]
    abx, aby, abz = tris[t, 3] - ax, tris[t, 4] - ay, tris[t, 5] - az
    acx, acy, acz = tris[t, 6] - ax, tris[t, 7] - ay, tris[t, 8] - az
    apx, apy, apz = p[0] - ax, p[1] - ay, p[2] - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        return ax, ay, az
    bpx, bpy, bpz = p[0] - tris[t, 3], p[1] - tris[t, 4], p[2] - tris[t, 5]
    d3 = abx * bpx + aby * bpy + abz * bpz
    d4 = acx * bpx + acy * bpy + acz * bpz
    if d3 >= 0.0 and d4 <= d3:
        return tris[t, 3], tris[t, 4], tris[t, 5]
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        w = d1 / (d1 - d3)
        return ax + w * abx, ay + w * aby, az + w * abz
    cpx, cpy, cpz = p[0] - tris[t, 6], p[1] - tris[t, 7], p[2] - tris[t, 8]
    d5 = abx * cpx + aby * cpy + abz * cpz
    d6 = acx * cpx + acy * cpy + acz * cpz
    if d6 >= 0.0 and d5 <= d6:
        return tris[t, 6], tris[t, 7], tris[t, 8]
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        w = d2 / (d2 - d6)
        return ax + w * acx, ay + w * acy, az + w * acz
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and d4 - d3 >= 0.0 and d5 - d6 >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return tris[t, 3] + w * (tris[t, 6] - tris[t, 3]), tris[t, 4] + w * (tris[t, 7] - tris[t, 4]), tris[t, 5] + w * (tris[t, 8] - tris[t, 5])
    den = 1.0 / (va + vb + vc)
    v, w = vb * den, vc * den
    return ax + v * abx + w * acx, ay + v * aby + w * acy, az + v * abz + w * acz


# --- one mesh ------------------------------------------------------------------

@njit(**EXACT_OPTIONS, inline="always")
def _first_crossing(tris, cells, items, G, x0, y0, z0, x1, y1, z1, reach, entry_only):
    """The first crossing of the segment q0 -> q1 (rest frame, finite) with the mesh
    of grid scalars ``G`` (:func:`_grid_scalars`): (segment parameter, triangle or -1,
    triangles tried, whether q1 is more than the slack off every tried triangle's
    plane on its outer side).

    The segment is clipped to the mesh's box grown by ``reach`` [m] and walked in
    pieces at most a cell long; each piece tries the triangles of the cells its box,
    grown by ``reach``, overlaps, and the walk stops at the first piece that holds
    the best crossing so far. Without a crossing the walk has tried every triangle
    of q1's cell (or q1 is outside the mesh's box). Inlined in the kernels: no call,
    no reference counts."""
    ox, oy, oz, hx, hy, hz, _, inv, nx, ny, nz, c0f, _, slack = G
    lox, loy, loz = ox - reach, oy - reach, oz - reach
    hix, hiy, hiz = hx + reach, hy + reach, hz + reach
    best, best_t, tested, outer = np.inf, -1, 0, True
    if (max(x0, x1) < lox or min(x0, x1) > hix or max(y0, y1) < loy or min(y0, y1) > hiy
            or max(z0, z1) < loz or min(z0, z1) > hiz):
        return best, best_t, tested, outer
    dx, dy, dz = x1 - x0, y1 - y0, z1 - z0
    slack = slack + 1e-12 * (abs(x0) + abs(y0) + abs(z0) + abs(dx) + abs(dy) + abs(dz))
    inx, iny = int(nx), int(ny)
    c0 = int(c0f)
    cell = G[6]
    ta, tb, pieces = 0.0, 1.0, 1
    if not (abs(dx) < cell and abs(dy) < cell and abs(dz) < cell):
        # a segment longer than a cell is clipped to the mesh's box and walked in
        # pieces; a shorter one (the common case) is one piece as it is (the cell
        # numbers are clamped to the grid), without the divisions
        if dx != 0.0:
            a, b = (lox - x0) / dx, (hix - x0) / dx
            ta, tb = max(ta, min(a, b)), min(tb, max(a, b))
        if dy != 0.0:
            a, b = (loy - y0) / dy, (hiy - y0) / dy
            ta, tb = max(ta, min(a, b)), min(tb, max(a, b))
        if dz != 0.0:
            a, b = (loz - z0) / dz, (hiz - z0) / dz
            ta, tb = max(ta, min(a, b)), min(tb, max(a, b))
        if not ta <= tb:
            return best, best_t, tested, outer
        cells_along = (tb - ta) * np.sqrt(dx * dx + dy * dy + dz * dz) * inv
        pieces = int(min(cells_along, nx + ny + nz)) + 1
    step = (tb - ta) / pieces
    for m in range(pieces):
        sa = ta + m * step
        sb = tb if m == pieces - 1 else sa + step
        ax, ay, az = x0 + sa * dx, y0 + sa * dy, z0 + sa * dz
        bx, by, bz = x0 + sb * dx, y0 + sb * dy, z0 + sb * dz
        ix0 = cell_coord(min(ax, bx) - reach, ox, inv, nx)
        ix1 = cell_coord(max(ax, bx) + reach, ox, inv, nx)
        iy0 = cell_coord(min(ay, by) - reach, oy, inv, ny)
        iy1 = cell_coord(max(ay, by) + reach, oy, inv, ny)
        iz0 = cell_coord(min(az, bz) - reach, oz, inv, nz)
        iz1 = cell_coord(max(az, bz) + reach, oz, inv, nz)
        for iz in range(iz0, iz1 + 1):
            for iy in range(iy0, iy1 + 1):
                row = c0 + (iz * iny + iy) * inx
                for j in range(cells[row + ix0], cells[row + ix1 + 1]):
                    t = items[j]
                    tested += 1
                    s, _, h1 = _hit(tris, t, x0, y0, z0, dx, dy, dz, BARY_TOL, entry_only, slack)
                    outer = outer and h1 > slack
                    if s < best:
                        best, best_t = s, t
        if best <= sb:
            break
    return best, best_t, tested, outer


@njit(**EXACT_OPTIONS, inline="always")
def _put_off(tris, t, x0, y0, z0, x1, y1, z1, margin):
    """:func:`.meshgrid.put_off` on triangle t's plane"""
    plane = (tris[t, T_NORMAL], tris[t, T_NORMAL + 1], tris[t, T_NORMAL + 2], tris[t, T_OFFSET])
    return put_off(plane, (x0, y0, z0, x1, y1, z1), margin)


@njit(**EXACT_OPTIONS, inline="always")
def _inside(tris, cells, items, G, x, y, z):
    """Whether (x, y, z) (rest frame, finite) is inside the closed mesh of grid scalars
    ``G``: its cell's inside flag, which alone decides a cell without triangles,
    flipped by each crossing of the segment from the point to the cell's centre
    (each triangle's plane first). False outside the mesh's box, for a centre on the
    surface, and where the segment passes within rounding of an edge, a corner, the
    point or the centre."""
    ox, oy, oz, hx, hy, hz, h, inv, nx, ny, nz, c0f, s0f, slack = G
    if x < ox or x > hx or y < oy or y > hy or z < oz or z > hz:
        return False
    ix, iy, iz = cell_coord(x, ox, inv, nx), cell_coord(y, oy, inv, ny), cell_coord(z, oz, inv, nz)
    local = (iz * int(ny) + iy) * int(nx) + ix
    flag = items[int(s0f) + local] & INSIDE_BITS
    if flag == UNKNOWN:
        return False
    c = int(c0f) + local
    j0, j1 = cells[c], cells[c + 1]
    if j0 == j1:
        return flag == 1
    dx, dy, dz = ox + (ix + 0.5) * h - x, oy + (iy + 0.5) * h - y, oz + (iz + 0.5) * h - z
    slack = slack + 1e-12 * (abs(x) + abs(y) + abs(z) + abs(dx) + abs(dy) + abs(dz))
    odd = flag
    for j in range(j0, j1):
        s, bary, _ = _hit(tris, items[j], x, y, z, dx, dy, dz, BARY_TOL, False, slack)
        if s <= 1.0:
            if bary < BARY_TOL or s < 1e-12 or s > 1.0 - 1e-12:
                return False
            odd ^= 1
    return odd == 1


@njit(**EXACT_OPTIONS, inline="always")
def _cell_flag(items, G, x, y, z):
    """The inside flag of the cell of (x, y, z) in the closed mesh of grid scalars ``G``
    (0 outside the mesh's box).

    _outside_by_planes: a point q on the outer side of the plane of every triangle of
    its cell is outside whenever that flag is not 1 (inside). The segment from q to
    the centre stays in the cell, so only those triangles can cross it; if none does,
    q is where the centre is; if one does, the first crossing from q passes from a
    triangle's outer side to its inner side, into the solid, so q is outside. The
    kernel takes the planes from its crossing search, which tried every triangle of
    the cell of a point it did not move."""
    ox, oy, oz, hx, hy, hz, _, inv, nx, ny, nz, _, s0f, _ = G
    if x < ox or x > hx or y < oy or y > hy or z < oz or z > hz:
        return 0
    ix, iy, iz = cell_coord(x, ox, inv, nx), cell_coord(y, oy, inv, ny), cell_coord(z, oz, inv, nz)
    return items[int(s0f) + (iz * int(ny) + iy) * int(nx) + ix] & INSIDE_BITS


@njit(**EXACT_OPTIONS, inline="always")
def _clear(items, G, x0, y0, z0, x1, y1, z1, short, closed):
    """Whether the segment q0 -> q1 (rest frame, finite) surely meets nothing and ends
    where nothing is to be done: it is shorter than ``short`` [m] (a cell less the
    search's reach, on every axis), so its box lies in the 27 cells about q1's
    (clamped) cell, that cell's status lacks NEAR (none of them holds a triangle),
    and, for a closed mesh, its centre is not inside (a point inside is pushed out
    by the full path). One read per point: the kernels' fast path."""
    if not (abs(x1 - x0) < short and abs(y1 - y0) < short and abs(z1 - z0) < short):
        return False
    ox, oy, oz, _, _, _, _, inv, nx, ny, nz, _, s0f, _ = G
    ix, iy, iz = cell_coord(x1, ox, inv, nx), cell_coord(y1, oy, inv, ny), cell_coord(z1, oz, inv, nz)
    st = items[int(s0f) + (iz * int(ny) + iy) * int(nx) + ix]
    return (st & NEAR) == 0 and not (closed and (st & INSIDE_BITS) != 0)


@njit(**EXACT_OPTIONS)
def _nearest(tris, g, cells, items, q):
    """(the surface point nearest to q (rest frame, in the mesh's box), its triangle
    or -1): the cells within r of q's, r doubling until the best is nearer than r cells."""
    ox, oy, oz, h, inv = g[G_ORIGIN], g[G_ORIGIN + 1], g[G_ORIGIN + 2], g[G_H], g[G_INV_H]
    nx, ny, nz = g[G_DIMS], g[G_DIMS + 1], g[G_DIMS + 2]
    inx, iny, inz = int(nx), int(ny), int(nz)
    ix, iy, iz = cell_coord(q[0], ox, inv, nx), cell_coord(q[1], oy, inv, ny), cell_coord(q[2], oz, inv, nz)
    c0 = int(g[G_CELL0])
    best, best_t = np.inf, -1
    cx, cy, cz = q
    r = 1
    while True:
        for kz in range(max(iz - r, 0), min(iz + r, inz - 1) + 1):
            for ky in range(max(iy - r, 0), min(iy + r, iny - 1) + 1):
                row = c0 + (kz * iny + ky) * inx
                for j in range(cells[row + max(ix - r, 0)], cells[row + min(ix + r, inx - 1) + 1]):
                    t = items[j]
                    px, py, pz = _closest(tris, t, q)
                    d2 = (px - q[0]) ** 2 + (py - q[1]) ** 2 + (pz - q[2]) ** 2
                    if d2 < best:
                        best, best_t, cx, cy, cz = d2, t, px, py, pz
        if (best_t >= 0 and np.sqrt(best) <= r * h) or r >= max(inx, iny, inz):
            return (cx, cy, cz), best_t
        r *= 2


@njit(**EXACT_OPTIONS)
def _push_out(tris, g, cells, items, q, margin):
    """For q inside the closed mesh of row ``g``: (the nearest surface point, ``margin``
    [m] beyond it away from q, True), or along the nearest triangle's outward normal
    where that point would still be inside; (q, False) where no triangle is found.
    Called only for points found inside, so its call costs nothing in the common case."""
    c, t = _nearest(tris, g, cells, items, q)
    if t < 0:
        return q, False
    dx, dy, dz = c[0] - q[0], c[1] - q[1], c[2] - q[2]
    length = np.sqrt(dx * dx + dy * dy + dz * dz)
    nx, ny, nz = tris[t, T_NORMAL], tris[t, T_NORMAL + 1], tris[t, T_NORMAL + 2]
    if length > 1e-12 * g[G_H]:
        out = (c[0] + margin * dx / length, c[1] + margin * dy / length, c[2] + margin * dz / length)
        if not _inside(tris, cells, items, _grid_scalars(g), out[0], out[1], out[2]):
            return out, True
    return (c[0] + margin * nx, c[1] + margin * ny, c[2] + margin * nz), True


# --- the kernels -----------------------------------------------------------------

@njit(**EXACT_OPTIONS, inline="always")
def _finite6(a, b, c, d, e, f):
    return (np.isfinite(a) and np.isfinite(b) and np.isfinite(c) and np.isfinite(d) and np.isfinite(e)
            and np.isfinite(f))


@njit(**EXACT_OPTIONS, inline="always")
def _misses_box(G, x0, y0, z0, x1, y1, z1, reach):
    """Whether the box of the segment, grown by ``reach`` [m], misses the mesh's box:
    the cheap test the kernels make before any search."""
    return (max(x0, x1) + reach < G[0] or min(x0, x1) - reach > G[3]
            or max(y0, y1) + reach < G[1] or min(y0, y1) - reach > G[4]
            or max(z0, z1) + reach < G[2] or min(z0, z1) - reach > G[5])


@njit(**EXACT_OPTIONS, inline="always")
def _tri_range(g, tris, prisms):
    """(first, end) of the rows of ``mesh_tris`` that hold the triangles of grid row
    ``g``'s mesh and have a prism: the hints outside it are not tried."""
    first = max(int(g[G_TRI0]), 0)
    return first, max(min(first + int(g[G_NTRI]), tris.shape[0], prisms.shape[0]), first)


@njit(**EXACT_OPTIONS)
def _pose(meshes, grid, s, k):
    """The pose row of mesh k for substep slot s, or an empty one when it is not finite
    (or the arrays disagree)."""
    row = min(max(s, 0), meshes.shape[0] - 1)
    m = meshes[row, k]
    if m.shape[0] < POSE_FIELDS or not np.all(np.isfinite(m[:POSE_FIELDS])):
        return m[:0]
    return m


@njit(**EXACT_OPTIONS)
def collide_meshes(P, L, free, control, lo, hi, s):
    """Points ``lo:hi`` of the (3, N) positions ``P`` [m] whose path since their last
    positions ``L``, in each mesh's frame, crosses the mesh, put back on the side they
    came from with friction relative to the mesh; points inside a closed mesh pushed
    out (see the module's docstring). ``free`` (N,): 0.0 for pinned points, which
    stay. ``control``: a named tuple with ``meshes`` (T, K, 26) pose rows or None
    (then nothing, the branch pruned), ``mesh_tris``, ``mesh_grid``, ``mesh_cells``,
    ``mesh_items`` from :func:`pack_meshes`; ``s`` the substep slot."""
    _collide_meshes(P, L, free, control.meshes, control, lo, hi, s)


@njit(**EXACT_OPTIONS)
def _collide_meshes(P, L, free, meshes, control, lo, hi, s):
    """The body of :func:`collide_meshes`, with ``control.meshes`` as ``meshes``, so that
    numba prunes it when that is None. Per point, no call: the searches are inlined,
    and each triangle's plane rejects the points that stay on one side of it."""
    if meshes is None:
        return
    tris, grid, cells, items = control.mesh_tris, control.mesh_grid, control.mesh_cells, control.mesh_items
    slabs, prisms, hints = control.mesh_slabs, control.mesh_prisms, control.mesh_hints
    if meshes.shape[0] == 0:
        return
    lo = max(lo, 0)
    hi = min(hi, P.shape[1], L.shape[1], free.shape[0])
    need = np.empty(max(hi - lo, 0), dtype=np.bool_)
    listed = np.empty(need.shape[0], dtype=np.int64)
    masks = np.empty((need.shape[0] + 63) // 64, dtype=np.uint64)
    for k in range(min(meshes.shape[1], grid.shape[0])):
        m = _pose(meshes, grid, s, k)
        if m.shape[0] == 0:
            continue
        g = grid[k]
        G = _grid_scalars(g)
        reach = _reach(g)
        now, before = _frame(m, 0), _frame(m, 12)
        keep = 1.0 - min(max(m[24], 0.0), 1.0)
        margin = max(m[25], 0.0)
        closed = g[G_CLOSED] != 0.0
        short = g[G_H] - 2.0 * reach
        first, last = _tri_range(g, tris, prisms)
        hinted = min(hi, hints.shape[1]) if k < hints.shape[0] else 0  # the points below keep hints
        count = look(P, L, free, lo, (before, now), G, (reach, short, closed, False), items, need, listed)
        if count == 0:
            continue
        left = hint_pass(P, L, (prisms, hints, k, first, last, hinted, closed), (before, now), G,
                         (margin, keep, True), lo, (need, listed[:count]))
        # the clear sides of the cells of the points left, tested in vector code first
        clear_sides(listed, left, (L, P, lo), (before, now), (items, slabs, G), closed, masks)
        plain = is_rest(before) and is_rest(now)
        for i in range(left):
            p = lo + listed[i]
            if (masks[i >> 6] >> np.uint64(i & 63)) & np.uint64(1):
                if p < hinted:
                    hints[k, p] = -1  # a hint that could not tell: see the module's docstring
                continue
            # the look listed the point, so its segment is finite, meets the mesh's box
            # and does not end quietly (what _clear tests): those tests are not made
            # again. A mesh in its rest pose is read as it stands (see look)
            if plain:
                x0, y0, z0 = L[0, p], L[1, p], L[2, p]
                x1, y1, z1 = P[0, p], P[1, p], P[2, p]
            else:
                x0, y0, z0 = _to_rest(before, L[0, p], L[1, p], L[2, p])
                x1, y1, z1 = _to_rest(now, P[0, p], P[1, p], P[2, p])
            if clear_side(items, slabs, G, x0, y0, z0, x1, y1, z1, closed):
                if p < hinted:
                    hints[k, p] = -1  # a hint that could not tell: see the module's docstring
                continue
            _, t, _, outer = _first_crossing(tris, cells, items, G, x0, y0, z0, x1, y1, z1, reach, closed)
            moved = t >= 0
            if p < hinted:
                hints[k, p] = t  # the triangle crossed, or -1 where none is
            x, y, z = x1, y1, z1
            if moved:
                sx, sy, sz = _put_off(tris, t, x0, y0, z0, x1, y1, z1, margin)
                x, y, z = x0 + keep * (sx - x0), y0 + keep * (sy - y0), z0 + keep * (sz - z0)
                if clear_side(items, slabs, G, x0, y0, z0, x, y, z, closed):
                    wx, wy, wz = _to_world(now, x, y, z)  # crosses nothing, ends outside
                    P[0, p], P[1, p], P[2, p] = wx, wy, wz
                    continue
                _, again, _, _ = _first_crossing(tris, cells, items, G, x0, y0, z0, x, y, z, reach, closed)
                if again >= 0:
                    x, y, z = x0, y0, z0
            # a point that crossed nothing and is off every plane of its cell on the outer
            # side is outside unless its cell's centre is inside (see _outside_by_planes)
            skip = not closed or (not moved and outer and _cell_flag(items, G, x, y, z) != 1)
            if not skip and _inside(tris, cells, items, G, x, y, z):
                q, pushed = _push_out(tris, g, cells, items, (x, y, z), margin)
                x, y, z = q
                moved = moved or pushed
            if moved:
                wx, wy, wz = _to_world(now, x, y, z)
                P[0, p], P[1, p], P[2, p] = wx, wy, wz


@njit(**EXACT_OPTIONS)
def settle_meshes(P, Q, free, control, lo, hi, s):
    """Points ``lo:hi`` whose move from ``Q`` (after the collider pass, outside) to
    ``P`` (after a later pass) [m], both (3, N), crosses a mesh in its now pose, put
    back at the crossing, margin off on Q's side, without friction. ``free`` and
    ``control`` as in :func:`collide_meshes`."""
    _settle_meshes(P, Q, free, control.meshes, control, lo, hi, s)


@njit(**EXACT_OPTIONS)
def _settle_meshes(P, Q, free, meshes, control, lo, hi, s):
    """The body of :func:`settle_meshes`, with ``control.meshes`` as ``meshes``, so that
    numba prunes it when that is None. A point the later pass did not move (most of
    them) is skipped by the vector pass, and the hinted ones are settled in a pass
    of their own, as in :func:`_collide_meshes`."""
    if meshes is None:
        return
    tris, grid, cells, items = control.mesh_tris, control.mesh_grid, control.mesh_cells, control.mesh_items
    slabs, prisms, hints = control.mesh_slabs, control.mesh_prisms, control.mesh_hints
    if meshes.shape[0] == 0:
        return
    lo = max(lo, 0)
    hi = min(hi, P.shape[1], Q.shape[1], free.shape[0])
    need = np.empty(max(hi - lo, 0), dtype=np.bool_)
    listed = np.empty(need.shape[0], dtype=np.int64)
    for k in range(min(meshes.shape[1], grid.shape[0])):
        m = _pose(meshes, grid, s, k)
        if m.shape[0] == 0:
            continue
        g = grid[k]
        G = _grid_scalars(g)
        reach = _reach(g)
        now = _frame(m, 0)
        margin = max(m[25], 0.0)
        closed = g[G_CLOSED] != 0.0
        short = g[G_H] - 2.0 * reach
        first, last = _tri_range(g, tris, prisms)
        hinted = min(hi, hints.shape[1]) if k < hints.shape[0] else 0
        # the cells' quiet test as the loop below makes it, for an open mesh
        count = look_settle(P, Q, free, lo, (now, now), G, (reach, short, False, True), items, (need, listed),
                            (hints, k, first, last, hinted))
        if count == 0:
            continue
        # no friction: the placement is the surface point, as below
        left = hint_pass(P, Q, (prisms, hints, k, first, last, hinted, closed), (now, now), G,
                         (margin, 1.0, False), lo, (need, listed[:count]))
        for i in range(left):
            p = lo + listed[i]
            px, py, pz = P[0, p], P[1, p], P[2, p]
            qx, qy, qz = Q[0, p], Q[1, p], Q[2, p]
            x0, y0, z0 = _to_rest(now, qx, qy, qz)
            x1, y1, z1 = _to_rest(now, px, py, pz)
            if not _finite6(x0, y0, z0, x1, y1, z1) or _misses_box(G, x0, y0, z0, x1, y1, z1, reach):
                continue
            if (_clear(items, G, x0, y0, z0, x1, y1, z1, short, False)
                    or clear_side(items, slabs, G, x0, y0, z0, x1, y1, z1, False)):
                if p < hinted:
                    hints[k, p] = -1
                continue
            _, t, _, _ = _first_crossing(tris, cells, items, G, x0, y0, z0, x1, y1, z1, reach, closed)
            if p < hinted:
                hints[k, p] = t
            if t < 0:
                continue
            x, y, z = _put_off(tris, t, x0, y0, z0, x1, y1, z1, margin)
            if not clear_side(items, slabs, G, x0, y0, z0, x, y, z, False):
                _, again, _, _ = _first_crossing(tris, cells, items, G, x0, y0, z0, x, y, z, reach, closed)
                if again >= 0:
                    x, y, z = x0, y0, z0
            wx, wy, wz = _to_world(now, x, y, z)
            P[0, p], P[1, p], P[2, p] = wx, wy, wz


@njit(**EXACT_OPTIONS)
def count_tests(P, L, free, control, lo, hi, s, out):
    """For the benchmark: the triangles :func:`collide_meshes` tries for each point of
    ``lo:hi`` (its first crossing search, over every mesh; a plane's early reject
    counts), written to ``out[lo:hi]``; moves nothing."""
    _count_tests(P, L, free, control.meshes, control, lo, hi, s, out)


@njit(**EXACT_OPTIONS)
def _count_tests(P, L, free, meshes, control, lo, hi, s, out):
    """The body of :func:`count_tests`, with ``control.meshes`` as ``meshes``, so that
    numba prunes it when that is None."""
    if meshes is None:
        return
    tris, grid, cells, items = control.mesh_tris, control.mesh_grid, control.mesh_cells, control.mesh_items
    hi = min(hi, P.shape[1], L.shape[1], free.shape[0], out.shape[0])
    for p in range(max(lo, 0), hi):
        out[p] = 0
    for k in range(min(meshes.shape[1], grid.shape[0])):
        m = _pose(meshes, grid, s, k)
        if m.shape[0] == 0:
            continue
        g = grid[k]
        G = _grid_scalars(g)
        reach = _reach(g)
        now, before = _frame(m, 0), _frame(m, 12)
        closed = g[G_CLOSED] != 0.0
        for p in range(max(lo, 0), hi):
            x0, y0, z0 = _to_rest(before, L[0, p], L[1, p], L[2, p])
            x1, y1, z1 = _to_rest(now, P[0, p], P[1, p], P[2, p])
            if free[p] != 0.0 and _finite6(x0, y0, z0, x1, y1, z1):
                out[p] += _first_crossing(tris, cells, items, G, x0, y0, z0, x1, y1, z1, reach, closed)[2]


__all__ = ["POSE_FIELDS", "collide_meshes", "count_tests", "pack_meshes", "pose_rows", "settle_meshes",
           "with_hints"]
