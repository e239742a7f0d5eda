"""Glue between a Simulation and the Renderer: meshes, springs as lines, framing."""

from __future__ import annotations

import numpy as np

from ..simulation import Simulation
from .camera import OrbitCamera, framing
from .geometry import Mesh, grid_tangents, pack_vertices, plane_mesh, sphere_mesh
from .renderer import Renderer

SPHERE_DRAW_SCALE = 0.96


def spring_lines(sim: Simulation) -> np.ndarray:
    """Index pairs of the springs of the enabled kinds, int32 (L, 2)."""
    m = sim.model
    keep = sim.params.enabled[m.spring_kind]
    return np.stack([m.spring_a[keep], m.spring_b[keep]], axis=1).astype(np.int32)


def cloth_vertices(sim: Simulation, out: np.ndarray | None = None) -> np.ndarray:
    m = sim.model
    pos = sim.positions
    return pack_vertices(pos, sim.normals, grid_tangents(pos, m.num_width_points, m.num_height_points),
                         m.uvs, out)


def cloth_mesh(sim: Simulation) -> Mesh:
    return Mesh(cloth_vertices(sim), np.asarray(sim.model.triangles), spring_lines(sim))


def reach_box(sim: Simulation) -> tuple[np.ndarray, np.ndarray]:
    """Where the cloth can be: its start box and 1.25 cloth sizes below it, cut
    at floors, plus the spheres. Fixed per scene, so every frame and every run of a
    sweep is framed alike."""
    rest = sim.model.rest_positions
    size = max(sim.model.width, sim.model.height)
    lo, hi = rest.min(axis=0).copy(), rest.max(axis=0).copy()
    lo[1] -= 1.25 * size
    for p in sim.planes:
        if p.normal[1] > 0.9:
            lo[1] = max(lo[1], p.point[1])
    for s in sim.spheres:
        lo = np.minimum(lo, np.asarray(s.origin) - s.radius)
        hi = np.maximum(hi, np.asarray(s.origin) + s.radius)
    return lo, hi


def current_box(sim: Simulation) -> tuple[np.ndarray, np.ndarray]:
    """Box around the cloth as it is now and the spheres."""
    lo, hi = sim.positions.min(axis=0), sim.positions.max(axis=0)
    for s in sim.spheres:
        lo = np.minimum(lo, np.asarray(s.origin) - s.radius)
        hi = np.maximum(hi, np.asarray(s.origin) + s.radius)
    return lo, hi


def default_camera(sim: Simulation, fixed: bool = True) -> OrbitCamera:
    """Camera on the scene's reach box (``fixed``: same for every frame and run)
    or tight on the cloth as it is now (for a single still image)."""
    target, distance = framing(*(reach_box(sim) if fixed else current_box(sim)))
    return OrbitCamera(target=target, distance=distance)


def collider_meshes(sim: Simulation, sphere_res: tuple[int, int] = (40, 40)) -> list[Mesh]:
    lo, hi = reach_box(sim)
    center = (lo + hi) / 2.0
    size = 2.5 * max(sim.model.width, sim.model.height)
    # drawn a little smaller, as the course code does, so the cloth lying on a
    # sphere is not pierced by it between its vertices
    meshes = [sphere_mesh(s.origin, SPHERE_DRAW_SCALE * s.radius, *sphere_res) for s in sim.spheres]
    meshes += [plane_mesh(p.point, p.normal, center, size) for p in sim.planes]
    return meshes


class SimulationView:
    """Keeps a Renderer's buffers in step with a Simulation."""

    def __init__(self, renderer: Renderer, sim: Simulation, sphere_res: tuple[int, int] = (40, 40)) -> None:
        self.renderer = renderer
        self.sphere_res = sphere_res
        self.attach(sim)

    def attach(self, sim: Simulation) -> None:
        self.sim = sim
        self._enabled = tuple(sim.params.enabled)
        self._vertices = cloth_vertices(sim)
        self.renderer.set_cloth(Mesh(self._vertices, np.asarray(sim.model.triangles), spring_lines(sim)))
        self.renderer.set_colliders(collider_meshes(sim, self.sphere_res))

    def set_sphere_res(self, res: tuple[int, int]) -> None:
        self.sphere_res = res
        self.renderer.set_colliders(collider_meshes(self.sim, res))

    def refresh_colliders(self) -> None:
        self.renderer.set_colliders(collider_meshes(self.sim, self.sphere_res))

    def sync(self) -> None:
        """Upload this frame's vertices; rebuild the spring lines only if a toggle changed."""
        enabled = tuple(self.sim.params.enabled)
        if enabled != self._enabled:
            self._enabled = enabled
            self.renderer.set_cloth_lines(spring_lines(self.sim))
        self.renderer.update_cloth(cloth_vertices(self.sim, self._vertices))
