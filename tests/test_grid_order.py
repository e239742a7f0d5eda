"""The grid path's slots: an upright cloth cut into parts is held column by column.

:func:`clothsim.solver.cloth_solver.grid_order` transposes the grid inside the
solver; what the user sees (positions, handles, the held point) stays in the
model's row-major order.
"""

from __future__ import annotations

import numpy as np
import pytest

from clothsim import Simulation
from clothsim.solver import cloth_solver
from clothsim.solver.cloth_solver import grid_order
from clothsim.standard_scenes import scene_path

from .conftest import SCENES

GRID = ["cloth.num_width_points=24", "cloth.num_height_points=16"]


def _upright(rows, cols):
    """rest positions of a cloth standing in the xy plane, rows going up y"""
    r, c = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    return np.stack([c.ravel() * 0.1, r.ravel() * 0.1, np.zeros(rows * cols)], axis=1)


def test_an_upright_cloth_in_parts_is_held_column_by_column():
    rest = _upright(3, 5)
    order, grid = grid_order(rest, (3, 5), 2, (0.0, -9.8, 0.0))
    assert grid == (5, 3)
    np.testing.assert_array_equal(np.sort(order), np.arange(15))
    # slot k of the transposed grid (row i, column r) holds the model's point (r, i)
    for i in range(5):
        for r in range(3):
            assert order[i * 3 + r] == r * 5 + i
    # one part, a cloth lying flat, or gravity across the rows: as the model numbers them
    for args in ((rest, (3, 5), 1, (0, -9.8, 0)), (rest[:, [0, 2, 1]], (3, 5), 2, (0, -9.8, 0)),
                 (rest, (3, 5), 2, (-9.8, 0, 0)), (rest, (3, 5), 2, (0, 0, 0))):
        order, grid = grid_order(*args)
        assert grid == (3, 5)
        np.testing.assert_array_equal(order, np.arange(15))


@pytest.mark.parametrize("scene, seconds", [(SCENES / "selfCollision.json", 0.05), (scene_path("curtain"), 0.1)])
def test_the_transposed_grid_moves_the_cloth_as_the_rows_do(monkeypatch, scene, seconds):
    """springs, gravity, damping, the floor and the handles on an upright cloth cut
    into two parts: held column by column or row by row, the same motion to the
    rounding of sums taken in another order, until the Provot pass first
    shortens a spring (its corrections, one after another, follow the order of
    the slots, as they follow the part count: later, the two part ways apart)"""
    runs = {}
    for transposed in (True, False):
        if not transposed:
            monkeypatch.setattr(cloth_solver, "grid_order",
                                lambda rest, grid, parts, gravity: (np.arange(grid[0] * grid[1]), tuple(grid)))
        sized = GRID if scene.name == "selfCollision.json" else []  # the curtain's handles name its points
        sim = Simulation.from_file(scene, sized + ["simulation.self_collision=false"], threads=2)
        assert sim.solver.transposed is transposed
        sim.run(seconds)
        runs[transposed] = sim.positions.copy()
    moved = np.abs(runs[True] - sim.model.rest_positions).max()
    assert moved > 1e-3
    np.testing.assert_allclose(runs[True], runs[False], rtol=0, atol=1e-10)


@pytest.mark.parametrize("overrides", [[], ["cloth.num_height_points=48"]], ids=["48x36", "square"])
def test_handles_and_the_held_point_keep_the_models_numbers(overrides):
    """the curtain (upright, handles along its top row) on two parts, held column by
    column: its handles' points are where they are on one part, row by row (the
    handles place them, whatever the cloth does), and a point the user holds is
    where the user holds it. A square grid transposed keeps its shape, so the
    solver must tell a transposed grid by its slots, not by its rows and columns."""
    runs = {}
    for threads in (1, 2):
        sim = Simulation.from_file(scene_path("curtain"), overrides, threads=threads)
        assert sim.solver.transposed is (threads == 2)
        held = sim.model.num_points // 2 + 7
        target = sim.model.rest_positions[held] + np.array([0.05, 0.1, 0.2])
        sim.grab(held, target)
        for _ in range(30):
            sim.step()
        np.testing.assert_array_equal(sim.positions[held], target)
        runs[threads] = sim
    points = np.concatenate([h.points for h in runs[1].handles])
    moved = runs[2].positions[points]
    assert np.abs(moved - runs[2].model.rest_positions[points]).max() > 0.05  # the handles slid apart
    np.testing.assert_array_equal(moved, runs[1].positions[points])


@pytest.mark.parametrize("threads", [1, 2])
def test_the_upright_pile_keeps_its_layers_apart(threads):
    """self-collision on the transposed grid: after the fall no two points that are
    not grid neighbours lie closer than half the reach"""
    sim = Simulation.from_file(SCENES / "selfCollision.json", GRID, threads=threads)
    assert sim.solver.transposed is (threads == 2)
    sim.run(1.5)
    P = sim.positions
    reach = 2 * sim.model.cloths[0].thickness
    d = np.linalg.norm(P[:, None] - P[None], axis=2)
    rows, cols = sim.model.cloths[0].grid
    r, c = np.divmod(np.arange(rows * cols), cols)
    near = (np.abs(r[:, None] - r[None]) <= 2) & (np.abs(c[:, None] - c[None]) <= 2)
    assert np.ptp(P[:, 1]) < 0.3
    assert d[~near].min() > 0.5 * reach
