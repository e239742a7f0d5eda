"""The drift bound: how much closer any two points may have come since the list was built.

The timings behind its choices are in docs/performance.md ('Drift test').
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..shared import EXACT_OPTIONS, KERNEL_OPTIONS, part_range

DRIFT_OPTIONS = dict(cache=True, boundscheck=False, error_model="numpy",
                     fastmath={"reassoc", "contract", "nsz", "arcp"})
"""fastmath without the no-NaN and no-inf assumptions: the sums vectorise, and a
non-finite displacement still counts as drifted"""

DRIFT_SAMPLE = 512
"""about this many points, evenly spread over the cloth, choose the centres of
the drift test"""

DRIFT_LEVELS = 256
"""steps in which :func:`drift_bound` measures the squared distance of a
displacement from its centre, up to (skin/2)²"""


@njit(**DRIFT_OPTIONS)
def drift_bound(Q, reference, skin, centres, spread, worst):
    """A bound B below ``skin`` on how much closer any two points may have come
    since the list was built, or inf when two may have come closer by ``skin``.
    ``Q`` and ``reference`` hold the positions now and at the build, in single
    precision from one origin, each coordinate rounded by less than ``spread``
    (the sum of their largest magnitudes) times 2**-24.

    If every displacement d lies within B/2 of one centre c, any two differ
    by less than B; this holds for any c, so c need not be exact. Two
    centres are tried in one pass: the mean of a sample of the displacements
    (tight when the whole cloth moves alike) and the middle of their box
    (tight when part of the cloth moves and the rest stays, a cloth falling
    onto the floor). The pass takes the largest squared distance from each
    centre in DRIFT_LEVELS steps, as integers: a maximum of floats does not
    vectorise without assuming no NaN, and a NaN must count as drifted. It
    reads single precision, sixteen points at a time, twice as many as in
    double precision. B is widened past what the rounding may hide.

    ``centres`` (2, 3) keeps the last centres chosen, and they are tried
    first: choosing them from the sample costs more than the pass itself,
    and the displacements change little from one substep to the next, so
    old centres mostly still hold. Only when neither does are new ones
    chosen and tried.

    The pass with the old centres is made beside the copy to single
    precision, part by part, while each part's positions are still in its
    core's cache (see :func:`copy_and_level`): ``worst`` (parts, 2) holds
    each part's largest steps from either centre.
    """
    level = min(worst[:, 0].max(), worst[:, 1].max())
    if level >= DRIFT_LEVELS:
        _choose_centres(Q, reference, centres, skin)
        pair = _level_both(Q, reference, skin, centres, 0, reference.shape[1])
        level = min(pair[0], pair[1])
        if level >= DRIFT_LEVELS:
            return np.inf
    # every squared distance from the centre is below (level + 1) steps of (skin/2)²
    bound = skin * np.sqrt((level + 1.0) / DRIFT_LEVELS)
    largest = 0.0
    for c in range(3):
        largest = max(largest, abs(centres[0, c]), abs(centres[1, c]))
    # a displacement is rounded by (spread + its magnitude) * 2**-24 per coordinate, a
    # centre by its magnitude * 2**-24, the distance between them relatively by a few
    # 2**-24: far less than this
    return bound * (1.0 + 2.0 ** -18) + (spread + skin + 2.0 * largest) * 2.0 ** -18


@njit(**DRIFT_OPTIONS)
def levels(Q, reference, skin, centres, parts):
    """``worst`` for :func:`drift_bound` where the positions were copied apart from
    it: each of ``parts`` ranges' largest steps from either centre, (parts, 2)."""
    n = reference.shape[1]
    worst = np.empty((parts, 2), dtype=np.int32)
    for t in range(parts):
        lo, hi = part_range(n, parts, t)
        mean, mid = _level_both(Q, reference, skin, centres, lo, hi)
        worst[t, 0] = mean
        worst[t, 1] = mid
    return worst


@njit(**DRIFT_OPTIONS)
def _choose_centres(Q, reference, centres, skin):
    """The mean and the box middle of a sample of the displacements, into ``centres``,
    each coordinate smaller than ``skin`` * 2**-24 made 0 (see :func:`_level_both`)."""
    n = reference.shape[1]
    step = max(1, n // DRIFT_SAMPLE)
    tiny = skin * 2.0 ** -24
    for c in range(3):
        s, lo, hi = 0.0, np.inf, -np.inf
        x, r = Q[c], reference[c]
        k = 0
        for p in range(0, n, step):
            d = np.float64(x[p] - r[p])
            s += d
            lo = d if d < lo else lo
            hi = d if d > hi else hi
            k += 1
        mean, mid = s / k, 0.5 * (lo + hi)
        centres[0, c] = mean if abs(mean) >= tiny else 0.0
        centres[1, c] = mid if abs(mid) >= tiny else 0.0


@njit(**DRIFT_OPTIONS)
def _level_both(Q, reference, skin, centres, lo, hi):
    """How many DRIFT_LEVELS steps of (skin/2)² the displacements of points
    ``lo:hi`` reach from each of the two centres, the largest from each:
    DRIFT_LEVELS for a point at skin/2 or farther, or not finite. The better
    centre's is the smaller of the two.

    Each difference from a centre is scaled to steps before it is squared
    (by the square root of the steps a squared length): a cloth that falls
    or lies flat moves most points by exactly 0 along x and z, while the
    centres there are a few 1e-20 m (the rounding of the displacements'
    sums), and the squares of such differences in single precision are
    subnormal numbers, each a microcode assist of some hundred cycles on
    Intel's cores: on the 50x50 `plane` at rest the pass took 24 µs instead
    of 2. Scaled, they are squares of some 1e-17; and
    :func:`_choose_centres` makes centres of less than skin * 2**-24 zero."""
    n = hi - lo
    f32 = np.float32
    step = f32(np.sqrt(DRIFT_LEVELS / (0.25 * skin * skin)))
    top = f32(DRIFT_LEVELS)
    m0, m1, m2 = f32(centres[0, 0]), f32(centres[0, 1]), f32(centres[0, 2])
    c0, c1, c2 = f32(centres[1, 0]), f32(centres[1, 1]), f32(centres[1, 2])
    # views from lo, as in _to_single
    x, y, z = Q[0, lo:hi], Q[1, lo:hi], Q[2, lo:hi]
    rx, ry, rz = reference[0, lo:hi], reference[1, lo:hi], reference[2, lo:hi]
    cap = np.int32(DRIFT_LEVELS)
    worst_mean = np.int32(0)
    worst_mid = np.int32(0)
    for p in range(n):
        dx = x[p] - rx[p]
        dy = y[p] - ry[p]
        dz = z[p] - rz[p]
        ex, ey, ez = (dx - m0) * step, (dy - m1) * step, (dz - m2) * step
        fx, fy, fz = (dx - c0) * step, (dy - c1) * step, (dz - c2) * step
        a = ex * ex + ey * ey + ez * ez
        b = fx * fx + fy * fy + fz * fz
        la = np.int32(a) if a < top else cap  # NaN and inf take the top step
        lb = np.int32(b) if b < top else cap
        worst_mean = la if la > worst_mean else worst_mean
        worst_mid = lb if lb > worst_mid else worst_mid
    return worst_mean, worst_mid


@njit(cache=True, inline="always")
def widened2(radius, extent):
    """The square of ``radius`` widened past the rounding of single-precision
    coordinates of magnitude up to ``extent`` (each rounded by at most
    extent * 2**-24, their differences by a hair more), as a float32 rounded
    up: a pair closer than ``radius`` always tests closer in single precision."""
    wide = radius * (1.0 + 2.0 ** -18) + 4.0 * extent * 2.0 ** -23
    return np.float32(wide * wide * (1.0 + 2.0 ** -18))


@njit(**EXACT_OPTIONS, inline="always")
def single_copy(P, frame, Q, extent, reference):
    """P from the origin ``frame[:3]`` in single precision into ``Q`` and ``reference``
    (the build's positions), cut into as many parts as ``extent`` has
    (``prange`` where inlined into parallel code), each noting the bits of
    its largest magnitude there; returns the largest. Each part copies its
    own points into ``reference`` while they are in its cache: one thread
    copying all of them afterwards read half from the other core."""
    parts = extent.shape[0]
    n = P.shape[1]
    for t in prange(parts):
        lo, hi = part_range(n, parts, t)
        extent[t] = _to_single(P, frame[0], frame[1], frame[2], Q, lo, hi)
        _keep(Q, reference, lo, hi)
    return _largest(extent)


@njit(**KERNEL_OPTIONS)
def _keep(Q, reference, lo, hi):
    """points ``lo:hi`` of ``Q`` into ``reference`` (3, N)"""
    for c in range(3):
        q, r = Q[c, lo:hi], reference[c, lo:hi]
        for p in range(hi - lo):
            r[p] = q[p]


@njit(**EXACT_OPTIONS, inline="always")
def copy_and_level(P, frame, Q, extent, reference, skin, centres, worst):
    """:func:`single_copy`, each part then measuring its points' displacements
    from ``reference`` against the last ``centres`` into its row of ``worst``
    (parts, 2) int32 (see :func:`drift_bound`) while they are in its cache: a
    pass of its own after the copy read, on two threads, half its points from
    the other core (docs/performance.md, 'Where two threads lose time')."""
    parts = extent.shape[0]
    n = P.shape[1]
    for t in prange(parts):
        lo, hi = part_range(n, parts, t)
        extent[t] = _to_single(P, frame[0], frame[1], frame[2], Q, lo, hi)
        mean, mid = _level_both(Q, reference, skin, centres, lo, hi)
        worst[t, 0] = mean
        worst[t, 1] = mid
    return _largest(extent)


@njit(cache=True, inline="always")
def _largest(extent):
    """the largest of the parts' magnitudes, noted as float32 bits in ``extent``"""
    most = extent.view(np.float32)
    top = most[0]
    for t in range(1, most.shape[0]):
        top = max(top, most[t])
    return np.float64(top)


@njit(**KERNEL_OPTIONS)
def _to_single(P, ox, oy, oz, Q, lo, hi):
    """Points ``lo:hi`` of P from (ox, oy, oz) in single precision into ``Q``; returns
    the bits of the largest magnitude so written, as an int32. The magnitudes
    are taken on the bits, whose order is theirs: a maximum of floats does
    not vectorise."""
    most = np.int32(0)
    m = hi - lo
    for c in range(3):
        # views from lo: indexed from lo into the whole planes, the loop ran
        # scalar inside the substep
        x, q = P[c, lo:hi], Q[c, lo:hi]
        bits = q.view(np.int32)
        o = ox if c == 0 else (oy if c == 1 else oz)
        for p in range(m):
            q[p] = np.float32(x[p] - o)
            most = max(most, bits[p] & np.int32(0x7FFFFFFF))
    return most
