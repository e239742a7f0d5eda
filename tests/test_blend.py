"""The colliders' write-back: whole stores of a blend, with every bit of the
points they leave as they were (see clothsim.solver.blend)."""

from __future__ import annotations

import re

import numba
import numpy as np
import pytest
from numba import njit

from clothsim.solver.blend import unchanged
from clothsim.solver.colliders import box, plane, sphere
from clothsim.solver.shared import KERNEL_OPTIONS

ODD_VALUES = [0.0, -0.0, 5e-324, -2.2250738585072014e-308, 1.0, -1.5, 1e308, np.inf, -np.inf]


@njit(**KERNEL_OPTIONS)
def _write_back(a, hit):
    for i in range(a.shape[0]):
        v = a[i]
        a[i] = 2.0 * v + 1.0 if hit[i] else unchanged(v)


def test_unchanged_keeps_every_bit_of_what_it_is_given():
    a = np.array(ODD_VALUES * 7 + [np.nan], dtype=np.float64)
    # a NaN with a payload of its own, which a copy through arithmetic would not keep
    a[-1] = np.frombuffer(np.uint64(0x7FF8_0000_DEAD_BEEF).tobytes(), dtype=np.float64)[0]
    hit = np.zeros(a.shape[0], dtype=np.bool_)
    hit[::3] = True
    before = a.copy()
    _write_back(a, hit)
    assert np.array_equal(a.view(np.uint64)[~hit], before.view(np.uint64)[~hit])
    with np.errstate(over="ignore"):
        assert np.array_equal(a[hit], 2.0 * before[hit] + 1.0, equal_nan=True)


MASKED_STORE = re.compile(r"^\s*(?:vmaskmovp[sd]\s+%[xy]mm\d+, %[xy]mm\d+, .*\)"
                          r"|vmov\w*\s+%[xyz]mm\d+, [^,]*\(.*\)\s*\{%k\d\})\s*$", re.MULTILINE)
"""an x86 store under a mask: AVX's vmaskmov to memory, or AVX-512's move to
memory under a mask register"""

AVX_MASKED_STORE = re.compile(r"^\s*vmaskmovp[sd]\s+%[xy]mm\d+, %[xy]mm\d+, .*\)\s*$", re.MULTILINE)
"""AVX's vmaskmov to memory alone: the slow store of the CPUs without AVX-512"""


def _masked_stores(asm: str) -> list[str]:
    """The masked stores the collider loops must not have: any, in 256-bit code; in
    512-bit code (clothsim.vector_width, only where the CPU has AVX-512) AVX's
    vmaskmov alone. The slow masked stores are AVX's on AMD cores before Zen 4,
    which lack AVX-512 and so never run 512-bit code. In 512-bit code LLVM writes
    the hit points under a mask register whatever the blend says; what that costs
    is measured in docs/performance.md ("512-bit vectors")."""
    wide = "-prefer-256-bit" in (numba.config.CPU_FEATURES or "").split(",")
    return (AVX_MASKED_STORE if wide else MASKED_STORE).findall(asm)


def _asm(kernel, *args):
    """the host's assembly of a fresh, uncached compile of ``kernel`` for ``args``"""
    fresh = njit(**{**KERNEL_OPTIONS, "cache": False})(kernel.py_func)
    fresh(*args)
    return "\n".join(fresh.inspect_asm().values())


@pytest.mark.parametrize("kind", ["sphere", "plane", "box"])
def test_the_collider_loops_store_whole_vectors(kind):
    """LLVM would otherwise write the points that hit through masked stores, which
    are slow on AMD cores before Zen 4 (docs/performance.md, "Masked stores"). A
    host without such stores (not x86) passes as it is."""
    n = 1000
    rng = np.random.default_rng(3)
    P = rng.uniform(-1, 1, (3, n))
    L = P + rng.normal(0, 1e-3, (3, n))
    free = np.ones(n)
    lo, hi, s = np.int64(0), np.int64(n), np.int64(0)
    if kind == "sphere":
        kernel, rows = sphere.collide_spheres, sphere.pack([_Obj(origin=(0, 0, 0), radius=0.5, friction=0.3)])
    elif kind == "plane":
        kernel, rows = plane.collide_planes, plane.pack([_Obj(point=(0, 0, 0), normal=(0, 1, 0), friction=0.3)])
    else:
        # both of the vector pass's loops, each still and moving: the aligned box's
        # (sliding) and the general one (sliding, or turning)
        row = box.pack([_Obj(center=(0, 0, 0), size=(1, 0.4, 1), rotate=(0, 0, 0), friction=0.3, margin=1e-3)])[0, 0]
        box_ = tuple(float(v) for v in row[:17])
        planes, refs, marked = (P[0], P[1], P[2]), (L[0], L[1], L[2]), np.zeros(n, dtype=np.bool_)
        carry = tuple(float(v) for v in row[17:])
        for shift in (None, (0.01, 0.0, -0.02)):
            assert not _masked_stores(_asm(box._aligned_loop, planes, refs, free, marked, box_, shift))
        for a, shift in ((None, None), (carry, None), (carry, (0.01, 0.0, -0.02))):
            assert not _masked_stores(_asm(box._turned_loop, planes, refs, free, marked, box_, a, shift))
        return
    asm = _asm(kernel, P, L, free, rows, lo, hi, s)
    assert not _masked_stores(asm)


class _Obj:
    def __init__(self, **kw):
        self.__dict__.update(kw, animation=None)
