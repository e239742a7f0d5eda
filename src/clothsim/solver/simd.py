"""A vector instruction numba does not write by itself: AVX-512's compress.

The list build finds a chunk's pairs as a mask of bits, one per candidate
slot, and must append the points of the set bits to the list. Written as a
loop over the bits, that ends in a mispredicted branch for most chunks; the
compress instruction packs the chosen lanes of a vector together in one
step, so the append is a load, a compress and a store whatever the bits.
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
"""int32 lanes of one compress: a 512-bit vector"""

FORCE_PORTABLE = "CLOTHSIM_NO_AVX512"
"""set (to anything but empty) in the environment to compile the portable path
on a machine that has AVX-512: how the tests check that path"""


def target_features() -> str:
    """The CPU features numba compiles for: its configured ones, else the host's."""
    name = numba.config.CPU_NAME
    if name and name != "host":
        return numba.config.CPU_FEATURES or ""
    return llvm.get_host_cpu_features().flatten()


def has_compress() -> bool:
    """Whether compiled code may use the AVX-512 compress (AVX512F)."""
    if os.environ.get(FORCE_PORTABLE):
        return False
    return "+avx512f" in target_features().split(",")


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
        a = context.make_array(src_t)(context, builder, src_v)
        d = context.make_array(dst_t)(context, builder, dst_v)
        at_v = context.cast(builder, at_v, signature.args[1], types.intp)
        row_v = context.cast(builder, row_v, signature.args[3], types.intp)
        end_v = context.cast(builder, end_v, signature.args[4], types.intp)
        mask_v = context.cast(builder, mask_v, signature.args[5], types.uint64)
        from_ptr = cgutils.get_item_pointer(context, builder, src_t, a, [at_v], wraparound=False)
        to_ptr = cgutils.get_item_pointer(context, builder, dst_t, d, [row_v, end_v], wraparound=False)
        vec = ir.VectorType(ir.IntType(32), LANES)
        bits = ir.VectorType(ir.IntType(1), LANES)
        lanes = builder.load(builder.bitcast(from_ptr, vec.as_pointer()), align=4)
        chosen = builder.bitcast(builder.trunc(mask_v, ir.IntType(LANES)), bits)
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(vec, [vec, vec, bits]),
                                            "llvm.x86.avx512.mask.compress.v16i32")
        packed = builder.call(fn, [lanes, ir.Constant(vec, None), chosen])
        builder.store(packed, builder.bitcast(to_ptr, vec.as_pointer()), align=4)
        return context.get_dummy_value()

    return sig, codegen
