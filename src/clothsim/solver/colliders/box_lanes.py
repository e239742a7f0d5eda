"""The box's vector pass, a few points at a time (see :mod:`.lanes`).

Of the 2,500 points of the 50×50 cloth lying on a box, 757 end inside it in
a substep: 59% of the runs of eight consecutive points hold none, and
64% of the runs of four. Each call tests its points first
(ending inside, or moved farther than the box's thinnest side); where none
is, it only clears their marks, and writes nothing. A box whose axes are the
world's and that stands still or only slides takes four points a call
(ALIGNED_LANES); a turned box whose references are not carried (a still
one, or any box's settle) or only slide eight with AVX-512 and four without
(STILL_LANES); any other moving box eight (TURNED_LANES): each ran faster so
(docs/performance.md, 'Four lanes' and 'A turned box's runs').

The arithmetic is that of :func:`.box._axis` and :func:`.box._write_or_mark`,
in the same order: the positions are those of the loop numba vectorised
before, to the bit, on the standard box scenes; the few points past the last
full call, placed one by one in numba's code, may round differently in a turned
box's turns (fast-math lets LLVM fuse their sums otherwise in scalar code).
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.core.errors import TypingError
from numba.extending import intrinsic

from ..simd import _vector_at, has_avx512f
from .lanes import MAP, YAW_MAP, Lanes, check_numbers, check_rows, planes_of

__all__ = ["ALIGNED_LANES", "STILL_LANES", "TURNED_LANES", "aligned_lanes", "sliding_lanes", "sliding_turned_lanes",
           "still_lanes", "turned_lanes"]

ALIGNED_LANES = 4
"""points a call of :func:`aligned_lanes` or :func:`sliding_lanes` places: one
256-bit vector of doubles"""

TURNED_LANES = 8
"""points a call of :func:`turned_lanes` places: its turns into and out of the
box's frame hold 36 numbers, and on four lanes it was no faster"""

STILL_LANES = 8 if has_avx512f() else 4
"""points a call of :func:`still_lanes` places"""

_BOX = 14
"""numbers in a box's tuple, see :func:`aligned_lanes`"""


def _check(planes, refs, free, marked, box, maps=()):
    """A typing error unless the arguments are what the lanes read and write."""
    arrays = planes_of(planes) + planes_of(refs) + (free,)
    if len(arrays) != 7:
        raise TypingError("the box's lanes take three planes and three references")
    check_rows("the box's lanes", arrays)
    if not (isinstance(marked, types.Array) and marked.ndim == 1 and marked.layout == "C"
            and marked.dtype == types.boolean):
        raise TypingError("the box's lanes take a contiguous bool (N,) array of marks")
    size = len(maps[0]) if maps and isinstance(maps[0], types.UniTuple) and len(maps[0]) == YAW_MAP else MAP
    check_numbers("the box's lanes", ((box, _BOX),) + tuple((m, size) for m in maps))


def _place_lanes(lanes, ends, starts, load_free, old, box, back, store, moved=None):
    """The body of a call: ``ends`` and ``starts`` (three vectors each) are the
    points and their references in the frame where the box is ``box``
    (:func:`aligned_lanes`'s numbers, each in every lane), ``load_free()``
    reads whether each point is free (an i1 vector; read only behind the
    test, which a pinned point seldom passes), ``old`` the points as read (three
    vectors, the world's); ``back`` maps a placed point to the world (None: it
    is there already; where there is one, ``box`` is in the box's own frame,
    and its centre, 0, is not read); ``store(planes, marks)`` writes three vectors of
    positions (or None: leave them) and the marks (an i1 vector). ``moved``:
    where the references stay where they are, |point - reference|² in the
    world's frame (a turn keeps it), which the far test then takes, and
    ``starts`` a function that makes the references' vectors, called only
    behind the test. Returns the count of marks (i64)."""
    b = lanes.builder
    c, h, reach = box[0:3], box[3:6], box[6:12]
    keep, thinnest2 = box[12], box[13]

    def off_centre(a, k):
        """a - c[k]; a itself where the box is in its own frame (``back``), with
        its centre at 0, which LLVM cannot know: x - 0.0 is x, bit for bit"""
        return a if back is not None else lanes.sub(a, c[k])

    ends_in = [lanes.less(lanes.abs(off_centre(ends[k], k)), h[k]) for k in range(3)]
    inside = b.and_(b.and_(ends_in[0], ends_in[1]), ends_in[2])
    if moved is None:
        moves = [lanes.sub(ends[k], starts[k]) for k in range(3)]
        moved = lanes.squared(moves)
    far = lanes.at_least(moved, thinnest2)
    count = cgutils.alloca_once_value(b, ir.Constant(ir.IntType(64), 0))
    with b.if_else(lanes.any(b.or_(inside, far)), likely=False) as (some, none):
        with some:
            if callable(starts):
                starts = starts()
                moves = [lanes.sub(ends[k], starts[k]) for k in range(3)]
            free_ = load_free()
            inside = b.and_(inside, free_)
            far = b.and_(far, free_)
            outs, new = [], []
            for k in range(3):
                a0 = starts[k]
                out = lanes.at_least(lanes.abs(off_centre(a0, k)), h[k])
                face = lanes.sub(lanes.clamp(a0, reach[2 * k], reach[2 * k + 1]), a0)
                new.append(lanes.add(a0, lanes.mul(keep, lanes.pick(out, face, moves[k]))))
                outs.append(out)
            u, v, w = outs
            one = b.and_(b.xor(b.xor(u, v), w), b.not_(b.and_(b.and_(u, v), w)))
            simple = b.and_(b.and_(inside, one), b.not_(far))
            mark = b.or_(b.and_(inside, b.not_(one)), far)
            placed = back(new) if back is not None else new
            store([lanes.pick(simple, placed[k], old[k]) for k in range(3)], mark)
            b.store(lanes.count(mark), count)
        with none:
            store(None, ir.Constant(lanes.bits, None))
    return b.load(count)


def _codegen(turned, still=False, sliding=False):
    width = (STILL_LANES if still else TURNED_LANES) if turned else ALIGNED_LANES

    def codegen(context, builder, signature, args):
        planes_t, refs_t, free_t, marked_t, at_t, box_t = signature.args[:6]
        planes_v, refs_v, free_v, marked_v, at_v, box_v = args[:6]
        lanes = Lanes(context, builder, width)
        at = context.cast(builder, at_v, at_t, types.intp)
        plane_vals = cgutils.unpack_tuple(builder, planes_v, 3)
        ref_vals = cgutils.unpack_tuple(builder, refs_v, 3)
        row_t = planes_t.dtype
        xyz = [lanes.load(row_t, p, at) for p in plane_vals]
        refs = [lanes.load(row_t, r, at) for r in ref_vals]

        def load_free():
            return lanes.nonzero(lanes.load(free_t, free_v, at))

        box = lanes.numbers(box_t, box_v)
        back, moved = None, None

        def carried():
            """the references, carried by a sliding box's slide (its last argument)"""
            if not sliding:
                return refs
            shift = lanes.numbers(signature.args[-1], args[-1])
            return [lanes.add(refs[k], shift[k]) for k in range(3)]

        if turned:
            ref_m, end_m, back_m = (lanes.numbers(signature.args[6 + k], args[6 + k]) for k in range(3))
            ends = lanes.affine(end_m, xyz)
            if still:
                # the far test on the move in the world's frame, and the references
                # turned only where the rule runs (see still_lanes)
                starts_world = carried()
                moved = lanes.squared([lanes.sub(xyz[k], starts_world[k]) for k in range(3)])

                def starts():
                    return lanes.affine(ref_m, refs)
            else:
                starts = lanes.affine(ref_m, refs)

            def back(new):
                return lanes.affine(back_m, new)
        else:
            starts, ends = carried(), xyz

        def store(values, mark):
            if values is not None:
                for p, v in zip(plane_vals, values):
                    lanes.store(v, row_t, p, at)
            bytes_ = ir.VectorType(ir.IntType(8), width)
            ptr = _vector_at(context, builder, marked_t, marked_v, [at], bytes_)
            builder.store(builder.zext(mark, bytes_), ptr, align=1)

        return _place_lanes(lanes, ends, starts, load_free, xyz, box, back, store, moved)

    return codegen


@intrinsic
def aligned_lanes(typingctx, planes, refs, free, marked, at, box):
    """The vector pass of a still box whose axes are the world's (as
    :func:`.box._aligned_loop`) for points ``at:at + ALIGNED_LANES`` of ``planes``
    (x, y, z; m) from their references ``refs`` (three planes), ``free`` the
    points' free weights: the common case written, the rest marked in
    ``marked``, or, where none of them ends inside the box or moved farther than its
    thinnest side, only the marks cleared. ``box``: centre (3), half sizes (3),
    the slab widened by the margin along each axis (lo, hi; 6), 1 - friction,
    the square of the thinnest side. Returns how many it marked. Nothing is
    bounds-checked: the caller keeps ``at + ALIGNED_LANES`` within every array."""
    _check(planes, refs, free, marked, box)
    return types.int64(planes, refs, free, marked, at, box), _codegen(False)


@intrinsic
def sliding_lanes(typingctx, planes, refs, free, marked, at, box, shift):
    """:func:`aligned_lanes` for a box whose axes are the world's and that only
    slides over the substep: its references carried by ``shift`` (3 floats,
    [m]), the box's move."""
    _check(planes, refs, free, marked, box)
    check_numbers("the box's lanes", ((shift, 3),))
    return types.int64(planes, refs, free, marked, at, box, shift), _codegen(False, sliding=True)


@intrinsic
def turned_lanes(typingctx, planes, refs, free, marked, at, box, ref, end, back):
    """:func:`aligned_lanes` for any box (as :func:`.box._turned_loop`): ``box`` in the
    box's own frame (its centre at 0), ``ref``, ``end`` and ``back`` the maps
    of :func:`.box._frame_maps`, for points ``at:at + TURNED_LANES``."""
    _check(planes, refs, free, marked, box, (ref, end, back))
    return types.int64(planes, refs, free, marked, at, box, ref, end, back), _codegen(True)


@intrinsic
def still_lanes(typingctx, planes, refs, free, marked, at, box, ref, end, back):
    """:func:`turned_lanes` where the references stay where they are (a still box,
    or the settle's references, of the substep's end; ``ref`` then turns them
    as ``end`` turns the points). A turn keeps lengths, so the far test takes
    the move in the world's frame, as the aligned box's does, and the
    references are turned (twelve multiply-adds a point) only for the calls
    where the rule runs."""
    _check(planes, refs, free, marked, box, (ref, end, back))
    return types.int64(planes, refs, free, marked, at, box, ref, end, back), _codegen(True, still=True)


@intrinsic
def sliding_turned_lanes(typingctx, planes, refs, free, marked, at, box, ref, end, back, shift):
    """:func:`still_lanes` for a turned box that only slides, by ``shift`` (3
    floats [m]: its carry's turn is the identity, and ``ref`` carries the
    references by the slide and turns them): the far test takes the move from
    the references so carried, in the world's frame."""
    _check(planes, refs, free, marked, box, (ref, end, back))
    check_numbers("the box's lanes", ((shift, 3),))
    return types.int64(planes, refs, free, marked, at, box, ref, end, back, shift), _codegen(True, still=True,
                                                                                             sliding=True)
