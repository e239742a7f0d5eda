"""Wavefront OBJ export of the cloth mesh."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from ..outputs import write_atomic


def obj_text(positions: np.ndarray, normals: np.ndarray, uvs: np.ndarray, triangles: np.ndarray) -> str:
    """OBJ with v, vt, vn and f lines; vertices in the grid's row-major order."""
    buf = io.StringIO()
    buf.write("# clothsim cloth mesh\n")
    np.savetxt(buf, positions, fmt="v %.9g %.9g %.9g")
    np.savetxt(buf, uvs, fmt="vt %.6g %.6g")
    np.savetxt(buf, normals, fmt="vn %.6g %.6g %.6g")
    t = triangles.astype(np.int64) + 1
    faces = np.repeat(t, 3, axis=1)  # v/vt/vn share the index
    np.savetxt(buf, faces, fmt="f %d/%d/%d %d/%d/%d %d/%d/%d")
    return buf.getvalue()


def write_obj(path: str | Path, positions: np.ndarray, normals: np.ndarray, uvs: np.ndarray,
              triangles: np.ndarray) -> None:
    text = obj_text(positions, normals, uvs, triangles)
    write_atomic(path, lambda tmp: tmp.write_text(text))
