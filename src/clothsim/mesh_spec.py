"""A cloth made from a mesh file, as a scene names it (``shared/scene-format.md``,
"Cloth from a mesh").

numpy and the mesh readers load only when a scene has a mesh cloth (the
command line's ``--help`` loads no numpy). The mesh is loaded while the scene is parsed (:func:`parse_mesh_cloth`), so
that a missing, unreadable, empty, degenerate or non-manifold mesh and a pin
outside it are scene errors at load, naming the scene file, the key and the
mesh file; the spec then holds the checked mesh (:class:`MeshData`) after its
transform.
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from .scene_limits import DENSITY_MAX, DENSITY_MIN, KS_MAX, LENGTH_MAX, LENGTH_MIN, POINTS_MAX
from .scene_reader import Reader, Vec3, describe
from .transform import MeshTransform, parse_transform

if TYPE_CHECKING:

    from .meshfile import MeshData

GRID_KEYS = ("width", "height", "num_width_points", "num_height_points", "orientation", "pinned")
MATERIAL_DEFAULTS: dict[str, Any] = {"damping": 0.2, "density": 150.0, "ks": 5000.0, "enable_structural": True,
                                     "enable_shearing": True, "enable_bending": True}
MESH_KEYS = {"mesh", "transform", "pinned_vertices", "pinned_region", "thickness", "handles"} | set(MATERIAL_DEFAULTS)


@dataclass
class MeshClothSpec:
    """A cloth whose points, faces and springs come from a mesh file."""

    mesh: str
    """the file as the scene writes it"""
    path: str
    """the file: ``mesh`` relative to the scene file's folder (to the working
    folder for a scene that has no file)"""
    thickness: float
    """self-collision keeps points ``2*thickness`` apart [m]"""
    transform: MeshTransform = field(default_factory=MeshTransform)
    pinned_vertices: list[int] = field(default_factory=list)
    """vertex indices of the file (0-based, file order) that never move"""
    pinned_region: tuple[Vec3, Vec3] | None = None
    """(min, max) corners [m]: every point inside the box (after the transform) is pinned"""
    damping: float = 0.2
    """percent of velocity removed per substep"""
    density: float = 150.0
    """g/cm² as in CS184; sets the mass of each point"""
    ks: float = 5000.0
    """spring constant [N/m]; bending springs use 0.2*ks"""
    enable_structural: bool = True
    enable_shearing: bool = True
    enable_bending: bool = True
    handles: list = field(default_factory=list)
    """groups of vertices moved by an animation (:class:`~clothsim.world_spec.HandleSpec`)"""
    data: MeshData | None = field(default=None, compare=False, repr=False)
    """the mesh as loaded: welded, checked and transformed"""

    def to_dict(self) -> dict[str, Any]:
        """The scene keys of this cloth (what :func:`parse_mesh_cloth` reads back)."""
        out: dict[str, Any] = {"mesh": self.mesh, "thickness": self.thickness,
                               "transform": self.transform.to_dict()}
        if self.pinned_vertices:
            out["pinned_vertices"] = list(self.pinned_vertices)
        if self.pinned_region is not None:
            out["pinned_region"] = {"min": list(self.pinned_region[0]), "max": list(self.pinned_region[1])}
        out.update({name: getattr(self, name) for name in MATERIAL_DEFAULTS})
        if self.handles:
            out["handles"] = [h.to_dict() for h in self.handles]
        return out


def is_mesh_cloth(raw: Any) -> bool:
    """True for a cloth object of a scene that names a mesh."""
    return isinstance(raw, dict) and "mesh" in raw


def parse_mesh_cloth(r: Reader, c: dict[str, Any], key: str) -> MeshClothSpec:
    """Validate the mesh cloth ``c`` at key path ``key`` and load its mesh."""
    # here, not at the top: numpy only for a scene that has a mesh
    from .meshfile import MeshFileError, load_mesh
    from .world_reader import parse_mesh_handles

    for name in c:
        if name in GRID_KEYS:
            raise r.fail(f"{key}.{name}", "a mesh cloth (one with 'mesh') has no grid keys; "
                                          f"drop {name!r} or 'mesh'")
    r.keys(c, key, MESH_KEYS, ("mesh", "thickness"), lenient=True)
    mesh = c["mesh"]
    if not isinstance(mesh, str) or not mesh:
        raise r.fail(f"{key}.mesh", f"expected the name of a mesh file, got {describe(mesh)}")
    shown = os.path.normpath(os.path.join(os.path.dirname(r.source), mesh)) if r.source else mesh
    transform = parse_transform(r, c.get("transform", {}), f"{key}.transform")
    try:
        data = load_mesh(os.path.abspath(shown), transform.apply)
    except MeshFileError as exc:
        raise r.fail(f"{key}.mesh", f"{shown}: {exc}") from None
    _check_extent(r, data, f"{key}.mesh", shown)
    for count, what in ((data.num_welded, "welded onto another at the same position"),
                        (data.num_unused, "dropped: in no face")):
        if count:
            print(f"clothsim: warning: {r.source or '<scene>'}: {key}.mesh: {shown}: {count} "
                  f"{'vertex' if count == 1 else 'vertices'} {what}", file=sys.stderr)
    material = {name: c.get(name, default) for name, default in MATERIAL_DEFAULTS.items()}
    pinned = _pinned_vertices(r, c.get("pinned_vertices", []), f"{key}.pinned_vertices", data, shown)
    return MeshClothSpec(
        mesh=mesh,
        path=os.path.abspath(shown),
        thickness=r.number(c["thickness"], f"{key}.thickness", lo=LENGTH_MIN, hi=LENGTH_MAX),
        transform=transform,
        pinned_vertices=pinned,
        pinned_region=_region(r, c["pinned_region"], f"{key}.pinned_region") if "pinned_region" in c else None,
        damping=r.number(material["damping"], f"{key}.damping", lo=0, hi=100),
        density=r.number(material["density"], f"{key}.density", lo=DENSITY_MIN, hi=DENSITY_MAX),
        ks=r.number(material["ks"], f"{key}.ks", lo=0, hi=KS_MAX),
        enable_structural=r.boolean(material["enable_structural"], f"{key}.enable_structural"),
        enable_shearing=r.boolean(material["enable_shearing"], f"{key}.enable_shearing"),
        enable_bending=r.boolean(material["enable_bending"], f"{key}.enable_bending"),
        handles=parse_mesh_handles(r, c["handles"], f"{key}.handles", data, shown, pinned) if "handles" in c else [],
        data=data,
    )


def _check_extent(r: Reader, data: MeshData, key: str, shown: str) -> None:
    """At most POINTS_MAX points, each within ±LENGTH_MAX m after the transform."""
    if len(data.vertices) > POINTS_MAX:
        raise r.fail(key, f"{shown}: expected at most {POINTS_MAX:,} points, got {len(data.vertices):,}")
    extent = float(abs(data.vertices).max()) if len(data.vertices) else 0.0
    if not extent <= LENGTH_MAX:  # inf and nan too
        raise r.fail(key, f"{shown}: expected every point within ±{LENGTH_MAX:g} m after the transform, "
                          f"got one at {extent:g}")


def _pinned_vertices(r: Reader, raw: Any, key: str, data: MeshData, shown: str) -> list[int]:
    if not isinstance(raw, list):
        raise r.fail(key, f"expected a list of vertex indices, got {describe(raw)}")
    out = []
    n = data.num_file_vertices
    for k, item in enumerate(raw):
        index = r.integer(item, f"{key}[{k}]")
        if not 0 <= index < n:
            raise r.fail(f"{key}[{k}]", f"expected a vertex index of {shown} (0..{n - 1}), got {index}")
        if data.file_to_point[index] < 0:
            raise r.fail(f"{key}[{k}]", f"vertex {index} of {shown} is in no face")
        out.append(index)
    return out


def _region(r: Reader, raw: Any, key: str) -> tuple[Vec3, Vec3]:
    box = r.obj(raw, key)
    r.keys(box, key, {"min", "max"}, ("min", "max"))
    lo, hi = r.vec3(box["min"], f"{key}.min", LENGTH_MAX), r.vec3(box["max"], f"{key}.max", LENGTH_MAX)
    for axis, a, b in zip("xyz", lo, hi):
        if a > b:
            raise r.fail(key, f"expected min <= max on every axis, got {axis} min {a:g} > max {b:g}")
    return lo, hi
