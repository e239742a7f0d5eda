"""The general path's springs as each point's pulls (:mod:`clothsim.solver.mesh_pulls`).

:func:`pull_step` sums every point's springs and takes the Verlet step,
eight points a call (:func:`clothsim.solver.pull_lanes.pull_lanes`). It is
held here to the exact step, computed in long double from the spring lists
as the course code adds each spring to both its ends, on any springs among
any points (a last eight cut short, points of many springs and of none,
pins, two cloths with constants of their own, kinds switched off); to
itself when the eights are cut into parts and taken in any order; and it
must follow the live constants (:func:`refresh_constants`). Provot's pass
(:func:`mesh_provot`), which skips eights of springs by a vector test on
the same rows, must give the bits of the pass that takes every spring.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit

from clothsim.solver.groups import MeshKnobs
from clothsim.solver.mesh_pulls import LANES, build_mesh_pulls, pull_step, refresh_constants, rows_buffer, to_rows
from clothsim.solver.meshsprings import build_mesh_springs, mesh_provot
from clothsim.solver.pull_lanes import over_lanes


def _model(n, a, b, rest, kind, starts):
    """what build_mesh_pulls reads of a model: springs a-b of ``kind``, cloths from ``starts``"""
    return SimpleNamespace(num_points=n, spring_a=np.asarray(a, dtype=np.int32), spring_b=np.asarray(b, dtype=np.int32),
                           spring_rest=np.asarray(rest, dtype=np.float32), spring_kind=np.asarray(kind, dtype=np.int8),
                           cloths=[SimpleNamespace(start=s) for s in starts])


def _knobs(n, k_over_m, keep, dt2=1e-4):
    return MeshKnobs(gravity=np.array([0.3, -9.8, 0.1]), k_over_m=np.asarray(k_over_m, dtype=np.float64),
                     enabled=np.ones(len(k_over_m), dtype=bool), keep=keep, dt2=dt2, simulation_steps=1,
                     self_collision=False, inv_mass=np.ones(n))


def _sets(model):
    cloth = np.searchsorted([c.start for c in model.cloths], model.spring_a, side="right") - 1
    return 3 * cloth + model.spring_kind


def _exact(model, P, L, free, knobs):
    """the step in long double, each spring added to both ends; and the scale of
    each point's terms (for the error the double step may make)"""
    x, last = P.T.astype(np.longdouble), L.T.astype(np.longdouble)
    a, b = model.spring_a, model.spring_b
    k = knobs.k_over_m[_sets(model)].astype(np.longdouble)
    d = x[b] - x[a]
    length = np.sqrt((d * d).sum(axis=1))
    rest = model.spring_rest.astype(np.longdouble)
    f = (k * (1 - rest / np.maximum(length, 1e-15)))[:, None] * d
    acc = np.zeros_like(x) + knobs.gravity
    np.add.at(acc, a, f)
    np.add.at(acc, b, -f)
    size = np.zeros(len(x), dtype=np.longdouble)
    np.add.at(size, a, k * (length + rest))
    np.add.at(size, b, k * (length + rest))
    keep = knobs.keep[:, None]
    new = x + free[:, None] * (keep * (x - last) + acc * knobs.dt2)
    scale = (size + np.abs(knobs.gravity).sum()) * knobs.dt2 + np.abs(x).max(axis=1) + np.abs(x - last).max(axis=1)
    return new.astype(np.float64).T, scale.astype(np.float64)


def _pulled(model, P, L, free, knobs, cuts=None):
    """L after pull_step from P, the eights cut into the ranges ``cuts`` (taken in that order)"""
    pulls = build_mesh_pulls(model)
    refresh_constants(pulls, knobs.k_over_m)
    n = P.shape[1]
    R = rows_buffer(n)
    to_rows(P, R, 0, n)
    out = L.copy()
    eights = -(-n // LANES)
    for lo, hi in cuts or [(0, eights)]:
        pull_step(P, R, out, free, knobs, pulls, lo, hi)
    return out


@st.composite
def _cases(draw):
    n = draw(st.integers(1, 40))
    count = draw(st.integers(0, 4 * n)) if n > 1 else 0
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    a = rng.integers(0, n, count)
    b = (a + rng.integers(1, max(n, 2), count)) % n  # never a spring from a point to itself
    starts = [0] if n < 2 else [0, int(rng.integers(1, n))]
    kind = rng.integers(0, 3, count)
    k = rng.uniform(0.0, 3e4, 3 * len(starts)) * (rng.uniform(size=3 * len(starts)) > 0.2)  # some switched off
    P = rng.normal(0.0, 0.5, (3, n))
    rest = np.linalg.norm(P[:, a] - P[:, b], axis=0) * rng.uniform(0.5, 1.5, count)
    model = _model(n, a, b, rest, kind, starts)
    L = P + rng.normal(0.0, 0.01, (3, n))
    free = (rng.uniform(size=n) > 0.2).astype(np.float64)
    knobs = _knobs(n, k, rng.uniform(0.9, 1.0, n))
    return model, P, L, free, knobs


@settings(max_examples=150, deadline=None)
@given(_cases())
def test_the_pulls_take_the_exact_step(case):
    model, P, L, free, knobs = case
    before = P.copy()
    new = _pulled(model, P, L, free, knobs)
    exact, scale = _exact(model, P, L, free, knobs)
    assert np.array_equal(P, before)  # the positions are only read
    assert np.all(np.abs(new - exact) <= 1e-14 * scale)


@settings(max_examples=60, deadline=None)
@given(_cases(), st.data())
def test_parts_in_any_order_give_the_whole_models_bits(case, data):
    model, P, L, free, knobs = case
    eights = -(-P.shape[1] // LANES)
    cut = data.draw(st.integers(0, eights))
    whole = _pulled(model, P, L, free, knobs)
    parts = _pulled(model, P, L, free, knobs, cuts=[(cut, eights), (0, cut)])
    assert np.array_equal(whole.view(np.int64), parts.view(np.int64))


def test_a_changed_constant_reaches_the_slots():
    """the first refresh fills the slots from nothing; a later one with other
    constants rewrites them, and the step follows"""
    n = 20
    rng = np.random.default_rng(3)
    a = np.arange(n - 1)
    model = _model(n, a, a + 1, np.full(n - 1, 0.05), np.zeros(n - 1), [0])
    P = rng.normal(0.0, 0.2, (3, n))
    L = P.copy()
    free = np.ones(n)
    pulls = build_mesh_pulls(model)
    for k in ([100.0, 0.0, 0.0], [250.0, 0.0, 0.0], [0.0, 0.0, 0.0]):
        knobs = _knobs(n, k, np.ones(n))
        refresh_constants(pulls, knobs.k_over_m)
        R = rows_buffer(n)
        to_rows(P, R, 0, n)
        out = L.copy()
        pull_step(P, R, out, free, knobs, pulls, 0, -(-n // LANES))
        exact, scale = _exact(model, P, L, free, knobs)
        assert np.all(np.abs(out - exact) <= 1e-14 * scale), k


def test_slots_of_another_model_leave_the_points_alone():
    """pull_step reads its slots unchecked, so slots made for another count of
    points, or rows too short for them, must not run at all"""
    a = np.arange(15)
    model = _model(16, a, a + 1, np.full(15, 0.05), np.zeros(15), [0])
    pulls = build_mesh_pulls(model)
    refresh_constants(pulls, np.array([100.0, 0.0, 0.0]))
    for n in (15, 17, 24):
        P = np.ones((3, n))
        L = np.full((3, n), 7.0)
        knobs = _knobs(n, [100.0, 0.0, 0.0], np.ones(n))
        R = rows_buffer(n)
        to_rows(P, R, 0, n)
        pull_step(P, R, L, np.ones(n), knobs, pulls, 0, -(-n // LANES))
        assert np.all(L == 7.0), n
    P, L = np.ones((3, 16)), np.full((3, 16), 7.0)
    knobs = _knobs(16, [100.0, 0.0, 0.0], np.ones(16))
    pull_step(P, rows_buffer(8), L, np.ones(16), knobs, pulls, 0, 2)  # rows for half the points
    pull_step(P, rows_buffer(16), L, np.ones(16), knobs, pulls, 0, 3)  # one eight too many
    assert np.all(L == 7.0)


@settings(max_examples=80, deadline=None)
@given(_cases(), st.integers(1, 3))
def test_provots_eights_change_nothing(case, parts):
    """mesh_provot's vector test on the rows only skips eights of springs the pass
    would leave alone: the same bits as the pass one spring after another (given
    rows of the wrong shape), on states where every spring is near its limit
    (about half over it), and R left as the rows of the result"""
    model, P, L, free, knobs = case
    n = P.shape[1]
    rng = np.random.default_rng(n)
    stretched = P * rng.uniform(0.9, 1.25, P.shape)
    # rest lengths that leave every spring within 1.5% of its limit, either side
    length = np.linalg.norm(stretched[:, model.spring_a] - stretched[:, model.spring_b], axis=0)
    model.spring_rest = (length / (1.1 * rng.uniform(0.985, 1.015, length.shape))).astype(np.float32)
    model.pinned = free == 0.0
    springs = build_mesh_springs(model, parts)
    out = []
    for R in (rows_buffer(n), np.zeros((n, 3))):
        p = stretched.copy()
        if R.shape[1] == 4:
            to_rows(p, R, 0, n)
        for t in range(parts + 1):
            mesh_provot(p, R, springs, knobs.enabled, springs.part_start[t], springs.part_start[t + 1])
        out.append(p)
        if R.shape[1] == 4:
            assert np.array_equal(R[:, :3], p.T)
    assert np.array_equal(out[0].view(np.int64), out[1].view(np.int64))


@njit
def _over_each_eight(R, a, b, limit2):
    out = np.zeros(len(a) // LANES, dtype=np.bool_)
    for e in range(len(out)):
        out[e] = over_lanes(R, a, b, limit2, e * LANES)
    return out


def test_provots_vector_test_pairs_each_spring_with_its_own_limit():
    """over_lanes says, for each eight, whether a spring is longer than its own
    limit (less a part in 1e12): springs of lengths over four orders of
    magnitude, one in each eight over a limit half its squared length and the
    rest under one twice theirs, so that a length taken in another lane than
    its limit's, or a coordinate missed, changes some eights' answers; and a
    spring at its limit to the bit is flagged (the test never misses one)"""
    rng = np.random.default_rng(5)
    n, eights = 300, 400
    R = rows_buffer(n)
    to_rows(rng.normal(size=(3, n)) * 10.0 ** rng.uniform(-2, 2, n), R, 0, n)
    a = rng.integers(0, n, eights * LANES).astype(np.int32)
    b = ((a + rng.integers(1, n, eights * LANES)) % n).astype(np.int32)  # never a itself
    l2 = ((R[b, :3] - R[a, :3]) ** 2).sum(axis=1)
    over = rng.random(eights * LANES) < 1.0 / LANES
    limit2 = np.where(over, 0.5 * l2, 2.0 * l2)
    expected = (l2 > limit2).reshape(eights, LANES).any(axis=1)
    assert 0 < expected.sum() < eights
    assert np.array_equal(_over_each_eight(R, a, b, limit2), expected)
    at_limit = np.where(np.arange(eights * LANES) % LANES == 3, l2, 2.0 * l2)
    assert _over_each_eight(R, a, b, at_limit).all()
