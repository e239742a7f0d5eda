"""The box's collision pass (clothsim.solver.colliders.box) against the exact
geometry: random boxes along the world's axes or turned, still or sliding,
thin or thick, and random segments, among them fast ones that go right
through the box. Both of the vector pass's loops and the scalar pass are
reached: an aligned box, still or sliding, takes one loop, any other box the
other (still, its references turned only where a run's rule runs; moving,
carried and turned everywhere)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit

from clothsim.motion import Animation, Keyframe, rotation_matrices
from clothsim.solver.colliders import box

N = 96


TURNS = ("none", "about y", "any")
"""a box's own rotation: none, about the vertical alone (the lanes then take the
maps of a turn about y, lanes.YAW_MAP), or about all three axes"""

MOTIONS = ("still", "sliding", "turning about y", "turning")
"""a box's motion over the frame's one substep: none; 5 cm along x (the carry's
turn is the identity); the same slide with a 10° turn about y; with a turn about
all three axes"""


def _scene(seed: int, turned, sliding):
    """(box, local frame, reference and end positions (3, N) [m], free weights);
    ``turned`` one of TURNS (a bool: "any" or "none"), ``sliding`` one of MOTIONS
    (a bool: "sliding" or "still")"""
    turned = {True: "any", False: "none"}.get(turned, turned)
    sliding = {True: "sliding", False: "still"}.get(sliding, sliding)
    rng = np.random.default_rng(seed)
    center = rng.uniform(-1.0, 1.0, 3)
    size = rng.choice([0.002, 0.05, 0.4, 1.0], 3)
    rotate = {"none": (0.0, 0.0, 0.0), "about y": (0.0, rng.uniform(-90.0, 90.0), 0.0),
              "any": tuple(rng.uniform(-90.0, 90.0, 3))}[turned]
    turn = {"still": None, "sliding": (0.0, 0.0, 0.0), "turning about y": (0.0, 10.0, 0.0),
            "turning": (4.0, 10.0, -6.0)}[sliding]
    animation = None if turn is None else Animation((Keyframe(0.0), Keyframe(1.0, (0.05, 0.0, 0.0), turn)))
    b = SimpleNamespace(center=center, size=size, rotate=rotate, friction=0.0, margin=1e-3, animation=animation)
    M = rotation_matrices(rotate)
    half = size / 2
    # starts outside the box on a random side, ends: inside, through to the far side, or anywhere
    start = rng.uniform(-1.0, 1.0, (N, 3)) * (half + 0.3)
    axis = rng.integers(0, 3, N)
    side = rng.choice([-1.0, 1.0], N)
    start[np.arange(N), axis] = side * (half[axis] + rng.uniform(1e-4, 0.3, N))
    end = np.empty_like(start)
    kind = rng.integers(0, 3, N)
    end[kind == 0] = rng.uniform(-0.99, 0.99, ((kind == 0).sum(), 3)) * half
    through = kind == 1
    end[through] = start[through] * rng.uniform(0.0, 0.9, (through.sum(), 3))
    end[through, axis[through]] = -side[through] * (half[axis[through]] + rng.uniform(1e-4, 0.2, through.sum()))
    end[kind == 2] = rng.uniform(-1.0, 1.0, ((kind == 2).sum(), 3)) * (half + 0.3)
    # the world's positions: a local point's world place is centre + M @ local
    world = lambda local: (center + local @ M.T).T.copy()  # noqa: E731
    free = np.ones(N)
    free[rng.random(N) < 0.1] = 0.0
    return b, M, world(start), world(end), free


def _entry(l0: np.ndarray, l1: np.ndarray, half: np.ndarray):
    """(entered, axis, clear) per segment l0 -> l1 in the box's frame: whether it
    meets the box, the axis of the face it enters through, and whether that is
    clear by more than rounding (not through an edge, nor grazing)"""
    d = l1 - l0
    d = np.where(np.abs(d) > 1e-300, d, 1e-300)
    ta, tb = (-half - l0) / d, (half - l0) / d
    lo, hi = np.minimum(ta, tb), np.maximum(ta, tb)
    t_in, t_out = lo.max(axis=1), hi.min(axis=1)
    entered = (t_in <= t_out) & (t_in <= 1.0) & (t_in >= 0.0)
    second = np.sort(lo, axis=1)[:, 1]
    clear = (t_out - t_in > 1e-6) & (t_in - second > 1e-6) & (t_in < 1.0 - 1e-6)
    return entered, lo.argmax(axis=1), clear


def _carried(rows: np.ndarray, R: np.ndarray) -> np.ndarray:
    """the references (3, N) carried by the box's motion over the substep (its carry map)"""
    a = np.array(box.carry_of(rows[0, 0], box.COLUMNS))
    return a[:9].reshape(3, 3) @ R + a[9:, None]


@settings(max_examples=80, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), turned=st.sampled_from(TURNS), sliding=st.sampled_from(MOTIONS))
def test_no_point_ends_inside_and_a_point_that_entered_stays_on_its_side(seed, turned, sliding):
    b, M, R, P, free = _scene(seed, turned, sliding)
    rows = box.pack([b], 0.0, 1.0, 1)
    out = P.copy()
    box.collide_boxes(out, R, free, rows, 0, N, 0)
    carried = _carried(rows, R)  # the reference positions ride along with the box
    M = rows[0, 0, 3:12].reshape(3, 3)  # the box's axes at the substep's end
    center = rows[0, 0, :3]
    half = b.size / 2
    l0 = (carried.T - center) @ M
    l1 = (P.T - center) @ M
    lf = (out.T - center) @ M
    pinned = free == 0.0
    assert np.array_equal(out[:, pinned], P[:, pinned])
    inside = np.all(np.abs(lf) < half, axis=1)
    assert not inside[~pinned].any()
    entered, axis, clear = _entry(l0, l1, half)
    missed = ~entered & ~np.all(np.abs(l1) < half + 1e-9, axis=1) & (np.abs(l1 - l0).max(axis=1) > 0)
    # a segment that misses the box leaves its point where it is, to the bit
    assert np.array_equal(out[:, missed], P[:, missed])
    # one that entered through a face and ended inside, or went right through the
    # box (a move longer than its thinnest side: only such a move can), however
    # fast, ends on that face's side of the box. A shorter move that clips an
    # edge and leaves through another face is not looked for (as deep as half
    # the move at most, and a cloth's points move far less than a box's side)
    ended_inside = np.all(np.abs(l1) < half, axis=1)
    long = ((l1 - l0) ** 2).sum(axis=1) >= 4 * half.min() ** 2 * (1 + 1e-9)
    k = np.flatnonzero(entered & clear & ~pinned & (ended_inside | long))
    a = axis[k]
    assert (np.sign(lf[k, a]) == np.sign(l0[k, a])).all()
    assert (np.abs(lf[k, a]) >= half[a] - 1e-12).all()
    assert (entered & clear & ~pinned).sum() + missed.sum() > 0


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), turned=st.sampled_from(TURNS), sliding=st.sampled_from(MOTIONS),
       friction=st.floats(0.0, 1.0))
def test_a_run_at_a_time_as_one_by_one(seed, turned, sliding, friction):
    """The pass takes the points a run at a time (four or eight, box_lanes) in
    vector code written by hand and the few left over one by one in numba's: both place every
    point alike (the one-by-one run of each point goes through its own pass, a
    single point long). A box along the world's axes, to the bit; a turned or
    moving one within rounding, as fast-math lets LLVM fuse the turns' sums
    differently in a vector and in a lone point's code."""
    b, M, R, P, free = _scene(seed, turned, sliding)
    b.friction = friction
    rows = box.pack([b], 0.0, 1.0, 1)
    runs = P.copy()
    box.collide_boxes(runs, R, free, rows, 0, N, 0)
    ones = P.copy()
    for p in range(N):
        box.collide_boxes(ones, R, free, rows, p, p + 1, 0)
    if turned != "none" or sliding != "still":
        assert np.abs(runs - ones).max() < 1e-12
    else:
        assert np.array_equal(runs, ones)


def test_the_settle_pass_of_a_turning_sliding_box_puts_points_back_where_the_colliders_left_them():
    """the settle pass tests a point's move from where the colliders left it (Q,
    in the box's pose at the end of the substep) to where a later pass put it
    (P): both are of the same moment, so Q is not carried by the box's motion.
    A point that the later pass pushed a little into a box that slides 5 cm
    and turns 10° over the substep goes back to Q, in the runs of the vector
    pass as in the pass of a single point (which the scalar code takes)"""
    motion = Animation((Keyframe(0.0), Keyframe(1.0, (0.05, 0.0, 0.0), (0.0, 10.0, 0.0))))
    b = SimpleNamespace(center=np.array([0.2, 0.3, -0.1]), size=np.array([0.6, 0.2, 0.6]), rotate=(0.0, 15.0, 0.0),
                        friction=0.3, margin=1e-3, animation=motion)
    rows = box.pack([b], 0.0, 1.0, 1)
    row = rows[0, 0]
    R, center = row[3:12].reshape(3, 3), row[:3]
    rng = np.random.default_rng(11)
    n = 8 * 8
    # on the top face of the box in its pose at the end of the substep: Q just
    # above it, P pushed 1-5 mm below it
    local = np.column_stack([rng.uniform(-0.25, 0.25, n), np.full(n, 0.1 + 2e-3), rng.uniform(-0.25, 0.25, n)])
    Q = (center + local @ R.T).T.copy()
    pushed = local - np.column_stack([np.zeros(n), rng.uniform(3e-3, 7e-3, n), np.zeros(n)])
    P0 = (center + pushed @ R.T).T.copy()
    free = np.ones(n)
    runs = P0.copy()
    box.settle_boxes(runs, Q, free, rows, 0, n, 0)
    ones = P0.copy()
    for p in range(n):
        box.settle_boxes(ones, Q, free, rows, p, p + 1, 0)
    np.testing.assert_allclose(runs, Q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(ones, Q, rtol=0, atol=1e-12)


def test_points_by_a_turned_box_that_moved_about_its_thinnest_side_are_marked_as_one_by_one():
    """points around a box, none inside, most having moved little, a few just
    past the box's thinnest side (they may have gone through it: marked) or just
    short of it (not marked): for a still box turned on all three axes, whose
    runs take the move's length in the world's frame and turn the references
    only where a run's rule runs, for the same box sliding and turning, whose
    runs turn every reference, for a box along the world's axes and the
    turned one that only slide, whose runs test the move from the references
    carried by the slide alone, and for a box turned about y alone, still,
    turning about y and sliding, whose runs take the maps of a turn about y,
    the runs mark the same points as the pass of a single point, and move
    none"""
    rng = np.random.default_rng(7)
    size = np.array([0.6, 0.2, 0.5])
    turned = (12.0, 35.0, -20.0)
    turning = Animation((Keyframe(0.0), Keyframe(1.0, (0.05, 0.0, 0.0), (3.0, 10.0, 0.0))))
    sliding = Animation((Keyframe(0.0), Keyframe(1.0, (0.05, -0.02, 0.03))))
    yawing = Animation((Keyframe(0.0), Keyframe(1.0, (0.05, 0.0, 0.0), (0.0, 10.0, 0.0))))
    about_y = (0.0, 35.0, 0.0)  # the runs take the maps of a turn about y
    for rotate, animation in ((turned, None), (turned, turning), ((0.0, 0.0, 0.0), sliding), (turned, sliding),
                              (about_y, None), (about_y, yawing), (about_y, sliding)):
        b = SimpleNamespace(center=np.array([0.1, 0.4, -0.2]), size=size, rotate=rotate, friction=0.5,
                            margin=1e-3, animation=animation)
        rows = box.pack([b], 0.0, 1.0, 1)
        row = rows[0, 0]
        a = box.carry_of(row, box.COLUMNS)
        A, t = np.array(a[:9]).reshape(3, 3), np.array(a[9:])
        n = 40 * 8
        # the ends on a shell well outside the box (its half diagonal is 0.41 m)
        ways = rng.normal(size=(n, 3))
        now = row[:3] + rng.uniform(0.5, 1.0, (n, 1)) * ways / np.linalg.norm(ways, axis=1)[:, None]
        gap = np.full(n, 0.1 * size.min())
        past = np.arange(3, n, 19)
        short = np.setdiff1d(np.arange(7, n, 31), past)
        gap[past] = size.min() * (1.0 + 1e-9)
        gap[short] = size.min() * (1.0 - 1e-9)
        ways = rng.normal(size=(n, 3))
        carried = now - gap[:, None] * ways / np.linalg.norm(ways, axis=1)[:, None]
        refs = np.ascontiguousarray(np.linalg.solve(A, (carried - t).T))
        P = np.ascontiguousarray(now.T)
        free = np.ones(n)
        moving = animation is not None
        runs = np.zeros(n, dtype=np.bool_)
        aligned = rotate == (0.0, 0.0, 0.0)
        count = box._common(P, refs, free, row, 0, runs, moving, True, aligned)
        ones = np.zeros(n, dtype=np.bool_)
        for p in range(n):
            box._common(P, refs, free, row, p, ones[p:p + 1], moving, True, aligned)
        expected = np.zeros(n, dtype=np.bool_)
        expected[past] = True
        np.testing.assert_array_equal(runs, expected)
        np.testing.assert_array_equal(ones, expected)
        assert count == len(past)
        np.testing.assert_array_equal(P, now.T)


@njit(cache=True)
def _runs_both_ways(P, R, free, row, a, shift, width):
    """The turned box's runs over P (3, n), n a multiple of ``width``, from
    references R, once with the maps of 12 numbers (on a copy of P) and once
    with those of a turn about y (on P itself). Returns (the copy as the
    first placed it, its marks, their count, the second's marks, their
    count)"""
    n = P.shape[1]
    box_ = (row[0], row[1], row[2], row[3], row[4], row[5], row[6], row[7], row[8], row[9], row[10], row[11],
            row[12], row[13], row[14], 1.0 - row[15], row[16])
    ref, end, back = box._frame_maps(box_, box._STAY if a is None else a)
    hu, hv, hw, margin = row[12], row[13], row[14], row[16]
    lanes_box = (0.0, 0.0, 0.0, hu, hv, hw, -(hu + margin), hu + margin, -(hv + margin), hv + margin,
                 -(hw + margin), hw + margin, 1.0 - row[15], box._thinnest2(box_))
    planes, refs = (P[0], P[1], P[2]), (R[0], R[1], R[2])
    first = np.copy(P)
    marks12 = np.zeros(n, np.bool_)
    count12 = box._turned_runs((first[0], first[1], first[2]), refs, free, marks12, lanes_box, (ref, end, back), a,
                               shift, n, width)
    marks7 = np.zeros(n, np.bool_)
    count7 = box._turned_runs(planes, refs, free, marks7, lanes_box,
                              (box.yaw_map(ref), box.yaw_map(end), box.yaw_map(back)), a, shift, n, width)
    return first, marks12, count12, marks7, count7


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), sliding=st.sampled_from(MOTIONS[:3]), friction=st.floats(0.0, 1.0))
def test_a_box_turned_about_y_places_alike_with_the_maps_of_a_turn_about_y(seed, sliding, friction):
    """a box turned about y, still, sliding or turning about y: its runs take the
    maps of seven numbers (the zero terms of the twelve left out), and mark
    every point as the maps of twelve do, and place it within rounding (the
    terms left out are exact zeros, but fast-math lets LLVM fuse the sums that
    are left otherwise than in the maps of twelve: a point in some hundreds
    lands an ulp away)"""
    b, _, R, P, free = _scene(seed, "about y", sliding)
    b.friction = friction
    rows = box.pack([b], 0.0, 1.0, 1)
    row = rows[0, 0]
    a = None if sliding == "still" else box.carry_of(row, box.COLUMNS)
    assert box.turns_about_y(row[3:12]) and (a is None or box.turns_about_y(a))
    shift = (a[9], a[10], a[11]) if sliding == "sliding" else None
    width = box.STILL_LANES if a is None or shift is not None else box.TURNED_LANES
    first, marks12, count12, marks7, count7 = _runs_both_ways(P, R, free, row, a, shift, width)
    assert np.array_equal(marks12, marks7) and count12 == count7
    np.testing.assert_allclose(P, first, rtol=0, atol=1e-15)
    assert count7 > 0 or not np.array_equal(P, _scene(seed, "about y", sliding)[3])
