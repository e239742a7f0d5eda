"""The near list: what the grid's near stencil does, for a cloth that is not a grid.

The points of a fine cloth have many neighbours inside the list radius at
rest, and they stay inside it for good: every build of the list finds them
again, tests each against the rest layout and writes it, and on a 10,000
point mesh they were two pairs in three of the list. On a grid the near
stencil checks them as fixed offsets and the build drops them in its first,
vectorised test, from their grid rows and columns (:func:`~.nearstencil.grid_metric`).

A mesh has no rows and columns, but its rest layout can stand in for them:
each point gets two coordinates, its rest position projected onto the plane
of its cloth (two axes of the cloth's rest box), each cloth placed far from
the others. The build's first test then drops every pair closer than the
list radius in that layout (the same single-precision test the grid's
metric takes, with both spacings 1). Projecting never lengthens a distance,
so a pair the build keeps is at least the radius apart at rest, farther
than the reach: no further test can reject it, and the build appends
without one. The pairs it drops that are not closer than the reach in the
rest layout itself (in three dimensions, in double precision, the rule
that decides which pairs are never pushed) are this near list, found once,
and appended to the list at every build, so every pair the list holds
without the layout, it holds with it.

Where a cloth is far from flat (a sleeve, a skirt), its projection brings
points close that are not: the near list would hold pairs that rarely
touch. A cloth whose near list would hold more than NEAR_LIMIT pairs a point
takes no layout, and its pairs all go through the build's tests.
"""

from __future__ import annotations

import numpy as np

NEAR_LIMIT = 24
"""most near-list pairs per point before the layout is given up"""


def rest_layout(rest: np.ndarray, starts: list[int], gap: float) -> np.ndarray:
    """Two coordinates per point [m], float64 (2, N): each cloth (points
    ``starts[k]:starts[k+1]``) projected onto the two longest axes of its rest box,
    the cloths side by side along the first, ``gap`` [m] apart."""
    n = len(rest)
    layout = np.zeros((2, n))
    at = 0.0
    for lo, hi in zip(starts[:-1], starts[1:]):
        if hi <= lo:
            continue
        part = rest[lo:hi]
        axes = np.argsort(np.ptp(part, axis=0))[::-1][:2]
        uv = part[:, axes] - part[:, axes].min(axis=0)
        layout[0, lo:hi] = uv[:, 0] + at
        layout[1, lo:hi] = uv[:, 1]
        at += float(uv[:, 0].max()) + gap
    return layout


def layout_metric(radius: float) -> np.ndarray:
    """The metric (spacings² 1 and 1, rho² the list radius², exact) that makes the build
    drop the pairs closer than ``radius`` [m] in the layout, as in :func:`~.nearstencil.grid_metric`."""
    return np.array([1.0, 1.0, float(np.float32(radius * radius)), 1.0])


def dropped(layout32: np.ndarray, a: np.ndarray, b: np.ndarray, metric: np.ndarray) -> np.ndarray:
    """Which pairs (a, b) the build's first test drops: the single-precision
    arithmetic of :func:`clothsim.solver.simd.inside`, in its order."""
    f32 = np.float32
    dr = layout32[0, b] - layout32[0, a]
    dc = layout32[1, b] - layout32[1, a]
    grid = (dr * dr) * f32(metric[0]) + (dc * dc) * f32(metric[1])
    return ~(grid >= f32(metric[2]))


def near_pairs(rest: np.ndarray, layout32: np.ndarray, reach: float, metric: np.ndarray) -> np.ndarray:
    """The pairs the build drops that are not closer than ``reach`` [m] at rest, each
    once, int32 (2, M): every pair within a hair more than the metric's radius in the
    layout, kept where :func:`dropped` drops it."""
    from scipy.spatial import cKDTree

    radius = float(np.sqrt(metric[2]))
    found = cKDTree(layout32.T.astype(np.float64)).query_pairs(radius * (1.0 + 1e-4), output_type="ndarray")
    a, b = found[:, 0].astype(np.int64), found[:, 1].astype(np.int64)
    keep = dropped(layout32, a, b, metric)
    keep &= np.linalg.norm(rest[a] - rest[b], axis=1) >= reach
    order = np.lexsort((b[keep], a[keep]))
    return np.stack([a[keep][order], b[keep][order]]).astype(np.int32)


def mesh_near(rest: np.ndarray, starts: list[int], reach: float, radius: float
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(layout float32 (2, N), metric (4,), near pairs int32 (2, M)) for a model of
    cloths at ``starts`` whose list radius is ``radius`` and reach ``reach`` [m],
    or None where the near list would hold more than NEAR_LIMIT pairs a point."""
    n = len(rest)
    if n < 2:
        return None
    layout32 = rest_layout(rest, starts, 4.0 * radius).astype(np.float32)
    metric = layout_metric(radius)
    pairs = near_pairs(rest, layout32, reach, metric)
    if pairs.shape[1] > NEAR_LIMIT * n:
        return None
    return layout32, metric, pairs
