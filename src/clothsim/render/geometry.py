"""Meshes for drawing: vertex attributes of the cloth and of the colliders.

Vertex layout shared by every mesh, float32, 14 per vertex:
position (x, y, z, 1), normal (x, y, z, 0), tangent (x, y, z, 1), uv (u, v).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

FLOATS_PER_VERTEX = 14


@dataclass
class Mesh:
    vertices: np.ndarray
    """interleaved attributes, float32 (V, 14)"""
    triangles: np.ndarray
    """int32 (T, 3)"""
    lines: np.ndarray | None = None
    """int32 (L, 2) segments for the wireframe; None draws the triangles' edges"""
    parts: tuple[tuple[int, int], ...] = ()
    """(first triangle, count) of each cloth, drawn each in its own colour
    (:func:`cloth_colors`); empty: one part, every triangle"""


def cloth_colors(first: tuple[float, float, float], count: int) -> list[tuple[float, float, float]]:
    """A colour per cloth: ``first`` (the user's colour) for the first, then hues
    turned from it by the golden angle, so that cloths side by side never share
    one, at its lightness and saturation."""
    import colorsys

    h, lum, sat = colorsys.rgb_to_hls(*first)
    return [first] + [colorsys.hls_to_rgb((h + 0.381966 * k) % 1.0, lum, sat) for k in range(1, count)]


def pack_vertices(pos: np.ndarray, normals: np.ndarray, tangents: np.ndarray, uvs: np.ndarray,
                  out: np.ndarray | None = None) -> np.ndarray:
    n = pos.shape[0]
    if out is None:
        out = np.empty((n, FLOATS_PER_VERTEX), dtype=np.float32)
    out[:, 0:3] = pos
    out[:, 3] = 1.0
    out[:, 4:7] = normals
    out[:, 7] = 0.0
    out[:, 8:11] = tangents
    out[:, 11] = 1.0
    out[:, 12:14] = uvs
    return out


def sphere_mesh(center, radius: float, lat: int, lon: int) -> Mesh:
    """UV sphere with ``lat`` bands and ``lon`` segments; seams duplicated for the uvs."""
    lat, lon = max(2, int(lat)), max(3, int(lon))
    theta = np.linspace(0.0, math.pi, lat + 1)        # from +y down
    phi = np.linspace(0.0, 2.0 * math.pi, lon + 1)
    th, ph = np.meshgrid(theta, phi, indexing="ij")
    normal = np.stack([np.sin(th) * np.cos(ph), np.cos(th), -np.sin(th) * np.sin(ph)], axis=-1).reshape(-1, 3)
    tangent = np.stack([-np.sin(ph), np.zeros_like(ph), -np.cos(ph)], axis=-1).reshape(-1, 3)
    uv = np.stack([ph / (2.0 * math.pi), 1.0 - th / math.pi], axis=-1).reshape(-1, 2)
    pos = np.asarray(center, float) + radius * normal
    idx = np.arange((lat + 1) * (lon + 1)).reshape(lat + 1, lon + 1)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    tris = np.concatenate([np.stack([a, c, b], 1), np.stack([b, c, d], 1)]).astype(np.int32)
    return Mesh(pack_vertices(pos, normal, tangent, uv), tris)


def plane_mesh(point, normal, center, size: float, divisions: int = 32) -> Mesh:
    """Square patch of an infinite plane, ``size`` wide around the projection of ``center``."""
    n = np.asarray(normal, float)
    n = n / np.linalg.norm(n)
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    t = np.cross(helper, n)
    t /= np.linalg.norm(t)
    b = np.cross(n, t)
    c = np.asarray(center, float)
    c = c - np.dot(c - np.asarray(point, float), n) * n
    s = np.linspace(-0.5, 0.5, divisions + 1)
    uu, vv = np.meshgrid(s, s, indexing="xy")
    pos = c + size * (uu.reshape(-1, 1) * t + vv.reshape(-1, 1) * b)
    count = pos.shape[0]
    uv = np.stack([uu.ravel() + 0.5, vv.ravel() + 0.5], axis=1) * 2.0  # texture tiles twice
    idx = np.arange(count).reshape(divisions + 1, divisions + 1)
    a, bb = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    cc, d = idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    # wound so the face looks along +normal: (t, b) then n = t x b
    tris = np.concatenate([np.stack([a, bb, cc], 1), np.stack([bb, d, cc], 1)]).astype(np.int32)
    return Mesh(pack_vertices(pos, np.tile(n, (count, 1)), np.tile(t, (count, 1)), uv), tris)


# a box's faces: the axis of the outward normal, its sign, and two in-face axes
# (a, b) with a x b along the normal, so each face winds counter-clockwise seen
# from outside
_BOX_FACES = ((0, 1, 1, 2), (0, -1, 2, 1), (1, 1, 2, 0), (1, -1, 0, 2), (2, 1, 0, 1), (2, -1, 1, 0))


def box_mesh(center, size, rotation=None) -> Mesh:
    """An oriented box: 6 faces of 4 vertices each (24, flat normals, uvs 0..1 per
    face) and 12 triangles; ``size``: full lengths along its own axes [m];
    ``rotation``: (3, 3) turning its axes (None: axis-aligned). Its lines are
    the 12 edges (each face's outline), not the faces' diagonals."""
    R = np.eye(3) if rotation is None else np.asarray(rotation, float)
    half = 0.5 * np.asarray(size, float)
    corners = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    pos, normals, tangents, uvs = [], [], [], []
    for axis, sign, a, b in _BOX_FACES:
        local = np.zeros((4, 3))
        local[:, axis] = sign * half[axis]
        local[:, a] = (2.0 * corners[:, 0] - 1.0) * half[a]
        local[:, b] = (2.0 * corners[:, 1] - 1.0) * half[b]
        n, t = np.zeros(3), np.zeros(3)
        n[axis], t[a] = sign, 1.0
        pos.append(local)
        normals.append(np.tile(n, (4, 1)))
        tangents.append(np.tile(t, (4, 1)))
        uvs.append(corners)
    pos = np.concatenate(pos) @ R.T + np.asarray(center, float)
    normals, tangents = np.concatenate(normals) @ R.T, np.concatenate(tangents) @ R.T
    quad = np.arange(0, 24, 4)[:, None]
    tris = np.concatenate([quad + [0, 1, 2], quad + [0, 2, 3]]).astype(np.int32)
    lines = np.concatenate([quad + [0, 1], quad + [1, 2], quad + [2, 3], quad + [3, 0]]).astype(np.int32)
    return Mesh(pack_vertices(pos, normals, tangents, np.concatenate(uvs)), tris, lines)


SMOOTH_ANGLE = 40.0
"""[degrees] a mesh collider's corner takes the smooth (vertex) normal where it is
within this of its face's normal, else the face's own (a crease)"""


def triangle_mesh(vertices, triangles, smooth_angle: float = SMOOTH_ANGLE) -> Mesh:
    """A triangle mesh to draw (a mesh collider): ``vertices`` [m] (V, 3),
    ``triangles`` (F, 3) indices. Every triangle gets its own three vertices
    (3F), normal and tangent: smooth where the surface bends less than
    ``smooth_angle`` (the area-weighted vertex normal), flat at creases, so a
    torus looks round and a cube keeps its edges. Uvs are the positions on the
    two widest sides of the bounding box, 0..1 across it; the tangent is u's
    direction made normal to the normal (any normal direction where u is along it)."""
    from ..mesh import compute_normals

    v = np.ascontiguousarray(vertices, dtype=np.float64)
    tri = np.ascontiguousarray(triangles, dtype=np.int64).reshape(-1, 3)
    corners = v[tri]                                              # (F, 3, 3)
    face = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    face /= np.maximum(np.linalg.norm(face, axis=1, keepdims=True), 1e-300)
    smooth = compute_normals(v, tri)[tri]                         # (F, 3, 3)
    keep = np.einsum("fk,fck->fc", face, smooth) >= math.cos(math.radians(smooth_angle))
    normals = np.where(keep[..., None], smooth, face[:, None, :]).reshape(-1, 3)
    pos = corners.reshape(-1, 3)
    lo, span = v.min(axis=0), np.ptp(v, axis=0)
    wide = np.argsort(-span)[:2]
    uv = (pos[:, wide] - lo[wide]) / np.maximum(span[wide], 1e-12)
    u_dir = np.zeros(3)
    u_dir[wide[0]] = 1.0
    tangent = u_dir - (normals @ u_dir)[:, None] * normals
    length = np.linalg.norm(tangent, axis=1, keepdims=True)
    fallback = np.zeros(3)
    fallback[wide[1]] = 1.0
    tangent = np.where(length > 1e-6, tangent / np.maximum(length, 1e-12), fallback)
    count = len(tri)
    return Mesh(pack_vertices(pos, normals, tangent, uv), np.arange(3 * count, dtype=np.int32).reshape(count, 3))


def parse_resolution(text: str) -> tuple[int, int]:
    """'16' -> (16, 16); '40,60' -> (40, 60): latitude bands, longitude segments."""
    parts = [p for p in text.replace("x", ",").split(",") if p.strip()]
    if not 1 <= len(parts) <= 2 or not all(p.strip().isdigit() for p in parts):
        raise ValueError(f"expected N or LAT,LON (positive integers), got {text!r}")
    lat = int(parts[0])
    lon = int(parts[-1]) if len(parts) == 2 else lat
    if lat < 2 or lon < 3:
        raise ValueError(f"expected at least 2 latitude bands and 3 longitude segments, got {text!r}")
    return lat, lon
