"""Collisions hold at any substep count: no point ends inside a sphere or behind
a plane, whatever ``simulation_steps`` and however fast the cloth falls.

At the standard scenes' own 30 substeps a point moves well under a millimetre
per substep and the course's radial rule for spheres is all there is; at a few
substeps, or under high gravity, a point crosses much of the sphere in one
substep (and, before this rule, ended up to 19 cm inside it or fell through),
and Provot's pass pulls points a few millimetres in. The sphere collider then
tests the segment from the last position, and the settle pass after Provot
takes out anything deeper than SPHERE_SETTLE (see docs/physics.md).
"""

from __future__ import annotations

import types

import numpy as np
import pytest

from clothsim import Simulation
from clothsim.solver.colliders import SPHERE_SETTLE, collide_spheres
from clothsim.solver.colliders.sphere import SPHERE_OFFSET, pack, settle_spheres

from .conftest import SCENES

PATHS = [(1, "auto"), (2, "auto"), (1, "mesh")]
"""(threads, solver path): serial, cut in two, the general path"""


@pytest.fixture(params=PATHS, ids=["serial", "threads2", "mesh"])
def path(request):
    return request.param


def deepest_at_frame_ends(sim: Simulation, seconds: float) -> float:
    """the largest depth of any point inside the scene's sphere at the end of
    any frame of ``seconds`` [m] (negative: all outside)"""
    s = sim.spheres[0]
    worst = [-np.inf]

    def look(sim):
        depth = s.radius - np.linalg.norm(sim.positions - np.asarray(s.origin), axis=1)
        worst[0] = max(worst[0], depth.max())

    sim.run(seconds, look)
    return worst[0]


# the standard cloth's ks of 5000 at one or two substeps a frame (11 and 5.6 ms)
# is past Verlet's limit for its springs: on some paths the cloth blows up there
# whatever the collider does (on the sphere after 0.4 s), so those cases run
# with a softer cloth
SOFT_1, SOFT_2 = "cloth.ks=500", "cloth.ks=2000"
CASES = {"1 substep": ["simulation.simulation_steps=1", SOFT_1],
         "2 substeps": ["simulation.simulation_steps=2", SOFT_2],
         "3 substeps": ["simulation.simulation_steps=3"],
         "5 substeps": ["simulation.simulation_steps=5"],
         "gravity -200": ["simulation.gravity=[0,-200,0]"]}


@pytest.mark.parametrize("overrides", CASES.values(), ids=CASES.keys())
def test_no_point_ends_inside_the_sphere_at_any_substep_count(path, overrides):
    """sphere.json at 1 to 5 substeps a frame and at 20 g: at no frame's end is a
    point deeper than SPHERE_SETTLE inside the sphere (they were up to 19 cm)"""
    threads, solver = path
    sim = Simulation.from_file(SCENES / "sphere.json", overrides, threads=threads, solver_path=solver)
    assert deepest_at_frame_ends(sim, 1.5) <= SPHERE_SETTLE + 1e-12


def test_sphere_json_at_its_own_substeps_keeps_the_course_result():
    """at its own 30 substeps sphere.json moves no point far enough, nor leaves one
    deep enough, for the segment rule or the settle to act: its result is the
    course rule's. The figures are those of the solver before the rule (serial
    path); the deepest point stays under a quarter of SPHERE_SETTLE. The mean
    height's tolerance takes in the two ways the springs divide by their length
    (:data:`clothsim.solver.shared.DIVIDE`), 2.3e-9 of it apart after 2 s; the
    rule or the settle moving a single point by 2.5 µm would move it by 1e-8."""
    sim = Simulation.from_file(SCENES / "sphere.json", threads=1)
    deepest = deepest_at_frame_ends(sim, 2.0)
    assert deepest < SPHERE_SETTLE / 4
    assert deepest == pytest.approx(0.00013048158322209735, rel=1e-9)
    assert sim.positions[:, 1].mean() == pytest.approx(0.09850384520152307, rel=1e-8)


def planes(rows):
    """(N, 3) points as (3, N) coordinate planes"""
    return np.ascontiguousarray(np.asarray(rows, dtype=np.float64).T)


def sphere_rows(origin, radius, friction, moving=False):
    """a still sphere's rows; ``moving``: the same sphere as two identical slots,
    so that the kernel takes its loop for moving spheres (the carry is the identity)"""
    rows = pack([types.SimpleNamespace(origin=tuple(origin), radius=radius, friction=friction, animation=None)])
    return np.ascontiguousarray(np.repeat(rows, 2, axis=0)) if moving else rows


@pytest.mark.parametrize("moving", [False, True], ids=["still", "moving loop"])
@pytest.mark.parametrize("friction", [0.0, 0.3])
def test_a_fast_point_aimed_through_a_sphere_stops_at_its_near_side(moving, friction):
    """a point that crosses a whole sphere of radius 0.1 in one substep (from 5 cm above
    it to 5 cm below), and one that ends just past the centre, both stop where their
    segment entered, SPHERE_OFFSET above the top, then friction takes them back toward
    their last position along the segment; a point outside that moved as far beside
    the sphere is left alone"""
    c, r = np.array([0.0, 1.0, 0.0]), 0.1
    L = planes([[0.0, 1.15, 0.0], [0.01, 1.15, 0.0], [0.5, 1.15, 0.0]])
    P = planes([[0.0, 0.85, 0.0], [0.01, 0.99, 0.0], [0.5, 0.85, 0.0]])
    before = P.copy()
    collide_spheres(P, L, np.ones(3), sphere_rows(c, r, friction, moving), 0, 3, 0)
    for p in range(2):
        u = (before[:, p] - L[:, p]) / np.linalg.norm(before[:, p] - L[:, p])
        # where the segment meets the sphere, from its last position
        e = L[:, p] - c
        t = -(e @ u) - np.sqrt((e @ u) ** 2 - (e @ e - r * r))
        entry = c + (e + t * u) * (r + SPHERE_OFFSET) / r
        np.testing.assert_allclose(P[:, p], L[:, p] + (1 - friction) * (entry - L[:, p]), atol=1e-12)
        assert np.linalg.norm(P[:, p] - c) > r
        assert P[1, p] > c[1] + 0.099
    np.testing.assert_array_equal(P[:, 2], before[:, 2])


def test_the_radial_rule_is_the_course_one_for_points_that_enter_on_their_own_side():
    """points moving a few millimetres into the sphere (the ordinary case) take the
    CS184 rule: radially to the surface, then toward the last position by friction,
    as the course code computes it"""
    rng = np.random.default_rng(7)
    c, r, friction = np.array([0.5, 0.2, 0.5]), 0.2, 0.3
    n = 200
    normal = rng.normal(size=(n, 3))
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    last = c + normal * (r + rng.uniform(-2e-4, 2e-3, (n, 1)))
    now = last + rng.normal(scale=2e-3, size=(n, 3)) - normal * 3e-3
    P, L = planes(now), planes(last)
    collide_spheres(P, L, np.ones(n), sphere_rows(c, r, friction), 0, n, 0)
    d = now - c
    dist = np.linalg.norm(d, axis=1)
    inside = dist < r
    assert inside.sum() > n // 2
    course = last + (1 - friction) * (c + d * (r / dist)[:, None] - last)
    expected = np.where(inside[:, None], course, now)
    np.testing.assert_allclose(P.T, expected, rtol=0, atol=1e-15)


def test_settle_takes_out_only_points_deeper_than_its_depth():
    """after Provot's pass: a point 0.5 mm inside stays to the bit, one 3 mm inside
    goes out radially to the surface, one pulled past the centre goes back to where
    its segment from the last position entered"""
    c, r = np.array([0.0, 0.0, 0.0]), 0.2
    L = planes([[0.0, 0.2005, 0.0], [0.0, 0.2005, 0.0], [0.0, 0.201, 0.0]])
    P = planes([[0.0, 0.1995, 0.0], [0.0, 0.197, 0.0], [0.0, -0.05, 0.0]])
    before = P.copy()
    settle_spheres(P, L, np.ones(3), sphere_rows(c, r, 0.5), 0, 3, 0)
    np.testing.assert_array_equal(P[:, 0], before[:, 0])
    np.testing.assert_allclose(P[:, 1], [0.0, r, 0.0], atol=1e-15)
    np.testing.assert_allclose(P[:, 2], [0.0, r + SPHERE_OFFSET, 0.0], atol=1e-12)


@pytest.mark.parametrize("overrides", [["simulation.simulation_steps=1", SOFT_1],
                                       ["simulation.simulation_steps=1", SOFT_1, "simulation.gravity=[0,-200,0]"]],
                         ids=["1 substep", "1 substep, gravity -200"])
def test_no_point_ends_below_the_plane_at_one_substep(path, overrides):
    """plane.json at one substep a frame, also at 20 g (a point falls up to 2 m a
    substep there): at every frame's end every point is on the plane's side"""
    threads, solver = path
    sim = Simulation.from_file(SCENES / "plane.json", overrides, threads=threads, solver_path=solver)
    lowest = [np.inf]
    sim.run(1.5, lambda sim: lowest.__setitem__(0, min(lowest[0], sim.positions[:, 1].min())))
    assert lowest[0] >= 0.0


def test_the_moving_loop_takes_the_still_rule_a_run_at_a_time():
    """the moving sphere's loop takes its points LANES at a time: with the identity
    carry, over a part that starts and ends off a multiple of LANES, it puts
    every point where the still sphere's loop does, and leaves the points
    outside the part alone"""
    from clothsim.solver.colliders.sphere_lanes import LANES

    rng = np.random.default_rng(11)
    c, r, friction = np.array([0.5, 0.2, 0.5]), 0.2, 0.3
    n = 90 * LANES + 17
    normal = rng.normal(size=(n, 3))
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    last = c + normal * (r + rng.uniform(-2e-4, 2e-3, (n, 1)))
    now = last + rng.normal(scale=2e-3, size=(n, 3)) - normal * 3e-3
    now[::41] += 0.3  # some points moved too far for the loop: its second pass takes them
    free = np.ones(n)
    free[::7] = 0.0
    lo, hi = 5 * LANES + 3, n - 5
    out = {}
    for moving in (False, True):
        P, L = planes(now), planes(last)
        collide_spheres(P, L, free, sphere_rows(c, r, friction, moving), lo, hi, 0)
        out[moving] = P
    np.testing.assert_allclose(out[True], out[False], rtol=0, atol=1e-15)
    moved = np.any(out[True] != planes(now), axis=0)
    assert moved[lo:hi].sum() > (hi - lo) // 3
    assert not moved[:lo].any() and not moved[hi:].any()


def test_the_sphere_a_run_at_a_time_as_one_by_one():
    """the sphere's loops, moving and still, take their points LANES at a time in
    vector code written by hand (sphere_lanes) and the few left over one by one
    in numba's: both put every point of a spinning, sliding sphere's part (or
    of the same sphere standing still) in the same place to the bit and count
    the same fast points (the one-by-one run of each point goes through the
    loop a single point long)"""
    from clothsim.motion import Animation, Keyframe
    from clothsim.solver.colliders import sphere

    rng = np.random.default_rng(5)
    c, r = np.array([0.1, 0.3, -0.2]), 0.25
    spin = Animation((Keyframe(0.0), Keyframe(0.5, translate=(0.05, 0.0, 0.02), rotate=(0.0, 90.0, 20.0))))
    spec = types.SimpleNamespace(origin=tuple(c), radius=r, friction=0.4, animation=spin)
    rows = sphere.pack([spec], 0.1, 0.01, 4)
    row = rows[2, 0]
    assert np.abs(row[5:14].reshape(3, 3) - np.eye(3)).max() > 1e-3  # a real turn to carry
    n = 64 * sphere.LANES
    normal = rng.normal(size=(n, 3))
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    last = c + normal * (r + rng.uniform(-2e-3, 4e-3, (n, 1)))
    now = last + rng.normal(scale=3e-3, size=(n, 3)) - normal * 4e-3
    now[::37] += 0.4
    free = np.ones(n)
    free[::9] = 0.0
    far2 = sphere._far2(r)[1]
    for rule in (sphere._carried_rule, sphere._still_rule):  # the still one reads the row's sphere alone
        P, L = planes(now), planes(last)
        fast = rule(P[0], P[1], P[2], L[0], L[1], L[2], free, row, far2)
        ones, fast_ones = planes(now), 0
        for p in range(n):
            fast_ones += rule(ones[0, p:p + 1], ones[1, p:p + 1], ones[2, p:p + 1], L[0, p:], L[1, p:], L[2, p:],
                              free[p:], row, far2)
        assert fast == fast_ones == len(range(0, n, 37))
        np.testing.assert_array_equal(P, ones)
        assert np.any(P != planes(now), axis=0).sum() > n // 3
