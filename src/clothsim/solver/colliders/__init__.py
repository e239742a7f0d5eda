"""Colliders: one module per kind, walked in the order of :data:`KINDS`.

Each kind's module holds ``pack(specs, t0, dt, substeps)``, which turns the
scene's colliders of that kind into float64 rows (T, K, C) for one frame
(slot s: substep s; see :mod:`.motion_rows`), or None when the scene has
none, and a kernel ``(P, L, free, rows, lo, hi, s)`` that moves points
``lo:hi`` of the (3, N) positions ``P`` out of them over substep s, given
the last positions ``L`` and the ``free`` weights (0 for pinned points). A
kernel returns at once when its rows are None; numba prunes that branch
when it compiles the substep for a scene without the kind, so a scene
compiles only the colliders it has.

The kinds that test a point's whole segment (boxes, meshes) also have a
settle kernel that the substep runs after the Provot pass, from the
positions the colliders left (Q) to where the pass put them: no constraint
pushes a point through a box or a mesh. Spheres have one too, which reads
the last positions L instead of Q: a point that the pass left deeper than
:data:`~.sphere.SPHERE_SETTLE` inside goes out to the surface.

Adding a kind: its module, its field in :class:`~clothsim.solver.groups.Control`
and in :data:`KINDS`, its line in :func:`collide` (and :func:`settle`) and in
:func:`pack_colliders`. The colliders are fields of the control group itself,
not a group of their own inside it: numba cannot hand a named tuple read
from another one into a ``prange`` body.
"""

from __future__ import annotations

from numba import njit

from . import box, plane, sphere
from .box import collide_boxes, settle_boxes
from .mesh import collide_meshes, settle_meshes
from .plane import PLANE_OFFSET, collide_planes
from .sphere import SPHERE_SETTLE, collide_spheres, settle_spheres

KINDS = ("spheres", "planes", "boxes", "meshes")
"""the collider fields of :class:`~clothsim.solver.groups.Control`, in the order
:func:`collide` walks them"""


def pack_colliders(world, t0: float = 0.0, dt: float = 0.0, substeps: int = 1) -> dict:
    """The sphere, plane and box fields of :class:`~clothsim.solver.groups.Control`
    for a frame from ``t0`` of ``substeps`` substeps of ``dt`` [s], from ``world``'s
    ``spheres``, ``planes`` and ``boxes`` (objects as the scene's specs)."""
    return dict(spheres=sphere.pack(world.spheres, t0, dt, substeps),
                planes=plane.pack(world.planes, t0, dt, substeps),
                boxes=box.pack(getattr(world, "boxes", ()), t0, dt, substeps))


@njit(cache=True)
def collide(P, L, free, control, lo, hi, s):
    """Points ``lo:hi`` out of every collider of ``control`` (a
    :class:`~clothsim.solver.groups.Control`) over substep ``s``, kind after
    kind, spheres and planes in the CS184 order."""
    collide_spheres(P, L, free, control.spheres, lo, hi, s)
    collide_planes(P, L, free, control.planes, lo, hi, s)
    collide_boxes(P, L, free, control.boxes, lo, hi, s)
    collide_meshes(P, L, free, control, lo, hi, s)


@njit(cache=True)
def settle(P, Q, L, free, control, lo, hi, s):
    """Points ``lo:hi`` that the Provot pass moved from Q into a box are put back
    at Q, those it moved across a mesh where they crossed, and those it left
    deep in a sphere go out to its surface (see the module); L: the last
    positions."""
    settle_spheres(P, L, free, control.spheres, lo, hi, s)
    settle_boxes(P, Q, free, control.boxes, lo, hi, s)
    settle_meshes(P, Q, free, control, lo, hi, s)


@njit(cache=True)
def has_settle(control):
    """Whether the scene has a collider kind that :func:`settle` acts for"""
    return control.spheres is not None or control.boxes is not None or control.meshes is not None


@njit(cache=True)
def settle_needs_q(control):
    """Whether :func:`settle` reads Q, the positions after the colliders: the
    sphere's settle does not, so a scene with spheres alone skips the copy"""
    return control.boxes is not None or control.meshes is not None


__all__ = ["KINDS", "PLANE_OFFSET", "SPHERE_SETTLE", "collide", "collide_boxes", "collide_planes", "collide_spheres",
           "has_settle", "pack_colliders", "settle", "settle_needs_q"]
