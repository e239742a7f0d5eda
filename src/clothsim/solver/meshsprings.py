"""Spring forces, the Verlet step and Provot's limit over spring lists: the general path.

The grid path (:mod:`.springs`) needs one grid cloth, whose springs are
fixed offsets between points. Any other model (a cloth from a mesh, several
cloths in one scene) takes this path: every spring is a pair of point
indices, so its loads are gathers, not strides.

A substep here is three passes, each cut into ranges that threads may share
with no two writing one value:

1. :func:`mesh_spring_forces` writes each spring's force over the point mass into
   ``F`` (S, 3), a range of springs per part;
2. :func:`mesh_verlet` has each point of a range gather its springs' forces
   through the incidence lists (``first``/``spring``/``sign``: the CSR of the
   springs at each point) and take its Verlet step; gathering, rather than
   adding into both ends of every spring, lets points be split among threads;
3. :func:`mesh_provot` shortens the springs over their limit, one after another
   (Gauss-Seidel, as the CS184 course code does), springs with both ends in
   a part's points by that part, the springs across parts afterwards.

Springs of every cloth are in one list; each names its *set*, ``3 * cloth +
kind``, which indexes the per-set constants of :class:`~.groups.MeshKnobs`, so
each cloth keeps its own ks, density and spring toggles.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from ..model import Model
from .provot import MAX_STRETCH
from .shared import KERNEL_OPTIONS, inv_length, part_range


class MeshSprings(NamedTuple):
    """The springs of a model as lists, ordered for the parts that share a substep."""

    a: np.ndarray
    """first end of each spring, int64 (S,)"""
    b: np.ndarray
    """second end, int64 (S,)"""
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
    first: np.ndarray
    """point q's springs are entries ``first[q]:first[q+1]`` of ``spring``, int64 (N + 1,)"""
    spring: np.ndarray
    """the springs at each point, int64 (2S,)"""
    sign: np.ndarray
    """+1 where the point is the spring's first end, -1 where its second, float64 (2S,)"""


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
    ends = np.concatenate([a, b])
    by_point = np.argsort(ends, kind="stable")
    spring = np.concatenate([np.arange(len(a)), np.arange(len(a))])[by_point].astype(np.int64)
    sign = np.concatenate([np.ones(len(a)), -np.ones(len(a))])[by_point]
    first = np.searchsorted(ends[by_point], np.arange(n + 1)).astype(np.int64)
    out = MeshSprings(a=a, b=b, rest=rest, limit2=(MAX_STRETCH * rest) ** 2, set=spring_sets(model)[order],
                      share=share, part_start=part_start, first=first, spring=spring, sign=sign)
    for arr in out:
        arr.setflags(write=False)
    return out


def _owner(p: np.ndarray, n: int, parts: int) -> np.ndarray:
    """The part whose range ``part_range(n, parts, t)`` holds each point of p."""
    cuts = np.array([t * n // parts for t in range(parts + 1)])
    return np.searchsorted(cuts, p, side="right") - 1


@njit(**KERNEL_OPTIONS)
def mesh_spring_forces(P, mesh_knobs, mesh_springs, F, lo, hi):
    """The force over the point mass of springs ``lo:hi`` [m/s²] into ``F`` (S, 3):
    Hooke's law along the spring, pulling its first end toward its second
    (``mesh_knobs.k_over_m[set]``, 0 where the kind is off or the cloth's ks is)."""
    a, b, rest, sets = mesh_springs.a, mesh_springs.b, mesh_springs.rest, mesh_springs.set
    k_over_m = mesh_knobs.k_over_m
    x, y, z = P[0], P[1], P[2]
    for s in range(lo, hi):
        i, j = a[s], b[s]
        dx = x[j] - x[i]
        dy = y[j] - y[i]
        dz = z[j] - z[i]
        f = k_over_m[sets[s]] * (1.0 - rest[s] * inv_length(dx * dx + dy * dy + dz * dz))
        F[s, 0] = f * dx
        F[s, 1] = f * dy
        F[s, 2] = f * dz


@njit(**KERNEL_OPTIONS)
def mesh_verlet(P, L, free, mesh_knobs, mesh_springs, F, lo, hi):
    """Points ``lo:hi`` gather their springs' forces from ``F`` and take their
    Verlet step, ``x' = x + keep*(x - x_prev) + a dt²`` where ``free`` is 1,
    ``a`` gravity plus the springs, ``keep`` the point's cloth's (``mesh_knobs.keep`` (N,))."""
    gravity, keep, dt2 = mesh_knobs.gravity, mesh_knobs.keep, mesh_knobs.dt2
    first, spring, sign = mesh_springs.first, mesh_springs.spring, mesh_springs.sign
    gx, gy, gz = gravity[0], gravity[1], gravity[2]
    for q in range(lo, hi):
        ax, ay, az = gx, gy, gz
        for e in range(first[q], first[q + 1]):
            s, w = spring[e], sign[e]
            ax += w * F[s, 0]
            ay += w * F[s, 1]
            az += w * F[s, 2]
        fq, kq = free[q], keep[q]
        x0, x1, x2 = P[0, q], P[1, q], P[2, q]
        P[0, q] = x0 + fq * (kq * (x0 - L[0, q]) + ax * dt2)
        P[1, q] = x1 + fq * (kq * (x1 - L[1, q]) + ay * dt2)
        P[2, q] = x2 + fq * (kq * (x2 - L[2, q]) + az * dt2)
        L[0, q], L[1, q], L[2, q] = x0, x1, x2


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
            e = 1.0 - np.sqrt(limit2[s]) * inv_length(d2)
            ea, eb = e * share[0, s], e * share[1, s]
            P[0, i] += ea * dx
            P[1, i] += ea * dy
            P[2, i] += ea * dz
            P[0, j] -= eb * dx
            P[1, j] -= eb * dy
            P[2, j] -= eb * dz

