"""How the springs take the inverse of their length, by the CPU the kernels compile for.

:func:`clothsim.solver.shared.divides` picks a double square root and divide
on AMD's Zen cores without AVX-512 and a single-precision estimate refined
in double elsewhere. A test process compiles for one CPU only, so the other
choice is compiled in a subprocess, for a CPU of the other kind with this
machine's features less AVX-512, and the eights' and loops' tests run there.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import llvmlite.binding as llvm
import numpy as np
import pytest

from clothsim.solver.shared import DIVIDE, divides, over_length
from clothsim.solver.simd import FORCE_PORTABLE, has_compress
from clothsim.vector_width import features_without_avx512, target_cpu_name

OTHER_RUN = "CLOTHSIM_TEST_OTHER_INVERSE"
"""set in the subprocess that compiles the other choice, which must not start another"""


def test_only_zen_cores_without_avx512_divide():
    assert divides("znver3", compress=False)
    assert divides("znver2", compress=False)
    assert not divides("znver4", compress=True)
    for intel in ("alderlake", "skylake", "rocketlake", "haswell", "x86-64-v3"):
        assert not divides(intel, compress=False)
    assert not divides("sapphirerapids", compress=True)
    assert DIVIDE == divides(target_cpu_name(), has_compress())


def test_features_without_avx512_turn_off_the_family_and_keep_the_rest():
    host = "+sse4.2,+avx2,+fma,+avx512f,+avx512bw,-avx512fp16,+avx512vl,+amx-tile,+avxvnni,+avx10.1-512,+bmi2"
    out = features_without_avx512(host).split(",")
    assert out == ["+sse4.2", "+avx2", "+fma", "-avx512f", "-avx512bw", "-avx512fp16", "-avx512vl", "-amx-tile",
                   "-avxvnni", "-avx10.1-512", "+bmi2"]


def test_over_length_is_within_its_error_of_the_exact_inverse():
    """a / sqrt(l2) to 1e-15 dividing, 1e-13 from the estimate, across the
    lengths a spring takes and at 0 (finite)"""
    rng = np.random.default_rng(5)
    l2 = np.concatenate([rng.uniform(1e-8, 4.0, 2000), 10.0 ** rng.uniform(-12, 2, 2000)])
    got = np.array([over_length(0.7, v) for v in l2])
    exact = 0.7 / np.sqrt(l2)
    assert np.max(np.abs(got - exact) / exact) < (1e-15 if DIVIDE else 1e-13)
    assert np.isfinite(over_length(1.0, 0.0))


def _other_cpu() -> str:
    """an LLVM CPU name whose choice is the other one, on this machine's features"""
    return "alderlake" if DIVIDE else "znver3"


@pytest.mark.skipif(bool(os.environ.get(OTHER_RUN)), reason="this run is the other choice")
def test_the_other_choice_keeps_the_eights_and_the_loops_together(tmp_path):
    """compiled for a CPU of the other kind (without AVX-512, in a cache of its
    own), the choice flips, and the eights still agree with the loops: the
    same to the bit where both divide, within the loops' error where the loops
    take the estimate"""
    env = {**os.environ, OTHER_RUN: "1", FORCE_PORTABLE: "1", "NUMBA_CACHE_DIR": str(tmp_path),
           "NUMBA_CPU_NAME": _other_cpu(),
           "NUMBA_CPU_FEATURES": features_without_avx512(llvm.get_host_cpu_features().flatten())}
    probe = subprocess.run([sys.executable, "-c", "from clothsim.solver.shared import DIVIDE; print(DIVIDE)"],
                           env=env, capture_output=True, text=True, check=False)
    assert probe.stdout.strip() == str(not DIVIDE), probe.stdout + probe.stderr[-3000:]
    here = Path(__file__).parent
    run = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                          str(here / "test_spring_lanes.py"), __file__],
                         env=env, capture_output=True, text=True, check=False, timeout=1800)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    assert " failed" not in run.stdout and " passed" in run.stdout, run.stdout[-3000:]
