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


# ------------------------------------------------------------------ several cloths, mesh cloths


def _two():
    from .handmade import two_cloth_scene

    return Simulation(parse_scene(two_cloth_scene(), "two"))


def test_measure_of_two_cloths_each_below_its_own_pins():
    """at rest the vertical cloth hangs 0.5 m below its pinned top row, the
    horizontal one not at all: the scene's sag is the larger; each cloth's own
    lowest point and stretch 1"""
    sim = _two()
    m = metrics.measure(sim)
    assert m["cloth_0.sag"] == 0.0 and m["cloth_1.sag"] == pytest.approx(0.5)
    assert m["sag"] == pytest.approx(0.5)
    assert m["cloth_0.lowest_y"] == 1.0 and m["cloth_1.lowest_y"] == 0.0 and m["lowest_y"] == 0.0
    assert m["cloth_0.max_stretch"] == pytest.approx(1.0) and m["cloth_1.max_stretch"] == pytest.approx(1.0)
    # a cloth without pins has no sag; the scene's is the others'
    sim2 = Simulation(parse_scene({"cloth": [small_scene()["cloth"], {**small_scene()["cloth"], "pinned": []}]}))
    m2 = metrics.measure(sim2)
    assert math.isnan(m2["cloth_1.sag"]) and m2["sag"] == 0.0


def test_stretch_of_two_cloths_uses_each_cloths_own_toggles():
    """pull one point of the second cloth: its stretch is the largest ratio of its
    own springs (brute force), the first cloth's stays 1; turning the second's
    structural springs off leaves only its other kinds, the first's untouched"""
    from clothsim.model import STRUCTURAL

    sim = _two()
    model = sim.model
    c1 = model.cloths[1]
    point = c1.start + 5 * 12 + 6  # a free point inside the hanging cloth
    sim.state.positions[point] += [0.0, 0.0, 0.05]
    p = sim.positions
    ratio = np.linalg.norm(p[model.spring_a] - p[model.spring_b], axis=1) / model.spring_rest
    in1 = (model.spring_a >= c1.start) & (model.spring_a < c1.stop)
    m = metrics.measure(sim)
    assert m["cloth_1.max_stretch"] == ratio[in1].max() > 1.001
    assert m["cloth_0.max_stretch"] == pytest.approx(1.0) and m["max_stretch"] == ratio.max()
    sim.cloths[1].params.enable_structural = False
    m = metrics.measure(sim)
    assert m["cloth_1.max_stretch"] == ratio[in1 & (model.spring_kind != STRUCTURAL)].max()
    assert m["cloth_1.max_stretch"] < ratio[in1].max()
    assert m["cloth_0.max_stretch"] == pytest.approx(1.0)
    with pytest.raises(AttributeError):
        sim.params.enabled  # noqa: B018 - several cloths: no single set of toggles


def test_sag_and_stretch_of_a_mesh_cloth():
    """a Delaunay disc pinned at its centre with its rim pushed 0.2 m down: sag
    0.2; its edges' stretch is the longest edge over its rest length"""
    from .handmade import disc_model, simulation_of

    model = disc_model(pinned_center=True)
    sim = simulation_of(model)
    assert metrics.measure(sim)["max_stretch"] == pytest.approx(1.0)
    rim = np.linalg.norm(sim.positions[:, [0, 2]] - [0.5, 0.5], axis=1) > 0.49
    sim.state.positions[rim, 1] -= 0.2
    m = metrics.measure(sim)
    assert m["sag"] == pytest.approx(0.2) and m["lowest_y"] == pytest.approx(0.8)
    p = sim.positions
    ratio = np.linalg.norm(p[model.spring_a] - p[model.spring_b], axis=1) / model.spring_rest
    assert m["max_stretch"] == ratio.max() > 1.05
