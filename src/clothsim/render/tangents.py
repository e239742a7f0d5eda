"""Vertex tangents of any triangle mesh from its texture coordinates.

Bump and Displacement tilt the normal in the frame (tangent, normal x
tangent, normal); the tangent is the direction of increasing u on the
surface. Per triangle it is the standard derivative dP/du of the linear map
from uv to position::

    e1 = P1 - P0, e2 = P2 - P0,  (du1, dv1), (du2, dv2) the uv edges,
    r = du1 dv2 - du2 dv1,        T = (e1 dv2 - e2 dv1) / r

summed over each vertex's triangles (unnormalised, so a triangle counts by
its own dP/du, as is usual), then made perpendicular to the vertex normal
(Gram-Schmidt) and unit. Triangles whose uvs are degenerate (collinear or
repeated: ``|r|`` under 1e-9 of the product of the uv edge lengths) add
nothing; a vertex left with no tangent (all its triangles degenerate, or its
tangent along its normal) gets a unit vector perpendicular to its normal, the
one the shaders fall back on: ``n x (0, 1, 0)``, or ``n x (1, 0, 0)`` where
``|n_y| >= 0.9``.

On a grid (u along the width index) this is, up to the blend of its cells,
the central difference along a row the renderer used before meshes.
"""

from __future__ import annotations

import numpy as np

DEGENERATE = 1e-9
"""a triangle's |r| at most this times the product of its uv edge lengths adds no tangent"""


class UvTangents:
    """The constant part (uv derivatives) of one mesh, made once; call with each
    frame's positions and normals."""

    def __init__(self, uvs: np.ndarray, triangles: np.ndarray) -> None:
        """``uvs``: float (N, 2); ``triangles``: vertex indices, int (T, 3)."""
        tri = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
        uv = np.asarray(uvs, dtype=np.float64)
        self.num_points = uv.shape[0]
        self.triangles = tri
        d1 = uv[tri[:, 1]] - uv[tri[:, 0]]
        d2 = uv[tri[:, 2]] - uv[tri[:, 0]]
        r = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
        scale = np.linalg.norm(d1, axis=1) * np.linalg.norm(d2, axis=1)
        ok = np.abs(r) > DEGENERATE * scale
        inv = np.divide(1.0, r, out=np.zeros_like(r), where=ok)
        self.c1 = (d2[:, 1] * inv)[:, None]   # T = c1 e1 + c2 e2
        self.c2 = (-d1[:, 1] * inv)[:, None]
        self.corners = tri.T.ravel()           # corner k of every triangle, k = 0, 1, 2
        self.degenerate = int((~ok).sum())
        """how many triangles have degenerate uvs"""

    def __call__(self, positions: np.ndarray, normals: np.ndarray) -> np.ndarray:
        """Unit tangents perpendicular to ``normals``, float64 (N, 3), for
        ``positions`` [m] (N, 3) and unit ``normals`` (N, 3)."""
        p = np.asarray(positions, dtype=np.float64)
        n = np.asarray(normals, dtype=np.float64)
        t = self.triangles
        tri_t = (p[t[:, 1]] - p[t[:, 0]]) * self.c1 + (p[t[:, 2]] - p[t[:, 0]]) * self.c2
        acc = np.empty((self.num_points, 3))
        for a in range(3):
            acc[:, a] = np.bincount(self.corners, weights=np.tile(tri_t[:, a], 3), minlength=self.num_points)
        acc -= np.sum(acc * n, axis=1, keepdims=True) * n
        length = np.linalg.norm(acc, axis=1)
        scale = np.maximum(np.linalg.norm(tri_t, axis=1).max(initial=0.0), 1e-300)
        ok = length > 1e-9 * scale
        acc[ok] /= length[ok, None]
        if not ok.all():
            acc[~ok] = perpendicular(n[~ok])
        return acc


def perpendicular(normals: np.ndarray) -> np.ndarray:
    """A unit vector perpendicular to each of ``normals`` (M, 3), as the shaders
    choose it: ``n x (0, 1, 0)``, or ``n x (1, 0, 0)`` where ``|n_y| >= 0.9``;
    (1, 0, 0) for a zero normal."""
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    helper = np.where((np.abs(n[:, 1]) < 0.9)[:, None], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0])
    out = np.cross(n, helper)
    length = np.linalg.norm(out, axis=1)
    good = length > 1e-12
    out[good] /= length[good, None]
    out[~good] = (1.0, 0.0, 0.0)
    return out
