"""The springs' lanes (:mod:`clothsim.solver.spring_lanes`) against numba's loops.

Where ``springs.BY_LANES``, :func:`integrate` moves every point but those
of the last rows through the LLVM vector code of the lanes, eight points a
call with AVX-512 and four without; :func:`integrate_chunks` is the loops
it replaced, which take the last rows, and the whole cloth on AMD's Zen
cores without AVX-512. The lanes are checked on every machine. Both must give
the same positions, last positions and force buffer on any grid (rows shorter than a call and longer), any spring
constants (kinds switched off among them), pins, and the ranges a thread's
part takes: the same to the bit where both divide by the length's square
root (without AVX-512, on an AMD Zen core: ``shared.DIVIDE``), and within
the loops' own error where one of them takes an estimate (the lanes
AVX-512's, ``RSQRT14``, which is checked against the exact forces; the
loops a single-precision one). A test process compiles for one kind of
CPU; ``test_inverse_length.py`` runs these tests again compiled for the
other.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from clothsim.solver.shared import DIVIDE, LINE
from clothsim.solver.spring_lanes import LANES, RSQRT14, force_pad, integrate_eights
from clothsim.solver.springs import (CHUNK, NO_LIMIT, build_stencil, force_buffer, gap_bits, integrate,
                                     integrate_chunks, part_force_buffers)

from .test_solver import grid_model, knobs, planes, stencil


def _state(nw, nh, seed, pins=()):
    """a grid cloth stretched and shaken at random: positions and last positions as planes"""
    m = grid_model(nw, nh, pinned=pins, spacing=0.1)
    rng = np.random.default_rng(seed)
    P = planes(m.rest_positions * rng.uniform(0.8, 1.3) + rng.normal(0.0, 0.02, m.rest_positions.shape))
    L = P + rng.normal(0.0, 0.005, P.shape)
    return m, P, L


def _eights(P, L, free, knobs, springs, F, first, stop, moved):
    """integrate as it runs where BY_LANES: the lanes, then the loops for the rest"""
    done = integrate_eights(P, L, free, knobs, springs, F, first, stop, moved)
    integrate_chunks(P, L, free, knobs, springs, F, done, stop, moved)


def _both(m, P, L, k, first, stop, moved):
    """(P, L, F) after the eights and the loops and after the loops alone, from the same state"""
    springs = stencil(m)
    free = (~m.pinned).astype(np.float64)
    out = []
    for step in (_eights, integrate_chunks):
        p, last, F = P.copy(), L.copy(), force_buffer(springs, P.shape[1])
        step(p, last, free, k, springs, F, first, stop, moved)
        out.append((p, last, F))
    return out


def _same_bits(a, b):
    return np.array_equal(np.ascontiguousarray(a).view(np.int64), np.ascontiguousarray(b).view(np.int64))


FORCE_ERROR = 2e-13
"""how far apart the eights' forces and the loops' may be, of ``k |d|`` (the
loops' single-precision estimate is off by up to 1.3e-13 of it)"""


def _agree(eights, loops, k_sets, P):
    """the two runs' (P, L, F) the same to the bit where both divide, or, where
    either takes an estimate, within the loops' error: forces within FORCE_ERROR of
    ``k |d|`` (``|d|`` at most the cloth's span), the new positions (written
    over L) within what that moves a point in a step; P is read only"""
    (pa, la, fa), (pb, lb, fb) = eights, loops
    if not RSQRT14 and DIVIDE:
        return _same_bits(pa, pb) and _same_bits(la, lb) and _same_bits(fa, fb)
    span = float(np.ptp(P, axis=1).max())
    force = FORCE_ERROR * float(np.max(k_sets)) * span
    return (_same_bits(pa, pb) and np.allclose(fa, fb, rtol=0.0, atol=force)
            and np.allclose(la, lb, rtol=0.0, atol=1e-13))


@settings(max_examples=40, deadline=None)
@given(nw=st.integers(2, 40), nh=st.integers(2, 40), seed=st.integers(0, 2**32 - 1),
       off=st.lists(st.booleans(), min_size=6, max_size=6), pinned=st.booleans())
def test_the_eights_move_the_cloth_as_the_loops_do(nw, nh, seed, off, pinned):
    pins = [[0, 0], [nw - 1, 0]] if pinned else ()
    m, P, L = _state(nw, nh, seed, pins)
    k_sets = np.where(off, 0.0, np.random.default_rng(seed).uniform(50.0, 5000.0, 6))
    if not k_sets.any():
        k_sets[0] = 100.0  # with every kind off integrate takes its gravity-only loop
    k = knobs(k_sets, (0.0, -9.8, 0.3), 0.998, 1e-5)
    eights, loops = _both(m, P, L, k, 0, nw * nh, 0)
    assert _agree(eights, loops, k_sets, P)
    assert np.array_equal(eights[0], P)  # P is only read
    assert not np.array_equal(eights[1], L)  # the step moved the cloth, writing over L


def test_a_part_of_the_cloth_moves_as_the_loops_move_it():
    """the ranges a thread's part takes: from before a chunk's start, the
    first points' forces only (the springs the part before also works out)"""
    m, P, L = _state(60, 50, 7, pins=[[0, 0], [59, 0]])
    k_sets = np.full(6, 3000.0)
    k = knobs(k_sets, (0.0, -9.8, 0.0), 0.998, 1e-5)
    n = 60 * 50
    for first, stop, moved in ((0, n, 0), (CHUNK - 128, n, CHUNK), (0, 2 * CHUNK, 0), (CHUNK - 8, 2 * CHUNK, CHUNK)):
        eights, loops = _both(m, P, L, k, first, stop, moved)
        assert _agree(eights, loops, k_sets, P)
        assert np.array_equal(eights[1][:, :moved], L[:, :moved])  # the points before moved take no step
        assert np.array_equal(eights[0], P)


def test_the_eights_stop_where_a_spring_would_reach_past_the_cloth():
    m, P, L = _state(30, 20, 3)
    springs = stencil(m)
    k = knobs(np.full(6, 3000.0), (0.0, -9.8, 0.0), 0.998, 1e-5)
    n = 600
    done = integrate_eights(P.copy(), L.copy(), np.ones(n), k, springs, force_buffer(springs, n), 0, n, 0)
    reach = int(max(springs.start.max(), springs.end.max()))
    assert done % LANES == 0 and done + LANES > n - reach >= done


def test_the_eights_leave_a_range_or_buffer_they_cannot_read_inside_to_the_loops():
    m, P, L = _state(20, 20, 5)
    springs = stencil(m)
    k = knobs(np.full(6, 3000.0), (0.0, -9.8, 0.0), 0.998, 1e-5)
    free, F = np.ones(400), force_buffer(springs, 400)
    half = LANES // 2
    for first, moved in ((half, half), (LANES, LANES + half), (-LANES, 0)):
        assert integrate_eights(P.copy(), L.copy(), free, k, springs, F, first, 400, moved) == first
    short = np.zeros((6, 3, 400 + 4))  # a pad of four slots
    assert integrate_eights(P.copy(), L.copy(), free, k, springs, short, 0, 400, 0) == 0
    assert integrate_eights(P.copy(), L.copy(), free, k, springs, F, 0, 400, 0) > 0


def test_gaps_mark_every_slot_without_a_spring():
    m = grid_model(11, 5)
    springs = stencil(m)
    bits = np.unpackbits(springs.gaps, axis=1, bitorder="little")[:, :springs.valid.shape[1]]
    assert np.array_equal(bits == 1, springs.valid == 0)
    assert np.array_equal(gap_bits(np.ones((6, 3))), np.zeros((6, 1), np.uint8) | np.uint8(0b11111000))
    assert build_stencil(m.rest_positions, m.pinned, 5, 11).gaps.dtype == np.uint8


def test_the_force_buffer_holds_the_eight_read_before_the_first():
    """the step of the first eight reads the eight slots before it, inside the pad
    even where the springs reach back fewer (rows of two or three points)"""
    for nw in (2, 3, 4, 50):
        m = grid_model(nw, 4)
        assert force_pad(force_buffer(stencil(m), 4 * nw), 4 * nw) >= LANES


def test_the_force_buffers_rows_start_on_cache_lines():
    """every set's and coordinate's slot of point 0 lies on a 64-byte line, in
    the one buffer and in each part's, so that a call's stores of its forces
    (points a multiple of LANES on) are aligned vectors"""
    for nw, nh, parts in ((50, 50, 1), (7, 9, 2), (3, 5, 3)):
        springs, n = stencil(grid_model(nw, nh)), nw * nh
        for F in (force_buffer(springs, n), *part_force_buffers(springs, n, parts)):
            pad = force_pad(F, n)
            assert pad >= max(int(springs.end.max()) + 1, LANES) and pad % LINE == 0
            assert F.shape[2] >= pad + n and np.all(F == 0.0)
            assert all(F[s, c, pad:].ctypes.data % 64 == 0 for s in range(6) for c in range(3))


def test_the_solvers_planes_and_the_springs_rows_start_on_cache_lines():
    """the arrays the kernels load eight doubles at a time: the solver's planes
    and free weights start on a 64-byte line, and every set's row of the
    stencil's per-slot arrays too, its padding slots holding no spring"""
    from clothsim import Simulation
    from clothsim.scene import parse_scene

    scene = {"cloth": {"width": 1.0, "height": 1.0, "num_width_points": 7, "num_height_points": 9,
                       "thickness": 0.01, "orientation": 0, "pinned": [[0, 0]], "damping": 0.2,
                       "density": 150, "ks": 5000}}
    solver = Simulation(parse_scene(scene, "lines"), threads=1).solver
    n = 63
    for a in (solver.scratch.P, solver.scratch.L, solver.scratch.Q, solver.points.free):
        assert a.ctypes.data % 64 == 0 and a.shape[-1] == n
    springs = solver.springs
    assert springs.rest.shape == (6, 64)
    for rows in (springs.valid, springs.rest, springs.limit, springs.share[:, 0], springs.share[:, 1]):
        assert all(rows[s].ctypes.data % 64 == 0 for s in range(6))
    assert np.all(springs.valid[:, n:] == 0.0) and np.all(springs.rest[:, n:] == 0.0)
    assert np.all(springs.limit[:, n:] == NO_LIMIT)


@settings(max_examples=20, deadline=None)
@given(nw=st.integers(2, 40), nh=st.integers(2, 40), seed=st.integers(0, 2**32 - 1))
def test_the_eights_forces_are_within_1e_14_of_exact(nw, nh, seed):
    """every spring the eights compute, against ``(k - k rest / |d|) d`` in
    double precision: AVX-512's estimate refined twice, or the double square
    root and divide, are both within 1e-14 of ``k |d|``"""
    m, P, L = _state(nw, nh, seed)
    k_sets = np.random.default_rng(seed).uniform(50.0, 5000.0, 6)
    springs, n = stencil(m), nw * nh
    F = force_buffer(springs, n)
    done = integrate_eights(P.copy(), L.copy(), np.ones(n), knobs(k_sets, (0.0, -9.8, 0.0), 0.998, 1e-5),
                            springs, F, 0, n, 0)
    pad = force_pad(F, n)
    for s in range(6):
        a, b = springs.start[s], springs.end[s]
        d = P[:, b:b + done] - P[:, a:a + done]
        length = np.sqrt((d * d).sum(axis=0))
        exact = (k_sets[s] - k_sets[s] * springs.rest[s, :done] / length) * d * springs.valid[s, :done]
        error = np.abs(F[s, :, pad:pad + done] - exact) / (k_sets[s] * length)
        assert error.max(initial=0.0) < 1e-14


def test_the_eights_leave_springs_that_are_not_a_grids_to_the_loops():
    """the eights load each end the sets share once: a stencil whose ends
    differ from a grid's is left to the loops"""
    m, P, L = _state(12, 10, 9)
    springs = stencil(m)
    k = knobs(np.full(6, 3000.0), (0.0, -9.8, 0.0), 0.998, 1e-5)
    start = springs.start.copy()
    start[3] = 2  # set 3 no longer starts where set 0 ends
    odd = springs._replace(start=start)
    shifted = springs._replace(start=springs.start + 1, end=springs.end + 1)  # every spring a point along
    F = force_buffer(springs, 120)
    assert integrate_eights(P.copy(), L.copy(), np.ones(120), k, odd, F, 0, 120, 0) == 0
    assert integrate_eights(P.copy(), L.copy(), np.ones(120), k, shifted, force_buffer(shifted, 120), 0, 120, 0) == 0
    assert integrate_eights(P.copy(), L.copy(), np.ones(120), k, springs, F, 0, 120, 0) > 0
