"""The moving sphere's screen: the carry of a point's last position is made only
where the point may need it (``sphere.carry_screen``), and the result is the
same as making it everywhere."""

from __future__ import annotations

import types

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from clothsim.motion import Animation, Keyframe
from clothsim.solver.colliders import sphere


def rotation(axis, angle):
    """the rotation matrix of ``angle`` [rad] about ``axis`` (Rodrigues)"""
    k = np.asarray(axis, dtype=float)
    k = k / np.linalg.norm(k)
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * K @ K


def unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


vectors = st.tuples(*[st.floats(-1.0, 1.0)] * 3).filter(lambda v: np.linalg.norm(v) > 1e-3)


@settings(max_examples=300, deadline=None)
@given(centre=vectors, radius=st.floats(0.01, 2.0), axis=vectors, angle=st.floats(0.0, 0.3),
       pivot=vectors, shift=vectors, shift_len=st.floats(0.0, 0.05), where=vectors,
       reach_part=st.floats(0.0, 1.0), way=vectors, move_part=st.floats(0.0, 1.0))
def test_a_point_the_screen_vouches_for_is_within_far_of_its_carried_last_position(
        centre, radius, axis, angle, pivot, shift, shift_len, where, reach_part, way, move_part):
    """a point at most sqrt(reach2) from the centre that moved at most sqrt(move2)
    from its last position is within sqrt(far2) of that position carried by
    the sphere's turn and slide, the far test's bound: taken at the edges of
    both bounds, in any direction, for turns about any pivot"""
    c = np.array(centre)
    A = rotation(axis, angle)
    q = np.array(pivot)
    t = q - A @ q + shift_len * unit(shift)
    a = tuple(A.ravel()) + tuple(t)
    row = np.concatenate([c, [radius]])
    far2 = sphere._far2(radius)[1]
    reach2, move2 = sphere.carry_screen(a, row, far2)
    if move2 < 0.0:
        return  # the screen vouches for no point: every call makes the carry
    p = c + np.sqrt(reach2) * reach_part * unit(where)
    last = p - np.sqrt(move2) * move_part * unit(way)
    m = A @ last + t
    assert np.sum((p - m) ** 2) <= far2


@settings(max_examples=200, deadline=None)
@given(radius=st.floats(0.05, 2.0), axis=vectors, angle=st.floats(1e-4, 0.3), slide_part=st.floats(0.0, 0.7),
       plane_dir=vectors)
def test_the_screen_holds_where_every_term_of_its_bound_points_one_way(radius, axis, angle, slide_part, plane_dir):
    """the worst case of the bound, built: a turn about the centre, the point at the
    screen's reach in the plane of the turn, the slide and the point's own move
    both along the way the turn moves it. Its carried last position is then
    farther from it by the sum of the three terms, and still within sqrt(far2);
    a screen a fifth more generous in either bound fails here"""
    c = np.array([0.3, -0.2, 0.1])
    k = unit(axis)
    A = rotation(k, angle)
    far2 = sphere._far2(radius)[1]
    big = np.sqrt(far2)
    inplane = np.cross(k, unit(plane_dir))
    if np.linalg.norm(inplane) < 1e-3:
        return
    inplane = unit(inplane)
    # the direction the turn moves a point at inplane from the centre
    w = unit((np.eye(3) - A) @ inplane)
    s = -slide_part * big * w  # the slide: (A - I)c + t = s for a turn about c
    t = c - A @ c + s
    a = tuple(A.ravel()) + tuple(t)
    reach2, move2 = sphere.carry_screen(a, np.concatenate([c, [radius]]), far2)
    assert move2 > 0.0  # a slide under 3F/4 leaves room
    p = c + np.sqrt(reach2) * inplane
    last = p - np.sqrt(move2) * (A.T @ w)
    m = A @ last + t
    along = (p - m) @ w
    assert np.sum((p - m) ** 2) <= far2
    # the three terms do point one way: the case is the bound's worst
    turn = np.linalg.norm((np.eye(3) - A) @ (p - c))
    assert along == pytest.approx(turn + np.sqrt(move2) + slide_part * big, rel=1e-9)


def test_the_screen_vouches_for_the_cloth_about_a_spinning_sphere():
    """for a sphere that turns a full turn in 4 s (the ``spinning_sphere`` scene's)
    at 30 substeps a frame of 1/90 s, the screen covers every point within 10 m
    that moved less than a centimetre: the carry is skipped where it can be"""
    spin = Animation((Keyframe(0.0), Keyframe(4.0, rotate=(0.0, 360.0, 0.0))), loop=True)
    spec = types.SimpleNamespace(origin=(0.0, 0.0, 0.0), radius=0.5, friction=1.0, animation=spin)
    row = sphere.pack([spec], 1.0, 1.0 / 2700, 30)[3, 0]
    far2 = sphere._far2(0.5)[1]
    reach2, move2 = sphere.carry_screen(sphere.carry_of(row, 5), row, far2)
    assert reach2 > 10.0 ** 2 and move2 > 0.01 ** 2


def planes(points):
    return np.ascontiguousarray(np.asarray(points, dtype=float).T)


def test_points_off_a_fast_turning_sphere_are_counted_and_left_as_one_by_one():
    """points around a sphere that turns and slides fast, none inside it, some
    runs all moved little, others holding a point that moved just past the far
    bound or just short of it: the loop of vector calls, with its screen,
    counts the same fast points as the loop taken a point at a time (each of
    which makes its carry), and writes none; with a slide so fast that the
    screen vouches for nothing, the same"""
    rng = np.random.default_rng(3)
    c, r = np.array([0.0, 0.5, 0.0]), 0.3
    far2 = sphere._far2(r)[1]
    for degrees, slide, expect_screen in ((30.0, 0.2, True), (3000.0, 3.0, False)):
        spin = Animation((Keyframe(0.0), Keyframe(0.5, translate=(slide, 0.0, 0.0), rotate=(0.0, degrees, 10.0))))
        spec = types.SimpleNamespace(origin=tuple(c), radius=r, friction=0.5, animation=spin)
        row = sphere.pack([spec], 0.1, 0.01, 4)[2, 0]
        a = sphere.carry_of(row, 5)
        assert (sphere.carry_screen(a, row, far2)[1] > 0.0) == expect_screen
        n = 64 * sphere.LANES
        out = unit(rng.normal(size=3))
        now = c + (r + rng.uniform(0.01, 0.5, (n, 1))) * np.array([unit(v) for v in rng.normal(size=(n, 3))])
        now[:, 1] = np.maximum(now[:, 1], c[1] + r + 0.01)  # all above the sphere, outside it
        A = np.array(a[:9]).reshape(3, 3)
        t = np.array(a[9:])
        # last positions such that the carried one lies a chosen distance from now
        gap = np.full(n, 0.1) * np.sqrt(far2)
        past = np.arange(5, n, 23)
        short = np.setdiff1d(np.arange(9, n, 29), past)
        gap[past] = np.sqrt(far2) * (1.0 + 1e-9)  # just past: fast
        gap[short] = np.sqrt(far2) * (1.0 - 1e-9)  # just short: not fast
        carried = now - gap[:, None] * out
        last = np.linalg.solve(A, (carried - t).T).T
        free = np.ones(n)
        P, L = planes(now), planes(last)
        fast = sphere._carried_rule(P[0], P[1], P[2], L[0], L[1], L[2], free, row, far2)
        ones, fast_ones = planes(now), 0
        for p in range(n):
            fast_ones += sphere._carried_rule(ones[0, p:p + 1], ones[1, p:p + 1], ones[2, p:p + 1], L[0, p:],
                                              L[1, p:], L[2, p:], free[p:], row, far2)
        u = P - (A @ L + t[:, None])
        expected = int((np.sum(u * u, axis=0) > far2).sum())
        assert expected == len(past)  # a gap of 1e-9 F is far past rounding
        assert fast == fast_ones == expected
        np.testing.assert_array_equal(P, planes(now))
        np.testing.assert_array_equal(ones, planes(now))
