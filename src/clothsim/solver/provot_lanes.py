"""Provot's check of a grid's spring set, a block of BLOCK springs in LLVM vector code.

The check (:func:`.provot.provot`) sets a bit for each spring of a set whose
squared length is over its squared limit, a 64-bit word per BLOCK springs.
Written as a numba loop, the word is an or of shifted selects, which LLVM
vectorises as 64-bit lanes of ones shifted and or-ed together: more work
than the test itself. Here each eight springs' comparison is already the
eight bits of a byte (a mask register's with AVX-512, a ``movmskpd`` pair's
without), shifted into place in the word. Same loads, the same squared
lengths (x² rounded, y² and then z² each fused into the sum where the
machine fuses), the same comparison: the same bits as the loop
(docs/performance.md, 'Provot's check as bytes').
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.core.errors import TypingError
from numba.extending import intrinsic

from .colliders.lanes import Lanes, check_rows, planes_of
from .shared import BLOCK

__all__ = ["over_word"]

_EIGHT = 8
"""springs a comparison takes: eight doubles, one 512-bit vector or two 256-bit ones"""


@intrinsic
def over_word(typingctx, planes, a, b, limit, at):
    """The word of bits of springs ``at:at + BLOCK`` of a set that joins point
    ``a + p`` to point ``b + p`` of ``planes`` (x, y, z; contiguous float64
    (N,) [m]) for each spring p, bit j set where spring ``at + j`` is longer
    than ``limit[at + j]`` [m] (its squared length over the limit's square).
    Nothing is bounds-checked: the caller keeps ``at + BLOCK`` within
    ``limit`` and ``a + at + BLOCK``, ``b + at + BLOCK`` within the planes."""
    arrays = planes_of(planes)
    if not arrays:
        raise TypingError("over_word takes three planes")
    check_rows("over_word", arrays + (limit,))
    if not all(isinstance(t, types.Integer) for t in (a, b, at)):
        raise TypingError("over_word takes integer offsets")

    def codegen(context, builder, signature, args):
        planes_t, a_t, b_t, limit_t, at_t = signature.args
        planes_v, a_v, b_v, limit_v, at_v = args
        lanes = Lanes(context, builder, _EIGHT)
        fuse = cgutils.get_or_insert_function(builder.module, ir.FunctionType(lanes.vec, [lanes.vec] * 3),
                                              f"llvm.fmuladd.v{_EIGHT}f64")
        plane_t = planes_t.dtype
        xyz = [builder.extract_value(planes_v, k) for k in range(3)]
        at = context.cast(builder, at_v, at_t, types.intp)
        first = builder.add(context.cast(builder, a_v, a_t, types.intp), at)
        second = builder.add(context.cast(builder, b_v, b_t, types.intp), at)
        word_t = ir.IntType(64)
        word = ir.Constant(word_t, 0)
        for k in range(0, BLOCK, _EIGHT):
            step = ir.Constant(word_t, k)
            ends_a = [lanes.load(plane_t, p, builder.add(first, step)) for p in xyz]
            ends_b = [lanes.load(plane_t, p, builder.add(second, step)) for p in xyz]
            d = [builder.fsub(ends_b[c], ends_a[c]) for c in range(3)]
            # numba's loop: fmuladd(dz, dz, fmuladd(dy, dy, dx * dx)). Left to fuse plain
            # sums itself, even without reassociation, LLVM fused x² into y² instead,
            # and a spring just at its limit (Provot's pass leaves it there) came out
            # over it in a few cases in a hundred where the loop had it under, or the
            # other way. llvm.fmuladd is a plain multiply and add where nothing fuses
            length2 = builder.fmul(d[0], d[0])
            for c in (1, 2):
                length2 = builder.call(fuse, [d[c], d[c], length2])
            lim = lanes.load(limit_t, limit_v, builder.add(at, step))
            over = builder.fcmp_ordered(">", length2, builder.fmul(lim, lim))
            byte = builder.zext(builder.bitcast(over, ir.IntType(_EIGHT)), word_t)
            word = builder.or_(word, builder.shl(byte, step))
        return word

    return types.uint64(planes, a, b, limit, at), codegen
