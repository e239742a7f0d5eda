"""The control of one frame: what the world imposes on the cloth, made anew each frame."""

from __future__ import annotations

import numpy as np

from .colliders import pack_colliders
from .groups import Control
from .handles import pack_handles
from .wind import pack_wind

MESH_FIELDS = ("mesh_tris", "mesh_grid", "mesh_cells", "mesh_items", "mesh_slabs", "mesh_prisms", "mesh_hints")
"""the fields of a mesh collider's shape: built once per scene, not per frame (the
hints are the points' last crossed triangles, which the kernels keep)"""


def make_control(handle: int, handle_pos, world, t0: float = 0.0, dt: float = 0.0, substeps: int = 1,
                 mesh_shapes: dict | None = None) -> Control:
    """The :class:`~.groups.Control` of a frame from time ``t0`` [s] of ``substeps``
    substeps of ``dt`` [s]: the user's held point, and ``world``'s colliders
    (``spheres``, ``planes``, ``boxes``, ``mesh_colliders``), ``handles`` and
    ``wind`` where they stand and move over the frame. ``mesh_shapes``: the
    mesh colliders' shapes as :func:`.colliders.mesh.pack_meshes` made them, once."""
    moved_points, moved_to = pack_handles(getattr(world, "handles", ()), t0, dt, substeps)
    meshes = None
    shapes = dict.fromkeys(MESH_FIELDS)
    colliders = getattr(world, "mesh_colliders", ())
    if colliders:
        from .colliders.mesh import pack_poses

        meshes = pack_poses(colliders, t0, dt, substeps)
        shapes.update(mesh_shapes)
    return Control(handle=int(handle), handle_pos=np.asarray(handle_pos, dtype=np.float64),
                   **pack_colliders(world, t0, dt, substeps), meshes=meshes, **shapes,
                   moved_points=moved_points, moved_to=moved_to,
                   wind=_frame_rows(pack_wind(getattr(world, "wind", None), t0, dt)))


def _frame_rows(row):
    """a frame's row as rows (1, R), one a frame (see :func:`stack_frames`), or None"""
    return None if row is None else row[None]


SLOTTED = ("spheres", "planes", "boxes", "meshes", "moved_to")
"""the fields with a slot per substep (T rows; T = 1 where nothing of the kind moves)"""

FRAMED = ("wind",)
"""the fields with a row per frame: the wind's holds the time its frame starts at"""


def stack_frames(controls: list[Control]) -> Control:
    """One control for consecutive frames of the same substeps, from each frame's
    own: every moving kind's slots frame after frame (the kernels read slot
    ``f * substeps + s`` in substep s of the call's frame f), a still kind's one
    slot as it is, the wind's rows frame after frame (row f in frame f), the
    rest (the held point, the mesh shapes, the hints) the first frame's. The
    frames must have more than one substep each: a moving collider's frame of
    one substep has two slots (see :func:`.colliders.motion_rows.frame_poses`),
    and frames of those do not stack."""
    first = controls[0]
    fields = {}
    for name in SLOTTED + FRAMED:
        rows = [getattr(c, name) for c in controls]
        if rows[0] is not None and (rows[0].shape[0] > 1 or name in FRAMED):
            fields[name] = np.ascontiguousarray(np.concatenate(rows, axis=0))
    return first._replace(**fields)
