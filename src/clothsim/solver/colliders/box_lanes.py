"""The box's vector pass written eight points at a time, with a branch per eight.

On a cloth lying on a box, most points are nowhere near the box's inside:
of the 2,500 points of the 50×50 cloth draped over a box, 757 end inside it
in a substep, and 59% of the runs of eight consecutive points hold none.
Such a run needs no rule: it is not written, and its marks are cleared. A
loop that numba vectorises cannot skip a vector's worth of points (its body
is branch-free, and a loop of eight is left scalar or pays for tests of
overlapping arrays every time), so the pass's body is written here as LLVM
vector code on eight doubles, with the test first and the rule behind a
branch.

The arithmetic is that of :func:`.box._axis` and :func:`.box._write_or_mark`,
in the same order and with the same fast-math flags numba gives it: the
positions are those of the loop numba vectorised before, to the bit, on the
standard box scenes; the few points past the last eight, placed one by one in
numba's code, may round differently in a turned box's turns (fast-math lets
LLVM fuse their sums otherwise in scalar code). LLVM lowers the eight-double
vectors for any x86 target: one 512-bit register with AVX-512, two 256-bit
ones without.
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.core.errors import TypingError
from numba.extending import intrinsic

from ..simd import _splat, _vector_at

LANES = 8
"""points a call places: one vector of eight doubles"""

FAST = ("fast",)
"""the flags numba's ``fastmath=True`` puts on every floating-point operation"""

_BOX = 14
"""numbers in a box's tuple, see :func:`aligned_lanes`"""

_MAP = 12
"""numbers in an affine map, see :func:`.motion_rows.carry_of`"""


def _check(planes, refs, free, marked, box, maps=()):
    """A typing error unless the arguments are what the lanes read and write."""
    row = types.Array(types.float64, 1, "C")
    arrays = tuple(planes) + tuple(refs) + (free,) if (isinstance(planes, types.UniTuple) and
                                                         isinstance(refs, types.UniTuple)) else ()
    if len(arrays) != 7 or not all(isinstance(a, types.Array) and a.dtype == row.dtype and a.ndim == 1
                                   and a.layout == "C" for a in arrays):
        raise TypingError("the box's lanes take three planes, three references and the free "
                          "weights as contiguous float64 (N,) arrays")
    if not (isinstance(marked, types.Array) and marked.ndim == 1 and marked.layout == "C"
            and marked.dtype == types.boolean):
        raise TypingError("the box's lanes take a contiguous bool (N,) array of marks")
    sizes = ((box, _BOX),) + tuple((m, _MAP) for m in maps)
    if not all(isinstance(t, types.UniTuple) and t.dtype == types.float64 and len(t) == k for t, k in sizes):
        raise TypingError("the box's lanes take a box of 14 floats and maps of 12")


class _Lanes:
    """The vector code of one call: eight lanes of doubles."""

    def __init__(self, context, builder):
        self.context, self.builder = context, builder
        self.vec = ir.VectorType(ir.DoubleType(), LANES)
        self.bits = ir.VectorType(ir.IntType(1), LANES)
        module = builder.module
        self._fabs = cgutils.get_or_insert_function(module, ir.FunctionType(self.vec, [self.vec]),
                                                    "llvm.fabs.v8f64")

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

    def affine(self, m, point):
        """the map m (12 numbers, :func:`.motion_rows.carry_of`) of a point, in the
        order :func:`.motion_rows.carry_point` sums it"""
        x, y, z = point
        return tuple(self.add(self.add(self.add(self.mul(m[3 * k], x), self.mul(m[3 * k + 1], y)),
                                       self.mul(m[3 * k + 2], z)), m[9 + k]) for k in range(3))


def _place_lanes(lanes, ends, starts, box, back, store):
    """The body of a call: ``ends`` and ``starts`` (three vectors each) are the
    points and their references in the frame where the box is ``box``
    (:func:`aligned_lanes`'s numbers, each in every lane); ``back`` maps a
    placed point to the world (None: it is there already); ``store(planes,
    marks)`` writes three vectors of positions (or None: leave them) and the
    marks (an i1 vector). Returns the count of marks (i64)."""
    b = lanes.builder
    c, h, reach = box[0:3], box[3:6], box[6:12]
    keep, thinnest2 = box[12], box[13]
    ends, free_, old = ends[:3], ends[3], ends[4:]
    inside = free_
    for k in range(3):
        inside = b.and_(lanes.less(lanes.abs(lanes.sub(ends[k], c[k])), h[k]), inside)
    moves = [lanes.sub(ends[k], starts[k]) for k in range(3)]
    d2 = lanes.add(lanes.add(lanes.mul(moves[0], moves[0]), lanes.mul(moves[1], moves[1])),
                   lanes.mul(moves[2], moves[2]))
    far = b.and_(lanes.at_least(d2, thinnest2), free_)
    act = b.bitcast(b.or_(inside, far), ir.IntType(LANES))
    count = cgutils.alloca_once_value(b, ir.Constant(ir.IntType(64), 0))
    with b.if_else(b.icmp_unsigned("!=", act, ir.Constant(act.type, 0)), likely=False) as (some, none):
        with some:
            outs, new = [], []
            for k in range(3):
                a0 = starts[k]
                out = lanes.at_least(lanes.abs(lanes.sub(a0, c[k])), h[k])
                face = lanes.sub(lanes.clamp(a0, reach[2 * k], reach[2 * k + 1]), a0)
                new.append(lanes.add(a0, lanes.mul(keep, lanes.pick(out, face, moves[k]))))
                outs.append(out)
            u, v, w = outs
            one = b.and_(b.xor(b.xor(u, v), w), b.not_(b.and_(b.and_(u, v), w)))
            simple = b.and_(b.and_(inside, one), b.not_(far))
            mark = b.or_(b.and_(inside, b.not_(one)), far)
            placed = back(new) if back is not None else new
            store([lanes.pick(simple, placed[k], old[k]) for k in range(3)], mark)
            popcount = cgutils.get_or_insert_function(b.module, ir.FunctionType(ir.IntType(LANES),
                                                                                [ir.IntType(LANES)]),
                                                      "llvm.ctpop.i8")
            marks = b.call(popcount, [b.bitcast(mark, ir.IntType(LANES))])
            b.store(b.zext(marks, ir.IntType(64)), count)
        with none:
            store(None, ir.Constant(lanes.bits, None))
    return b.load(count)


def _codegen(turned):
    def codegen(context, builder, signature, args):
        planes_t, refs_t, free_t, marked_t, at_t, box_t = signature.args[:6]
        planes_v, refs_v, free_v, marked_v, at_v, box_v = args[:6]
        lanes = _Lanes(context, builder)
        at = context.cast(builder, at_v, at_t, types.intp)
        plane_vals = cgutils.unpack_tuple(builder, planes_v, 3)
        ref_vals = cgutils.unpack_tuple(builder, refs_v, 3)
        row_t = planes_t.dtype
        xyz = [lanes.load(row_t, p, at) for p in plane_vals]
        refs = [lanes.load(row_t, r, at) for r in ref_vals]
        free_ = builder.fcmp_unordered("!=", lanes.load(free_t, free_v, at), ir.Constant(lanes.vec, None),
                                       flags=FAST)
        box = lanes.numbers(box_t, box_v)
        back = None
        if turned:
            ref_m, end_m, back_m = (lanes.numbers(signature.args[6 + k], args[6 + k]) for k in range(3))
            starts = lanes.affine(ref_m, refs)
            ends = lanes.affine(end_m, xyz)

            def back(new):
                return lanes.affine(back_m, new)
        else:
            starts, ends = refs, xyz

        def store(values, mark):
            if values is not None:
                for p, v in zip(plane_vals, values):
                    lanes.store(v, row_t, p, at)
            bytes_ = ir.VectorType(ir.IntType(8), LANES)
            ptr = _vector_at(context, builder, marked_t, marked_v, [at], bytes_)
            builder.store(builder.zext(mark, bytes_), ptr, align=1)

        return _place_lanes(lanes, tuple(ends) + (free_,) + tuple(xyz), tuple(starts), box, back, store)

    return codegen


@intrinsic
def aligned_lanes(typingctx, planes, refs, free, marked, at, box):
    """The vector pass of a still box whose axes are the world's (as
    :func:`.box._aligned_loop`) for points ``at:at + LANES`` of ``planes`` (x, y,
    z; m) from their references ``refs`` (three planes), ``free`` the points'
    free weights: the common case written, the rest marked in ``marked``, or,
    where none of the eight ends inside the box or moved farther than its
    thinnest side, only the marks cleared. ``box``: centre (3), half sizes (3),
    the slab widened by the margin along each axis (lo, hi; 6), 1 - friction,
    the square of the thinnest side. Returns how many it marked. Nothing is
    bounds-checked: the caller keeps ``at + LANES`` within every array."""
    _check(planes, refs, free, marked, box)
    return types.int64(planes, refs, free, marked, at, box), _codegen(False)


@intrinsic
def turned_lanes(typingctx, planes, refs, free, marked, at, box, ref, end, back):
    """:func:`aligned_lanes` for any box (as :func:`.box._turned_loop`): ``box`` in the
    box's own frame (its centre at 0), ``ref``, ``end`` and ``back`` the maps
    of :func:`.box._frame_maps`."""
    _check(planes, refs, free, marked, box, (ref, end, back))
    return types.int64(planes, refs, free, marked, at, box, ref, end, back), _codegen(True)
