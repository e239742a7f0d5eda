"""Simulation: the model, the state, the control and the live parameters, stepped frame by frame."""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import SimulationError
from .export import write_model_obj
from .interrupts import held_interrupts
from .mesh import compute_normals
from .model import Cloth, Model, build_scene_model
from .params import Material, Params
from .scene import PlaneSpec, Scene, SphereSpec, load_scene
from .scene_limits import RUN_FRAMES_MAX, STEPS_MAX, run_frames
from .solver import ClothSolver, Control
from .solver.control import make_control, stack_frames
from .solver.cloth_solver import RUNAWAY_FACTOR
from .state import State
from .world import Handle, pin_handles, scene_handles
from .world_spec import BoxSpec, MeshColliderSpec, WindSpec

__all__ = ["ClothView", "Material", "Params", "Simulation", "State"]

FRAME_CALL_WORK = 5_000_000
"""point-substeps (points times substeps) a compiled call of :meth:`Simulation.step_frames`
takes at most: some 66 frames of a 50x50 cloth at 30 substeps a frame, 4 of a
200x200 one; a call's return to Python costs about what two or three of a
50x50 cloth's substeps do, so this many leave it a few thousandths of the run"""

MOVING_FRAMES_MAX = 256
"""the most frames of a moving world (:meth:`Simulation.holds_still` false) in one
call: each frame's control is made in Python before the call, so a small cloth,
whose FRAME_CALL_WORK spans tens of thousands of frames, would wait on that"""


@dataclass(frozen=True)
class ClothView:
    """One cloth of a running simulation: ``sim.cloths[i]``."""

    sim: Simulation
    index: int
    """its place in the scene's ``cloth`` list"""

    @property
    def model(self) -> Cloth:
        """its part of the model: point and triangle ranges, thickness, area"""
        return self.sim.model.cloths[self.index]

    @property
    def name(self) -> str:
        return self.model.name

    @property
    def params(self) -> Material:
        """its live material (ks, density, damping, enable_*), edited between frames"""
        return self.sim.params.cloths[self.index]

    @property
    def positions(self) -> np.ndarray:
        """its points' positions [m], a view into ``sim.positions``, (n, 3)"""
        return self.sim.positions[self.model.points]

    @property
    def pinned(self) -> np.ndarray:
        """its pinned points, bool (n,)"""
        return self.sim.model.pinned[self.model.points]

    @property
    def triangles(self) -> np.ndarray:
        """its triangles, indices into its own points, int32 (t, 3)"""
        return self.sim.model.triangles[self.model.triangle_range] - self.model.start

    @property
    def point_mass(self) -> float:
        """mass of one of its points [density units x m²], as CS184 computes it"""
        return self.model.point_mass(self.params.density)


@dataclass
class Simulation:
    """A running cloth: ``step()`` advances one frame of ``params.frames_per_sec``.

    ``params``, the colliders (``spheres``, ``planes``, ``boxes``: friction,
    position, animation; ``mesh_colliders``: friction, animation) and ``wind``
    (None, or velocity, turbulence, drag, lift) may be edited between frames;
    nothing is rebuilt for it.

    ``threads``: how many threads share each substep, fixed when the
    simulation is made (None: one for cloths under PARALLEL_MIN_POINTS
    points, else numba's thread count, which ``NUMBA_NUM_THREADS`` sets). The
    result depends on this count (the order of the Provot corrections and of
    the self-collision sums), not on the machine.
    """

    scene: Scene
    threads: int | None = None
    solver_path: str = "auto"
    """the solver's path: "auto" (the grid's stencils for one grid cloth, else the
    general spring lists), "grid" or "mesh" (the general path for any model)"""
    model: Model = field(init=False)
    params: Params = field(init=False)
    state: State = field(init=False)
    spheres: list[SphereSpec] = field(init=False)
    planes: list[PlaneSpec] = field(init=False)
    boxes: list[BoxSpec] = field(init=False)
    mesh_colliders: list[MeshColliderSpec] = field(init=False)
    handles: list[Handle] = field(init=False)
    wind: WindSpec | None = field(init=False)

    def __post_init__(self) -> None:
        model = build_scene_model(self.scene)
        self.handles = scene_handles(self.scene, model)
        self.model = pin_handles(model, self.handles)
        self.params = Params.from_scene(self.scene)
        self.spheres = copy.deepcopy(self.scene.spheres)
        self.planes = copy.deepcopy(self.scene.planes)
        self.boxes = copy.deepcopy(self.scene.boxes)
        self.mesh_colliders = [copy.copy(m) for m in self.scene.mesh_colliders]  # the shapes are shared
        self.wind = copy.deepcopy(self.scene.wind)
        self._mesh_shapes = None
        if self.mesh_colliders:
            from .solver.colliders.mesh import pack_meshes, with_hints

            self._mesh_shapes = with_hints(pack_meshes(self.mesh_colliders), self.model.num_points)
        self.state = State.at_rest(self.model)
        self._normals: np.ndarray | None = None
        self._handle = -1
        self._handle_pos = np.zeros(3)
        self.solver = ClothSolver(self.model, self.threads, (self.control, self.params), self.solver_path)

    @classmethod
    def from_file(cls, path: str | Path, overrides: list[str] | tuple[str, ...] = (),
                  threads: int | None = None, solver_path: str = "auto", strict: bool = False) -> Simulation:
        """The simulation of a scene file (``strict`` as in :func:`~clothsim.scene.load_scene`)."""
        return cls(load_scene(path, overrides, strict), threads, solver_path)

    # ------------------------------------------------------------------ state

    @property
    def positions(self) -> np.ndarray:
        """point mass positions [m] of every cloth in scene order, float64 (N, 3);
        a grid's row-major, a mesh's in its file's vertex order"""
        return self.state.positions

    @property
    def cloths(self) -> list[ClothView]:
        """the cloths in scene order, each with its live ``params`` and its points"""
        return [ClothView(self, k) for k in range(len(self.model.cloths))]

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
        """mass of one point of the only cloth [density units x m²], as CS184
        computes it (a scene of several: ``sim.cloths[i].point_mass``)"""
        if len(self.model.cloths) != 1:
            raise AttributeError(f"the scene has {len(self.model.cloths)} cloths: use sim.cloths[i].point_mass")
        return self.cloths[0].point_mass

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
        return self.solver.rebuilds

    @property
    def control(self) -> Control:
        """what the world imposes over the next frame: the held point, the colliders,
        handles and wind where they stand and move"""
        return self._control(self.params.simulation_steps)

    def _control(self, substeps: int, t0: float | None = None) -> Control:
        return make_control(self._handle, self._handle_pos, self, self.state.time if t0 is None else t0,
                            self.params.dt, substeps, self._mesh_shapes)

    def _frames_control(self, substeps: int, frames: int) -> Control:
        """the control of the next ``frames`` frames: each frame's from the time that
        frame starts at, as :meth:`step` would add it up, stacked"""
        t, step = self.state.time, substeps * self.params.dt
        controls = []
        for _ in range(frames):
            controls.append(self._control(substeps, t))
            t += step
        return stack_frames(controls)

    @property
    def kernels_compiled(self) -> bool:
        """False when the next step compiles the kernels first (once per
        variant and machine; afterwards they load from the cache)"""
        return self.solver.is_compiled(self.control, self.params)

    @property
    def grabbed(self) -> int:
        """index of the held point, or -1"""
        return self._handle

    # ------------------------------------------------------------------ stepping

    def step(self, substeps: int | None = None) -> None:
        """Advance one frame (or ``substeps`` substeps, a whole number from 0 to
        :data:`~clothsim.scene_limits.STEPS_MAX`: 0 loads the kernels and advances
        nothing; any other is ValueError); raise SimulationError on blow-up."""
        p = self.params
        if substeps is not None and (isinstance(substeps, bool) or not isinstance(substeps, (int, np.integer))
                                     or not 0 <= substeps <= STEPS_MAX):
            raise ValueError(f"substeps: expected a whole number from 0 to {STEPS_MAX:,}, got {substeps!r}")
        n = p.simulation_steps if substeps is None else int(substeps)
        control = self._control(n)
        self.solver.load(self.state, control, p, n)
        with held_interrupts():  # the clock moves with the cloth, even on Ctrl-C
            far2 = self.solver.step(self.state, control, p, n)
            self.state.frame += 1 if substeps is None else 0
            self.state.time += n * p.dt
            self._normals = None
        self._check_runaway(far2)

    def step_frames(self, frames: int) -> None:
        """Advance ``frames`` whole frames (a whole number from 0 to
        :data:`~clothsim.scene_limits.RUN_FRAMES_MAX`), as that many calls of
        :meth:`step` would: the same positions to the bit, and a blow-up raised
        at the frame it happens. Up to :attr:`frames_per_call` frames run in
        one compiled call, which spares each frame's return to Python and the
        caches it cools (figures: docs/performance.md, 'Frames in one call'):
        where the world holds still (:meth:`holds_still`) on one control, and
        where colliders, handles or the wind move, on each frame's control made
        as :meth:`step` makes it, their slots and rows one frame after another
        (:func:`~clothsim.solver.control.stack_frames`). Frames of one substep
        with something moving take one frame a call."""
        if isinstance(frames, bool) or not isinstance(frames, (int, np.integer)) \
                or not 0 <= frames <= RUN_FRAMES_MAX:
            raise ValueError(f"frames: expected a whole number from 0 to {RUN_FRAMES_MAX:,}, got {frames!r}")
        p = self.params
        n = p.simulation_steps
        left = int(frames)
        still = self.holds_still()  # nothing the user edits changes during the loop
        per_call = self._frames_per_call(still)
        while left > 0:
            many = min(left, per_call)
            if still:
                control = self._control(n)
            elif n > 1:
                control = self._frames_control(n, many)
            else:
                many, control = 1, self._control(n)
            self.solver.load(self.state, control, p, n)
            with held_interrupts():  # the clock moves with the cloth, even on Ctrl-C
                far2, done = self.solver.step_frames(self.state, control, p, n, many, self.solver.runaway2)
                for _ in range(done):  # as step() adds them, frame by frame
                    self.state.frame += 1
                    self.state.time += n * p.dt
                self._normals = None
            self._check_runaway(far2)
            left -= done

    @property
    def frames_per_call(self) -> int:
        """the most frames :meth:`step_frames` runs in one compiled call: about
        FRAME_CALL_WORK point-substeps, so that a call stays short enough for
        a progress bar and Ctrl-C to answer between calls, and at most
        MOVING_FRAMES_MAX where something moves"""
        return self._frames_per_call(self.holds_still())

    def _frames_per_call(self, still: bool) -> int:
        most = max(1, FRAME_CALL_WORK // max(1, self.model.num_points * self.params.simulation_steps))
        return most if still else min(most, MOVING_FRAMES_MAX)

    def holds_still(self) -> bool:
        """Whether the world imposes the same on every frame: no collider animated
        (or only by keys that never move it), no handles and no wind (its gusts
        change with time). Then one control serves many frames; otherwise
        :meth:`step_frames` makes each frame's."""
        movers = (*self.spheres, *self.planes, *self.boxes, *self.mesh_colliders)
        return (not self.handles and self.wind is None
                and all(getattr(c, "animation", None) is None or c.animation.is_still for c in movers))

    def _check_runaway(self, far2: float) -> None:
        """SimulationError unless the largest squared distance ``far2`` [m²] of a point
        from the start is finite and within the runaway limit"""
        p = self.params
        if not (np.isfinite(far2) and far2 <= self.solver.runaway2):  # holds where the limit is inf too
            what = "is no longer finite" if not np.isfinite(far2) else (
                f"has a point {np.sqrt(far2):.3g} m from the start, more than "
                f"{RUNAWAY_FACTOR:g}x the cloth size")
            raise SimulationError(
                f"the simulation became unstable at frame {self.state.frame} "
                f"(t={self.state.time:.3f} s): the cloth {what}; parameters: {p.describe()}. "
                f"Lower ks or raise simulation_steps (the substep is {p.dt * 1e3:.3g} ms)")

    def run(self, seconds: float, on_frame=None) -> int:
        """Advance ``seconds`` of simulated time (whole frames, :func:`~clothsim.scene_limits.run_frames`:
        ValueError, before any step, unless a finite number >= 0 of at most
        :data:`~clothsim.scene_limits.RUN_FRAMES_MAX` frames); return the frame count."""
        frames = run_frames(seconds, self.params.frames_per_sec)
        if on_frame is None:
            self.step_frames(frames)
            return frames
        for _ in range(frames):
            self.step()
            on_frame(self)
        return frames

    def export_obj(self, path: str | Path, overwrite: bool = True) -> None:
        """Write the cloth as an OBJ (one object per cloth); ``overwrite=False``: never
        over a file that is at ``path`` when it is placed."""
        write_model_obj(path, self.model, self.positions, self.normals, overwrite)

    # ------------------------------------------------------------------ notebooks

    @property
    def recording(self):
        """the :class:`~clothsim.trajectory.Trajectory` of the last
        :func:`clothsim.record` call on this simulation, or None: the frames a
        notebook shows for it. Nothing else is kept: stepping records nothing."""
        return self.__dict__.get("_recording")

    def show(self, width: int = 640, height: int = 400, **look):
        """The web player of the frames recorded so far, for a notebook: those of
        the last :func:`clothsim.record` call (``recording``), or the current frame
        alone when there is none. A :class:`~clothsim.trajectory.Player` (``look``:
        color, camera, phong, light, title)."""
        from .trajectory import Player, _trajectory

        traj = self.recording
        if traj is None:
            traj = _trajectory(self, self.positions[None].copy(), np.array([self.time]),
                               self.params.frames_per_sec)
        return Player(traj, width, height, **look)

    def _repr_html_(self) -> str:
        """Jupyter shows a simulation as :meth:`show`'s player."""
        return self.show()._repr_html_()
