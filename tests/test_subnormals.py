"""No subnormal numbers where a cloth's motion makes tiny ones likely.

A multiply or add that takes or makes a subnormal number costs an x86 core a
microcode assist of some hundred cycles. These tests read the SSE status
register's sticky flags (denormal operand, underflow) around a kernel, from
compiled code, so that nothing else runs between clearing and reading them.
"""

from __future__ import annotations

import platform

import numpy as np
import pytest
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

from clothsim.solver.selfcollide.drift import drift_bound, levels

pytestmark = pytest.mark.skipif(platform.machine().lower() not in ("x86_64", "amd64"),
                                reason="reads the x86 SSE status register")

DENORMAL, UNDERFLOW = 1 << 1, 1 << 4
"""MXCSR's sticky flags: an operand was subnormal; a result was tiny (subnormal or flushed)"""
FLAGS = 0x3F
"""all six sticky exception flags"""


def _status_call(builder, name, slot):
    """``name`` (llvm.x86.sse.stmxcsr or ldmxcsr) on the 32 bits at ``slot``"""
    byte_ptr = ir.IntType(8).as_pointer()
    fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.VoidType(), [byte_ptr]), name)
    builder.call(fn, [builder.bitcast(slot, byte_ptr)])


@intrinsic
def _read_status(typingctx):
    """MXCSR, as a uint32"""
    def codegen(context, builder, signature, args):
        slot = cgutils.alloca_once(builder, ir.IntType(32))
        _status_call(builder, "llvm.x86.sse.stmxcsr", slot)
        return builder.load(slot)
    return types.uint32(), codegen


@intrinsic
def _write_status(typingctx, value):
    """MXCSR set to ``value`` (a uint32)"""
    def codegen(context, builder, signature, args):
        slot = cgutils.alloca_once_value(builder, args[0])
        _status_call(builder, "llvm.x86.sse.ldmxcsr", slot)
        return context.get_dummy_value()
    return types.void(types.uint32), codegen


@njit
def _drift_flags(Q, reference, skin, centres, extent, parts):
    """the drift test as the substep makes it, and the sticky flags it raised"""
    before = _read_status()
    _write_status(before & np.uint32(~FLAGS & 0xFFFFFFFF))
    bound = drift_bound(Q, reference, skin, centres, extent, levels(Q, reference, skin, centres, parts))
    raised = _read_status() & np.uint32(FLAGS)
    _write_status(before)
    return bound, raised


def test_status_flags_are_read():
    """the probe itself: a square of 1e-20 in single precision underflows (read from
    and written to arrays, so that the multiply stays between the reads of the flags)"""
    @njit
    def square(a, b):
        before = _read_status()
        _write_status(before & np.uint32(~FLAGS & 0xFFFFFFFF))
        b[0] = a[0] * a[0]
        raised = _read_status() & np.uint32(FLAGS)
        _write_status(before)
        return raised

    out = np.zeros(1, dtype=np.float32)
    assert square(np.array([1e-20], dtype=np.float32), out) & UNDERFLOW
    assert not square(np.array([1e-10], dtype=np.float32), out) & (UNDERFLOW | DENORMAL)


def test_drift_test_of_a_cloth_that_fell_flat_makes_no_subnormal():
    """A flat cloth that fell moved every point by the same height and by exactly
    0 along x and z, but for a few 1e-18 m of rounding on some points (a
    plane's contact leaves them). The mean of such displacements is a few
    1e-20 m, and the squares of 0 less it, taken in single precision, were
    subnormal for nearly every point: on the 50x50 `plane` at rest the drift
    test took 24 µs a substep instead of 2. The bound is still the bound."""
    rows = cols = 50
    # in single precision from the origin of the list's build, a corner point: the
    # points of the first column lie at x = 0, and their rounding stays there
    u, v = np.meshgrid(np.linspace(0.0, 1.0, cols), np.linspace(0.0, 1.0, rows))
    ref32 = np.stack([u.ravel(), np.zeros(rows * cols), v.ravel()]).astype(np.float32)
    Q = ref32 + np.array([[0.0], [-0.2], [0.0]], dtype=np.float32)
    rng = np.random.default_rng(7)
    column = np.arange(0, rows * cols, cols)
    Q[0, column] = rng.uniform(-5e-18, 5e-18, column.size).astype(np.float32)
    moved = Q - ref32
    assert np.count_nonzero(moved[0]) == column.size and np.all(moved[2] == 0.0)
    skin = 0.01425
    centres = np.zeros((2, 3))  # from before the fall: they no longer hold, and are chosen afresh
    extent = float(np.abs(Q).max() + np.abs(ref32).max())
    bound, raised = _drift_flags(Q, ref32, skin, centres, extent, 1)
    assert not raised & (UNDERFLOW | DENORMAL), hex(raised)
    # all moved alike: the first of the steps, widened by a hair for the rounding
    assert bound <= skin / 16 * (1 + 2 ** -18) + 3 * extent * 2 ** -18
    # and kept centres hold again without being chosen
    bound_again, raised = _drift_flags(Q, ref32, skin, centres, extent, 2)
    assert bound_again == bound and not raised & (UNDERFLOW | DENORMAL), hex(raised)
