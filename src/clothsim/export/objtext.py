"""Compiled text for the OBJ writer: rows of floats as ``%.{P}g`` lines, and whole
frames written to open files without the GIL.

:func:`format_rows` writes exactly what ``np.savetxt`` with ``"%.9g"`` writes
(Python's formatting: correctly rounded, ties to even, trailing zeros dropped,
the exponent form outside 1e-4 <= |x| < 10**P, ``nan``/``inf``), about 10x
faster (2,500 rows of three %.9g: 0.33 ms, np.savetxt 3.1 ms).
:func:`write_frames` formats a batch of frames and writes each whole file with
the C library's creat/write/close/rename in one call that holds no GIL, so
that a background thread (:class:`clothsim.export.objseq.ObjSequence`) writes an
OBJ sequence beside the simulation, taking the GIL only to pick up a batch.

Exactness: for 10**(P-22) <= |x| < 10**(P-1), ``|x| * 10**s`` (0 <= s <= 22,
where 10**s is a double) is computed without error as a pair of doubles
(Dekker's product: no fused multiply-add, which numba does not contract
without fastmath), and the rounding is decided on the pair. Outside that range
(a position beyond 1e8 m or under 1e-13 m, a normal component under 1e-16)
the scaling is rounded; where that leaves the rounding undecided (the value
within its error of a tie: never seen, but possible) the kernels say so and
the caller formats the frame with Python instead.

Imported by :mod:`clothsim.export.obj` on first use, so that ``import
clothsim.export`` stays free of numba.
"""

from __future__ import annotations

import math
import os
import sys

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

from .. import kernel_cache

kernel_cache.configure()  # before the decorators: see kernel_cache

from ..mesh import vertex_normals  # noqa: E402 - after configure(), as mesh.py itself does

POW10 = np.array([10.0 ** k for k in range(23)])
"""10**0 .. 10**22, each exact in a double"""

MAX_PRECISION = 15
"""the most significant digits: the rounding is decided exactly while 10**P < 2**53"""

NATIVE_WRITE = os.name == "posix" and sys.maxsize > 2 ** 32
"""whether :func:`write_frames` can call the C library's ``write(int, void*, size_t)``"""

UNDECIDED = -1
"""what the formatting kernels return when a rounding was left undecided"""

_SPLIT = 134217729.0  # 2**27 + 1
_LOG10_2 = math.log10(2.0)
_SCALED_ERROR = 1e-14
"""bound on the relative error of a scaling outside the exact range (at most 16
rounded multiplications or divisions by powers of ten, each within 2**-53)"""


@njit(cache=True, inline="always")
def _two_prod(a, b):
    """(p, e) with p = fl(a*b) and p + e == a*b exactly (Dekker, no FMA)"""
    p = a * b
    c = _SPLIT * a
    ah = c - (c - a)
    al = a - ah
    c = _SPLIT * b
    bh = c - (c - b)
    bl = b - bh
    e = ((ah * bh - p) + ah * bl + al * bh) + al * bl
    return p, e


@njit(cache=True, inline="always")
def _scale(a, s):
    """a * 10**s as (hi, lo, err): hi + lo exactly and err = 0 for 0 <= s <= 22;
    else hi rounded, lo = 0 and err a bound on |hi - a * 10**s|"""
    if 0 <= s <= 22:
        hi, lo = _two_prod(a, POW10[s])
        return hi, lo, 0.0
    y = a
    if s > 0:
        while s > 22:
            y *= 1e22
            s -= 22
        y *= POW10[s]
    else:
        while s < -22:
            y /= 1e22
            s += 22
        y /= POW10[-s]
    return y, 0.0, y * _SCALED_ERROR


@njit(cache=True, boundscheck=False, error_model="numpy", inline="always")
def _write_g(x, precision, out, pos, digits):
    """``"%.{precision}g" % x`` into ``out`` from ``pos``: the new end, or UNDECIDED"""
    a = x
    if x < 0.0 or (x == 0.0 and math.copysign(1.0, x) < 0.0):
        out[pos] = 45  # '-'
        pos += 1
        a = -x
    if a == 0.0:
        out[pos] = 48
        return pos + 1
    if a != a or a == math.inf:
        if a != a:  # no sign was written: Python drops a NaN's
            out[pos], out[pos + 1], out[pos + 2] = 110, 97, 110  # nan
        else:
            out[pos], out[pos + 1], out[pos + 2] = 105, 110, 102  # inf
        return pos + 3
    lower = POW10[precision - 1]
    upper = POW10[precision]
    e10 = int(math.floor((math.frexp(a)[1] - 1) * _LOG10_2))  # floor(log10(a)), or one less
    hi, lo, err = _scale(a, precision - 1 - e10)
    if hi < lower or (hi == lower and lo < 0.0):
        e10 -= 1
        hi, lo, err = _scale(a, precision - 1 - e10)
    elif hi > upper or (hi == upper and lo >= 0.0):
        e10 += 1
        hi, lo, err = _scale(a, precision - 1 - e10)
    d0 = math.floor(hi)
    frac = hi - d0  # exact: hi < 2**53
    if err > 0.0 and abs(frac - 0.5) <= err:
        return -1
    d = np.uint64(d0)
    if frac > 0.5 or (frac == 0.5 and (lo > 0.0 or (lo == 0.0 and (d & np.uint64(1)) == 1))):
        d += np.uint64(1)
    if d >= np.uint64(upper):  # 9.999999995 -> 10.0000000
        d //= np.uint64(10)
        e10 += 1
    for i in range(precision - 1, -1, -1):
        q = d // np.uint64(10)
        digits[i] = 48 + (d - q * np.uint64(10))
        d = q
    nsig = precision
    while nsig > 1 and digits[nsig - 1] == 48:
        nsig -= 1
    if -4 <= e10 < precision:
        if e10 >= 0:
            for i in range(e10 + 1):
                out[pos] = digits[i]
                pos += 1
            if nsig > e10 + 1:
                out[pos] = 46  # '.'
                pos += 1
                for i in range(e10 + 1, nsig):
                    out[pos] = digits[i]
                    pos += 1
        else:
            out[pos] = 48
            out[pos + 1] = 46
            pos += 2
            for _ in range(-e10 - 1):
                out[pos] = 48
                pos += 1
            for i in range(nsig):
                out[pos] = digits[i]
                pos += 1
    else:
        out[pos] = digits[0]
        pos += 1
        if nsig > 1:
            out[pos] = 46
            pos += 1
            for i in range(1, nsig):
                out[pos] = digits[i]
                pos += 1
        out[pos] = 101  # 'e'
        out[pos + 1] = 45 if e10 < 0 else 43
        pos += 2
        e = -e10 if e10 < 0 else e10
        if e >= 100:
            out[pos] = 48 + e // 100
            pos += 1
        out[pos] = 48 + (e // 10) % 10
        out[pos + 1] = 48 + e % 10
        pos += 2
    return pos


def line_width(columns: int, prefix_len: int, precision: int) -> int:
    """the most bytes one line can take: the longest number is
    ``-d.ddde-308`` (precision + 7 characters)"""
    return prefix_len + columns * (precision + 8) + 1


@njit(cache=True, boundscheck=False, error_model="numpy", nogil=True)
def _format_rows(values, prefix, precision, out, start):
    """``prefix v0 v1 ..\\n`` per row of ``values`` into ``out`` from ``start``:
    the end, or UNDECIDED"""
    rows, cols = values.shape
    digits = np.empty(24, np.uint8)
    pos = start
    for r in range(rows):
        for c in range(prefix.shape[0]):
            out[pos] = prefix[c]
            pos += 1
        for c in range(cols):
            if c > 0:
                out[pos] = 32
                pos += 1
            pos = _write_g(values[r, c], precision, out, pos, digits)
            if pos < 0:
                return -1
        out[pos] = 10
        pos += 1
    return pos


def format_rows(values: np.ndarray, prefix: str, precision: int) -> bytes:
    """The lines ``prefix`` + the row's numbers as ``%.{precision}g``, space-separated,
    for every row of ``values`` (M, K) or (M,): byte for byte what ``np.savetxt(f,
    values, fmt=prefix + " ".join(["%.{precision}g"] * K))`` writes, as ASCII."""
    if not 1 <= precision <= MAX_PRECISION:
        raise ValueError(f"precision {precision} is not in 1..{MAX_PRECISION}")
    values = np.ascontiguousarray(values, dtype=np.float64)
    if values.ndim == 1:
        values = values[:, None]
    prefix_bytes = np.frombuffer(prefix.encode("ascii"), np.uint8)
    out = np.empty(values.shape[0] * line_width(values.shape[1], len(prefix_bytes), precision), np.uint8)
    n = _format_rows(values, prefix_bytes, precision, out, 0)
    if n == UNDECIDED:
        line = prefix + " ".join([f"%.{precision}g"] * values.shape[1]) + "\n"
        return (line * values.shape[0] % tuple(values.ravel().tolist())).encode("ascii")
    return out[:n].tobytes()


# ---------------------------------------------------------------- whole frames

_I8P = ir.IntType(8).as_pointer()


def _libc(name: str, result: ir.Type, *params: ir.Type):
    """an intrinsic calling the C library's ``name``; pointer arguments pass as uint64
    addresses (the functions taken are not variadic, so any C calling convention
    passes them alike)"""
    widths = {64: types.int64, 32: types.int32}
    sig = widths[result.width](*(types.uint64 if p is _I8P else widths[p.width] for p in params))

    def codegen(context, builder, signature, values):
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(result, list(params)), name)
        return builder.call(fn, [builder.inttoptr(v, _I8P) if p is _I8P else v for v, p in zip(values, params)])

    # numba's intrinsics take no *args: one signature per arity
    if len(params) == 1:
        def call(typingctx, a):
            return sig, codegen
    elif len(params) == 2:
        def call(typingctx, a, b):
            return sig, codegen
    else:
        def call(typingctx, a, b, c):
            return sig, codegen
    call.__name__ = call.__qualname__ = f"c_{name}"
    return intrinsic(call)


_I32, _I64 = ir.IntType(32), ir.IntType(64)
_c_creat = _libc("creat", _I32, _I8P, _I32)  # int creat(const char *, mode_t): open(O_CREAT|O_WRONLY|O_TRUNC)
_c_write = _libc("write", _I64, _I32, _I8P, _I64)  # ssize_t write(int, const void *, size_t)
_c_close = _libc("close", _I32, _I32)
_c_rename = _libc("rename", _I32, _I8P, _I8P)
_c_link = _libc("link", _I32, _I8P, _I8P)  # int link(const char *, const char *): fails where the name is taken
_c_unlink = _libc("unlink", _I32, _I8P)


@njit(cache=True, boundscheck=False, error_model="numpy", inline="always")
def _write_all(fd, buf, start, stop):
    """write ``buf[start:stop]`` whole; False on an error"""
    base = np.uint64(buf.ctypes.data)
    while start < stop:
        n = _c_write(np.int32(fd), base + np.uint64(start), np.int64(stop - start))
        if n <= 0:
            return False
        start += n
    return True


@njit(cache=True, boundscheck=False)
def copy_frame(positions, normals, slot, frame_positions, frame_normals):
    """``positions[slot] = frame_positions`` and the same for the normals, holding the
    GIL: numpy's copy of a frame lets go of it, and the writing thread, waiting for
    it, would take it for as long as it runs Python"""
    positions[slot] = frame_positions
    normals[slot] = frame_normals


FRAME_OK, FRAME_WRITE_FAILED, FRAME_UNDECIDED, FRAME_NOT_PLACED = 0, 1, 2, 3
"""the status :func:`write_frames` gives each frame"""

FILE_MODE = 0o666
"""the mode a new file asks for (less the umask), as ``open()`` does"""


@njit(cache=True, boundscheck=False, error_model="numpy", nogil=True)
def write_frames(positions, normals, slots, compute, triangles, names, head, vt, faces, v_prefix, vn_prefix,
                 scratch, status, exclusive):
    """For each j, write frame ``positions[slots[j]]``, ``normals[slots[j]]`` (first
    computed there from ``triangles`` where ``compute[j]``) as a whole OBJ file:
    ``head``, the v lines (%.9g), ``vt``, the vn lines (%.6g), ``faces``, to the
    temporary file ``names[2j]`` and rename it to ``names[2j+1]`` (``names``:
    (2J, L) uint8, NUL-terminated paths); where ``exclusive``, hard-link it there
    instead (which fails where a file is already there) and remove the
    temporary name. ``status[j]``: FRAME_OK, FRAME_WRITE_FAILED (the caller
    learns why by writing it again), FRAME_UNDECIDED (the caller formats it
    with Python) or FRAME_NOT_PLACED (the link failed: the temporary file is
    whole and left for the caller to place, or to refuse). Holds no GIL."""
    base = np.uint64(names.ctypes.data)
    row = np.uint64(names.shape[1])
    for j in range(slots.shape[0]):
        status[j] = FRAME_WRITE_FAILED
        s = slots[j]
        if compute[j]:
            vertex_normals(positions[s], triangles, normals[s])
        mid = _format_rows(positions[s], v_prefix, 9, scratch, 0)
        end = UNDECIDED if mid == UNDECIDED else _format_rows(normals[s], vn_prefix, 6, scratch, mid)
        if end == UNDECIDED:
            status[j] = FRAME_UNDECIDED
            continue
        tmp = base + np.uint64(2 * j) * row
        fd = _c_creat(tmp, np.int32(FILE_MODE))
        if fd < 0:
            continue
        ok = (_write_all(fd, head, 0, head.shape[0]) and _write_all(fd, scratch, 0, mid)
              and _write_all(fd, vt, 0, vt.shape[0]) and _write_all(fd, scratch, mid, end)
              and _write_all(fd, faces, 0, faces.shape[0]))
        if _c_close(fd) != 0 or not ok:
            continue
        if not exclusive:
            if _c_rename(tmp, tmp + row) == 0:
                status[j] = FRAME_OK
        elif _c_link(tmp, tmp + row) == 0:
            _c_unlink(tmp)
            status[j] = FRAME_OK
        else:
            status[j] = FRAME_NOT_PLACED
