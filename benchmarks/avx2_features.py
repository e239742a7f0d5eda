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
The CPU's name picks how the springs take their inverse length
(:func:`clothsim.solver.shared.divides`): ``znver3`` compiles the code of an
AMD Zen core, which divides; an Intel core's name (``alderlake``) the code of
an Intel core without AVX-512, which takes the single-precision estimate.
"""

from __future__ import annotations

import llvmlite.binding as llvm

from clothsim.vector_width import features_without_avx512


def avx2_features() -> str:
    """The host's LLVM feature string with the AVX-512 family turned off."""
    return features_without_avx512(llvm.get_host_cpu_features().flatten())


if __name__ == "__main__":
    print(avx2_features())
