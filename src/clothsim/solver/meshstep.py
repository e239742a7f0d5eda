"""Frames of substeps of the general path (spring lists) in a single compiled call."""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .colliders import collide, has_settle, settle, settle_needs_q
from .handles import place_handles
from .mesh_pulls import pull_step, refresh_constants, to_rows
from .meshsprings import mesh_provot
from .pull_lanes import LANES
from .selfcollide import self_collide
from .shared import part_range, renamed
from .step import ADVANCE_OPTIONS, _copy_range, _farthest, _gather_planes, _hold, _scatter_planes
from .wind import blow, frame_row


def _advance_mesh(positions, last_positions, points, mesh_springs, mesh_pulls, mesh_knobs, control, lists, pairs,
                  scratch, frame_run):
    """Run the frames of ``frame_run`` (a :class:`~.groups.FrameRun`) on
    ``positions``/``last_positions`` (N, 3) [m] in place, for a model of any
    cloths: the general path's twin of :func:`~.step._advance`, with the same
    groups but ``mesh_springs`` a :class:`~.meshsprings.MeshSprings`
    and ``mesh_pulls`` a :class:`~.mesh_pulls.MeshPulls` (the springs as lists
    for Provot and as each point's slots for the forces: a group inside
    another does not reach a prange body), ``mesh_knobs`` a
    :class:`~.groups.MeshKnobs` and ``scratch.F`` (N, 4) the positions as
    rows, which the springs' pass and Provot's test read the ends from.

    Returns (largest squared distance of a point from ``points.center``, inf
    when not finite; the neighbour list's pairs array; the frames run), the
    distance taken after every frame as :func:`~.step._advance` takes it.

    Order per substep as in :func:`~.step._advance`: forces and Verlet, the
    handles and the wind, self-collision, the colliders, the Provot pass and
    the settle pass. The forces and Verlet step write the new positions into
    the last positions' planes, and the two planes then swap names: P holds
    the new positions, L those they came from. Cut into parts: the forces
    and Verlet step by ranges of eights of points, the colliders by ranges
    of points, Provot by the parts of ``mesh_springs.part_start``, each
    part's own springs at once, the springs across parts after the parts,
    on one thread. Compiled twice, as
    :func:`advance_mesh` (parts one after another) and
    :func:`advance_mesh_parallel` (parts on threads).
    """
    P, L, R = scratch.P, scratch.L, scratch.F
    free, center = points.free, points.center
    handle, handle_pos = control.handle, control.handle_pos
    enabled, simulation_steps = mesh_knobs.enabled, mesh_knobs.simulation_steps
    self_collision = mesh_knobs.self_collision
    part_start = mesh_springs.part_start
    parts = part_start.shape[0] - 2
    _gather_planes(positions, P, points.order)
    _gather_planes(last_positions, L, points.order)
    n = P.shape[1]
    eights = (n + LANES - 1) // LANES
    refresh_constants(mesh_pulls, mesh_knobs.k_over_m)
    W, Q = scratch.W, scratch.Q
    settling = has_settle(control)
    copying = settle_needs_q(control)
    substeps, frames, limit2 = frame_run.substeps, frame_run.frames, frame_run.limit2
    far2 = 0.0
    done = np.int64(0)  # not a literal: numba would compile frame_row once more for it
    while done < frames:
        for s in range(substeps):
            slot = done * substeps + s  # the control's slot: frame after frame
            for t in prange(parts):
                lo, hi = part_range(n, parts, t)
                to_rows(P, R, lo, hi)
            for t in prange(parts):
                lo, hi = part_range(eights, parts, t)
                pull_step(P, R, L, free, mesh_knobs, mesh_pulls, lo, hi)
            P, L = L, P
            if handle >= 0:
                _hold(P, handle, handle_pos)
            place_handles(P, control.moved_points, control.moved_to, slot)
            blow(P, L, points, mesh_knobs.inv_mass, mesh_knobs.dt2, frame_row(control.wind, done), W, s)
            if self_collision:
                pairs, _ = self_collide(P, points, simulation_steps, lists, pairs)
            for t in prange(parts):
                lo, hi = part_range(n, parts, t)
                collide(P, L, free, control, lo, hi, slot)
                if copying:
                    _copy_range(P, Q, lo, hi)
                to_rows(P, R, lo, hi)  # a part's own springs join its own points
                mesh_provot(P, R, mesh_springs, enabled, part_start[t], part_start[t + 1])
            mesh_provot(P, R, mesh_springs, enabled, part_start[parts], part_start[parts + 1])
            if settling:
                for t in prange(parts):
                    lo, hi = part_range(n, parts, t)
                    settle(P, Q, L, free, control, lo, hi, slot)
            if handle >= 0:
                _hold(P, handle, handle_pos)
            place_handles(P, control.moved_points, control.moved_to, slot)
        far2 = _farthest(P, center)
        done += 1
        if far2 == np.inf or not far2 <= limit2:
            break
    _scatter_planes(P, positions, points.order)
    _scatter_planes(L, last_positions, points.order)
    return far2, pairs, done


advance_mesh = njit(**ADVANCE_OPTIONS)(renamed(_advance_mesh, "advance_mesh"))
advance_mesh_parallel = njit(**ADVANCE_OPTIONS, parallel=True)(renamed(_advance_mesh, "advance_mesh_parallel"))
