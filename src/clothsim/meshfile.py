"""Mesh files for cloth: read the file's polygons, weld, check.

OBJ is read here, line by line, and not through trimesh: trimesh splits
every quad into two triangles on load (a cloth keeps its quads: four
structural edges and two shearing diagonals, which a triangle pair cannot
tell apart from a quad), and to keep the file's vertex order
(``maintain_order``) it reorders the faces and drops the texture
coordinates, while without it it splits vertices at uv seams. The OBJ
subset a cloth needs is small: ``v`` (the first three numbers), ``vt`` and
``f`` (``a``, ``a/b``, ``a//c``, ``a/b/c``, negative indices counting back);
every other statement is ignored. PLY, STL and glTF/GLB are read by trimesh
(``process=False`` keeps their vertex order) and give triangles.

What the cloth gets (:class:`MeshData`) is the file after three steps:

- **weld**: vertices at the same position (to 1e-9 of the mesh's size: the
  duplicates a file has along its uv seams, or every vertex of an STL) become
  one point, the first of them in file order; faces keep their corners
  through the weld and the caller is told how many were welded;
- **unused vertices** (in no face) are dropped;
- **checks**: a face with a repeated vertex or zero area and an edge shared
  by more than two faces are a :class:`MeshFileError`.

The points keep the file's order otherwise, so a file with neither welded nor
unused vertices has its points exactly in file order.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .scene_limits import FILE_COORD_MAX

SUFFIXES = (".obj", ".ply", ".stl", ".glb", ".gltf")
WELD_TOLERANCE = 1e-9
"""vertices closer than this times the mesh's bounding-box diagonal are welded"""
AREA_TOLERANCE = 1e-12
"""a triangle of area below this times its longest edge squared has zero area"""


class MeshFileError(Exception):
    """A mesh file that cannot be a cloth; the message is one line that does not
    name the file (the caller adds the file and the scene key)."""


@dataclass(frozen=True, eq=False)
class MeshData:
    """A mesh file read for a cloth, welded and checked (see the module)."""

    vertices: np.ndarray
    """point positions [m], float64 (V, 3), after the scene's transform"""
    faces: np.ndarray
    """point indices of each face, int64 (F, 4), in file order and winding; a
    triangle has -1 in its fourth column"""
    uvs: np.ndarray | None
    """texture coordinates from the file, float32 (V, 2), or None"""
    file_to_point: np.ndarray
    """the point of each vertex of the file, int64 (file vertices,); -1 for a
    vertex in no face"""
    num_welded: int
    """file vertices that were welded onto an earlier one"""
    num_unused: int
    """file vertices in no face (dropped)"""

    @property
    def num_file_vertices(self) -> int:
        return len(self.file_to_point)

    @property
    def is_quad(self) -> np.ndarray:
        """True for a quad face, bool (F,)"""
        return self.faces[:, 3] >= 0


# --------------------------------------------------------------------------
# reading


def read_polygons(path: str | Path) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """The file's vertices float64 (V, 3), faces int64 (F, 4) (-1 in the fourth
    column of a triangle) in file order, and per-vertex uvs float64 (V, 2) or None."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise MeshFileError(f"expected an OBJ, PLY, STL or glTF/GLB file (by its suffix), got {suffix or 'none'!r}")
    if not path.exists():
        raise MeshFileError("no such file")
    if path.is_dir():
        raise MeshFileError("expected a mesh file, got a directory")
    if suffix == ".obj":
        return _read_obj(path)
    return _read_with_trimesh(path)


def _read_obj(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise MeshFileError("cannot read: not a text OBJ file") from None
    except OSError as exc:
        raise MeshFileError(f"cannot read: {exc.strerror or exc}") from None
    verts: list[list[float]] = []
    tex: list[list[float]] = []
    faces: list[list[int]] = []
    corner_uv: list[list[int]] = []
    for lineno, line in enumerate(text.replace("\\\n", " ").splitlines(), 1):
        parts = line.split("#", 1)[0].split()
        if not parts:
            continue
        head, args = parts[0], parts[1:]
        try:
            if head == "v":
                if len(args) < 3:
                    raise ValueError("a vertex needs x, y and z")
                verts.append([float(a) for a in args[:3]])
            elif head == "vt":
                if not args:
                    raise ValueError("a texture coordinate needs u")
                tex.append([float(args[0]), float(args[1]) if len(args) > 1 else 0.0])
            elif head == "f":
                if not 3 <= len(args) <= 4:
                    raise MeshFileError(f"line {lineno}: a face of {len(args)} vertices; "
                                        "expected triangles or quads")
                vs, ts = [], []
                for token in args:
                    fields = token.split("/")
                    vs.append(_obj_index(fields[0], len(verts), "vertex"))
                    has_t = len(fields) > 1 and fields[1] != ""
                    ts.append(_obj_index(fields[1], len(tex), "texture coordinate") if has_t else -1)
                faces.append(vs + [-1] * (4 - len(vs)))
                corner_uv.append(ts + [-1] * (4 - len(ts)))
        except ValueError as exc:
            raise MeshFileError(f"line {lineno}: cannot read {head!r}: {exc}") from None
    v = np.array(verts, dtype=np.float64).reshape(-1, 3)
    f = np.array(faces, dtype=np.int64).reshape(-1, 4)
    t = np.array(corner_uv, dtype=np.int64).reshape(-1, 4)
    uvs = None
    corners = f >= 0
    if len(f) and (t[corners] >= 0).all():
        # one uv per vertex: the first corner (in file order) that names it
        vert, uv_index = f[corners], t[corners]
        first = np.full(len(v), -1, dtype=np.int64)
        order = np.arange(len(vert))[::-1]
        first[vert[order]] = uv_index[order]
        tex_arr = np.array(tex, dtype=np.float64).reshape(-1, 2)
        uvs = np.zeros((len(v), 2))
        uvs[first >= 0] = tex_arr[first[first >= 0]]
    return v, f, uvs


def _obj_index(text: str, count: int, what: str) -> int:
    k = int(text)
    index = k - 1 if k > 0 else count + k
    if k == 0 or not 0 <= index < count:
        raise MeshFileError(f"a face names {what} {k}, but only {count} are defined before it")
    return index


def _read_with_trimesh(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    import warnings

    import trimesh

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            mesh = trimesh.load(str(path), force="mesh", process=False, maintain_order=True)
    except Exception as exc:  # noqa: BLE001 -- trimesh raises many kinds for a file it cannot parse
        raise MeshFileError(f"cannot read: {str(exc).splitlines()[0] if str(exc) else type(exc).__name__}") from None
    faces = getattr(mesh, "faces", None)
    if faces is None or len(faces) == 0:
        return np.zeros((0, 3)), np.zeros((0, 4), dtype=np.int64), None
    v = np.asarray(mesh.vertices, dtype=np.float64).reshape(-1, 3)
    f = np.full((len(faces), 4), -1, dtype=np.int64)
    f[:, :3] = np.asarray(faces, dtype=np.int64)
    uv = getattr(mesh.visual, "uv", None) if getattr(mesh.visual, "kind", None) == "texture" else None
    uvs = None if uv is None or len(uv) != len(v) else np.asarray(uv, dtype=np.float64)[:, :2]
    return v, f, uvs


# --------------------------------------------------------------------------
# weld and check


def load_mesh(path: str | Path, transform=None) -> MeshData:
    """Read ``path``, weld it, drop unused vertices, apply ``transform`` (a
    function of float64 (V, 3) positions) and check the faces; a
    :class:`MeshFileError` for a mesh that cannot be a cloth."""
    v, f, uvs = read_polygons(path)
    if len(f) == 0:
        raise MeshFileError("the file holds no faces")
    if not np.isfinite(v).all():
        raise MeshFileError(f"vertex {int(np.argmax(~np.isfinite(v).all(axis=1)))} is not at a finite position")
    far = np.abs(v).max(axis=1) > FILE_COORD_MAX
    if far.any():
        k = int(np.argmax(far))
        raise MeshFileError(f"vertex {k} has a coordinate beyond ±{FILE_COORD_MAX:g} ({np.abs(v[k]).max():g})")
    corners = f >= 0
    fs = np.sort(np.where(corners, f, -1 - np.arange(4)), axis=1)
    repeated = (fs[:, 1:] == fs[:, :-1]).any(axis=1)
    if repeated.any():
        k = int(np.argmax(repeated))
        raise MeshFileError(f"face {k} is degenerate: it names a vertex twice ({_face_text(f[k])})")
    file_to_point, num_welded = _weld(v)
    faces = np.where(corners, file_to_point[np.where(corners, f, 0)], -1)
    # unused points dropped, the rest keep their order
    used = np.zeros(file_to_point.max() + 1, dtype=bool)
    used[faces[corners]] = True
    compact = np.cumsum(used) - 1
    compact[~used] = -1
    num_unused = int(np.count_nonzero(compact[file_to_point] < 0))
    file_to_point = compact[file_to_point]
    faces = np.where(corners, compact[np.where(corners, faces, 0)], -1)
    # each point's first file vertex that a face names (its position and uv)
    named = np.zeros(len(v), dtype=bool)
    named[f[corners]] = True
    first = np.full(used.sum(), -1, dtype=np.int64)
    order = np.flatnonzero(named)[::-1]
    first[file_to_point[order]] = order
    points = v[first]
    point_uvs = None if uvs is None else uvs[first].astype(np.float32)
    if transform is not None:
        points = np.ascontiguousarray(transform(points), dtype=np.float64)
    fs = np.sort(np.where(corners, faces, -1 - np.arange(4)), axis=1)
    welded_twice = (fs[:, 1:] == fs[:, :-1]).any(axis=1)
    if welded_twice.any():
        k = int(np.argmax(welded_twice))
        raise MeshFileError(f"face {k} is degenerate: two of its vertices are at the same position "
                            f"({_face_text(f[k])})")
    _check_areas(points, faces, f)
    _check_manifold(faces, first)
    for arr in (points, faces, file_to_point) + (() if point_uvs is None else (point_uvs,)):
        arr.setflags(write=False)
    return MeshData(points, faces, point_uvs, file_to_point, num_welded, num_unused)


def _weld(v: np.ndarray) -> tuple[np.ndarray, int]:
    """The welded index of each vertex (first occurrence first) and how many were welded."""
    size = float(np.linalg.norm(np.ptp(v, axis=0))) if len(v) else 0.0
    tol = WELD_TOLERANCE * size if size > 0 else 1.0
    keys = np.round((v - v.min(axis=0)) / tol).astype(np.int64)
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    rank = np.empty(len(first), dtype=np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(len(first))
    return rank[inverse], len(v) - len(first)


def split_triangles(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Triangles of (F, 4) faces in face order, a quad (a, b, c, d) as (a, b, c)
    and (a, c, d): int64 (T, 3), and the face of each triangle int64 (T,)."""
    quad = faces[:, 3] >= 0
    per_face = np.where(quad, 2, 1)
    face_of = np.repeat(np.arange(len(faces)), per_face)
    second = np.zeros(len(face_of), dtype=bool)
    second[np.cumsum(per_face)[quad] - 1] = True
    fo = faces[face_of]
    tris = np.where(second[:, None], fo[:, [0, 2, 3]], fo[:, [0, 1, 2]])
    return tris, face_of


def triangle_areas(points: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Area [m²] of each triangle, float64 (T,)."""
    p0, p1, p2 = points[tris[:, 0]], points[tris[:, 1]], points[tris[:, 2]]
    return 0.5 * np.linalg.norm(np.cross(p1 - p0, p2 - p0), axis=1)


def _check_areas(points: np.ndarray, faces: np.ndarray, file_faces: np.ndarray) -> None:
    tris, face_of = split_triangles(faces)
    p = points[tris]
    longest = np.max([np.sum((p[:, a] - p[:, b]) ** 2, axis=1) for a, b in ((0, 1), (1, 2), (2, 0))], axis=0)
    bad = triangle_areas(points, tris) <= AREA_TOLERANCE * longest
    if bad.any():
        k = int(face_of[np.argmax(bad)])
        raise MeshFileError(f"face {k} is degenerate: it has zero area ({_face_text(file_faces[k])})")


def face_edges(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every edge of every face, int64 (E, 2) with the smaller index first (an edge
    shared by two faces appears twice), and the face of each, int64 (E,)."""
    tri = faces[:, 3] < 0
    nxt = faces[:, [1, 2, 3, 0]]
    nxt[tri, 2] = faces[tri, 0]
    valid = np.ones(faces.shape, dtype=bool)
    valid[:, 3] = ~tri
    a, b = faces[valid], nxt[valid]
    face_of = np.broadcast_to(np.arange(len(faces))[:, None], faces.shape)[valid]
    return np.stack([np.minimum(a, b), np.maximum(a, b)], axis=1), face_of


def _check_manifold(faces: np.ndarray, point_to_file: np.ndarray) -> None:
    edges, _ = face_edges(faces)
    n = int(faces.max()) + 1
    keys, counts = np.unique(edges[:, 0] * n + edges[:, 1], return_counts=True)
    if (counts > 2).any():
        k = int(np.argmax(counts > 2))
        a, b = point_to_file[[keys[k] // n, keys[k] % n]]
        raise MeshFileError(f"non-manifold: the edge between vertices {a} and {b} is shared by "
                            f"{counts[k]} faces (at most 2)")


def _face_text(face: np.ndarray) -> str:
    return "vertices " + ", ".join(str(int(x)) for x in face if x >= 0)
