"""Whole stores of a select: :func:`unchanged`, an identity that LLVM cannot see through.

A collider's loop writes back every point: ``x[p] = new if hit else old``,
with ``old`` read from ``x[p]`` in the same pass. LLVM sees that where
``hit`` is false the store writes back what it read, drops that half, and
the vectorised loop then writes ``new`` through a masked store
(``vmaskmovpd``) under the mask of ``hit``. On AMD cores before Zen 4 such a
store is slow, and slower still when the mask is mixed (some points hit,
some not): the loop over a cloth resting on a plane took 5.3-6.1 µs instead
of 3.2-3.7 on a Zen 3 core (docs/performance.md, "Masked stores").

Written ``x[p] = new if hit else unchanged(old)``, the stored value is no
longer, as far as LLVM can tell, the one it read: the loop blends the two
and stores the whole vector, as it does wherever its first store is not
the only one (a store to another coordinate plane in between may alias).
:func:`unchanged` is LLVM's ``freeze``, which returns its operand as it is
(it only fixes a value that is undefined, which a number read from memory
never is): the same bits, with no instruction emitted for it.
:func:`write_point` states that write-back once, for the three coordinate
planes of a point.
"""

from __future__ import annotations

from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic


class _Freeze(ir.instructions.Instruction):
    """LLVM's ``freeze`` (llvmlite's builder has no method for it)"""


@intrinsic
def unchanged(typingctx, value):
    """``value`` (a float) as it is, through LLVM's ``freeze``: see the module."""
    if not isinstance(value, types.Float):
        return None

    def codegen(context, builder, signature, args):
        frozen = _Freeze(builder.block, args[0].type, "freeze", [args[0]])
        builder._insert(frozen)
        return frozen

    return value(value), codegen


@njit(cache=True, inline="always")
def write_point(planes, p, hit, new, old):
    """Point ``p`` of the coordinate planes ``planes`` (x, y, z; m) set to ``new``
    (three floats, m) where ``hit``, else to ``old`` (the three read from it in
    this pass), kept as it is: whole stores of a blend, see the module."""
    x, y, z = planes
    x[p] = new[0] if hit else unchanged(old[0])
    y[p] = new[1] if hit else unchanged(old[1])
    z[p] = new[2] if hit else unchanged(old[2])
