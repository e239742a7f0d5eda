"""Glue between a Simulation and the Renderer: meshes, springs as lines, framing.

Nothing here assumes a grid: the cloth mesh is every cloth's triangles (one
draw call), its tangents come from the uvs (:mod:`.tangents`), the wireframe
from the model's spring lists, the framing from the rest layout's boxes.

The colliders (spheres, planes, boxes, mesh colliders, in that order) are
built once in their rest poses; each frame every one with an animation gets
its pose at ``sim.time`` as a model matrix (:func:`collider_poses`).
"""

from __future__ import annotations

import numpy as np

from ..motion import rotation_matrices
from ..simulation import Simulation
from ..spring_mask import active_springs, enabled_kinds
from ..world import pose_at
from .camera import OrbitCamera, fit_points, framing
from .geometry import Mesh, box_mesh, pack_vertices, plane_mesh, sphere_mesh, triangle_mesh
from .renderer import Renderer
from .tangents import UvTangents

SPHERE_DRAW_SCALE = 0.96

DRAW_INSET = 0.003
"""[m]: boxes and closed mesh colliders are drawn this much inside their surface,
as spheres are drawn smaller: cloth resting on one lies within its margin of
the surface, and would be pierced by it between its points"""


def spring_lines(sim: Simulation) -> np.ndarray:
    """Index pairs of the springs that act (their kind enabled in their own
    cloth's material), model point indices, int32 (L, 2)."""
    m = sim.model
    keep = active_springs(m, sim.params)
    return np.stack([m.spring_a[keep], m.spring_b[keep]], axis=1).astype(np.int32)


def cloth_tangents(sim: Simulation) -> UvTangents:
    """The uv tangents of the simulation's mesh (every cloth)."""
    return UvTangents(sim.model.uvs, sim.model.triangles)


def cloth_vertices(sim: Simulation, out: np.ndarray | None = None,
                   tangents: UvTangents | None = None) -> np.ndarray:
    """Every cloth's packed vertices (see :mod:`.geometry`), float32 (N, 14);
    ``tangents``: the mesh's :class:`UvTangents`, made afresh when None."""
    tangents = tangents or cloth_tangents(sim)
    pos, normals = sim.positions, sim.normals
    return pack_vertices(pos, normals, tangents(pos, normals), sim.model.uvs, out)


def cloth_parts(sim: Simulation) -> tuple[tuple[int, int], ...]:
    """(first triangle, count) of each cloth: each is drawn in its own colour"""
    return tuple((c.tri_start, c.tri_stop - c.tri_start) for c in sim.model.cloths)


def cloth_mesh(sim: Simulation) -> Mesh:
    return Mesh(cloth_vertices(sim), np.asarray(sim.model.triangles), spring_lines(sim), cloth_parts(sim))


def cloth_size(model, k: int) -> float:
    """The largest side of cloth ``k``'s rest layout [m]: a grid's width or
    height, a mesh's largest side of the box around its rest points."""
    c = model.cloths[k]
    if c.grid is not None:
        return float(max(c.width, c.height))
    rest = model.rest_positions[c.points]
    return float(np.ptp(rest, axis=0).max()) if len(rest) else 0.0


def drop_size(model) -> float:
    """How far a cloth can hang below its start: the largest cloth's size [m]."""
    return max((cloth_size(model, k) for k in range(len(model.cloths))), default=0.0)


def layout_size(model) -> float:
    """The size of the whole rest layout [m]: one cloth's own, or the box
    around every cloth (the colliders' planes are drawn 2.5 of these wide)."""
    if len(model.cloths) == 1:
        return cloth_size(model, 0)
    return max(model.size, drop_size(model))


def _colliders(sim: Simulation) -> list[tuple[object, np.ndarray]]:
    """every collider with the pivot its animation turns about, in drawing order:
    spheres (``origin``), planes (``point``), boxes (``center``), mesh colliders (``pivot``)"""
    out = [(s, np.asarray(s.origin, float)) for s in sim.spheres]
    out += [(p, np.asarray(p.point, float)) for p in sim.planes]
    out += [(b, np.asarray(b.center, float)) for b in sim.boxes]
    return out + [(m, m.pivot) for m in sim.mesh_colliders]


def collider_poses(sim: Simulation, t: float | None = None) -> list[np.ndarray]:
    """Each collider's model matrix at time ``t`` [s] (default ``sim.time``), in
    the order of :func:`collider_meshes`: (4, 4) float64, ``x_now = M @ x_rest``;
    the identity for a collider without an animation."""
    t = sim.time if t is None else t
    out = []
    for spec, pivot in _colliders(sim):
        m = np.eye(4)
        if spec.animation is not None:
            m[:3, :3], m[:3, 3] = pose_at(spec.animation, pivot, t)
        out.append(m)
    return out


def _key_times(animation, now: float | None) -> list[float]:
    """when to sample a collider's pose for the framing: ``now``, else every key (rest without one)"""
    if now is not None:
        return [now]
    return [0.0] if animation is None else [k.t for k in animation.keys]


def _sphere_centres(sim: Simulation, now: float | None = None) -> list[tuple[np.ndarray, float]]:
    """(centre [m] (3,), radius [m]) of each sphere at each sampled time (:func:`_key_times`)"""
    out = []
    for s in sim.spheres:
        for t in _key_times(s.animation, now):
            R, o = pose_at(s.animation, s.origin, t)
            out.append((R @ np.asarray(s.origin, float) + o, float(s.radius)))
    return out


def _solid_corners(sim: Simulation, now: float | None = None) -> np.ndarray:
    """the corners of every box and of every mesh collider's bounding box [m],
    at each sampled time (:func:`_key_times`), (K, 3)"""
    signs = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
    shapes = [(b, np.asarray(b.center, float), (signs * b.size) @ rotation_matrices(b.rotate).T + b.center)
              for b in sim.boxes]
    for m in sim.mesh_colliders:
        lo, hi = m.vertices.min(axis=0), m.vertices.max(axis=0)
        shapes.append((m, (lo + hi) / 2.0, (lo + hi) / 2.0 + signs * (hi - lo)))
    out = [np.empty((0, 3))]
    for spec, pivot, corners in shapes:
        for t in _key_times(spec.animation, now):
            R, o = pose_at(spec.animation, pivot, t)
            out.append(corners @ R.T + o)
    return np.concatenate(out)


def _add_colliders(sim: Simulation, lo: np.ndarray, hi: np.ndarray, now: float | None) -> tuple:
    for c, r in _sphere_centres(sim, now):
        lo, hi = np.minimum(lo, c - r), np.maximum(hi, c + r)
    corners = _solid_corners(sim, now)
    if len(corners):
        lo, hi = np.minimum(lo, corners.min(axis=0)), np.maximum(hi, corners.max(axis=0))
    return lo, hi


def reach_box(sim: Simulation) -> tuple[np.ndarray, np.ndarray]:
    """Where the cloths can be: their start box and 1.25 cloth sizes (the
    largest cloth's) below it, cut at floors, plus the spheres, boxes and mesh
    colliders (wherever their animation's keys put them). Fixed per scene, so
    every frame and every run of a sweep is framed alike."""
    rest = sim.model.rest_positions
    size = drop_size(sim.model)
    lo, hi = rest.min(axis=0).copy(), rest.max(axis=0).copy()
    lo[1] -= 1.25 * size
    for p in sim.planes:
        if p.normal[1] > 0.9:
            lo[1] = max(lo[1], p.point[1])
    return _add_colliders(sim, lo, hi, None)


def current_box(sim: Simulation) -> tuple[np.ndarray, np.ndarray]:
    """Box around the cloths as they are now and the spheres, boxes and mesh colliders where they are now."""
    return _add_colliders(sim, sim.positions.min(axis=0), sim.positions.max(axis=0), sim.time)


def default_camera(sim: Simulation, fixed: bool = True) -> OrbitCamera:
    """Camera on the scene's reach box (``fixed``: same for every frame and run)
    or tight on the cloths as they are now (for a single still image); moved
    back where needed so that every cloth point (at rest when ``fixed``, else
    now), every sphere and every box and mesh collider's box is in view of a
    square image (:func:`fit_points`)."""
    target, distance = framing(*(reach_box(sim) if fixed else current_box(sim)))
    camera = OrbitCamera(target=target, distance=distance)
    points = sim.model.rest_positions if fixed else sim.positions
    now = None if fixed else sim.time
    return fit_points(camera, np.concatenate([points, _sphere_outlines(sim, camera, now),
                                              _solid_corners(sim, now)]))


def _sphere_outlines(sim: Simulation, camera: OrbitCamera, now: float | None = None) -> np.ndarray:
    """the four points of each sphere (at each sampled time, :func:`_key_times`)
    farthest along the camera's side and up axes, (4S, 3)"""
    v = camera.view()
    axes = np.array([v[0, :3], -v[0, :3], v[1, :3], -v[1, :3]])
    out = [c + r * axes for c, r in _sphere_centres(sim, now)]
    return np.concatenate(out) if out else np.empty((0, 3))


def collider_meshes(sim: Simulation, sphere_res: tuple[int, int] = (40, 40)) -> list[Mesh]:
    """Every collider's mesh in its rest pose, in the order of :func:`collider_poses`."""
    lo, hi = reach_box(sim)
    center = (lo + hi) / 2.0
    size = 2.5 * layout_size(sim.model)
    # drawn a little smaller, as the course code does, so the cloth lying on a
    # sphere is not pierced by it between its vertices
    meshes = [sphere_mesh(s.origin, SPHERE_DRAW_SCALE * s.radius, *sphere_res) for s in sim.spheres]
    meshes += [plane_mesh(p.point, p.normal, center, size) for p in sim.planes]
    meshes += [box_mesh(b.center, np.maximum(np.asarray(b.size) - 2 * DRAW_INSET, 0.5 * np.asarray(b.size)),
                        rotation_matrices(b.rotate)) for b in sim.boxes]
    meshes += [triangle_mesh(_inset(m), m.triangles) for m in sim.mesh_colliders]
    return meshes


def _inset(collider) -> np.ndarray:
    """a closed mesh collider's vertices moved DRAW_INSET inward along their normals;
    an open one's as they are (it is two-sided: cloth may rest on either side)"""
    if not collider.closed:
        return collider.vertices
    from ..mesh import compute_normals

    return collider.vertices - DRAW_INSET * compute_normals(collider.vertices, collider.triangles)


class SimulationView:
    """Keeps a Renderer's buffers in step with a Simulation."""

    def __init__(self, renderer: Renderer, sim: Simulation, sphere_res: tuple[int, int] = (40, 40)) -> None:
        self.renderer = renderer
        self.sphere_res = sphere_res
        self.attach(sim)

    def attach(self, sim: Simulation) -> None:
        self.sim = sim
        self._enabled = enabled_kinds(sim.params).tobytes()
        self._tangents = cloth_tangents(sim)
        self._vertices = cloth_vertices(sim, tangents=self._tangents)
        self.renderer.set_cloth(Mesh(self._vertices, np.asarray(sim.model.triangles), spring_lines(sim),
                                     cloth_parts(sim)))
        self.refresh_colliders()

    def set_sphere_res(self, res: tuple[int, int]) -> None:
        self.sphere_res = res
        self.refresh_colliders()

    def refresh_colliders(self) -> None:
        """Rebuild the colliders' meshes (a collider added, removed or resized)."""
        self._collider_count = _collider_count(self.sim)
        self.renderer.set_colliders(collider_meshes(self.sim, self.sphere_res))

    def sync(self) -> None:
        """Upload this frame's vertices and put the colliders where they are at
        ``sim.time``; rebuild the spring lines only if a toggle changed, the
        collider meshes only if a collider was added or removed."""
        if _collider_count(self.sim) != self._collider_count:
            self.refresh_colliders()
        self.renderer.set_collider_poses(collider_poses(self.sim))
        enabled = enabled_kinds(self.sim.params).tobytes()
        if enabled != self._enabled:
            self._enabled = enabled
            self.renderer.set_cloth_lines(spring_lines(self.sim))
        self.renderer.update_cloth(cloth_vertices(self.sim, self._vertices, self._tangents))


def _collider_count(sim: Simulation) -> tuple[int, int, int, int]:
    return len(sim.spheres), len(sim.planes), len(sim.boxes), len(sim.mesh_colliders)
