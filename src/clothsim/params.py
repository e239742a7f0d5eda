"""Params: the knobs a user may turn between frames without rebuilding anything."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .scene import Scene


@dataclass
class Params:
    """What a user may change between frames without rebuilding the model."""

    ks: float
    """spring constant [N/m]; bending springs use 0.2*ks"""
    density: float
    """g/cm² as in CS184"""
    damping: float
    """percent of velocity removed per substep, 0..100"""
    enable_structural: bool
    enable_shearing: bool
    enable_bending: bool
    gravity: tuple[float, float, float]
    """[m/s²]"""
    frames_per_sec: float
    simulation_steps: int
    """substeps per frame"""
    self_collision: bool

    @classmethod
    def from_scene(cls, scene: Scene) -> Params:
        c, s = scene.cloth, scene.simulation
        return cls(ks=c.ks, density=c.density, damping=c.damping,
                   enable_structural=c.enable_structural, enable_shearing=c.enable_shearing,
                   enable_bending=c.enable_bending, gravity=tuple(s.gravity),
                   frames_per_sec=s.frames_per_sec, simulation_steps=s.simulation_steps,
                   self_collision=s.self_collision)

    @property
    def dt(self) -> float:
        """length of one substep [s]"""
        return 1.0 / (self.frames_per_sec * self.simulation_steps)

    @property
    def enabled(self) -> np.ndarray:
        """which spring kinds act, indexed by STRUCTURAL, SHEARING, BENDING"""
        return np.array([self.enable_structural, self.enable_shearing, self.enable_bending])

    def describe(self) -> str:
        return (f"ks={self.ks:g} N/m, density={self.density:g}, damping={self.damping:g}%, "
                f"{self.frames_per_sec:g} frames/s x {self.simulation_steps} substeps")
