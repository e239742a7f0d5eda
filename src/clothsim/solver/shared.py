"""What the kernels of every stage share: compile options and small inlined helpers."""

from __future__ import annotations

import types

import numpy as np
from numba import njit
from numba.cpython.unsafe.numbers import trailing_zeros

from ..vector_width import target_cpu_name
from .simd import has_compress

KERNEL_OPTIONS = dict(cache=True, fastmath=True, boundscheck=False, error_model="numpy")
"""error_model="numpy" drops the zero-division check, which would stop LLVM vectorising"""

EXACT_OPTIONS = dict(cache=True, boundscheck=False, error_model="numpy")
"""for the kernels that test for NaN before turning coordinates into cell
indices: fastmath would let LLVM drop the test, also where one of them is
inlined into another, and a NaN index could then reach memory"""

SET_STEP = ((0, 1), (1, 0), (1, 1), (1, -1), (0, 2), (2, 0))
"""(dr, di) of each spring set of a grid cloth: set s joins grid point (r, i)
to (r + dr, i + di) (see :mod:`.springs`)"""

BLOCK = 64
"""springs the Provot pass checks together: one bit each in a 64-bit word"""

LINE = 8
"""doubles in a 64-byte cache line"""


def whole_lines(count: int) -> int:
    """``count`` doubles rounded up to whole cache lines"""
    return -(-int(count) // LINE) * LINE


def on_lines(shape: tuple, fill: float = 0.0) -> np.ndarray:
    """A float64 array of ``shape`` filled with ``fill`` that starts on a 64-byte
    cache line (NumPy promises 16 bytes). A vector of eight doubles loaded
    from or stored to a line costs half what one across two lines does
    (docs/performance.md, 'Arrays on cache lines'), so the planes and the
    springs' rows the kernels read eight at a time start on one."""
    size = int(np.prod(shape))
    raw = np.full(size + LINE, fill)
    skip = (-raw.ctypes.data % (8 * LINE)) // 8
    return raw[skip:skip + size].reshape(shape)


@njit(**KERNEL_OPTIONS, inline="always")
def inv_length(l2):
    """1/sqrt(l2) to about 1e-13 relative: a single-precision estimate refined by
    one Newton step in double, which is cheaper than a double sqrt and divide
    where vectors hold eight doubles (AVX-512) and on Intel's cores (see
    :func:`divides`)."""
    y = np.float64(np.float32(1.0) / np.sqrt(np.float32(max(l2, 1e-30))))
    return y * (1.5 - 0.5 * l2 * y * y)


def divides(cpu_name: str, compress: bool) -> bool:
    """Whether :func:`over_length` should divide by a double square root on a
    CPU of LLVM's name ``cpu_name``, given whether the kernels use AVX-512
    (``compress``, :func:`.simd.has_compress`), rather than multiply by
    :func:`inv_length`'s estimate: only on AMD's Zen cores (``znver*``)
    without AVX-512. There the square root and the divide run in a unit of
    their own beside the two multiply units, which the estimate's
    conversions and refining steps keep busy: the spring force loop was
    faster dividing, and the same to the bit on every such core. On an Intel
    core, with the same code, the estimate's loop was the faster by about a
    quarter; with AVX-512 a vector holds eight doubles and the divide unit
    is no wider (figures: docs/performance.md, 'The inverse length as a
    square root and a divide' and 'The estimate on Intel cores without
    AVX-512')."""
    return not compress and cpu_name.startswith("znver")


DIVIDE = divides(target_cpu_name(), has_compress())
"""whether :func:`over_length` divides (see :func:`divides`), for the CPU numba
compiles for: numba's cache keys every entry on that CPU's name and
features, so kernels of either kind never mix"""


@njit(**KERNEL_OPTIONS, inline="always")
def divided_by_length(a, l2):
    """a/sqrt(l2) for a squared length l2 [m²] by a double square root and a
    divide, each rounded once: the same bits on every machine; finite for
    l2 = 0. Provot's correction
    takes it on every core: one spring at a time, in scalar code, the
    estimate's longer chain of dependent steps cost more than the divide
    (docs/performance.md, 'The estimate on Intel cores without AVX-512')."""
    return a / np.sqrt(max(l2, 1e-30))


@njit(**KERNEL_OPTIONS, inline="always")
def _over_length_estimate(a, l2):
    return a * inv_length(l2)


over_length = divided_by_length if DIVIDE else _over_length_estimate
"""``over_length(a, l2)``: a/sqrt(l2) for a squared length l2 [m²], one of the two
ways :data:`DIVIDE` chooses between, for the vector loops (a spring's pull;
the wind's triangle normals where there is AVX-512); finite for l2 = 0"""


@njit(cache=True, inline="always")
def gap2(xa, ya, za, i, xb, yb, zb, j):
    """Squared distance from point i of the planes (xa, ya, za) to point j of
    (xb, yb, zb): the test of every vectorised check, where the planes are
    views that start at each end of a set of pairs."""
    dx = xb[j] - xa[i]
    dy = yb[j] - ya[i]
    dz = zb[j] - za[i]
    return dx * dx + dy * dy + dz * dz


@njit(cache=True, inline="always")
def pop_lowest(mask):
    """(index of the lowest set bit of the uint64 ``mask``, mask without it): one
    step of a walk over the bits a vectorised check set."""
    return np.int64(trailing_zeros(mask)), mask & (mask - np.uint64(1))


@njit(cache=True, inline="always")
def part_range(n, parts, t):
    """Items ``lo:hi`` of part t when n items are cut into ``parts`` nearly equal ranges."""
    return t * n // parts, (t + 1) * n // parts


def renamed(f, name: str, **swapped):
    """A copy of the Python function ``f`` under another name, reading the globals
    ``swapped`` in place of its module's: numba caches compiled code by the
    function's name, so two builds of one body (serial and parallel; with the
    helpers it calls swapped for others) must not share a name."""
    g = types.FunctionType(f.__code__, {**f.__globals__, **swapped} if swapped else f.__globals__, name,
                           f.__defaults__, f.__closure__)
    g.__qualname__ = name
    g.__module__ = f.__module__
    g.__doc__ = f.__doc__
    return g
