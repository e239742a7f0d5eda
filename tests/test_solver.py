"""Kernels checked against the formulas they implement, on hand-built inputs."""

from __future__ import annotations

import numpy as np

from clothsim.solver.collide import PLANE_OFFSET, collide_planes, collide_spheres
from clothsim.solver.constrain import provot
from clothsim.solver.integrate import accumulate_accelerations, verlet
from clothsim.solver.self_collide import self_collide, table_size


def test_hooke_force_along_spring():
    """a spring stretched by e pulls both ends toward each other with ks*e/m"""
    pos = np.array([[0.0, 0, 0], [1.5, 0, 0]])
    acc = np.zeros_like(pos)
    accumulate_accelerations(pos, acc, np.zeros(3), np.array([0], np.int32), np.array([1], np.int32),
                             np.array([1.0]), np.array([0, 1, 1, 1]), np.array([10.0, 0, 0]))
    np.testing.assert_allclose(acc, [[5.0, 0, 0], [-5.0, 0, 0]])


def test_disabled_kind_adds_no_force():
    """k_over_m of 0 for a kind means its springs add nothing: only gravity remains"""
    pos = np.array([[0.0, 0, 0], [2.0, 0, 0]])
    acc = np.zeros_like(pos)
    accumulate_accelerations(pos, acc, np.array([0, -9.8, 0]), np.array([0], np.int32),
                             np.array([1], np.int32), np.array([1.0]), np.array([0, 0, 1, 1]),
                             np.array([10.0, 0.0, 0.0]))
    np.testing.assert_allclose(acc, [[0, -9.8, 0], [0, -9.8, 0]])


def test_verlet_formula_and_pins():
    """x' = x + (1-d)(x - x_prev) + a dt^2 for free points; pinned points untouched"""
    pos = np.array([[1.0, 2, 3], [1.0, 2, 3]])
    last = np.array([[0.5, 2, 3], [0.5, 2, 3]])
    acc = np.array([[0.0, -10, 0], [0.0, -10, 0]])
    verlet(pos, last, acc, np.array([False, True]), 0.9, 0.01)
    np.testing.assert_allclose(pos[0], [1.0 + 0.9 * 0.5, 2 - 0.1, 3])
    np.testing.assert_allclose(last[0], [1.0, 2, 3])
    np.testing.assert_array_equal(pos[1], [1.0, 2, 3])


def test_provot_independent_springs_end_at_110_percent():
    """springs sharing no point end at exactly 1.1x rest in one pass: half each, all to the free end, none if both pinned"""
    rng = np.random.default_rng(3)
    pos = rng.normal(size=(8, 3))
    a = np.array([0, 2, 4, 6], np.int32)
    b = np.array([1, 3, 5, 7], np.int32)
    rest = np.linalg.norm(pos[a] - pos[b], axis=1) / 1.6  # all stretched to 160%
    pinned = np.array([False, False, True, False, False, True, True, True])
    before = pos.copy()
    provot(pos, pinned, a, b, rest, np.array([0, 4, 4, 4]), np.array([True, True, True]))
    length = np.linalg.norm(pos[a] - pos[b], axis=1)
    np.testing.assert_allclose(length[:3] / rest[:3], 1.1, rtol=1e-12)
    assert length[3] / rest[3] == 1.6 or np.isclose(length[3] / rest[3], 1.6)  # both pinned: untouched
    for p in np.flatnonzero(pinned):
        np.testing.assert_array_equal(pos[p], before[p])
    # half each: the midpoint of a free-free spring does not move
    np.testing.assert_allclose((pos[0] + pos[1]) / 2, (before[0] + before[1]) / 2, atol=1e-12)


def test_provot_skips_disabled_kinds_and_short_springs():
    """a disabled kind and a spring under 110% are left alone"""
    pos = np.array([[0.0, 0, 0], [3.0, 0, 0], [10.0, 0, 0], [11.05, 0, 0]])
    before = pos.copy()
    provot(pos, np.zeros(4, bool), np.array([0, 2], np.int32), np.array([1, 3], np.int32),
           np.array([1.0, 1.0]), np.array([0, 1, 2, 2]), np.array([False, True, True]))
    np.testing.assert_array_equal(pos, before)


def test_sphere_pushes_to_surface_with_friction():
    """a point inside goes to last + (1-f)(surface - last), surface on the ray from the centre"""
    sphere = np.array([[0.0, 0, 0, 1.0, 0.25]])
    pos = np.array([[0.0, 0.5, 0.0]])
    last = np.array([[0.2, 1.2, 0.0]])
    collide_spheres(pos, last, np.array([False]), sphere)
    surface = np.array([0.0, 1.0, 0.0])
    np.testing.assert_allclose(pos[0], last[0] + 0.75 * (surface - last[0]))


def test_plane_puts_crossing_point_back_on_its_side():
    """a point that crossed the plane ends on its old side, PLANE_OFFSET off it (no friction)"""
    plane = np.array([[0.0, 0, 0, 0, 1, 0, 0.0]])
    pos = np.array([[0.3, -0.2, 0.1], [0.0, -0.5, 0.0]])
    last = np.array([[0.3, 0.1, 0.1], [0.0, -0.4, 0.0]])  # the second was already below: not crossing
    collide_planes(pos, last, np.zeros(2, bool), plane)
    np.testing.assert_allclose(pos[0], [0.3, PLANE_OFFSET, 0.1])
    np.testing.assert_allclose(pos[1], [0.0, -0.5, 0.0])


def test_plane_friction_one_returns_to_last():
    """with friction 1 a crossing point goes back to where it was"""
    plane = np.array([[0.0, 0, 0, 0, 1, 0, 1.0]])
    pos = np.array([[0.3, -0.2, 0.4]])
    last = np.array([[0.1, 0.1, 0.1]])
    collide_planes(pos, last, np.zeros(1, bool), plane)
    np.testing.assert_allclose(pos[0], last[0])


def _self_collide(pos, rest, thickness, cell, steps=1, pinned=None):
    n = len(pos)
    pinned = np.zeros(n, bool) if pinned is None else pinned
    return self_collide(pos, rest, pinned, thickness, cell, steps,
                        np.zeros(table_size(n) + 1, np.int64), np.zeros(n, np.int64), np.zeros((n, 3)),
                        np.zeros((n, 3)), np.zeros((n, 3), np.int64), np.zeros((n, 3)), np.zeros(n, np.int64))


def test_self_collision_pushes_pair_apart_across_cell_border():
    """two points on either side of a cell border each move to 2*thickness from the other's old place"""
    t = 0.01
    pos = np.array([[0.995, 0.5, 0.5], [1.005, 0.5, 0.5]])  # border at x = 1.0 for cell 0.1
    before = pos.copy()
    rest = np.array([[0.0, 0, 0], [5.0, 0, 0]])             # far apart at rest
    assert _self_collide(pos, rest, t, 0.1) == 1
    np.testing.assert_allclose(np.linalg.norm(pos[0] - before[1]), 2 * t, rtol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(pos[1] - before[0]), 2 * t, rtol=1e-12)


def test_self_collision_averages_and_divides_by_steps():
    """the push on a point is the mean over its colliding neighbours divided by simulation_steps"""
    t = 0.05
    pos = np.array([[0.0, 0, 0], [0.06, 0, 0], [0.0, 0.08, 0]])
    rest = np.array([[0.0, 0, 0], [10.0, 0, 0], [20.0, 0, 0]])
    before = pos.copy()
    _self_collide(pos, rest, t, 0.3, steps=4)
    expected = (np.array([-(0.1 - 0.06), 0, 0]) + np.array([0, -(0.1 - 0.08), 0])) / 2 / 4
    np.testing.assert_allclose(pos[0] - before[0], expected, atol=1e-12)


def test_self_collision_ignores_pairs_close_at_rest():
    """neighbours already closer than 2*thickness at rest are not pushed apart"""
    pos = np.array([[0.0, 0, 0], [0.01, 0, 0]])
    rest = pos.copy()
    before = pos.copy()
    assert _self_collide(pos, rest, 0.0095, 0.03) == 0
    np.testing.assert_array_equal(pos, before)


def test_self_collision_matches_brute_force():
    """the hash finds exactly the pairs a brute-force search finds, for random clouds"""
    rng = np.random.default_rng(7)
    pos = rng.uniform(0, 0.3, size=(400, 3))
    rest = rng.uniform(0, 100, size=(400, 3))
    d = np.linalg.norm(pos[:, None] - pos[None], axis=2)
    expected = int((np.triu(d < 0.04, 1)).sum())
    assert _self_collide(pos.copy(), rest, 0.02, 0.06) == expected
    assert _self_collide(pos.copy(), rest, 0.02, 0.013) == expected  # cells smaller than the reach
