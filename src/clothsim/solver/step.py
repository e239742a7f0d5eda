"""Frames of substeps in a single compiled call, and the order of a substep's stages."""

from __future__ import annotations

import numba
import numpy as np
from numba import njit, prange

from .colliders import collide, has_settle, settle, settle_needs_q
from .handles import place_handles
from .wind import blow_grid, frame_row
from .provot import provot
from .springs import AHEAD_STEP, integrate
from .selfcollide import self_collide
from .shared import renamed

PARALLEL_MIN_POINTS = 5000
"""cloths with fewer points run on one thread unless asked: each parallel
region costs time to start, which a small cloth's substep barely repays
(figures: docs/performance.md, 'Threads')"""


def parts_for(num_points: int, threads: int | None = None) -> int:
    """How many parts a cloth's substep is cut into: ``threads``, or by default
    numba's thread count for cloths of PARALLEL_MIN_POINTS points and more."""
    if threads is None:
        return 1 if num_points < PARALLEL_MIN_POINTS else int(numba.get_num_threads())
    if threads < 1:
        raise ValueError(f"threads must be at least 1, not {threads}")
    return int(threads)


@njit(cache=True, boundscheck=False)
def _farthest(P, center):
    """Largest squared distance from ``center``; inf if any coordinate is not finite.
    Compiled without fastmath, which would let LLVM assume the check away."""
    worst = 0.0
    for p in range(P.shape[1]):
        dx = P[0, p] - center[0]
        dy = P[1, p] - center[1]
        dz = P[2, p] - center[2]
        d2 = dx * dx + dy * dy + dz * dz
        if not np.isfinite(d2):
            return np.inf
        if d2 > worst:
            worst = d2
    return worst


@njit(cache=True, boundscheck=False)
def _gather_planes(pos, P, order):
    """(N, 3) positions into (3, N) planes, slot k taking point ``order[k]``: the
    kernels' layout, in the solver's slots (``Points.order``; the identity but
    on a grid held column by column, see :func:`~.cloth_solver.grid_order`)"""
    for k in range(order.shape[0]):
        p = order[k]
        for c in range(3):
            P[c, k] = pos[p, c]


@njit(cache=True, boundscheck=False)
def _scatter_planes(P, pos, order):
    """the planes back into (N, 3) positions: :func:`_gather_planes` undone"""
    for k in range(order.shape[0]):
        p = order[k]
        for c in range(3):
            pos[p, c] = P[c, k]


def _advance(positions, last_positions, points, springs, knobs, control, lists, pairs, scratch, frame_run):
    """Run the frames of ``frame_run`` (a :class:`~.groups.FrameRun`) on
    ``positions``/``last_positions`` (N, 3) [m] in place.

    The groups: ``points`` (:class:`~.groups.Points`), ``springs``
    (:class:`~.springs.GridSprings`), ``knobs`` (:class:`~.groups.Knobs`),
    ``control`` (:class:`~.groups.Control`), ``lists`` the
    :class:`~.selfcollide.NeighbourList` (used while ``knobs.self_collision``),
    ``pairs`` its list of pairs now, and ``scratch`` (:class:`~.groups.Scratch`).

    Returns (largest squared distance of a point from ``points.center``
    afterwards, inf when the state is no longer finite; the pairs array of
    the neighbour list, a new one after each build; the frames run). The
    distance is taken after every frame, and the call stops after the first
    frame that puts it past ``frame_run.limit2`` (or makes it inf): a blow-up is
    caught at the frame it happens, as one call a frame would catch it.

    Order per substep, as in the CS184 course code: forces and Verlet,
    self-collision, the colliders, then the Provot pass; clothsim's own stages
    fit between: the handles and the wind after Verlet, and where the scene
    has spheres, boxes or mesh colliders a settle pass after Provot (see
    :mod:`.colliders`). ``control.handle`` (or -1) is a point held at
    ``control.handle_pos`` by the user's grab: it moves kinematically.

    The substep is cut into as many parts as ``scratch.masks`` has: ranges
    of points, each moved, collided and constrained by one part; the Provot
    pass then takes the springs across the cuts. The Verlet step writes the
    new positions over the last ones and P and L then swap (see
    :func:`~.springs.integrate`): every part reads positions that no part
    writes, each with a force buffer of its own (``scratch.F[t]``), so no
    thread waits on another's forces and none moves points after the parts.
    This body is compiled twice: as :func:`advance`, which runs the parts
    one after another (one part: the whole cloth), and as
    :func:`advance_parallel`, where each ``prange`` hands them to threads.
    """
    P, L, F, masks = scratch.P, scratch.L, scratch.F, scratch.masks
    free, center = points.free, points.center
    handle, handle_pos = control.handle, control.handle_pos
    enabled, simulation_steps, self_collision = knobs.enabled, knobs.simulation_steps, knobs.self_collision
    ahead = springs.ahead
    cols = springs.end[1]  # set 1 joins each point to the one a row down
    parts = masks.shape[0]
    # the grid path's slots may hold the points column by column (points.order)
    _gather_planes(positions, P, points.order)
    _gather_planes(last_positions, L, points.order)
    n = P.shape[1]
    # every call takes its ranges as variables, never as constants: numba
    # compiles a kernel once per distinct literal argument, and the first run
    # of a scene paid for each. Provot's switch is the exception: compiled for
    # each value, its pass ran faster
    W, Q = scratch.W, scratch.Q
    settling = has_settle(control)
    copying = settle_needs_q(control)
    substeps, frames, limit2 = frame_run.substeps, frame_run.frames, frame_run.limit2
    far2 = 0.0
    done = np.int64(0)  # not a literal: numba would compile frame_row once more for it
    while done < frames:
        for s in range(substeps):
            slot = done * substeps + s  # the control's slot: frame after frame
            # a part's first points gather the forces of the part before's last
            # springs: each part works those out too, from positions no part writes
            for t in prange(parts):
                lo, hi = _part_span(n, parts, t, ahead)
                integrate(P, L, free, knobs, springs, F[t], max(lo - ahead, 0), hi, lo)
            P, L = L, P  # the new positions were written over the last ones
            if handle >= 0:
                _hold(P, handle, handle_pos)
            place_handles(P, control.moved_points, control.moved_to, slot)
            blow_grid(P, L, free, springs.valid[0], knobs.inv_mass, knobs.dt2, frame_row(control.wind, done), W, s,
                      cols)
            if self_collision:
                pairs, _ = self_collide(P, points, simulation_steps, lists, pairs)
            for t in prange(parts):
                lo, hi = _part_span(n, parts, t, ahead)
                collide(P, L, free, control, lo, hi, slot)
                if copying:
                    _copy_range(P, Q, lo, hi)
                provot(P, springs, enabled, masks[t], lo, hi, False)
            for t in range(1, parts):
                lo, _ = _part_span(n, parts, t, ahead)
                provot(P, springs, enabled, masks[0], lo, lo, True)
            if settling:
                for t in prange(parts):
                    lo, hi = _part_span(n, parts, t, ahead)
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


ADVANCE_OPTIONS = dict(cache=True, boundscheck=False, error_model="numpy", nogil=True)
"""nogil: a frame's substeps release the GIL, so a writer's thread (an exporter
loading its library, say) runs beside them"""
advance = njit(**ADVANCE_OPTIONS)(renamed(_advance, "advance"))
advance_parallel = njit(**ADVANCE_OPTIONS, parallel=True)(renamed(_advance, "advance_parallel"))


@njit(cache=True, inline="always")
def _part_span(n, parts, t, lead):
    """Points ``lo:hi`` of part t of ``parts``, cut at multiples of AHEAD_STEP (a
    part's force pass starts on a whole eight, see :func:`~.springs.integrate`).
    Every part after the first also works out the forces of the ``lead``
    springs before its range: the first takes ``lead`` points more than the
    others, so that each part's springs take about as long."""
    return _cut(n, parts, t, lead), _cut(n, parts, t + 1, lead)


@njit(cache=True, inline="always")
def _cut(n, parts, c, lead):
    """Where part c of :func:`_part_span` starts (``n`` for c = ``parts``): each part
    ``share - lead`` points after the first's ``share``, at most n."""
    if c == 0:
        return 0
    if c == parts:
        return n
    share = (n + (parts - 1) * lead) // parts
    return min((c * share - (c - 1) * lead) // AHEAD_STEP * AHEAD_STEP, n)


@njit(cache=True, inline="always")
def _copy_range(P, Q, lo, hi):
    for c in range(3):
        for p in range(lo, hi):
            Q[c, p] = P[c, p]


@njit(cache=True, inline="always")
def _hold(P, handle, target):
    P[0, handle] = target[0]
    P[1, handle] = target[1]
    P[2, handle] = target[2]
