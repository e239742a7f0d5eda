"""The model: everything about the cloths that does not change while they run.

Built once, by a builder (:func:`build_model` makes a grid cloth from a
:class:`~clothsim.scene.ClothSpec`); a reset restores the state from it and
changing ks or the spring toggles never rebuilds it. The model holds any
number of cloths, each a range of the points, and springs as plain lists of
ends, so that a cloth need not be a grid; the solver takes the grid's
strides as a fast path where a cloth has them (:attr:`Cloth.grid`).
Arrays are structure-of-arrays so that the solver kernels take them directly.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .mesh_cloth import mesh_cloth_parts
from .scene import ClothSpec, MeshClothSpec, Scene

STRUCTURAL, SHEARING, BENDING = 0, 1, 2
SPRING_KINDS = ("structural", "shearing", "bending")


@dataclass(frozen=True)
class Cloth:
    """One cloth of a model: its points are ``start:stop`` of the model's."""

    start: int
    stop: int
    thickness: float
    """[m]: its points keep twice this apart in self-collision"""
    area: float
    """[m²]: its points share it evenly as CS184 does (mass = area x density / points)"""
    grid: tuple[int, int] | None
    """(rows, columns) when its points are a row-major grid whose springs are
    the grid's own (the solver's stencil fast path), else None"""
    width: float
    """extent of the rest layout along its first axis [m]"""
    height: float
    """extent of the rest layout along its second axis [m]"""
    tri_start: int = 0
    """its triangles are ``tri_start:tri_stop`` of the model's"""
    tri_stop: int = 0
    name: str = "cloth"
    """what exports call it (the OBJ object, the USD prim): unique in a model"""

    @property
    def num_points(self) -> int:
        return self.stop - self.start

    @property
    def points(self) -> slice:
        """its points in the model's arrays"""
        return slice(self.start, self.stop)

    @property
    def triangle_range(self) -> slice:
        """its triangles in ``Model.triangles``"""
        return slice(self.tri_start, self.tri_stop)

    def point_mass(self, density: float) -> float:
        """mass of one of its points [density units x m²] at ``density``, as CS184
        computes it: the area shared evenly (density is a live parameter)"""
        return self.area * density / self.num_points


@dataclass(frozen=True)
class Model:
    cloths: tuple[Cloth, ...]
    """the cloths, in scene order, their points one after another"""
    rest_positions: np.ndarray
    """start positions of the point masses [m], float64 (N, 3), row-major (j is the row)"""
    pinned: np.ndarray
    """True where a point never moves, bool (N,)"""
    spring_a: np.ndarray
    """first end of each spring, int32 (S,)"""
    spring_b: np.ndarray
    """second end of each spring, int32 (S,)"""
    spring_rest: np.ndarray
    """rest length of each spring [m], float64 (S,)"""
    spring_kind: np.ndarray
    """STRUCTURAL, SHEARING or BENDING, int8 (S,); springs are sorted by kind"""
    kind_start: np.ndarray
    """springs of kind k are ``kind_start[k] : kind_start[k+1]``, int64 (4,)"""
    triangles: np.ndarray
    """model point indices, int32 (T, 3), each cloth's in its ``triangle_range``; for a
    grid two per cell, counter-clockwise seen from +y / -z"""
    uvs: np.ndarray
    """texture coordinates in [0, 1]², float32 (N, 2)"""

    @property
    def num_points(self) -> int:
        return self.rest_positions.shape[0]

    @property
    def num_springs(self) -> int:
        return self.spring_a.shape[0]

    @property
    def cloth(self) -> Cloth:
        """the only cloth; a model of several has no single one"""
        if len(self.cloths) != 1:
            raise ValueError(f"the model has {len(self.cloths)} cloths, not one")
        return self.cloths[0]

    @property
    def thickness(self) -> float:
        """the cloth's thickness [m]"""
        return self.cloth.thickness

    @property
    def width(self) -> float:
        return self.cloth.width

    @property
    def height(self) -> float:
        return self.cloth.height

    @property
    def size(self) -> float:
        """the largest side of the box around the rest layout [m]"""
        return float(np.ptp(self.rest_positions, axis=0).max()) if self.num_points else 0.0

    @property
    def num_width_points(self) -> int:
        """grid columns of the only cloth"""
        return self._grid()[1]

    @property
    def num_height_points(self) -> int:
        """grid rows of the only cloth"""
        return self._grid()[0]

    def index(self, i: int, j: int) -> int:
        """Row-major index of grid point (i along width, j along height)."""
        return self.cloth.start + j * self.num_width_points + i

    def _grid(self) -> tuple[int, int]:
        if self.cloth.grid is None:
            raise ValueError("the cloth is not a grid")
        return self.cloth.grid




def grid_positions(spec: ClothSpec, seed: int = 0) -> np.ndarray:
    """Start positions by orientation, as the CS184 format defines them."""
    nw, nh = spec.num_width_points, spec.num_height_points
    i = np.tile(np.arange(nw), nh)
    j = np.repeat(np.arange(nh), nw)
    pos = np.empty((nw * nh, 3), dtype=np.float64)
    pos[:, 0] = i * (spec.width / (nw - 1))
    if spec.orientation == 0:
        pos[:, 1] = 1.0
        pos[:, 2] = j * (spec.height / (nh - 1))
    else:
        pos[:, 1] = j * (spec.height / (nh - 1))
        pos[:, 2] = np.random.default_rng(seed).uniform(-0.001, 0.001, nw * nh)
    return pos


def grid_springs(nw: int, nh: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Springs of a grid: (a, b, kind), grouped by kind.

    Structural to the left and upper neighbour, shearing to the upper-left and
    upper-right diagonal, bending to the point two left and two above.
    """
    idx = np.arange(nw * nh).reshape(nh, nw)
    pairs = [
        (STRUCTURAL, idx[:, 1:], idx[:, :-1]),     # left
        (STRUCTURAL, idx[1:, :], idx[:-1, :]),     # up
        (SHEARING, idx[1:, 1:], idx[:-1, :-1]),    # upper-left
        (SHEARING, idx[1:, :-1], idx[:-1, 1:]),    # upper-right
        (BENDING, idx[:, 2:], idx[:, :-2]),        # two left
        (BENDING, idx[2:, :], idx[:-2, :]),        # two up
    ]
    a = np.concatenate([p[1].ravel() for p in pairs]).astype(np.int32)
    b = np.concatenate([p[2].ravel() for p in pairs]).astype(np.int32)
    kind = np.concatenate([np.full(p[1].size, p[0], dtype=np.int8) for p in pairs])
    return a, b, kind


def grid_triangles(nw: int, nh: int) -> np.ndarray:
    """Two triangles per cell, wound so horizontal cloth faces +y."""
    idx = np.arange(nw * nh).reshape(nh, nw)
    p00, p10 = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    p01, p11 = idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    t1 = np.stack([p00, p01, p10], axis=1)
    t2 = np.stack([p10, p01, p11], axis=1)
    return np.concatenate([t1, t2]).astype(np.int32)


def build_model(spec: ClothSpec, seed: int = 0) -> Model:
    """The model of one grid cloth, as CS184 lays it out."""
    nw, nh = spec.num_width_points, spec.num_height_points
    pos = grid_positions(spec, seed)
    pinned = np.zeros(nw * nh, dtype=bool)
    for i, j in spec.pinned:
        pinned[j * nw + i] = True
    a, b, kind = grid_springs(nw, nh)
    rest = np.linalg.norm(pos[a] - pos[b], axis=1)
    u = np.tile(np.arange(nw) / (nw - 1), nh)
    v = np.repeat(np.arange(nh) / (nh - 1), nw)
    uvs = np.stack([u, v], axis=1).astype(np.float32)
    for arr in (pos, pinned, a, b, rest, kind, uvs):
        arr.setflags(write=False)
    kind_start = np.searchsorted(kind, np.arange(len(SPRING_KINDS) + 1)).astype(np.int64)
    tris = grid_triangles(nw, nh)
    for arr in (kind_start, tris):
        arr.setflags(write=False)
    cloth = Cloth(0, nw * nh, spec.thickness, spec.width * spec.height, (nh, nw), spec.width, spec.height,
                  0, len(tris))
    return Model((cloth,), pos, pinned, a, b, rest, kind, kind_start, tris, uvs)


def concatenate(models: list[Model], names: list[str] | None = None) -> Model:
    """One model holding the cloths of ``models`` one after another, in order:
    points, triangles and springs renumbered, springs sorted by kind again
    (stably: within a kind, in model order). ``names``: one per cloth, else
    ``cloth``, ``cloth_1``, ... A single model is returned as it is, renamed."""
    cloths = [c for m in models for c in m.cloths]
    if names is None:
        names = ["cloth" if k == 0 else f"cloth_{k}" for k in range(len(cloths))]
    if len(models) == 1:
        renamed = tuple(replace(c, name=n) for c, n in zip(models[0].cloths, names))
        return replace(models[0], cloths=renamed)
    point_base = np.cumsum([0] + [m.num_points for m in models])
    tri_base = np.cumsum([0] + [len(m.triangles) for m in models])
    out, k = [], 0
    for m, pb, tb in zip(models, point_base, tri_base):
        for c in m.cloths:
            out.append(replace(c, start=c.start + int(pb), stop=c.stop + int(pb), tri_start=c.tri_start + int(tb),
                               tri_stop=c.tri_stop + int(tb), name=names[k]))
            k += 1
    a = np.concatenate([m.spring_a.astype(np.int64) + pb for m, pb in zip(models, point_base)])
    b = np.concatenate([m.spring_b.astype(np.int64) + pb for m, pb in zip(models, point_base)])
    rest = np.concatenate([m.spring_rest for m in models])
    kind = np.concatenate([m.spring_kind for m in models])
    order = np.argsort(kind, kind="stable")
    arrays = dict(
        rest_positions=np.concatenate([m.rest_positions for m in models]),
        pinned=np.concatenate([m.pinned for m in models]),
        spring_a=a[order].astype(np.int32), spring_b=b[order].astype(np.int32),
        spring_rest=rest[order], spring_kind=kind[order],
        kind_start=np.searchsorted(kind[order], np.arange(len(SPRING_KINDS) + 1)).astype(np.int64),
        triangles=np.concatenate([m.triangles.astype(np.int64) + pb for m, pb in zip(models, point_base)]
                                 ).astype(np.int32),
        uvs=np.concatenate([m.uvs for m in models]))
    for arr in arrays.values():
        arr.setflags(write=False)
    return Model(cloths=tuple(out), **arrays)


def build_scene_model(scene: Scene) -> Model:
    """The model of every cloth of a scene, in scene order (see :func:`concatenate`)."""
    return concatenate([_build_one(spec, scene.simulation.seed + k) for k, spec in enumerate(scene.cloths)],
                       cloth_names(scene))


def _build_one(spec: ClothSpec | MeshClothSpec, seed: int) -> Model:
    if isinstance(spec, MeshClothSpec):
        return build_mesh_model(spec)
    return build_model(spec, seed)


def build_mesh_model(spec: MeshClothSpec) -> Model:
    """The model of one mesh cloth (its parts from :func:`clothsim.mesh_cloth.mesh_cloth_parts`)."""
    parts = mesh_cloth_parts(spec)
    pairs = np.concatenate(parts.springs)
    kind = np.concatenate([np.full(len(p), k, dtype=np.int8) for k, p in enumerate(parts.springs)])
    pos = parts.positions.copy()
    arrays = dict(rest_positions=pos, pinned=parts.pinned,
                  spring_a=pairs[:, 0].astype(np.int32), spring_b=pairs[:, 1].astype(np.int32),
                  spring_rest=np.linalg.norm(pos[pairs[:, 0]] - pos[pairs[:, 1]], axis=1), spring_kind=kind,
                  kind_start=np.searchsorted(kind, np.arange(len(SPRING_KINDS) + 1)).astype(np.int64),
                  triangles=parts.triangles.astype(np.int32), uvs=parts.uvs.astype(np.float32))
    # contiguous, as the grid builder's are: the kernels are compiled for one layout
    arrays = {k: np.ascontiguousarray(v) for k, v in arrays.items()}
    for arr in arrays.values():
        arr.setflags(write=False)
    cloth = Cloth(0, len(parts.positions), spec.thickness, parts.area, None, parts.width, parts.height,
                  0, len(parts.triangles))
    return Model(cloths=(cloth,), **arrays)


def cloth_names(scene: Scene) -> list[str]:
    """The export names of a scene's cloths: ``cloth`` alone, else ``cloth_0``, ``cloth_1``, ..."""
    n = len(scene.cloths)
    return ["cloth"] if n == 1 else [f"cloth_{k}" for k in range(n)]
