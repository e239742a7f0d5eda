"""USD export: a run as one time-sampled stage, for Blender, Houdini, Omniverse, usdview.

Layout of the stage (``/World`` is the default prim)::

    /World                      Xform
    /World/Cloth                Mesh: points, normals and extent sampled at every frame,
                                faceVertexCounts/Indices once, primvars:st (vertex uvs),
                                primvars:displayColor, subdivisionScheme "none"
    /World/Cloths/NAME          (a scene of several cloths, instead of /World/Cloth) one
                                such Mesh per cloth, named by the cloth's name (cloth_0,
                                cloth_1, ...; made a valid prim name), its own points and
                                faces (indices into its own points), in scene order
    /World/Colliders            Scope
    /World/Colliders/Sphere_0   Sphere: radius, xformOp:translate (the origin)
    /World/Colliders/Plane_0    Plane (axis "Y"), xformOp:translate + xformOp:orient
                                turning +y onto the plane's normal; a square 2.5 cloth
                                sizes wide around the cloth's reach, as the renderer draws it

Frame ``k`` of the trajectory is time code ``k``; ``timeCodesPerSecond`` and
``framesPerSecond`` are the run's frames per simulated second and the range is
``0 .. F-1``, so a DCC plays it at its real speed. Metres (``metersPerUnit = 1``),
y up. The layer's ``customLayerData`` holds the scene name (``clothsim:scene``), the
parameters in one line (``clothsim:description``) and the whole scene as JSON
(``clothsim:sceneJson``); its doc string says the same in words.

Each cloth's mesh carries ``clothsim:name`` (the cloth's name) and
``clothsim:firstPoint`` (where its points start in the run's concatenated
points: the NumPy export's ``cloth_start``). The colliders carry their
friction as the custom attribute ``clothsim:friction``.
Colliders do not move in a clothsim run, so they hold no time samples.

Orientation: the triangles are counter-clockwise seen from the front (the side
their vertex normals point to, which the renderer treats as the front face), which
is USD's ``rightHanded``, its fallback; it is written out anyway. Points and normals
are single precision (``point3f[]``, as the schema types them): positions within
8 m of the origin keep 1e-6 m.

``.usda`` is text, ``.usdc`` binary (crate); ``.usd`` is written as crate too.
``pxr`` (the ``usd-core`` package) is imported only when a file is written.
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..mesh import compute_normals
from ..outputs import OutputError, check_writable

if TYPE_CHECKING:
    from ..trajectory import Trajectory

USD_FORMATS = {".usda": "usda", ".usdc": "usdc", ".usd": "usdc"}
"""file extension -> the layer format written (``.usd`` holds binary crate)"""

CLOTH_COLOR = (0.80, 0.22, 0.20)
"""the renderer's default cloth colour (``DrawSettings.color``), linear RGB"""
COLLIDER_COLOR = (0.78, 0.78, 0.80)
"""the renderer's collider colour (``render.renderer.COLLIDER_COLOR``)"""
PLANE_SIZE = 2.5
"""a plane is drawn this many cloth sizes wide, as the renderer draws it"""


def usd_format(path: str | Path) -> str:
    """The layer format for ``path``'s extension (``usda`` or ``usdc``);
    :class:`OutputError` for any other extension."""
    suffix = Path(path).suffix.lower()
    if suffix not in USD_FORMATS:
        raise OutputError(f"{path}: unknown USD extension {Path(path).suffix or '(none)'!r}; "
                          f"expected {', '.join(USD_FORMATS)}")
    return USD_FORMATS[suffix]


def check_usd_path(path: str | Path, overwrite: bool = False) -> Path:
    """Fail before any work when ``path`` cannot take a USD file: an unknown
    extension, an existing file without ``overwrite``, a folder that does not
    exist, is a file, or cannot be written (tried with a probe file, removed at
    once); and when ``pxr`` is not installed."""
    import importlib.util

    path = Path(path)
    usd_format(path)
    if importlib.util.find_spec("pxr") is None:
        raise OutputError(f"{path}: writing USD needs the usd-core package (pip install usd-core)")
    check_writable(path, overwrite)
    folder = path.parent
    if not folder.is_dir():
        raise OutputError(f"{path}: {folder} is not a folder")
    try:
        fd, probe = tempfile.mkstemp(prefix=f".{path.stem}-probe-", suffix=path.suffix, dir=folder)
    except OSError as exc:
        raise OutputError(f"{path}: cannot write in {folder} ({exc.strerror or exc})") from None
    os.close(fd)
    os.unlink(probe)
    return path


def write_usd(path: str | Path, traj: Trajectory) -> None:
    """Write ``traj`` to ``path`` as a time-sampled USD stage (see the module doc).

    Writes exactly ``path``, in the format of its extension; callers that want
    no partial file write a temporary path and move it (as ``FrameRecorder`` does).
    """
    stage = StageBuilder(traj)
    for k in range(traj.num_frames):
        stage.add(traj.positions[k])
    stage.finish(path, traj)


def cloth_prim_paths(names: list[str]) -> list[str]:
    """The prim path of each cloth's Mesh: ``/World/Cloth`` for one cloth, else
    ``/World/Cloths/NAME`` with each name made a valid, unique prim name."""
    from pxr import Tf

    if len(names) == 1:
        return ["/World/Cloth"]
    out, seen = [], set()
    for name in names:
        base = Tf.MakeValidIdentifier(str(name)) or "cloth"
        ident, k = base, 1
        while ident in seen:
            ident, k = f"{base}_{k}", k + 1
        seen.add(ident)
        out.append(f"/World/Cloths/{ident}")
    return out


class StageBuilder:
    """A stage built frame by frame, so that a run's frames can go in while it runs
    (``FrameRecorder`` feeds one from a thread beside the substeps, which release
    the GIL): each cloth's topology and uvs from ``start``, a trajectory of the
    run's first frame; their points, normals and extent at each :meth:`add`; the
    frame range, the colliders and the file at :meth:`finish`."""

    def __init__(self, start: Trajectory) -> None:
        from pxr import Sdf, Usd, UsdGeom, Vt

        self._pxr = Sdf, Usd, UsdGeom, Vt
        self.triangles = np.ascontiguousarray(start.triangles, dtype=np.int32)
        self.layer = Sdf.Layer.CreateAnonymous("clothsim.usdc")
        self.stage = Usd.Stage.Open(self.layer)
        world = UsdGeom.Xform.Define(self.stage, "/World")
        self.stage.SetDefaultPrim(world.GetPrim())
        parts = start.parts
        paths = cloth_prim_paths([c.name for c in parts])
        if len(parts) > 1:
            UsdGeom.Scope.Define(self.stage, "/World/Cloths")
        uvs = np.ascontiguousarray(start.uvs, dtype=np.float32)
        self.cloths = []  # (points slice, points attr, normals attr, extent attr)
        for cloth, path in zip(parts, paths):
            mesh = UsdGeom.Mesh.Define(self.stage, path)
            tris = np.ascontiguousarray(self.triangles[cloth.triangle_range] - cloth.start, dtype=np.int32)
            mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(tris), 3, dtype=np.int32)))
            mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(tris.ravel()))
            mesh.CreateOrientationAttr(UsdGeom.Tokens.rightHanded)
            mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)  # a polygon cloth, its normals as given
            mesh.CreateDoubleSidedAttr(True)  # both sides are seen, as the renderer draws them
            mesh.CreateDisplayColorAttr(Vt.Vec3fArray([CLOTH_COLOR]))
            st = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                                         UsdGeom.Tokens.vertex)
            st.Set(Vt.Vec2fArray.FromNumpy(np.ascontiguousarray(uvs[cloth.points])))
            mesh.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
            prim = mesh.GetPrim()
            prim.CreateAttribute("clothsim:name", Sdf.ValueTypeNames.String, custom=True).Set(str(cloth.name))
            prim.CreateAttribute("clothsim:firstPoint", Sdf.ValueTypeNames.Int, custom=True).Set(int(cloth.start))
            self.cloths.append((cloth.points, mesh.CreatePointsAttr(), mesh.CreateNormalsAttr(),
                                mesh.CreateExtentAttr()))
        self.frames = 0

    def add(self, positions: np.ndarray) -> None:
        """The next frame's point positions [m], (N, 3), every cloth's: one bulk
        copy per attribute and cloth (FromNumpy), the extent in C++; no
        per-point Python."""
        Sdf, Usd, UsdGeom, Vt = self._pxr
        t = Usd.TimeCode(float(self.frames))
        positions = np.ascontiguousarray(positions, dtype=np.float64)
        normals = compute_normals(positions, self.triangles).astype(np.float32)
        with Sdf.ChangeBlock():  # setting values (not defining prims) is safe inside one
            for points, p_attr, n_attr, e_attr in self.cloths:
                frame = Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(positions[points], dtype=np.float32))
                p_attr.Set(frame, t)
                n_attr.Set(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(normals[points])), t)
                e_attr.Set(UsdGeom.PointBased.ComputeExtent(frame), t)
        self.frames += 1

    def finish(self, path: str | Path, traj: Trajectory) -> None:
        """Write the stage to ``path`` in its extension's format; ``traj`` is the
        whole run (its colliders and their reach, its name and parameters)."""
        Sdf, Usd, UsdGeom, Vt = self._pxr
        path = Path(path)
        fmt = usd_format(path)
        stage, layer, frames = self.stage, self.layer, self.frames
        fps = float(traj.frames_per_sec)
        stage.SetStartTimeCode(0.0)
        stage.SetEndTimeCode(float(max(frames - 1, 0)))
        stage.SetTimeCodesPerSecond(fps)
        stage.SetFramesPerSecond(fps)
        UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
        UsdGeom.SetStageMetersPerUnit(stage, 1.0)
        layer.documentation = (f"clothsim run of scene {traj.name!r}: {frames} frames at {fps:g} frames/s"
                               + (f"; {traj.description}" if traj.description else ""))
        layer.customLayerData = {"clothsim:scene": traj.name, "clothsim:description": traj.description,
                                 "clothsim:sceneJson": json.dumps(traj.scene, sort_keys=True),
                                 "clothsim:framesPerSecond": fps, "clothsim:frames": frames}
        _define_colliders(stage, traj, Sdf, UsdGeom, Vt)
        args = {"format": fmt} if path.suffix.lower() == ".usd" else {}
        if not layer.Export(str(path), args=args):
            raise OutputError(f"{path}: USD could not write the file")


def _define_colliders(stage, traj: Trajectory, Sdf, UsdGeom, Vt) -> None:
    from pxr import Gf

    if not (traj.spheres or traj.planes):
        return
    UsdGeom.Scope.Define(stage, "/World/Colliders")
    for i, s in enumerate(traj.spheres):
        sphere = UsdGeom.Sphere.Define(stage, f"/World/Colliders/Sphere_{i}")
        r = float(s.radius)
        sphere.CreateRadiusAttr(r)
        sphere.CreateExtentAttr(Vt.Vec3fArray([(-r, -r, -r), (r, r, r)]))
        sphere.AddTranslateOp().Set(Gf.Vec3d(*map(float, s.origin)))
        _collider_extras(sphere, s.friction, Sdf, Vt)

    if traj.planes:
        pos = traj.positions
        size = PLANE_SIZE * float(np.max(pos[0].max(axis=0) - pos[0].min(axis=0)))
        lo, hi = pos.min(axis=(0, 1)), pos.max(axis=(0, 1))
        for s in traj.spheres:
            lo = np.minimum(lo, np.asarray(s.origin) - s.radius)
            hi = np.maximum(hi, np.asarray(s.origin) + s.radius)
        center = (lo + hi) / 2.0
    for i, p in enumerate(traj.planes):
        n = np.asarray(p.normal, float)
        n /= np.linalg.norm(n)
        point = np.asarray(p.point, float)
        c = center - np.dot(center - point, n) * n  # the reach's centre, on the plane
        plane = UsdGeom.Plane.Define(stage, f"/World/Colliders/Plane_{i}")
        plane.CreateAxisAttr(UsdGeom.Tokens.y)
        plane.CreateWidthAttr(size)
        plane.CreateLengthAttr(size)
        plane.CreateDoubleSidedAttr(True)
        plane.CreateExtentAttr(Vt.Vec3fArray([(-size / 2, 0, -size / 2), (size / 2, 0, size / 2)]))
        plane.AddTranslateOp().Set(Gf.Vec3d(*c))
        plane.AddOrientOp(UsdGeom.XformOp.PrecisionDouble).Set(
            Gf.Rotation(Gf.Vec3d(0, 1, 0), Gf.Vec3d(*n)).GetQuat())
        plane.GetPrim().CreateAttribute("clothsim:point", Sdf.ValueTypeNames.Point3d, custom=True).Set(
            Gf.Vec3d(*point))
        plane.GetPrim().CreateAttribute("clothsim:normal", Sdf.ValueTypeNames.Normal3d, custom=True).Set(
            Gf.Vec3d(*n))
        _collider_extras(plane, p.friction, Sdf, Vt)


def _collider_extras(gprim, friction: float, Sdf, Vt) -> None:
    gprim.CreateDisplayColorAttr(Vt.Vec3fArray([COLLIDER_COLOR]))
    gprim.GetPrim().CreateAttribute("clothsim:friction", Sdf.ValueTypeNames.Double, custom=True).Set(
        float(friction))


__all__ = ["USD_FORMATS", "StageBuilder", "check_usd_path", "cloth_prim_paths", "usd_format", "write_usd"]
