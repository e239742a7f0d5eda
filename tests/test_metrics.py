"""clothsim.metrics on cases with known answers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from clothsim import Simulation, metrics
from clothsim.scene import parse_scene

from .conftest import small_scene


def test_lowest_point_and_sag():
    """lowest y, and the drop of the lowest point below the lowest pin"""
    pos = np.array([[0, 1.0, 0], [1, 0.9, 0], [0.5, 0.25, 0]])
    assert metrics.lowest_point(pos) == 0.25
    assert metrics.sag_below_pins(pos, np.array([True, True, False])) == pytest.approx(0.65)
    assert math.isnan(metrics.sag_below_pins(pos, np.zeros(3, bool)))


def test_max_stretch_of_known_springs():
    """length/rest of the longest active spring"""
    pos = np.array([[0, 0, 0], [3.0, 0, 0], [3.0, 4.0, 0]])
    a, b = np.array([0, 0]), np.array([1, 2])
    rest = np.array([2.0, 5.0])
    assert metrics.max_stretch(pos, a, b, rest) == pytest.approx(1.5)
    assert metrics.max_stretch(pos, a, b, rest, np.array([False, True])) == pytest.approx(1.0)


def test_mean_speed_is_verlet_velocity():
    """mean of |x - x_prev| / dt"""
    pos = np.array([[0.0, 0, 0], [0, 0, 0]])
    last = np.array([[0.0, 0.01, 0], [0.03, 0, 0.04]])
    assert metrics.mean_speed(pos, last, 0.01) == pytest.approx((1.0 + 5.0) / 2)


def test_measure_at_start_and_after_settling():
    """a cloth at its start is at rest with stretch 1; a falling one moves"""
    sim = Simulation(parse_scene(small_scene()))
    m = metrics.measure(sim)
    assert m["at_rest"] and m["mean_speed"] == 0.0 and m["max_stretch"] == pytest.approx(1.0)
    assert m["sag"] == 0.0 and m["lowest_y"] == 1.0
    sim.run(0.3)
    m = metrics.measure(sim)
    assert not m["at_rest"] and m["sag"] > 0.1 and m["lowest_y"] < 0.9
