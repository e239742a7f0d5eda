"""Spring forces and the Provot pass as stencils over the cloth grid.

The cloth is a regular grid, so every spring kind is a fixed offset between
two grid points. Holding x, y and z as separate planes of ``rows*cols``
values, point p of a spring set is joined to point ``p + offset``, and each
set is one long loop over contiguous memory, which LLVM turns into SIMD code;
a loop over a spring list with indexed ends does not vectorise. Where the
offset would wrap past the end of a grid row, the spring does not exist and
its ``valid`` weight is 0.

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

from dataclasses import dataclass

import numpy as np
from numba import njit
from numba.cpython.unsafe.numbers import trailing_zeros

from ..model import BENDING, SHEARING, STRUCTURAL, ClothModel
MAX_STRETCH = 1.1
"""Provot: no spring longer than this times its rest length"""

KERNEL_OPTIONS = dict(cache=True, fastmath=True, boundscheck=False, error_model="numpy")
"""error_model="numpy" drops the zero-division check, which would stop LLVM vectorising"""

SET_KIND = np.array([STRUCTURAL, STRUCTURAL, SHEARING, SHEARING, BENDING, BENDING])
"""the spring kind of each stencil set"""
SET_STEP = ((0, 1), (1, 0), (1, 1), (1, -1), (0, 2), (2, 0))
"""(dr, di) of each stencil set"""
CHUNK = 512
"""points per chunk of the force loop: their forces stay in cache until gathered"""
NO_LIMIT = 1e30
"""the Provot limit where a set has no spring: never reached"""
BLOCK = 64
"""springs the Provot pass checks together: one bit each in a 64-bit word"""


@dataclass(frozen=True)
class Stencil:
    """The springs of a grid as six offset sets over flat point indices."""

    start: np.ndarray
    """first end of set s's spring p is point ``p + start[s]``, int64 (6,)"""
    end: np.ndarray
    """its second end is ``p + end[s]``, int64 (6,)"""
    count: np.ndarray
    """p runs over ``range(count[s])``, int64 (6,)"""
    valid: np.ndarray
    """1.0 where spring p of set s exists, 0.0 where it would wrap a row, (6, N)"""
    rest: np.ndarray
    """rest lengths [m], 0 where no spring, (6, N)"""
    limit: np.ndarray
    """Provot: ``MAX_STRETCH * rest`` [m] where the spring exists, else NO_LIMIT, (6, N)"""
    batch: np.ndarray
    """the half of the set's Provot pass that spring p takes part in, uint8 (6, N):
    the springs of one half share no point"""
    share: np.ndarray
    """fraction of a Provot correction that goes to each end, (6, 2, N): half
    each, all to the free end when the other is pinned, none when both are"""


def build_stencil(model: ClothModel) -> Stencil:
    rows, cols = model.num_height_points, model.num_width_points
    n = rows * cols
    r = np.repeat(np.arange(rows), cols)
    i = np.tile(np.arange(cols), rows)
    start, end, count = np.zeros(6, np.int64), np.zeros(6, np.int64), np.zeros(6, np.int64)
    valid = np.zeros((6, n))
    rest = np.zeros((6, n))
    limit = np.full((6, n), NO_LIMIT)
    batch = np.zeros((6, n), dtype=np.uint8)
    share = np.zeros((6, 2, n))
    free = ~model.pinned
    pos = model.rest_positions
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
    for arr in (start, end, count, valid, rest, limit, batch, share):
        arr.setflags(write=False)
    return Stencil(start, end, count, valid, rest, limit, batch, share)


@njit(**KERNEL_OPTIONS, inline="always")
def _inv_length(l2):
    """1/sqrt(l2) to about 1e-13 relative: a single-precision estimate refined by
    one Newton step in double, which is cheaper than a double sqrt and divide."""
    y = np.float64(np.float32(1.0) / np.sqrt(np.float32(max(l2, 1e-30))))
    return y * (1.5 - 0.5 * l2 * y * y)


def force_buffer(stencil: Stencil, num_points: int) -> np.ndarray:
    """Scratch for :func:`integrate`: each set's spring forces, zero-padded in
    front so that ``F[s, c, pad + p]`` is spring p and every index a point
    reads stays inside, (6, 3, pad + N)."""
    return np.zeros((6, 3, int(stencil.end.max()) + 1 + num_points))


@njit(**KERNEL_OPTIONS)
def integrate(P, L, gravity, k_over_m, free, keep, dt2, start, end, count, valid, rest, F):
    """One Verlet step under gravity and the spring forces; P, L are (3, N) planes.

    ``x' = x + keep*(x - x_prev) + a dt²`` where ``free`` is 1, with ``a`` the
    acceleration from gravity and every spring (Hooke's law along the
    spring, ``k_over_m[s]`` set s's constant over the point mass, 0 when
    its kind is disabled).

    Spring forces go to the (6, 3, pad + N) buffer ``F`` first, then each
    point gathers its twelve: ``a[q] = g + sum_s F_s[q - start_s] - F_s[q - end_s]``.
    That reads each force twice but writes each acceleration once, instead
    of adding into both ends of every spring. The cloth is walked in chunks
    of CHUNK points so the forces are still in cache when gathered. A chunk's
    springs only look forward (both ends at ``p`` or later), so a point can
    be moved as soon as its chunk is gathered: no later chunk reads it.
    """
    n = P.shape[1]
    integrate_range(P, L, gravity, k_over_m, free, keep, dt2, start, end, count, valid, rest, F, 0, n, 0)


@njit(**KERNEL_OPTIONS)
def integrate_range(P, L, gravity, k_over_m, free, keep, dt2, start, end, count, valid, rest, F,
                    first, stop, moved):
    """:func:`integrate` on the springs that start at points ``first:stop``, moving
    only the points from ``moved`` on: a thread's part of the cloth, whose
    first points the previous part's springs still read."""
    if not has_springs(k_over_m):
        verlet_gather(P, L, gravity, free, keep, dt2, start, end, F, max(first, moved), stop, False)
        return
    for lo in range(first, stop, CHUNK):
        hi = min(lo + CHUNK, stop)
        spring_forces(P, k_over_m, start, end, count, valid, rest, F, lo, hi)
        if lo >= moved:
            verlet_gather(P, L, gravity, free, keep, dt2, start, end, F, lo, hi)


@njit(cache=True, inline="always")
def has_springs(k_over_m):
    """Whether any spring set pulls: with every kind switched off, the substep
    is plain Verlet under gravity, and writing and gathering six sets of zero
    forces cost 9 us a substep on a 50x50 cloth, six times the step itself."""
    for s in range(k_over_m.shape[0]):
        if k_over_m[s] != 0.0:
            return True
    return False


@njit(**KERNEL_OPTIONS)
def spring_forces(P, k_over_m, start, end, count, valid, rest, F, lo, hi):
    """The forces of the springs that start at points ``lo:hi``, into ``F``; see :func:`integrate`."""
    pad = F.shape[2] - P.shape[1]
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
        w, rl = valid[s, lo:], rest[s, lo:]
        for p in range(m):
            dx = xb[p] - xa[p]
            dy = yb[p] - ya[p]
            dz = zb[p] - za[p]
            f = k * w[p] * (1.0 - rl[p] * _inv_length(dx * dx + dy * dy + dz * dz))
            fx[p] = f * dx
            fy[p] = f * dy
            fz[p] = f * dz


@njit(**KERNEL_OPTIONS)
def verlet_gather(P, L, gravity, free, keep, dt2, start, end, F, lo, hi, springs=True):
    """Points ``lo:hi`` gather their spring forces from ``F`` and take their Verlet
    step; without ``springs`` (see :func:`has_springs`) under gravity alone,
    and ``F``, which then holds the last forces written, is not read (the
    test is loop-invariant: LLVM keeps a loop for each case)."""
    pad = F.shape[2] - P.shape[1]
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
            if springs:
                a += ((f0a[q] - f0b[q]) + (f1a[q] - f1b[q]) + (f2a[q] - f2b[q])
                      + (f3a[q] - f3b[q]) + (f4a[q] - f4b[q]) + (f5a[q] - f5b[q]))
            xq = xc[q]
            xc[q] = xq + fr[q] * (keep * (xq - lc[q]) + a * dt2)
            lc[q] = xq


@njit(**KERNEL_OPTIONS)
def provot(P, enabled, start, end, count, limit, batch, share, masks, lo, hi, crossing):
    """Shorten every enabled spring longer than its limit (1.1x rest) back to it.

    Only the springs with both ends in points ``lo:hi`` are taken, or with
    ``crossing`` those with one end before ``lo`` and one from ``lo`` on. A
    thread then owns its part of the cloth; the springs across a cut
    between two parts are shortened afterwards. ``0, N, False`` takes all.

    One Gauss-Seidel pass over each set in two batches of springs that share
    no point (every other row of a vertical set, every other spring of a row
    for a horizontal one): within a batch that gives the same result as any
    sequential order.

    Few springs are over the limit at any time (a mean of 4 to 8 in each
    block of BLOCK that has one, in the standard scenes). So the whole set is
    first checked in a vectorised loop without square roots that only sets a
    bit per spring over, and then only those springs are corrected, one by
    one; correcting whole flagged blocks as vectors took 2.5 times as long
    on pinned4. The check serves both batches: a spring of the second batch
    can only have changed its length if a correction of the first moved one
    of its ends, and those (the springs ``o`` before and after, ``o`` the
    set's offset) are marked and checked again. Checking each batch on its
    own walked a horizontal set twice. ``masks`` is uint64 scratch, (2, words),
    a word per BLOCK springs of a set.
    """
    x, y, z = P[0], P[1], P[2]
    found, again = masks[0], masks[1]
    for s in range(6):
        if not enabled[s]:
            continue
        oa, ob = start[s], end[s]
        o = ob - oa
        # springs p of this set with both ends inside, or across the cut at lo
        plo, phi = (lo - ob, lo - oa) if crossing else (lo - oa, hi - ob)
        first, stop = max(plo, 0), min(phi, count[s])
        lim_s, batch_s, wa, wb = limit[s], batch[s], share[s, 0], share[s, 1]
        words = 0
        for q in range(first, stop, BLOCK):
            n = min(BLOCK, stop - q)
            xa, ya, za = x[oa + q:], y[oa + q:], z[oa + q:]
            xb, yb, zb = x[ob + q:], y[ob + q:], z[ob + q:]
            lim = lim_s[q:]
            mask = np.uint64(0)  # an or of shifted selects vectorises
            for p in range(n):
                over = gap2(xa, ya, za, p, xb, yb, zb, p) > lim[p] * lim[p]
                mask |= np.uint64(1 if over else 0) << np.uint64(p)
            found[words] = mask
            again[words] = 0
            words += 1
        for w in range(words):
            mask = found[w]
            while mask != 0:
                j, mask = pop_lowest(mask)
                p = first + w * BLOCK + j
                if batch_s[p] != 0:
                    continue
                _correct(P, oa + p, ob + p, lim_s[p], wa[p], wb[p])
                for j in (p - o - first, p + o - first):
                    if 0 <= j < stop - first:
                        again[j // BLOCK] |= np.uint64(1) << np.uint64(j % BLOCK)
        for w in range(words):
            mask = found[w] | again[w]
            while mask != 0:
                j, mask = pop_lowest(mask)
                p = first + w * BLOCK + j
                if batch_s[p] == 0:
                    continue
                a, b = oa + p, ob + p
                if gap2(x, y, z, a, x, y, z, b) > lim_s[p] * lim_s[p]:
                    _correct(P, a, b, lim_s[p], wa[p], wb[p])


@njit(cache=True, inline="always")
def gap2(xa, ya, za, i, xb, yb, zb, j):
    """Squared distance from point i of the planes (xa, ya, za) to point j of
    (xb, yb, zb): the test of every vectorised check, where the planes are
    views that start at each end of a set of pairs."""
    dx = xb[j] - xa[i]
    dy = yb[j] - ya[i]
    dz = zb[j] - za[i]
    return dx * dx + dy * dy + dz * dz


@njit(cache=True, inline="always")
def pop_lowest(mask):
    """(index of the lowest set bit of the uint64 ``mask``, mask without it): one
    step of a walk over the bits a vectorised check set."""
    return np.int64(trailing_zeros(mask)), mask & (mask - np.uint64(1))


@njit(**KERNEL_OPTIONS, inline="always")
def _correct(P, a, b, lim, wa, wb):
    """Shorten the spring from point a to point b to ``lim``, moving a by ``wa`` and b
    by ``wb`` of the correction."""
    dx = P[0, b] - P[0, a]
    dy = P[1, b] - P[1, a]
    dz = P[2, b] - P[2, a]
    e = 1.0 - lim * _inv_length(dx * dx + dy * dy + dz * dz)
    ea = e * wa
    eb = e * wb
    P[0, a] += ea * dx
    P[1, a] += ea * dy
    P[2, a] += ea * dz
    P[0, b] -= eb * dx
    P[1, b] -= eb * dy
    P[2, b] -= eb * dz
