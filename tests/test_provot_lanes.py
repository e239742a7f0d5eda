"""Provot's check as bytes of vector comparisons (:mod:`clothsim.solver.provot_lanes`).

The check must flag exactly the springs over their limit, each at its own
bit, from a block's first spring at any offset; and the pass built on it
must still equal the one-spring-at-a-time pass where a cloth is cut into
parts whose ranges start mid-block.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from clothsim.solver.provot import check_set
from clothsim.solver.provot_lanes import over_word
from clothsim.solver.shared import BLOCK, KERNEL_OPTIONS, gap2

from .test_solver import grid_model, reference_provot, run_provot, stencil


@njit(cache=True)
def words(P, a, b, limit, starts):
    x, y, z = P[0], P[1], P[2]
    out = np.empty(starts.shape[0], dtype=np.uint64)
    for k in range(starts.shape[0]):
        out[k] = over_word((x, y, z), a, b, limit, starts[k])
    return out


def test_each_spring_has_its_own_bit_and_a_spring_at_its_limit_is_not_over():
    """Springs with ends a whole number of sixteenths apart (every sum exact, fused
    or not): one exactly at its limit is not flagged, one whose limit is a unit in
    the last place shorter is; each bit is its own spring's, for blocks starting
    anywhere."""
    rng = np.random.default_rng(7)
    n, a, b = 700, 3, 41
    count = n - b
    # spring p joins point a + p to b + p: place each b + p by its own spring's move
    # from its a + p, so every point is set once, a + p before b + p (a < b)
    pos = rng.integers(-64, 64, size=(3, n)).astype(np.float64) / 16
    moves = np.array([[3, 4, 12], [2, 3, 6], [1, 4, 8], [2, 6, 9]], dtype=np.float64) / 16
    lengths = np.array([13, 7, 9, 11], dtype=np.float64) / 16
    kinds = rng.integers(0, 4, size=count)
    limit = np.empty(count)
    for p in range(count):
        pos[:, b + p] = pos[:, a + p] + moves[kinds[p]] * rng.choice([-1.0, 1.0], size=3)
    expected = np.zeros(count, dtype=bool)
    for p in range(count):
        d = pos[:, b + p] - pos[:, a + p]
        exact = np.sqrt(d @ d)
        choice = rng.integers(0, 3)
        if choice == 0:
            limit[p] = exact  # at the limit: not over
        elif choice == 1:
            limit[p] = np.nextafter(exact, 0.0)  # a unit in the last place short: over
            expected[p] = True
        else:
            limit[p] = exact * rng.uniform(0.5, 2.0)
            expected[p] = limit[p] * limit[p] < d @ d
    gaps = pos[:, b:b + count] - pos[:, a:a + count]
    np.testing.assert_array_equal(np.sqrt((gaps * gaps).sum(axis=0)), lengths[kinds])  # exact
    starts = np.array([0, 1, 5, 63, 64, 100, count - BLOCK], dtype=np.int64)
    got = words(pos, a, b, limit, starts)
    for at, word in zip(starts, got):
        bits = np.array([(int(word) >> j) & 1 for j in range(BLOCK)], dtype=bool)
        np.testing.assert_array_equal(bits, expected[at:at + BLOCK], err_msg=f"block from {at}")
    assert 0 < expected.sum() < count


@njit(**KERNEL_OPTIONS)
def loop_words(P, a, b, limit, first, stop, found):
    """the check as numba's loop makes it (as the pass made every word before,
    and still makes the last few springs'): an or of shifted selects"""
    x, y, z = P[0], P[1], P[2]
    words = 0
    for q in range(first, stop, BLOCK):
        xa, ya, za = x[a + q:], y[a + q:], z[a + q:]
        xb, yb, zb = x[b + q:], y[b + q:], z[b + q:]
        lim = limit[q:]
        mask = np.uint64(0)
        for p in range(min(BLOCK, stop - q)):
            over = gap2(xa, ya, za, p, xb, yb, zb, p) > lim[p] * lim[p]
            mask |= np.uint64(1 if over else 0) << np.uint64(p)
        found[words] = mask
        words += 1
    return words


@njit(cache=True)
def set_words(P, a, b, limit, first, stop, found, again):
    return check_set((P[0], P[1], P[2]), a, b, limit, first, stop, found, again)


def test_springs_at_their_limit_to_the_last_bit_are_told_as_the_loop_tells_them():
    """Limits a few units in the last place about each spring's length, so that
    the test turns on how the squared length rounds: the vector check flags the
    same springs as numba's loop, whose sums fuse their products one way (a
    different fusion flagged a few in a hundred otherwise)."""
    rng = np.random.default_rng(23)
    n, a, b = 4099, 0, 53
    P = rng.uniform(-1.0, 1.0, size=(3, n))
    count = n - b
    d = P[:, b:b + count] - P[:, a:a + count]
    length = np.sqrt((d * d).sum(axis=0))
    limit = length * (1.0 + rng.integers(-3, 4, size=count) * 2.0 ** -52)
    for first, stop in ((0, count), (7, count - 5), (64, 64 + 10 * BLOCK)):
        blocks = -(-(stop - first) // BLOCK)
        expected = np.zeros(blocks, dtype=np.uint64)
        got = np.zeros(blocks, dtype=np.uint64)
        assert loop_words(P, a, b, limit, first, stop, expected) == blocks
        again = np.ones(blocks, dtype=np.uint64)
        assert set_words(P, a, b, limit, first, stop, got, again) == blocks
        np.testing.assert_array_equal(got, expected)
        assert not again.any()  # the pass's marks for the second batch start clear
    flagged = sum(bin(int(w)).count("1") for w in expected)
    assert 0.2 * 10 * BLOCK < flagged < 0.8 * 10 * BLOCK  # the limits fall on both sides


def test_the_pass_cut_into_parts_mid_block_equals_the_sequential_pass():
    """a grid large enough for whole blocks in every set, cut where no block starts:
    the parts' passes (each set's springs from the cut on, in blocks of BLOCK and a
    last few) and the springs across the cuts equal the one-by-one pass"""
    m = grid_model(31, 26, pinned=[(0, 0), (30, 0)])
    n = m.num_points
    rng = np.random.default_rng(19)
    pos = m.rest_positions + rng.normal(scale=0.08, size=m.rest_positions.shape)
    for cuts in ([0, n], [0, 201, 517, n], [0, 77, n]):
        windows = [(lo, hi, False) for lo, hi in zip(cuts, cuts[1:])] + [(c, c, True) for c in cuts[1:-1]]
        after = run_provot(m, pos, [True] * 6, windows)
        np.testing.assert_allclose(after, reference_provot(m, pos, [True] * 6, windows), rtol=0, atol=1e-11)
    assert min(stencil(m).count) > 5 * BLOCK
