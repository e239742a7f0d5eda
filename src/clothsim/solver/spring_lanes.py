"""The springs and the Verlet step eight points at a time, in one pass (see :mod:`.springs`).

numba's loops (:func:`.springs.integrate_chunks`) compute every set's spring
forces for a chunk of 512 points into the force buffer, then gather each
point's twelve and move it: nine loops a chunk, the gathering reading the
buffer back from the L2 cache. Here a numba loop walks the cloth eight
points at a time and calls LLVM vector code that computes the six sets'
forces of the springs that start at the eight, stores them, and moves the
eight at once (:func:`spring_step_lanes`). A point's forces come from its
own springs, still in registers; from the springs one and two points back
along its row, shifted across from the eight before; and from the rows
above, stored a row or two ago and still in the L1 cache. No later eight
reads a moved point: a spring's ends are both at its start or after it.

The arithmetic is :func:`.springs.spring_forces`' and
:func:`.springs.verlet_gather`'s with numba's fast-math flags, in the order
LLVM gives numba's loops (the sums and the multiply-adds spelled out where
LLVM would order this code otherwise), so the positions are the same to the
bit: ``tests/test_spring_lanes.py`` holds the two to it. The slots where a
set has no spring (a row's wrap, or a kind switched off) are stored as
zeros, as the loops store them: each set takes a byte whose bits pick the
lanes to zero (:attr:`.springs.GridSprings.gaps`).
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.core.errors import TypingError
from numba.extending import intrinsic

from .colliders.lanes import FAST, LANES, Lanes
from .shared import DIVIDE, KERNEL_OPTIONS, SET_STEP
from .simd import _vector_at

__all__ = ["LANES", "force_lanes", "integrate_eights", "spring_step_lanes"]

SETS = len(SET_STEP)
"""spring sets of a grid cloth"""

IN_ORDER = ("nnan", "ninf", "nsz", "arcp", "contract", "afn")
"""numba's fast-math flags without ``reassoc``, for the gathered sums, written
in the order LLVM reassociates numba's own loop into: left free to
reassociate, LLVM orders this code's terms otherwise (some are shifted
vectors, not loads), and the sums round differently"""

NEAR = tuple((1 if di < 0 else 0, max(di, 0) if dr == 0 else None) for dr, di in SET_STEP)
"""each set's ends as offsets back from a point to the springs that reach it
(``start``, ``end`` of :class:`.springs.GridSprings`) where they do not
depend on the row's length: the step takes those forces from the eight just
computed and the eight before, shifted across, not from the buffer"""


def _is_array(t, ndim):
    return isinstance(t, types.Array) and t.ndim == ndim and t.layout == "C" and t.dtype == types.float64


def _ints(builder, tuple_type, value, count):
    if not (isinstance(tuple_type, types.UniTuple) and len(tuple_type) == count
            and isinstance(tuple_type.dtype, types.Integer)):
        raise TypingError(f"the springs' lanes take a tuple of {count} integers")
    return cgutils.unpack_tuple(builder, value, count)


def _floats(tuple_type, count):
    if not (isinstance(tuple_type, types.UniTuple) and len(tuple_type) == count
            and tuple_type.dtype == types.float64):
        raise TypingError(f"the springs' lanes take a tuple of {count} floats")


def _check_forces(P, rest, gaps, F, k_over_m):
    """A typing error unless the arguments are what the force pass reads and writes."""
    if not (_is_array(P, 2) and _is_array(rest, 2) and _is_array(F, 3)):
        raise TypingError("the springs' lanes take C float64 (3, N), (6, N) and (6, 3, M) arrays")
    if not (isinstance(gaps, types.Array) and gaps.ndim == 2 and gaps.layout == "C" and gaps.dtype == types.uint8):
        raise TypingError("the springs' lanes take a C uint8 (6, E) array of gaps")
    _floats(k_over_m, SETS)


def _over_length(lanes, a, l2):
    """a / sqrt(l2) for eight lanes, as :func:`.shared.over_length` computes it
    (a double square root and divide, or the single-precision estimate and
    one Newton step, as :data:`.shared.DIVIDE` chooses)."""
    b = lanes.builder
    tiny = lanes.splat(ir.Constant(ir.DoubleType(), 1e-30))
    l2c = lanes.pick(b.fcmp_ordered("<", l2, tiny, flags=FAST), tiny, l2)
    if DIVIDE:
        return lanes.div(a, lanes.sqrt(l2c))
    vec32 = ir.VectorType(ir.FloatType(), LANES)
    sqrt32 = cgutils.get_or_insert_function(b.module, ir.FunctionType(vec32, [vec32]), "llvm.sqrt.v8f32")
    one32 = ir.Constant(vec32, [1.0] * LANES)
    y32 = b.fdiv(one32, b.call(sqrt32, [b.fptrunc(l2c, vec32)], fastmath=FAST), flags=FAST)
    y = b.fpext(y32, lanes.vec)
    half = lanes.splat(ir.Constant(ir.DoubleType(), 0.5))
    three_halves = lanes.splat(ir.Constant(ir.DoubleType(), 1.5))
    step = lanes.sub(three_halves, lanes.mul(lanes.mul(lanes.mul(half, l2), y), y))
    return lanes.mul(a, lanes.mul(y, step))


def _forces(context, b, types_, values):
    """The body of :func:`force_lanes` (its first nine arguments): stores the
    forces and returns them, [set][coordinate] vectors."""
    P_t, rest_t, gaps_t, F_t, at_t, pad_t, ends_t, k_t, off_t = types_[:9]
    P_v, rest_v, gaps_v, F_v, at_v, pad_v, ends_v, k_v, off_v = values[:9]
    lanes = Lanes(context, b)
    intp = context.get_value_type(types.intp)
    at = context.cast(b, at_v, at_t, types.intp)
    eight = b.ashr(at, ir.Constant(intp, 3))
    pad = context.cast(b, pad_v, pad_t, types.intp)
    ends = [context.cast(b, e, ends_t.dtype, types.intp) for e in _ints(b, ends_t, ends_v, 2 * SETS)]
    offs = _ints(b, off_t, off_v, SETS)
    ks = lanes.numbers(k_t, k_v)
    zero = ir.Constant(lanes.vec, None)
    byte = ir.IntType(LANES)
    gaps = context.make_array(gaps_t)(context, b, gaps_v)

    def plane(c, i):
        return b.load(_vector_at(context, b, P_t, P_v, [ir.Constant(intp, c), i], lanes.vec), align=8)

    out = []
    for s in range(SETS):
        # each set loads its ends afresh: the loads shared between sets (both
        # ends of set 3 are other sets' ends), LLVM fused the sums' products
        # otherwise than in numba's loop, and the forces rounded differently
        ia, ib = b.add(at, ends[s]), b.add(at, ends[SETS + s])
        d = [lanes.sub(plane(c, ib), plane(c, ia)) for c in range(3)]
        l2 = lanes.add(lanes.add(lanes.mul(d[0], d[0]), lanes.mul(d[1], d[1])), lanes.mul(d[2], d[2]))
        rl = b.load(_vector_at(context, b, rest_t, rest_v, [ir.Constant(intp, s), at], lanes.vec), align=8)
        f = lanes.sub(ks[s], _over_length(lanes, lanes.mul(ks[s], rl), l2))
        gap_ptr = cgutils.get_item_pointer(context, b, gaps_t, gaps, [ir.Constant(intp, s), eight],
                                           wraparound=False)
        bits = b.bitcast(b.or_(b.load(gap_ptr), b.trunc(offs[s], byte)), lanes.bits)
        out.append([])
        for c in range(3):
            value = lanes.pick(bits, zero, lanes.mul(f, d[c]))
            ptr = _vector_at(context, b, F_t, F_v, [ir.Constant(intp, s), ir.Constant(intp, c), b.add(pad, at)],
                             lanes.vec)
            b.store(value, ptr, align=8)
            out[s].append(value)
    return out


@intrinsic
def force_lanes(typingctx, P, rest, gaps, F, at, pad, ends, k_over_m, off):
    """The forces of the six sets' springs that start at points ``at:at + LANES``
    (``at`` a multiple of LANES) into the force buffer ``F`` (6, 3, pad + N)
    at ``pad + at``: spring p of set s joins ``p + ends[s]`` to ``p + ends[6 +
    s]`` of the (3, N) planes P, rest length ``rest[s, p]`` [m], constant
    ``k_over_m[s]``. A lane is stored as 0 where its bit is set in ``gaps[s,
    at / LANES]`` (:attr:`.springs.GridSprings.gaps`) or in ``off[s]`` (255
    where set s is switched off). Nothing is bounds-checked: the caller keeps
    every spring's ends inside P."""
    _check_forces(P, rest, gaps, F, k_over_m)
    sig = types.void(P, rest, gaps, F, at, pad, ends, k_over_m, off)

    def codegen(context, builder, signature, args):
        _forces(context, builder, signature.args, args)
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def spring_step_lanes(typingctx, P, rest, gaps, F, at, pad, ends, k_over_m, off, L, free, motion):
    """:func:`force_lanes` and then the Verlet step of the same eight points
    ``at:at + LANES`` of the (3, N) planes P (moved in place) and L (set to
    where the points were), as :func:`.springs.verlet_gather` takes it:
    ``a = g + sum_s F_s[q - ends[s]] - F_s[q - ends[6 + s]]``, ``x' = x +
    free (keep (x - x_last) + a dt²)``; ``motion``: gravity (3) [m/s²],
    keep, dt² [s²]. The forces the eight just computed are taken as
    computed, and those at the offsets of :data:`NEAR` shifted across from
    the eight before, read where it was stored whole: a read across the
    eight just stored would wait for the stores to reach the cache. The
    buffer's pad must hold at least LANES slots (:func:`.springs.force_buffer`).
    Nothing is bounds-checked."""
    if not (_is_array(L, 2) and _is_array(free, 1)):
        raise TypingError("spring_step_lanes takes C float64 (3, N) and (N,) arrays")
    _check_forces(P, rest, gaps, F, k_over_m)
    _floats(motion, 5)
    sig = types.void(P, rest, gaps, F, at, pad, ends, k_over_m, off, L, free, motion)

    def codegen(context, builder, signature, args):
        b = builder
        forces = _forces(context, b, signature.args, args)
        F_t, at_t, pad_t, ends_t = signature.args[3], signature.args[4], signature.args[5], signature.args[6]
        F_v = args[3]
        L_t, free_t, motion_t = signature.args[9:]
        L_v, free_v, motion_v = args[9:]
        P_t, P_v = signature.args[0], args[0]
        lanes = Lanes(context, b)
        intp = context.get_value_type(types.intp)
        at = context.cast(b, args[4], at_t, types.intp)
        base = b.add(context.cast(b, args[5], pad_t, types.intp), at)
        ends = [context.cast(b, e, ends_t.dtype, types.intp) for e in _ints(b, ends_t, args[6], 2 * SETS)]
        gravity0, gravity1, gravity2, keep, dt2 = lanes.numbers(motion_t, motion_v)
        gravity = (gravity0, gravity1, gravity2)
        fr = lanes.load(free_t, free_v, at)
        index = ir.VectorType(ir.IntType(32), LANES)

        def stored(s, c, back):
            ptr = _vector_at(context, b, F_t, F_v, [ir.Constant(intp, s), ir.Constant(intp, c), b.sub(base, back)],
                             lanes.vec)
            return b.load(ptr, align=8)

        def near(s, c, shift):
            if shift == 0:
                return forces[s][c]
            before = stored(s, c, ir.Constant(intp, LANES))
            picks = ir.Constant(index, [LANES + j - shift for j in range(LANES)])
            return b.shuffle_vector(before, forces[s][c], picks)

        for c in range(3):
            # the order LLVM gives numba's loop of verlet_gather: gravity and the
            # starting ends' forces in one sum, the ending ends' in another
            pulls, pushes = gravity[c], None
            for s in range(SETS):
                back_a, back_b = NEAR[s]
                fb = near(s, c, back_b) if back_b is not None else stored(s, c, ends[SETS + s])
                pulls = b.fadd(near(s, c, back_a), pulls, flags=IN_ORDER)
                pushes = fb if pushes is None else b.fadd(pushes, fb, flags=IN_ORDER)
            a = b.fsub(pulls, pushes, flags=IN_ORDER)
            kc = ir.Constant(intp, c)
            xp = _vector_at(context, b, P_t, P_v, [kc, at], lanes.vec)
            lp = _vector_at(context, b, L_t, L_v, [kc, at], lanes.vec)
            xq = b.load(xp, align=8)
            # the multiply-adds LLVM makes of numba's loop, spelled out: left to
            # LLVM, this code's sum fused the other product
            velocity = b.fsub(xq, b.load(lp, align=8), flags=IN_ORDER)
            turn = _mul_add(b, velocity, keep, b.fmul(a, dt2, flags=IN_ORDER))
            b.store(_mul_add(b, turn, fr, xq), xp, align=8)
            b.store(xq, lp, align=8)
        return context.get_dummy_value()

    return sig, codegen


def _mul_add(b, x, y, z):
    """x y + z as one rounding where the target has a fused multiply-add, as
    numba's loops compute it (``llvm.fmuladd``)"""
    fn = cgutils.get_or_insert_function(b.module, ir.FunctionType(x.type, [x.type] * 3), "llvm.fmuladd.v8f64")
    return b.call(fn, [x, y, z], fastmath=IN_ORDER)


@njit(**KERNEL_OPTIONS)
def integrate_eights(P, L, free, knobs, springs, F, first, stop, moved):
    """:func:`.springs.integrate` eight points at a time, from ``first`` (a
    multiple of LANES) for as long as eight more points lie before ``stop``
    and every spring of the eight has both ends inside the cloth. Returns
    the point where it stopped: the caller's loops take the rest. The points
    before ``moved`` get their forces and are not moved. Where ``first`` or
    ``moved - first`` is not a multiple of LANES, or the arrays are too short
    for an eight's reads (a force buffer whose pad holds fewer than LANES
    slots, see :func:`.springs.force_buffer`), it does nothing and returns
    ``first``."""
    start, end, rest, gaps = springs.start, springs.end, springs.rest, springs.gaps
    k, g = knobs.k_over_m, knobs.gravity
    n = P.shape[1]
    pad = F.shape[2] - n
    reach = 0
    for s in range(SETS):
        reach = max(reach, start[s], end[s])
    last = min(stop, n - reach)
    if first < 0 or first % LANES != 0 or (moved - first) % LANES != 0 or pad < max(reach + 1, LANES) \
            or rest.shape[1] < n or free.shape[0] < n or L.shape[1] < n or gaps.shape[1] * LANES < n:
        return first  # not a range or buffer the eights can read inside: the loops take it all
    ends = (start[0], start[1], start[2], start[3], start[4], start[5],
            end[0], end[1], end[2], end[3], end[4], end[5])
    ks = (k[0], k[1], k[2], k[3], k[4], k[5])
    off = (_off(k[0]), _off(k[1]), _off(k[2]), _off(k[3]), _off(k[4]), _off(k[5]))
    motion = (g[0], g[1], g[2], knobs.keep, knobs.dt2)
    p = first
    while p + LANES <= min(last, moved):
        force_lanes(P, rest, gaps, F, p, pad, ends, ks, off)
        p += LANES
    while p + LANES <= last:
        spring_step_lanes(P, rest, gaps, F, p, pad, ends, ks, off, L, free, motion)
        p += LANES
    return p


@njit(cache=True, inline="always")
def _off(k):
    return np.int64(255) if k == 0.0 else np.int64(0)
