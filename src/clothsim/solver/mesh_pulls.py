"""The general path's springs and Verlet step as each point's pulls, eight points at a time.

Each point keeps a list of *slots*, one per spring it is an end of: the
spring's other end, rest length and constant. A pass over the points sums
each point's pulls from its slots and moves it (:func:`pull_step`, with
:func:`.pull_lanes.pull_lanes` doing eight points a call). The lists are
laid out for that: the points are taken in eights, and an eight's slots are
rows of LANES, one lane per point, as many rows as the eight's longest list
(the others padded with springs of constant 0 from the point to itself).

Every spring is computed twice, once at each end, where the course code's
loop (and :func:`.meshsprings.mesh_provot` still) takes it once and adds
to both. The pass reads the positions and writes the new ones apart (into
the last positions' planes, which the substep then swaps with the
positions'), so it needs no force buffer, no order among the springs and
no pass on one thread for the springs across parts: every point is read as
it was at the substep's start, and parts of the points run at once.

The constants per slot follow the live knobs: :func:`refresh_constants`
rewrites them from ``MeshKnobs.k_over_m`` when it differs from what they
were made from.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from ..model import Model
from .pull_lanes import LANES, pull_lanes
from .shared import EXACT_OPTIONS, KERNEL_OPTIONS


def spring_sets(model: Model) -> np.ndarray:
    """Each model spring's set, 3 x its cloth + its kind, int64 (S,)."""
    starts = np.array([c.start for c in model.cloths], dtype=np.int64)
    cloth = np.searchsorted(starts, model.spring_a, side="right") - 1
    return 3 * cloth + model.spring_kind.astype(np.int64)


class MeshPulls(NamedTuple):
    """Each point's springs as slots, in rows of LANES: row ``r`` of the
    eight ``e`` (points ``LANES e`` on) is for ``chunk_start[e] <= r <
    chunk_start[e + 1]``, lane ``j`` for point ``LANES e + j``."""

    other: np.ndarray
    """the far end of each slot's spring, int32 (R, LANES); the lane's own point
    in a padding slot (the model's last point past its end)"""
    rest: np.ndarray
    """rest length of each slot's spring [m], float64 (R, LANES); 0 in padding"""
    set: np.ndarray
    """each slot's set (3 x cloth + kind, as :func:`spring_sets`),
    int64 (R, LANES); the number of sets in padding, whose constant is 0"""
    k: np.ndarray
    """each slot's spring constant over the point mass [1/s²], float64 (R, LANES),
    written by :func:`refresh_constants`"""
    k_rest: np.ndarray
    """``k`` times ``rest`` [m/s²], float64 (R, LANES), written with it"""
    k_of_set: np.ndarray
    """the constant of each set the slots' ``k`` were made from, float64 (sets + 1,),
    NaN before the first refresh; the last entry, padding's, stays 0"""
    chunk_start: np.ndarray
    """the first row of each eight of points, int64 (ceil(N / LANES) + 1,)"""
    points: int
    """N, the model's points: every far end is one of them"""


def build_mesh_pulls(model: Model) -> MeshPulls:
    """The slots of every spring of ``model`` at both its ends, in model order at each point."""
    n = model.num_points
    a = model.spring_a.astype(np.int64)
    b = model.spring_b.astype(np.int64)
    sets = spring_sets(model)
    ends, others = np.concatenate([a, b]), np.concatenate([b, a])
    order = np.argsort(ends, kind="stable")
    ends, others = ends[order], others[order]
    chunks = -(-n // LANES)
    degree = np.zeros(chunks * LANES, dtype=np.int64)
    degree[:n] = np.bincount(ends, minlength=n)
    chunk_start = np.concatenate([[0], np.cumsum(degree.reshape(chunks, LANES).max(axis=1))]).astype(np.int64)
    rows = int(chunk_start[-1])
    own = np.minimum(np.arange(chunks * LANES), n - 1).reshape(chunks, LANES)
    other = np.repeat(own, np.diff(chunk_start), axis=0).astype(np.int32)
    count = 3 * len(model.cloths)
    rest = np.zeros((rows, LANES))
    set_ = np.full((rows, LANES), count, dtype=np.int64)
    first_of = np.concatenate([[0], np.cumsum(degree[:n])])
    rank = np.arange(len(ends)) - first_of[ends]
    row, lane = chunk_start[ends // LANES] + rank, ends % LANES
    other[row, lane] = others
    rest[row, lane] = np.concatenate([model.spring_rest, model.spring_rest])[order]
    set_[row, lane] = np.concatenate([sets, sets])[order]
    k_of_set = np.full(count + 1, np.nan)
    k_of_set[count] = 0.0
    if len(others) and not (0 <= others.min() and others.max() < n):
        raise ValueError(f"a spring's end lies outside the model's {n} points")
    out = MeshPulls(other=other, rest=rest, set=set_, k=np.zeros((rows, LANES)), k_rest=np.zeros((rows, LANES)),
                    k_of_set=k_of_set, chunk_start=chunk_start, points=n)
    for arr in (out.other, out.rest, out.set, out.chunk_start):
        arr.setflags(write=False)
    return out


@njit(**EXACT_OPTIONS)
def refresh_constants(mesh_pulls, k_over_m):
    """Each slot's constant from ``k_over_m`` (one per set, as
    :attr:`.groups.MeshKnobs.k_over_m`) where it differs from what they were
    made from: a frame's call does this once, and rewrites them only when a
    material or a spring switch changed. Compiled without fast-math, under
    which LLVM may assume the NaN of the first call equals anything."""
    k, k_rest, k_of_set = mesh_pulls.k, mesh_pulls.k_rest, mesh_pulls.k_of_set
    sets, rest = mesh_pulls.set, mesh_pulls.rest
    count = k_of_set.shape[0] - 1
    if k_over_m.shape[0] != count:
        return  # not this model's sets: the slots keep what they have
    same = True
    for s in range(count):
        if not k_over_m[s] == k_of_set[s]:  # a NaN (the first call) is never the same
            same = False
    if same:
        return
    for s in range(count):
        k_of_set[s] = k_over_m[s]
    rows, lanes = k.shape
    for r in range(rows):
        for j in range(lanes):
            k[r, j] = k_of_set[min(max(sets[r, j], 0), count)]
            k_rest[r, j] = k[r, j] * rest[r, j]


@njit(**KERNEL_OPTIONS)
def pull_step(P, R, L, free, mesh_knobs, mesh_pulls, first, stop):
    """Eights ``first:stop`` of the points take their springs' pulls and their
    Verlet step, ``x' = x + free (keep (x - x_last) + a dt²)``, read from the
    (3, N) planes P [m] (the far ends from R (N, 4), P's copy by
    :func:`to_rows`) and written into L (which held the last positions): P
    is not written, so eights may run in any order and at once. ``a`` is
    gravity plus the pulls over the point mass [m/s²]. Does nothing where the
    slots are not for P's points or the arrays are too short for them: the
    calls read unchecked."""
    other, k, k_rest, chunk_start = mesh_pulls.other, mesh_pulls.k, mesh_pulls.k_rest, mesh_pulls.chunk_start
    g, keep = mesh_knobs.gravity, mesh_knobs.keep
    n = P.shape[1]
    chunks = (n + LANES - 1) // LANES
    if mesh_pulls.points != n or chunk_start.shape[0] != chunks + 1 or chunk_start[chunks] > other.shape[0] \
            or other.shape[1] != LANES or k.shape != other.shape or k_rest.shape != other.shape \
            or L.shape[1] < n or R.shape[0] < n or R.shape[1] != 4 or free.shape[0] < n or keep.shape[0] < n \
            or first < 0 or stop > chunks:
        return
    motion = (g[0], g[1], g[2], mesh_knobs.dt2)
    for e in range(first, stop):
        at = e * LANES
        pull_lanes(P, R, L, free, keep, other, k, k_rest, (chunk_start[e], chunk_start[e + 1]), at,
                   min(LANES, n - at), motion)


def rows_buffer(n: int) -> np.ndarray:
    """An (n, 4) float64 buffer for :func:`to_rows` whose rows start on 32-byte
    boundaries: a far end's 256-bit load then never spans two cache lines."""
    whole = np.zeros(4 * n + 8)
    skip = (-whole.ctypes.data % 64) // 8
    return whole[skip:skip + 4 * n].reshape(n, 4)


@njit(**KERNEL_OPTIONS)
def to_rows(P, R, lo, hi):
    """Points ``lo:hi`` of the (3, N) planes P [m] copied into the rows of R (N, 4),
    whose fourth column is 0: the far ends :func:`pull_step` reads, a load
    each. Written through the rows' flat view, whose stride LLVM knows: it
    then turns eight points' planes into their rows in vector shuffles, where
    ``R[q, c]`` (the row's stride read at run time) left one store a number."""
    x, y, z = P[0], P[1], P[2]
    flat = R.reshape(-1)
    for q in range(lo, hi):
        flat[4 * q] = x[q]
        flat[4 * q + 1] = y[q]
        flat[4 * q + 2] = z[q]
        flat[4 * q + 3] = 0.0
