"""A list build's slack labels eight pairs at a time (see :func:`.slack.label_pairs`).

Each pair's ends are loaded by index from anywhere in the cloth; numba's
loop over the pairs stays scalar, eight loads and a bucket's arithmetic a
pair. Here LLVM vector code takes eight pairs: their ends' rows of four from
a copy of the positions (:func:`..mesh_pulls.to_rows`), the squared
distances summed on the rows (:meth:`..pull_lanes._Rows.squared_lengths`),
and the eight buckets at once. Every operation is rounded as the scalar
loop's (no fast-math), so the labels are the same.
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.core.errors import TypingError
from numba.extending import intrinsic

from ..pull_lanes import I32, LANES, _plane, _Rows
from ..simd import _vector_at


@intrinsic
def slack_lanes(typingctx, R, a, b, at, reach2, scale, last, labels):
    """The slack labels of the pairs ``at:at + LANES`` joining points ``a`` to
    ``b`` (int32 (K,)) of the rows R (N, 4) [m], whose fourth column is 0,
    into ``labels[at:]`` (int8 (K,)): 0 where the squared distance ``d2``
    is under ``reach2`` [m²], else ``min(1 + (d2 - reach2) scale, last)``
    truncated, as :func:`.slack.label_pairs` writes them. Nothing is
    bounds-checked: the caller keeps ``at + LANES`` inside the pairs and
    their ends inside R."""
    if not (_plane(R, 2) and _plane(a, 1, types.int32) and _plane(b, 1, types.int32)
            and _plane(labels, 1, types.int8)):
        raise TypingError("slack_lanes takes C float64 (N, 4), int32 (K,), int32 (K,), int8 (K,) arrays")
    sig = types.void(R, a, b, at, reach2, scale, last, labels)

    def codegen(context, builder, signature, args):
        R_t, a_t, b_t, at_t, reach_t, scale_t, last_t, labels_t = signature.args
        R_v, a_v, b_v, at_v, reach_v, scale_v, last_v, labels_v = args
        at = context.cast(builder, at_v, at_t, types.intp)
        v = _Rows(context, builder, ir.Constant(ir.VectorType(ir.IntType(1), LANES), [1] * LANES))
        d2 = v.squared_lengths((R_t, R_v), (a_t, a_v), (b_t, b_v), at, flags=())
        reach2, scale, last = (v.splat(context.cast(builder, x, t, types.float64))
                               for x, t in ((reach_v, reach_t), (scale_v, scale_t), (last_v, last_t)))
        steps = builder.fadd(v.constant(1.0), builder.fmul(builder.fsub(d2, reach2), scale))
        steps = builder.select(builder.fcmp_ordered("<", last, steps), last, steps)
        steps = builder.select(builder.fcmp_ordered("<", d2, reach2), v.constant(0.0), steps)
        bytes_ = ir.VectorType(ir.IntType(8), LANES)
        out = builder.trunc(builder.fptosi(steps, ir.VectorType(I32, LANES)), bytes_)
        builder.store(out, _vector_at(context, builder, labels_t, labels_v, [at], bytes_), align=1)
        return context.get_dummy_value()

    return sig, codegen
