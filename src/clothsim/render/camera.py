"""Orbit camera and light: matrices as NumPy arrays, no GL here."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

FOV_Y_DEG = 35.0
NEAR = 0.01


def perspective(fov_y_deg: float, aspect: float, near: float, far: float) -> np.ndarray:
    f = 1.0 / math.tan(math.radians(fov_y_deg) / 2.0)
    m = np.zeros((4, 4))
    m[0, 0] = f / aspect
    m[1, 1] = f
    m[2, 2] = (far + near) / (near - far)
    m[2, 3] = 2.0 * far * near / (near - far)
    m[3, 2] = -1.0
    return m


def look_at(eye: np.ndarray, target: np.ndarray, up: np.ndarray) -> np.ndarray:
    fwd = target - eye
    fwd = fwd / np.linalg.norm(fwd)
    side = np.cross(fwd, up)
    if np.linalg.norm(side) < 1e-9:  # looking straight up or down
        side = np.cross(fwd, np.array([0.0, 0.0, -1.0]))
    side = side / np.linalg.norm(side)
    true_up = np.cross(side, fwd)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = side, true_up, -fwd
    m[:3, 3] = -m[:3, :3] @ eye
    return m


@dataclass
class OrbitCamera:
    """Spherical angles around a target: azimuth from +z toward +x, elevation above the xz-plane."""

    target: np.ndarray = field(default_factory=lambda: np.array([0.5, 0.5, 0.5]))
    azimuth: float = 30.0
    """degrees"""
    elevation: float = 25.0
    """degrees"""
    distance: float = 3.0
    """[m]"""
    fov_y: float = FOV_Y_DEG
    near: float = NEAR

    @property
    def position(self) -> np.ndarray:
        az, el = math.radians(self.azimuth), math.radians(self.elevation)
        offset = np.array([math.cos(el) * math.sin(az), math.sin(el), math.cos(el) * math.cos(az)])
        return np.asarray(self.target, dtype=float) + self.distance * offset

    def view(self) -> np.ndarray:
        return look_at(self.position, np.asarray(self.target, dtype=float), np.array([0.0, 1.0, 0.0]))

    def view_projection(self, aspect: float) -> np.ndarray:
        far = max(100.0, self.distance * 10.0)
        return perspective(self.fov_y, aspect, self.near, far) @ self.view()

    def orbit(self, d_azimuth: float, d_elevation: float) -> None:
        self.azimuth = (self.azimuth + d_azimuth) % 360.0
        self.elevation = float(np.clip(self.elevation + d_elevation, -89.0, 89.0))

    def zoom(self, factor: float) -> None:
        self.distance = float(np.clip(self.distance * factor, 0.05, 1000.0))

    def pan(self, dx: float, dy: float) -> None:
        """Move the target in the image plane by fractions of the distance."""
        v = self.view()
        right, up = v[0, :3], v[1, :3]
        self.target = np.asarray(self.target, float) + self.distance * (dx * right + dy * up)


@dataclass
class Light:
    position: tuple[float, float, float] = (0.5, 2.0, 2.0)
    intensity: tuple[float, float, float] = (3.0, 3.0, 3.0)


def framing(lo: np.ndarray, hi: np.ndarray, fov_y: float = FOV_Y_DEG) -> tuple[np.ndarray, float]:
    """Target and distance that fit the box [lo, hi] in view."""
    center = (lo + hi) / 2.0
    radius = max(float(np.linalg.norm(hi - lo)) / 2.0, 1e-3)
    # a box seen from an oblique angle covers less than its bounding sphere
    return center, 0.8 * radius / math.sin(math.radians(fov_y) / 2.0)


def fit_points(camera: OrbitCamera, points: np.ndarray, aspect: float = 1.0, margin: float = 0.92) -> OrbitCamera:
    """Move ``camera`` back along its view (never closer) until every one of
    ``points`` [m] (M, 3) lies within ``margin`` of the image's half-width and
    half-height, for an image ``aspect`` = width / height; returns the camera.

    :func:`framing` fits a box by its bounding sphere, which leaves a wide flat
    layout (a cloth at rest, several cloths side by side) partly out of view
    from the default oblique angle; this fixes that and nothing else."""
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    if not len(pts):
        return camera
    v = camera.view()
    d = pts - np.asarray(camera.target, dtype=float)
    x, y, back = d @ v[0, :3], d @ v[1, :3], d @ v[2, :3]
    half = margin * math.tan(math.radians(camera.fov_y) / 2.0)
    # a point at depth (distance - back) is in view while |x| <= half * aspect * depth, |y| <= half * depth
    need = float(max((back + np.abs(x) / (half * aspect)).max(), (back + np.abs(y) / half).max()))
    if np.isfinite(need) and need > camera.distance:
        camera.distance = need
    return camera
