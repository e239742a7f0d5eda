"""The scene's moving world: boxes, mesh colliders, a cloth's handles and the wind
(the format's "More colliders", "Motion" and "Wind" sections)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from .transform import MeshTransform
from .motion import Animation, Vec3

if TYPE_CHECKING:  # numpy loads with a scene's meshes, not with the command line's --help
    import numpy as np

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

    def to_dict(self) -> dict[str, Any]:
        """The scene keys of this box (what the scene reader reads back)."""
        out = {"center": list(self.center), "size": list(self.size), "rotate": list(self.rotate),
               "friction": self.friction, "margin": self.margin}
        return with_animation(out, self.animation)


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
        """the middle of the bounding box after the transform [m], (3,): what an animation
        turns about. Kept with the vertices it was found from, as the control of every
        frame asks for it and a large mesh's box took longer than the frame's substeps."""
        kept = self.__dict__.get("_pivot")
        if kept is None or kept[0] is not self.vertices:
            kept = (self.vertices, (self.vertices.min(axis=0) + self.vertices.max(axis=0)) / 2.0)
            kept[1].setflags(write=False)
            self.__dict__["_pivot"] = kept
        return kept[1]

    def to_dict(self) -> dict[str, Any]:
        """The scene keys of this collider; ``path`` as the scene wrote it, so the dict
        reads back with the same scene source."""
        out = {"path": self.path, "transform": self.transform.to_dict(), "friction": self.friction,
               "margin": self.margin}
        return with_animation(out, self.animation)


@dataclass
class HandleSpec:
    """Points of a cloth moved by an animation instead of pinned where they are."""

    animation: Animation
    points: list[tuple[int, int]] = field(default_factory=list)
    """grid indices ``(i, j)`` (a grid cloth)"""
    vertices: list[int] = field(default_factory=list)
    """file vertex indices (a mesh cloth)"""

    def to_dict(self) -> dict[str, Any]:
        """The scene keys of this handle: ``points`` (a grid cloth's) or ``vertices``."""
        members = {"points": [list(p) for p in self.points]} if self.points else {"vertices": list(self.vertices)}
        return {**members, "animation": self.animation.to_dict()}


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

    def to_dict(self) -> dict[str, Any]:
        """The scene keys of the wind."""
        return {"velocity": list(self.velocity), "turbulence": self.turbulence, "drag": self.drag,
                "lift": self.lift, "seed": self.seed}


def with_animation(out: dict[str, Any], animation: Animation | None) -> dict[str, Any]:
    """``out`` with the key ``animation`` where there is one (never ``null``)"""
    if animation is not None:
        out["animation"] = animation.to_dict()
    return out
