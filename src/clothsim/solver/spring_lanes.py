"""The springs and the Verlet step a few points at a time, in one pass (see :mod:`.springs`).

numba's loops (:func:`.springs.integrate_chunks`) compute every set's spring
forces for a chunk of 512 points into the force buffer, then gather each
point's twelve and move it: nine loops a chunk, the gathering reading the
buffer back from the L2 cache. Here a numba loop walks the cloth LANES
points at a time (eight with AVX-512, four without) and calls LLVM vector
code that computes the six sets' forces of the springs that start at those
points, stores them, and steps the points at once
(:func:`spring_step_lanes`). A point's forces come from its own springs,
still in registers; from the springs one and two points back along its
row, shifted across from the call before; and from the rows above, stored
a row or two ago and still in the L1 cache. The new positions go over the
last ones (see :func:`.springs.integrate`). The functions keep the names
of the eights, which they were written as.

The arithmetic is :func:`.springs.spring_forces`' and
:func:`.springs.verlet_gather`'s with numba's fast-math flags, the gathered
sums and the step's multiply-adds in the order LLVM gives numba's loops.
Two things differ, both for speed: the six ends the sets share are loaded
once (:data:`END_KEYS`), and with AVX-512 the inverse length is the
machine's estimate refined twice (:func:`_over_length`). The forces then
differ from the loops' by up to 1e-13 of ``k |d|``, the loops' own error.
Without AVX-512 this code divides: on AMD's Zen cores the loops divide
too, the same to the bit; on other cores the loops take their
single-precision estimate. ``tests/test_spring_lanes.py`` holds the two to
that. Every lane computes its own spring, so a spring's
force does not depend on where a call starts: a thread's part gives the
whole cloth's bits. The slots where a set has no spring (a row's wrap, or
a kind switched off) are stored as zeros, as the loops store them: each set
takes a byte of bits for each eight points, which pick the lanes to zero
(:attr:`.springs.GridSprings.gaps`).
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.core.errors import TypingError
from numba.extending import intrinsic

from .colliders.lanes import FAST, Lanes
from .shared import KERNEL_OPTIONS, LINE, SET_STEP
from .simd import _vector_at, has_avx512f, has_compress

__all__ = ["LANES", "force_lanes", "force_pad", "integrate_eights", "spring_step_lanes"]

SETS = len(SET_STEP)
"""spring sets of a grid cloth"""

LANES = 8 if has_avx512f() else 4
"""points a call takes: eight, a 512-bit vector of doubles, where numba
compiles for AVX-512, whose 32 vector registers hold an eight's forces;
four, a 256-bit vector, without it. Eight points in pairs of AVX2's 16
registers spilled, and ran slower than numba's loops; four ran faster on an
Intel core, and slower on a Zen 4 core, whose springs keep the loops
(:data:`.springs.BY_LANES`; docs/performance.md, 'The springs four points
at a time without AVX-512')"""

GAP_BITS = 8
"""points a byte of :attr:`.springs.GridSprings.gaps` covers, whatever LANES is"""

IN_ORDER = ("nnan", "ninf", "nsz", "arcp", "contract", "afn")
"""numba's fast-math flags without ``reassoc``, for the gathered sums, written
in the order LLVM reassociates numba's own loop into: left free to
reassociate, LLVM orders this code's terms otherwise (some are shifted
vectors, not loads), and the sums round differently"""

END_KEYS = tuple(((0, 1 if di < 0 else 0), (dr, max(di, 0))) for dr, di in SET_STEP)
"""each set's two ends as (rows, points) along from a spring's start point
``p`` (the ``start`` and ``end`` of :func:`.springs.build_stencil`): the sets
share six ends, so a call loads each of those once (18 vectors) rather
than twice a set (36), and the step takes the point's own from them;
:func:`integrate_eights` leaves any other stencil to the loops"""

RSQRT14 = has_compress()
"""whether the inverse length is AVX-512's estimate refined twice (see
:func:`_over_length`): where numba compiles for AVX-512, unless
``CLOTHSIM_NO_AVX512`` asks for the portable path, where this code divides"""

NEAR = tuple((1 if di < 0 else 0, max(di, 0) if dr == 0 else None) for dr, di in SET_STEP)
"""each set's ends as offsets back from a point to the springs that reach it
(``start``, ``end`` of :class:`.springs.GridSprings`) where they do not
depend on the row's length: the step takes those forces from the lanes just
computed and the call's before, shifted across, not from the buffer"""


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


class _Vector(Lanes):
    """:class:`.colliders.lanes.Lanes` with what the springs' code needs
    besides: pointers into arrays of more dimensions, constants in every
    lane, and LLVM's other vector intrinsics by name."""

    def __init__(self, context, builder, width=8):
        super().__init__(context, builder, width)
        self.intp = context.get_value_type(types.intp)

    def constant(self, x):
        return ir.Constant(self.vec, [x] * self.width)

    def at(self, array_type, array, *index):
        """the vector's pointer at ``array[index]``, ints or intp values"""
        index = [ir.Constant(self.intp, i) if isinstance(i, int) else i for i in index]
        return _vector_at(self.context, self.builder, array_type, array, index, self.vec)

    def load(self, array_type, array, *index):
        return self.builder.load(self.at(array_type, array, *index), align=8)

    def call(self, name, args):
        """``llvm.name`` on vectors of doubles, with numba's fast-math flags
        (without ``reassoc`` for ``fmuladd``)"""
        fn = cgutils.get_or_insert_function(self.builder.module, ir.FunctionType(self.vec, [self.vec] * len(args)),
                                            f"llvm.{name}.v{self.width}f64")
        return self.builder.call(fn, args, fastmath=FAST if name != "fmuladd" else IN_ORDER)


def _over_length(v, a, l2):
    """a / sqrt(l2) for squared lengths l2 [m²], finite at 0. With AVX-512,
    its estimate of 1/sqrt (``vrsqrt14pd``, 14 bits) refined by two Newton
    steps in double, to about 1e-15 relative: the single-precision square
    root and divide of :func:`.shared.inv_length` that numba's loops use there
    wait on the divider, and are a hundred times less exact (1e-13).
    Elsewhere a double square root and divide, as :func:`.shared.over_length`
    computes it on AMD's Zen cores (:data:`.shared.DIVIDE`). numba's loops
    take a single-precision estimate on other cores without AVX-512, good to
    1e-13; the general path (:mod:`.pull_lanes`) promises its pulls to 1e-14,
    so this code divides there. The springs' four lanes divide there too:
    given a single-precision estimate (the lengths rounded to single
    precision and back, the estimate refined in double) they ran slower
    than dividing on an Intel core (docs/performance.md, 'The springs four
    points at a time without AVX-512')."""
    b = v.builder
    tiny = v.constant(1e-30)
    l2c = b.select(b.fcmp_ordered("<", l2, tiny, flags=FAST), tiny, l2)
    if not RSQRT14:
        return b.fdiv(a, v.call("sqrt", [l2c]), flags=FAST)
    estimate = cgutils.get_or_insert_function(b.module, ir.FunctionType(v.vec, [v.vec, v.vec, ir.IntType(8)]),
                                              "llvm.x86.avx512.rsqrt14.pd.512")
    y = b.call(estimate, [l2c, ir.Constant(v.vec, None), ir.Constant(ir.IntType(8), 255)])
    half = v.mul(v.constant(0.5), l2c)
    for _ in range(2):
        y = v.mul(y, v.sub(v.constant(1.5), v.mul(v.mul(half, y), y)))
    return v.mul(a, y)


class _Pass:
    """One call's forces (and step): the arguments unpacked, the code emitted
    set by set."""

    def __init__(self, context, b, types_, values):
        P_t, rest_t, gaps_t, F_t, at_t, pad_t, ends_t, k_t, off_t = types_[:9]
        P_v, rest_v, gaps_v, F_v, at_v, pad_v, ends_v, k_v, off_v = values[:9]
        self.v = v = _Vector(context, b, LANES)
        self.b = b
        self.P, self.rest, self.F = (P_t, P_v), (rest_t, rest_v), (F_t, F_v)
        self.at = context.cast(b, at_v, at_t, types.intp)
        self.base = b.add(context.cast(b, pad_v, pad_t, types.intp), self.at)
        self.ends = [context.cast(b, e, ends_t.dtype, types.intp) for e in _ints(b, ends_t, ends_v, 2 * SETS)]
        self.offs = _ints(b, off_t, off_v, SETS)
        self.ks = [v.splat(k) for k in cgutils.unpack_tuple(b, k_v, SETS)]
        self.loaded = {}
        gaps = context.make_array(gaps_t)(context, b, gaps_v)
        eight = b.ashr(self.at, ir.Constant(v.intp, 3))  # the byte of gaps that holds the call's bits
        # where a call takes fewer than GAP_BITS points, its bits lie (at % GAP_BITS) up the byte
        self.gap_shift = (b.trunc(b.and_(self.at, ir.Constant(v.intp, GAP_BITS - 1)), ir.IntType(8))
                          if LANES < GAP_BITS else None)
        self.gap_at = lambda s: cgutils.get_item_pointer(context, b, gaps_t, gaps, [ir.Constant(v.intp, s), eight],
                                                         wraparound=False)

    def forces(self, s):
        """set s's forces at the call's points, stored and returned (x, y, z)"""
        v, b = self.v, self.b
        d = [v.sub(self.end(s, 1, c), self.end(s, 0, c)) for c in range(3)]
        l2 = v.add(v.add(v.mul(d[0], d[0]), v.mul(d[1], d[1])), v.mul(d[2], d[2]))
        f = v.sub(self.ks[s], _over_length(v, v.mul(self.ks[s], v.load(*self.rest, s, self.at)), l2))
        byte = b.load(self.gap_at(s))
        if LANES < GAP_BITS:
            byte = b.trunc(b.lshr(byte, self.gap_shift), ir.IntType(LANES))
        gaps = b.or_(byte, b.trunc(self.offs[s], ir.IntType(LANES)))
        # the lanes kept, not the gaps: a select of the product where kept, else
        # zero, is AVX-512's multiply with zero-masking, one instruction
        kept = b.bitcast(b.xor(gaps, ir.Constant(gaps.type, (1 << LANES) - 1)), v.bits)
        out = []
        for c in range(3):
            value = b.select(kept, v.mul(f, d[c]), ir.Constant(v.vec, None))
            b.store(value, v.at(*self.F, s, c, self.base), align=8)
            out.append(value)
        return out

    def end(self, s, which, c):
        """coordinate c of end ``which`` (0: start, 1: end) of set s's springs
        at the call's points, loaded once for every set that shares it"""
        key = (END_KEYS[s][which], c)
        if key not in self.loaded:
            at = self.b.add(self.at, self.ends[s + SETS * which])
            self.loaded[key] = self.v.load(*self.P, c, at)
        return self.loaded[key]

    def stored(self, s, c, back):
        """the forces of set s at the call's points less ``back`` (an intp), from the buffer"""
        return self.b.load(self.v.at(*self.F, s, c, self.b.sub(self.base, back)), align=8)

    def near(self, forces, s, c, shift):
        """the forces of set s ``shift`` points back: the call's own, shifted
        across from the lanes before it where ``shift`` > 0"""
        if shift == 0:
            return forces[c]
        before = self.stored(s, c, ir.Constant(self.v.intp, LANES))
        picks = ir.Constant(ir.VectorType(ir.IntType(32), LANES), [LANES + j - shift for j in range(LANES)])
        return self.b.shuffle_vector(before, forces[c], picks)


@njit(cache=True, inline="always")
def force_pad(F, n):
    """the slots ahead of point 0 in the force buffer ``F`` (6, 3, M) of
    :func:`.springs.force_buffer` for ``n`` points: its pad and its rows are
    whole cache lines, so that a call of the lanes stores its forces to
    vectors that each lie on one"""
    return F.shape[2] - (n + LINE - 1) // LINE * LINE


@intrinsic
def force_lanes(typingctx, P, rest, gaps, F, at, pad, ends, k_over_m, off):
    """The forces of the six sets' springs that start at points ``at:at +
    LANES`` (``at`` a multiple of LANES) into the force buffer ``F`` (6, 3, pad + N) at ``pad + at``: spring p of set s
    joins ``p + ends[s]`` to ``p + ends[6 + s]`` of the (3, N) planes P, rest
    length ``rest[s, p]`` [m], constant ``k_over_m[s]``. A lane is stored as
    0 where its bit is set in ``gaps`` (:attr:`.springs.GridSprings.gaps`)
    or in ``off[s]`` (255 where set s is switched off). Nothing is
    bounds-checked: the caller keeps every spring's ends inside P."""
    _check_forces(P, rest, gaps, F, k_over_m)
    sig = types.void(P, rest, gaps, F, at, pad, ends, k_over_m, off)

    def codegen(context, builder, signature, args):
        one = _Pass(context, builder, signature.args, args)
        for s in range(SETS):
            one.forces(s)
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def spring_step_lanes(typingctx, P, rest, gaps, F, at, pad, ends, k_over_m, off, L, free, motion):
    """:func:`force_lanes` and then the Verlet step of the same points of the
    (3, N) planes P (read only) and L (the last positions, overwritten by the new ones), as
    :func:`.springs.verlet_gather` takes it: ``a = g + sum_s F_s[q - ends[s]]
    - F_s[q - ends[6 + s]]``, ``x' = x + free (keep (x - x_last) + a dt²)``;
    ``motion``: gravity (3) [m/s²], keep, dt² [s²]. The forces the call
    just computed are taken as computed, and those at the offsets of
    :data:`NEAR` shifted across from the lanes before, read where they were
    stored whole: a read across the lanes just stored would wait for the
    stores to reach the cache. The buffer's pad must hold at least LANES
    slots (:func:`.springs.force_buffer`). Nothing is bounds-checked."""
    _check_forces(P, rest, gaps, F, k_over_m)
    if not (_is_array(L, 2) and _is_array(free, 1)):
        raise TypingError("spring_step_lanes takes C float64 (3, N) and (N,) arrays")
    _floats(motion, 5)
    sig = types.void(P, rest, gaps, F, at, pad, ends, k_over_m, off, L, free, motion)

    def codegen(context, builder, signature, args):
        b = builder
        one = _Pass(context, b, signature.args, args)
        v = one.v
        L_t, free_t, motion_t = signature.args[9:12]
        L_v, free_v, motion_v = args[9:12]
        gravity0, gravity1, gravity2, keep, dt2 = (v.splat(x) for x in cgutils.unpack_tuple(b, motion_v, 5))
        # the order LLVM gives numba's loop of verlet_gather: gravity and the
        # starting ends' forces in one sum, the ending ends' in another, each
        # set's terms added as soon as its forces are in (fewer live vectors)
        pulls, pushes = [gravity0, gravity1, gravity2], [None] * 3
        for s in range(SETS):
            forces = one.forces(s)
            back_a, back_b = NEAR[s]
            for c in range(3):
                fb = one.near(forces, s, c, back_b) if back_b is not None else one.stored(s, c, one.ends[SETS + s])
                pulls[c] = b.fadd(one.near(forces, s, c, back_a), pulls[c], flags=IN_ORDER)
                pushes[c] = fb if pushes[c] is None else b.fadd(pushes[c], fb, flags=IN_ORDER)
        fr = v.load(free_t, free_v, one.at)
        for c in range(3):
            a = b.fsub(pulls[c], pushes[c], flags=IN_ORDER)
            lp = v.at(L_t, L_v, c, one.at)
            xq = one.end(0, 0, c)  # set 0 starts at the point itself (checked by integrate_eights)
            # the multiply-adds LLVM makes of numba's loop, spelled out: left to
            # LLVM, this code's sum fused the other product
            velocity = b.fsub(xq, b.load(lp, align=8), flags=IN_ORDER)
            turn = v.call("fmuladd", [velocity, keep, b.fmul(a, dt2, flags=IN_ORDER)])
            b.store(v.call("fmuladd", [turn, fr, xq]), lp, align=8)
        return context.get_dummy_value()

    return sig, codegen


@njit(cache=True, inline="always")
def _off(k):
    """the zeroed lanes of a set whose constant is k: all where it is switched off"""
    return np.int64(255) if k == 0.0 else np.int64(0)


@njit(**KERNEL_OPTIONS)
def integrate_eights(P, L, free, knobs, springs, F, first, stop, moved):
    """:func:`.springs.integrate` LANES points at a time, from ``first`` for as
    long as LANES more points lie before ``stop`` and every spring of them
    has both ends inside the cloth. Returns the point where it stopped: the
    caller's loops take the rest. The points before ``moved`` get their
    forces and no step. Where ``first`` or ``moved - first`` is not a
    multiple of LANES, or the arrays are too short for a call's reads (a
    force buffer whose pad holds fewer than LANES slots, see
    :func:`.springs.force_buffer`), it does nothing and returns ``first``."""
    start, end, rest, gaps = springs.start, springs.end, springs.rest, springs.gaps
    k, g = knobs.k_over_m, knobs.gravity
    n = P.shape[1]
    pad = force_pad(F, n)
    reach = 0
    for s in range(SETS):
        reach = max(reach, start[s], end[s])
    last = min(stop, n - reach)
    if first < 0 or first % LANES != 0 or (moved - first) % LANES != 0 or pad < max(reach + 1, LANES) \
            or rest.shape[1] < n or free.shape[0] < n or L.shape[1] < n or gaps.shape[1] * GAP_BITS < n:
        return first  # not a range or buffer the calls can read inside: the loops take it all
    ends = (start[0], start[1], start[2], start[3], start[4], start[5],
            end[0], end[1], end[2], end[3], end[4], end[5])
    for s in range(SETS):
        (r0, c0), (r1, c1) = END_KEYS[s]
        if start[s] != r0 * springs.cols + c0 or end[s] != r1 * springs.cols + c1:
            return first  # not a grid's stencil: the calls load one end for every set that shares it
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

