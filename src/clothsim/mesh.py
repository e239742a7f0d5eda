"""Per-vertex normals of the cloth mesh."""

from __future__ import annotations

import numpy as np
from numba import njit

from . import kernel_cache
kernel_cache.configure()  # before the decorator: see kernel_cache


@njit(cache=True, fastmath=True, boundscheck=False, nogil=True)
def vertex_normals(pos, triangles, out):
    """Area-weighted average of adjacent face normals, unit length, into ``out`` (N, 3).

    The unnormalised cross product of two edges is twice the face area times its
    normal, so summing cross products weights each face by its area for free.
    """
    out[:] = 0.0
    for t in range(triangles.shape[0]):
        a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
        e1x = pos[b, 0] - pos[a, 0]
        e1y = pos[b, 1] - pos[a, 1]
        e1z = pos[b, 2] - pos[a, 2]
        e2x = pos[c, 0] - pos[a, 0]
        e2y = pos[c, 1] - pos[a, 1]
        e2z = pos[c, 2] - pos[a, 2]
        nx = e1y * e2z - e1z * e2y
        ny = e1z * e2x - e1x * e2z
        nz = e1x * e2y - e1y * e2x
        for v in (a, b, c):
            out[v, 0] += nx
            out[v, 1] += ny
            out[v, 2] += nz
    for v in range(out.shape[0]):
        length = np.sqrt(out[v, 0] ** 2 + out[v, 1] ** 2 + out[v, 2] ** 2)
        if length > 0.0:
            out[v, 0] /= length
            out[v, 1] /= length
            out[v, 2] /= length
    return out


def compute_normals(pos: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    return vertex_normals(pos, triangles, np.empty_like(pos))
