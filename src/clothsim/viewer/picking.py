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
