"""How wide the kernels' vectors are: the whole of AVX-512's 512 bits, where the CPU has it.

On a CPU with AVX-512, LLVM still vectorises loops 256 bits at a time (four
doubles, eight floats) unless told otherwise: its Intel CPU models carry the
``prefer-256-bit`` tuning, chosen for the first AVX-512 chips, which lowered
their clock for 512-bit work. numba compiles with the host's model and
features, so clothsim's loops ran at half the width the machine offers.
:func:`widen` asks for 512-bit vectors by adding ``-prefer-256-bit`` to the
features numba compiles for (``numba.config.CPU_FEATURES``), which numba
reads once, when it first compiles anything in the process; its cache keys
every entry on those features, so kernels of either width never mix. The
gain is measured in docs/performance.md.

``CLOTHSIM_VECTOR_BITS=256`` asks for 256-bit vectors instead, by adding
``+prefer-256-bit``: LLVM's model of AMD's Zen 4 (``znver4``) lacks that
tuning, so there its default is already 512 bits, and leaving the features
alone would not narrow anything. Both are left alone where the user chose
the target (``NUMBA_CPU_NAME`` or ``NUMBA_CPU_FEATURES`` set) and where the
CPU lacks AVX-512F. This module imports numba only when :func:`widen` is
called.
"""

from __future__ import annotations

import os

NARROW = "CLOTHSIM_VECTOR_BITS"
"""the environment variable that asks for 256-bit vectors when set to 256"""

WIDE_FEATURE = "-prefer-256-bit"
"""the LLVM feature added to the host's: vectors of the full 512 bits"""

NARROW_FEATURE = "+prefer-256-bit"
"""the LLVM feature added to the host's for CLOTHSIM_VECTOR_BITS=256"""


def wide_features(host: str, environ=None) -> str | None:
    """The feature string numba should compile for, given the host's (``host``, as
    llvmlite flattens it) and the environment (``os.environ`` by default): the
    host's with 512-bit vectors, or 256-bit ones where CLOTHSIM_VECTOR_BITS=256;
    None where the host's features stand (see the module's docstring)."""
    environ = os.environ if environ is None else environ
    if environ.get("NUMBA_CPU_NAME") or environ.get("NUMBA_CPU_FEATURES"):
        return None
    features = [f for f in host.split(",") if f not in (WIDE_FEATURE, NARROW_FEATURE)]
    if "+avx512f" not in features:
        return None
    narrow = environ.get(NARROW, "").strip() == "256"
    return ",".join(features + [NARROW_FEATURE if narrow else WIDE_FEATURE])


WITHOUT_AVX512 = ("avx512", "amx", "avxvnni", "avx10")
"""parts of the LLVM feature names that a machine without AVX-512 lacks"""


def features_without_avx512(host: str) -> str:
    """``host`` (an LLVM feature string, as llvmlite flattens it) with the AVX-512
    family turned off: with ``NUMBA_CPU_FEATURES`` set to it, numba compiles
    the code a machine without AVX-512 runs (``benchmarks/avx2_features.py``
    prints it; the tests compile the other inverse length with it)."""
    out = []
    for feature in host.split(","):
        name = feature[1:]
        out.append(f"-{name}" if feature.startswith("+") and any(p in name for p in WITHOUT_AVX512) else feature)
    return ",".join(out)


def target_cpu_name() -> str:
    """The name of the CPU model numba compiles for, as LLVM spells it
    (``znver3``, ``alderlake``, ...): ``NUMBA_CPU_NAME`` where the user chose
    one, else the host's."""
    import llvmlite.binding as llvm
    import numba

    name = numba.config.CPU_NAME
    if not name or name == "host":
        name = llvm.get_host_cpu_name()
    return name


def widen() -> bool:
    """Set numba's compile features to the vector width :func:`wide_features` picks;
    whether numba now compiles 512-bit vectors. Call before the first kernel
    compiles (numba fixes its target then); later calls change nothing."""
    import llvmlite.binding as llvm
    import numba

    if numba.config.CPU_FEATURES is None:
        features = wide_features(llvm.get_host_cpu_features().flatten())
        if features is not None:
            numba.config.CPU_FEATURES = features
    return WIDE_FEATURE in (numba.config.CPU_FEATURES or "").split(",")
