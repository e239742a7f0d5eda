"""The slack sort: the list ordered by how far past the reach each pair was at the build.

The timings behind its choices are in docs/performance.md ('Slack sort').
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..pull_lanes import LANES
from ..shared import EXACT_OPTIONS
from ..simd import BYTES64, count_equal
from .buffers import BUCKET, SLACK_BUCKETS
from .slack_lanes import slack_lanes

@njit(**EXACT_OPTIONS)
def label_pairs(R, reach, pairs, k0, k1, labels, scale):
    """The slack bucket of listed pairs ``k0:k1`` into ``labels``: 0 if the pair is
    closer than ``reach``, else 1 + its squared distance past the reach's
    square times ``scale``, at most SLACK_BUCKETS - 1. See
    :func:`sort_by_slack`. ``R`` (N, 4) holds the positions as rows
    (:func:`..mesh_pulls.to_rows`): eight pairs at a time take their ends
    from it in vector code (:func:`.slack_lanes.slack_lanes`), the last few
    one by one, with the same roundings. A pass of its own, without the
    pushes: it has no branch, and the pairs that touch, bucket 0, are pushed
    after the sort like those of any substep."""
    reach2 = reach * reach
    last = np.float64(SLACK_BUCKETS - 1)
    a, b = pairs[0], pairs[1]
    k = k0
    while k + LANES <= k1:
        slack_lanes(R, a, b, k, reach2, scale, last, labels)
        k += LANES
    for q in range(k, k1):
        i, j = a[q], b[q]
        dx = R[j, 0] - R[i, 0]
        dy = R[j, 1] - R[i, 1]
        dz = R[j, 2] - R[i, 2]
        d2 = dx * dx + dy * dy + dz * dz
        steps = min(1.0 + (d2 - reach2) * scale, last)
        labels[q] = np.int8(0 if d2 < reach2 else steps)


SORT_LANES = 8
"""runs of the list each part of :func:`sort_by_slack` walks side by side, so
that the others go on while one run's count waits on its last store: of 1,
2, 4 and 8 runs, 8 sorted a long list fastest (figures: docs/performance.md,
'Slack sort')"""


PAD_ROWS = -(-16 // SLACK_BUCKETS)
"""rows of counters (int64) between two segments' blocks in :func:`sort_by_slack`:
at least 128 bytes"""


@njit(**EXACT_OPTIONS, inline="always")
def sort_by_slack(pairs, labels, segments, meta, parts):
    """The listed pairs ordered by their ``labels`` (slack buckets), keeping the
    order within a bucket, packed from the front of a new array as large as
    ``pairs`` (copying them back would be a pass more); where each bucket
    ends goes into ``meta[BUCKET:]``. The pairs lie in ``segments``, int64
    (S, 2) rows (start, count) in ``pairs`` and ``labels``, with gaps between
    them: each share of the list build wrote its own, and the sort gathers
    them, so they are not first moved together into one run (a pass over
    the list, on one thread). Segment i is owned by part ``i * parts // S``,
    which sorts it here and pushes its pairs between builds. With the
    shares in the order of their points, a part owns the pairs found from
    the points it moves, and reads the other parts' points only for pairs
    that reach across: on two threads, pushing an even cut of the list made
    each part read half its ends from lines the other core had just written
    (docs/performance.md, 'Pairs pushed by the part that owns them'). Each
    part writes only into its own block of the sorted list: sorted by the
    part that found them (``i % parts``, as the build deals its shares out),
    the two parts' runs took turns in every bucket, and the sort took longer
    on two threads than on one (docs/performance.md, 'Where two threads'
    substep goes').

    A pair of the list started ``slack`` past the reach, and it cannot touch
    before two points have come closer by that much; :func:`drift_bound`
    bounds by how much any two have, so each substep only checks the buckets
    that bound reaches (see :func:`self_collide`). Pairs that touched at the
    build come first: every substep checks them, without a branch (see
    :func:`pair_pushes`). Runs once after each build; its scratch is
    allocated here, as the list may have grown.

    A counting sort cut into ``parts`` (``prange`` where inlined into
    parallel code), each walking SORT_LANES runs of each of its segments side by side
    with a counter row per run: a single run's next count or place waits on
    the store of its last whenever two labels in a row are alike. Its loops
    are inlined here, where ``out`` is allocated: compiled apart, each store
    into ``out`` might have changed a counter, which was then read again.
    """
    # a block of counter rows per segment, apart from the next by a row of padding
    segs = segments.shape[0]
    at = np.zeros((segs, SORT_LANES + PAD_ROWS, SLACK_BUCKETS), dtype=np.int64)
    for t in prange(parts):
        own = np.int64(t)  # prange's index is unsigned: mixed with a signed one, a float
        for i in range(own * segs // parts, (own + 1) * segs // parts):
            lo = segments[i, 0]
            _count_runs(labels, lo, lo + segments[i, 1], at[i])
    # the list is cut into one block per part, the pairs each part owns: those
    # its segments found, the segments in order cut into ``parts`` equal runs
    # (a list build's shares are ranges of points in order, so a part owns the
    # pairs found from its own points, see self_collide). In a block, bucket j
    # follows bucket j - 1; in a bucket, the owner's segments in turn, their
    # runs in turn
    total = 0
    for o in range(parts):
        for j in range(SLACK_BUCKETS):
            for i in range(o * segs // parts, (o + 1) * segs // parts):
                for r in range(SORT_LANES):
                    c = at[i, r, j]
                    at[i, r, j] = total
                    total += c
            meta[BUCKET + o * SLACK_BUCKETS + j] = total
    out = np.empty_like(pairs)
    for t in prange(parts):
        own = np.int64(t)
        for i in range(own * segs // parts, (own + 1) * segs // parts):
            lo = segments[i, 0]
            _place_runs(pairs, labels, lo, lo + segments[i, 1], at[i], out)
    return out


@njit(**EXACT_OPTIONS, inline="always")
def _count_runs(labels, lo, hi, at):
    """Labels ``lo:hi`` cut into SORT_LANES runs, each run counting into its row
    of ``at``; what is left over goes to the last run (the runs
    :func:`_place_runs` walks)."""
    size = (hi - lo) // SORT_LANES
    for r in range(SORT_LANES):
        _count(labels, lo + r * size, lo + (r + 1) * size, at[r])
    _count(labels, lo + SORT_LANES * size, hi, at[SORT_LANES - 1])


@njit(**EXACT_OPTIONS, inline="always")
def _count(labels, lo, hi, row):
    """Add the count of each label among ``labels[lo:hi]`` into ``row``
    (SLACK_BUCKETS,): each label's count 64 labels at a time
    (:func:`~..simd.count_equal`), then the last few one by one. Counted one
    by one throughout, each label's count was loaded, added and stored back:
    0.7 ns a label on a 74,000-pair list (docs/performance.md, 'A list
    build's passes, one by one')."""
    whole = lo + (hi - lo) // BYTES64 * BYTES64
    for j in range(SLACK_BUCKETS):
        total = 0
        for k in range(lo, whole, BYTES64):
            total += count_equal(labels, k, j)
        row[j] += total
    for k in range(whole, hi):
        row[labels[k]] += 1


@njit(**EXACT_OPTIONS, inline="always")
def _place_runs(pairs, labels, lo, hi, at, out):
    """The runs of :func:`_count_runs` again, each pair put into ``out`` at the next
    place its run's row of ``at`` holds for its label."""
    size = (hi - lo) // SORT_LANES
    for i in range(size):
        for r in range(SORT_LANES):
            _place(pairs, labels, lo + r * size + i, at, np.uint64(r), out)
    for k in range(lo + SORT_LANES * size, hi):
        _place(pairs, labels, k, at, np.uint64(SORT_LANES - 1), out)


@njit(**EXACT_OPTIONS, inline="always")
def _place(pairs, labels, k, at, r, out):
    """Put pair k into ``out`` at the next place row r of ``at`` holds for its label.
    Every index is unsigned: a signed one costs a negative-index check per
    access, and with them the sort took twice as long (docs/performance.md,
    'Slack sort')."""
    q = np.uint64(k)
    j = np.uint64(labels[q])
    place = np.uint64(at[r, j])
    out[0, place] = pairs[0, q]
    out[1, place] = pairs[1, q]
    at[r, j] = place + np.uint64(1)


@njit(cache=True, inline="always")
def checked_pairs(meta, reachable, owner=0):
    """Where the pairs of part ``owner`` that a substep checks end in the list: its
    buckets whose least slack lies below ``reachable`` (in the steps of
    :func:`pair_pushes`); they start where the part before's buckets end."""
    top = min(np.int64(reachable) + 1, SLACK_BUCKETS - 1)
    return meta[BUCKET + owner * SLACK_BUCKETS + top]
