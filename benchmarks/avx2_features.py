"""Print the CPU features numba should compile for to get the code a machine
without AVX-512 runs: this machine's features with every AVX-512 (and AMX,
AVX-VNNI, AVX10) extension switched off.

On a machine with AVX-512 the kernels otherwise compile to AVX-512 code
everywhere; ``CLOTHSIM_NO_AVX512=1`` only switches clothsim's own choice of
the list build's compress. To time what an AVX2 machine runs, compile the
whole of it for an AVX2 CPU, in a cache folder of its own:

    NUMBA_CPU_NAME=znver3 NUMBA_CPU_FEATURES=$(python benchmarks/avx2_features.py) \\
        NUMBA_CACHE_DIR=/tmp/avx2-kernels python benchmarks/bench_sim.py --against-soa

The C yardstick is then best built for the same CPU (``-march=znver3``) by hand.
"""

from __future__ import annotations

import llvmlite.binding as llvm

OFF = ("avx512", "amx", "avxvnni", "avx10")
"""feature name parts that a machine without AVX-512 lacks"""


def avx2_features() -> str:
    """The host's LLVM feature string with the AVX-512 family turned off."""
    out = []
    for feature in llvm.get_host_cpu_features().flatten().split(","):
        name = feature[1:]
        out.append(f"-{name}" if feature.startswith("+") and any(p in name for p in OFF) else feature)
    return ",".join(out)


if __name__ == "__main__":
    print(avx2_features())
