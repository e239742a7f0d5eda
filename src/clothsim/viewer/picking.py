"""Screen-space picking for the mouse grab; NumPy only, no GL."""

from __future__ import annotations

import numpy as np


def project(points: np.ndarray, view_projection: np.ndarray, size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Window pixel coordinates (x right, y down) of points, and whether each is in front."""
    homo = np.c_[points, np.ones(len(points))] @ view_projection.T
    w = homo[:, 3]
    front = w > 1e-9
    ndc = homo[:, :2] / np.where(front, w, 1.0)[:, None]
    px = np.empty((len(points), 2))
    px[:, 0] = (ndc[:, 0] + 1) * 0.5 * size[0]
    px[:, 1] = (1 - ndc[:, 1]) * 0.5 * size[1]
    return px, front


def nearest_point(points: np.ndarray, view_projection: np.ndarray, size: tuple[int, int],
                  cursor: tuple[float, float], radius_px: float = 25.0) -> int:
    """Index of the point drawn nearest to the cursor (within ``radius_px``), or -1.

    Among the points within a few pixels of the best match the one nearest the
    camera wins, so the visible layer is grabbed, not one behind it.
    """
    px, front = project(points, view_projection, size)
    d = np.linalg.norm(px - np.asarray(cursor), axis=1)
    d[~front] = np.inf
    if not np.isfinite(d).any() or d.min() > radius_px:
        return -1
    close = np.flatnonzero(d <= d.min() + 4.0)
    depth = (np.c_[points[close], np.ones(close.size)] @ view_projection.T)[:, 3]
    return int(close[np.argmin(depth)])


def cursor_ray(view_projection: np.ndarray, size: tuple[int, int], cursor: tuple[float, float]):
    """Origin and unit direction of the ray through a window pixel."""
    inv = np.linalg.inv(view_projection)
    x = 2.0 * cursor[0] / size[0] - 1.0
    y = 1.0 - 2.0 * cursor[1] / size[1]
    near = inv @ np.array([x, y, -1.0, 1.0])
    far = inv @ np.array([x, y, 1.0, 1.0])
    near, far = near[:3] / near[3], far[:3] / far[3]
    d = far - near
    return near, d / np.linalg.norm(d)


def drag_target(view_projection: np.ndarray, size: tuple[int, int], cursor: tuple[float, float],
                anchor: np.ndarray, facing: np.ndarray) -> np.ndarray:
    """Where the cursor ray meets the plane through ``anchor`` facing the camera (normal ``facing``)."""
    origin, direction = cursor_ray(view_projection, size, cursor)
    denom = float(direction @ facing)
    if abs(denom) < 1e-9:
        return np.asarray(anchor, float).copy()
    t = float((np.asarray(anchor) - origin) @ facing) / denom
    return origin + t * direction


def ray_hit(points: np.ndarray, triangles: np.ndarray, origin: np.ndarray, direction: np.ndarray):
    """The first triangle the ray ``origin + t * direction`` (t > 0) meets, both
    sides counted: (its index, barycentric weights of its corners (3,), t), or
    None when it meets none. ``points`` [m] (N, 3), ``triangles`` int (T, 3);
    every triangle tested at once (Moller-Trumbore), any mesh."""
    tri = np.asarray(triangles, dtype=np.int64)
    if not len(tri):
        return None
    p0, p1, p2 = points[tri[:, 0]], points[tri[:, 1]], points[tri[:, 2]]
    e1, e2 = p1 - p0, p2 - p0
    d = np.asarray(direction, dtype=float)
    h = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, h)
    ok = np.abs(det) > 1e-14 * np.maximum(np.einsum("ij,ij->i", e1, e1), 1e-300)
    inv = np.divide(1.0, det, out=np.zeros_like(det), where=ok)
    s = np.asarray(origin, dtype=float) - p0
    u = np.einsum("ij,ij->i", s, h) * inv
    q = np.cross(s, e1)
    v = (q @ d) * inv
    t = np.einsum("ij,ij->i", e2, q) * inv
    eps = 1e-9
    hit = ok & (u >= -eps) & (v >= -eps) & (u + v <= 1 + eps) & (t > 0)
    if not hit.any():
        return None
    k = int(np.flatnonzero(hit)[np.argmin(t[hit])])
    return k, np.array([1.0 - u[k] - v[k], u[k], v[k]]), float(t[k])


def pick_point(points: np.ndarray, triangles: np.ndarray, view_projection: np.ndarray, size: tuple[int, int],
               cursor: tuple[float, float], radius_px: float = 25.0) -> int:
    """The point to grab under the cursor: the corner nearest the hit of the
    first triangle the cursor's ray meets (so a big triangle of a coarse mesh is
    grabbed anywhere on it, and the visible layer wins), else the point drawn
    nearest the cursor within ``radius_px`` (:func:`nearest_point`), else -1."""
    origin, direction = cursor_ray(view_projection, size, cursor)
    hit = ray_hit(points, triangles, origin, direction)
    if hit is not None:
        k, weights, _ = hit
        return int(np.asarray(triangles)[k, int(np.argmax(weights))])
    return nearest_point(points, view_projection, size, cursor, radius_px)
