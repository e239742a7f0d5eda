"""A sphere's pass, LANES points at a time (see :mod:`.lanes`).

Each call tests its LANES points (inside the sphere, or moved too far for
the radial rule from their last positions carried along with the sphere's
motion; a still sphere's stay as they are, and a moving one's are carried
only where :func:`carried_lanes`'s screen cannot vouch for the move); only
where one of them is inside and free does it take the square root, the
division and the friction rule, and write them back. Of the 2,500 points of the 50×50 cloth draped over
the sphere of ``sphere.json``, 359 are inside in a substep: 72% of the runs
of eight hold none, and 78% of the runs of four. Four lanes (one
256-bit vector) skip more than eight, and ran faster with AVX-512 as
without (docs/performance.md, 'Four lanes').

The arithmetic is that of :func:`.sphere._carried_point`, in the same order:
the positions are the same to the bit.
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.core.errors import TypingError
from numba.extending import intrinsic

from .lanes import MAP, Lanes, check_numbers, check_rows, planes_of

__all__ = ["LANES", "carried_lanes", "still_lanes"]

LANES = 4
"""points a call places: four doubles, one 256-bit vector"""

_SPHERE = 7
"""numbers in a sphere's tuple, see :func:`carried_lanes`"""


def _rule(lanes, context, xyz, m, d, d2, near, load_free, far2, sphere_numbers, store):
    """The rule behind the test: ``far`` (moved farther than far2 allows from the
    carried last positions m), and where ``near`` (inside), free
    (``load_free()``, read only where some point is inside) and not far, the
    radial rule with friction, written through ``store``. Returns the count
    of far lanes (i64)."""
    b = lanes.builder
    cx, cy, cz, r, r2, keep, _ = sphere_numbers
    centre = (cx, cy, cz)
    u = [lanes.sub(xyz[k], m[k]) for k in range(3)]
    far = lanes.greater(lanes.squared(u), far2)
    inside = b.and_(near, b.not_(far))
    with b.if_then(lanes.any(inside), likely=False):
        hit = b.and_(inside, load_free())
        one = lanes.splat(context.get_constant(types.float64, 1.0))
        f = lanes.div(r, lanes.sqrt(lanes.pick(hit, d2, one)))
        for k in range(3):
            n = lanes.add(m[k], lanes.mul(keep, lanes.sub(lanes.add(centre[k], lanes.mul(d[k], f)), m[k])))
            store(k, lanes.pick(hit, n, xyz[k]))
    return lanes.count(far)


def _codegen(context, builder, signature, args):
    planes_t, lasts_t, free_t, at_t, sphere_t = signature.args[:5]
    planes_v, lasts_v, free_v, at_v, sphere_v = args[:5]
    lanes = Lanes(context, builder, LANES)
    b = builder
    at = context.cast(b, at_v, at_t, types.intp)
    row_t = planes_t.dtype
    plane_vals = cgutils.unpack_tuple(b, planes_v, 3)
    xyz = [lanes.load(row_t, p, at) for p in plane_vals]
    last = [lanes.load(row_t, q, at) for q in cgutils.unpack_tuple(b, lasts_v, 3)]

    def load_free():
        return lanes.nonzero(lanes.load(free_t, free_v, at))

    numbers = lanes.numbers(sphere_t, sphere_v)
    cx, cy, cz, r, r2, keep, far2 = numbers
    centre = (cx, cy, cz)

    def store(k, value):
        lanes.store(value, row_t, plane_vals[k], at)

    d = [lanes.sub(xyz[k], centre[k]) for k in range(3)]
    d2 = lanes.squared(d)
    zero = lanes.splat(context.get_constant(types.float64, 0.0))
    near = b.and_(lanes.less(d2, r2), lanes.greater(d2, zero))
    if len(args) == 5:
        # a still sphere's last positions as they are: the course code's sums
        return _rule(lanes, context, xyz, last, d, d2, near, load_free, far2, numbers, store)
    # a moving sphere: its carry is made only where a point is inside or may have
    # moved too far from its carried last position (see carried_lanes)
    carry = lanes.numbers(signature.args[5], args[5])
    reach2, move2 = lanes.numbers(signature.args[6], args[6])
    u0 = [lanes.sub(xyz[k], last[k]) for k in range(3)]
    maybe = b.or_(lanes.greater(d2, reach2), lanes.greater(lanes.squared(u0), move2))
    count = cgutils.alloca_once_value(b, ir.Constant(ir.IntType(64), 0))
    with b.if_then(lanes.any(b.or_(near, maybe)), likely=False):
        b.store(_rule(lanes, context, xyz, lanes.affine(carry, last), d, d2, near, load_free, far2, numbers, store),
                count)
    return b.load(count)


def _check(planes, lasts, free, sphere, carry=None, screen=None):
    """A typing error unless the arguments are what the lanes read and write."""
    arrays = planes_of(planes) + planes_of(lasts) + (free,)
    if len(arrays) != 7:
        raise TypingError("the sphere's lanes take three planes and three last positions")
    check_rows("the sphere's lanes", arrays)
    moving = ((carry, MAP), (screen, 2)) if carry is not None else ()
    check_numbers("the sphere's lanes", ((sphere, _SPHERE),) + moving)


@intrinsic
def still_lanes(typingctx, planes, lasts, free, at, sphere):
    """:func:`carried_lanes` for a still sphere: the last positions as they are, so
    the sums are the course code's (:func:`.sphere.collide_spheres`)."""
    _check(planes, lasts, free, sphere)
    return types.int64(planes, lasts, free, at, sphere), _codegen


@intrinsic
def carried_lanes(typingctx, planes, lasts, free, at, sphere, carry, screen):
    """The moving sphere's rule (:func:`.sphere._carried_point`) for points
    ``at:at + LANES`` of ``planes`` (x, y, z; m), their last positions
    ``lasts`` (three planes) carried by ``carry`` (12 numbers,
    :func:`.motion_rows.carry_of`), ``free`` their free weights, against
    ``sphere`` (cx, cy, cz, r, r^2, 1 - friction, far2): the points written
    where one of them is inside, else left as they are. Returns how many
    moved farther than far2 allows. Nothing is bounds-checked: the caller
    keeps ``at + LANES`` within every array.

    The carry (twelve multiply-adds a point) is made only for the points of
    a call where one is inside, or may have moved too far: ``screen`` (reach2,
    move2) of :func:`.sphere.carry_screen` are bounds such that a point no
    farther than sqrt(reach2) from the centre that moved no more than
    sqrt(move2) from its last position as it stands is within sqrt(far2) of
    its carried one. Elsewhere no point is written and none counted, as the
    rule would have it: the positions are the same to the bit."""
    _check(planes, lasts, free, sphere, carry, screen)
    return types.int64(planes, lasts, free, at, sphere, carry, screen), _codegen
