"""The general path's springs and Verlet step eight points at a time (see :mod:`.mesh_pulls`).

A mesh's springs join points anywhere in the list, so each spring's far
end is a load from anywhere, which numba's loops leave scalar. Here LLVM
vector code takes eight points, walks their slots
(:class:`.mesh_pulls.MeshPulls`) a row at a time, loads the row's eight far
ends, adds each spring's pull to its point in registers, and moves the
eight: the springs and the Verlet step in one pass, with no force written
to memory.

The far ends come from a copy of the positions as rows of four doubles
(x, y, z, 0): one 256-bit load per end and seven shuffles turn them into
the eight x, y and z. AVX-512's gather instruction (three a row, one per
coordinate plane) took nearly twice as long on Zen 4, whether LLVM wrote
it or eight scalar loads stood for it (docs/performance.md, 'The general
path's springs as pulls').

Provot's pass over the spring lists (:func:`.meshsprings.mesh_provot`)
tests eight springs at once on the same rows (:func:`over_lanes`), and
takes one by one only the eights where one may be over its limit.

Each spring is computed at both its ends, by the same arithmetic on the
ends' difference and its negation, so the two pulls are equal and opposite
to the bit. No point's sum depends on another lane or another call, so a
thread's part gives the whole model's bits. The inverse length is
:func:`.spring_lanes._over_length` (AVX-512's estimate refined twice where
there is AVX-512, else a square root and divide).
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.core.errors import TypingError
from numba.extending import intrinsic

from .colliders.lanes import FAST, LANES
from .simd import _splat, _vector_at
from .spring_lanes import _over_length, _Vector

__all__ = ["LANES", "over_lanes", "pull_lanes"]

I64 = ir.IntType(64)
I32 = ir.IntType(32)


def _plane(t, ndim, dtype=types.float64):
    return isinstance(t, types.Array) and t.ndim == ndim and t.layout == "C" and t.dtype == dtype


class _Rows(_Vector):
    """:class:`.spring_lanes._Vector` with the masked loads and stores and the
    far ends' loads of the pulls' code."""

    def __init__(self, context, builder, valid):
        super().__init__(context, builder)
        self.valid = valid
        """i1 per lane: the lanes whose point exists (the last eight of a model may be short)"""

    def _masked(self, name, ret, args):
        fn = cgutils.get_or_insert_function(self.builder.module, ir.FunctionType(ret, [a.type for a in args]), name)
        return self.builder.call(fn, args)

    def masked_load(self, array_type, array, *index):
        """the valid lanes from ``array[index]`` on, 0 in the others (which are not read)"""
        ptr = self.at(array_type, array, *index)
        return self._masked(f"llvm.masked.load.v{LANES}f64.p0", self.vec,
                            [ptr, ir.Constant(I32, 8), self.valid, ir.Constant(self.vec, None)])

    def masked_store(self, value, array_type, array, *index):
        """the valid lanes of ``value`` into ``array[index]`` on; the others are not written"""
        ptr = self.at(array_type, array, *index)
        self._masked(f"llvm.masked.store.v{LANES}f64.p0", ir.VoidType(),
                     [value, ptr, ir.Constant(I32, 8), self.valid])

    def far_ends(self, rows_ptr, ids):
        """(x, y, z) of the eight points ``ids`` (i32) of the (N, 4) rows at
        ``rows_ptr``: a 256-bit load per point, transposed"""
        b = self.builder
        quad = ir.VectorType(ir.DoubleType(), 4)
        base = b.bitcast(rows_ptr, quad.as_pointer())
        # lanes 1 and 2 (5 and 6) loaded swapped: the unpacks and block picks
        # below then leave x, y, z in lane order, seven shuffles in all
        order = [0, 2, 1, 3, 4, 6, 5, 7]
        got = [b.load(b.gep(base, [b.sext(b.extract_element(ids, ir.Constant(I32, j)), I64)]), align=8)
               for j in order]

        def pick(a, c, lanes):
            return b.shuffle_vector(a, c, ir.Constant(ir.VectorType(I32, len(lanes)), lanes))

        pairs = [pick(got[j], got[j + 1], list(range(8))) for j in range(0, LANES, 2)]
        even = [pick(pairs[h], pairs[h + 1], [0, 8, 2, 10, 4, 12, 6, 14]) for h in (0, 2)]
        odd = [pick(pairs[h], pairs[h + 1], [1, 9, 3, 11, 5, 13, 7, 15]) for h in (0, 2)]
        low, high = [0, 1, 4, 5, 8, 9, 12, 13], [2, 3, 6, 7, 10, 11, 14, 15]
        return pick(even[0], even[1], low), pick(odd[0], odd[1], low), pick(even[0], even[1], high)

    def rows_at(self, R_type, R):
        """a pointer to ``R[0, 0]`` of the (N, 4) rows R, which the far ends' loads index"""
        zero = ir.Constant(self.intp, 0)
        R_a = self.context.make_array(R_type)(self.context, self.builder, R)
        return cgutils.get_item_pointer(self.context, self.builder, R_type, R_a, [zero, zero], wraparound=False)

    def squared_lengths(self, R, a, b_, at, flags=FAST):
        """|R[b] - R[a]|² of the eight pairs ``at:at + LANES`` joining points
        ``a`` to ``b_`` of the (N, 4) rows R, whose fourth column is 0; each of
        R, a and b_ a (type, value) of the codegen's arguments, a and b_ int32
        (K,) arrays. Each difference and its square taken on its 256-bit row,
        then the rows' sums in ten shuffles, where the ends' coordinates
        transposed first took twenty-two. With ``flags=()`` every operation is
        rounded as written, ``(dx² + dy²) + dz²``, as :func:`.shared.gap2`
        computes it without fast-math."""
        b = self.builder
        rows_ptr = self.rows_at(*R)
        ivec = ir.VectorType(I32, LANES)
        ids_a, ids_b = (b.load(_vector_at(self.context, b, t, value, [at], ivec), align=4) for t, value in (a, b_))
        quad = ir.VectorType(ir.DoubleType(), 4)
        base = b.bitcast(rows_ptr, quad.as_pointer())

        def row(ids, j):
            return b.load(b.gep(base, [b.sext(b.extract_element(ids, ir.Constant(I32, j)), I64)]), align=8)

        def pick(a, c, lanes):
            return b.shuffle_vector(a, c, ir.Constant(ir.VectorType(I32, len(lanes)), lanes))

        # springs 1 and 2 (5 and 6) taken swapped: the sums below then come
        # out in the springs' order
        squares = []
        for j in (0, 2, 1, 3, 4, 6, 5, 7):
            d = b.fsub(row(ids_b, j), row(ids_a, j), flags=flags)
            squares.append(b.fmul(d, d, flags=flags))
        pairs = [pick(squares[j], squares[j + 1], list(range(8))) for j in range(0, LANES, 2)]
        # each pair's x + y and z + 0 side by side, then the two halves added
        halves = [b.fadd(pick(pairs[h], pairs[h + 1], [0, 8, 2, 10, 4, 12, 6, 14]),
                         pick(pairs[h], pairs[h + 1], [1, 9, 3, 11, 5, 13, 7, 15]), flags=flags) for h in (0, 2)]
        return b.fadd(pick(halves[0], halves[1], [0, 1, 4, 5, 8, 9, 12, 13]),
                      pick(halves[0], halves[1], [2, 3, 6, 7, 10, 11, 14, 15]), flags=flags)


@intrinsic
def pull_lanes(typingctx, P, R, L, free, keep, other, k, k_rest, rows, at, count, motion):
    """Points ``at:at + count`` (``count`` ≤ LANES) of the (3, N) planes P take
    their Verlet step into L: ``x' = x + free (keep (x - L) + a dt²)``, with
    ``a = g + sum over rows r of rows[0]:rows[1] of (k - k_rest / |d|) d``
    and ``d = R[other[r], :3] - x``, lane by lane.

    ``R`` (N, 4): P's positions as rows, a load per far end; ``other`` int32
    (R, LANES): the far ends; ``k`` [1/s²] and ``k_rest`` (k times the rest
    length) [m/s²] float64 (R, LANES); ``free`` and ``keep`` float64 (N,);
    ``motion``: gravity (3) [m/s²], dt² [s²]. L then holds the new
    positions; P is left as it was (a later call reads it). Nothing is
    bounds-checked: the caller keeps ``rows`` inside the slots, every
    ``other`` of them inside R, and ``at + count`` ≤ N. The lanes from
    ``count`` on are neither read nor written."""
    if not (_plane(P, 2) and _plane(R, 2) and _plane(L, 2) and _plane(free, 1) and _plane(keep, 1) and _plane(k, 2)
            and _plane(k_rest, 2) and _plane(other, 2, types.int32)):
        raise TypingError("pull_lanes takes C float64 (3, N), (N, 4), (3, N), (N,), (N,), int32 (R, 8), "
                          "float64 (R, 8), (R, 8) arrays")
    if not (isinstance(rows, types.UniTuple) and len(rows) == 2 and isinstance(rows.dtype, types.Integer)):
        raise TypingError("pull_lanes takes its rows as a tuple of two integers")
    if not (isinstance(motion, types.UniTuple) and len(motion) == 4 and motion.dtype == types.float64):
        raise TypingError("pull_lanes takes gravity and dt² as a tuple of four floats")
    sig = types.void(P, R, L, free, keep, other, k, k_rest, rows, at, count, motion)

    def codegen(context, b, signature, args):
        P_t, R_t, L_t, free_t, keep_t, other_t, k_t, kr_t, rows_t, at_t, count_t, _ = signature.args
        P_v, R_v, L_v, free_v, keep_v, other_v, k_v, kr_v, rows_v, at_v, count_v, motion_v = args
        intp = context.get_value_type(types.intp)
        at = context.cast(b, at_v, at_t, types.intp)
        count = context.cast(b, count_v, count_t, types.intp)
        first, stop = (context.cast(b, r, rows_t.dtype, types.intp) for r in cgutils.unpack_tuple(b, rows_v, 2))
        lane_ids = ir.Constant(ir.VectorType(intp, LANES), list(range(LANES)))
        valid = b.icmp_signed("<", lane_ids, _splat(b, count, ir.VectorType(intp, LANES)))
        v = _Rows(context, b, valid)
        g0, g1, g2, dt2 = (v.splat(x) for x in cgutils.unpack_tuple(b, motion_v, 4))
        x = [v.masked_load(P_t, P_v, c, at) for c in range(3)]
        rows_ptr = v.rows_at(R_t, R_v)
        sums = [cgutils.alloca_once_value(b, v.constant(0.0)) for _ in range(3)]
        ivec = ir.VectorType(I32, LANES)
        with cgutils.for_range_slice(b, first, stop, ir.Constant(intp, 1), inc=True) as (r, _):
            ids = b.load(_vector_at(context, b, other_t, other_v, [r, ir.Constant(intp, 0)], ivec), align=4)
            ks = v.load(k_t, k_v, r, ir.Constant(intp, 0))
            pull = v.load(kr_t, kr_v, r, ir.Constant(intp, 0))
            d = [v.sub(end, x[c]) for c, end in enumerate(v.far_ends(rows_ptr, ids))]
            l2 = v.add(v.add(v.mul(d[0], d[0]), v.mul(d[1], d[1])), v.mul(d[2], d[2]))
            f = v.sub(ks, _over_length(v, pull, l2))
            for c in range(3):
                b.store(v.call("fmuladd", [f, d[c], b.load(sums[c])]), sums[c])
        fr = v.masked_load(free_t, free_v, at)
        kp = v.masked_load(keep_t, keep_v, at)
        for c, g in enumerate((g0, g1, g2)):
            a = v.add(b.load(sums[c]), g)
            last = v.masked_load(L_t, L_v, c, at)
            turn = v.call("fmuladd", [v.sub(x[c], last), kp, v.mul(a, dt2)])
            v.masked_store(v.call("fmuladd", [turn, fr, x[c]]), L_t, L_v, c, at)
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def over_lanes(typingctx, R, a, b, limit2, at):
    """Whether any of the springs ``at:at + LANES`` joining points ``a`` to ``b``
    (int32 (S,)) of the rows R (N, 4) [m] may be longer than its limit, its
    squared length over ``limit2`` (float64 (S,)) [m²] less a part in 1e12:
    a test that never misses a spring the exact one takes, for Provot's pass
    to skip the eight where it is false. Nothing is bounds-checked: the
    caller keeps ``at + LANES`` inside the springs and their ends inside R."""
    if not (_plane(R, 2) and _plane(a, 1, types.int32) and _plane(b, 1, types.int32) and _plane(limit2, 1)):
        raise TypingError("over_lanes takes C float64 (N, 4), int32 (S,), int32 (S,), float64 (S,) arrays")
    sig = types.boolean(R, a, b, limit2, at)

    def codegen(context, b_, signature, args):
        R_t, a_t, b_t, limit_t, at_t = signature.args
        R_v, a_v, b_v, limit_v, at_v = args
        at = context.cast(b_, at_v, at_t, types.intp)
        v = _Rows(context, b_, ir.Constant(ir.VectorType(ir.IntType(1), LANES), [1] * LANES))
        l2 = v.squared_lengths((R_t, R_v), (a_t, a_v), (b_t, b_v), at)
        limit = v.mul(v.load(limit_t, limit_v, at), v.constant(1.0 - 1e-12))
        return v.any(v.greater(l2, limit))

    return sig, codegen
