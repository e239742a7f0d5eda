"""Cloths that are not grids, built by hand as Models, and simulations that
draw them: the downstream tests (render, exports, metrics, viewer) use them
without a mesh file."""

from __future__ import annotations

import copy
from dataclasses import replace

import numpy as np
from scipy.spatial import Delaunay

from clothsim import Simulation
from clothsim.model import SPRING_KINDS, STRUCTURAL, Cloth, Model, concatenate
from clothsim.scene import parse_scene
from clothsim.state import State

from .conftest import SMALL_CLOTH


def disc_model(center=(0.5, 1.0, 0.5), radius: float = 0.5, rings: int = 8, name: str = "cloth",
               pinned_center: bool = False) -> Model:
    """A horizontal disc of triangles (a Delaunay triangulation of points on
    rings), facing +y; uvs a planar projection onto [0, 1]²; structural springs
    along every edge, rest lengths from the layout."""
    pts = [(0.0, 0.0)]
    for k in range(1, rings + 1):
        count = 6 * k
        ang = 2 * np.pi * np.arange(count) / count + 0.3 * k
        pts += list(zip(k / rings * np.cos(ang), k / rings * np.sin(ang)))
    xz = np.array(pts)
    tri = Delaunay(xz).simplices.astype(np.int64)
    a, b, c = xz[tri[:, 0]], xz[tri[:, 1]], xz[tri[:, 2]]
    ccw_xz = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]) > 0
    tri[ccw_xz] = tri[ccw_xz][:, [0, 2, 1]]  # counter-clockwise in (x, z) faces -y: turn those
    pos = np.empty((len(xz), 3))
    pos[:, 0] = center[0] + radius * xz[:, 0]
    pos[:, 1] = center[1]
    pos[:, 2] = center[2] + radius * xz[:, 1]
    uvs = ((xz + 1.0) / 2.0).astype(np.float32)
    pinned = np.zeros(len(xz), bool)
    pinned[0] = pinned_center
    edges = np.unique(np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1), axis=0)
    sa, sb = edges[:, 0].astype(np.int32), edges[:, 1].astype(np.int32)
    kind = np.full(len(sa), STRUCTURAL, np.int8)
    area = float(0.5 * np.linalg.norm(np.cross(pos[tri[:, 1]] - pos[tri[:, 0]], pos[tri[:, 2]] - pos[tri[:, 0]]),
                                      axis=1).sum())
    cloth = Cloth(0, len(pos), 0.01, area, None, 2 * radius, 2 * radius, 0, len(tri), name)
    return Model((cloth,), pos, pinned, sa, sb, np.linalg.norm(pos[sa] - pos[sb], axis=1), kind,
                 np.searchsorted(kind, np.arange(len(SPRING_KINDS) + 1)).astype(np.int64),
                 tri.astype(np.int32), uvs)


def moved(model: Model, offset) -> Model:
    """``model`` with its rest layout shifted by ``offset`` [m]"""
    return replace(model, rest_positions=model.rest_positions + np.asarray(offset, float))


def two_cloth_scene(**second) -> dict:
    """A scene of two grid cloths: the usual small horizontal one at y = 1 and a
    vertical 1 x 0.5 one below it (z = 0, y in [0, 0.5]) of ``second``'s keys."""
    lower = copy.deepcopy(SMALL_CLOTH)
    lower.update(orientation=1, height=0.5, num_width_points=12, num_height_points=8, pinned=[[0, 7], [11, 7]])
    lower.update(second)
    return {"cloth": [copy.deepcopy(SMALL_CLOTH), lower]}


def simulation_of(model: Model, **sections) -> Simulation:
    """A Simulation that draws and exports ``model`` (its cloths' materials those
    of the small test cloth): built from a scene with as many grid cloths, then
    given the model. Stepping it steps nothing of ``model``."""
    scene = parse_scene({"cloth": [copy.deepcopy(SMALL_CLOTH) for _ in model.cloths], **sections}, "handmade")
    sim = Simulation(scene)
    sim.model = model
    sim.state = State.at_rest(model)
    sim._normals = None
    return sim


def disc_and_grid() -> Model:
    """a disc beside (in +x of) a 16 x 16 grid: two cloths, one not a grid"""
    from clothsim.model import build_model

    grid = build_model(parse_scene({"cloth": copy.deepcopy(SMALL_CLOTH)}, "grid").cloth)
    return concatenate([moved(disc_model(), (1.2, 0.0, 0.0)), grid], ["disc", "grid"])


def turn_about_y(sim, center, frames: int) -> np.ndarray:
    """How far each point of ``sim`` turns about the vertical line through ``center``
    ((x, z) [m]) over ``frames`` frames [rad], unwrapped frame by frame, (N,): a
    positive turn about y takes +x toward -z, so it reads negative here."""
    cx, cz = center

    def angle(p):
        return np.arctan2(p[:, 2] - cz, p[:, 0] - cx)

    last, turned = angle(sim.positions), np.zeros(sim.model.num_points)
    for _ in range(frames):
        sim.step()
        now = angle(sim.positions)
        turned += np.angle(np.exp(1j * (now - last)))
        last = now
    return turned

