"""A moving collider carries the point resting on it by friction, whatever the
number of substeps in a frame: one substep included (the kernels tell a
moving collider from a still one by its rows' slots)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from clothsim.motion import Animation, Keyframe
from clothsim.solver.colliders import box, plane, sphere

SLIDE = 0.05
"""how far [m] each collider moves along x over the frame"""

SLIDING = Animation((Keyframe(0.0), Keyframe(1.0, (SLIDE, 0.0, 0.0), (0.0, 0.0, 0.0))))


def _collider(kind: str, animation):
    """(pack, collide, object): a collider whose top lies at y = 0 at the start"""
    if kind == "sphere":
        return sphere.pack, sphere.collide_spheres, SimpleNamespace(origin=(0.0, -0.5, 0.0), radius=0.5,
                                                                    friction=1.0, animation=animation)
    if kind == "plane":
        return plane.pack, plane.collide_planes, SimpleNamespace(point=(0.0, 0.0, 0.0), normal=(0.0, 1.0, 0.0),
                                                                 friction=1.0, animation=animation)
    return box.pack, box.collide_boxes, SimpleNamespace(center=np.array([0.0, -0.5, 0.0]),
                                                        size=np.array([2.0, 1.0, 2.0]), rotate=(0.0, 0.0, 0.0),
                                                        friction=1.0, margin=1e-3, animation=animation)


@pytest.mark.parametrize("kind", ["sphere", "plane", "box"])
@pytest.mark.parametrize("substeps", [1, 4])
def test_a_point_resting_on_a_sliding_collider_moves_with_it(kind, substeps):
    """a point 1 mm above the collider's top at the start of each substep, pulled 5 mm
    down (into it, also where the sphere's top has slid away from under it): with
    friction 1 it goes where its last position was carried, so over the frame it
    moves along x as far as the collider does (and a still collider leaves it
    where it was)"""
    dt = 1.0 / substeps
    for animation, expected in ((SLIDING, SLIDE), (None, 0.0)):
        pack, collide, obj = _collider(kind, animation)
        rows = pack([obj], 0.0, dt, substeps)
        last = np.array([[0.0], [1e-3], [0.0]])
        free = np.ones(1)
        for s in range(substeps):
            P = last.copy()
            P[1] -= 6e-3
            collide(P, last, free, rows, 0, 1, s)
            assert P[1, 0] >= -1e-12  # never left inside
            last = P.copy()
            last[1] = 1e-3  # back onto the surface for the next substep
        assert last[0, 0] == pytest.approx(expected, abs=1e-9), (kind, substeps, animation is not None)
