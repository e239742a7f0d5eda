"""A mesh collider's rigid pose, as the kernels read it: into its rest frame and out.

A pose is the tuple of 12 floats of :func:`frame`: a rotation R (row-major) and
an offset o [m], so that a world point is ``x = R @ x_rest + o``. Read once per
mesh and substep, then passed to the loops, where its numbers are constants.
"""

from __future__ import annotations

from numba import njit

from ..shared import EXACT_OPTIONS


@njit(**EXACT_OPTIONS, inline="always")
def frame(m, o):
    """The rotation (row-major) and offset at m[o:o+12] as one tuple of 12 floats."""
    return (m[o], m[o + 1], m[o + 2], m[o + 3], m[o + 4], m[o + 5], m[o + 6], m[o + 7], m[o + 8],
            m[o + 9], m[o + 10], m[o + 11])


@njit(**EXACT_OPTIONS, inline="always")
def to_rest(f, x, y, z):
    """R^T (p - o) for the frame tuple ``f`` of :func:`frame`."""
    px, py, pz = x - f[9], y - f[10], z - f[11]
    return (f[0] * px + f[3] * py + f[6] * pz,
            f[1] * px + f[4] * py + f[7] * pz,
            f[2] * px + f[5] * py + f[8] * pz)


@njit(**EXACT_OPTIONS, inline="always")
def to_world(f, x, y, z):
    """R q + o for the frame tuple ``f`` of :func:`frame`."""
    return (f[0] * x + f[1] * y + f[2] * z + f[9],
            f[3] * x + f[4] * y + f[5] * z + f[10],
            f[6] * x + f[7] * y + f[8] * z + f[11])


@njit(**EXACT_OPTIONS, inline="always")
def is_rest(f):
    """whether the frame tuple ``f`` is the rest pose itself (R = I, o = 0, exactly)"""
    return (f[0] == 1.0 and f[1] == 0.0 and f[2] == 0.0 and f[3] == 0.0 and f[4] == 1.0 and f[5] == 0.0
            and f[6] == 0.0 and f[7] == 0.0 and f[8] == 1.0 and f[9] == 0.0 and f[10] == 0.0 and f[11] == 0.0)
