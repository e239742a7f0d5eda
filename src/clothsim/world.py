"""The cloths' world as it moves: the handles of a scene's cloths, found in its model.

The colliders and the wind are the scene's specs themselves (copies that a
user may edit between frames, ``sim.spheres``, ``sim.boxes``, ``sim.wind``
...); what needs the model is a handle: which of its points it moves and
where they start.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from .mesh_spec import MeshClothSpec
from .model import Model
from .motion import Animation
from .scene import Scene


@dataclass(frozen=True, eq=False)
class Handle:
    """Points of the model moved by an animation (see :mod:`clothsim.solver.handles`)."""

    cloth: int
    """the index of its cloth in the scene"""
    points: np.ndarray
    """indices into the model's points, int64 (H,)"""
    start: np.ndarray
    """their start positions [m], float64 (H, 3)"""
    animation: Animation

    @property
    def pivot(self) -> np.ndarray:
        """the centroid of the start positions [m], (3,): the animation turns about it"""
        return self.start.mean(axis=0)


def handle_points(spec) -> list[np.ndarray]:
    """Each handle's points of one cloth spec, as indices into that cloth's own
    points, int64: a grid's ``(i, j)`` is row-major ``j * num_width_points + i``;
    a mesh's file vertices go through its weld."""
    out = []
    for h in getattr(spec, "handles", ()):
        if isinstance(spec, MeshClothSpec):
            idx = spec.data.file_to_point[np.asarray(h.vertices, dtype=np.int64)]
        else:
            idx = np.array([j * spec.num_width_points + i for i, j in h.points], dtype=np.int64)
        out.append(np.unique(idx))
    return out


def scene_handles(scene: Scene, model: Model) -> list[Handle]:
    """Every handle of every cloth of ``scene``, on ``model`` (its model)."""
    out = []
    for k, (spec, cloth) in enumerate(zip(scene.cloths, model.cloths)):
        for h, idx in zip(spec.handles, handle_points(spec)):
            points = idx + cloth.start
            out.append(Handle(k, points, model.rest_positions[points].copy(), h.animation))
    return out


def pin_handles(model: Model, handles: list[Handle]) -> Model:
    """``model`` with every handle's points pinned: no force, collider or constraint
    moves them; the substep puts them where their animation carries them."""
    if not handles:
        return model
    pinned = model.pinned.copy()
    for h in handles:
        pinned[h.points] = True
    pinned.setflags(write=False)
    return dataclasses.replace(model, pinned=pinned)


def pose_at(animation: Animation | None, pivot, t: float) -> tuple[np.ndarray, np.ndarray]:
    """A collider's or handle's rigid pose at time ``t`` [s]: (R (3, 3), o (3,)),
    ``x_now = R @ x_rest + o``; the identity for no animation. The pivot of each
    kind: a sphere's ``origin``, a plane's ``point``, a box's ``center``, a mesh
    collider's ``pivot``."""
    if animation is None:
        return np.eye(3), np.zeros(3)
    R, o = animation.rigid([t], pivot)
    return R[0], o[0]
