"""The self-collision stage of a substep: its passes in order.

The timings behind its thresholds and the order of its passes are in
docs/performance.md ('List build', 'Pushes').
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..mesh_pulls import to_rows
from ..shared import EXACT_OPTIONS, KERNEL_OPTIONS, part_range
from .buffers import BUCKET, PAIRS, REBUILDS, SKIN, SLACK_BUCKETS, SPARSE_PAIRS, VALID
from .drift import copy_and_level, drift_bound, single_copy, widened2
from .hashgrid import sort_into_cells
from .listbuild import query_points
from .nearstencil import NEAR_LEVELS, near_pushes
from .pushes import apply_pushes, apply_sparse, pair_pushes
from .slack import checked_pairs, label_pairs, sort_by_slack

@njit(**EXACT_OPTIONS, inline="always")
def self_collide(P, points, simulation_steps, lists, pairs):
    """Push apart pairs closer than 2*thickness (Jacobi: all from the same positions).

    Each pair pushes both ends; a point's pushes are averaged over its
    colliding neighbours and divided by ``simulation_steps``; pinned points
    (``free`` 0) stay. Returns (pairs array, number of colliding pairs); the
    array is a new one after each build (see :func:`sort_by_slack`). When
    the points are spread wider than ``span`` [m] (a run that blew up) no
    list is built and nothing is pushed.

    The work is cut into as many parts as the buffers have (``push.shape[0]``),
    each with its own pushes, summed at the end. Inlined into a
    ``parallel=True`` caller the parts run on threads (``prange``); called
    from serial code they run one after another. The result depends on the
    number of parts (the order of the sums), not on the threads.

    ``points`` is the :class:`~clothsim.solver.groups.Points` of the cloth
    (rest layout, free weights, thickness, span), ``lists`` its
    :class:`~.buffers.NeighbourList` and ``pairs`` its list of pairs now
    (``lists.pairs`` until a build replaces it); the positions P are (3, N) planes.
    """
    # read by name once, here: a store through a tuple's field inside a prange
    # body is dropped by numba
    rest, free, thickness, span = points.rest, points.free, points.thickness, points.span
    reference, frame, centres = lists.reference, lists.frame, lists.centres
    push, count, meta, tally = lists.push, lists.count, lists.meta, lists.tally
    pos32, extent32, touched = lists.pos32, lists.extent32, lists.touched
    near, rows = lists.near_pairs, lists.rows
    n = P.shape[1]
    parts = push.shape[0]
    reach = 2.0 * thickness
    skin = 0.001 * meta[SKIN] * reach
    # the positions in single precision, from the last build's origin: the drift
    # test, the near stencil and the pairs that rarely touch read them (see
    # drift_bound, near_pushes, pair_pushes)
    worst = np.empty((parts, 2), dtype=np.int32)
    extent = copy_and_level(P, frame, pos32, extent32, reference, skin, centres, worst)
    bound = np.inf if meta[VALID] == 0 else drift_bound(pos32, reference, skin, centres,
                                                         extent + frame[3], worst)
    fresh = not bound < skin
    span2 = (reach + skin) ** 2 - reach * reach
    if fresh:
        radius = reach + skin
        # each of the first parts sorts the points into a copy of the grid of its
        # own, all at the same time, so that its query reads the grid from its
        # own cache (see GRID_COPIES); the others query copy 0
        copies = lists.cell_start.shape[0]
        grids = np.empty((copies, 8))
        for t in prange(copies):
            grid = sort_into_cells(P, radius, span, lists, t)
            for c in range(8):  # by element: an array assignment compiles string helpers for its error
                grids[t, c] = grid[c]
        if grids[0, 3] == 0.0:
            meta[VALID] = 0
            return pairs, 0
        # the points are cut into more shares than parts, dealt out in turn: the
        # cost of a share depends on how crowded its part of the cloth is
        shares = tally.shape[0]
        size = pairs.shape[1] // shares
        while True:  # once more with room for twice the largest share when one overflowed
            for t in prange(parts):
                own = np.int64(t)  # prange's index is unsigned: with the 0, a float
                grid = grids[own if own < copies else 0]
                for j in range(t, shares, parts):
                    lo, hi = part_range(n, shares, j)
                    tally[j, 0] = query_points(grid, reach, radius, rest, lists, lo, hi, pairs,
                                               j * size, size)
                # the positions as rows for the labels, each part its own points
                lo, hi = part_range(n, parts, own)
                to_rows(P, rows, lo, hi)
            most = 0
            for j in range(shares):
                most = max(most, tally[j, 0])
            if most <= size:
                break
            size = 2 * most
            pairs = np.empty((2, shares * size), dtype=np.int32)
        if near.shape[1] > 0:  # a mesh's near list, which the build dropped (see nearlist)
            listed = _close_up(pairs, tally, size)
            if listed + near.shape[1] > pairs.shape[1]:
                grown = np.empty((2, listed + near.shape[1] + n), dtype=np.int32)
                _copy_pairs(pairs, grown, listed)
                pairs = grown
            _append(near, pairs, listed)
            listed += near.shape[1]
            segments = _even_segments(listed, parts)
        else:
            # the shares' pairs stay where each share wrote them: the labels and
            # the sort below read them there, and the sort packs them
            segments = _share_segments(tally, size)
            listed = 0  # a loop: numba's array sum compiles helpers of its own in every process
            for j in range(shares):
                listed += tally[j, 0]
        meta[PAIRS] = listed
        # the new list labelled and sorted by slack (a pass of its own, with no
        # branch: in one with the pushes, as it was, it made the substep of a
        # build slower). Slack is measured in squared distance past the reach's
        # square (no square root per pair), in steps of the span up to the list
        # radius's square
        labels = np.empty(pairs.shape[1], dtype=np.int8)
        # each part labels the segments it owns (see sort_by_slack): their ends are
        # mostly its own points, whose rows it has just written
        for t in prange(parts):
            own, segs = np.int64(t), segments.shape[0]
            for i in range(own * segs // parts, (own + 1) * segs // parts):
                k0 = segments[i, 0]
                label_pairs(rows, reach, pairs, k0, k0 + segments[i, 1], labels, (SLACK_BUCKETS - 1) / span2)
        pairs = sort_by_slack(pairs, labels, segments, meta, parts)
        for c in range(3):
            frame[c] = P[c, 0]
        extent = single_copy(P, frame, pos32, extent32, reference)
        frame[3] = extent
        centres[:] = 0.0
        meta[VALID] = 1
        meta[REBUILDS] += 1
    if meta[VALID] == 0:
        return pairs, 0
    # every substep checks the pairs whose slack the drift bound reaches, on
    # the substep of a build the touching ones
    reachable = ((reach + bound) ** 2 - reach * reach) * (1.0 + 1e-6) / span2
    # bucket 0, the pairs that touched at the build, is pushed without a branch
    # per pair: those pairs hover about the reach, and the branch on whether
    # one touches was mispredicted about as often as not
    # the pairs that rarely touch and, between builds, the near stencil are first
    # tested in single precision (see near_pushes)
    wide2 = widened2(reach, extent)
    for t in prange(parts):
        own = np.int64(t)  # prange's index is unsigned: with the 1 below, a float
        h = near_pushes(P, reach, lists, t, parts, fresh, reachable * NEAR_LEVELS, NEAR_LEVELS / span2,
                        wide2, not fresh)
        # each part pushes the pairs it owns (see sort_by_slack): they run from the
        # end of the part before's buckets, its own touching ones first
        start = 0 if own == 0 else meta[BUCKET + own * SLACK_BUCKETS - 1]
        touching = meta[BUCKET + own * SLACK_BUCKETS]
        checked = touching if fresh else checked_pairs(meta, reachable * (SLACK_BUCKETS - 1), own)
        sure = min(checked, touching)
        h += pair_pushes(P, reach, pairs, start, sure, sure, lists, t, h, wide2)
        tally[t, 1] = h + pair_pushes(P, reach, pairs, sure, sure, checked, lists, t, h, wide2)
    hits, most = 0, 0
    for t in range(parts):
        hits += tally[t, 1]
        most = max(most, tally[t, 1])
    if hits > 0:
        inv_steps = 1.0 / simulation_steps
        if most <= SPARSE_PAIRS:
            apply_sparse(P, push, count, free, inv_steps, touched, tally)
        else:
            for t in prange(parts):
                lo, hi = part_range(n, parts, t)
                apply_pushes(P, push, count, free, inv_steps, lo, hi)
    return pairs, hits


@njit(cache=True)
def _share_segments(tally, size):
    """(start, count) of each share's pairs, int64 (shares, 2): share j wrote
    ``tally[j, 0]`` pairs from ``j * size``."""
    shares = tally.shape[0]
    out = np.empty((shares, 2), dtype=np.int64)
    for j in range(shares):
        out[j, 0] = j * size
        out[j, 1] = tally[j, 0]
    return out


@njit(cache=True)
def _even_segments(listed, parts):
    """``listed`` pairs from the front cut evenly into ``parts`` segments, (parts, 2)."""
    out = np.empty((parts, 2), dtype=np.int64)
    for t in range(parts):
        lo, hi = part_range(listed, parts, t)
        out[t, 0] = lo
        out[t, 1] = hi - lo
    return out


@njit(**EXACT_OPTIONS)
def _close_up(pairs, tally, size):
    """Move each share's pairs (share j's from ``j * size``) into one run; returns their number."""
    total = tally[0, 0]
    for t in range(1, tally.shape[0]):
        base = t * size
        for j in range(tally[t, 0]):
            pairs[0, total + j] = pairs[0, base + j]
            pairs[1, total + j] = pairs[1, base + j]
        total += tally[t, 0]
    return total


@njit(**KERNEL_OPTIONS)
def _copy_pairs(src, dst, count):
    """The first ``count`` pairs of ``src`` into ``dst`` (both (2, capacity))."""
    for c in range(2):
        for j in range(count):
            dst[c, j] = src[c, j]


@njit(**KERNEL_OPTIONS)
def _append(near, pairs, at):
    """The pairs of ``near`` (2, M) into ``pairs`` from ``at`` on."""
    for c in range(2):
        a, b = near[c], pairs[c]
        for j in range(near.shape[1]):
            b[at + j] = a[j]
