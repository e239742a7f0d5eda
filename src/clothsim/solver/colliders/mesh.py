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
from .meshgrid import (G_CELL0, G_CLOSED, G_DIMS, G_H, G_HI, G_INV_H, G_ORIGIN, G_STATUS0, UNKNOWN,
                       cell_coord, pack_meshes)

POSE_FIELDS = 26
"""a pose row: R_now (9), o_now (3), R_before (9), o_before (3), friction, margin"""

BARY_TOL = 1e-9
"""slack on a triangle's barycentric bounds, so that a segment through an edge or
corner shared by two triangles crosses at least one of them"""


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


# --- one triangle ------------------------------------------------------------------

@njit(**EXACT_OPTIONS, inline="always")
def _hit(tris, t, q, d, tol, entry_only):
    """Where the segment q -> q + d crosses triangle ``t`` (Moller-Trumbore):
    (parameter s in [0, 1], or inf for none; the smallest barycentric coordinate;
    whether the segment enters, moving against the normal (b-a) x (c-a)). Barycentric
    bounds widened by ``tol``; a zero-area triangle, a segment in its plane or a
    non-entering crossing when ``entry_only`` is none."""
    ax, ay, az = tris[t, 0], tris[t, 1], tris[t, 2]
    e1x, e1y, e1z = tris[t, 3] - ax, tris[t, 4] - ay, tris[t, 5] - az
    e2x, e2y, e2z = tris[t, 6] - ax, tris[t, 7] - ay, tris[t, 8] - az
    dx, dy, dz = d
    px = dy * e2z - dz * e2y
    py = dz * e2x - dx * e2z
    pz = dx * e2y - dy * e2x
    det = e1x * px + e1y * py + e1z * pz  # -d . ((b-a) x (c-a)): > 0 enters
    if not (det > 0.0 if entry_only else abs(det) > 0.0):
        return np.inf, 0.0, False
    inv = 1.0 / det
    tx, ty, tz = q[0] - ax, q[1] - ay, q[2] - az
    u = (tx * px + ty * py + tz * pz) * inv
    if not (u >= -tol and u <= 1.0 + tol):
        return np.inf, 0.0, False
    qx = ty * e1z - tz * e1y
    qy = tz * e1x - tx * e1z
    qz = tx * e1y - ty * e1x
    v = (dx * qx + dy * qy + dz * qz) * inv
    if not (v >= -tol and u + v <= 1.0 + tol):
        return np.inf, 0.0, False
    s = (e2x * qx + e2y * qy + e2z * qz) * inv
    if not (s >= 0.0 and s <= 1.0):
        return np.inf, 0.0, False
    return s, min(u, v, 1.0 - u - v), det > 0.0


@njit(**EXACT_OPTIONS)
def _unit_normal(tris, t):
    """The unit normal (b-a) x (c-a) / |...| of triangle ``t`` (a crossed one: not zero-area)."""
    e1x, e1y, e1z = tris[t, 3] - tris[t, 0], tris[t, 4] - tris[t, 1], tris[t, 5] - tris[t, 2]
    e2x, e2y, e2z = tris[t, 6] - tris[t, 0], tris[t, 7] - tris[t, 1], tris[t, 8] - tris[t, 2]
    nx = e1y * e2z - e1z * e2y
    ny = e1z * e2x - e1x * e2z
    nz = e1x * e2y - e1y * e2x
    w = 1.0 / np.sqrt(nx * nx + ny * ny + nz * nz)
    return nx * w, ny * w, nz * w


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

@njit(**EXACT_OPTIONS)
def _first_crossing(tris, g, cells, items, q0, q1, reach, entry_only):
    """The first crossing of the segment q0 -> q1 (rest frame, finite) with the mesh
    of grid row ``g``: (segment parameter, triangle or -1, triangles tested).

    The segment is clipped to the mesh's box grown by ``reach`` [m] and walked in
    pieces at most a cell long; each piece tests the triangles of the cells its box,
    grown by ``reach``, overlaps, and the walk stops at the first piece that holds
    the best crossing so far."""
    x0, y0, z0 = q0
    x1, y1, z1 = q1
    lox, loy, loz = g[G_ORIGIN] - reach, g[G_ORIGIN + 1] - reach, g[G_ORIGIN + 2] - reach
    hix, hiy, hiz = g[G_HI] + reach, g[G_HI + 1] + reach, g[G_HI + 2] + reach
    if (max(x0, x1) < lox or min(x0, x1) > hix or max(y0, y1) < loy or min(y0, y1) > hiy
            or max(z0, z1) < loz or min(z0, z1) > hiz):
        return np.inf, -1, 0
    dx, dy, dz = x1 - x0, y1 - y0, z1 - z0
    ta, tb = 0.0, 1.0
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
        return np.inf, -1, 0
    ox, oy, oz, inv = g[G_ORIGIN], g[G_ORIGIN + 1], g[G_ORIGIN + 2], g[G_INV_H]
    nx, ny, nz = g[G_DIMS], g[G_DIMS + 1], g[G_DIMS + 2]
    inx, iny = int(nx), int(ny)
    c0 = int(g[G_CELL0])
    cells_along = (tb - ta) * np.sqrt(dx * dx + dy * dy + dz * dz) * inv
    pieces = int(min(cells_along, nx + ny + nz)) + 1
    step = (tb - ta) / pieces
    d = (dx, dy, dz)
    best, best_t, tested = np.inf, -1, 0
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
                    s, _, _ = _hit(tris, t, q0, d, BARY_TOL, entry_only)
                    if s < best:
                        best, best_t = s, t
        if best <= sb:
            break
    return best, best_t, tested


@njit(**EXACT_OPTIONS)
def _put_off(tris, t, q0, q1, s, margin):
    """Where a point whose move q0 -> q1 crossed triangle t (at parameter s) goes:
    q1 put on the triangle's plane, as a plane collider puts it, then ``margin`` [m]
    off it on the side q0 came from, or only as far as q0 was if that is nearer (a
    point resting within the margin must not bounce off it). Friction alone
    (the caller's) takes tangential motion away, not the segment."""
    nx, ny, nz = _unit_normal(tris, t)
    dx, dy, dz = q1[0] - q0[0], q1[1] - q0[1], q1[2] - q0[2]
    side = 1.0 if dx * nx + dy * ny + dz * nz < 0.0 else -1.0
    d0 = abs((q0[0] - tris[t, 0]) * nx + (q0[1] - tris[t, 1]) * ny + (q0[2] - tris[t, 2]) * nz)
    d1 = (q1[0] - tris[t, 0]) * nx + (q1[1] - tris[t, 1]) * ny + (q1[2] - tris[t, 2]) * nz
    off = side * min(margin, d0) - d1
    return q1[0] + off * nx, q1[1] + off * ny, q1[2] + off * nz


@njit(**EXACT_OPTIONS)
def _inside(tris, g, cells, items, q):
    """Whether q (rest frame, finite) is inside the closed mesh of grid row ``g``: its
    cell centre's inside flag, flipped by each crossing of the segment q -> centre.
    False outside the mesh's box, for a centre on the surface, and where the segment
    passes within rounding of an edge, a corner, q or the centre."""
    x, y, z = q
    if (x < g[G_ORIGIN] or x > g[G_HI] or y < g[G_ORIGIN + 1] or y > g[G_HI + 1]
            or z < g[G_ORIGIN + 2] or z > g[G_HI + 2]):
        return False
    ox, oy, oz, h, inv = g[G_ORIGIN], g[G_ORIGIN + 1], g[G_ORIGIN + 2], g[G_H], g[G_INV_H]
    nx, ny, nz = g[G_DIMS], g[G_DIMS + 1], g[G_DIMS + 2]
    ix, iy, iz = cell_coord(x, ox, inv, nx), cell_coord(y, oy, inv, ny), cell_coord(z, oz, inv, nz)
    local = (iz * int(ny) + iy) * int(nx) + ix
    flag = items[int(g[G_STATUS0]) + local]
    if flag == UNKNOWN:
        return False
    d = (ox + (ix + 0.5) * h - x, oy + (iy + 0.5) * h - y, oz + (iz + 0.5) * h - z)
    c = int(g[G_CELL0]) + local
    odd = flag
    for j in range(cells[c], cells[c + 1]):
        s, bary, _ = _hit(tris, items[j], q, d, BARY_TOL, False)
        if s <= 1.0:
            if bary < BARY_TOL or s < 1e-12 or s > 1.0 - 1e-12:
                return False
            odd ^= 1
    return odd == 1


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
    """(q, False), or where q is inside the closed mesh of row ``g`` (the nearest
    surface point, ``margin`` [m] beyond it away from q, True); along the nearest
    triangle's outward normal where that point would still be inside."""
    if not _inside(tris, g, cells, items, q):
        return q, False
    c, t = _nearest(tris, g, cells, items, q)
    if t < 0:
        return q, False
    dx, dy, dz = c[0] - q[0], c[1] - q[1], c[2] - q[2]
    length = np.sqrt(dx * dx + dy * dy + dz * dz)
    nx, ny, nz = _unit_normal(tris, t)
    if length > 1e-12 * g[G_H]:
        out = (c[0] + margin * dx / length, c[1] + margin * dy / length, c[2] + margin * dz / length)
        if not _inside(tris, g, cells, items, out):
            return out, True
    return (c[0] + margin * nx, c[1] + margin * ny, c[2] + margin * nz), True


# --- the kernels -----------------------------------------------------------------

@njit(**EXACT_OPTIONS, inline="always")
def _to_rest(m, o, x, y, z):
    """R^T (p - o) for R the row-major 3x3 at m[o:o+9] and offset m[o+9:o+12]."""
    px, py, pz = x - m[o + 9], y - m[o + 10], z - m[o + 11]
    return (m[o] * px + m[o + 3] * py + m[o + 6] * pz,
            m[o + 1] * px + m[o + 4] * py + m[o + 7] * pz,
            m[o + 2] * px + m[o + 5] * py + m[o + 8] * pz)


@njit(**EXACT_OPTIONS, inline="always")
def _to_world(m, o, q):
    """R q + o for R and o as in :func:`_to_rest`."""
    return (m[o] * q[0] + m[o + 1] * q[1] + m[o + 2] * q[2] + m[o + 9],
            m[o + 3] * q[0] + m[o + 4] * q[1] + m[o + 5] * q[2] + m[o + 10],
            m[o + 6] * q[0] + m[o + 7] * q[1] + m[o + 8] * q[2] + m[o + 11])


@njit(**EXACT_OPTIONS, inline="always")
def _finite3(q):
    return np.isfinite(q[0]) and np.isfinite(q[1]) and np.isfinite(q[2])


@njit(**EXACT_OPTIONS, inline="always")
def _misses_box(g, q0, q1, reach):
    """Whether the box of the segment q0 -> q1, grown by ``reach`` [m], misses the mesh's
    box: the cheap test the kernels make before any search (a call that takes the
    arrays costs more than the test)."""
    return (max(q0[0], q1[0]) + reach < g[G_ORIGIN] or min(q0[0], q1[0]) - reach > g[G_HI]
            or max(q0[1], q1[1]) + reach < g[G_ORIGIN + 1] or min(q0[1], q1[1]) - reach > g[G_HI + 1]
            or max(q0[2], q1[2]) + reach < g[G_ORIGIN + 2] or min(q0[2], q1[2]) - reach > g[G_HI + 2])


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
    numba prunes it when that is None."""
    if meshes is None:
        return
    tris, grid, cells, items = control.mesh_tris, control.mesh_grid, control.mesh_cells, control.mesh_items
    if meshes.shape[0] == 0:
        return
    lo = max(lo, 0)
    hi = min(hi, P.shape[1], L.shape[1], free.shape[0])
    for k in range(min(meshes.shape[1], grid.shape[0])):
        m = _pose(meshes, grid, s, k)
        if m.shape[0] == 0:
            continue
        g = grid[k]
        keep = 1.0 - min(max(m[24], 0.0), 1.0)
        margin = max(m[25], 0.0)
        closed = g[G_CLOSED] != 0.0
        for p in range(lo, hi):
            if free[p] == 0.0:
                continue
            q0 = _to_rest(m, 12, L[0, p], L[1, p], L[2, p])
            q1 = _to_rest(m, 0, P[0, p], P[1, p], P[2, p])
            if not (_finite3(q0) and _finite3(q1)) or _misses_box(g, q0, q1, margin):
                continue
            best, t, _ = _first_crossing(tris, g, cells, items, q0, q1, margin, closed)
            moved = t >= 0
            q = q1
            if moved:
                S = _put_off(tris, t, q0, q1, best, margin)
                q = (q0[0] + keep * (S[0] - q0[0]), q0[1] + keep * (S[1] - q0[1]), q0[2] + keep * (S[2] - q0[2]))
                _, again, _ = _first_crossing(tris, g, cells, items, q0, q, margin, closed)
                if again >= 0:
                    q = q0
            if closed:
                q, pushed = _push_out(tris, g, cells, items, q, margin)
                moved = moved or pushed
            if moved:
                w = _to_world(m, 0, q)
                P[0, p], P[1, p], P[2, p] = w[0], w[1], w[2]


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
    numba prunes it when that is None."""
    if meshes is None:
        return
    tris, grid, cells, items = control.mesh_tris, control.mesh_grid, control.mesh_cells, control.mesh_items
    if meshes.shape[0] == 0:
        return
    lo = max(lo, 0)
    hi = min(hi, P.shape[1], Q.shape[1], free.shape[0])
    for k in range(min(meshes.shape[1], grid.shape[0])):
        m = _pose(meshes, grid, s, k)
        if m.shape[0] == 0:
            continue
        g = grid[k]
        margin = max(m[25], 0.0)
        closed = g[G_CLOSED] != 0.0
        for p in range(lo, hi):
            if free[p] == 0.0:
                continue
            q0 = _to_rest(m, 0, Q[0, p], Q[1, p], Q[2, p])
            q1 = _to_rest(m, 0, P[0, p], P[1, p], P[2, p])
            if not (_finite3(q0) and _finite3(q1)) or _misses_box(g, q0, q1, margin):
                continue
            best, t, _ = _first_crossing(tris, g, cells, items, q0, q1, margin, closed)
            if t < 0:
                continue
            q = _put_off(tris, t, q0, q1, best, margin)
            _, again, _ = _first_crossing(tris, g, cells, items, q0, q, margin, closed)
            if again >= 0:
                q = q0
            w = _to_world(m, 0, q)
            P[0, p], P[1, p], P[2, p] = w[0], w[1], w[2]


@njit(**EXACT_OPTIONS)
def count_tests(P, L, free, control, lo, hi, s, out):
    """For the benchmark: the triangles :func:`collide_meshes` tests for each point of
    ``lo:hi`` (its first crossing search, over every mesh), written to ``out[lo:hi]``;
    moves nothing."""
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
        for p in range(max(lo, 0), hi):
            q0 = _to_rest(m, 12, L[0, p], L[1, p], L[2, p])
            q1 = _to_rest(m, 0, P[0, p], P[1, p], P[2, p])
            if free[p] != 0.0 and _finite3(q0) and _finite3(q1):
                out[p] += _first_crossing(tris, g, cells, items, q0, q1, max(m[25], 0.0), g[G_CLOSED] != 0.0)[2]


__all__ = ["POSE_FIELDS", "collide_meshes", "count_tests", "pack_meshes", "pose_rows", "settle_meshes"]
