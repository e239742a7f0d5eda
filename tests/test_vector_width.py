"""The kernels' vectors (clothsim.vector_width): 512 bits wide where the CPU has
AVX-512 and the user left the target to numba, LLVM's 256 otherwise."""

from __future__ import annotations

import os
import subprocess
import sys

import llvmlite.binding as llvm

from clothsim.vector_width import NARROW, NARROW_FEATURE, WIDE_FEATURE, wide_features

AVX512 = "+sse4.2,+avx,+avx2,+fma,+avx512f,+avx512vl,-amx-tile"
AVX2 = "+sse4.2,+avx,+avx2,+fma,-avx512f,-avx512vl"


def test_wide_vectors_only_on_avx512_and_only_when_the_user_left_the_target():
    assert wide_features(AVX512, {}) == AVX512 + "," + WIDE_FEATURE
    assert wide_features(AVX2, {}) is None  # "-avx512f" is not "+avx512f"
    assert wide_features(AVX512 + "," + WIDE_FEATURE, {}) == AVX512 + "," + WIDE_FEATURE  # not twice
    # 256 asked for by name: a CPU model without the tuning (AMD's Zen 4) is 512 bits wide by default
    assert wide_features(AVX512, {NARROW: "256"}) == AVX512 + "," + NARROW_FEATURE
    assert wide_features(AVX512 + "," + NARROW_FEATURE, {}) == AVX512 + "," + WIDE_FEATURE
    assert wide_features(AVX2, {NARROW: "256"}) is None
    assert wide_features(AVX512, {NARROW: "512"}) == AVX512 + "," + WIDE_FEATURE
    assert wide_features(AVX512, {"NUMBA_CPU_NAME": "znver3"}) is None
    assert wide_features(AVX512, {"NUMBA_CPU_FEATURES": AVX2}) is None


PROBE = """
import numba, numpy as np
import clothsim.solver  # sets the features before anything compiles
@numba.njit
def axpy(a, x, y):
    for i in range(y.shape[0]):
        y[i] += a * x[i]
axpy(2.0, np.ones(64), np.ones(64))
asm = next(iter(axpy.inspect_asm().values()))
print((numba.config.CPU_FEATURES or "") + "|" + str("zmm" in asm))
"""


def probe(env: dict) -> tuple[str, bool]:
    """(numba's compile features, whether a plain loop used 512-bit registers) in a
    fresh process importing the solver"""
    env = {k: v for k, v in {**os.environ, **env}.items() if v is not None}
    out = subprocess.run([sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    features, zmm = out.stdout.strip().rsplit("|", 1)
    return features, zmm == "True"


def test_a_loop_compiled_after_importing_the_solver_uses_the_whole_vector():
    """on this machine: 512-bit registers in a plain loop where it has AVX-512, and
    256-bit code with CLOTHSIM_VECTOR_BITS=256 (or without AVX-512), whatever
    LLVM's model of the CPU prefers"""
    avx512 = "+avx512f" in llvm.get_host_cpu_features().flatten().split(",")
    features, zmm = probe({NARROW: None, "NUMBA_CPU_FEATURES": None, "NUMBA_CPU_NAME": None})
    assert zmm == avx512
    assert (WIDE_FEATURE in features.split(",")) == avx512
    features, zmm = probe({NARROW: "256", "NUMBA_CPU_FEATURES": None, "NUMBA_CPU_NAME": None})
    assert not zmm
    assert (NARROW_FEATURE in features.split(",")) == avx512
