"""Params: the knobs a user may turn between frames without rebuilding anything.

Each cloth has its own :class:`Material` (``params.cloths[i]``, also
``sim.cloths[i].params``); what the whole scene shares (gravity, the frame
rate, the substeps, self-collision) sits on :class:`Params` itself. A scene of
one cloth, as every CS184 scene is, reads and sets its material through
``params.ks`` etc. as well.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from .scene import Scene


@dataclass
class Material:
    """What a user may change of one cloth between frames."""

    ks: float
    """spring constant [N/m]; bending springs use 0.2*ks"""
    density: float
    """g/cm² as in CS184"""
    damping: float
    """percent of velocity removed per substep, 0..100"""
    enable_structural: bool
    enable_shearing: bool
    enable_bending: bool

    @classmethod
    def of(cls, spec) -> Material:
        """The material a cloth spec of the scene starts with."""
        return cls(**{f.name: getattr(spec, f.name) for f in fields(cls)})

    @property
    def enabled(self) -> np.ndarray:
        """which spring kinds act, indexed by STRUCTURAL, SHEARING, BENDING"""
        return np.array([self.enable_structural, self.enable_shearing, self.enable_bending])

    def describe(self) -> str:
        return f"ks={self.ks:g} N/m, density={self.density:g}, damping={self.damping:g}%"


MATERIAL_KEYS = tuple(f.name for f in fields(Material))


@dataclass
class Params:
    """What a user may change between frames without rebuilding the model."""

    cloths: list[Material]
    """each cloth's material, in scene order"""
    gravity: tuple[float, float, float]
    """[m/s²]"""
    frames_per_sec: float
    simulation_steps: int
    """substeps per frame"""
    self_collision: bool

    @classmethod
    def from_scene(cls, scene: Scene) -> Params:
        s = scene.simulation
        return cls(cloths=[Material.of(c) for c in scene.cloths], gravity=tuple(s.gravity),
                   frames_per_sec=s.frames_per_sec, simulation_steps=s.simulation_steps,
                   self_collision=s.self_collision)

    @property
    def material(self) -> Material:
        """the material of the only cloth; a scene of several names each:
        ``params.cloths[i]``"""
        if len(self.cloths) != 1:
            raise AttributeError(f"the scene has {len(self.cloths)} cloths, each with its own material: "
                                 f"use params.cloths[i] (sim.cloths[i].params)")
        return self.cloths[0]

    def __getattr__(self, name: str):
        # the single-cloth shorthands: params.ks is params.cloths[0].ks
        if name in MATERIAL_KEYS or name == "enabled":
            return getattr(self.material, name)
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    def __setattr__(self, name: str, value) -> None:
        if name in MATERIAL_KEYS:
            setattr(self.material, name, value)
        else:
            object.__setattr__(self, name, value)

    @property
    def dt(self) -> float:
        """length of one substep [s]"""
        return 1.0 / (self.frames_per_sec * self.simulation_steps)

    def describe(self) -> str:
        cloths = "; ".join(m.describe() for m in self.cloths)
        return f"{cloths}, {self.frames_per_sec:g} frames/s x {self.simulation_steps} substeps"
