"""Spring forces, the Verlet step and Provot's limit over spring lists: the general path.

The grid path (:mod:`.springs`) needs one grid cloth, whose springs are
fixed offsets between points. Any other model (a cloth from a mesh, several
cloths in one scene) takes this path: every spring is a pair of point
indices, so its loads are gathers, not strides.

The points are cut into parts, ranges that threads share (one part: the
whole model). A substep here is two passes over the springs:

1. :func:`.mesh_pulls.pull_step` sums each point's pulls from its springs
   and moves it (the Verlet step), eight points at a time, each part its
   own points at once: the springs as each point's slots
   (:class:`.mesh_pulls.MeshPulls`);
2. :func:`mesh_provot` shortens the springs over their limit, one after another
   (Gauss-Seidel, as the CS184 course code does), each part its own springs
   (both ends in its points) at once, the springs across parts afterwards on
   one thread: the springs as lists of ends, cut by part. Eight springs at a
   time are first tested at once on the positions as rows, and only an
   eight with a spring over its limit goes one by one.

Springs of every cloth are in one list; each names its *set*, ``3 * cloth +
kind``, which indexes the per-set constants of :class:`~.groups.MeshKnobs`, so
each cloth keeps its own ks, density and spring toggles.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from ..model import Model
from .mesh_pulls import spring_sets
from .provot import MAX_STRETCH, shorten
from .pull_lanes import LANES, over_lanes
from .shared import KERNEL_OPTIONS


class MeshSprings(NamedTuple):
    """The springs of a model as lists, ordered for the parts that share a substep."""

    a: np.ndarray
    """first end of each spring, int32 (S,)"""
    b: np.ndarray
    """second end, int32 (S,)"""
    limit2: np.ndarray
    """Provot: the square of MAX_STRETCH times the rest length [m²], float64 (S,)"""
    set: np.ndarray
    """its set, 3 x cloth + kind, int64 (S,)"""
    share: np.ndarray
    """the part of a Provot correction each end takes, float64 (2, S): half
    each, all to the free end when the other is pinned, none when both are"""
    part_start: np.ndarray
    """springs of part t (both ends in its points) are ``part_start[t]:part_start[t+1]``,
    those across parts the last range, int64 (parts + 2,)"""


def build_mesh_springs(model: Model, parts: int) -> MeshSprings:
    """The springs of ``model`` for a substep cut into ``parts`` ranges of points
    (``part_range(N, parts, t)``): each part's own springs in model order, then
    those across parts, in model order too."""
    n = model.num_points
    a = model.spring_a.astype(np.int64)
    b = model.spring_b.astype(np.int64)
    owner_a = _owner(a, n, parts)
    owner_b = _owner(b, n, parts)
    group = np.where(owner_a == owner_b, owner_a, parts)
    order = np.argsort(group, kind="stable")
    part_start = np.searchsorted(group[order], np.arange(parts + 2)).astype(np.int64)
    a, b = a[order], b[order]
    rest = model.spring_rest[order].astype(np.float64)
    free = ~model.pinned
    fa, fb = free[a].astype(np.float64), free[b].astype(np.float64)
    share = np.stack([fa * (1.0 - 0.5 * fb), fb * (1.0 - 0.5 * fa)])
    out = MeshSprings(a=a.astype(np.int32), b=b.astype(np.int32), limit2=(MAX_STRETCH * rest) ** 2,
                      set=spring_sets(model)[order], share=share, part_start=part_start)
    for arr in out:
        arr.setflags(write=False)
    return out


def _owner(p: np.ndarray, n: int, parts: int) -> np.ndarray:
    """The part whose range ``part_range(n, parts, t)`` holds each point of p."""
    cuts = np.array([t * n // parts for t in range(parts + 1)])
    return np.searchsorted(cuts, p, side="right") - 1


@njit(**KERNEL_OPTIONS)
def mesh_provot(P, R, mesh_springs, enabled, lo, hi):
    """Shorten springs ``lo:hi`` longer than their limit (MAX_STRETCH x rest) back to
    it, one after another, where ``enabled[set]``; a pinned end does not move.

    R (N, 4) holds the positions of the (3, N) planes P as rows
    (:func:`.mesh_pulls.to_rows`) for the ends of these springs, and is kept
    so: eight springs at a time are first tested in one vector test on R
    (:func:`.pull_lanes.over_lanes`), which never misses a spring over its
    limit, and only an eight where it finds one goes one spring after
    another, as before. The result is the same to the bit as going one by
    one throughout. Where R is not P's rows' shape, every spring goes one by
    one."""
    a, b, limit2 = mesh_springs.a, mesh_springs.b, mesh_springs.limit2
    sets, share = mesh_springs.set, mesh_springs.share
    rows = R.shape[0] >= P.shape[1] and R.shape[1] == 4
    s = lo
    while s < hi:
        stop = min(s + LANES, hi)
        # the springs one by one in their own loop, not a helper's: a call per
        # spring (inlined or not) took each eight three times as long
        if stop - s < LANES or not rows or over_lanes(R, a, b, limit2, s):
            for t in range(s, stop):
                i, j = a[t], b[t]
                dx = P[0, j] - P[0, i]
                dy = P[1, j] - P[1, i]
                dz = P[2, j] - P[2, i]
                if dx * dx + dy * dy + dz * dz > limit2[t] and enabled[sets[t]]:
                    shorten(P, i, j, np.sqrt(limit2[t]), share[0, t], share[1, t])
                    if rows:
                        for c in range(3):
                            R[i, c] = P[c, i]
                            R[j, c] = P[c, j]
        s = stop
