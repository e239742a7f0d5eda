"""The buffers of the cell grid and the neighbour list, and the layout of their state."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..mesh_pulls import rows_buffer
from ..shared import BLOCK

NEAR = 5
"""grid offsets up to this many rows and columns may be checked as a stencil"""

PUSH_DTYPE = np.float32
"""the pushes and their counts are summed in single precision: the pushes land
all over the buffers and the applying pass reads them whole, so half the bytes
are half the cache lines to fetch on one thread and, with two, half the lines
that go from core to core every substep, as each part's buffers are read and
cleared by the other part (figures: docs/performance.md, "Two cores near and
far"). A push is at most the reach (millimetres), so single precision keeps it
to a few times 1e-10 m; a count is a whole number, exact in single precision up
to 2**24"""

SPARSE_PAIRS = 64
"""when no part pushed more pairs than this, only their ends are moved, not
every point: see :func:`apply_sparse`"""

QUERY_SHARES = 4
"""shares of the list build per thread, where there is more than one"""

GRID_COPIES = 4
"""most copies of the cell grid: each of the first this many parts sorts the
points into a copy of its own, all at once, and queries it. With one copy,
sorted on one thread, every other part's query first fetched the whole grid
from that core's cache (figures: docs/performance.md, 'A cell grid per
part'). A copy takes 136 bytes a point: past this many parts the others
share copy 0"""

WIDE = 64
"""candidates tested together in a longer range: one bit each in a 64-bit word"""

PAD = WIDE
"""columns past the last slot of ``sorted_pos`` and ``order``: a chunk of
candidates may read that far beyond its range, and masks those slots out"""

# fields of the ``meta`` int64 array that carries the list's state between calls
# (SKIN: the skin in thousandths of the reach)
PAIRS, VALID, REBUILDS, COLS, SKIN, BUCKET = 0, 1, 2, 3, 4, 5

SLACK_BUCKETS = 16
"""buckets of the list by how far past the reach a pair was at the build: see
:func:`sort_by_slack`. A substep checks its last reachable bucket whole: on
the piling 50x50 cloth it checked 6% fewer pairs than with 8 buckets, and the
sort costs the same"""

META_SIZE = BUCKET + SLACK_BUCKETS
"""``meta``'s size for one part; each part more adds SLACK_BUCKETS: ``BUCKET + o *
SLACK_BUCKETS + j`` is where bucket j of the pairs part o owns ends in the list
(see :func:`~.slack.sort_by_slack`)"""


class NeighbourList(NamedTuple):
    """The buffers of the cell grid and the neighbour list, allocated once per
    cloth by :meth:`allocate`; :func:`~clothsim.solver.selfcollide.self_collide`
    reads them by name. Every array is scratch or state of the list that
    lives from one substep to the next; ``pairs`` is replaced by a new array
    after each build (see :func:`~.slack.sort_by_slack`)."""

    cell_start: np.ndarray
    """per copy of the cell grid (see GRID_COPIES): cell c holds slots
    ``cell_start[g, c] : cell_start[g, c+1]``, int64 (copies, cells + 1)"""
    search: np.ndarray
    """per copy and point: its cell and the cells it searches, int64 (copies,
    SEARCH_ROWS, N): see :func:`~.hashgrid.sort_into_cells`"""
    order: np.ndarray
    """per copy: the point in each slot, int32 (copies, N + PAD): past the points see ``_put``"""
    slot: np.ndarray
    """per copy: the slot of each point, int64 (copies, N)"""
    sorted_pos: np.ndarray
    """per copy and slot: position from the grid's corner, grid row and column,
    float32 (copies, 5, N + PAD)"""
    reference: np.ndarray
    """the positions at the build, float32 from ``frame``'s origin, (3, N)"""
    frame: np.ndarray
    """the build's origin (x, y, z) [m] and the largest magnitude of a coordinate of reference, (4,)"""
    centres: np.ndarray
    """the drift test's last centres, (2, 3): see :func:`~.drift.drift_bound`"""
    pairs: np.ndarray
    """the listed pairs, int32 (2, capacity), sorted by slack bucket"""
    push: np.ndarray
    """each part's summed pushes [m], PUSH_DTYPE (parts, 3, N)"""
    count: np.ndarray
    """each part's count of pushes per point, PUSH_DTYPE (parts, N)"""
    meta: np.ndarray
    """the list's state, int64 (META_SIZE + SLACK_BUCKETS * (parts - 1),): fields PAIRS,
    VALID, REBUILDS, COLS, SKIN, then the buckets' ends part by part (see META_SIZE)"""
    near_offset: np.ndarray
    """flat offsets of the near stencil, int64 (S,): see :func:`~.nearstencil.near_stencil`"""
    near_weight: np.ndarray
    """1 where a stencil pair exists and is not closer than the reach at rest, uint8 (S, N + PAD)"""
    near_table: np.ndarray
    """the (dr, di) the stencil takes, int64 (NEAR + 1, 2 NEAR + 1)"""
    near_metric: np.ndarray
    """the :func:`~.nearstencil.grid_metric` of the offsets the list never holds, or
    of a mesh's rest layout (:mod:`.nearlist`), (4,)"""
    layout: np.ndarray
    """a mesh's rest layout, the two coordinates per point its metric takes in place
    of grid rows and columns, float32 (2, N), or (2, 0) where the points are a grid"""
    near_pairs: np.ndarray
    """the pairs of a mesh's near list (:mod:`.nearlist`), appended at each build, int32 (2, M)"""
    near_masks: np.ndarray
    """each part's bits of stencil pairs inside the reach, uint64 (parts, words)"""
    near_level: np.ndarray
    """per offset and block of the stencil: slack level of its closest pair at the build, int32"""
    pos32: np.ndarray
    """the positions in single precision from ``frame``'s origin, (3, N + PAD)"""
    extent32: np.ndarray
    """the bits (as of a float32) of each part's largest magnitude of a coordinate, int32 (parts,)"""
    touched: np.ndarray
    """each part's ends of pushed pairs and a spare pair that ``pair_pushes`` may
    overwrite, int64 (parts, 2 SPARSE_PAIRS + 2)"""
    tally: np.ndarray
    """pairs found per share of the list build, pairs pushed per part, int64 (shares, 2)"""
    rows: np.ndarray
    """the positions at a build as rows of four (x, y, z, 0) [m], float64 (N, 4),
    32-byte aligned: the slack labels' loads (see :func:`~.slack.label_pairs`)"""

    @classmethod
    def allocate(cls, num_points: int, cols: int | None = None,
                 near: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None,
                 parts: int = 1, skin: float = 0.5,
                 mesh: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> NeighbourList:
        """``cols`` and ``near`` (from :func:`~.nearstencil.near_stencil`, with the
        same ``skin``) describe the cloth's grid; without them every pair goes
        through the list. ``mesh``: instead, a mesh's (layout, metric, near
        pairs) of :func:`~.nearlist.mesh_near`, made for the same reach and
        skin. ``parts``: how many threads may share the work; each has its own
        scratch and pushes. ``skin``: the fraction of the reach of
        :func:`~.nearstencil.skin_factor`."""
        from .hashgrid import CELLS_PER_POINT, SEARCH_ROWS
        n = num_points
        meta = np.zeros(META_SIZE + SLACK_BUCKETS * (max(parts, 1) - 1), dtype=np.int64)
        meta[COLS] = n if cols is None else cols
        meta[SKIN] = round(1000 * skin)
        if near is None:
            near = (np.zeros(0, np.int64), np.zeros((0, n), np.uint8),
                    np.zeros((NEAR + 1, 2 * NEAR + 1), np.int64), np.zeros(4))
        near_offset, weight, near_table, near_metric = near
        layout, near_pairs = np.zeros((2, 0), np.float32), np.zeros((2, 0), np.int32)
        if mesh is not None:
            layout, near_metric, near_pairs = mesh
        # padded: the single-precision stencil reads up to PAD pairs past the points
        near_weight = np.zeros((len(weight), n + PAD), dtype=np.uint8)
        near_weight[:, :n] = weight
        copies = min(parts, GRID_COPIES)
        return cls(
            cell_start=np.zeros((copies, max(CELLS_PER_POINT * n, 64) + 1), dtype=np.int64),
            search=np.zeros((copies, SEARCH_ROWS, n), dtype=np.int64),
            order=np.zeros((copies, n + PAD), dtype=np.int32),
            slot=np.zeros((copies, n), dtype=np.int64),
            sorted_pos=np.zeros((copies, 5, n + PAD), dtype=np.float32),
            reference=np.zeros((3, n), dtype=np.float32),
            frame=np.zeros(4),
            centres=np.zeros((2, 3)),
            pairs=np.zeros((2, 4 * n), dtype=np.int32),
            push=np.zeros((parts, 3, n), dtype=PUSH_DTYPE),
            count=np.zeros((parts, n), dtype=PUSH_DTYPE),
            meta=meta,
            near_offset=near_offset,
            near_weight=near_weight,
            near_table=near_table,
            near_metric=near_metric,
            layout=layout,
            near_pairs=near_pairs,
            near_masks=np.zeros((parts, n // BLOCK + 2), dtype=np.uint64),
            near_level=np.zeros((len(near_offset), n // BLOCK + 1), dtype=np.int32),
            pos32=np.zeros((3, n + PAD), dtype=np.float32),
            extent32=np.zeros(parts, dtype=np.int32),
            touched=np.zeros((parts, 2 * SPARSE_PAIRS + 2), dtype=np.int64),
            tally=np.zeros((parts * (QUERY_SHARES if parts > 1 else 1), 2), dtype=np.int64),
            rows=rows_buffer(n),
        )

    @property
    def rebuilds(self) -> int:
        """how often the list was built"""
        return int(self.meta[REBUILDS])

    @property
    def parts(self) -> int:
        return self.push.shape[0]
