"""Simulation: the model, the state and the live parameters, stepped frame by frame."""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import solver
from .errors import SimulationError
from .export import write_obj
from .mesh import compute_normals
from .model import ClothModel, build_model
from .scene import PlaneSpec, Scene, SphereSpec, load_scene
from .solver.grid import BLOCK, SET_KIND, build_stencil, force_buffer
from .solver.self_collide import NeighbourList, near_stencil, skin_factor

RUNAWAY_FACTOR = 100.0
"""a point farther than this many cloth sizes from the start means the run blew up"""


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


@dataclass
class State:
    """What a substep changes."""

    positions: np.ndarray
    """point mass positions [m], float64 (N, 3)"""
    last_positions: np.ndarray
    """positions one substep ago [m], float64 (N, 3)"""
    frame: int = 0
    time: float = 0.0
    """simulated time [s]"""

    @classmethod
    def at_rest(cls, model: ClothModel) -> State:
        return cls(model.rest_positions.copy(), model.rest_positions.copy())


class _Scratch:
    """Buffers the kernels reuse every substep, allocated once per model."""

    def __init__(self, model: ClothModel, parts: int) -> None:
        n = model.num_points
        self.parts = parts
        self.stencil = build_stencil(model)
        self.free = (~model.pinned).astype(np.float64)
        self.planes = np.zeros((2, 3, n))  # positions, last positions
        self.forces = force_buffer(self.stencil, n)
        self.masks = np.zeros((parts, 2, n // BLOCK + 2), dtype=np.uint64)  # Provot scratch
        grid = (model.rest_positions, model.num_height_points, model.num_width_points, model.thickness)
        skin = skin_factor(*grid)
        self.lists = NeighbourList(n, model.num_width_points, near_stencil(*grid, skin), parts, skin)


@dataclass
class Simulation:
    """A running cloth: ``step()`` advances one frame of ``params.frames_per_sec``.

    ``params``, ``spheres`` and ``planes`` (friction, position) may be edited
    between frames; nothing is rebuilt for it.

    ``threads``: how many threads share each substep, fixed when the
    simulation is made (None: one for cloths under PARALLEL_MIN_POINTS
    points, else numba's thread count, which ``NUMBA_NUM_THREADS`` sets). The
    result depends on this count (the order of the Provot corrections and of
    the self-collision sums), not on the machine.
    """

    scene: Scene
    threads: int | None = None
    model: ClothModel = field(init=False)
    params: Params = field(init=False)
    state: State = field(init=False)
    spheres: list[SphereSpec] = field(init=False)
    planes: list[PlaneSpec] = field(init=False)

    def __post_init__(self) -> None:
        self.model = build_model(self.scene.cloth, self.scene.simulation.seed)
        self.params = Params.from_scene(self.scene)
        self.spheres = copy.deepcopy(self.scene.spheres)
        self.planes = copy.deepcopy(self.scene.planes)
        self.state = State.at_rest(self.model)
        self._scratch = _Scratch(self.model, solver.parts_for(self.model.num_points, self.threads))
        self._center = self.model.rest_positions.mean(axis=0)
        size = max(self.model.width, self.model.height)
        self._runaway2 = (RUNAWAY_FACTOR * size) ** 2
        self._span = 2.0 * RUNAWAY_FACTOR * size  # spread beyond which self-collision stops
        self._normals: np.ndarray | None = None
        self._handle = -1
        self._handle_pos = np.zeros(3)

    @classmethod
    def from_file(cls, path: str | Path, overrides: list[str] | tuple[str, ...] = (),
                  threads: int | None = None) -> Simulation:
        return cls(load_scene(path, overrides), threads)

    # ------------------------------------------------------------------ state

    @property
    def positions(self) -> np.ndarray:
        """point mass positions [m], float64 (N, 3), row-major grid order"""
        return self.state.positions

    @property
    def normals(self) -> np.ndarray:
        """unit vertex normals, float64 (N, 3), cached until the next step"""
        if self._normals is None:
            self._normals = compute_normals(self.state.positions, self.model.triangles)
        return self._normals

    @property
    def frame(self) -> int:
        return self.state.frame

    @property
    def time(self) -> float:
        return self.state.time

    @property
    def point_mass(self) -> float:
        """mass of one point [density units x m²], as CS184 computes it"""
        m = self.model
        return m.width * m.height * self.params.density / m.num_points

    def reset(self) -> None:
        """Put the cloth back at its start; the parameters keep their current values."""
        self.state = State.at_rest(self.model)
        self._normals = None
        self.release()

    def grab(self, index: int, target) -> None:
        """Hold point ``index`` at ``target`` [m] during the following steps (a mouse pull)."""
        if not 0 <= index < self.model.num_points:
            raise IndexError(f"point {index} is not in the cloth (0..{self.model.num_points - 1})")
        if self.model.pinned[index]:
            return
        self._handle = int(index)
        self._handle_pos = np.asarray(target, dtype=np.float64).copy()

    def release(self) -> None:
        self._handle = -1

    @property
    def neighbour_list_rebuilds(self) -> int:
        """how often self-collision rebuilt its neighbour list since the start"""
        return self._scratch.lists.rebuilds

    @property
    def grabbed(self) -> int:
        """index of the held point, or -1"""
        return self._handle

    # ------------------------------------------------------------------ stepping

    def step(self, substeps: int | None = None) -> None:
        """Advance one frame (or ``substeps`` substeps); raise SimulationError on blow-up."""
        p = self.params
        n = p.simulation_steps if substeps is None else substeps
        k = p.ks / self.point_mass
        k_over_m = (np.array([k, k, 0.2 * k]) * p.enabled)[SET_KIND]
        m, s = self.model, self._scratch
        st = s.stencil
        advance = solver.advance if s.parts == 1 else solver.advance_parallel
        far2, s.lists.pairs = advance(
            self.state.positions, self.state.last_positions, m.rest_positions, s.free,
            np.asarray(p.gravity, dtype=np.float64), k_over_m, p.enabled[SET_KIND],
            1.0 - p.damping / 100.0, p.dt, n, p.simulation_steps,
            st.start, st.end, st.count, st.valid, st.rest, st.limit, st.batch, st.share,
            solver.pack_spheres(self.spheres), solver.pack_planes(self.planes),
            bool(p.self_collision), m.thickness, self._span, s.planes[0], s.planes[1], s.forces,
            s.masks, s.lists.buffers(), self._handle, self._handle_pos, self._center)
        self.state.frame += 1 if substeps is None else 0
        self.state.time += n * p.dt
        self._normals = None
        if not far2 <= self._runaway2:
            what = "is no longer finite" if not np.isfinite(far2) else (
                f"has a point {np.sqrt(far2):.3g} m from the start, more than "
                f"{RUNAWAY_FACTOR:g}x the cloth size")
            raise SimulationError(
                f"the simulation became unstable at frame {self.state.frame} "
                f"(t={self.state.time:.3f} s): the cloth {what}; parameters: {p.describe()}. "
                f"Lower ks or raise simulation_steps (the substep is {p.dt * 1e3:.3g} ms)")

    def run(self, seconds: float, on_frame=None) -> int:
        """Advance ``seconds`` of simulated time (whole frames); return the frame count."""
        frames = max(0, int(round(seconds * self.params.frames_per_sec)))
        for _ in range(frames):
            self.step()
            if on_frame is not None:
                on_frame(self)
        return frames

    def export_obj(self, path: str | Path) -> None:
        write_obj(path, self.positions, self.normals, self.model.uvs, self.model.triangles)
