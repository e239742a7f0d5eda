"""Trajectory: the frames of a run, in memory, for the exporters that take a whole run."""

from __future__ import annotations

import copy
from dataclasses import dataclass, field

import numpy as np

from .mesh import compute_normals


@dataclass
class Trajectory:
    """The positions of every frame of a run and what they need to be drawn elsewhere."""

    positions: np.ndarray
    """point positions [m] of each recorded frame, float64 (F, N, 3); frame 0 is the
    state when recording began (the start, for a fresh simulation)"""
    times: np.ndarray
    """simulated time of each frame [s], float64 (F,)"""
    triangles: np.ndarray
    """vertex indices, int32 (T, 3), counter-clockwise seen from the front"""
    uvs: np.ndarray
    """texture coordinates, float32 (N, 2)"""
    frames_per_sec: float
    """the frames per simulated second the times step by"""
    spheres: list = field(default_factory=list)
    """the spheres as they stood (``SphereSpec``: origin, radius, friction)"""
    planes: list = field(default_factory=list)
    """the planes as they stood (``PlaneSpec``: point, unit normal, friction)"""
    scene: dict = field(default_factory=dict)
    """the scene as JSON data"""
    name: str = "cloth"
    """the scene's name (its file's stem)"""
    description: str = ""
    """the parameters in one line"""

    @property
    def num_frames(self) -> int:
        return self.positions.shape[0]

    def normals(self, frame: int) -> np.ndarray:
        """unit vertex normals of ``frame``, float64 (N, 3)"""
        return compute_normals(self.positions[frame], self.triangles)


class TrajectoryRecorder:
    """Collects a simulation's frames; :meth:`trajectory` gives them as a :class:`Trajectory`."""

    def __init__(self, sim) -> None:
        self._frames: list[np.ndarray] = []
        self._times: list[float] = []
        self(sim)

    def __call__(self, sim) -> None:
        """Record the simulation's current frame."""
        self._frames.append(sim.positions.copy())
        self._times.append(sim.time)

    def trajectory(self, sim) -> Trajectory:
        source = sim.scene.source
        name = "cloth" if source is None else str(source).replace("\\", "/").rsplit("/", 1)[-1]
        return Trajectory(positions=np.stack(self._frames), times=np.array(self._times),
                          triangles=np.asarray(sim.model.triangles), uvs=np.asarray(sim.model.uvs),
                          frames_per_sec=float(sim.params.frames_per_sec),
                          spheres=copy.deepcopy(sim.spheres), planes=copy.deepcopy(sim.planes),
                          scene=sim.scene.to_dict(), name=name.removesuffix(".json"),
                          description=sim.params.describe())
