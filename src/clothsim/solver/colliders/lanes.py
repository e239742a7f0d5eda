"""Lanes of doubles in LLVM vector code, for the colliders' passes.

A collider's pass over a cloth lying on it touches few of the points: most
lie nowhere near the collider's inside. A loop that numba vectorises cannot
skip a vector's worth of points (its body is branch-free, and a loop of
eight is left scalar or pays for tests of overlapping arrays every time),
so the box's and the sphere's passes are written as LLVM vector code on a
few points at a time, with their test first and their rule behind a branch
taken only where one of them needs it (:mod:`.box_lanes`,
:mod:`.sphere_lanes`). :class:`Lanes` emits that code: the operations carry
the fast-math flags numba gives its own (``fastmath=True``), so the same
sums in the same order give the same bits. LLVM lowers the vectors for any
x86 target: eight doubles are one 512-bit register with AVX-512 and two
256-bit ones without; four are one 256-bit register on either. Each pass
takes the width it ran fastest at (docs/performance.md, 'Four lanes').
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.core.errors import TypingError

from ..simd import _splat, _vector_at

LANES = 8
"""the lanes of :class:`Lanes` unless told otherwise: one vector of eight doubles"""

FAST = ("fast",)
"""the flags numba's ``fastmath=True`` puts on every floating-point operation"""

MAP = 12
"""numbers in an affine map, see :func:`.motion_rows.carry_of`"""

YAW_MAP = 7
"""numbers in an affine map whose turn is about the y axis alone (its y row
and column are those of the identity): the four corners of its turn, then
its shift (3), as :func:`.box.yaw_map` picks them from a map of MAP"""


def check_rows(who, arrays):
    """A typing error naming ``who`` unless ``arrays`` are contiguous float64 (N,)."""
    if not all(isinstance(a, types.Array) and a.dtype == types.float64 and a.ndim == 1 and a.layout == "C"
               for a in arrays):
        raise TypingError(f"{who} take contiguous float64 (N,) arrays")


def check_numbers(who, pairs):
    """A typing error naming ``who`` unless each (tuple type, length) of ``pairs``
    is a tuple of that many float64."""
    if not all(isinstance(t, types.UniTuple) and t.dtype == types.float64 and len(t) == k for t, k in pairs):
        raise TypingError(f"{who} take tuples of " + ", ".join(str(k) for _, k in pairs) + " floats")


def planes_of(tuple_type):
    """the arrays of a tuple type of three planes, or () when it is not one"""
    return tuple(tuple_type) if isinstance(tuple_type, types.UniTuple) and len(tuple_type) == 3 else ()


class Lanes:
    """The vector code of one call: ``width`` lanes of doubles."""

    def __init__(self, context, builder, width=LANES):
        self.context, self.builder = context, builder
        self.width = width
        self.vec = ir.VectorType(ir.DoubleType(), width)
        self.bits = ir.VectorType(ir.IntType(1), width)
        module = builder.module
        self._fabs = cgutils.get_or_insert_function(module, ir.FunctionType(self.vec, [self.vec]),
                                                    f"llvm.fabs.v{width}f64")

    def splat(self, value):
        return _splat(self.builder, value, self.vec)

    def numbers(self, tuple_type, value):
        """the floats of a UniTuple, each in every lane"""
        return [self.splat(v) for v in cgutils.unpack_tuple(self.builder, value, len(tuple_type))]

    def load(self, array_type, array, at):
        ptr = _vector_at(self.context, self.builder, array_type, array, [at], self.vec)
        return self.builder.load(ptr, align=8)

    def store(self, value, array_type, array, at):
        ptr = _vector_at(self.context, self.builder, array_type, array, [at], self.vec)
        self.builder.store(value, ptr, align=8)

    def add(self, a, b):
        return self.builder.fadd(a, b, flags=FAST)

    def sub(self, a, b):
        return self.builder.fsub(a, b, flags=FAST)

    def mul(self, a, b):
        return self.builder.fmul(a, b, flags=FAST)

    def abs(self, a):
        return self.builder.call(self._fabs, [a])

    def less(self, a, b):
        return self.builder.fcmp_ordered("<", a, b, flags=FAST)

    def at_least(self, a, b):
        return self.builder.fcmp_ordered(">=", a, b, flags=FAST)

    def pick(self, flag, a, b):
        return self.builder.select(flag, a, b)

    def clamp(self, a, lo, hi):
        """min(max(a, lo), hi), as numba's min and max (a select on a comparison)"""
        up = self.pick(self.builder.fcmp_ordered(">", a, lo, flags=FAST), a, lo)
        return self.pick(self.builder.fcmp_ordered("<", up, hi, flags=FAST), up, hi)

    def squared(self, v):
        """|v|² of three vectors, summed x² + y², then + z², as the scalar rules sum it"""
        return self.add(self.add(self.mul(v[0], v[0]), self.mul(v[1], v[1])), self.mul(v[2], v[2]))

    def affine(self, m, point):
        """the map m (12 numbers, :func:`.motion_rows.carry_of`) of a point, in the
        order :func:`.motion_rows.carry_point` sums it; or m of YAW_MAP numbers, a
        turn about y: the terms of the map of 12 that are exact zeros (and y's
        exact 1) left out, which spares 5 of its 12 operations and of the 12
        numbers it holds in registers. The terms left out add nothing, but
        fast-math lets LLVM fuse the sums left otherwise: a coordinate may
        round an ulp away from the map of 12's"""
        x, y, z = point
        if len(m) == YAW_MAP:
            c00, c02, c20, c22, tx, ty, tz = m
            return (self.add(self.add(self.mul(c00, x), self.mul(c02, z)), tx), self.add(y, ty),
                    self.add(self.add(self.mul(c20, x), self.mul(c22, z)), tz))
        return tuple(self.add(self.add(self.add(self.mul(m[3 * k], x), self.mul(m[3 * k + 1], y)),
                                       self.mul(m[3 * k + 2], z)), m[9 + k]) for k in range(3))


    def sqrt(self, a):
        fn = cgutils.get_or_insert_function(self.builder.module, ir.FunctionType(self.vec, [self.vec]),
                                            f"llvm.sqrt.v{self.width}f64")
        return self.builder.call(fn, [a], fastmath=FAST)

    def div(self, a, b):
        return self.builder.fdiv(a, b, flags=FAST)

    def greater(self, a, b):
        return self.builder.fcmp_ordered(">", a, b, flags=FAST)

    def nonzero(self, a):
        """a != 0.0, as numba compares (true for NaN)"""
        return self.builder.fcmp_unordered("!=", a, ir.Constant(self.vec, None), flags=FAST)

    def count(self, flags):
        """how many of the i1 ``flags`` (one a lane) are set, as an i64"""
        b = self.builder
        word = ir.IntType(self.width)
        popcount = cgutils.get_or_insert_function(b.module, ir.FunctionType(word, [word]),
                                                  f"llvm.ctpop.i{self.width}")
        return b.zext(b.call(popcount, [b.bitcast(flags, word)]), ir.IntType(64))

    def any(self, flags):
        """whether any of the i1 ``flags`` (one a lane) is set (an i1)"""
        b = self.builder
        word = b.bitcast(flags, ir.IntType(self.width))
        return b.icmp_unsigned("!=", word, ir.Constant(word.type, 0))
