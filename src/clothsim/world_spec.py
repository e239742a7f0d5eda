"""The scene's moving world: boxes, mesh colliders, a cloth's handles and the wind
(the format's "More colliders", "Motion" and "Wind" sections)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .mesh_spec import MeshTransform
from .motion import Animation, Vec3

MARGIN_DEFAULT = 0.001
"""how far off a box's or a mesh's surface a colliding point is put back [m]"""


@dataclass
class BoxSpec:
    """An oriented box: ``size`` along its own axes, turned by ``rotate`` about its centre."""

    center: Vec3
    """[m]"""
    size: Vec3
    """full lengths along the box's axes [m], each > 0"""
    friction: float
    rotate: Vec3 = (0.0, 0.0, 0.0)
    """degrees about x, then y, then z (as a mesh's transform)"""
    margin: float = MARGIN_DEFAULT
    animation: Animation | None = None


@dataclass
class MeshColliderSpec:
    """A triangle mesh that points may not cross; a closed one is a solid."""

    path: str
    """the file as the scene writes it"""
    file: str
    """the file: ``path`` relative to the scene file's folder"""
    friction: float
    transform: MeshTransform = field(default_factory=MeshTransform)
    margin: float = MARGIN_DEFAULT
    animation: Animation | None = None
    vertices: np.ndarray | None = field(default=None, compare=False, repr=False)
    """positions after the transform [m], float64 (V, 3)"""
    triangles: np.ndarray | None = field(default=None, compare=False, repr=False)
    """vertex indices, int64 (F, 3) (quads and polygons split)"""
    closed: bool = False
    """every edge is shared by exactly two triangles: a solid"""

    @property
    def pivot(self) -> np.ndarray:
        """the middle of the bounding box after the transform [m], (3,): what an animation turns about"""
        return (self.vertices.min(axis=0) + self.vertices.max(axis=0)) / 2.0


@dataclass
class HandleSpec:
    """Points of a cloth moved by an animation instead of pinned where they are."""

    animation: Animation
    points: list[tuple[int, int]] = field(default_factory=list)
    """grid indices ``(i, j)`` (a grid cloth)"""
    vertices: list[int] = field(default_factory=list)
    """file vertex indices (a mesh cloth)"""


@dataclass
class WindSpec:
    """Air moving at ``velocity``: drag and lift on every triangle of every cloth."""

    velocity: Vec3
    """[m/s]"""
    turbulence: float = 0.0
    """gusts relative to the speed, 0..1"""
    drag: float = 1.0
    """drag coefficient of a triangle facing the air"""
    lift: float = 0.0
    """lift coefficient"""
    seed: int = 0
    """seeds the gusts"""
