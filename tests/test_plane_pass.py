"""The plane's collision pass (clothsim.solver.colliders.plane) against the exact
geometry: random planes, still, sliding or turning, and random points, many
of them crossing in one substep. A free point ends on the side its last
position (carried by the plane's motion) was on; the others are left as they
were."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from clothsim.motion import Animation, Keyframe
from clothsim.solver.colliders import plane
from clothsim.solver.colliders.motion_rows import frame_poses

N = 96


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), motion=st.sampled_from(["still", "sliding", "turning"]),
       substeps=st.sampled_from([1, 3]), friction=st.sampled_from([0.0, 0.4, 1.0]))
def test_every_free_point_ends_on_its_carried_side(seed, motion, substeps, friction):
    rng = np.random.default_rng(seed)
    point = rng.uniform(-1.0, 1.0, 3)
    normal = rng.normal(size=3)
    normal /= np.linalg.norm(normal)
    animation = None
    if motion == "sliding":
        animation = Animation((Keyframe(0.0), Keyframe(1.0, tuple(rng.uniform(-0.2, 0.2, 3)), (0.0, 0.0, 0.0))))
    elif motion == "turning":
        animation = Animation((Keyframe(0.0), Keyframe(1.0, (0.0, 0.0, 0.0), tuple(rng.uniform(-30.0, 30.0, 3)))))
    obj = SimpleNamespace(point=tuple(point), normal=tuple(normal), friction=friction, animation=animation)
    dt = 1.0 / substeps
    rows = plane.pack([obj], 0.0, dt, substeps)
    _, _, carries = frame_poses(animation, point, 0.0, dt, substeps)
    free = np.where(rng.random(N) < 0.1, 0.0, 1.0)
    for s in range(substeps):
        last = rng.uniform(-1.5, 1.5, (3, N))
        now = last + rng.normal(scale=0.3, size=(3, N))
        out = now.copy()
        plane.collide_planes(out, last, free, rows, 0, N, s)
        row = rows[min(s, rows.shape[0] - 1), 0]
        p_now, n_now = row[0:3], row[3:6]
        a = carries[min(s, carries.shape[0] - 1)]
        carried = a[:9].reshape(3, 3) @ last + a[9:, None]
        side = np.where((carried.T - p_now) @ n_now >= 0.0, 1.0, -1.0)
        before = (now.T - p_now) @ n_now * side
        after = (out.T - p_now) @ n_now * side
        pinned = free == 0.0
        assert np.array_equal(out[:, pinned], now[:, pinned])
        stayed = (before > 0.0) & ~pinned
        assert np.array_equal(out[:, stayed], now[:, stayed])
        crossed = (before <= 0.0) & ~pinned
        assert (after[crossed] > 0.0).all(), after[crossed].min()
        if friction == 1.0:  # it goes where its last position was carried
            assert np.allclose(out[:, crossed], carried[:, crossed], atol=1e-12)
