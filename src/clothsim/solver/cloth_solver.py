"""ClothSolver: the compiled substep of a model, its scratch, and what it takes each frame."""

from __future__ import annotations

import numpy as np

from .. import kernel_cache
from ..model import Model
from ..params import Params
from ..state import State
from . import prewarm
from .colliders import KINDS
from .groups import Control, FrameRun, Knobs, MeshKnobs, Points, Scratch
from .mesh_pulls import build_mesh_pulls, rows_buffer
from .meshsprings import build_mesh_springs
from .meshstep import advance_mesh, advance_mesh_parallel
from .selfcollide import NeighbourList, near_stencil, skin_factor
from .selfcollide.nearlist import mesh_near
from .selfcollide.nearstencil import SKIN_FACTOR
from .shared import BLOCK, on_lines
from .springs import SET_KIND, build_stencil, part_force_buffers
from .step import advance, advance_parallel, parts_for
from .wind import wind_buffer

RUNAWAY_FACTOR = 100.0
"""a point farther than this many cloth sizes from the start means the run blew up"""


BUILD_VARIANT = "build"
"""the warm marker of the kernels a solver compiles when it is made (the list
build checks the rest layout: see :func:`~.selfcollide.nearstencil.grid_metric`)"""


PATHS = ("auto", "grid", "mesh")
"""the solver's paths: the grid's stencils, the general spring lists, or the first that fits"""


def build_compiled() -> bool:
    """Whether making a solver finds its kernels compiled (False: it compiles
    them first, once; see docs/performance.md, 'Compile time')."""
    return kernel_cache.is_warm(BUILD_VARIANT)


def grid_order(rest: np.ndarray, grid: tuple[int, int], parts: int, gravity) -> tuple[np.ndarray, tuple[int, int]]:
    """(order, (rows, cols)): the slots in which the grid path holds a grid cloth's
    points, and the grid as it holds them. The parts of a substep are ranges of
    slots, cut between rows. A cloth whose rows follow one another down
    ``gravity`` (hangs, or falls upright) folds across its rows, and its layers
    pile up from rows far apart: cut between rows, half the pairs of the pile
    that self-collision pushes at 100×100 reached from one part into the
    other. Such a cloth, cut into more than one part, is held column by
    column (the grid transposed: ``order[k]`` is the model's point in slot
    k), so the cut runs down the cloth, and the layers of each half stay in
    that half's part (figures: docs/performance.md, 'Pairs pushed by the
    part that owns them'). One part, or any other cloth: row by row, as the
    model numbers them. ``rest`` (N, 3) [m], ``grid`` (rows, cols)."""
    rows, cols = grid
    n = rows * cols
    order = np.arange(n)
    if parts < 2 or rows < 2 or cols < 2:
        return order, (rows, cols)
    g = np.asarray(gravity, dtype=np.float64)
    g = g / max(float(np.linalg.norm(g)), 1e-300)
    down_rows = abs(float(np.dot(rest[cols] - rest[0], g))) / max(float(np.linalg.norm(rest[cols] - rest[0])), 1e-300)
    down_cols = abs(float(np.dot(rest[1] - rest[0], g))) / max(float(np.linalg.norm(rest[1] - rest[0])), 1e-300)
    if down_rows <= down_cols:
        return order, (rows, cols)
    return order.reshape(rows, cols).T.ravel(), (cols, rows)


class ClothSolver:
    """Steps a :class:`~clothsim.model.Model` in place: ``step(state, control, params, substeps)``.

    Owns everything made once per model for the kernels (the springs as grid
    stencils, the neighbour list, the scratch) and chooses the compiled
    variant: serial, or cut into ``parts`` that threads share (``threads``:
    see :func:`~.step.parts_for`). The result depends on the part count (the
    order of the Provot corrections and of the self-collision sums), not on
    the machine.

    Two paths: a model of one grid cloth takes the grid's strides (the
    spring, Provot and near-stencil kernels of :mod:`.springs`, :mod:`.provot`,
    :mod:`.selfcollide.nearstencil`); any other model (mesh cloths, several
    cloths) the spring lists of :mod:`.meshsprings`, each cloth with its own
    material. Both share the colliders and self-collision.
    """

    def __init__(self, model: Model, threads: int | None = None,
                 first: tuple[Control, Params] | None = None, path: str = "auto") -> None:
        """``first``: the control and params of the first step, where known. If
        its kernels are not in the cache yet, a second process starts
        compiling them at once (see :mod:`.prewarm`), while this one builds.
        ``path``: "grid" (a model of one grid cloth only), "mesh" (any model)
        or "auto", the grid path where the model allows it."""
        grid = len(model.cloths) == 1 and model.cloths[0].grid is not None
        if path not in PATHS:
            raise ValueError(f"path must be one of {', '.join(PATHS)}, not {path!r}")
        if path == "grid" and not grid:
            raise ValueError("the grid path takes a model of one grid cloth")
        self.path = "grid" if path == "auto" and grid else "mesh" if path == "auto" else path
        n = model.num_points
        self.model = model
        self.parts = parts_for(n, threads)
        self._warm: set[str] = set()
        if self.path == "grid":
            self._build_grid(first)
        else:
            self._build_mesh(first)
        self.scratch = Scratch(P=on_lines((3, n)), L=on_lines((3, n)), F=self._forces,
                               masks=np.zeros((self.parts, 2, n // BLOCK + 2), dtype=np.uint64),
                               Q=on_lines((3, n)), W=self._wind)
        kernel_cache.mark_warm(BUILD_VARIANT)

    def _points(self, size: float, order: np.ndarray) -> None:
        """the Points of the model, its points in the slots ``order`` gives"""
        model = self.model
        # pairs of different cloths keep the larger thickness apart: one reach for the whole list
        thickness = max(c.thickness for c in model.cloths)
        slot = np.empty_like(order)
        slot[order] = np.arange(order.shape[0])
        self._slot = slot
        rest = np.ascontiguousarray(model.rest_positions[order])
        triangles = slot[model.triangles].astype(model.triangles.dtype)
        for a in (rest, triangles, order):
            a.setflags(write=False)  # as the model's arrays are: the kernels are compiled for read-only ones
        free = on_lines(order.shape)
        free[:] = ~model.pinned[order]
        self.points = Points(rest=rest, free=free,
                             thickness=float(thickness), center=model.rest_positions.mean(axis=0),
                             span=2.0 * RUNAWAY_FACTOR * size, triangles=triangles, order=order)
        self.runaway2 = (RUNAWAY_FACTOR * size) ** 2
        """squared distance from the start past which a point means the run blew up [m²]"""

    def _build_grid(self, first) -> None:
        """The grid path: the springs as stencils, the near stencil of self-collision."""
        model, n = self.model, self.model.num_points
        cloth = model.cloths[0]
        if first is not None and not self.is_compiled(*first):
            prewarm.start(self.variant(*first))
        gravity = first[1].gravity if first is not None else (0.0, -1.0, 0.0)
        order, (rows, cols) = grid_order(model.rest_positions, cloth.grid, self.parts, gravity)
        self._points(max(cloth.width, cloth.height), order)
        self.transposed = bool((order != np.arange(n)).any())
        """whether the grid's points are held column by column (see :func:`grid_order`)"""
        rest, pinned = self.points.rest, self.points.free == 0.0
        self.springs = build_stencil(rest, pinned, rows, cols)
        self._forces = part_force_buffers(self.springs, n, self.parts)
        self._wind = wind_buffer(n, cols)
        skin = skin_factor(rest, rows, cols, cloth.thickness)
        near = near_stencil(rest, rows, cols, cloth.thickness, skin)
        self.lists = NeighbourList.allocate(n, cols, near, self.parts, skin)
        self._advance = advance if self.parts == 1 else advance_parallel

    def _build_mesh(self, first) -> None:
        """The general path: springs as lists, self-collision with the mesh's near list."""
        model, n = self.model, self.model.num_points
        if first is not None and not self.is_compiled(*first):
            prewarm.start(self.variant(*first))
        self.springs = build_mesh_springs(model, self.parts)
        self.pulls = build_mesh_pulls(model)
        self._points(max(model.size, 1e-9), np.arange(n))
        self.transposed = False
        self._forces = rows_buffer(n)
        self._wind = np.zeros((3, n))
        starts = [c.start for c in model.cloths] + [n]
        reach = 2.0 * self.points.thickness
        mesh = mesh_near(model.rest_positions, starts, reach, reach * (1.0 + SKIN_FACTOR))
        self.lists = NeighbourList.allocate(n, None, None, self.parts, SKIN_FACTOR, mesh)
        self._cloth_sizes = np.diff(starts)
        self._advance = advance_mesh if self.parts == 1 else advance_mesh_parallel

    def knobs(self, params: Params) -> Knobs | MeshKnobs:
        """The kernels' view of the live parameters."""
        if self.path == "mesh":
            return self._mesh_knobs(params)
        material = params.cloths[0]
        k = material.ks / self.model.cloths[0].point_mass(material.density)
        enabled = material.enabled
        return Knobs(gravity=np.asarray(params.gravity, dtype=np.float64),
                     k_over_m=(np.array([k, k, 0.2 * k]) * enabled)[SET_KIND],
                     enabled=enabled[SET_KIND], keep=1.0 - material.damping / 100.0, dt2=params.dt * params.dt,
                     simulation_steps=int(params.simulation_steps),
                     self_collision=bool(params.self_collision),
                     inv_mass=np.full(self.model.num_points, 1.0 / self.model.cloths[0].point_mass(material.density)))

    def _mesh_knobs(self, params: Params) -> MeshKnobs:
        cloths, materials = self.model.cloths, params.cloths
        if len(materials) != len(cloths):
            raise ValueError(f"params hold {len(materials)} materials for {len(cloths)} cloths")
        k = np.array([[m.ks / c.point_mass(m.density)] * 2 + [0.2 * m.ks / c.point_mass(m.density)]
                      for c, m in zip(cloths, materials)])
        enabled = np.array([m.enabled for m in materials])
        keep = np.repeat(np.array([1.0 - m.damping / 100.0 for m in materials]), self._cloth_sizes)
        inv_mass = np.repeat(np.array([1.0 / c.point_mass(m.density) for c, m in zip(cloths, materials)]),
                             self._cloth_sizes)
        return MeshKnobs(gravity=np.asarray(params.gravity, dtype=np.float64),
                         k_over_m=(k * enabled).ravel(), enabled=enabled.ravel(), keep=keep,
                         dt2=params.dt * params.dt, simulation_steps=int(params.simulation_steps),
                         self_collision=bool(params.self_collision), inv_mass=inv_mass)

    def variant(self, control: Control, params: Params) -> str:
        """The name of the compiled specialization a step with these takes: serial
        or parallel, and the collider kinds the scene has (each compiles only
        where present, see :mod:`.colliders`)."""
        parts = ["serial" if self.parts == 1 else "parallel"]
        if self.path == "mesh":
            parts = ["mesh-" + parts[0]]
        parts += [name for name in KINDS if getattr(control, name) is not None]
        parts += [name for name, field in (("handles", "moved_points"), ("wind", "wind"))
                  if getattr(control, field) is not None]
        return "+".join(parts)

    def is_compiled(self, control: Control, params: Params) -> bool:
        """Whether a step with these finds its kernels compiled, in this process
        or in the cache; False means the next step compiles them first, once
        (see docs/performance.md, 'Compile time')."""
        variant = self.variant(control, params)
        return variant in self._warm or kernel_cache.is_warm(variant)

    def step(self, state: State, control: Control, params: Params, substeps: int) -> float:
        """Advance ``state`` by ``substeps`` substeps of ``params.dt`` in place; returns the
        largest squared distance of a point from the start [m²] (inf when not finite)."""
        return self.step_frames(state, control, params, substeps, 1)[0]

    def load(self, state: State, control: Control, params: Params, substeps: int) -> None:
        """Compile (or load from the cache) the kernels a step with these takes,
        once per variant in a process; advances nothing. A caller that holds
        Ctrl-C back over a step (:func:`clothsim.interrupts.held_interrupts`)
        calls this first, so that the hold never covers a compile."""
        if self.variant(control, params) not in self._warm:
            self._call(state, control, params, substeps, 0, np.inf)

    def step_frames(self, state: State, control: Control, params: Params, substeps: int, frames: int,
                    limit2: float = np.inf) -> tuple[float, int]:
        """Advance ``state`` in place by up to ``frames`` frames of ``substeps`` substeps
        each on ``control`` (one still frame's, or the frames' stacked by
        :func:`.control.stack_frames`), in one compiled call that stops after
        the first frame leaving a point farther than sqrt(``limit2``) [m] from
        the start or not finite. Returns (that frame's largest squared distance
        [m²], inf when not finite; the frames run)."""
        return self._call(state, control, params, substeps, frames, limit2)

    def _call(self, state: State, control: Control, params: Params, substeps: int, frames: int,
              limit2: float) -> tuple[float, int]:
        """the compiled call of :meth:`step_frames` (0 frames: of :meth:`load`)"""
        springs = (self.springs,) if self.path == "grid" else (self.springs, self.pulls)
        if self.transposed:  # the held point and the handles' points, in the solver's slots
            moved = control.moved_points
            control = control._replace(handle=int(self._slot[control.handle]) if control.handle >= 0 else -1,
                                       moved_points=None if moved is None else self._slot[moved])
        frame_run = FrameRun(substeps=int(substeps), frames=int(frames), limit2=float(limit2))
        far2, pairs, done = self._advance(state.positions, state.last_positions, self.points, *springs,
                                          self.knobs(params), control, self.lists, self.lists.pairs,
                                          self.scratch, frame_run)
        self.lists = self.lists._replace(pairs=pairs)
        variant = self.variant(control, params)
        if variant not in self._warm:
            self._warm.add(variant)
            kernel_cache.mark_warm(variant)
        return far2, done

    @property
    def rebuilds(self) -> int:
        """how often self-collision built its neighbour list"""
        return self.lists.rebuilds
