"""The named groups of arrays and numbers that reach the substep's kernels.

Each group is a ``typing.NamedTuple`` so numba compiles field reads into
plain loads; a kernel reads the fields it needs by name into locals at its
entry (stores through a field inside a ``prange`` body are dropped by
numba), and no order of buffers is written anywhere but here and in the
groups of the stages (:class:`~.springs.GridSprings`, :class:`~.selfcollide.NeighbourList`).
A group used inside a ``prange`` body must reach it as an argument of the
compiled call, not as a field of another group: numba cannot unpack it there.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np



class Points(NamedTuple):
    """What the kernels need of the model's points, fixed while the cloth runs."""

    rest: np.ndarray
    """rest layout [m], float64 (N, 3): self-collision never pushes pairs closer than the reach in it"""
    free: np.ndarray
    """1.0 for a point that moves, 0.0 for a pinned one, float64 (N,)"""
    thickness: float
    """[m]: pairs closer than twice this push apart"""
    center: np.ndarray
    """the middle of the rest layout [m], (3,): the blow-up test measures from it"""
    span: float
    """[m]: a spread of the points beyond which the run has blown up and self-collision stops looking"""
    triangles: np.ndarray
    """the cloths' triangles, int32 (T, 3): the wind acts on each"""
    order: np.ndarray
    """the model's point in each of the solver's slots, int64 (N,): the grid path
    may hold the grid's points column by column (see
    :func:`~.cloth_solver.grid_order`); the general path holds them in order"""


class Knobs(NamedTuple):
    """The live parameters as the kernels take them, made from ``Params`` each frame."""

    gravity: np.ndarray
    """[m/s²], float64 (3,)"""
    k_over_m: np.ndarray
    """each spring set's constant over the point mass [1/s²], 0 where its kind is off, float64 (6,)"""
    enabled: np.ndarray
    """which spring sets the Provot pass takes, bool (6,)"""
    keep: float
    """the share of velocity a substep keeps, 1 - damping"""
    dt2: float
    """the substep squared [s²]"""
    simulation_steps: int
    """substeps per frame: a self-collision push is divided by it"""
    self_collision: bool
    """whether pairs closer than twice the thickness push apart (a switch, not a
    variant compiled apart: the viewer turns it live)"""
    inv_mass: np.ndarray
    """one over each point's mass [1/mass unit], float64 (N,): how a force (the wind's) moves it"""


class MeshKnobs(NamedTuple):
    """The live parameters as the general path's kernels take them (see
    :mod:`.meshsprings`): per spring set (3 x cloth + kind) and per point, as
    every cloth has its own material."""

    gravity: np.ndarray
    """[m/s²], float64 (3,)"""
    k_over_m: np.ndarray
    """each set's spring constant over its cloth's point mass [1/s²], 0 where the
    kind is off, float64 (3 x cloths,)"""
    enabled: np.ndarray
    """which sets the Provot pass takes, bool (3 x cloths,)"""
    keep: np.ndarray
    """the share of velocity a substep keeps, 1 - damping of the point's cloth, float64 (N,)"""
    dt2: float
    """the substep squared [s²]"""
    simulation_steps: int
    """substeps per frame: a self-collision push is divided by it"""
    self_collision: bool
    """whether pairs closer than twice the thickness push apart"""
    inv_mass: np.ndarray
    """one over each point's mass (its cloth's) [1/mass unit], float64 (N,)"""


class Control(NamedTuple):
    """What the world imposes from outside over one frame's substeps, made anew
    each frame (:func:`.control.make_control`) from the world as it stands and moves.

    A collider kind's rows are float64 (T, K, C): slot s is substep s of the
    frame (T = 1 when nothing of the kind moves; see :mod:`.colliders.motion_rows`),
    and in a control of several frames (:func:`.control.stack_frames`) slot
    ``f * substeps + s`` is substep s of frame f.
    A field is None when the scene has none of it: numba then compiles nothing for it."""

    handle: int
    """a point held by the user's grab, or -1"""
    handle_pos: np.ndarray
    """where the held point is held [m], float64 (3,)"""
    spheres: np.ndarray | None
    """the spheres: see :mod:`.colliders.sphere`"""
    planes: np.ndarray | None
    """the planes: see :mod:`.colliders.plane`"""
    boxes: np.ndarray | None
    """the boxes: see :mod:`.colliders.box`"""
    meshes: np.ndarray | None
    """the mesh colliders' poses: see :mod:`.colliders.mesh`"""
    mesh_tris: np.ndarray | None
    """every mesh collider's triangles in its rest pose with their planes, float64
    (Ttot, 13): see :mod:`.colliders.meshgrid`"""
    mesh_grid: np.ndarray | None
    """each mesh collider's cell grid, one row per mesh: see :mod:`.colliders.mesh`"""
    mesh_cells: np.ndarray | None
    """where each cell's triangles start in ``mesh_items``, int64 (cells + 1,)"""
    mesh_items: np.ndarray | None
    """the triangles of each cell, then each mesh's cell status entries, int32"""
    mesh_slabs: np.ndarray | None
    """each cell's clear side, float64 (S, 4): see :mod:`.colliders.meshslab`"""
    mesh_prisms: np.ndarray | None
    """each triangle's clear prism, float64 (Ttot, 14): see :mod:`.colliders.meshprism`"""
    mesh_hints: np.ndarray | None
    """each point's last crossed triangle per mesh collider, or -1, int32 (K, N) (N may
    be 0: no hints): the collider kernels write it, and try it before they search; a
    guess that never changes their results (see :mod:`.colliders.mesh`)"""
    moved_points: np.ndarray | None
    """the points of every handle, int64 (H,): see :mod:`.handles`"""
    moved_to: np.ndarray | None
    """where they are at the end of each substep [m], float64 (T, H, 3)"""
    wind: np.ndarray | None
    """the wind's row for each frame (F, R) (F = 1 but in a control of several
    frames, :func:`.control.stack_frames`): see :mod:`.wind`"""


class FrameRun(NamedTuple):
    """How far one compiled call of the substep runs: ``frames`` frames of
    ``substeps`` substeps each, on a control whose moving kinds hold a slot
    for every substep of them (:class:`Control`), stopping after the first
    frame that leaves a point farther than sqrt(``limit2``) from the cloth's
    centre or not finite. One call for many
    frames spares each frame's return to Python (see :meth:`~clothsim.Simulation.step_frames`)."""

    substeps: int
    """substeps a frame (0: the call only loads the kernels)"""
    frames: int
    """frames the call runs (0: it only loads the kernels, see :meth:`~.cloth_solver.ClothSolver.load`)"""
    limit2: float
    """[m²] the squared distance from ``Points.center`` past which the run stops (inf: none)"""


class Scratch(NamedTuple):
    """Buffers the substep reuses, allocated once per model."""

    P: np.ndarray
    """positions as coordinate planes [m], float64 (3, N)"""
    L: np.ndarray
    """last positions as coordinate planes [m], float64 (3, N)"""
    F: np.ndarray
    """the grid path's spring forces of :func:`~.springs.integrate`, a buffer a part,
    (parts, 6, 3, pad + N);
    the general path's positions as rows (x, y, z, 0), (N, 4), that its springs'
    pass reads the far ends from (:func:`~.mesh_pulls.to_rows`)"""
    masks: np.ndarray
    """each part's Provot bits, uint64 (parts, 2, words): see :func:`~.provot.provot`"""
    Q: np.ndarray
    """positions after the colliders, float64 (3, N): the segments that the settle
    pass after Provot tests (only where the scene has boxes or mesh colliders)"""
    W: np.ndarray
    """the wind's forces (only where there is wind): the general path's on the
    points, float64 (3, N); the grid path's on the corners of each kind of
    triangle, (2, 3, pad + N) (see :func:`~.wind.blow_grid`)"""
