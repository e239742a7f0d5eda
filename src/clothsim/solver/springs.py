"""Spring forces and the Verlet step as stencils over the cloth grid.

The cloth is a regular grid, so every spring kind is a fixed offset between
two grid points. Holding x, y and z as separate planes of ``rows*cols``
values, point p of a spring set is joined to point ``p + offset``, and each
set is one long loop over contiguous memory, which LLVM turns into SIMD code;
a loop over a spring list with indexed ends does not vectorise. Where the
offset would wrap past the end of a grid row, the spring does not exist: its
``valid`` weight is 0, and the force loop, which reads no weight, zeroes those
few slots (whole grid columns, :attr:`GridSprings.wrap`) after each set.

The six sets, indexed by ``s``, join grid point ``(r, i)`` to ``(r + dr, i + di)``:

===  ==========  ==  ==
s    kind        dr  di
===  ==========  ==  ==
0    structural  0   1
1    structural  1   0
2    shearing    1   1
3    shearing    1   -1
4    bending     0   2
5    bending     2   0
===  ==========  ==  ==
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from ..model import BENDING, SHEARING, STRUCTURAL
from .provot import MAX_STRETCH
from .shared import DIVIDE, KERNEL_OPTIONS, SET_STEP, on_lines, over_length, whole_lines
from .simd import has_avx512f
from .spring_lanes import LANES, force_pad, integrate_eights

SET_KIND = np.array([STRUCTURAL, STRUCTURAL, SHEARING, SHEARING, BENDING, BENDING])
"""the spring kind of each stencil set"""

CHUNK = 512
"""points per chunk of the force loop: their forces stay in cache until gathered"""

AHEAD_STEP = 8
"""``ahead`` is rounded up to this many points, a vector of doubles at 512
bits (two at 256): a part's force pass then starts on a whole call of
:mod:`.spring_lanes`"""

BY_LANES = has_avx512f() or not DIVIDE
"""whether :func:`integrate` walks the cloth in calls of :mod:`.spring_lanes`
(eight points with AVX-512, four without) rather than numba's loops: not
on AMD's Zen cores without AVX-512 (:data:`.shared.DIVIDE`), where four at a
time ran slower than the loops on a Zen 4 core with its AVX2 code, and faster
on an Intel core (docs/performance.md, 'The springs four points at a time
without AVX-512')"""

NO_LIMIT = 1e30
"""the Provot limit where a set has no spring: never reached"""


class GridSprings(NamedTuple):
    """The springs of a grid cloth as six offset sets over flat point indices,
    with what the Provot pass needs of them (see :mod:`.provot`)."""

    start: np.ndarray
    """first end of set s's spring p is point ``p + start[s]``, int64 (6,)"""
    end: np.ndarray
    """its second end is ``p + end[s]``, int64 (6,)"""
    count: np.ndarray
    """p runs over ``range(count[s])``, int64 (6,)"""
    valid: np.ndarray
    """1.0 where spring p of set s exists, 0.0 where it would wrap a row or
    lies past the cloth, (6, N'): N rounded up to whole cache lines, each
    set's row starting a line (:func:`.shared.on_lines`), as in the arrays
    below; the wind's stencils weigh by it, the force loop uses ``wrap``
    instead"""
    rest: np.ndarray
    """rest lengths [m], 0 where no spring, (6, N')"""
    limit: np.ndarray
    """Provot: ``MAX_STRETCH * rest`` [m] where the spring exists, else NO_LIMIT, (6, N')"""
    batch: np.ndarray
    """the half of the set's Provot pass that spring p takes part in, uint8 (6, N'):
    the springs of one half share no point"""
    share: np.ndarray
    """fraction of a Provot correction that goes to each end, (6, 2, N'): half
    each, all to the free end when the other is pinned, none when both are"""
    wrap: np.ndarray
    """the grid columns where set s's springs would wrap a row, int64 (6, 2), -1
    for none: spring p with ``p % cols`` among them is the one ``valid`` weighs 0.
    The force loop computes every slot with no weight (one load and one multiply
    fewer a spring) and then zeroes these few, at most two a row"""
    gaps: np.ndarray
    """the slots with no spring by eights, uint8 (6, ceil(N / 8)): bit j of
    ``gaps[s, e]`` is set where slot ``8 e + j`` of set s is one ``valid``
    weighs 0, or lies past ``count[s]``; the eights' force pass zeroes those
    lanes (see :mod:`.spring_lanes`)"""
    cols: int
    """points in a grid row"""
    ahead: int
    """how far the springs reach, rounded up to AHEAD_STEP: a thread's part
    that moves points ``lo:hi`` also works out the forces of the springs that
    start this many points before ``lo``, which its first points gather
    (see :func:`integrate`)"""


def build_stencil(rest_positions: np.ndarray, pinned: np.ndarray, rows: int, cols: int) -> GridSprings:
    """The springs of a ``rows`` x ``cols`` grid cloth whose points, row-major, start
    at ``rest_positions`` (N, 3) [m]; ``pinned`` (N,) marks the points that never move."""
    n = rows * cols
    r = np.repeat(np.arange(rows), cols)
    i = np.tile(np.arange(cols), rows)
    start, end, count = np.zeros(6, np.int64), np.zeros(6, np.int64), np.zeros(6, np.int64)
    # every set's row of slots whole cache lines, each starting one: the eights
    # and Provot's check load eight slots at a time
    slots = whole_lines(n)
    valid = on_lines((6, slots))
    rest = on_lines((6, slots))
    limit = on_lines((6, slots), NO_LIMIT)
    batch = np.zeros((6, slots), dtype=np.uint8)
    share = on_lines((6, 2, slots))
    free = ~pinned
    pos = rest_positions
    for s, (dr, di) in enumerate(SET_STEP):
        # set 3 goes down-left: it starts one column in, so p stays the cell's corner
        start[s] = 1 if di < 0 else 0
        end[s] = dr * cols + max(di, 0)
        count[s] = n - max(start[s], end[s])
        p = np.arange(count[s])
        ok = (r[p] + dr < rows) & (i[p] + abs(di) < cols)
        valid[s, p] = ok
        a, b = p[ok] + start[s], p[ok] + end[s]
        rest[s, p[ok]] = np.linalg.norm(pos[b] - pos[a], axis=1)
        fa, fb = free[p + start[s]], free[p + end[s]]
        share[s, 0, p] = fa * (1.0 - 0.5 * fb)
        share[s, 1, p] = fb * (1.0 - 0.5 * fa)
        step = abs(di) if dr == 0 else dr
        # every other spring of a row (pairs of them for bending), or every other row
        batch[s, p] = ((i[p] if dr == 0 else r[p]) // step) % 2
        limit[s, p[ok]] = MAX_STRETCH * rest[s, p[ok]]
    wrap = wrap_columns(valid, count, cols)
    gaps = gap_bits(valid)
    for arr in (start, end, count, valid, rest, limit, batch, share, wrap, gaps):
        arr.setflags(write=False)
    ahead = int((end.max() + AHEAD_STEP - 1) // AHEAD_STEP * AHEAD_STEP)
    return GridSprings(start=start, end=end, count=count, valid=valid, rest=rest, limit=limit, batch=batch,
                       share=share, wrap=wrap, gaps=gaps, cols=int(cols), ahead=ahead)


def gap_bits(valid: np.ndarray) -> np.ndarray:
    """:attr:`GridSprings.gaps` of the (6, N) weights ``valid``."""
    n = valid.shape[1]
    eights = -(-n // 8)
    missing = np.ones((valid.shape[0], 8 * eights), dtype=bool)
    missing[:, :n] = valid == 0
    return np.packbits(missing.reshape(valid.shape[0], eights, 8), axis=2, bitorder="little")[:, :, 0]


def wrap_columns(valid: np.ndarray, count: np.ndarray, cols: int) -> np.ndarray:
    """The columns (of a spring's index p, ``p % cols``) where each set has no spring,
    int64 (6, 2), -1 padded: the ends of a row that a set's step would wrap past.
    Every slot p < count[s] that ``valid`` (6, N) weighs 0 lies in one of them."""
    wrap = np.full((6, 2), -1, dtype=np.int64)
    for s in range(6):
        slots = np.arange(count[s])
        missing = valid[s, :count[s]] == 0
        columns = np.unique(slots[missing] % cols)
        if len(columns) > 2 or not np.array_equal(missing, np.isin(slots % cols, columns)):
            raise ValueError(f"spring set {s}: the slots with no spring are not whole grid columns")
        wrap[s, :len(columns)] = columns
    return wrap




def force_buffer(stencil: GridSprings, num_points: int) -> np.ndarray:
    """Scratch for :func:`integrate`: each set's spring forces, zero-padded in
    front so that ``F[s, c, pad + p]`` is spring p and every index a point
    reads stays inside, (6, 3, pad + N rounded up to whole lines); the pad holds at
    least the LANES slots the lanes read before their first
    (:mod:`.spring_lanes`), and the pad and every row are whole cache lines
    (:func:`force_pad`)."""
    return on_lines(_buffer_shape(stencil, num_points))


def _buffer_shape(stencil: GridSprings, num_points: int) -> tuple:
    pad = whole_lines(max(int(stencil.end.max()) + 1, LANES))
    return (6, 3, pad + whole_lines(num_points))


def part_force_buffers(stencil: GridSprings, num_points: int, parts: int) -> np.ndarray:
    """A :func:`force_buffer` for each of ``parts`` threads' parts, (parts, 6, 3,
    pad + N'): a part writes and reads only its own, so no force goes from one
    core to the other (see :func:`integrate`)."""
    return on_lines((parts,) + _buffer_shape(stencil, num_points))


@njit(**KERNEL_OPTIONS)
def integrate(P, L, free, knobs, springs, F, first, stop, moved):
    """One Verlet step under gravity and the spring forces for the springs that
    start at points ``first:stop`` of the (3, N) planes P (positions) and L
    (last positions), stepping only the points from ``moved`` on: ``0, N, 0``
    is the whole cloth. The stepped points' new positions go to L, over their
    last ones, and P is not written: the caller then swaps the two, so P
    holds the new positions and L the ones before. Read by no one while the
    step runs, P may be read by every thread at once: a thread's part
    ``lo:hi`` takes ``max(lo - springs.ahead, 0), hi, lo``, the springs of
    the part before that its first points gather as well as its own.

    ``x' = x + keep*(x - x_prev) + a dt²`` where ``free`` is 1, with ``a`` the
    acceleration from gravity and every spring (Hooke's law along the
    spring, ``knobs.k_over_m[s]`` set s's constant over the point mass, 0
    when its kind is disabled); ``knobs`` is a :class:`~clothsim.solver.groups.Knobs`,
    ``springs`` the cloth's :class:`GridSprings`.

    Spring forces go to the (6, 3, pad + N') buffer ``F`` first (:func:`force_buffer`), then each
    point gathers its twelve: ``a[q] = g + sum_s F_s[q - start_s] - F_s[q - end_s]``.
    That reads each force twice but writes each acceleration once, instead
    of adding into both ends of every spring. Where BY_LANES, the cloth is
    walked :data:`.spring_lanes.LANES` points at a time
    (:mod:`.spring_lanes`: eight with AVX-512, four without), the forces of
    their springs and then their step; elsewhere, and for the last rows,
    whose springs would reach past the end, in chunks of CHUNK points
    (:func:`integrate_chunks`), with the same sums in the same order. A spring's ends are both at its
    start ``p`` or later, so a point's step can be taken as soon as its own
    springs' forces are in.
    """
    k_over_m = knobs.k_over_m
    # the switch of verlet_gather is a constant: compiled for each value, its
    # loop ran faster than with the switch a run-time value
    if not has_springs(k_over_m):
        verlet_gather(P, L, free, knobs, springs, F, max(first, moved), stop, False)
        return
    done = integrate_eights(P, L, free, knobs, springs, F, first, stop, moved) if BY_LANES else first
    integrate_chunks(P, L, free, knobs, springs, F, done, stop, moved)


@njit(**KERNEL_OPTIONS)
def integrate_chunks(P, L, free, knobs, springs, F, first, stop, moved):
    """:func:`integrate` as numba's loops, a chunk at a time: the springs'
    forces of CHUNK points, then their gathering with the Verlet step. It
    takes the points :func:`.spring_lanes.integrate_eights` leaves (the last
    rows, whose springs would reach past the cloth's end) and is what the
    tests hold the eights to."""
    k_over_m = knobs.k_over_m
    for lo in range(first, stop, CHUNK):
        hi = min(lo + CHUNK, stop)
        spring_forces(P, k_over_m, springs, F, lo, hi)
        if hi > moved:
            verlet_gather(P, L, free, knobs, springs, F, max(lo, moved), hi, True)


@njit(cache=True, inline="always")
def has_springs(k_over_m):
    """Whether any spring set pulls: with every kind switched off, the substep
    is plain Verlet under gravity, without writing and gathering six sets of
    zero forces, which cost several times the step itself (figures:
    docs/performance.md, 'Springs')."""
    for s in range(k_over_m.shape[0]):
        if k_over_m[s] != 0.0:
            return True
    return False


@njit(**KERNEL_OPTIONS)
def spring_forces(P, k_over_m, springs, F, lo, hi):
    """The forces of the springs that start at points ``lo:hi``, into ``F``; see :func:`integrate`."""
    start, end, count, rest = springs.start, springs.end, springs.count, springs.rest
    wrap, cols = springs.wrap, springs.cols
    pad = force_pad(F, P.shape[1])
    x, y, z = P[0], P[1], P[2]
    for s in range(6):
        k = k_over_m[s]
        m = min(hi, count[s]) - lo
        fx, fy, fz = F[s, 0, pad + lo:], F[s, 1, pad + lo:], F[s, 2, pad + lo:]
        if k == 0.0:
            for p in range(m):
                fx[p] = 0.0
                fy[p] = 0.0
                fz[p] = 0.0
            continue
        oa, ob = start[s] + lo, end[s] + lo
        # views that start at each end: plain p indexing lets LLVM skip the
        # negative-index wraparound, which would block vectorisation
        xa, ya, za = x[oa:], y[oa:], z[oa:]
        xb, yb, zb = x[ob:], y[ob:], z[ob:]
        rl = rest[s, lo:]
        for p in range(m):
            dx = xb[p] - xa[p]
            dy = yb[p] - ya[p]
            dz = zb[p] - za[p]
            f = k - over_length(k * rl[p], dx * dx + dy * dy + dz * dz)
            fx[p] = f * dx
            fy[p] = f * dy
            fz[p] = f * dz
        zero_wrapped(fx, fy, fz, wrap[s], cols, lo, m)


@njit(cache=True, inline="always")
def zero_wrapped(fx, fy, fz, wrap, cols, lo, m):
    """Zero the forces of the slots ``lo:lo+m`` (at index ``p - lo``) that lie in a
    wrap column (see :attr:`GridSprings.wrap`): the slots with no spring, one
    every ``cols`` slots for each such column."""
    for j in range(wrap.shape[0]):
        c = wrap[j]
        if c < 0:
            continue
        for p in range((c - lo) % cols, m, cols):
            fx[p] = 0.0
            fy[p] = 0.0
            fz[p] = 0.0


@njit(**KERNEL_OPTIONS)
def verlet_gather(P, L, free, knobs, springs, F, lo, hi, with_springs):
    """Points ``lo:hi`` gather their spring forces from ``F`` and take their Verlet
    step from P into L (see :func:`integrate`); without ``with_springs`` (see
    :func:`has_springs`) under gravity alone, and ``F``, which then holds the
    last forces written, is not read (the test is loop-invariant: LLVM keeps
    a loop for each case)."""
    gravity, keep, dt2 = knobs.gravity, knobs.keep, knobs.dt2
    start, end = springs.start, springs.end
    pad = force_pad(F, P.shape[1])
    fr = free[lo:]
    for c in range(3):
        xc, lc = P[c, lo:hi], L[c, lo:]
        g = gravity[c]
        b = pad + lo
        f0a, f0b = F[0, c, b - start[0]:], F[0, c, b - end[0]:]
        f1a, f1b = F[1, c, b - start[1]:], F[1, c, b - end[1]:]
        f2a, f2b = F[2, c, b - start[2]:], F[2, c, b - end[2]:]
        f3a, f3b = F[3, c, b - start[3]:], F[3, c, b - end[3]:]
        f4a, f4b = F[4, c, b - start[4]:], F[4, c, b - end[4]:]
        f5a, f5b = F[5, c, b - start[5]:], F[5, c, b - end[5]:]
        for q in range(hi - lo):
            a = g
            if with_springs:
                a += ((f0a[q] - f0b[q]) + (f1a[q] - f1b[q]) + (f2a[q] - f2b[q])
                      + (f3a[q] - f3b[q]) + (f4a[q] - f4b[q]) + (f5a[q] - f5b[q]))
            xq = xc[q]
            lc[q] = xq + fr[q] * (keep * (xq - lc[q]) + a * dt2)
