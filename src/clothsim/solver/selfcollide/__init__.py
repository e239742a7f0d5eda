"""Self-collision: a spatial hash feeding a neighbour list with a skin.

Every pair closer than ``reach = 2*thickness`` is pushed apart. Finding those
pairs with a spatial hash costs far more than pushing them, and between two
substeps the points barely move relative to each other. So the hash is asked
for every pair within ``reach + skin`` (a neighbour list, as in molecular
dynamics), and each substep only tests the listed pairs. The list is rebuilt
as soon as any point may have come within ``reach`` of a point not listed:
when the displacements since the build may differ by ``skin`` between two
points (not while every displacement lies within ``skin/2`` of one centre,
see :func:`_drift_bound`). Two unlisted points started at least
``reach + skin`` apart and their displacements differ by less than
``skin``, so they are still farther apart than ``reach``; the pairs found
are exactly those a hash rebuilt every substep would find. The same bound,
taken below ``skin``, spares most listed pairs their test: one that started
farther past the reach than the displacements can differ by cannot touch
yet, and the list is kept sorted by that slack (:func:`_sort_by_slack`).

The spatial hash is a dense grid of cells over the cloth's bounding box (a
perfect hash: no two cells share a bucket, so no key is checked), filled
by a counting sort, so a rebuild is a few linear passes. A point looks in
every cell that its search sphere overlaps, its own and the adjacent ones,
so no pair is missed at a cell border; cells adjacent along x are adjacent
in memory, so each row of them is one range of candidates.
Pairs already closer than ``reach`` at rest (neighbours on a fine grid) never
enter the list: the C++ course code pushes them apart, and its fine cloths
then fight their own springs and boil.

Positions are (3, N) coordinate planes; ``rest`` is the (N, 3) start layout.
"""

from .buffers import NeighbourList
from .collide import self_collide
from .nearstencil import near_stencil, skin_factor

__all__ = ["NeighbourList", "near_stencil", "self_collide", "skin_factor"]
