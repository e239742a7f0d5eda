"""A sphere's pass, LANES points at a time (see :mod:`.lanes`).

Each call carries its LANES last positions along with the sphere's motion
(a still sphere's stay as they are) and tests them (inside the sphere and
free, or moved too far for the radial rule); only where one of them is
inside does it take the square root, the division and the friction rule,
and write them back. Of the 2,500 points of the 50×50 cloth draped over
the sphere of ``sphere.json``, 359 are inside in a substep: 72% of the runs
of eight hold none, and 78% of the runs of four. Four lanes (one
256-bit vector) skip more than eight, and ran faster with AVX-512 as
without (docs/performance.md, 'Four lanes').

The arithmetic is that of :func:`.sphere._carried_point`, in the same order:
the positions are the same to the bit.
"""

from __future__ import annotations

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
    free_ = lanes.nonzero(lanes.load(free_t, free_v, at))
    cx, cy, cz, r, r2, keep, far2 = lanes.numbers(sphere_t, sphere_v)
    centre = (cx, cy, cz)
    # a still sphere's last positions as they are: the course code's sums
    m = lanes.affine(lanes.numbers(signature.args[5], args[5]), last) if len(args) > 5 else last
    d = [lanes.sub(xyz[k], centre[k]) for k in range(3)]
    d2 = lanes.add(lanes.add(lanes.mul(d[0], d[0]), lanes.mul(d[1], d[1])), lanes.mul(d[2], d[2]))
    u = [lanes.sub(xyz[k], m[k]) for k in range(3)]
    far = lanes.greater(lanes.add(lanes.add(lanes.mul(u[0], u[0]), lanes.mul(u[1], u[1])), lanes.mul(u[2], u[2])),
                        far2)
    zero = lanes.splat(context.get_constant(types.float64, 0.0))
    hit = b.and_(b.and_(b.and_(lanes.less(d2, r2), lanes.greater(d2, zero)), free_), b.not_(far))
    with b.if_then(lanes.any(hit), likely=False):
        one = lanes.splat(context.get_constant(types.float64, 1.0))
        f = lanes.div(r, lanes.sqrt(lanes.pick(hit, d2, one)))
        for k in range(3):
            n = lanes.add(m[k], lanes.mul(keep, lanes.sub(lanes.add(centre[k], lanes.mul(d[k], f)), m[k])))
            lanes.store(lanes.pick(hit, n, xyz[k]), row_t, plane_vals[k], at)
    return lanes.count(far)


def _check(planes, lasts, free, sphere, carry=None):
    """A typing error unless the arguments are what the lanes read and write."""
    arrays = planes_of(planes) + planes_of(lasts) + (free,)
    if len(arrays) != 7:
        raise TypingError("the sphere's lanes take three planes and three last positions")
    check_rows("the sphere's lanes", arrays)
    check_numbers("the sphere's lanes", ((sphere, _SPHERE),) + (((carry, MAP),) if carry is not None else ()))


@intrinsic
def still_lanes(typingctx, planes, lasts, free, at, sphere):
    """:func:`carried_lanes` for a still sphere: the last positions as they are, so
    the sums are the course code's (:func:`.sphere.collide_spheres`)."""
    _check(planes, lasts, free, sphere)
    return types.int64(planes, lasts, free, at, sphere), _codegen


@intrinsic
def carried_lanes(typingctx, planes, lasts, free, at, sphere, carry):
    """The moving sphere's rule (:func:`.sphere._carried_point`) for points
    ``at:at + LANES`` of ``planes`` (x, y, z; m), their last positions
    ``lasts`` (three planes) carried by ``carry`` (12 numbers,
    :func:`.motion_rows.carry_of`), ``free`` their free weights, against
    ``sphere`` (cx, cy, cz, r, r^2, 1 - friction, far2): the points written
    where one of them is inside, else left as they are. Returns how many
    moved farther than far2 allows. Nothing is bounds-checked: the caller
    keeps ``at + LANES`` within every array."""
    _check(planes, lasts, free, sphere, carry)
    return types.int64(planes, lasts, free, at, sphere, carry), _codegen
