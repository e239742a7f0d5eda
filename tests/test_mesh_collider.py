"""The triangle-mesh collider kernels (solver/colliders/mesh.py, meshgrid.py), on their own.

The kernels take the solver's Control (:func:`Ctl` sets its mesh fields). Positions are (3, N) coordinate planes [m].
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest
import trimesh

from clothsim.solver.colliders.mesh import (
    collide_meshes,
    count_tests,
    pack_meshes,
    pose_rows,
    settle_meshes,
)
from clothsim.solver.colliders.meshgrid import G_CELL0, G_DIMS, G_H, G_ORIGIN, G_STATUS0, INSIDE_BITS, NEAR
from clothsim.solver.groups import Control

MARGIN = 1e-3
EYE = np.eye(3)
ZERO = np.zeros(3)


def Ctl(**mesh_fields):
    """the solver's own Control with only the mesh fields set: a kernel compiled for a
    named tuple of this module would go into numba's cache with it, and a process that
    cannot import this module could not load that cache any more"""
    return Control(handle=-1, handle_pos=np.zeros(3), spheres=None, planes=None, boxes=None, moved_points=None,
                   moved_to=None, wind=None, **mesh_fields)


def shape(vertices, triangles, closed):
    return SimpleNamespace(vertices=np.asarray(vertices, float), triangles=np.asarray(triangles, np.int64),
                           closed=closed)


def control(shapes, poses):
    """a control group from shapes and pose rows (K, 26) or (T, K, 26)"""
    poses = np.asarray(poses, float)
    return Ctl(meshes=poses if poses.ndim == 3 else poses[None], **pack_meshes(shapes))


def static(friction=0.0, margin=MARGIN, k=1):
    return np.repeat(pose_rows(EYE, ZERO, EYE, ZERO, friction, margin)[None], k, axis=0)


def square(z=0.0, half=1.0):
    """an open horizontal square of two triangles at height z"""
    v = [[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]]
    return shape(v, [[0, 1, 2], [0, 2, 3]], closed=False)


def sphere(radius=1.0, subdivisions=3, center=(0.0, 0.0, 0.0)):
    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    return shape(m.vertices + np.asarray(center), m.faces, closed=True)


def planes(points):
    """(3, N) from (N, 3)"""
    return np.ascontiguousarray(np.asarray(points, float).T)


def run(ctl, P, L, s=0):
    free = np.ones(P.shape[1])
    collide_meshes(P, L, free, ctl, np.int64(0), np.int64(P.shape[1]), np.int64(s))
    return P


def face_distance(tris, points):
    """(N,) largest signed distance of each point to the planes of the faces of a convex
    mesh wound outward: > 0 outside, < 0 inside (exact for a convex solid)"""
    a, b, c = tris[:, 0:3], tris[:, 3:6], tris[:, 6:9]
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1)[:, None]
    return ((points[:, None, :] - a[None]) * n[None]).sum(axis=2).max(axis=1)


def brute_first_hit(tris, q0, q1, tol, entry_only):
    """(parameter, triangle) of the first crossing of each segment with any triangle,
    every triangle tried (numpy Moller-Trumbore); (inf, -1) for none. ``tol`` widens
    (> 0) or narrows (< 0) the barycentric bounds."""
    a, e1, e2 = tris[:, 0:3], tris[:, 3:6] - tris[:, 0:3], tris[:, 6:9] - tris[:, 0:3]
    d = (q1 - q0)[:, None, :]
    p = np.cross(d, e2[None])
    det = (e1[None] * p).sum(axis=2)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        tv = q0[:, None, :] - a[None]
        u = (tv * p).sum(axis=2) * inv
        q = np.cross(tv, e1[None])
        v = (d * q).sum(axis=2) * inv
        s = (e2[None] * q).sum(axis=2) * inv
    ok = (det > 0) if entry_only else (det != 0)
    ok &= (u >= -tol) & (u <= 1 + tol) & (v >= -tol) & (u + v <= 1 + tol) & (s >= 0) & (s <= 1)
    s = np.where(ok, s, np.inf)
    t = s.argmin(axis=1)
    best = s[np.arange(len(s)), t]
    return best, np.where(np.isfinite(best), t, -1)


def put_off_reference(tris, t, q0, q1, margin):
    """(N, 3) where the placement rule puts points that moved q0 -> q1 (N, 3) across
    triangles t (N,): q1 put on the triangle's plane, then min(margin, distance of q0
    from the plane) off it on q0's side (numpy, written apart from the kernel)"""
    a, b, c = tris[t, 0:3], tris[t, 3:6], tris[t, 6:9]
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1)[:, None]
    h0 = ((q0 - a) * n).sum(axis=1)
    h1 = ((q1 - a) * n).sum(axis=1)
    return q1 - h1[:, None] * n + (np.sign(h0) * np.minimum(margin, np.abs(h0)))[:, None] * n


# --- open meshes ------------------------------------------------------------------

def test_a_falling_point_stops_on_an_open_square_margin_above():
    ctl = control([square()], static())
    L = planes([[0.2, 0.3, 0.01]])
    P = planes([[0.2, 0.3, -0.02]])
    run(ctl, P, L)
    np.testing.assert_allclose(P[:, 0], [0.2, 0.3, MARGIN], atol=1e-12)


def test_a_point_rising_into_it_from_below_stays_below():
    ctl = control([square()], static())
    P = run(ctl, planes([[0.1, 0.1, 0.05]]), planes([[0.1, 0.1, -0.05]]))
    np.testing.assert_allclose(P[:, 0], [0.1, 0.1, -MARGIN], atol=1e-12)


def test_a_fast_point_does_not_cross_a_thin_open_mesh():
    """0.5 m in one substep, 500 times the margin, through a mesh of no thickness"""
    ctl = control([square(half=0.5)], static())
    L = planes([[0.05, -0.02, 0.25], [0.3, 0.4, 0.3]])
    P = planes([[-0.05, 0.03, -0.25], [0.1, 0.45, -0.2]])
    run(ctl, P, L)
    assert np.all(P[2] > 0.0)
    np.testing.assert_allclose(P[2], MARGIN, atol=1e-12)


def test_a_point_through_the_shared_edge_or_a_corner_is_caught():
    ctl = control([square()], static())
    # the diagonal x = y is the edge both triangles share; (1, 1) a corner of both
    P = run(ctl, planes([[0.3, 0.3, -0.1], [1.0, 1.0, -0.1]]), planes([[0.3, 0.3, 0.1], [1.0, 1.0, 0.1]]))
    np.testing.assert_allclose(P[2], MARGIN, atol=1e-12)


def test_points_moving_beside_or_parallel_are_untouched():
    ctl = control([square(half=0.5)], static())
    L = planes([[0.0, 0.0, 0.01], [0.7, 0.0, 0.1], [0.0, 0.0, 0.0005], [0.0, 0.0, 0.3]])
    P0 = planes([[0.3, 0.2, 0.01], [0.7, 0.0, -0.1], [0.2, 0.1, 0.0005], [0.0, 0.0, 0.1]])
    P = run(ctl, P0.copy(), L)
    np.testing.assert_array_equal(P, P0)


def test_meshes_none_does_nothing():
    ctl = control([square()], static())._replace(meshes=None)
    P0 = planes([[0.0, 0.0, -0.1]])
    P = P0.copy()
    collide_meshes(P, planes([[0.0, 0.0, 0.1]]), np.ones(1), ctl, np.int64(0), np.int64(1), np.int64(0))
    settle_meshes(P, planes([[0.0, 0.0, 0.1]]), np.ones(1), ctl, np.int64(0), np.int64(1), np.int64(0))
    np.testing.assert_array_equal(P, P0)


def test_pinned_points_and_points_outside_lo_hi_stay():
    ctl = control([square()], static())
    L = planes([[0.0, 0.0, 0.1]] * 3)
    P0 = planes([[0.0, 0.0, -0.1]] * 3)
    P = P0.copy()
    collide_meshes(P, L, np.array([1.0, 0.0, 1.0]), ctl, np.int64(0), np.int64(2), np.int64(0))
    np.testing.assert_allclose(P[2], [MARGIN, -0.1, -0.1], atol=1e-12)


# --- friction and motion ------------------------------------------------------------

def test_friction_one_keeps_the_last_position_and_zero_the_surface_point():
    L = planes([[0.1, 0.2, 0.05]])
    P0 = planes([[0.4, -0.1, -0.05]])
    # friction 0: the point now, put on the plane and margin off it; 1: the last position
    for f, want in ((1.0, [0.1, 0.2, 0.05]), (0.0, [0.4, -0.1, MARGIN]), (0.5, [0.25, 0.05, 0.025 + MARGIN / 2])):
        P = run(control([square()], static(friction=f)), P0.copy(), L)
        np.testing.assert_allclose(P[:, 0], want, atol=1e-12)


def test_a_moving_mesh_carries_a_point_resting_on_it():
    """translated by 0.1 m in x and lifted by 1 mm in the substep: with friction 1 the
    resting point moves with the mesh, with friction 0 it keeps its own tangential motion
    (it stays where it is along x) and is lifted with the mesh"""
    ob, on = np.array([0.0, 0.0, 0.0]), np.array([0.1, 0.0, 0.001])
    L = planes([[0.2, 0.2, MARGIN]])
    P0 = planes([[0.2, 0.2, MARGIN - 0.0005]])  # gravity's small drop
    P = run(control([square()], pose_rows(EYE, on, EYE, ob, 1.0, MARGIN)[None]), P0.copy(), L)
    np.testing.assert_allclose(P[:, 0], L[:, 0] + on - ob, atol=1e-12)
    P = run(control([square()], pose_rows(EYE, on, EYE, ob, 0.0, MARGIN)[None]), P0.copy(), L)
    np.testing.assert_allclose(P[:, 0], [0.2, 0.2, 0.001 + MARGIN], atol=1e-12)


def test_a_rotating_mesh_carries_a_point_and_the_slot_picks_the_pose():
    """a quarter turn about z over two substeps: slot 1 uses the second pose row"""
    def rz(deg):
        c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
        return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    rows = np.stack([pose_rows(rz(0), ZERO, rz(0), ZERO, 1.0, MARGIN)[None],
                     pose_rows(rz(90), ZERO, rz(45), ZERO, 1.0, MARGIN)[None]])
    ctl = control([square()], rows)
    L = planes([[0.5, 0.0, MARGIN]])
    P = run(ctl, planes([[0.5, 0.0, -0.01]]), L, s=1)
    np.testing.assert_allclose(P[:, 0], rz(45) @ L[:, 0], atol=1e-12)
    P = run(ctl, planes([[0.5, 0.0, -0.01]]), L, s=7)  # past the last slot: the last row
    np.testing.assert_allclose(P[:, 0], rz(45) @ L[:, 0], atol=1e-12)


def test_settle_puts_back_a_point_a_later_pass_pushed_through():
    ctl = control([square()], pose_rows(EYE, [0, 0, 0.2], EYE, ZERO, 1.0, MARGIN)[None])
    Q = planes([[0.1, 0.1, 0.2 + MARGIN], [0.3, 0.3, 0.25]])
    P = planes([[0.3, 0.1, 0.19], [0.35, 0.3, 0.24]])
    settle_meshes(P, Q, np.ones(2), ctl, np.int64(0), np.int64(2), np.int64(0))
    # the first crosses: its position put on the plane, margin off on Q's side (Q was
    # margin off), no friction, so it keeps its move along the plane
    np.testing.assert_allclose(P[:, 0], [0.3, 0.1, 0.2 + MARGIN], atol=1e-12)
    np.testing.assert_allclose(P[:, 1], [0.35, 0.3, 0.24])


# --- closed meshes ------------------------------------------------------------------

@pytest.fixture(scope="module")
def ball():
    shapes = [sphere(radius=0.5, subdivisions=3)]
    return shapes, control(shapes, static())


def test_random_segments_never_end_inside_a_closed_mesh(ball):
    """starting outside, none ends inside (exact: the icosphere is convex); those that
    cross nothing, by a brute-force test of every triangle, are not moved, and those
    that clearly cross end where the placement rule puts them for the brute force's
    first crossing (or stay at their start where the path to that place clearly
    crosses another triangle)"""
    shapes, ctl = ball
    tris = ctl.mesh_tris
    rng = np.random.default_rng(1)
    n = 4000
    direction = rng.normal(size=(n, 3))
    start = direction / np.linalg.norm(direction, axis=1)[:, None] * rng.uniform(0.5, 0.8, (n, 1))
    start = start[face_distance(tris, start) > 1e-6]
    end = start + rng.normal(size=start.shape) * rng.choice([0.01, 0.1, 0.6], size=(len(start), 1))
    L, P0 = planes(start), planes(end)
    P = run(ctl, P0.copy(), L)
    out = P.T
    assert np.all(face_distance(tris, out) > 0.0)
    wide, _ = brute_first_hit(tris, start, end, 1e-6, entry_only=True)
    narrow, t = brute_first_hit(tris, start, end, -1e-6, entry_only=True)
    missed = ~np.isfinite(wide)
    assert missed.sum() > 100 and (~missed).sum() > 100
    np.testing.assert_array_equal(out[missed], end[missed])
    clear = np.isfinite(narrow)
    placed = put_off_reference(tris, t[clear], start[clear], end[clear], MARGIN)
    # a crease: the path to the placed point crosses the mesh again, and the point stays
    again_wide, _ = brute_first_hit(tris, start[clear], placed, 1e-6, entry_only=True)
    again_narrow, _ = brute_first_hit(tris, start[clear], placed, -1e-6, entry_only=True)
    stays, goes = np.isfinite(again_narrow), ~np.isfinite(again_wide)
    assert goes.sum() > 100
    np.testing.assert_allclose(out[clear][goes], placed[goes], atol=1e-9)
    np.testing.assert_array_equal(out[clear][stays], start[clear][stays])
    # placed on the crossed triangle's plane, as near as it came from or margin off
    a, b, c = tris[t[clear], 0:3], tris[t[clear], 3:6], tris[t[clear], 6:9]
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1)[:, None]
    h0 = ((start[clear] - a) * n).sum(axis=1)
    h = ((out[clear][goes] - a[goes]) * n[goes]).sum(axis=1)
    np.testing.assert_allclose(h, np.minimum(MARGIN, h0[goes]), atol=1e-9)


def winding(tris, points):
    """(N,) the winding number of a closed mesh wound outward about each point (1 inside,
    0 outside), from the solid angles of its triangles (numpy, apart from the kernels)"""
    a = tris[None, :, 0:3] - points[:, None]
    b = tris[None, :, 3:6] - points[:, None]
    c = tris[None, :, 6:9] - points[:, None]
    la, lb, lc = (np.linalg.norm(v, axis=2) for v in (a, b, c))
    det = (a * np.cross(b, c)).sum(axis=2)
    den = la * lb * lc + (a * b).sum(axis=2) * lc + (b * c).sum(axis=2) * la + (c * a).sum(axis=2) * lb
    return 2.0 * np.arctan2(det, den).sum(axis=1) / (4.0 * np.pi)


def test_no_point_ends_inside_a_torus():
    """a solid that is not convex, points starting inside it and out, short moves (the
    rescue's shortcut for points off every plane of their cell) and long ones: none
    ends inside, by the winding number"""
    torus = trimesh.creation.torus(major_radius=0.5, minor_radius=0.15, major_sections=48, minor_sections=24)
    ctl = control([shape(torus.vertices, torus.faces, True)], static(friction=0.3))
    tris = ctl.mesh_tris
    rng = np.random.default_rng(4)
    n = 3000
    angle = rng.uniform(0, 2 * np.pi, n)
    ring = np.stack([np.cos(angle), np.sin(angle), np.zeros(n)], axis=1) * 0.5
    start = ring + rng.normal(size=(n, 3)) * rng.choice([0.05, 0.15, 0.3], size=(n, 1))
    end = start + rng.normal(size=start.shape) * rng.choice([0.002, 0.01, 0.1], size=(n, 1))
    before = winding(tris, start)
    assert (before > 0.5).sum() > 300 and (before < 0.5).sum() > 300
    P = run(ctl, planes(end), planes(start))
    assert np.all(winding(tris, P.T) < 0.5)
    # and the points that start and end outside without crossing are left alone
    _, t = brute_first_hit(tris, start, end, 1e-6, entry_only=True)
    calm = (before < 0.5) & (winding(tris, end) < 0.5) & (t < 0)
    assert calm.sum() > 300
    np.testing.assert_array_equal(P.T[calm], end[calm])


def test_a_point_passing_through_a_solid_stops_at_its_near_side(ball):
    _, ctl = ball
    P = run(ctl, planes([[0.01, 0.02, -0.9]]), planes([[0.0, 0.0, 0.9]]))
    assert P[2, 0] > 0.45 and face_distance(ctl.mesh_tris, P.T)[0] > 0.5 * MARGIN


def test_points_inside_a_closed_mesh_are_pushed_out(ball):
    """the deep centre too; each goes to near the surface point nearest it"""
    _, ctl = ball
    rng = np.random.default_rng(2)
    inside = rng.normal(size=(300, 3))
    inside *= rng.uniform(0.0, 0.47, (300, 1)) / np.linalg.norm(inside, axis=1)[:, None]
    inside = np.vstack([inside, [[0.0, 0.0, 0.0], [0.0, 0.0, 0.4999]]])
    inside = inside[face_distance(ctl.mesh_tris, inside) < -1e-6]
    P = run(ctl, planes(inside), planes(inside))
    d = face_distance(ctl.mesh_tris, P.T)
    assert np.all(d > 0.5 * MARGIN) and np.all(d < 2 * MARGIN)
    # pushed out radially, give or take the facets
    dots = (P.T * inside).sum(axis=1) / np.maximum(np.linalg.norm(inside, axis=1), 1e-12)
    assert np.all(dots[np.linalg.norm(inside, axis=1) > 0.05] > 0.0)


def test_a_point_inside_may_leave_a_closed_mesh(ball):
    """crossings out of a solid do not count: a point that slipped inside walks out"""
    _, ctl = ball
    P = run(ctl, planes([[0.0, 0.0, 0.7]]), planes([[0.0, 0.0, 0.3]]))
    np.testing.assert_array_equal(P[:, 0], [0.0, 0.0, 0.7])


def test_an_open_mesh_counts_crossings_both_ways():
    open_ball = [sphere(radius=0.5, subdivisions=2)]
    open_ball[0].closed = False
    ctl = control(open_ball, static())
    # out through a face and in through one: each is put on the face's plane, margin off
    # on the side it came from
    L = planes([[0.03, 0.05, 0.3], [0.05, -0.03, 0.8]])
    P0 = planes([[0.02, 0.04, 0.7], [0.04, -0.02, 0.2]])
    P = run(ctl, P0.copy(), L)
    _, t = brute_first_hit(ctl.mesh_tris, L.T, P0.T, -1e-6, entry_only=False)
    assert np.all(t >= 0)
    np.testing.assert_allclose(P.T, put_off_reference(ctl.mesh_tris, t, L.T, P0.T, MARGIN), atol=1e-12)
    a, b, c = ctl.mesh_tris[t, 0:3], ctl.mesh_tris[t, 3:6], ctl.mesh_tris[t, 6:9]
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1)[:, None]
    h = ((P.T - a) * n).sum(axis=1)  # the faces are wound outward
    np.testing.assert_allclose(h, [-MARGIN, MARGIN], atol=1e-12)  # on the side each came from
    # out through a corner shared by several faces (the pole): it does not get out
    P = run(ctl, planes([[0.0, 0.0, 0.7]]), planes([[0.0, 0.0, 0.3]]))
    assert np.linalg.norm(P[:, 0]) < 0.5


def test_a_mesh_wound_inward_is_turned_outward():
    m = trimesh.creation.icosphere(subdivisions=2, radius=0.5)
    ctl = control([shape(m.vertices, m.faces[:, ::-1], closed=True)], static())
    P = run(ctl, planes([[0.0, 0.0, 0.2]]), planes([[0.0, 0.0, 0.9]]))
    assert P[2, 0] > 0.45


# --- bad input ------------------------------------------------------------------------

def degenerate_square():
    """the square with a zero-area triangle, a repeated corner and a sliver"""
    v = [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0], [0, 0, 0], [2, 2, 0]]
    return shape(v, [[0, 1, 2], [0, 2, 3], [4, 4, 4], [0, 2, 5], [1, 1, 3]], closed=False)


def test_nan_inf_and_degenerate_triangles_do_not_crash():
    ctl = control([degenerate_square(), sphere(0.3, 2, (0, 0, 2))], static(k=2))
    bad = [np.nan, np.inf, -np.inf, 1e300, -1e308]
    L = planes([[0.2, 0.1, 0.1]] + [[b, 0.0, 0.1] for b in bad] + [[0.0, 0.0, 0.1]] * len(bad)
               + [[0.0, 0.0, 0.0], [0.0, 0.01, 2.5]])
    P0 = planes([[0.2, 0.1, -0.1]] + [[0.0, 0.0, -0.1]] * len(bad) + [[0.0, b, -0.1] for b in bad]
                + [[0.0, 0.0, 0.0], [0.0, 0.0, 2.0]])
    P = run(ctl, P0.copy(), L)
    np.testing.assert_allclose(P[:, 0], [0.2, 0.1, MARGIN], atol=1e-12)
    assert np.isnan(P[0, 1]) is np.False_ and np.isnan(P[1, 1 + len(bad)])  # NaN stays NaN
    for j in range(1, 1 + 2 * len(bad)):
        finite = np.isfinite(L[:, j]).all() and np.isfinite(P0[:, j]).all()
        if not finite:
            np.testing.assert_array_equal(P[:, j], P0[:, j])
    assert P[2, -1] > 2.25  # stopped on the ball above
    # a pose that is not finite leaves every point alone
    nan_pose = static(k=2)
    nan_pose[1, 3] = np.nan
    P = run(ctl._replace(meshes=nan_pose[None]), P0.copy(), L)
    assert P[2, -1] == 2.0


def test_a_mesh_of_one_degenerate_triangle_or_none_packs_and_runs():
    for s in (shape([[0, 0, 0]] * 3, [[0, 1, 2]], closed=True), shape(np.zeros((0, 3)), np.zeros((0, 3)), True)):
        ctl = control([s], static())
        P = run(ctl, planes([[0.0, 0.0, -0.1]]), planes([[0.0, 0.0, 0.1]]))
        np.testing.assert_array_equal(P[:, 0], [0.0, 0.0, -0.1])


def test_pack_refuses_bad_meshes():
    with pytest.raises(ValueError):
        pack_meshes([shape([[0, 0, np.nan]] * 3, [[0, 1, 2]], False)])
    with pytest.raises(ValueError):
        pack_meshes([shape([[0, 0, 0]] * 3, [[0, 1, 3]], False)])
    assert pack_meshes([]) is None


def test_a_huge_or_tiny_triangle_mesh_gets_a_bounded_grid():
    big = shape([[0, 0, 0], [1e6, 0, 0], [0, 1e6, 1e6], [1e-3, 0, 0], [0, 1e-3, 0]], [[0, 1, 2], [0, 3, 4]], True)
    packed = pack_meshes([big])
    assert len(packed["mesh_cells"]) <= (1 << 22) + 1 and len(packed["mesh_items"]) <= (1 << 24) + (1 << 22)


PROBE = """
import sys
import numpy as np
sys.path.insert(0, sys.argv[1])
import test_mesh_collider as t
t.test_nan_inf_and_degenerate_triangles_do_not_crash()
t.test_random_segments_never_end_inside_a_closed_mesh(t.ball.__wrapped__())
t.test_points_inside_a_closed_mesh_are_pushed_out(t.ball.__wrapped__())
t.test_a_fast_point_does_not_cross_a_thin_open_mesh()
t.test_no_point_ends_inside_a_torus()
print("ok")
"""


def test_the_kernels_run_with_every_index_checked(tmp_path):
    """NUMBA_BOUNDSCHECK=1 compiles the kernels with bounds checks: the bad-input and
    closed-mesh tests again, where an index out of range would raise"""
    env = dict(os.environ, NUMBA_BOUNDSCHECK="1", NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    done = subprocess.run([sys.executable, "-c", PROBE, os.path.dirname(__file__)], env=env,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.split()[-1] == "ok"


# --- the grid ---------------------------------------------------------------------

def grid_query(packed, k, lo, hi):
    """the triangles listed in the cells of mesh k the box lo..hi overlaps"""
    g = packed["mesh_grid"][k]
    o, h, dims = g[G_ORIGIN:G_ORIGIN + 3], g[G_H], g[G_DIMS:G_DIMS + 3].astype(int)
    a = np.clip(np.floor((lo - o) / h), 0, dims - 1).astype(int)
    b = np.clip(np.floor((hi - o) / h), 0, dims - 1).astype(int)
    found = set()
    for iz in range(a[2], b[2] + 1):
        for iy in range(a[1], b[1] + 1):
            for ix in range(a[0], b[0] + 1):
                c = int(g[G_CELL0]) + (iz * dims[1] + iy) * dims[0] + ix
                found.update(packed["mesh_items"][packed["mesh_cells"][c]:packed["mesh_cells"][c + 1]].tolist())
    return found


def surface_samples(tris, n=12):
    """(F, S, 3) points spread over each triangle, its corners and edges included"""
    i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1))
    keep = i + j <= n
    u, v = i[keep] / n, j[keep] / n
    a, b, c = tris[:, None, 0:3], tris[:, None, 3:6], tris[:, None, 6:9]
    return a + u[None, :, None] * (b - a) + v[None, :, None] * (c - a)


def test_the_grid_lists_every_triangle_that_meets_a_query_box():
    torus = trimesh.creation.torus(major_radius=0.6, minor_radius=0.2)
    shapes = [square(z=0.3, half=0.4), sphere(0.5, 3, (0.2, 0.0, 0.1)), shape(torus.vertices, torus.faces, True)]
    packed = pack_meshes(shapes)
    tris = packed["mesh_tris"]
    assert len(tris) == 2 + 1280 + len(torus.faces)
    samples = surface_samples(tris)
    starts = np.cumsum([0] + [len(s.triangles) for s in shapes])
    rng = np.random.default_rng(3)
    for _ in range(200):
        k = rng.integers(3)
        centre = rng.uniform(-0.9, 0.9, 3)
        lo = centre - rng.uniform(0, 0.2, 3)
        hi = centre + rng.uniform(0, 0.2, 3)
        mine = np.arange(starts[k], starts[k + 1])
        inside = np.all((samples[mine] >= lo) & (samples[mine] <= hi), axis=2)
        meets = mine[inside.any(axis=1)]
        found = grid_query(packed, k, lo, hi)
        assert set(meets.tolist()) <= found
        assert found <= set(mine.tolist())


def test_a_cell_lists_only_triangles_whose_plane_passes_through_it():
    """the plane filter leaves out of a cell the triangles whose bounding box, but not
    whose plane, reaches it: fewer entries than the boxes alone would make"""
    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.5)
    packed = pack_meshes([shape(ball.vertices, ball.faces, True)])
    g = packed["mesh_grid"][0]
    o, h, dims = g[G_ORIGIN:G_ORIGIN + 3], g[G_H], g[G_DIMS:G_DIMS + 3].astype(int)
    tris = packed["mesh_tris"]
    lo = np.clip(np.floor((np.minimum(np.minimum(tris[:, 0:3], tris[:, 3:6]), tris[:, 6:9]) - o) / h), 0, dims - 1)
    hi = np.clip(np.floor((np.maximum(np.maximum(tris[:, 0:3], tris[:, 3:6]), tris[:, 6:9]) - o) / h), 0, dims - 1)
    by_boxes = int(np.prod(hi - lo + 1, axis=1).sum())
    assert packed["mesh_cells"][-1] < 0.95 * by_boxes


def test_near_marks_exactly_the_cells_next_to_a_cell_with_triangles():
    """the fast path's flag, against a brute-force look at the 27 cells about each"""
    torus = trimesh.creation.torus(major_radius=0.6, minor_radius=0.2)
    packed = pack_meshes([square(z=0.3, half=0.4), shape(torus.vertices, torus.faces, True)])
    for k in range(2):
        g = packed["mesh_grid"][k]
        nx, ny, nz = g[G_DIMS:G_DIMS + 3].astype(int)
        c0, s0 = int(g[G_CELL0]), int(g[G_STATUS0])
        busy = (np.diff(packed["mesh_cells"][c0:c0 + nx * ny * nz + 1]) > 0).reshape(nz, ny, nx)
        status = packed["mesh_items"][s0:s0 + nx * ny * nz].reshape(nz, ny, nx)
        padded = np.pad(busy, 1)
        want = np.zeros_like(busy)
        for dz in range(3):
            for dy in range(3):
                for dx in range(3):
                    want |= padded[dz:dz + nz, dy:dy + ny, dx:dx + nx]
        assert np.array_equal((status & NEAR) != 0, want)
        if k == 0:
            assert not np.any(status & INSIDE_BITS)  # an open mesh has no inside
        else:
            assert want.sum() < 0.9 * want.size  # the hole and the corners are far from it


def test_a_point_deep_inside_a_closed_mesh_far_from_its_surface_is_pushed_out():
    """a cell inside the solid without a triangle near it is not on the fast path"""
    big = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    packed = pack_meshes([shape(big.vertices, big.faces, True)])
    ctl = Ctl(meshes=pose_rows(np.eye(3), np.zeros(3), np.eye(3), np.zeros(3), 0.0, 1e-3)[None, None], **packed)
    L, P = planes([[0.05, 0.02, 0.0]]), planes([[0.05, 0.02, -0.001]])
    collide_meshes(P, L, np.ones(1), ctl, np.int64(0), np.int64(1), np.int64(0))
    assert np.linalg.norm(P[:, 0]) > 0.99


def test_count_tests_counts_the_triangles_a_point_tries(ball):
    _, ctl = ball
    L = planes([[0.0, 0.0, 0.6], [3.0, 0.0, 0.0]])
    P = planes([[0.0, 0.0, 0.4], [3.0, 0.0, -0.1]])
    out = np.zeros(2, dtype=np.int64)
    count_tests(P, L, np.ones(2), ctl, np.int64(0), np.int64(2), np.int64(0), out)
    assert out[0] > 0 and out[1] == 0
    assert json.dumps(out.tolist())
