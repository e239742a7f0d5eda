"""A mesh file read as a collider: any triangle soup, welded and triangulated.

Unlike a cloth (:func:`clothsim.meshfile.load_mesh`) a collider need not be
manifold, and a face of zero area is dropped rather than refused: what the
solver needs is triangles and whether they close a solid. The steps:

- read the file's polygons (:func:`clothsim.meshfile.read_polygons`: OBJ by
  our reader, PLY, STL and glTF/GLB by trimesh);
- split quads into two triangles;
- weld vertices at the same position (as a cloth's are) and drop those in
  no triangle;
- apply the scene's transform, then drop triangles of zero area (a repeated
  corner, three corners on a line);
- ``closed``: every edge of the triangles is shared by exactly two of them.

Faults are :class:`~clothsim.meshfile.MeshFileError` with a one-line
message that does not name the file (the scene reader adds file and key).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .meshfile import AREA_TOLERANCE, MeshFileError, _weld, read_polygons, split_triangles, triangle_areas
from .scene_limits import FILE_COORD_MAX, LENGTH_MAX, TRIANGLES_MAX


def load_collider(path: str, transform: Callable[[np.ndarray], np.ndarray] | None = None
                  ) -> tuple[np.ndarray, np.ndarray, bool]:
    """(vertices [m] float64 (V, 3) after ``transform``, triangles int64 (F, 3), closed)
    of the mesh file ``path``; ``transform`` maps float64 (N, 3) file positions to metres."""
    v, faces, _ = read_polygons(path)
    if len(faces) == 0:
        raise MeshFileError("the file holds no faces")
    if len(faces) > TRIANGLES_MAX:  # before splitting allocates
        raise MeshFileError(f"expected at most {TRIANGLES_MAX:,} triangles, got {len(faces):,} faces")
    finite = np.isfinite(v).all(axis=1)
    if not finite.all():
        raise MeshFileError(f"vertex {int(np.argmin(finite))} is not at a finite position")
    far = np.abs(v).max(axis=1) > FILE_COORD_MAX
    if far.any():
        k = int(np.argmax(far))
        raise MeshFileError(f"vertex {k} has a coordinate beyond ±{FILE_COORD_MAX:g} ({np.abs(v[k]).max():g})")
    tris, _ = split_triangles(faces)
    if len(tris) > TRIANGLES_MAX:
        raise MeshFileError(f"expected at most {TRIANGLES_MAX:,} triangles, got {len(tris):,}")
    file_to_point, _ = _weld(v)
    # each welded point at its first file vertex
    first = np.empty(int(file_to_point.max()) + 1, dtype=np.int64)
    first[file_to_point[::-1]] = np.arange(len(v))[::-1]
    points = v[first]
    if transform is not None:
        points = np.asarray(transform(points), dtype=np.float64)
    extent = float(np.abs(points).max())
    if not extent <= LENGTH_MAX:  # inf and nan too
        raise MeshFileError(f"expected every vertex within ±{LENGTH_MAX:g} m after the transform, "
                            f"got one at {extent:g}")
    tris = file_to_point[tris]
    tris = tris[_has_area(points, tris)]
    if len(tris) == 0:
        raise MeshFileError("every face has zero area")
    points, tris = _compact(points, tris)
    return np.ascontiguousarray(points), np.ascontiguousarray(tris, dtype=np.int64), is_closed(tris)


def _has_area(points: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """True for a triangle of non-zero area, bool (F,) (as a cloth's faces are judged)."""
    p = points[tris]
    longest = np.max([np.sum((p[:, a] - p[:, b]) ** 2, axis=1) for a, b in ((0, 1), (1, 2), (2, 0))], axis=0)
    return triangle_areas(points, tris) > AREA_TOLERANCE * longest


def _compact(points: np.ndarray, tris: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Drop the points in no triangle, the others keeping their order."""
    used = np.zeros(len(points), dtype=bool)
    used[tris] = True
    index = np.cumsum(used) - 1
    return points[used], index[tris]


def is_closed(tris: np.ndarray) -> bool:
    """Whether every edge of ``tris`` (int64 (F, 3)) is shared by exactly two triangles."""
    edges = np.sort(tris[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    return bool((counts == 2).all())
