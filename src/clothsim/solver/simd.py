"""Vector code numba does not write by itself, for the list build's inner loop.

The build tests candidates LANES at a time and keeps a mask of bits, one per
candidate inside the search sphere (:func:`inside`), then appends the points
of the set bits to the list (:func:`compress_store`). The near stencil tests
its pairs the same way (:func:`close_lanes`).

- Written as a loop that ors a shifted bit per lane into a 64-bit mask,
  LLVM vectorises the test but then folds the lanes together in a chain of
  shuffles; LLVM's own vector code turns the lanes' comparison straight
  into a bit mask, one instruction on x86. Portable: LLVM lowers it for
  any target.
- Appending the set bits one by one ends in a mispredicted branch for most
  chunks; AVX-512's compress packs the chosen lanes of a vector together
  in one step, so the append is a load, a compress and a store whatever
  the bits. Only where the machine has AVX-512 (:func:`has_compress`).
"""

from __future__ import annotations

import os

import llvmlite.binding as llvm
import numba
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.core.errors import TypingError
from numba.extending import intrinsic

LANES = 16
"""lanes of 32 bits the build's vector code works on at once: one 512-bit vector"""

FORCE_PORTABLE = "CLOTHSIM_NO_AVX512"
"""set (to anything but empty) in the environment to compile the portable path
on a machine that has AVX-512: how the tests check that path. It takes effect
when the list build's module is imported (its ``COMPRESS``), and
:mod:`clothsim.kernel_cache` keys numba's cache folder on its value, so a run
with it set compiles into, and loads from, a folder of its own, never the
AVX-512 kernels"""


def target_features() -> str:
    """The CPU features numba compiles for: its configured ones, else the host's."""
    name = numba.config.CPU_NAME
    if name and name != "host":
        return numba.config.CPU_FEATURES or ""
    return llvm.get_host_cpu_features().flatten()


def has_avx512f() -> bool:
    """Whether numba compiles for AVX-512F (32 vector registers at either width,
    the compress instructions); its cache keys every entry on these features."""
    return "+avx512f" in target_features().split(",")


def has_compress() -> bool:
    """Whether compiled code may use the AVX-512 compress (AVX512F), unless
    FORCE_PORTABLE asks for the portable path."""
    if os.environ.get(FORCE_PORTABLE):
        return False
    return has_avx512f()


def _vector_at(context, builder, array_type, array, index, vec):
    """A pointer to ``vec`` (an LLVM vector type) at ``array[index]`` (a list of
    intp values), unchecked: the lanes are the elements from there on."""
    a = context.make_array(array_type)(context, builder, array)
    ptr = cgutils.get_item_pointer(context, builder, array_type, a, index, wraparound=False)
    return builder.bitcast(ptr, vec.as_pointer())


def _splat(builder, value, vec):
    """``value`` in every lane of ``vec`` (an LLVM vector type)."""
    one = builder.insert_element(ir.Constant(vec, ir.Undefined), value, ir.Constant(ir.IntType(32), 0))
    return builder.shuffle_vector(one, ir.Constant(vec, ir.Undefined),
                                  ir.Constant(ir.VectorType(ir.IntType(32), vec.count), [0] * vec.count))


@intrinsic
def compress_store(typingctx, src, at, dst, row, end, mask):
    """Store the lanes ``src[at:at + LANES]`` whose bit is set in ``mask``, in order,
    at ``dst[row, end:]``; the rest of ``dst[row, end:end + LANES]`` is
    overwritten with zeros. ``src`` is int32 (N,), ``dst`` int32 (R, M) with
    contiguous rows; nothing is bounds-checked. Only where :func:`has_compress`."""
    if not (isinstance(src, types.Array) and src.ndim == 1 and src.dtype == types.int32
            and isinstance(dst, types.Array) and dst.ndim == 2 and dst.dtype == types.int32):
        raise TypingError("compress_store takes int32 (N,) and (R, M) arrays")
    sig = types.void(src, at, dst, row, end, mask)

    def codegen(context, builder, signature, args):
        src_v, at_v, dst_v, row_v, end_v, mask_v = args
        src_t, _, dst_t = signature.args[:3]
        at_v = context.cast(builder, at_v, signature.args[1], types.intp)
        row_v = context.cast(builder, row_v, signature.args[3], types.intp)
        end_v = context.cast(builder, end_v, signature.args[4], types.intp)
        mask_v = context.cast(builder, mask_v, signature.args[5], types.uint64)
        vec = ir.VectorType(ir.IntType(32), LANES)
        bits = ir.VectorType(ir.IntType(1), LANES)
        lanes = builder.load(_vector_at(context, builder, src_t, src_v, [at_v], vec), align=4)
        chosen = builder.bitcast(builder.trunc(mask_v, ir.IntType(LANES)), bits)
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(vec, [vec, vec, bits]),
                                            "llvm.x86.avx512.mask.compress.v16i32")
        packed = builder.call(fn, [lanes, ir.Constant(vec, None), chosen])
        builder.store(packed, _vector_at(context, builder, dst_t, dst_v, [row_v, end_v], vec), align=4)
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def inside(typingctx, sx, sy, sz, rows, cols, at, x, y, z, row, col, radius2, wr2, wc2, rho2):
    """A bit per slot ``at + j``, j < LANES, of the float32 (N,) arrays of positions
    (sx, sy, sz) and grid rows and columns: set where the slot lies closer than
    ``sqrt(radius2)`` to (x, y, z) and its grid offset from (row, col) does not
    lie inside the ellipse ``(dr² wr2 + dc² wc2 < rho2)``. The same single
    precision arithmetic, in the same order, as the scalar form
    ``(dx*dx + dy*dy + dz*dz < radius2) & (dr*dr*wr2 + dc*dc*wc2 >= rho2)``;
    nothing is bounds-checked."""
    arrays = (sx, sy, sz, rows, cols)
    if not all(isinstance(a, types.Array) and a.ndim == 1 and a.dtype == types.float32 for a in arrays):
        raise TypingError("inside takes five float32 (N,) arrays")
    sig = types.uint64(sx, sy, sz, rows, cols, at, x, y, z, row, col, radius2, wr2, wc2, rho2)

    def codegen(context, builder, signature, args):
        vec = ir.VectorType(ir.FloatType(), LANES)
        start = context.cast(builder, args[5], signature.args[5], types.intp)

        def load(k):
            return builder.load(_vector_at(context, builder, signature.args[k], args[k], [start], vec), align=4)

        def splat(k):
            return _splat(builder, context.cast(builder, args[k], signature.args[k], types.float32), vec)

        sx_v, sy_v, sz_v, rows_v, cols_v = (load(k) for k in range(5))
        dx = builder.fsub(splat(6), sx_v)
        dy = builder.fsub(splat(7), sy_v)
        dz = builder.fsub(splat(8), sz_v)
        d2 = builder.fadd(builder.fadd(builder.fmul(dx, dx), builder.fmul(dy, dy)), builder.fmul(dz, dz))
        dr = builder.fsub(rows_v, splat(9))
        dc = builder.fsub(cols_v, splat(10))
        grid = builder.fadd(builder.fmul(builder.fmul(dr, dr), splat(12)),
                            builder.fmul(builder.fmul(dc, dc), splat(13)))
        ok = builder.and_(builder.fcmp_ordered("<", d2, splat(11)), builder.fcmp_ordered(">=", grid, splat(14)))
        return builder.zext(builder.bitcast(ok, ir.IntType(LANES)), ir.IntType(64))

    return sig, codegen


@intrinsic
def close_lanes(typingctx, qx, qy, qz, weight, a, b, limit2):
    """A bit per lane j < LANES: set where ``weight[a + j]`` is not 0 and points
    ``a + j`` and ``b + j`` of the float32 (N,) planes (qx, qy, qz) lie closer
    than ``sqrt(limit2)``; ``weight`` is uint8 (N,). The near stencil's test,
    in the arithmetic of the scalar form ``dx*dx + dy*dy + dz*dz < limit2``;
    nothing is bounds-checked."""
    planes = (qx, qy, qz)
    if not all(isinstance(q, types.Array) and q.ndim == 1 and q.dtype == types.float32 for q in planes):
        raise TypingError("close_lanes takes three float32 (N,) arrays")
    if not (isinstance(weight, types.Array) and weight.ndim == 1 and weight.dtype == types.uint8):
        raise TypingError("close_lanes takes a uint8 (N,) weight array")
    sig = types.uint64(qx, qy, qz, weight, a, b, limit2)

    def codegen(context, builder, signature, args):
        vec = ir.VectorType(ir.FloatType(), LANES)
        bytes_ = ir.VectorType(ir.IntType(8), LANES)
        a_v = context.cast(builder, args[4], signature.args[4], types.intp)
        b_v = context.cast(builder, args[5], signature.args[5], types.intp)

        def load(k, at, kind):
            return builder.load(_vector_at(context, builder, signature.args[k], args[k], [at], kind), align=1)

        splat = _splat(builder, context.cast(builder, args[6], signature.args[6], types.float32), vec)
        d = [builder.fsub(load(k, b_v, vec), load(k, a_v, vec)) for k in range(3)]
        d2 = builder.fadd(builder.fadd(builder.fmul(d[0], d[0]), builder.fmul(d[1], d[1])),
                          builder.fmul(d[2], d[2]))
        taken = builder.icmp_unsigned("!=", load(3, a_v, bytes_), ir.Constant(bytes_, None))
        ok = builder.and_(builder.fcmp_ordered("<", d2, splat), taken)
        return builder.zext(builder.bitcast(ok, ir.IntType(LANES)), ir.IntType(64))

    return sig, codegen


ROWS8 = 8
"""the rows :func:`rows_to_columns` moves at once: eight doubles a vector"""

ROW_WIDTH = 24
"""the doubles of each row :func:`rows_to_columns` moves: three vectors of eight"""


def _transpose8(builder, rows):
    """The eight <8 x double> vectors ``rows`` transposed: vector k of the answer
    holds lane k of each of them, in order (three rounds of two-source
    shuffles, 24 in all)."""
    idx = ir.IntType(32)

    def mix(a, b, lanes):
        return builder.shuffle_vector(a, b, ir.Constant(ir.VectorType(idx, ROWS8), lanes))

    low, high = [0, 8, 2, 10, 4, 12, 6, 14], [1, 9, 3, 11, 5, 13, 7, 15]
    t = []
    for i in range(0, 8, 2):
        t += [mix(rows[i], rows[i + 1], low), mix(rows[i], rows[i + 1], high)]
    pairs_low, pairs_high = [0, 1, 8, 9, 4, 5, 12, 13], [2, 3, 10, 11, 6, 7, 14, 15]
    u = [None] * 8
    for base in (0, 4):
        for odd in (0, 1):
            a, b = t[base + odd], t[base + 2 + odd]
            u[base + odd], u[base + 2 + odd] = mix(a, b, pairs_low), mix(a, b, pairs_high)
    halves_low, halves_high = [0, 1, 2, 3, 8, 9, 10, 11], [4, 5, 6, 7, 12, 13, 14, 15]
    out = [None] * 8
    for k in range(4):
        out[k], out[k + 4] = mix(u[k], u[k + 4], halves_low), mix(u[k], u[k + 4], halves_high)
    return out


@intrinsic
def rows_to_columns(typingctx, table, rows, j, dst, at, stride):
    """Rows ``rows[j + i]`` (i < ROWS8) of the float64 (T, ROW_WIDTH) C-ordered
    ``table`` written as columns: ``dst[at + c * stride + i] = table[rows[j + i],
    c]`` for every c < ROW_WIDTH, into the float64 flat ``dst``. Each row is read
    as ROW_WIDTH / 8 whole vectors and each block of eight by eight is transposed in
    registers, where numba's own loop gathers the table one double at a time.
    The values are moved, never computed: the same bits. ``rows`` is uint64
    (N,); nothing is bounds-checked."""
    if not (isinstance(table, types.Array) and table.ndim == 2 and table.dtype == types.float64
            and table.layout == "C"):
        raise TypingError(f"rows_to_columns takes a C-ordered float64 (T, {ROW_WIDTH}) table")
    if not (isinstance(rows, types.Array) and rows.ndim == 1 and rows.dtype == types.uint64):
        raise TypingError("rows_to_columns takes uint64 (N,) row numbers")
    if not (isinstance(dst, types.Array) and dst.ndim == 1 and dst.dtype == types.float64 and dst.layout == "C"):
        raise TypingError("rows_to_columns writes a contiguous float64 (M,) array")
    sig = types.void(table, rows, j, dst, at, stride)

    def codegen(context, builder, signature, args):
        table_v, rows_v, j_v, dst_v, at_v, stride_v = args
        table_t, rows_t, j_t, dst_t, at_t, stride_t = signature.args
        j_v = context.cast(builder, j_v, j_t, types.intp)
        at_v = context.cast(builder, at_v, at_t, types.intp)
        stride_v = context.cast(builder, stride_v, stride_t, types.intp)
        vec = ir.VectorType(ir.DoubleType(), ROWS8)
        intp = context.get_value_type(types.intp)
        rows_a = context.make_array(rows_t)(context, builder, rows_v)
        numbers = []
        for i in range(ROWS8):
            ptr = cgutils.get_item_pointer(context, builder, rows_t, rows_a, [builder.add(j_v, ir.Constant(intp, i))],
                                           wraparound=False)
            numbers.append(builder.load(ptr))
        for chunk in range(ROW_WIDTH // ROWS8):
            first = ir.Constant(intp, chunk * ROWS8)
            read = [builder.load(_vector_at(context, builder, table_t, table_v, [n, first], vec), align=8)
                    for n in numbers]
            for k, column in enumerate(_transpose8(builder, read)):
                row = builder.mul(ir.Constant(intp, chunk * ROWS8 + k), stride_v)
                where = _vector_at(context, builder, dst_t, dst_v, [builder.add(at_v, row)], vec)
                builder.store(column, where, align=8)
        return context.get_dummy_value()

    return sig, codegen


FLAGS8 = 8
"""the flags :func:`flagged_lanes` reads at once: eight int64 indices a vector"""


@intrinsic
def flagged_lanes(typingctx, flags, at, dst, end):
    """The indices ``at + i`` (i < FLAGS8) whose flag ``flags[at + i]`` is set, in
    order, written from ``dst[end]`` by AVX-512's compress; the rest of
    ``dst[end:end + FLAGS8]`` is overwritten with zeros. Returns how many
    (int64). ``flags`` is bool or uint8 (N,), ``dst`` int64 (M,), both
    contiguous: a walk over the set bits of a word ends in a mispredicted
    branch for most words, this is a load, a compress and a store whatever the
    flags. Nothing is bounds-checked. Only where :func:`has_compress`."""
    if not (isinstance(flags, types.Array) and flags.ndim == 1 and flags.layout == "C"
            and flags.dtype in (types.boolean, types.uint8)):
        raise TypingError("flagged_lanes reads a contiguous bool or uint8 (N,) array")
    if not (isinstance(dst, types.Array) and dst.ndim == 1 and dst.dtype == types.int64 and dst.layout == "C"):
        raise TypingError("flagged_lanes writes a contiguous int64 (M,) array")
    sig = types.int64(flags, at, dst, end)

    def codegen(context, builder, signature, args):
        flags_v, at_v, dst_v, end_v = args
        flags_t, at_t, dst_t, end_t = signature.args
        at_v = context.cast(builder, at_v, at_t, types.intp)
        end_v = context.cast(builder, end_v, end_t, types.intp)
        i64 = ir.IntType(64)
        vec = ir.VectorType(i64, FLAGS8)
        bits = ir.VectorType(ir.IntType(1), FLAGS8)
        bytes_ = ir.VectorType(ir.IntType(8), FLAGS8)
        read = builder.load(_vector_at(context, builder, flags_t, flags_v, [at_v], bytes_), align=1)
        chosen = builder.icmp_unsigned("!=", read, ir.Constant(bytes_, None))
        lanes = builder.add(_splat(builder, builder.sext(at_v, i64), vec), ir.Constant(vec, list(range(FLAGS8))))
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(vec, [vec, vec, bits]),
                                            "llvm.x86.avx512.mask.compress.v8i64")
        packed = builder.call(fn, [lanes, ir.Constant(vec, None), chosen])
        builder.store(packed, _vector_at(context, builder, dst_t, dst_v, [end_v], vec), align=8)
        count = builder.ctpop(builder.bitcast(chosen, ir.IntType(FLAGS8)))
        return builder.zext(count, i64)

    return sig, codegen


@intrinsic
def kept_lanes(typingctx, listed, at, cell, status, s0, keep, dst, end):
    """The entries q of ``listed[at:at + FLAGS8]`` (int64) whose cell ``cell[q]``
    (int32; negative for none) is none, or whose cell's status entry
    ``status[s0 + cell[q]]`` (int32) has a bit of ``keep`` set, in order, written
    from ``dst[end]`` (int64) by AVX-512's compress; the rest of ``dst[end:end +
    FLAGS8]`` is overwritten with zeros. Returns how many (int64). The cells and
    the status entries are read by two gathers, eight lanes at once: the loop
    that reads them one by one and appends each point was the slowest part of
    a mesh collider's first pass (docs/performance.md). ``dst`` may be
    ``listed`` itself with ``end <= at``: the lanes are read before the store.
    Nothing is bounds-checked: every ``q`` must index ``cell`` and every
    ``s0 + max(cell[q], 0)`` index ``status``. Only where :func:`has_compress`."""
    ints = (types.int64, types.int32)
    if not all(isinstance(a, types.Array) and a.ndim == 1 and a.layout == "C" and a.dtype == d
               for a, d in ((listed, ints[0]), (cell, ints[1]), (status, ints[1]), (dst, ints[0]))):
        raise TypingError("kept_lanes takes contiguous int64 listed and dst, int32 cell and status arrays")
    sig = types.int64(listed, at, cell, status, s0, keep, dst, end)

    def codegen(context, builder, signature, args):
        listed_v, at_v, cell_v, status_v, s0_v, keep_v, dst_v, end_v = args
        listed_t, at_t, cell_t, status_t, s0_t, keep_t, dst_t, end_t = signature.args
        at_v = context.cast(builder, at_v, at_t, types.intp)
        end_v = context.cast(builder, end_v, end_t, types.intp)
        s0_v = context.cast(builder, s0_v, s0_t, types.int64)
        keep_v = builder.trunc(context.cast(builder, keep_v, keep_t, types.int64), ir.IntType(32))
        i32, i64 = ir.IntType(32), ir.IntType(64)
        v32, v64 = ir.VectorType(i32, FLAGS8), ir.VectorType(i64, FLAGS8)
        bits = ir.VectorType(ir.IntType(1), FLAGS8)
        q = builder.load(_vector_at(context, builder, listed_t, listed_v, [at_v], v64), align=8)
        cells = _gather32(context, builder, cell_t, cell_v, q)
        none = builder.icmp_signed("<", cells, ir.Constant(v32, None))
        at_cell = builder.select(none, ir.Constant(v32, None), cells)
        index = builder.add(_splat(builder, s0_v, v64), builder.sext(at_cell, v64))
        st = _gather32(context, builder, status_t, status_v, index)
        held = builder.icmp_unsigned("!=", builder.and_(st, _splat(builder, keep_v, v32)), ir.Constant(v32, None))
        chosen = builder.or_(none, held)
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(v64, [v64, v64, bits]),
                                            "llvm.x86.avx512.mask.compress.v8i64")
        packed = builder.call(fn, [q, ir.Constant(v64, None), chosen])
        builder.store(packed, _vector_at(context, builder, dst_t, dst_v, [end_v], v64), align=8)
        return builder.zext(builder.ctpop(builder.bitcast(chosen, ir.IntType(FLAGS8))), i64)

    return sig, codegen


def _gather32(context, builder, array_type, array, index):
    """``array[index]`` for an int32 array and a vector of FLAGS8 int64 indices, by
    LLVM's masked gather with every lane on"""
    i32, i64 = ir.IntType(32), ir.IntType(64)
    v32, v64 = ir.VectorType(i32, FLAGS8), ir.VectorType(i64, FLAGS8)
    bits = ir.VectorType(ir.IntType(1), FLAGS8)
    a = context.make_array(array_type)(context, builder, array)
    base = _splat(builder, builder.ptrtoint(a.data, i64), v64)
    where = builder.inttoptr(builder.add(base, builder.shl(index, ir.Constant(v64, [2] * FLAGS8))),
                             ir.VectorType(i32.as_pointer(), FLAGS8))
    fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(v32, [where.type, i32, bits, v32]),
                                        "llvm.masked.gather.v8i32.v8p0")
    return builder.call(fn, [where, ir.Constant(i32, 4), ir.Constant(bits, [1] * FLAGS8), ir.Constant(v32, None)])


BYTES64 = 64
"""the labels :func:`count_equal` compares at once: one 512-bit vector of bytes"""


@intrinsic
def count_equal(typingctx, labels, at, value):
    """How many of ``labels[at:at + BYTES64]`` (int8 (N,), contiguous) equal
    ``value`` (int64), as an int64: one vector comparison of the 64 bytes and
    a count of its bits. A loop that adds one per equal label adds into a
    64-bit count (numba widens every integer sum), eight labels a vector.
    Nothing is bounds-checked. Portable: LLVM lowers it for any target."""
    if not (isinstance(labels, types.Array) and labels.ndim == 1 and labels.layout == "C"
            and labels.dtype == types.int8):
        raise TypingError("count_equal reads a contiguous int8 (N,) array")
    sig = types.int64(labels, at, value)

    def codegen(context, builder, signature, args):
        labels_v, at_v, value_v = args
        labels_t, at_t, value_t = signature.args
        at_v = context.cast(builder, at_v, at_t, types.intp)
        i8 = ir.IntType(8)
        bytes_ = ir.VectorType(i8, BYTES64)
        read = builder.load(_vector_at(context, builder, labels_t, labels_v, [at_v], bytes_), align=1)
        value = builder.trunc(context.cast(builder, value_v, value_t, types.int64), i8)
        equal = builder.icmp_signed("==", read, _splat(builder, value, bytes_))
        count = builder.ctpop(builder.bitcast(equal, ir.IntType(BYTES64)))
        return builder.zext(count, ir.IntType(64))

    return sig, codegen
