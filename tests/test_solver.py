"""Kernels checked against the formulas they implement, on hand-built inputs and
against plain NumPy/Python references over the model's spring list."""

from __future__ import annotations

import itertools
import os
import subprocess
import sys
from typing import NamedTuple

import numpy as np
import pytest
from numba import njit

from clothsim.model import build_model
from clothsim.scene import ClothSpec
from clothsim.solver.colliders import PLANE_OFFSET, collide_planes, collide_spheres
from clothsim.solver.groups import Knobs, Points
from clothsim.solver.provot import provot
from clothsim.solver.selfcollide import NeighbourList, near_stencil, self_collide
from clothsim.solver.selfcollide.buffers import BUCKET, NEAR, PAIRS, SKIN, SLACK_BUCKETS, SPARSE_PAIRS, WIDE
from clothsim.solver.selfcollide.drift import drift_bound, levels
from clothsim.solver.selfcollide.hashgrid import bounds
from clothsim.solver.selfcollide.listbuild import COMPRESS, NARROW, build_list
from clothsim.solver.selfcollide.nearstencil import COARSE_SKIN, NEAR_LEVELS, SKIN_FACTOR, grid_metric, skin_factor
from clothsim.solver.selfcollide.slack import PAD_ROWS, SORT_LANES, _count_runs, checked_pairs, label_pairs
from clothsim.solver.shared import BLOCK
from clothsim.solver.simd import FORCE_PORTABLE, has_compress
from clothsim.solver.springs import (AHEAD_STEP, CHUNK, NO_LIMIT, SET_KIND, SET_STEP, build_stencil, force_buffer,
                                     force_pad, integrate, part_force_buffers)
from clothsim.solver.step import _part_span


def grid_model(nw: int, nh: int, pinned=(), spacing: float = 1.0):
    spec = ClothSpec(width=spacing * (nw - 1), height=spacing * (nh - 1), num_width_points=nw,
                     num_height_points=nh, thickness=0.01, orientation=0, pinned=list(pinned))
    return build_model(spec)


def stencil(m):
    """the model's springs as the solver's grid stencil"""
    return build_stencil(m.rest_positions, m.pinned, m.num_height_points, m.num_width_points)


def knobs(k_sets, gravity, keep, dt2):
    """the live parameters as integrate() takes them"""
    return Knobs(gravity=np.asarray(gravity, dtype=np.float64), k_over_m=np.asarray(k_sets, dtype=np.float64),
                 enabled=np.ones(6, dtype=bool), keep=float(keep), dt2=float(dt2), simulation_steps=1,
                 self_collision=False, inv_mass=np.ones(0))


def run_integrate(P, L, free, k, springs, F):
    """one step of integrate() over the whole cloth, P then holding the new
    positions and L the last ones (integrate writes the new over the last, and
    the substep swaps the two)"""
    n = P.shape[1]
    before = P.copy()
    integrate(P, L, free, k, springs, F, 0, n, 0)
    np.testing.assert_array_equal(P, before)  # read only
    P[:], L[:] = L.copy(), before


def planes(pos: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(pos.T)


def still(rows) -> np.ndarray:
    """collider rows (K, C) as the kernels take them: one slot, (1, K, C + CARRY),
    of a collider that does not move over the substep"""
    rows = np.atleast_2d(np.asarray(rows, dtype=np.float64))
    carry = np.tile(np.concatenate([np.eye(3).ravel(), np.zeros(3)]), (len(rows), 1))
    return np.concatenate([rows, carry], axis=1)[None]


def test_stencil_sets_are_the_model_springs():
    """the six offset sets hold exactly the model's springs, with their rest lengths"""
    m = grid_model(7, 5)
    st = stencil(m)
    found = set()
    for s in range(6):
        for p in np.flatnonzero(st.valid[s]):
            a, b = p + st.start[s], p + st.end[s]
            found.add((min(a, b), max(a, b), SET_KIND[s]))
            assert st.rest[s, p] == pytest.approx(np.linalg.norm(m.rest_positions[a] - m.rest_positions[b]))
    expected = {(min(a, b), max(a, b), k) for a, b, k in zip(m.spring_a, m.spring_b, m.spring_kind)}
    assert found == expected
    assert sum(int(st.valid[s].sum()) for s in range(6)) == m.num_springs


def reference_accelerations(pos, m, k_kind, gravity):
    acc = np.tile(gravity, (len(pos), 1)).astype(float)
    d = pos[m.spring_b] - pos[m.spring_a]
    length = np.linalg.norm(d, axis=1)
    f = (k_kind[m.spring_kind] * (length - m.spring_rest) / length)[:, None] * d
    np.add.at(acc, m.spring_a, f)
    np.add.at(acc, m.spring_b, -f)
    return acc


def accelerations(pos, m, k_sets, gravity):
    """the acceleration integrate() applies: one step with dt = 1 from rest (x_prev = x)"""
    st = stencil(m)
    P = planes(pos)
    L = P.copy()
    run_integrate(P, L, np.ones(m.num_points), knobs(k_sets, gravity, 0.7, 1.0), st,
                  force_buffer(st, m.num_points))
    np.testing.assert_array_equal(L, planes(pos))  # x_prev <- x
    return (P - planes(pos)).T


@pytest.mark.parametrize("nw,nh", [(9, 6), (40, 30)])  # one chunk; several chunks
def test_hooke_forces_match_the_spring_list(nw, nh):
    """every spring pulls both ends along itself with k*(l - rest)/m; bending uses its own k"""
    m = grid_model(nw, nh)
    assert (nw * nh > CHUNK) == (nw == 40)
    rng = np.random.default_rng(1)
    pos = m.rest_positions * rng.uniform(0.8, 1.3, size=m.rest_positions.shape)
    k_kind = np.array([10.0, 7.0, 2.0])
    g = np.array([0.0, -9.8, 0.0])
    np.testing.assert_allclose(accelerations(pos, m, k_kind[SET_KIND], g),
                               reference_accelerations(pos, m, k_kind, g), rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("nw,nh", [(2, 7), (3, 5), (60, 12), (700, 2)])
def test_slots_without_a_spring_add_no_force(nw, nh):
    """the force loop weighs no slot and zeroes the ones that would wrap a row
    (GridSprings.wrap) after it: on narrow grids, where every slot of a set is
    one, and across chunks, a buffer full of stale forces from a stretched
    cloth leaves nothing behind, and the accelerations are the spring list's"""
    m = grid_model(nw, nh)
    st = stencil(m)
    for s in range(6):
        p = np.arange(st.count[s])
        columns = st.wrap[s][st.wrap[s] >= 0]
        np.testing.assert_array_equal(st.valid[s, p] == 0, np.isin(p % nw, columns))
    rng = np.random.default_rng(3)
    pos = m.rest_positions + rng.normal(0.0, 0.2, size=m.rest_positions.shape)
    k_kind = np.array([10.0, 7.0, 2.0])
    g = np.array([0.0, -9.8, 0.0])
    F = force_buffer(st, m.num_points)
    pad = force_pad(F, m.num_points)
    for s in range(6):
        F[s, :, pad:pad + st.count[s]] = 1e9  # the slots the loop writes; the rest stay zero
    P, L = planes(pos), planes(pos)
    run_integrate(P, L, np.ones(m.num_points), knobs(k_kind[SET_KIND], g, 0.7, 1.0), st, F)
    np.testing.assert_allclose((P - planes(pos)).T, reference_accelerations(pos, m, k_kind, g),
                               rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("nw,nh,parts", [(40, 30, 2), (70, 40, 3), (9, 6, 2)])
def test_parts_move_their_points_as_the_whole_cloth_does(nw, nh, parts):
    """cut into parts as the threads take them, each part working out the forces
    of the ``ahead`` springs before its range as well, in a buffer of its own:
    run the parts last to first (a part's points stepped before the part
    before it reads them, the worst order threads could take) and the step is
    still the whole cloth's, bit for bit. ``ahead`` covers the springs' reach
    and no more than a vector past it"""
    m = grid_model(nw, nh)
    st = stencil(m)
    assert st.end.max() <= st.ahead < st.end.max() + AHEAD_STEP
    rng = np.random.default_rng(5)
    pos = m.rest_positions + rng.normal(0.0, 0.01, size=m.rest_positions.shape)
    free = np.ones(m.num_points)
    free[[0, nw - 1]] = 0.0
    k = knobs(np.array([10.0, 10.0, 7.0, 7.0, 2.0, 2.0]), [0.0, -9.8, 0.0], 0.9, 1e-3)
    n = m.num_points
    P0, L0 = planes(pos), planes(m.rest_positions)
    whole_P, whole_L = P0.copy(), L0.copy()
    integrate(whole_P, whole_L, free, k, st, force_buffer(st, n), 0, n, 0)
    P, L, F = P0.copy(), L0.copy(), part_force_buffers(st, n, parts)
    for t in reversed(range(parts)):
        lo, hi = _part_span(n, parts, t, st.ahead)
        integrate(P, L, free, k, st, F[t], max(lo - st.ahead, 0), hi, lo)
    np.testing.assert_array_equal(P, whole_P)
    np.testing.assert_array_equal(L, whole_L)


@pytest.mark.parametrize("n,parts,lead", [(10000, 2, 208), (40000, 2, 408), (12345, 3, 208), (100, 4, 208),
                                           (16, 4, 8), (7, 1, 8)])
def test_the_parts_cover_the_cloth_in_eights_the_first_longer_by_the_lead(n, parts, lead):
    """the cut: ranges one after another from 0 to n, each starting on a whole
    eight (or empty at n), the first ``lead`` points longer than the next to
    within an eight (while there are points enough), and none longer than the first"""
    spans = [_part_span(n, parts, t, lead) for t in range(parts)]
    assert spans[0][0] == 0 and spans[-1][1] == n
    assert all(a[1] == b[0] for a, b in zip(spans, spans[1:]))
    assert all((lo % AHEAD_STEP == 0 or lo == n) and lo <= hi for lo, hi in spans)  # empty at the end
    sizes = [hi - lo for lo, hi in spans]
    assert max(sizes) == sizes[0]
    if parts > 1 and n > parts * (lead + AHEAD_STEP):
        assert abs(sizes[0] - sizes[1] - lead) <= AHEAD_STEP


def test_disabled_kind_adds_no_force():
    """k of 0 for a set means no force from it, however stretched, even after a step
    in which it was on (its buffered forces are not reused)"""
    m = grid_model(4, 4)
    pos = m.rest_positions * 2.0
    g = np.array([0, -9.8, 0.0])
    np.testing.assert_allclose(accelerations(pos, m, np.zeros(6), g), np.tile(g, (m.num_points, 1)))
    st = stencil(m)
    F = force_buffer(st, m.num_points)
    for k_sets in (np.full(6, 5.0), np.zeros(6)):
        P, L = planes(pos), planes(pos)
        run_integrate(P, L, np.ones(m.num_points), knobs(k_sets, g, 0.0, 1.0), st, F)
    np.testing.assert_allclose((P - planes(pos)).T, np.tile(g, (m.num_points, 1)))


def test_verlet_formula_and_pins():
    """x' = x + (1-d)(x - x_prev) + a dt^2 for free points; pinned points untouched"""
    m = grid_model(2, 2)
    st = stencil(m)
    P = planes(np.array([[1.0, 2, 3], [2.0, 2, 3], [0, 0, 0], [0, 0, 0]]))
    L = planes(np.array([[0.5, 2, 3], [1.5, 2, 3], [0, 0, 0], [0, 0, 0]]))
    run_integrate(P, L, np.array([1.0, 0.0, 1.0, 1.0]), knobs(np.zeros(6), [0.0, -10, 0], 0.9, 0.01), st,
                  force_buffer(st, 4))
    np.testing.assert_allclose(P[:, 0], [1.0 + 0.9 * 0.5, 2 - 0.1, 3])
    np.testing.assert_allclose(L[:, 0], [1.0, 2, 3])
    np.testing.assert_array_equal(P[:, 1], [2.0, 2, 3])


def run_provot(m, pos, enabled, windows=None):
    """The kernel's pass over each window (lo, hi, crossing) in turn; by default all springs."""
    st = stencil(m)
    P = planes(pos)
    for lo, hi, crossing in windows or [(0, m.num_points, False)]:
        provot(P, st, np.asarray(enabled), np.zeros((2, m.num_points // BLOCK + 2), np.uint64), lo, hi,
               crossing)
    return P.T.copy()


def test_provot_independent_springs_end_at_110_percent():
    """vertical springs of a 3x2 grid share no point: one pass leaves each at exactly 1.1x,
    half to each end, all to the free end, none when both ends are pinned"""
    m = grid_model(3, 2, pinned=[(0, 0), (2, 0), (2, 1)])
    pos = m.rest_positions.copy()
    pos[3:, 2] = 1.6  # row 1 moved so every vertical spring is at 160%
    after = run_provot(m, pos, [False, True, False, False, False, False])
    length = np.abs(after[3:, 2] - after[:3, 2])
    np.testing.assert_allclose(length[:2], 1.1, rtol=1e-12)
    assert length[2] == 1.6  # both ends pinned: untouched
    np.testing.assert_array_equal(after[m.pinned], pos[m.pinned])
    assert after[1, 2] + after[4, 2] == pytest.approx(pos[1, 2] + pos[4, 2])  # half each: midpoint stays


def in_window(a, b, window):
    """whether the spring from point a to point b > a belongs to window (lo, hi, crossing)"""
    lo, hi, crossing = window
    return a < lo <= b if crossing else lo <= a and b < hi


def reference_provot(m, pos, enabled, windows=None):
    """Plain sequential Gauss-Seidel over the springs in the kernel's batch order,
    window by window."""
    st = stencil(m)
    pos = pos.copy()
    pinned = m.pinned
    for window, s, half in itertools.product(windows or [(0, m.num_points, False)], range(6), range(2)):
        if not enabled[s]:
            continue
        for p in np.flatnonzero((st.limit[s] < NO_LIMIT) & (st.batch[s] == half)):
            a, b = p + st.start[s], p + st.end[s]
            if not in_window(a, b, window):
                continue
            d = pos[b] - pos[a]
            length = np.linalg.norm(d)
            limit = 1.1 * st.rest[s, p]
            if length <= limit or (pinned[a] and pinned[b]):
                continue
            e = (length - limit) / length
            ca = 0.0 if pinned[a] else (e if pinned[b] else e / 2)
            cb = 0.0 if pinned[b] else (e if pinned[a] else e / 2)
            pos[a] += ca * d
            pos[b] -= cb * d
    return pos


def test_provot_is_a_sequential_pass():
    """on a randomly stretched grid the kernel equals a one-spring-at-a-time pass
    (so batching springs that share no point changes nothing), disabled sets skipped"""
    m = grid_model(8, 7, pinned=[(0, 0), (7, 0), (3, 3)])
    rng = np.random.default_rng(5)
    pos = m.rest_positions + rng.normal(scale=0.3, size=m.rest_positions.shape)
    for enabled in ([True] * 6, [True, True, False, False, True, True], [False] * 6):
        np.testing.assert_allclose(run_provot(m, pos, enabled), reference_provot(m, pos, enabled),
                                   rtol=0, atol=1e-11)


def test_provot_in_parts_takes_each_spring_once():
    """cut into parts (both ends inside each part, then the springs across each
    cut), the pass takes every spring exactly once and equals the sequential pass
    in that order; the parts' passes touch no point outside their part"""
    m = grid_model(8, 9, pinned=[(0, 0), (7, 0)])
    st = stencil(m)
    n = m.num_points
    cuts = [0, 21, 45, n]  # not on row boundaries
    windows = [(lo, hi, False) for lo, hi in zip(cuts, cuts[1:])] + [(c, c, True) for c in cuts[1:-1]]
    for s in range(6):
        for p in np.flatnonzero(st.valid[s]):
            a, b = p + st.start[s], p + st.end[s]
            assert sum(in_window(a, b, w) for w in windows) == 1, (s, p)
    rng = np.random.default_rng(3)
    pos = m.rest_positions + rng.normal(scale=0.3, size=m.rest_positions.shape)
    after = run_provot(m, pos, [True] * 6, windows)
    np.testing.assert_allclose(after, reference_provot(m, pos, [True] * 6, windows), rtol=0, atol=1e-11)
    part = run_provot(m, pos, [True] * 6, [(21, 45, False)])
    outside = np.r_[0:21, 45:n]
    np.testing.assert_array_equal(part[outside], pos[outside])
    assert not np.allclose(part[21:45], pos[21:45])


def test_provot_finds_sparse_stretch_on_a_large_grid():
    """a few displaced points among thousands of springs at rest: the kernel, which
    only corrects blocks with a spring over the limit and skips the rows a batch does
    not own, still matches the sequential pass, and springs at rest are untouched"""
    m = grid_model(40, 30, pinned=[(0, 0), (39, 0)])
    rng = np.random.default_rng(11)
    pos = m.rest_positions.copy()
    moved = rng.choice(m.num_points, size=6, replace=False)
    pos[moved] += rng.normal(scale=0.2, size=(6, 3))
    after = run_provot(m, pos, [True] * 6)
    np.testing.assert_allclose(after, reference_provot(m, pos, [True] * 6), rtol=0, atol=1e-11)
    assert not np.allclose(after[moved], pos[moved])
    far = np.ones(m.num_points, bool)
    grid_index = np.arange(m.num_points).reshape(30, 40)
    for p in moved:
        r, i = divmod(int(p), 40)
        far[grid_index[max(r - 2, 0):r + 3, max(i - 2, 0):i + 3].ravel()] = False
    np.testing.assert_array_equal(after[far], pos[far])


def test_provot_checks_again_what_the_first_batch_stretched():
    """a row of three points: the first spring (first batch) at 150%, the second
    (second batch) at 105%. Correcting the first moves the middle point and
    stretches the second past 110%: the pass must shorten it too, as a
    sequential pass does, although it was under the limit when checked"""
    m = grid_model(3, 2, pinned=[(2, 0), (0, 1), (1, 1), (2, 1)])
    pos = m.rest_positions.copy()
    pos[:3, 0] = [0.0, 1.5, 2.55]
    after = run_provot(m, pos, [True, False, False, False, False, False])
    np.testing.assert_allclose(after, reference_provot(m, pos, [True] + [False] * 5), rtol=0, atol=1e-12)
    assert after[2, 0] - after[1, 0] == pytest.approx(1.1, rel=1e-12)  # all to the free end
    assert after[0, 0] == pytest.approx(0.2, rel=1e-12)  # the first: half of 0.4 to each end


def test_provot_batches_share_no_point():
    """the premise of the batching: within a batch no point is touched twice"""
    m = grid_model(9, 8)
    st = stencil(m)
    for s in range(6):
        for half in range(2):
            p = np.flatnonzero((st.limit[s] < NO_LIMIT) & (st.batch[s] == half))
            ends = np.concatenate([p + st.start[s], p + st.end[s]])
            assert len(np.unique(ends)) == len(ends), (s, half, SET_STEP[s])
        np.testing.assert_array_equal(st.limit[s] < NO_LIMIT, st.valid[s] == 1)


def test_sphere_pushes_to_surface_with_friction():
    """a point inside goes to last + (1-f)(surface - last), surface on the ray from the centre"""
    sphere = np.array([[0.0, 0, 0, 1.0, 0.25]])
    P = planes(np.array([[0.0, 0.5, 0.0], [0.0, 0.5, 0.0], [0.0, 2.0, 0.0]]))
    L = planes(np.array([[0.2, 1.2, 0.0], [0.2, 1.2, 0.0], [0.0, 2.0, 0.0]]))
    collide_spheres(P, L, np.array([1.0, 0.0, 1.0]), still(sphere), 0, 3, 0)
    surface = np.array([0.0, 1.0, 0.0])
    np.testing.assert_allclose(P[:, 0], L[:, 0] + 0.75 * (surface - L[:, 0]))
    np.testing.assert_array_equal(P[:, 1], [0.0, 0.5, 0.0])  # pinned: stays inside
    np.testing.assert_array_equal(P[:, 2], [0.0, 2.0, 0.0])  # outside: untouched


def test_plane_puts_crossing_point_back_on_its_side():
    """a point that crossed the plane ends on its old side, PLANE_OFFSET off it (no friction)"""
    plane = np.array([[0.0, 0, 0, 0, 1, 0, 0.0]])
    P = planes(np.array([[0.3, -0.2, 0.1], [0.0, -0.5, 0.0]]))
    L = planes(np.array([[0.3, 0.1, 0.1], [0.0, -0.4, 0.0]]))  # the second was already below: not crossing
    collide_planes(P, L, np.ones(2), still(plane), 0, 2, 0)
    np.testing.assert_allclose(P[:, 0], [0.3, PLANE_OFFSET, 0.1])
    np.testing.assert_allclose(P[:, 1], [0.0, -0.5, 0.0])


def test_plane_friction_one_returns_to_last():
    """with friction 1 a crossing point goes back to where it was"""
    plane = np.array([[0.0, 0, 0, 0, 1, 0, 1.0]])
    P = planes(np.array([[0.3, -0.2, 0.4]]))
    L = planes(np.array([[0.1, 0.1, 0.1]]))
    collide_planes(P, L, np.ones(1), still(plane), 0, 1, 0)
    np.testing.assert_allclose(P[:, 0], L[:, 0])


def points_group(rest, free, thickness, span=np.inf):
    """the points group as self-collision takes it (the blow-up centre is not read there)"""
    return Points(rest=np.array(rest, dtype=np.float64), free=np.asarray(free, dtype=np.float64),
                  thickness=float(thickness), center=np.zeros(3), span=float(span),
                  triangles=np.zeros((0, 3), dtype=np.int32), order=np.arange(len(free)))


def collide_in_place(P, rest, free, thickness, steps, lists, span=np.inf):
    """self_collide() on the (3, N) positions P in place: (the list with its pairs now, colliding pairs)"""
    pairs, hits = self_collide(P, points_group(rest, free, thickness, span), steps, lists, lists.pairs)
    return lists._replace(pairs=pairs), hits


def build(P, rest, reach, radius, lists, pairs):
    """build_list() of the (3, N) positions P into ``pairs``, with no span"""
    return build_list(P, np.array(rest, dtype=np.float64), reach, radius, np.inf, lists, pairs)


PUSH_ROUNDING = 2.0 ** -22
"""how far, as a share of the reach, a point pushed by self-collision may be from
the double-precision reference: the pushes and their sums are kept in single
precision (``buffers.PUSH_DTYPE``), each push within 2**-24 of its size, which is
at most the reach. A push to a wrong pair, or a missing one, is thousands of
times that"""


def _self_collide(pos, rest, thickness, steps=1, pinned=None, lists=None):
    """Run the kernel on (N, 3) positions in place; return (the number of colliding
    pairs, the neighbour list with its pairs now)."""
    n = len(pos)
    free = np.ones(n) if pinned is None else (~pinned).astype(float)
    x = NeighbourList.allocate(n) if lists is None else lists
    P = planes(pos)
    x, hits = collide_in_place(P, rest, free, thickness, steps, x)
    pos[:] = P.T
    return hits, x


def test_self_collision_pushes_pair_apart():
    """two close points each move to 2*thickness from the other's old place"""
    t = 0.01
    pos = np.array([[0.995, 0.5, 0.5], [1.005, 0.5, 0.5]])
    before = pos.copy()
    rest = np.array([[0.0, 0, 0], [5.0, 0, 0]])  # far apart at rest
    assert _self_collide(pos, rest, t)[0] == 1
    np.testing.assert_allclose(np.linalg.norm(pos[0] - before[1]), 2 * t, rtol=PUSH_ROUNDING)
    np.testing.assert_allclose(np.linalg.norm(pos[1] - before[0]), 2 * t, rtol=PUSH_ROUNDING)


def test_self_collision_pushes_once():
    """the pushes of one substep are not applied again in the next: after a collision
    the push buffers are back at zero, and a second call with the pair already
    apart moves nothing"""
    t = 0.01
    pos = np.array([[0.995, 0.5, 0.5], [1.005, 0.5, 0.5], [0.3, 0.3, 0.3]])
    rest = np.array([[0.0, 0, 0], [5.0, 0, 0], [9.0, 0, 0]])
    hits, x = _self_collide(pos, rest, t, lists=NeighbourList.allocate(3))
    assert hits == 1
    assert not x.push.any() and not x.count.any()
    apart = pos.copy()
    assert _self_collide(pos, rest, t, lists=x)[0] == 0
    np.testing.assert_array_equal(pos, apart)


def test_self_collision_averages_and_divides_by_steps():
    """the push on a point is the mean over its colliding neighbours divided by simulation_steps"""
    t = 0.05
    pos = np.array([[0.0, 0, 0], [0.06, 0, 0], [0.0, 0.08, 0]])
    rest = np.array([[0.0, 0, 0], [10.0, 0, 0], [20.0, 0, 0]])
    before = pos.copy()
    _self_collide(pos, rest, t, steps=4)
    expected = (np.array([-(0.1 - 0.06), 0, 0]) + np.array([0, -(0.1 - 0.08), 0])) / 2 / 4
    np.testing.assert_allclose(pos[0] - before[0], expected, atol=1e-12)


def test_self_collision_ignores_pairs_close_at_rest_and_pins():
    """neighbours already closer than 2*thickness at rest are not pushed; a pinned point stays"""
    pos = np.array([[0.0, 0, 0], [0.01, 0, 0], [0.0, 0.005, 0.0]])
    rest = np.array([[0.0, 0, 0], [0.01, 0, 0], [9.0, 9.0, 9.0]])
    before = pos.copy()
    assert _self_collide(pos, rest, 0.0095, pinned=np.array([True, False, False]))[0] == 2
    np.testing.assert_array_equal(pos[0], before[0])
    assert pos[1, 0] > before[1, 0]  # pushed only by point 2, away from it


def brute_force_pairs(pos, rest, reach):
    d = np.linalg.norm(pos[:, None] - pos[None], axis=2)
    r = np.linalg.norm(rest[:, None] - rest[None], axis=2)
    return int(np.triu((d < reach) & (r >= reach) & (d > 0), 1).sum())


@pytest.mark.parametrize("parts,skin", [(1, 0.5), (2, 0.5), (1, 0.75)])
def test_self_collision_matches_brute_force_as_points_move(parts, skin):
    """the neighbour list finds exactly the colliding pairs a fresh search finds, call after
    call while the points drift, jump and move together, reusing its buffers; also
    built in parts, whose shares of the list are closed up into one, and with
    the wider skin of a coarse cloth"""
    rng = np.random.default_rng(7)
    n, t = 400, 0.02
    pos = rng.uniform(0, 0.3, size=(n, 3))
    rest = rng.uniform(0, 3, size=(n, 3))
    lists = NeighbourList.allocate(n, parts=parts, skin=skin)
    lists = lists._replace(pairs=np.zeros((2, 8), dtype=np.int32))  # too small: the kernel must grow it
    for step in range(40):
        expected = brute_force_pairs(pos, rest, 2 * t)
        probe = pos.copy()
        hits, lists = _self_collide(probe, rest, t, steps=10 ** 9, lists=lists)
        assert hits == expected, step
        pos += rng.normal(scale=0.002, size=pos.shape)  # drift a little each call
        pos += [0.01, -0.02, 0.0]                       # and all together
        if step % 10 == 9:
            pos[rng.integers(n)] = rng.uniform(0, 0.3, 3)  # one point jumps
    assert 1 < lists.rebuilds < 40


def test_coarse_cloths_take_the_wider_skin():
    """a cloth whose wider list radius takes in only its rows, columns and diagonals
    gets the wider skin; finer cloths, whose stencil it would fill with rings
    of grid neighbours, keep the narrow one"""
    for n, expected in [(30, COARSE_SKIN), (50, COARSE_SKIN), (70, SKIN_FACTOR), (100, SKIN_FACTOR)]:
        spec = ClothSpec(width=1.0, height=1.0, num_width_points=n, num_height_points=n,
                         thickness=0.0095, orientation=0, pinned=[])
        m = build_model(spec)
        assert skin_factor(m.rest_positions, n, n, m.thickness) == expected, n


def test_neighbour_list_holds_exactly_the_pairs_within_the_radius():
    """a dense clump (candidate ranges of several WIDE chunks) and a sparse cloud
    (ranges within one NARROW chunk) in one search: the list holds each pair
    closer than the radius and apart at rest exactly once, and no other but a
    few a rounding error outside the radius"""
    rng = np.random.default_rng(11)
    clump = rng.uniform(0, 0.05, size=(300, 3))
    cloud = rng.uniform(0.2, 1.2, size=(300, 3))
    pos = np.concatenate([clump, cloud])
    rest = rng.uniform(0, 3, size=pos.shape)
    rest[:20] = rest[0] + rng.uniform(0, 0.001, size=(20, 3))  # close at rest: never listed
    reach, radius = 0.02, 0.03
    n = len(pos)
    x = NeighbourList.allocate(n)
    pairs = np.zeros((2, n * n // 2), dtype=np.int32)
    found = build(planes(pos), rest, reach, radius, x, pairs)
    d = np.linalg.norm(pos[:, None] - pos[None], axis=2)
    r = np.linalg.norm(rest[:, None] - rest[None], axis=2)
    expected = {(a, b) for a, b in zip(*np.nonzero(np.triu((d < radius) & (r >= reach), 1)))}
    listed = [tuple(sorted(p)) for p in pairs[:, :found].T.tolist()]
    assert len(listed) == len(set(listed)) == found
    assert set(listed) >= expected
    # beyond those, only pairs within the single-precision rounding of the radius
    extra = np.array(sorted(set(listed) - expected)).reshape(-1, 2)
    assert np.all(r[extra[:, 0], extra[:, 1]] >= reach)
    assert np.all(d[extra[:, 0], extra[:, 1]] < radius * (1 + 1e-4))
    assert len(extra) < 0.01 * len(expected)
    assert any(a < 20 and b < 20 for a, b in zip(*np.nonzero(np.triu(d < radius, 1))))
    # the clump's cells hold more points than two WIDE chunks, the cloud's fewer than one NARROW
    counts = np.diff(x.cell_start[:int(x.cell_start.argmax()) + 1])
    assert counts.max() > 2 * WIDE and np.median(counts[counts > 0]) < NARROW


def single(P, ref):
    """the positions and the reference as the drift test takes them: in single precision"""
    return P.astype(np.float32), ref.astype(np.float32)


def magnitudes(P, ref):
    """the largest magnitudes of a coordinate of both, which bound their rounding"""
    return float(np.abs(P).max() + np.abs(ref).max())


def test_drift_test_bounds_every_pair():
    """the list is kept while no two displacements can differ by the skin, whichever
    points moved, and given up as soon as two might or a coordinate is not finite;
    while it is kept, the bound exceeds every difference of two displacements"""
    rng = np.random.default_rng(2)
    ref = rng.uniform(0, 1, size=(3, 5000))
    skin = 0.01

    def bound(P):  # no centres kept from before
        Q, reference = single(P, ref)
        centres = np.zeros((2, 3))  # the parts' steps taken as the substep takes them
        return drift_bound(Q, reference, skin, centres, magnitudes(P, ref), levels(Q, reference, skin, centres, 3))

    def widest(P):  # the largest difference of two displacements, along each axis and overall
        d = P - ref
        return np.linalg.norm(d.max(axis=1) - d.min(axis=1))

    # all alike: rigid shift; the bound is widened by a hair for the rounding
    assert bound(ref + [[0.3], [-0.2], [0.1]]) <= skin / 16 * (1 + 2 ** -18) + 3 * 2 ** -18
    part = ref.copy()
    part[1, :500] -= 0.9 * skin  # a tenth falls, the rest stays: pairs differ by 0.9 skin
    assert 0.9 * skin < bound(part) < skin
    one = ref.copy()
    one[0, 4321] += 1.01 * skin  # a single point, off the sample's stride, moves past the skin
    assert np.isinf(bound(one))
    spread = ref + rng.normal(scale=0.2 * skin, size=ref.shape)
    assert np.isinf(bound(spread))  # random motion: some pair may differ by the skin
    for scale in (0.01, 0.05, 0.1):  # smaller random motion: kept, with a bound above every pair
        jitter = ref + rng.normal(scale=scale * skin, size=ref.shape) + [[0.02], [0.0], [-0.01]]
        b = bound(jitter)
        d = jitter - ref
        pairwise = np.linalg.norm(d[:, :, None] - d[:, None, :1000], axis=0).max()
        assert pairwise < b < 2.5 * widest(jitter) + skin / 16, scale
    bad = ref.copy()
    bad[2, 17] = np.nan
    assert np.isinf(bound(bad))


def test_drift_test_keeps_centres_while_they_hold():
    """centres that still hold every displacement are kept; ones that no longer do
    are chosen afresh, so the verdict is that of fresh centres, a NaN included"""
    rng = np.random.default_rng(3)
    ref = rng.uniform(0, 1, size=(3, 5000))
    skin = 0.01
    centres = np.zeros((2, 3))

    def drifted(P):
        Q, reference = single(P, ref)
        return np.isinf(drift_bound(Q, reference, skin, centres, magnitudes(P, ref),
                                    levels(Q, reference, skin, centres, 2)))

    part = ref.copy()
    part[1, :2500] -= 0.6 * skin  # half falls: only the box middle holds
    assert not drifted(part)
    np.testing.assert_allclose(centres[1], [0, -0.3 * skin, 0], atol=1e-7)  # single precision
    chosen = centres.copy()
    part[1, :2500] -= 0.1 * skin  # the old middle still holds (0.4 skin < 0.5 skin)
    assert not drifted(part)
    np.testing.assert_array_equal(centres, chosen)
    part += [[0.0], [0.0], [0.4 * skin]]  # all shift: the old centres fail, new ones hold
    assert not drifted(part)
    np.testing.assert_allclose(centres[1], [0, -0.35 * skin, 0.4 * skin], atol=1e-7)
    part[1, :2500] -= 0.4 * skin  # the halves now differ by 1.1 skin: no centre holds
    assert drifted(part)
    part[1, :2500] += 0.4 * skin
    part[0, 99] = np.nan
    assert drifted(part)


def test_self_collision_on_a_widely_spread_cloud_uses_coarser_cells():
    """clusters metres apart would need far more cells than the buffer holds: the
    grid coarsens and still finds exactly the brute-force pairs"""
    rng = np.random.default_rng(3)
    centres = rng.uniform(0, 50, size=(8, 3))
    pos = (centres[:, None, :] + rng.uniform(0, 0.1, size=(8, 25, 3))).reshape(-1, 3)
    rest = rng.uniform(0, 30, size=pos.shape)
    t = 0.01
    assert _self_collide(pos.copy(), rest, t, steps=10 ** 9)[0] == brute_force_pairs(pos, rest, 2 * t) > 0


def test_bounds_on_the_bits_match_min_and_max():
    """the box from the integer keys equals NumPy's min and max for negative, positive,
    signed-zero and tiny coordinates; inf or NaN anywhere gives False"""
    rng = np.random.default_rng(2)
    P = rng.normal(scale=1e3, size=(3, 1001))
    P[0, :4] = [-0.0, 0.0, 5e-324, -5e-324]
    P[1] = np.abs(P[1])          # all positive
    P[2] = -np.abs(P[2]) - 1.0   # all negative
    lo, hi = np.empty(3), np.empty(3)
    assert bounds(P, lo, hi)
    np.testing.assert_array_equal(lo, P.min(axis=1))
    np.testing.assert_array_equal(hi, P.max(axis=1))
    for bad in (np.inf, -np.inf, np.nan):
        Q = P.copy()
        Q[1, 500] = bad
        assert not bounds(Q, lo, hi)


def test_self_collision_skips_a_blown_up_state():
    """non-finite positions or a spread beyond the span build no list and push nothing"""
    pos = np.array([[0.0, 0, 0], [0.001, 0, 0], [np.nan, 0, 0]])
    rest = np.array([[0.0, 0, 0], [5.0, 0, 0], [9.0, 0, 0]])
    x = NeighbourList.allocate(3)
    P = planes(pos)
    x, hits = collide_in_place(P, rest, np.ones(3), 0.01, 1, x)
    assert hits == 0 and x.rebuilds == 0
    pos[2] = [1e6, 0, 0]
    P = planes(pos)
    x, hits = collide_in_place(P, rest, np.ones(3), 0.01, 1, x, span=1e3)
    assert hits == 0 and x.rebuilds == 0
    np.testing.assert_array_equal(P.T, pos)
    x, hits = collide_in_place(P, rest, np.ones(3), 0.01, 1, x, span=1e7)
    assert hits == 1 and x.rebuilds == 1


def reference_self_collision(pos, rest, free, reach, steps):
    """every pair closer than reach now and not at rest, pushed apart, averaged, / steps"""
    d = pos[:, None] - pos[None]
    dist = np.linalg.norm(d, axis=2)
    at_rest = np.linalg.norm(rest[:, None] - rest[None], axis=2)
    hit = (dist < reach) & (at_rest >= reach) & (dist > 0)
    scale = np.where(hit, (reach - dist) / np.where(hit, dist, 1.0), 0.0)
    push = (d * scale[..., None]).sum(axis=1)
    count = hit.sum(axis=1)
    return pos + push * free[:, None] / steps / np.maximum(count, 1)[:, None], int(hit.sum()) // 2


@pytest.mark.parametrize("parts", [1, 2])
@pytest.mark.parametrize("points", [60, 400])
def test_few_and_many_pushes_move_points_alike(points, parts):
    """a handful of colliding pairs (only their ends are visited) and hundreds (every
    point is) push as the brute-force reference does (to the rounding of the pushes,
    PUSH_ROUNDING), pinned points stay,
    and the buffers are left at zero"""
    rng = np.random.default_rng(points)
    pos = rng.uniform(0, 0.25, size=(points, 3))
    rest = rng.uniform(0, 5, size=(points, 3))
    pinned = rng.uniform(size=points) < 0.2
    free = (~pinned).astype(float)
    expected, hits = reference_self_collision(pos, rest, free, 0.04, 3)
    assert (hits <= SPARSE_PAIRS) == (points == 60) and hits > 5
    x = NeighbourList.allocate(points, parts=parts)
    P = planes(pos)
    x, found = collide_in_place(P, rest, free, 0.02, 3, x)
    assert found == hits
    np.testing.assert_allclose(P.T, expected, rtol=0, atol=PUSH_ROUNDING * 0.04)
    assert not x.push.any() and not x.count.any()


TALLY_PUSHED = 1
"""the column of NeighbourList.tally that holds the pairs each part pushed"""


@pytest.mark.parametrize("parts", [1, 2])
def test_touching_bucket_that_drifts_apart_pushes_only_the_pairs_still_touching(parts):
    """the pairs that touched at the build are pushed without a branch, and those
    that no longer touch still pass through the pass: with exactly SPARSE_PAIRS
    of them touching, listed before the ones that drifted apart, the sparse
    apply must still move the ends of every touching pair, as brute force does"""
    each = SPARSE_PAIRS + 8  # pairs per part
    pairs = each * parts
    pos = np.zeros((2 * pairs, 3))
    pos[0::2, 0] = np.arange(pairs)  # pairs a metre apart along x, each 0.03 across
    pos[1::2, 0] = np.arange(pairs) + 0.03
    rest = np.arange(2 * pairs)[:, None] * np.array([[1.0, 1.0, 1.0]])
    free = np.ones(2 * pairs)
    x = NeighbourList.allocate(2 * pairs, parts=parts)
    x, hits = collide_in_place(planes(pos), rest, free, 0.02, 3, x)
    ends = x.meta[BUCKET:].reshape(parts, SLACK_BUCKETS)
    # each part owns the pairs of its half of the points, and they all touch
    assert hits == pairs and x.rebuilds == 1
    np.testing.assert_array_equal(ends[:, 0], each * np.arange(1, parts + 1))
    moved = pos.copy()
    # the last 8 pairs of each part's block of the list, in the list's order
    listed = x.pairs[:, :pairs].min(axis=0) // 2  # the pair each entry is
    drifted = np.zeros(pairs, dtype=bool)
    for t in range(parts):
        drifted[listed[(t + 1) * each - 8:(t + 1) * each]] = True
    moved[2 * np.flatnonzero(drifted) + 1, 0] += 0.011  # past the reach, within the skin
    expected, hits = reference_self_collision(moved, rest, free, 0.04, 3)
    assert hits == SPARSE_PAIRS * parts
    P = planes(moved)
    x, found = collide_in_place(P, rest, free, 0.02, 3, x)
    assert x.rebuilds == 1 and found == hits
    assert np.all(x.tally[:parts, TALLY_PUSHED] == SPARSE_PAIRS)  # the sparse apply, at its limit
    np.testing.assert_allclose(P.T, expected, rtol=0, atol=PUSH_ROUNDING * 0.04)
    assert not x.push.any() and not x.count.any()


def sorted_pairs(pairs):
    """(2, K) pairs in lexicographic order: builds may list them in any order"""
    return pairs[:, np.lexsort(pairs[::-1])]


class Near(NamedTuple):
    """what near_stencil() returns, by name"""

    offsets: np.ndarray
    weight: np.ndarray
    table: np.ndarray
    metric: np.ndarray


EXACT = 3
"""the field of grid_metric()'s (row spacing², column spacing², rho², exact) that says whether it is exact"""


def stencil_of(rest, n, thickness, skin=SKIN_FACTOR) -> Near:
    return Near._make(near_stencil(rest, n, n, thickness, skin))


def folded_cloth(n, ratio, squeeze):
    """(model, near stencil, positions) of an n x n cloth with thickness ratio/(n-1),
    squeezed, its far half folded back over the near half, jittered"""
    spec = ClothSpec(width=1.0, height=1.0, num_width_points=n, num_height_points=n,
                     thickness=ratio / (n - 1), orientation=0, pinned=[[0, 0]])
    m = build_model(spec)
    near = stencil_of(m.rest_positions, n, m.thickness)
    rng = np.random.default_rng(n)
    pos = m.rest_positions * [squeeze, 1, squeeze]
    half = m.rest_positions[:, 2] > 0.5
    pos[half, 2] = 1.0 * squeeze - pos[half, 2]
    pos[half, 1] += 0.6 * m.thickness
    pos += rng.normal(scale=0.15 * m.thickness, size=pos.shape)
    return m, near, pos


@pytest.mark.parametrize("n,ratio", [(30, 1 / 2.4), (40, 0.75), (60, 1.2)])
def test_grid_metric_ellipse_keeps_a_margin_for_single_precision(n, ratio):
    """the build tests the ellipse in single precision, so its edge must lie well
    between the offsets it holds and those it does not; where a marked offset
    and one not marked lie equally far, it must drop neither"""
    m, near, _ = folded_cloth(n, ratio, 0.9)
    wr2, wc2, rho2, exact = near.metric
    assert exact == 1.0
    dr, di = np.meshgrid(np.arange(NEAR + 2), np.arange(-NEAR - 1, NEAR + 2), indexing="ij")
    value = dr * dr * wr2 + di * di * wc2
    assert np.all(np.abs(value - rho2) > 1e-3 * rho2)
    assert np.any((value < rho2) & ((dr > 0) | (di > 0)))  # it does drop some
    never = np.zeros((NEAR + 1, 2 * NEAR + 1), bool)
    never[0, NEAR + 1] = True  # the next column, but not the next row as near: no gap between them
    tie_wr2, tie_wc2, tie_rho2, tie_exact = grid_metric(m.rest_positions, n, n, never, 2 * m.thickness)
    drops = dr * dr * tie_wr2 + di * di * tie_wc2 < tie_rho2
    assert tie_exact == 0.0 and not np.any(drops & ((dr > 0) | (di > 0)))


@pytest.mark.parametrize("warp", [False, True])
@pytest.mark.parametrize("n,ratio", [(30, 1 / 2.4), (40, 0.75), (60, 1.2)])
def test_grid_metric_drops_only_offsets_the_list_never_holds(n, ratio, warp):
    """the build's early drop of grid neighbours by row and column leaves the list
    exactly as the exact tests alone make it; on a regular grid it also skips
    those tests, and on a rest layout with squeezed columns (pairs two columns
    apart closer than the reach at rest) it must not"""
    m, near, pos = folded_cloth(n, ratio, 0.9)
    rest = m.rest_positions.copy()
    reach = 2 * m.thickness
    if warp:
        col = np.arange(m.num_points) % n
        squeezed = (col >= 10) & (col <= 20)  # pairs 6 columns apart: 0.9 reach at rest
        rest[squeezed, 0] = rest[col == 10, 0].repeat(11) + (col[squeezed] - 10) * 0.15 * reach
        near = stencil_of(rest, n, m.thickness)
    assert near.metric[EXACT] == (0.0 if warp else 1.0)
    lists = []
    for metric in (near.metric, np.zeros(4)):
        x = NeighbourList.allocate(m.num_points, n, near._replace(metric=metric))
        pairs = np.zeros((2, 40 * m.num_points), dtype=np.int32)
        found = build(planes(pos), rest, reach, 1.5 * reach, x, pairs)
        assert 0 < found <= pairs.shape[1]
        lists.append(pairs[:, :found].copy())
    np.testing.assert_array_equal(lists[0], lists[1])
    if warp:  # at rest, the same metric marked exact would have let rest-close pairs in
        counts = []
        for metric in (near.metric, near.metric + [0, 0, 0, 1]):
            x = NeighbourList.allocate(m.num_points, n, near._replace(metric=metric))
            pairs = np.zeros((2, 40 * m.num_points), dtype=np.int32)
            counts.append(build(planes(rest), rest, reach, 1.5 * reach, x, pairs))
        assert counts[1] > counts[0]
    assert grid_metric(rest, n, n, np.zeros((6, 11), bool), reach)[EXACT] == 0.0


@pytest.mark.parametrize("parts", [1, 2])
def test_first_pass_over_a_new_list_sorts_it_by_slack(parts):
    """the pass right after a build orders the list by the part that owns each pair
    (the part whose points the build found it from), then by how far past the
    reach it was: in each part's block the touching pairs first, then buckets
    of slack, each in the build's order, with their ends noted; every pair of
    the build stays, and later passes leave the order be"""
    m, near, pos = folded_cloth(40, 0.75, 0.9)
    reach = 2 * m.thickness
    x = NeighbourList.allocate(m.num_points, 40, near, parts, skin=0.75)
    fresh = np.zeros((2, 40 * m.num_points), dtype=np.int32)
    built = build(planes(pos), m.rest_positions, reach, 1.75 * reach, x, fresh)
    free = np.ones(m.num_points)
    x, _ = collide_in_place(planes(pos), m.rest_positions, free, m.thickness, 3, x)
    listed = int(x.meta[PAIRS])
    assert listed == built
    pairs = x.pairs[:, :listed].copy()
    d = np.linalg.norm(pos[pairs[0]] - pos[pairs[1]], axis=1)
    radius = reach * (1 + 0.001 * x.meta[SKIN])
    steps = (d * d - reach * reach) * (SLACK_BUCKETS - 1) / (radius * radius - reach * reach)
    bucket = np.where(d < reach, 0, np.minimum(1 + np.floor(steps), SLACK_BUCKETS - 1))
    assert x.meta.shape == (BUCKET + SLACK_BUCKETS * parts,)
    ends = x.meta[BUCKET:].reshape(parts, SLACK_BUCKETS)
    assert ends[-1, -1] == listed and len(set(bucket.tolist())) >= 5
    order = {p: k for k, p in enumerate(map(tuple, fresh[:, :built].T.tolist()))}
    rank = np.array([order[p] for p in map(tuple, pairs.T.tolist())])
    assert len(set(rank.tolist())) == built  # the same pairs, each once
    # the build deals its shares of the points out to the parts in turn, and a pair
    # is its first end's; the shares in order are cut into one run per part,
    # which owns their pairs
    shares = x.tally.shape[0]
    share = (pairs[0].astype(np.int64) * shares + shares - 1) // m.num_points  # inverse of part_range
    assert np.all(share * m.num_points // shares <= pairs[0])
    assert np.all(pairs[0] < (share + 1) * m.num_points // shares)
    owner = share * parts // shares
    touching = 0
    for o in range(parts):
        start = 0 if o == 0 else ends[o - 1, -1]
        block = slice(start, ends[o, -1])
        assert np.all(owner[block] == o) and ends[o, -1] > start
        assert np.all(np.diff(bucket[block]) >= 0)
        np.testing.assert_array_equal(start + np.searchsorted(bucket[block], np.arange(SLACK_BUCKETS), side="right"),
                                      ends[o])
        key = share[block] * (built + 1) + rank[block]
        for j in range(SLACK_BUCKETS):
            assert np.all(np.diff(key[bucket[block] == j]) > 0)
        touching += ends[o, 0] - start
    assert touching == np.sum(d < reach) > 0
    assert np.sum(owner == parts - 1) > 0
    P = planes(pos)
    x, _ = collide_in_place(P, m.rest_positions, free, m.thickness, 10 ** 9, x)  # the list holds
    assert x.rebuilds == 1
    np.testing.assert_array_equal(x.pairs[:, :listed], pairs)


@njit
def _run_counts(labels, lo, hi):
    at = np.zeros((SORT_LANES + PAD_ROWS, SLACK_BUCKETS), dtype=np.int64)
    _count_runs(labels, lo, hi, at)
    return at


@pytest.mark.parametrize("length", [0, 5, 63, 64, 8 * 64 - 1, 8 * 64 + 9, 5473, 74299])
def test_the_slack_sort_counts_each_runs_labels(length):
    """the sort's count of each label in each of its SORT_LANES runs (the last
    taking what is left over), 64 labels at a time and the last few one by
    one, is numpy's, from an offset that is no multiple of 64; the rows of
    padding stay 0"""
    rng = np.random.default_rng(length)
    labels = rng.integers(0, SLACK_BUCKETS, length + 40).astype(np.int8)
    lo, hi = 21, 21 + length
    size = length // SORT_LANES
    expected = np.zeros((SORT_LANES + PAD_ROWS, SLACK_BUCKETS), dtype=np.int64)
    for r in range(SORT_LANES):
        stop = lo + (r + 1) * size if r < SORT_LANES - 1 else hi
        expected[r] = np.bincount(labels[lo + r * size:stop], minlength=SLACK_BUCKETS)
    np.testing.assert_array_equal(_run_counts(labels, lo, hi), expected)


@pytest.mark.parametrize("count", [0, 3, 8, 77, 4000])
def test_slack_labels_are_the_exact_arithmetics(count):
    """label_pairs, eight pairs at a time in vector code and the last few one by
    one, gives every pair the bucket of the scalar formula in double
    precision, rounded as written: pairs closer than the reach 0, at it to
    the bit 1, farther out in steps up to the last bucket; only labels
    ``k0:k1`` are written"""
    rng = np.random.default_rng(count)
    n, reach, scale = 200, 0.02, (SLACK_BUCKETS - 1) / 0.004
    P = rng.uniform(-0.03, 0.03, (3, n))
    rows = np.zeros((n, 4))
    rows[:, :3] = P.T
    a = rng.integers(0, n, count + 11).astype(np.int32)
    b = rng.integers(0, n, count + 11).astype(np.int32)
    if count > 5:  # a pair whose squared distance is the reach's square to the bit
        P[:, a[5]], P[:, b[5]] = 0.0, [reach, 0.0, 0.0]
        rows[:, :3] = P.T
    pairs = np.stack([a, b])
    d = P[:, b] - P[:, a]
    d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
    steps = np.minimum(1.0 + (d2 - reach * reach) * scale, SLACK_BUCKETS - 1.0)
    expected = np.where(d2 < reach * reach, 0.0, steps).astype(np.int8)
    labels = np.full(count + 11, -1, dtype=np.int8)
    label_pairs(rows, reach, pairs, 5, 5 + count, labels, scale)
    np.testing.assert_array_equal(labels[5:5 + count], expected[5:5 + count])
    assert np.all(labels[:5] == -1) and np.all(labels[5 + count:] == -1)
    if count > 5:
        assert labels[5] == 1
    if count > 1000:
        assert set(labels[5:5 + count].tolist()) == set(range(SLACK_BUCKETS))


def test_a_substep_checks_the_slack_buckets_its_drift_bound_reaches():
    """the checked front of the list ends with the last bucket whose least slack lies
    below what the bound can reach, and takes the whole list once that nears the skin"""
    meta = np.zeros(BUCKET + SLACK_BUCKETS, dtype=np.int64)
    meta[BUCKET:] = np.cumsum(np.arange(1, SLACK_BUCKETS + 1) * 10)
    ends = meta[BUCKET:]
    assert checked_pairs(meta, 0.0) == ends[1]  # touching, and less than one step past the reach
    assert checked_pairs(meta, 0.999) == ends[1]
    assert checked_pairs(meta, 1.001) == ends[2]
    assert checked_pairs(meta, 3.5) == ends[4]
    assert checked_pairs(meta, (SLACK_BUCKETS - 1) * 0.999) == ends[-1]


@pytest.mark.parametrize("parts", [1, 3])
def test_near_stencil_skips_only_blocks_the_drift_bound_cannot_bring_within_reach(parts):
    """a folded cloth squeezed a little more each call, so that more and more row
    neighbours come within reach: the stencil, which skips blocks whose closest
    pair started farther past the reach than the drift bound, still pushes every
    pair a brute-force pass pushes, call after call on one list; also with the
    blocks cut into parts"""
    n = 40
    m, _, pos = folded_cloth(n, 0.4655, 1.0)  # the standard scenes' thickness over spacing
    reach = 2 * m.thickness
    near = stencil_of(m.rest_positions, n, m.thickness, 0.75)
    np.testing.assert_array_equal(near.offsets, [1, n - 1, n, n + 1])  # rows, columns, diagonals
    lists = NeighbourList.allocate(m.num_points, n, near, parts, skin=0.75)
    free = np.ones(m.num_points)
    rng = np.random.default_rng(5)
    touching = []
    for call in range(60):
        expected, pairs = reference_self_collision(pos, m.rest_positions, free, reach, 10 ** 9)
        P = planes(pos)
        lists, hits = collide_in_place(P, m.rest_positions, free, m.thickness, 10 ** 9, lists)
        assert hits == pairs, call
        if call == 0:  # the build notes each block's closest pair, in levels of squared distance
            span2 = (1.75 * reach) ** 2 - reach ** 2
            for s, o in enumerate(near.offsets):
                d2 = np.sum((pos[o:] - pos[:-o]) ** 2, axis=1)
                d2[near.weight[s][:len(d2)] == 0] = np.inf
                blocks = -(-len(d2) // BLOCK)
                least = [d2[b * BLOCK:(b + 1) * BLOCK].min() for b in range(blocks)]
                expected = np.minimum(np.trunc((np.array(least) - reach ** 2) * NEAR_LEVELS / span2),
                                      NEAR_LEVELS)
                np.testing.assert_array_equal(lists.near_level[s, :blocks], expected)
            levels = lists.near_level[:, :blocks]
            assert np.median(levels[[1, 3]]) > NEAR_LEVELS // 4 > np.median(levels[[0, 2]])  # diagonals: far
        touching.append(int(np.sum(np.linalg.norm(pos[1:] - pos[:-1], axis=1) < reach)))
        pos[:, 0] *= 0.999  # squeeze along the rows
        pos += rng.normal(scale=0.002 * reach, size=pos.shape)
    assert touching[-1] > 1.5 * touching[0] + 100
    assert 1 < lists.rebuilds < 30


@pytest.mark.parametrize("parts", [1, 2])
def test_single_precision_stencil_misses_no_pair_a_hair_inside_the_reach(parts):
    """between builds the stencil tests its pairs in single precision, which rounds
    distances by about 1e-7 here: row neighbours set a hair inside the reach (by
    1e-8 of it) must all still be pushed, and those a hair outside must not"""
    n = 40
    m, _, pos = folded_cloth(n, 0.4655, 1.0)
    reach = 2 * m.thickness
    near = stencil_of(m.rest_positions, n, m.thickness, 0.75)
    lists = NeighbourList.allocate(m.num_points, n, near, parts, skin=0.75)
    free = np.ones(m.num_points)
    P = planes(pos)
    lists, _ = collide_in_place(P, m.rest_positions, free, m.thickness, 10 ** 9, lists)
    rng = np.random.default_rng(7)
    moved = pos.copy()
    rows = rng.choice(np.arange(0, n * n, n), size=30, replace=False)  # one pair per grid row
    for k, a in enumerate(rows + rng.integers(0, n - 1, size=30)):
        unit = (moved[a + 1] - moved[a]) / np.linalg.norm(moved[a + 1] - moved[a])
        moved[a + 1] = moved[a] + unit * reach * (1 + (-1e-8 if k % 2 else 1e-8))
    expected, pairs = reference_self_collision(moved, m.rest_positions, free, reach, 10 ** 9)
    P = planes(moved)
    lists, hits = collide_in_place(P, m.rest_positions, free, m.thickness, 10 ** 9, lists)
    assert lists.rebuilds == 1  # the same list: the stencil ran in single precision
    assert hits == pairs
    np.testing.assert_allclose(P.T, expected, rtol=0, atol=1e-15)


def test_list_build_writes_the_same_pairs_directly_and_stops_at_its_capacity():
    """on a regular grid the build writes each chunk's bits straight into the pairs
    array (two whether there or not, counted only if there); it must list
    exactly what the checked path lists, in the same order, and with too little
    room store the first pairs, count them all and write nothing past the end"""
    m, near, pos = folded_cloth(40, 0.75, 0.9)
    assert near.metric[EXACT] == 1.0  # exact: the direct writes apply
    n, reach = 40, 2 * m.thickness

    def build_with(metric, pairs):
        x = NeighbourList.allocate(m.num_points, n, near._replace(metric=metric))
        return build(planes(pos), m.rest_positions, reach, 1.5 * reach, x, pairs)

    checked = np.zeros((2, 40 * m.num_points), dtype=np.int32)
    total = build_with(near.metric * [1, 1, 1, 0], checked)  # the same ellipse, not marked exact
    direct = np.zeros_like(checked)
    assert build_with(near.metric, direct) == total > 100
    np.testing.assert_array_equal(direct[:, :total], checked[:, :total])
    for room in (total // 3, total - 1):
        store = np.full((2, room + 64), -7, dtype=np.int32)
        assert build_with(near.metric, store[:, :room]) == total
        np.testing.assert_array_equal(store[:, :room], checked[:, :room])
        assert np.all(store[:, room:] == -7)


@pytest.mark.parametrize("parts", [1, 3])
@pytest.mark.parametrize("n,ratio,squeeze", [(30, 1 / 2.4, 0.9), (40, 0.75, 0.95)])
def test_self_collision_with_near_stencil_matches_reference(n, ratio, squeeze, parts):
    """on a cloth whose grid neighbours sit inside the list radius at rest, the near
    stencil (which checks them every substep) and the list (the rest) together push
    like a brute-force pass (to PUSH_ROUNDING): a squeezed, folded, jittered cloth; also with
    the work cut into parts, each with its share of the list, the stencil and the
    pushes"""
    m, near, pos = folded_cloth(n, ratio, squeeze)
    assert len(near.offsets) > 0
    wr2, wc2, rho2, _ = near.metric
    assert rho2 > 1.2 * max(wr2, wc2)  # the build drops row and column neighbours early
    free = (~m.pinned).astype(float)
    expected, pairs = reference_self_collision(pos, m.rest_positions, free, 2 * m.thickness, 3)
    lists = NeighbourList.allocate(m.num_points, n, near, parts)
    P = planes(pos)
    lists, hits = collide_in_place(P, m.rest_positions, free, m.thickness, 3, lists)
    assert hits == pairs > 100
    np.testing.assert_allclose(P.T, expected, rtol=0, atol=PUSH_ROUNDING * 2 * m.thickness)


def test_append_path_follows_the_machine(monkeypatch):
    """the list build appends with AVX-512's compress where the machine has it, and
    FORCE_PORTABLE in the environment turns that off"""
    assert COMPRESS == has_compress()
    monkeypatch.setenv(FORCE_PORTABLE, "1")
    assert not has_compress()


PORTABLE_TESTS = ["test_append_path_follows_the_machine",
                  "test_neighbour_list_holds_exactly_the_pairs_within_the_radius",
                  "test_list_build_writes_the_same_pairs_directly_and_stops_at_its_capacity"]


@pytest.mark.skipif(bool(os.environ.get(FORCE_PORTABLE)), reason="already on the portable path")
def test_portable_append_passes_the_list_tests(tmp_path):
    """the other append, compiled afresh on the portable path, passes the list build's
    tests: on a machine with AVX-512 the portable path runs nowhere else, and on
    one without, these tests run it anyway"""
    env = {**os.environ, FORCE_PORTABLE: "1", "NUMBA_CACHE_DIR": str(tmp_path)}
    ids = [f"{__file__}::{name}" for name in PORTABLE_TESTS]
    run = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *ids],
                         env=env, capture_output=True, text=True)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    assert f"{len(PORTABLE_TESTS)} passed" in run.stdout


def folded_mesh(count, thickness, squeeze, seed=3, curl=0.0):
    """(rest positions, positions) of an irregular sheet of about ``count`` points
    (a Delaunay square, 1 m), squeezed, its far half folded back over the near
    half, jittered; ``curl`` [m] bends the rest sheet out of its plane"""
    from clothsim.procedural import delaunay_square

    mesh = delaunay_square(count=count, side=1.0, spacing=0.6 / np.sqrt(count), seed=seed)
    rest = mesh.vertices + [0.5, 1.0, 0.5]
    rest[:, 1] += curl * np.sin(np.pi * rest[:, 0])
    rng = np.random.default_rng(seed)
    pos = rest * [squeeze, 1, squeeze]
    half = rest[:, 2] > 0.5
    pos[half, 2] = 1.0 * squeeze - pos[half, 2]
    pos[half, 1] += 0.6 * thickness
    pos += rng.normal(scale=0.15 * thickness, size=pos.shape)
    return rest, pos


@pytest.mark.parametrize("parts", [1, 2])
@pytest.mark.parametrize("curl", [0.0, 0.05])
def test_mesh_near_list_and_layout_push_as_the_reference(parts, curl):
    """on an irregular mesh whose neighbours sit inside the list radius at rest, the
    build that drops them by the rest layout, with the near list appended, pushes
    like a brute-force pass (to PUSH_ROUNDING): a squeezed, folded, jittered sheet, flat at
    rest or curled out of its plane (where the projection shortens distances)"""
    from clothsim.solver.selfcollide.nearlist import mesh_near

    thickness = 0.02
    rest, pos = folded_mesh(900, thickness, 0.9, curl=curl)
    n = len(rest)
    reach = 2 * thickness
    mesh = mesh_near(rest, [0, n], reach, reach * 1.5)
    assert mesh is not None and mesh[2].shape[1] > 2 * n  # many neighbours inside the radius
    free = np.ones(n)
    expected, hits = reference_self_collision(pos, rest, free, reach, 3)
    lists = NeighbourList.allocate(n, parts=parts, skin=0.5, mesh=mesh)
    P = planes(pos)
    lists, found = collide_in_place(P, rest, free, thickness, 3, lists)
    assert found == hits > 100
    np.testing.assert_allclose(P.T, expected, rtol=0, atol=PUSH_ROUNDING * reach)
    # the build listed only the pairs the layout keeps, plus the near list
    plain = NeighbourList.allocate(n, parts=parts, skin=0.5)
    collide_in_place(planes(pos), rest, free, thickness, 3, plain)
    assert lists.meta[0] < plain.meta[0] + mesh[2].shape[1]


def test_mesh_layout_keeps_cloths_apart_and_drops_only_pairs_near_at_rest():
    """the rest layout places each cloth apart from the others (no pair of two cloths
    is dropped), and every pair it drops is within a hair of the list radius at rest"""
    from clothsim.solver.selfcollide.nearlist import dropped, layout_metric, rest_layout

    rest_a, _ = folded_mesh(400, 0.01, 1.0, seed=1)
    rest_b = rest_a + [0.0, 0.01, 0.0]  # a second sheet just above the first
    rest = np.concatenate([rest_a, rest_b])
    n = len(rest_a)
    layout32 = rest_layout(rest, [0, n, 2 * n], 0.1).astype(np.float32)
    metric = layout_metric(0.08)
    a, b = np.triu_indices(2 * n, 1)
    gone = dropped(layout32, a, b, metric)
    assert not np.any(gone & ((a < n) != (b < n)))
    d = np.linalg.norm(rest[a] - rest[b], axis=1)
    assert np.all(d[gone] < 0.08 * (1 + 1e-5)) and gone.sum() > 3 * n
