"""The parts of a cloth made from a mesh: springs, pins, uvs, triangles, area.

:func:`mesh_cloth_parts` turns a mesh cloth of the scene (its welded, checked
:class:`~clothsim.meshfile.MeshData`) into plain arrays;
:func:`clothsim.model.build_mesh_model` makes the :class:`~clothsim.model.Model`
of them (this module imports nothing of the model, which dispatches to it).

The springs, as ``shared/scene-format.md`` defines them (physics.md tells
why):

- **structural** along every edge of every face, once (a quad has four edges,
  no diagonal);
- **shearing** along both diagonals of every quad;
- **bending** (a) along rows of quad edges: at a vertex, two quad edges that
  share no face are a row through it, and a spring joins their far ends
  (the opposite edge at an interior vertex of valence 4, the two boundary
  edges at a boundary vertex of valence 3, none at a corner); where an edge
  has several such partners the straightest is taken; and (b) across each
  edge shared by two triangles, between the two vertices opposite it. Each
  pair of points is one spring.

On a quad grid these are exactly the grid's springs (``grid_springs``).
Everything is vectorised: a 10,000-vertex mesh takes a few tens of ms.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from .meshfile import face_edges, split_triangles, triangle_areas

if TYPE_CHECKING:
    from .scene import MeshClothSpec


class MeshClothParts(NamedTuple):
    positions: np.ndarray
    """rest positions [m], float64 (N, 3)"""
    pinned: np.ndarray
    """bool (N,)"""
    springs: tuple[np.ndarray, np.ndarray, np.ndarray]
    """the point pairs of each kind, int64 (S_k, 2) with the smaller index first,
    sorted, in the order of ``model.SPRING_KINDS`` (structural, shearing, bending)"""
    triangles: np.ndarray
    """int64 (T, 3), in face order and the file's winding (a quad as two)"""
    uvs: np.ndarray
    """float32 (N, 2): the file's, else a planar projection in [0, 1]²"""
    area: float
    """sum of the faces' rest areas [m²]"""
    width: float
    """the largest extent of the rest bounding box [m] (of the two largest, the
    one on the lower axis x < y < z)"""
    height: float
    """the other of the two largest extents [m]"""


def mesh_cloth_parts(spec: MeshClothSpec) -> MeshClothParts:
    """Everything the model of the mesh cloth ``spec`` holds, as plain arrays."""
    data = spec.data
    pos = np.asarray(data.vertices, dtype=np.float64)
    faces = np.asarray(data.faces, dtype=np.int64)
    tris, _ = split_triangles(faces)
    axes, _, extent = _plane_axes(pos)
    return MeshClothParts(
        positions=pos,
        pinned=pinned_points(spec),
        springs=mesh_springs(pos, faces),
        triangles=tris,
        uvs=data.uvs if data.uvs is not None else planar_uvs(pos),
        area=float(triangle_areas(pos, tris).sum()),
        width=float(extent[axes[0]]),
        height=float(extent[axes[1]]),
    )


def pinned_points(spec: MeshClothSpec) -> np.ndarray:
    """bool (N,): the points of ``pinned_vertices`` (file indices, through the
    weld) and every point inside ``pinned_region`` (bounds included)."""
    data = spec.data
    pinned = np.zeros(len(data.vertices), dtype=bool)
    if spec.pinned_vertices:
        pinned[data.file_to_point[np.asarray(spec.pinned_vertices, dtype=np.int64)]] = True
    if spec.pinned_region is not None:
        lo, hi = (np.asarray(v, dtype=np.float64) for v in spec.pinned_region)
        pinned |= np.all((data.vertices >= lo) & (data.vertices <= hi), axis=1)
    return pinned


def _plane_axes(pos: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The two axes of largest rest extent (in axis order), the box's low corner
    and its extents [m]."""
    lo = pos.min(axis=0)
    extent = pos.max(axis=0) - lo
    axes = np.sort(np.argsort(-extent, kind="stable")[:2])
    return axes, lo, extent


def planar_uvs(pos: np.ndarray) -> np.ndarray:
    """float32 (N, 2): the positions projected onto the two axes of largest rest
    extent (u on the lower axis), each scaled to [0, 1]."""
    axes, lo, extent = _plane_axes(pos)
    span = np.where(extent[axes] > 0, extent[axes], 1.0)
    return ((pos[:, axes] - lo[axes]) / span).astype(np.float32)


def mesh_springs(pos: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(structural, shearing, bending) point pairs of a mesh: each int64 (S, 2),
    smaller index first, sorted and unique (see the module docstring).

    ``pos``: float64 (N, 3) rest positions [m]; ``faces``: int64 (F, 4), -1 in
    the fourth column of a triangle.
    """
    quad = faces[:, 3] >= 0
    edges, edge_face = face_edges(faces)
    structural = _unique_pairs(edges)
    q = faces[quad]
    shearing = _unique_pairs(np.concatenate([q[:, [0, 2]], q[:, [1, 3]]]))
    rows = _row_bending(pos, faces, _unique_pairs(edges[quad[edge_face]]))
    across = _across_triangles(faces[~quad])
    return structural, shearing, _unique_pairs(np.concatenate([rows, across]))


def _unique_pairs(pairs: np.ndarray) -> np.ndarray:
    """int64 (S, 2): each unordered pair once, smaller index first, sorted; no (a, a)."""
    pairs = np.sort(pairs.reshape(-1, 2).astype(np.int64), axis=1)
    pairs = pairs[pairs[:, 0] != pairs[:, 1]]
    n = int(pairs.max()) + 1 if len(pairs) else 1
    keys = np.unique(pairs[:, 0] * n + pairs[:, 1])
    return np.stack([keys // n, keys % n], axis=1)


def _corners(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each face corner's vertex and its two neighbours along the face, int64 (C,) each."""
    tri = faces[:, 3] < 0
    nxt = faces[:, [1, 2, 3, 0]]
    nxt[tri, 2] = faces[tri, 0]
    prv = faces[:, [3, 0, 1, 2]]
    prv[tri, 0] = faces[tri, 2]
    valid = faces >= 0
    return faces[valid], prv[valid], nxt[valid]


def _row_bending(pos: np.ndarray, faces: np.ndarray, quad_edges: np.ndarray) -> np.ndarray:
    """Bending pairs (a): far ends of two quad edges at a vertex that share no
    face, the straightest partner of each edge; int64 (S, 2)."""
    if len(quad_edges) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    n = len(pos)
    # every quad edge from both ends, sorted by (vertex, far end)
    d = np.concatenate([quad_edges, quad_edges[:, ::-1]])
    d = d[np.lexsort((d[:, 1], d[:, 0]))]
    v, far = d[:, 0], d[:, 1]
    keys = v * n + far
    m = len(d)
    start = np.searchsorted(v, v, side="left")
    size = np.searchsorted(v, v, side="right") - start
    # every ordered pair (i, j) of edges at the same vertex
    i = np.repeat(np.arange(m), size)
    offset = np.arange(len(i)) - np.repeat(np.cumsum(size) - size, size)
    j = start[i] + offset
    keep = i != j
    i, j = i[keep], j[keep]
    # pairs of edges that share a face: the two edges at each face corner
    cv, cp, cn = _corners(faces)
    kp, kn = cv * n + cp, cv * n + cn
    ip, jn = np.searchsorted(keys, kp), np.searchsorted(keys, kn)
    ip, jn = np.minimum(ip, m - 1), np.minimum(jn, m - 1)
    both = (keys[ip] == kp) & (keys[jn] == kn)
    shared = np.concatenate([ip[both] * m + jn[both], jn[both] * m + ip[both]])
    free = ~np.isin(i * m + j, shared)
    i, j = i[free], j[free]
    if len(i) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    unit = pos[far] - pos[v]
    unit /= np.linalg.norm(unit, axis=1)[:, None]
    cos = np.einsum("ij,ij->i", unit[i], unit[j])
    order = np.lexsort((j, cos, i))
    i, j = i[order], j[order]
    first = np.ones(len(i), dtype=bool)
    first[1:] = i[1:] != i[:-1]
    return np.stack([far[i[first]], far[j[first]]], axis=1)


def _across_triangles(tri_faces: np.ndarray) -> np.ndarray:
    """Bending pairs (b): across each edge shared by two triangles, the two
    vertices opposite it; int64 (S, 2)."""
    t = tri_faces[:, :3]
    edges = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    opposite = np.concatenate([t[:, 2], t[:, 0], t[:, 1]])
    edges = np.sort(edges, axis=1)
    order = np.lexsort((edges[:, 1], edges[:, 0]))
    edges, opposite = edges[order], opposite[order]
    twin = np.all(edges[1:] == edges[:-1], axis=1)
    return np.stack([opposite[:-1][twin], opposite[1:][twin]], axis=1).reshape(-1, 2)
