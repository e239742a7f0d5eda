"""Colliders: one module per kind, walked in the order of :class:`Colliders`.

Each kind's module holds ``pack(specs)``, which turns the scene's colliders
of that kind into one float64 array of rows (or None when the scene has
none), and a kernel ``(P, L, free, rows, lo, hi)`` that moves points
``lo:hi`` of the (3, N) positions ``P`` out of them, given the last
positions ``L`` and the ``free`` weights (0 for pinned points). A kernel
returns at once when its rows are None; numba prunes that branch when it
compiles the substep for a scene without the kind, so a scene compiles only
the colliders it has.

Adding a kind: its module, its field in :class:`~clothsim.solver.groups.Control`
and in :data:`KINDS`, its line in :func:`collide` and in :func:`pack_colliders`. The colliders are
fields of the control group itself, not a group of their own inside it:
numba cannot hand a named tuple read from another one into a ``prange`` body.
"""

from __future__ import annotations

from numba import njit

from . import plane, sphere
from .plane import PLANE_OFFSET, collide_planes
from .sphere import collide_spheres


KINDS = ("spheres", "planes")
"""the collider fields of :class:`~clothsim.solver.groups.Control`, in the order
:func:`collide` walks them"""


def pack_colliders(spheres, planes) -> dict:
    """The collider fields of :class:`~clothsim.solver.groups.Control`, from the
    scene's collider objects of each kind."""
    return dict(spheres=sphere.pack(spheres), planes=plane.pack(planes))


@njit(cache=True)
def collide(P, L, free, control, lo, hi):
    """Points ``lo:hi`` out of every collider of ``control`` (a
    :class:`~clothsim.solver.groups.Control`), kind after kind, in the CS184 order."""
    collide_spheres(P, L, free, control.spheres, lo, hi)
    collide_planes(P, L, free, control.planes, lo, hi)


__all__ = ["KINDS", "PLANE_OFFSET", "collide", "collide_planes", "collide_spheres", "pack_colliders"]
