"""Measured results of a run, the numbers a sweep compares.

All take a Simulation (or its arrays) as it is now; lengths in metres,
speeds in m/s. Nothing here assumes a grid:

- **sag**: how far a cloth's lowest point hangs below its own lowest pinned
  point (y, metres). For a mesh cloth the points are its vertices; its faces
  are flat triangles, so its lowest vertex is its lowest point. A scene of
  several cloths reports each pinned cloth's sag and, as ``sag``, the largest
  of them; a cloth without pins has none (NaN).
- **stretch**: a spring's length over its rest length, over the springs that
  act: those whose kind is enabled in their own cloth's material. For a mesh
  these are the springs the mesh builder made (structural along every face
  edge, shearing across quad diagonals, bending across edges), their rest
  lengths from the file; ``max_stretch`` is the largest ratio, 1 at rest.
"""

from __future__ import annotations

import math

import numpy as np

from .simulation import Simulation
from .spring_mask import active_springs, spring_cloth

REST_SPEED = 0.01
"""mean point speed [m/s] under which the cloth counts as at rest"""


def lowest_point(positions: np.ndarray) -> float:
    """smallest y of any point [m]"""
    return float(positions[:, 1].min())


def sag_below_pins(positions: np.ndarray, pinned: np.ndarray) -> float:
    """how far the lowest point hangs below the lowest pin [m], for the points
    (N, 3) of one cloth and its pinned mask (N,); NaN with no pins"""
    if not pinned.any():
        return math.nan
    return float(positions[pinned, 1].min() - positions[:, 1].min())


def max_stretch(positions: np.ndarray, a: np.ndarray, b: np.ndarray, rest: np.ndarray,
                active: np.ndarray | None = None) -> float:
    """largest length/rest ratio over the springs (those marked ``active``);
    ``a``, ``b``: the springs' end points, int (S,); ``rest`` [m] (S,); NaN with no spring"""
    ratio = np.linalg.norm(positions[a] - positions[b], axis=1) / rest
    if active is not None:
        ratio = ratio[active]
    return float(ratio.max()) if ratio.size else math.nan


def mean_speed(positions: np.ndarray, last_positions: np.ndarray, dt: float) -> float:
    """mean over points of |x - x_prev| / dt, the Verlet velocity [m/s]"""
    return float(np.linalg.norm(positions - last_positions, axis=1).mean() / dt)


def cloth_measures(sim: Simulation) -> list[dict[str, float]]:
    """``lowest_y``, ``sag`` and ``max_stretch`` of each cloth, in scene order."""
    m, p = sim.model, sim.positions
    active = active_springs(m, sim.params)
    owner = spring_cloth(m) if len(m.cloths) > 1 else np.zeros(m.num_springs, np.int64)
    out = []
    for k, cloth in enumerate(m.cloths):
        mine = owner == k
        out.append({"lowest_y": lowest_point(p[cloth.points]),
                    "sag": sag_below_pins(p[cloth.points], m.pinned[cloth.points]),
                    "max_stretch": max_stretch(p, m.spring_a[mine], m.spring_b[mine], m.spring_rest[mine],
                                               active[mine])})
    return out


def measure(sim: Simulation) -> dict[str, float | bool]:
    """Every per-run quantity of a sweep for the simulation as it is now:
    ``lowest_y``, ``sag``, ``max_stretch``, ``mean_speed`` and ``at_rest`` of the
    whole scene and, for a scene of several cloths, ``NAME.lowest_y``,
    ``NAME.sag`` and ``NAME.max_stretch`` of each (see the module's docstring)."""
    m, p = sim.model, sim.positions
    speed = mean_speed(p, sim.state.last_positions, sim.params.dt)
    active = active_springs(m, sim.params)
    out: dict[str, float | bool] = {
        "lowest_y": lowest_point(p),
        "sag": sag_below_pins(p, m.pinned),
        "max_stretch": max_stretch(p, m.spring_a, m.spring_b, m.spring_rest, active),
        "mean_speed": speed,
        "at_rest": bool(speed < REST_SPEED),
    }
    if len(m.cloths) > 1:
        per = cloth_measures(sim)
        sags = [c["sag"] for c in per if not math.isnan(c["sag"])]
        out["sag"] = max(sags) if sags else math.nan
        for cloth, values in zip(m.cloths, per):
            out.update({f"{cloth.name}.{key}": value for key, value in values.items()})
    return out
