"""The mesh collider's clear sides: a half-space of each cell that no triangle reaches.

The kernels skip the crossing search for a segment on the clear sides of its
cells, so these tests check the promise the skip rests on (every triangle
listed in a cell lies below its plane; for a closed mesh the part above is
outside) and that the kernels give the same positions with and without it.
"""

from __future__ import annotations

import numpy as np
import trimesh

from clothsim.solver.colliders.meshgrid import G_CELL0, G_DIMS, G_H, G_ORIGIN, G_STATUS0
from clothsim.solver.colliders.meshslab import SLAB_SHIFT

from clothsim.solver.colliders.mesh import settle_meshes

from .test_mesh_collider import control, face_distance, planes, run, shape, sphere, square, static, winding


def torus():
    m = trimesh.creation.torus(major_radius=0.6, minor_radius=0.2)
    return shape(m.vertices, m.faces, True)


def cell_slabs(packed, k):
    """[(cell (ix, iy, iz), its triangles, n, w)] for every cell of mesh k with a slab"""
    g = packed["mesh_grid"][k]
    nx, ny, nz = g[G_DIMS:G_DIMS + 3].astype(int)
    c0, s0 = int(g[G_CELL0]), int(g[G_STATUS0])
    cells, items, slabs = packed["mesh_cells"], packed["mesh_items"], packed["mesh_slabs"]
    out = []
    for local in range(nx * ny * nz):
        r = int(items[s0 + local]) >> SLAB_SHIFT
        if r:
            ix, iy, iz = local % nx, (local // nx) % ny, local // (nx * ny)
            tris = items[cells[c0 + local]:cells[c0 + local + 1]]
            out.append(((ix, iy, iz), tris, slabs[r - 1, :3], slabs[r - 1, 3]))
    return out


def test_every_triangle_of_a_cell_lies_below_its_clear_side():
    packed = control([torus(), square(z=0.3, half=0.4)], static(k=2))._asdict()
    for k in range(2):
        rows = cell_slabs(packed, k)
        assert len(rows) > (50 if k == 0 else 3)  # the square's grid is 2 x 2 cells
        for _, tris, n, w in rows:
            corners = packed["mesh_tris"][tris, :9].reshape(-1, 3)
            assert np.all(corners @ n < w)
            assert abs(np.linalg.norm(n) - 1.0) < 1e-12


def test_the_clear_side_of_a_closed_mesh_cell_is_outside():
    """points of each clear side, in its cell, have winding number 0 about the torus"""
    packed = control([torus()], static())._asdict()
    g = packed["mesh_grid"][0]
    o, h = g[G_ORIGIN:G_ORIGIN + 3], g[G_H]
    rng = np.random.default_rng(5)
    rows = cell_slabs(packed, 0)
    points = []
    for cell, _, n, w in rows[::7]:
        p = o + (np.asarray(cell) + rng.uniform(0.0, 1.0, (40, 3))) * h
        points.append(p[p @ n >= w][:3])
    points = np.concatenate(points)
    assert len(points) > 100
    assert np.all(np.abs(winding(packed["mesh_tris"], points)) < 1e-6)


def settle_run(ctl, P, Q):
    settle_meshes(P, Q, np.ones(P.shape[1]), ctl, np.int64(0), np.int64(P.shape[1]), np.int64(0))
    return P


def without_slabs(ctl):
    return ctl._replace(mesh_slabs=np.zeros((0, 4)))


def test_the_kernels_move_points_as_they_would_without_the_clear_sides():
    """random short and long segments near a torus and an open square: the same
    positions, bit for bit, with the skip and without it (every cell searched)"""
    ctl = control([torus(), square(z=0.31, half=0.5)], static(friction=0.3, k=2))
    rng = np.random.default_rng(11)
    n = 6000
    start = rng.uniform(-0.85, 0.85, (n, 3)) * [1.0, 1.0, 0.45]
    end = start + rng.normal(size=(n, 3)) * rng.choice([0.002, 0.01, 0.05], size=(n, 1))
    L, P0 = planes(start), planes(end)
    fast = run(ctl, P0.copy(), L)
    full = run(without_slabs(ctl), P0.copy(), L)
    assert np.any(fast != P0)
    np.testing.assert_array_equal(fast, full)
    fast = settle_run(ctl, P0.copy(), L)
    full = settle_run(without_slabs(ctl), P0.copy(), L)
    assert np.any(fast != P0)
    np.testing.assert_array_equal(fast, full)


def test_points_resting_above_a_mesh_sphere_take_the_clear_side():
    """over a smooth mesh most points a few millimetres up are proved clear by their
    cells' slabs, and none of them ends inside (convex: exact face test)"""
    ball = sphere(radius=0.5, subdivisions=5)
    ctl = control([ball], static())
    rng = np.random.default_rng(2)
    d = rng.normal(size=(3000, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    start = d * (0.5 + rng.uniform(0.002, 0.006, (3000, 1)))
    end = start - d * rng.uniform(0.0, 0.008, (3000, 1))
    P = run(ctl, planes(end), planes(start)).T
    assert np.all(face_distance(ctl.mesh_tris, P) > 0.0)
    rows = cell_slabs(ctl._asdict(), 0)
    assert len(rows) > 0.8 * np.count_nonzero(np.diff(ctl.mesh_cells))
