"""Measured results of a run, the numbers a sweep compares.

All take a Simulation (or its arrays) as it is now; lengths in metres,
speeds in m/s.
"""

from __future__ import annotations

import math

import numpy as np

from .simulation import Simulation

REST_SPEED = 0.01
"""mean point speed [m/s] under which the cloth counts as at rest"""


def lowest_point(positions: np.ndarray) -> float:
    """smallest y of any point [m]"""
    return float(positions[:, 1].min())


def sag_below_pins(positions: np.ndarray, pinned: np.ndarray) -> float:
    """how far the lowest point hangs below the lowest pin [m]; NaN with no pins"""
    if not pinned.any():
        return math.nan
    return float(positions[pinned, 1].min() - positions[:, 1].min())


def max_stretch(positions: np.ndarray, a: np.ndarray, b: np.ndarray, rest: np.ndarray,
                active: np.ndarray | None = None) -> float:
    """largest length/rest ratio over the springs (those marked ``active``)"""
    ratio = np.linalg.norm(positions[a] - positions[b], axis=1) / rest
    if active is not None:
        ratio = ratio[active]
    return float(ratio.max()) if ratio.size else math.nan


def mean_speed(positions: np.ndarray, last_positions: np.ndarray, dt: float) -> float:
    """mean over points of |x - x_prev| / dt, the Verlet velocity [m/s]"""
    return float(np.linalg.norm(positions - last_positions, axis=1).mean() / dt)


def measure(sim: Simulation) -> dict[str, float | bool]:
    """Every per-run quantity of a sweep for the simulation as it is now."""
    m, p = sim.model, sim.positions
    speed = mean_speed(p, sim.state.last_positions, sim.params.dt)
    return {
        "lowest_y": lowest_point(p),
        "sag": sag_below_pins(p, m.pinned),
        "max_stretch": max_stretch(p, m.spring_a, m.spring_b, m.spring_rest, sim.params.enabled[m.spring_kind]),
        "mean_speed": speed,
        "at_rest": bool(speed < REST_SPEED),
    }
