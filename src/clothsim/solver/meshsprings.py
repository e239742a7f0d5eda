"""Spring forces, the Verlet step and Provot's limit over spring lists: the general path.

The grid path (:mod:`.springs`) needs one grid cloth, whose springs are
fixed offsets between points. Any other model (a cloth from a mesh, several
cloths in one scene) takes this path: every spring is a pair of point
indices, so its loads are gathers, not strides.

The points are cut into parts, ranges that threads share (one part: the
whole model), and the springs into each part's own (both ends in its points)
and those across parts. A substep here is three passes:

1. :func:`mesh_spring_forces` adds each spring's force over the point mass to
   its two ends' accelerations ``A`` (3, N), each part its own springs at
   once, the springs across parts afterwards on one thread;
2. :func:`mesh_verlet` moves each part's points;
3. :func:`mesh_provot` shortens the springs over their limit, one after another
   (Gauss-Seidel, as the CS184 course code does), each part its own springs,
   the springs across parts afterwards.

Adding into both ends of a spring in one loop was faster than writing the
forces out and gathering them per point (figures: docs/performance.md,
'General path').

Springs of every cloth are in one list; each names its *set*, ``3 * cloth +
kind``, which indexes the per-set constants of :class:`~.groups.MeshKnobs`, so
each cloth keeps its own ks, density and spring toggles.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from ..model import Model
from .provot import MAX_STRETCH, shorten
from .shared import KERNEL_OPTIONS


class MeshSprings(NamedTuple):
    """The springs of a model as lists, ordered for the parts that share a substep."""

    a: np.ndarray
    """first end of each spring, int32 (S,)"""
    b: np.ndarray
    """second end, int32 (S,)"""
    rest: np.ndarray
    """rest length [m], float64 (S,)"""
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


def spring_sets(model: Model) -> np.ndarray:
    """Each model spring's set, 3 x its cloth + its kind, int64 (S,)."""
    starts = np.array([c.start for c in model.cloths], dtype=np.int64)
    cloth = np.searchsorted(starts, model.spring_a, side="right") - 1
    return 3 * cloth + model.spring_kind.astype(np.int64)


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
    out = MeshSprings(a=a.astype(np.int32), b=b.astype(np.int32), rest=rest, limit2=(MAX_STRETCH * rest) ** 2, set=spring_sets(model)[order],
                      share=share, part_start=part_start)
    for arr in out:
        arr.setflags(write=False)
    return out


def _owner(p: np.ndarray, n: int, parts: int) -> np.ndarray:
    """The part whose range ``part_range(n, parts, t)`` holds each point of p."""
    cuts = np.array([t * n // parts for t in range(parts + 1)])
    return np.searchsorted(cuts, p, side="right") - 1


@njit(**KERNEL_OPTIONS)
def mesh_spring_forces(P, mesh_knobs, mesh_springs, A, lo, hi):
    """Add the force over the point mass of springs ``lo:hi`` [m/s²] to both ends'
    accelerations ``A`` (3, N): Hooke's law along the spring, pulling its
    first end toward its second (``mesh_knobs.k_over_m[set]``, 0 where the
    kind is off). One part's springs touch only its own points, so parts may
    add at once; the springs across parts add on one thread."""
    a, b, rest, sets = mesh_springs.a, mesh_springs.b, mesh_springs.rest, mesh_springs.set
    k_over_m = mesh_knobs.k_over_m
    x, y, z = P[0], P[1], P[2]
    ax, ay, az = A[0], A[1], A[2]
    for s in range(lo, hi):
        i, j = a[s], b[s]
        dx = x[j] - x[i]
        dy = y[j] - y[i]
        dz = z[j] - z[i]
        # a double square root and divide: in this scalar loop they cost less than
        # inv_length's single-precision estimate and its conversions (which pay
        # off where a loop is vectorised, as the grid's is)
        # (two ends at one place pull nothing, not NaN)
        f = k_over_m[sets[s]] * (1.0 - rest[s] / np.sqrt(max(dx * dx + dy * dy + dz * dz, 1e-30)))
        fx, fy, fz = f * dx, f * dy, f * dz
        ax[i] += fx
        ay[i] += fy
        az[i] += fz
        ax[j] -= fx
        ay[j] -= fy
        az[j] -= fz


@njit(**KERNEL_OPTIONS)
def mesh_verlet(P, L, free, mesh_knobs, A, lo, hi):
    """Points ``lo:hi`` take their Verlet step, ``x' = x + keep*(x - x_prev) + a dt²``
    where ``free`` is 1, with ``a`` the accelerations ``A`` (3, N) [m/s²], and
    leave ``A`` at gravity for the next substep's springs to add to; ``keep``
    is the point's cloth's (``mesh_knobs.keep`` (N,))."""
    gravity, keep, dt2 = mesh_knobs.gravity, mesh_knobs.keep, mesh_knobs.dt2
    for c in range(3):
        xc, lc, ac = P[c], L[c], A[c]
        g = gravity[c]
        for q in range(lo, hi):
            xq = xc[q]
            xc[q] = xq + free[q] * (keep[q] * (xq - lc[q]) + ac[q] * dt2)
            lc[q] = xq
            ac[q] = g


@njit(**KERNEL_OPTIONS)
def mesh_gravity(mesh_knobs, A, lo, hi):
    """Points ``lo:hi`` of the accelerations ``A`` (3, N) set to gravity [m/s²]."""
    gravity = mesh_knobs.gravity
    for c in range(3):
        ac = A[c]
        g = gravity[c]
        for q in range(lo, hi):
            ac[q] = g


@njit(**KERNEL_OPTIONS)
def mesh_provot(P, mesh_springs, enabled, lo, hi):
    """Shorten springs ``lo:hi`` longer than their limit (MAX_STRETCH x rest) back to
    it, one after another, where ``enabled[set]``; a pinned end does not move."""
    a, b, limit2 = mesh_springs.a, mesh_springs.b, mesh_springs.limit2
    sets, share = mesh_springs.set, mesh_springs.share
    for s in range(lo, hi):
        i, j = a[s], b[s]
        dx = P[0, j] - P[0, i]
        dy = P[1, j] - P[1, i]
        dz = P[2, j] - P[2, i]
        d2 = dx * dx + dy * dy + dz * dz
        if d2 > limit2[s] and enabled[sets[s]]:
            shorten(P, i, j, np.sqrt(limit2[s]), share[0, s], share[1, s])

