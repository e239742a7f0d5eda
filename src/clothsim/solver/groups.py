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

from .colliders import pack_colliders


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


class Control(NamedTuple):
    """What the world imposes from outside, read every substep and changed between frames."""

    handle: int
    """a point held by the user's grab, or -1"""
    handle_pos: np.ndarray
    """where the held point is held [m], float64 (3,)"""
    spheres: np.ndarray | None
    """the spheres as they stand now, (cx, cy, cz, r, friction) rows (K, 5), or None:
    see :mod:`.colliders.sphere`"""
    planes: np.ndarray | None
    """the planes as they stand now, (px, py, pz, nx, ny, nz, friction) rows (K, 7),
    or None: see :mod:`.colliders.plane`"""

    @classmethod
    def of(cls, handle: int, handle_pos, spheres, planes) -> Control:
        """The group from the held point and the scene's collider objects."""
        return cls(handle=int(handle), handle_pos=np.asarray(handle_pos, dtype=np.float64),
                   **pack_colliders(spheres, planes))


class Scratch(NamedTuple):
    """Buffers the substep reuses, allocated once per model."""

    P: np.ndarray
    """positions as coordinate planes [m], float64 (3, N)"""
    L: np.ndarray
    """last positions as coordinate planes [m], float64 (3, N)"""
    F: np.ndarray
    """the grid path's spring forces of :func:`~.springs.integrate`, (6, 3, pad + N);
    the general path's accelerations of the points, (3, N)"""
    masks: np.ndarray
    """each part's Provot bits, uint64 (parts, 2, words): see :func:`~.provot.provot`"""
