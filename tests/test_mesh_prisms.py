"""The mesh collider's clear prisms and hints (solver/colliders/meshprism.py, mesh.py).

Each point keeps the triangle it last crossed, and the kernels settle its
segment by that triangle's clear prism before any search. These tests check
the promise the shortcut rests on (no other triangle reaches into a prism),
that it is taken, and that it never changes where a point goes: the same
positions, bit for bit, with right, stale, wrong or no hints.
"""

from __future__ import annotations

import json

import numpy as np
import trimesh

from clothsim import Simulation
from clothsim.scene import parse_scene
from clothsim.solver.colliders.mesh import _grid_scalars, pack_meshes, pose_rows, with_hints
from clothsim.solver.colliders.meshgrid import G_H
from clothsim.solver.colliders.meshprism import P_DOWN, P_ROUNDING, P_UP, rounding_heights
from clothsim.standard_scenes import scene_path

from .test_mesh_collider import EYE, MARGIN, Ctl, face_distance, planes, run, shape, sphere, square, static
from .test_mesh_slabs import settle_run, torus


def crossing_squares():
    """two open squares that cut each other along a line: a mesh that intersects itself"""
    a = [[-0.5, -0.5, 0.0], [0.5, -0.5, 0.0], [0.5, 0.5, 0.0], [-0.5, 0.5, 0.0]]
    b = [[-0.5, 0.0, -0.5], [0.5, 0.0, -0.5], [0.5, 0.0, 0.5], [-0.5, 0.0, 0.5]]
    return shape(a + b, [[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]], closed=False)


def hinted(shapes, poses, points):
    return Ctl(meshes=np.asarray(poses)[None], **with_hints(pack_meshes(shapes), points))


def samples(corners, per=24, seed=0):
    """(T * per, 3) points spread over each triangle of (T, 3, 3), its corners and edges included"""
    rng = np.random.default_rng(seed)
    w = rng.dirichlet([0.6, 0.6, 0.6], size=(len(corners), per))
    w[:, :3] = np.eye(3)
    return np.einsum("tsk,tkd->tsd", w, corners).reshape(-1, 3), np.repeat(np.arange(len(corners)), per)


def test_no_other_triangle_reaches_into_a_triangles_clear_prism():
    """points spread over every triangle of a torus, an open square and two squares
    that cut each other: none lies over another triangle, inside its prism, within
    its heights; a smooth torus leaves most prisms their full height, and where
    the squares cross, the prisms that the cut passes through have none"""
    for mesh, full in ((torus(), 0.9), (square(half=0.5), 1.0), (crossing_squares(), 0.0)):
        packed = pack_meshes([mesh])
        tris, prisms, h = packed["mesh_tris"], packed["mesh_prisms"], packed["mesh_grid"][0, G_H]
        corners = tris[:, :9].reshape(-1, 3, 3)
        points, owner = samples(corners)
        n, w = tris[:, 9:12], tris[:, 12]
        for t in range(len(tris)):
            r = prisms[t]
            inside = np.all(np.stack([points @ r[4 * e:4 * e + 3] >= r[4 * e + 3] for e in range(3)]), axis=0)
            height = points @ n[t] - w[t]
            reached = inside & (height <= r[P_UP]) & (height >= -r[P_DOWN]) & (owner != t)
            assert not reached.any(), (t, points[reached][:3])
        assert np.mean(prisms[:, P_UP] == h) >= full
        if full == 0.0:  # each square is cut through its middle: no triangle is free both ways
            assert np.all(np.maximum(prisms[:, P_UP], prisms[:, P_DOWN]) == 0.0)


def random_segments(n, seed):
    """segments near the torus and the square of the mix below, half of them short and
    long moves anywhere, half from just over the torus's surface into it, as a cloth
    resting on it moves"""
    rng = np.random.default_rng(seed)
    half = n // 2
    start = rng.uniform(-0.85, 0.85, (half, 3)) * [1.0, 1.0, 0.45]
    end = start + rng.normal(size=(half, 3)) * rng.choice([0.0005, 0.002, 0.01, 0.05], size=(half, 1))
    m = torus()
    corners = m.vertices[m.triangles]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    points, owner = samples(corners, per=8, seed=seed)
    pick = rng.choice(len(points), n - half)
    up = normals[owner[pick]]
    rest = points[pick] + up * rng.uniform(0.0, 0.003, (n - half, 1))
    fall = rest - up * rng.uniform(0.0, 0.006, (n - half, 1)) + rng.normal(size=(n - half, 3)) * 0.001
    return planes(np.concatenate([start, rest])), planes(np.concatenate([end, fall]))


def test_hints_right_stale_wrong_or_none_give_the_same_positions():
    """random segments near a torus (closed) and an open square: the positions after
    the collider pass and after the settle pass are the same, bit for bit, without
    hints, with the hints the first pass left, with hints of another set of
    segments, and with random numbers (other meshes' triangles, -1, out of range)"""
    shapes = [torus(), square(z=0.31, half=0.5)]
    poses = static(friction=0.3, k=2)
    n = 6000
    L, P0 = random_segments(n, 11)
    plain = Ctl(meshes=np.asarray(poses)[None], **pack_meshes(shapes))
    assert plain.mesh_hints.shape == (2, 0)
    want = run(plain, P0.copy(), L)
    want_settled = settle_run(plain, P0.copy(), L)
    assert np.any(want != P0)

    ctl = hinted(shapes, poses, n)
    first = run(ctl, P0.copy(), L)
    np.testing.assert_array_equal(first, want)
    right = ctl.mesh_hints.copy()
    assert (right >= 0).sum() > 1000  # the crossings were kept
    stale = hinted(shapes, poses, n)
    run(stale, *random_segments(n, 12)[::-1])
    rng = np.random.default_rng(3)
    wrong = rng.integers(-5, len(plain.mesh_tris) + 5, size=(2, n)).astype(np.int32)
    for hints in (right, stale.mesh_hints, wrong):
        np.testing.assert_array_equal(run(ctl._replace(mesh_hints=hints.copy()), P0.copy(), L), want)
        np.testing.assert_array_equal(settle_run(ctl._replace(mesh_hints=hints.copy()), P0.copy(), L),
                                      want_settled)
    # a prism table narrower than the hint pass's whole rows (not made by pack_prisms): no hint decides
    narrow = ctl._replace(mesh_hints=right.copy(), mesh_prisms=np.ascontiguousarray(ctl.mesh_prisms[:, :14]))
    np.testing.assert_array_equal(run(narrow, P0.copy(), L), want)


def test_a_settle_pass_after_which_few_points_moved_places_them_as_without_hints():
    """the settle pass lists the few moved points that have a hint without its first
    tests (meshlook._look_moved): after a collider pass that kept hints, a later
    pass moves one point in fifty (some back through the surface, some off
    anywhere, one to NaN); the settled positions are the same, bit for bit, with
    those hints, with wrong ones and with none"""
    shapes = [torus(), square(z=0.31, half=0.5)]
    poses = static(friction=0.3, k=2)
    n = 6000
    L, P0 = random_segments(n, 21)
    ctl = hinted(shapes, poses, n)
    Q = run(ctl, P0.copy(), L)
    right = ctl.mesh_hints.copy()
    rng = np.random.default_rng(5)
    moved = np.flatnonzero(rng.random(n) < 0.02)
    assert np.isin(moved, np.flatnonzero((right >= 0).any(axis=0))).sum() > 20
    P = Q.copy()
    P[:, moved] += (Q[:, moved] - L[:, moved]) * rng.uniform(0.5, 3.0, moved.size) \
        + rng.normal(size=(3, moved.size)) * rng.choice([1e-4, 2e-3, 0.05], moved.size)
    P[0, moved[0]] = np.nan
    plain = Ctl(meshes=np.asarray(poses)[None], **pack_meshes(shapes))
    want = settle_run(plain, P.copy(), Q)
    assert np.sum(np.any(want != P, axis=0)) > 5  # some were put back
    wrong = rng.integers(-5, len(plain.mesh_tris) + 5, size=(2, n)).astype(np.int32)
    for hints in (right, wrong):
        np.testing.assert_array_equal(settle_run(ctl._replace(mesh_hints=hints.copy()), P.copy(), Q), want)


def test_a_mesh_in_its_rest_pose_is_read_as_the_turned_one_is():
    """a mesh standing in its rest pose skips the turns into its frame in the vector
    pass (and the hinted points go in blocks): the same segments against the same
    meshes posed one part in 1e300 off the rest pose, which takes the turns, end
    where they end, bit for bit, hints and all, some coordinates not finite"""
    shapes = [torus(), square(z=0.31, half=0.5)]
    n = 3000
    L, P0 = random_segments(n, 5)
    for which, bad in enumerate((np.nan, np.inf, -np.inf)):
        P0[which % 3, 7 + 11 * which] = bad
        L[(which + 1) % 3, 500 + 13 * which] = bad
    off = np.array([1e-300, 0.0, 0.0])
    rest = static(friction=0.4, k=2)
    near = np.repeat(pose_rows(EYE, off, EYE, off, 0.4, MARGIN)[None], 2, axis=0)
    got = {}
    for name, poses in (("rest", rest), ("near", near)):
        ctl = hinted(shapes, poses, n)
        first = run(ctl, P0.copy(), L)
        hints = ctl.mesh_hints.copy()
        got[name] = (first, run(ctl, P0.copy(), L), settle_run(ctl, P0.copy(), L), hints)
    assert (got["rest"][3] >= 0).sum() > 1000  # many points went through the hint blocks
    for a, b in zip(got["rest"], got["near"]):
        np.testing.assert_array_equal(a, b)
    assert np.any(got["rest"][0] != P0)


def test_a_point_resting_on_its_triangle_is_placed_by_the_hint_alone():
    """points a few millimetres over a mesh ball (20,480 triangles), falling through
    it: with their hints and the cells' lists emptied (no search can find a
    triangle) they land where the full search puts them, and none inside"""
    ball = sphere(radius=0.5, subdivisions=5)
    rng = np.random.default_rng(2)
    d = rng.normal(size=(2000, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    start = d * (0.5 + rng.uniform(0.0005, 0.003, (2000, 1)))
    end = start - d * rng.uniform(0.004, 0.006, (2000, 1))
    ctl = hinted([ball], static(friction=0.5), 2000)
    want = run(ctl, planes(end), planes(start))
    blind = ctl._replace(mesh_cells=np.zeros_like(ctl.mesh_cells))
    assert np.array_equal(run(blind._replace(mesh_hints=np.full((1, 2000), -1, np.int32)), planes(end),
                              planes(start)), planes(end))  # no search finds anything
    got = run(blind, planes(end), planes(start))
    placed = np.all(got == want, axis=0)
    assert placed.mean() > 0.99, placed.mean()
    assert np.all(face_distance(ctl.mesh_tris, got.T[placed]) > 0.0)


def heights_over(tris, n, seed, span):
    """(L, P, triangle, h0, h1) for n points over random triangles of ``tris``, well
    inside each, whose last position stands h0 off the triangle's plane and whose
    position now h1 off it (both from 10**span[0] to 10**span[1] m, either side), moved a
    little along the plane too"""
    rng = np.random.default_rng(seed)
    t = rng.integers(0, len(tris), n)
    w = rng.dirichlet([4.0, 4.0, 4.0], n)
    corners = tris[t, :9].reshape(n, 3, 3)
    foot = np.einsum("nk,nkd->nd", w, corners)
    normal = tris[t, 9:12]
    h0 = 10.0 ** rng.uniform(*span, n) * rng.choice([-1.0, 1.0], n)
    h1 = 10.0 ** rng.uniform(*span, n) * rng.choice([-1.0, 1.0], n)
    along = rng.normal(scale=2e-5, size=(n, 3))
    along -= (along * normal).sum(axis=1)[:, None] * normal
    return planes(foot + h0[:, None] * normal), planes(foot + along + h1[:, None] * normal), t, h0, h1


def test_crossings_told_by_heights_are_the_searchs_at_any_height():
    """points over a mesh ball (closed, 20,480 triangles) and an open square, from
    1e-16 to 1e-5 m (1e-9 to 1e-3 m) off the surface on either side, crossing it or not: with their
    triangles as hints the collider pass puts every point where the search does,
    bit for bit; and where both ends stand in the prism beyond the triangle's
    rounding bound, the hint alone (the cells emptied: no search finds anything)
    places each point that goes in as the search does, and leaves each that
    crosses nothing"""
    cases = ((sphere(radius=0.5, subdivisions=5), True, (-16, -5)), (square(half=0.5), False, (-9, -3)))
    for mesh, closed, span in cases:
        n = 4000
        plain = Ctl(meshes=static(friction=0.4)[None], **pack_meshes([mesh]))
        L, P, t, h0, h1 = heights_over(plain.mesh_tris, n, 7, span)
        want = run(plain, P.copy(), L)
        assert np.any(want != P)
        ctl = hinted([mesh], static(friction=0.4), n)
        ctl.mesh_hints[0] = t
        np.testing.assert_array_equal(run(ctl._replace(mesh_hints=ctl.mesh_hints.copy()), P.copy(), L), want)
        bound = ctl.mesh_prisms[t, P_ROUNDING]
        assert np.all(bound > 0.0) and np.all(bound < 1e-12), bound.max()
        # beyond the bound, and where the pass's other tests let the hint decide: an open
        # mesh leaves a start within its plane slack to the search, and a closed one a
        # placement nearer the plane than the rounding of its coordinates
        floor = np.maximum(2.0 * bound, _grid_scalars(ctl.mesh_grid[0])[13] if not closed else 1e-12)
        rows = ctl.mesh_prisms[t]
        in_prism = np.ones(n, dtype=bool)
        for X in (L, P):
            for e in range(3):
                in_prism &= (X.T * rows[:, 4 * e:4 * e + 3]).sum(axis=1) >= rows[:, 4 * e + 3]
        told = (np.abs(h0) > floor) & (np.abs(h1) > floor) & in_prism
        going_in = told & (h0 > 0.0) & (h1 < 0.0)
        missing = told & (np.sign(h0) == np.sign(h1)) & (h0 > 0.0 if closed else True)
        blind = ctl._replace(mesh_cells=np.zeros_like(ctl.mesh_cells))
        got = run(blind._replace(mesh_hints=ctl.mesh_hints.copy()), P.copy(), L)
        assert going_in.sum() > 100 and missing.sum() > 100, (going_in.sum(), missing.sum())
        assert np.all(want[:, going_in] != P[:, going_in])
        np.testing.assert_array_equal(got[:, going_in | missing], want[:, going_in | missing])


def test_the_rounding_bound_grows_with_a_triangles_size_place_and_thinness():
    """a triangle's rounding bound: a few hundred machine epsilons of its coordinates for
    a well-shaped triangle near the origin, larger far from it and for a thin one, and
    inf for one with no area"""
    eps = np.finfo(float).eps

    def bound(corners, cap=0.01):
        row = np.zeros((1, 13))
        row[0, :9] = np.ravel(corners)
        return rounding_heights(row, cap)[0]

    fair = bound([[0, 0, 0], [0.02, 0, 0], [0.01, 0.017, 0]])
    assert 10 * eps < fair < 1000 * eps
    assert bound([[100, 0, 0], [100.02, 0, 0], [100.01, 0.017, 0]]) > 100 * fair
    assert bound([[0, 0, 0], [0.02, 0, 0], [0.01, 0.0001, 0]]) > 10 * fair
    assert bound([[0, 0, 0], [0.02, 0, 0], [0.04, 0, 0]]) == np.inf


def test_a_simulation_with_hints_runs_as_it_would_without_them(tmp_path):
    """sphere.json at 24x24 on two threads, its sphere a mesh ball: the same positions
    after 1.5 s with the kept hints and with none, and the hints were used"""
    scene = json.loads(scene_path("sphere").read_text())
    sphere_spec = scene.pop("sphere")
    scene["cloth"].update(num_width_points=24, num_height_points=24)
    trimesh.creation.icosphere(subdivisions=4).export(tmp_path / "ball.obj")
    scene["mesh"] = {"path": "ball.obj", "friction": sphere_spec["friction"],
                     "transform": {"scale": sphere_spec["radius"], "translate": sphere_spec["origin"]}}
    sims = [Simulation(parse_scene(scene, str(tmp_path / "s.json")), threads=2) for _ in range(2)]
    sims[1]._mesh_shapes["mesh_hints"] = np.full((1, 0), -1, np.int32)
    for sim in sims:
        sim.run(1.5)
    np.testing.assert_array_equal(sims[0].positions, sims[1].positions)
    # hints kept by the points resting on the ball (those that could not tell are dropped)
    assert (sims[0]._mesh_shapes["mesh_hints"] >= 0).sum() > 50
    assert sims[0].positions[:, 1].min() < sphere_spec["origin"][1]  # it drapes over the ball


def test_a_hint_that_could_not_tell_is_dropped_and_a_crossing_gives_one():
    """over a closed icosphere: a point hovering 1 mm over one triangle with a far one
    for a hint (whose prism cannot tell) loses it, in the collider pass and in the
    settle pass; one hovering over a triangle with that hint keeps it (its prism
    told); one that goes in through a triangle without a hint gets it. The
    positions are those of the passes without hints."""
    ball = sphere(subdivisions=3)
    plain = Ctl(meshes=static()[None], **pack_meshes([ball]))
    tris = plain.mesh_tris
    centre = tris[:, :9].reshape(-1, 3, 3).mean(axis=1)
    normal = tris[:, 9:12]
    a, b, c = 0, 400, 800
    gap, side = 1e-3, np.array([1e-5, 0.0, 0.0])
    last = planes([centre[a] + gap * normal[a], centre[b] + gap * normal[b], centre[c] + gap * normal[c]])
    now = planes([centre[a] + gap * normal[a] + side, centre[b] + gap * normal[b] + side,
                  centre[c] - gap * normal[c]])
    want = run(plain, now.copy(), last)
    assert np.array_equal(want[:, :2], now[:, :2]) and not np.array_equal(want[:, 2], now[:, 2])

    ctl = hinted([ball], static(), 3)
    ctl.mesh_hints[0] = [a + 600, b, -1]
    np.testing.assert_array_equal(run(ctl, now.copy(), last), want)
    assert list(ctl.mesh_hints[0]) == [-1, b, c]

    moved = want.copy()
    moved[:, :2] += side[:, None]
    want_settled = settle_run(plain, moved.copy(), want)
    ctl.mesh_hints[0] = [a + 600, b, c]
    np.testing.assert_array_equal(settle_run(ctl, moved.copy(), want), want_settled)
    assert list(ctl.mesh_hints[0][:2]) == [-1, b]


ROWS_CHECK = """
import numpy as np
from numba import njit
from clothsim.solver.simd import ROW_WIDTH, rows_to_columns

@njit
def moved(table, rows, dst, at, stride):
    for j in range(0, rows.shape[0] - 7, 8):
        rows_to_columns(table, rows, j, dst, at + j, stride)

rng = np.random.default_rng(4)
table = rng.normal(size=(50, ROW_WIDTH))
table[3, 5], table[7, ROW_WIDTH - 2] = np.nan, -0.0
rows = rng.integers(0, 50, 24).astype(np.uint64)
rows[:2] = 3, 7
dst = np.full(40 * 29 + 5, 9.0)
moved(table, rows, dst, 5, 29)
want = np.full_like(dst, 9.0)
for j in range(24):
    want[5 + j + 29 * np.arange(ROW_WIDTH)] = table[rows[j]]
print(want.tobytes() == dst.tobytes())
"""


def test_rows_become_columns_to_the_bit_on_any_target():
    """the hint pass's copy: eight rows of a (T, 32) table at a time written as
    columns of a flat scratch at a stride, NaN and -0.0 kept, the rest of the
    scratch untouched; compiled for this CPU and for LLVM's generic x86 (no AVX)"""
    import os
    import subprocess
    import sys

    for env in ({}, {"NUMBA_CPU_NAME": "generic"}):
        out = subprocess.run([sys.executable, "-c", ROWS_CHECK], capture_output=True, text=True, timeout=300,
                             env={**os.environ, **env})
        assert out.stdout.strip() == "True", (env, out.stderr[-2000:])
