"""Wavefront OBJ export of the cloth mesh: one frame, or a sequence of them.

A file holds, in this order, a comment line, the ``v`` lines (positions [m],
``%.9g``), the ``vt`` lines (``%.6g``), the ``vn`` lines (unit normals,
``%.6g``) and the ``f`` lines (``f a/a/a b/b/b c/c/c``: v, vt and vn share the
index, 1-based, counter-clockwise seen from the front); vertices in the
model's order (every cloth's points in scene order: a grid's row-major, a
mesh's in its file's order). A scene of several cloths gets one object per
cloth: the vertex lines of all cloths come first (OBJ's vertex lists are
global to the file), then each cloth's ``o NAME`` line and its own faces,
which use only its own vertices; trimesh and Blender split the file into one
mesh per object. A single cloth's file has no ``o`` line, as before.
The text is byte for byte what ``np.savetxt`` with those
formats writes, made by a compiled formatter (:mod:`.objtext`), with the
``vt`` and ``f`` lines made once per mesh: a frame of 2,500 points takes 0.7 ms
(np.savetxt: 17 ms).

:class:`~clothsim.export.objseq.ObjSequence` writes one such file per frame and,
on POSIX, formats and writes them in a background thread whose work holds no
GIL, so a sequence costs the simulation little more than copying each frame.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..outputs import write_atomic

HEADER = b"# clothsim cloth mesh\n"


def _objtext():
    from . import objtext  # numba: on first use only

    return objtext


def compute_normals(positions: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    from ..mesh import compute_normals  # numba: on first use only

    return compute_normals(positions, triangles)


Objects = tuple[tuple[str, int, int], ...]
"""OBJ objects: (name, first triangle, end triangle) each, the triangles in order"""


def model_objects(model) -> Objects | None:
    """One OBJ object per cloth of ``model`` (its name and triangle range), or
    None for a model of one cloth (its file has no ``o`` line)."""
    if len(model.cloths) == 1:
        return None
    return tuple((c.name, c.tri_start, c.tri_stop) for c in model.cloths)


def _object_name(name: str) -> str:
    """an ``o`` line's name: one word (white space turned into ``_``)"""
    return "_".join(str(name).split()) or "cloth"


class MeshText:
    """The lines of a mesh that do not change from frame to frame: ``vt`` and ``f``
    (with the ``o`` lines of ``objects``, when given)."""

    def __init__(self, uvs: np.ndarray, triangles: np.ndarray, objects: Objects | None = None) -> None:
        self.uvs = np.array(uvs, copy=True)
        self.triangles = np.array(triangles, copy=True)
        self.objects = _objects(objects)
        self.vt = _objtext().format_rows(self.uvs, "vt ", 6)
        t = np.repeat(self.triangles.astype(np.int64) + 1, 3, axis=1)  # v/vt/vn share the index
        if self.objects is None:
            self.faces = _faces(t)
        else:
            bounds = [0] + [b for _, _, b in self.objects]
            if not self.objects or [a for _, a, _ in self.objects] != bounds[:-1] or bounds[-1] != len(t):
                raise ValueError("OBJ objects: expected triangle ranges that follow each other and cover "
                                 f"all {len(t)} triangles, got {self.objects}")
            self.faces = b"".join(f"o {_object_name(n)}\n".encode("ascii", "replace") + _faces(t[a:b])
                                  for n, a, b in self.objects)

    def matches(self, uvs: np.ndarray, triangles: np.ndarray, objects: Objects | None = None) -> bool:
        return (np.shape(uvs) == self.uvs.shape and np.shape(triangles) == self.triangles.shape
                and np.array_equal(uvs, self.uvs) and np.array_equal(triangles, self.triangles)
                and _objects(objects) == self.objects)


def _objects(objects) -> Objects | None:
    return None if objects is None else tuple((str(n), int(a), int(b)) for n, a, b in objects)


def _faces(t: np.ndarray) -> bytes:
    return ("f %d/%d/%d %d/%d/%d %d/%d/%d\n" * len(t) % tuple(t.ravel().tolist())).encode("ascii")


_last_mesh: list[MeshText] = []
"""the mesh text of the last call, reused while the uvs and triangles are the same"""


def _mesh_text(uvs: np.ndarray, triangles: np.ndarray, objects: Objects | None = None) -> MeshText:
    if _last_mesh and _last_mesh[0].matches(uvs, triangles, objects):
        return _last_mesh[0]
    mesh = MeshText(uvs, triangles, objects)
    _last_mesh[:] = [mesh]
    return mesh


def _frame_parts(positions: np.ndarray, normals: np.ndarray, mesh: MeshText) -> list[bytes]:
    fmt = _objtext().format_rows
    return [HEADER, fmt(positions, "v ", 9), mesh.vt, fmt(normals, "vn ", 6), mesh.faces]


def obj_bytes(positions: np.ndarray, normals: np.ndarray, uvs: np.ndarray, triangles: np.ndarray,
              objects: Objects | None = None) -> bytes:
    """The OBJ file of one frame (see the module docstring), as ASCII bytes:
    ``positions`` [m] and unit ``normals`` (N, 3), ``uvs`` (N, 2), ``triangles``
    int (T, 3); ``objects``: one ``o`` per entry (:func:`model_objects`), or none."""
    return b"".join(_frame_parts(positions, normals, _mesh_text(uvs, triangles, objects)))


def obj_text(positions: np.ndarray, normals: np.ndarray, uvs: np.ndarray, triangles: np.ndarray,
             objects: Objects | None = None) -> str:
    """OBJ with v, vt, vn and f lines (and ``o`` lines for ``objects``), as text."""
    return obj_bytes(positions, normals, uvs, triangles, objects).decode("ascii")


def write_obj(path: str | Path, positions: np.ndarray, normals: np.ndarray, uvs: np.ndarray,
              triangles: np.ndarray, objects: Objects | None = None, overwrite: bool = True) -> None:
    """Write one frame's OBJ to ``path``, whole or not at all (without ``overwrite``,
    never over a file that appeared meanwhile)."""
    data = obj_bytes(positions, normals, uvs, triangles, objects)
    write_atomic(path, lambda tmp: tmp.write_bytes(data), overwrite)


def model_obj_text(model, positions: np.ndarray, normals: np.ndarray | None = None) -> str:
    """The OBJ of ``model`` (a :class:`~clothsim.model.Model`) at ``positions`` [m]
    (N, 3): its uvs and triangles, one object per cloth when it has several;
    ``normals`` (N, 3) computed from the positions when None."""
    if normals is None:
        normals = compute_normals(np.asarray(positions, np.float64), model.triangles)
    return obj_text(positions, normals, model.uvs, model.triangles, model_objects(model))


def write_model_obj(path: str | Path, model, positions: np.ndarray, normals: np.ndarray | None = None,
                    overwrite: bool = True) -> None:
    """Write :func:`model_obj_text` to ``path``, whole or not at all (``Simulation.export_obj``)."""
    if normals is None:
        normals = compute_normals(np.asarray(positions, np.float64), model.triangles)
    write_obj(path, positions, normals, model.uvs, model.triangles, model_objects(model), overwrite)
