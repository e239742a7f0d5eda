"""The mesh kernels' first pass (solver/colliders/meshlook.py): the settle pass's
look at the points a later pass moved, one by one, flags and lists the same
points as the vector pass over every point (where no point has a hint; the
points with one it lists as they are, for the hint pass: test_mesh_prisms.py
checks that the outcome is the same)."""

from __future__ import annotations

import numpy as np
import pytest

from clothsim.solver.colliders.mesh import _grid_scalars, _reach, pack_meshes, pose_rows
from clothsim.solver.colliders.meshgrid import G_H
from clothsim.solver.colliders.meshlook import FEW_MOVED, look, look_settle
from clothsim.solver.colliders.meshpose import frame

from .test_mesh_collider import EYE, ZERO
from .test_mesh_slabs import torus


def turned():
    """a pose turned 30 degrees about z and moved, as rows of a frame"""
    c, s = np.cos(np.pi / 6), np.sin(np.pi / 6)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return pose_rows(R, [0.1, -0.05, 0.02], R, [0.1, -0.05, 0.02], 0.0, 1e-3)


def cloth_over(seed, n=3000):
    """(Q, P) (3, n) [m]: points around the torus, some on its surface, with
    pinned, NaN and infinite ones"""
    rng = np.random.default_rng(seed)
    m = torus()
    on = m.vertices[rng.integers(0, len(m.vertices), n // 2)]
    anywhere = rng.uniform(-1.0, 1.0, (n - n // 2, 3)) * [1.0, 1.0, 0.4]
    Q = np.concatenate([on, anywhere]).T.copy()
    Q[:, rng.integers(0, n, 5)] = np.nan
    Q[1, rng.integers(0, n, 3)] = np.inf
    return Q


def both(ctl_fields, pose, P, Q, free):
    """(count, need, listed) of the vector pass and of :func:`look_settle`"""
    g = ctl_fields["mesh_grid"][0]
    G = _grid_scalars(g)
    reach = _reach(g)
    now = frame(pose, 0)
    limits = (reach, g[G_H] - 2.0 * reach, False, True)
    no_hints = (np.full((1, 0), -1, dtype=np.int32), 0, 0, len(ctl_fields["mesh_tris"]), 0)
    out = []
    for kernel in (look, look_settle):
        need = np.ones(P.shape[1], dtype=np.bool_)
        listed = np.full(P.shape[1], -1, dtype=np.int64)
        args = (P, Q, free, np.int64(0), (now, now), G, limits, ctl_fields["mesh_items"])
        count = kernel(*args, (need, listed), no_hints) if kernel is look_settle else kernel(*args, need, listed)
        out.append((count, need, listed[:count]))
    return out


@pytest.mark.parametrize("moved_share", [0.0, 0.001, 0.05, 1.0 / (FEW_MOVED + 1), 0.5])
# up to one in FEW_MOVED moved, look_settle flags them one by one; beyond, it runs the vector pass
@pytest.mark.parametrize("posed", ["rest", "turned"])
def test_the_settle_pass_flags_the_moved_points_as_the_vector_pass_does(moved_share, posed):
    packed = pack_meshes([torus()])
    pose = pose_rows(EYE, ZERO, EYE, ZERO, 0.0, 1e-3) if posed == "rest" else turned()
    for seed in range(3):
        Q = cloth_over(seed)
        n = Q.shape[1]
        rng = np.random.default_rng(100 + seed)
        P = Q.copy()
        moved = rng.random(n) < moved_share
        P[:, moved] += rng.normal(size=(3, int(moved.sum()))) * rng.choice([1e-4, 3e-3, 0.05], (1, int(moved.sum())))
        free = np.ones(n)
        free[rng.integers(0, n, 20)] = 0.0
        (c0, need0, list0), (c1, need1, list1) = both(packed, pose, P, Q, free)
        assert c0 == c1
        np.testing.assert_array_equal(list0, list1)
        # the kernels read the flags only through the list: a flagged point the
        # vector pass then found quiet may keep its flag there
        assert need0[list0].all() and need1[list1].all()
        assert c0 <= moved.sum()
        if 0.01 < moved_share < 0.5:  # a real share of them near the torus
            assert c0 > 0


def test_only_moved_free_finite_points_near_the_surface_are_listed():
    """a point left where it was, a pinned one and a NaN one are not listed; one moved
    across the torus's surface is"""
    packed = pack_meshes([torus()])
    pose = pose_rows(EYE, ZERO, EYE, ZERO, 0.0, 1e-3)
    top = np.array([0.6, 0.0, 0.2])  # on the tube's top
    Q = np.array([top + [0, 0, 0.002]] * 4).T.copy()
    P = Q.copy()
    P[2, [0, 2, 3]] -= 0.004  # through the surface
    P[0, 3] = np.nan
    free = np.array([1.0, 1.0, 0.0, 1.0])
    for count, need, listed in both(packed, pose, P, Q, free):
        assert count == 1 and listed[0] == 0
        assert need.tolist() == [True, False, False, False]


@pytest.mark.parametrize("closed", [False, True])
def test_the_walks_list_the_busy_flagged_points(closed):
    """the end of the vector pass: the flagged points whose cell is busy (NEAR, or
    inside a closed mesh) or whose move is long (cell -1), list and count as
    NumPy says, their flags kept, for any share of flagged points and lengths that are not a
    multiple of eight; over each word's set bits, and with AVX-512's compress where
    the machine has it (the kernels then use it)"""
    from clothsim.solver.colliders.meshgrid import INSIDE_BITS, NEAR
    from clothsim.solver.colliders.meshlook import COMPRESS, _walk, _walk_compressed, _walk_words
    from clothsim.solver.simd import has_compress

    assert COMPRESS == has_compress()
    walks = (_walk_words, _walk_compressed) if COMPRESS else (_walk_words,)
    assert _walk is walks[-1]
    rng = np.random.default_rng(7)
    items = rng.integers(0, 8, 700).astype(np.int32)  # status entries: NEAR and INSIDE_BITS in the low bits
    s0 = 37
    for n in (0, 1, 7, 8, 9, 63, 64, 65, 1003):
        for share in (0.0, 0.03, 0.5, 1.0):
            need = rng.random(n) < share
            cell = rng.integers(-1, 600, n).astype(np.int32)
            st = items[s0 + np.maximum(cell, 0)]
            busy = need & ((cell < 0) | ((st & NEAR) != 0) | (closed & ((st & INSIDE_BITS) != 0)))
            for walk in walks:
                flags = need.copy()
                listed = np.full(n, -9, dtype=np.int64)
                count = walk(flags, cell, (items, s0, closed), listed)
                np.testing.assert_array_equal(listed[:count], np.flatnonzero(busy))
                # every listed point keeps its flag; an unlisted one may keep it (the
                # kernels read the flags through the list), but only if it had one
                assert flags[busy].all()
                np.testing.assert_array_equal(flags & ~need, False)
            if share == 1.0 and n > 60:
                assert busy.any()  # some cells are busy
