"""What the benchmarks share: the standard scenes and their resizing, and what
every benchmark line carries: the machine and the library versions."""

from __future__ import annotations

import json
import platform
import resource
import sys

SCENES = ["pinned2", "pinned4", "sphere", "plane", "selfCollision"]
"""the standard scenes, each one grid cloth that :func:`sized` resizes"""


def sized(scene: str, n: int) -> list[str]:
    """Overrides that resize a standard scene to n x n, keeping its pins at the corners."""
    out = [f"cloth.num_width_points={n}", f"cloth.num_height_points={n}"]
    if scene == "pinned2":
        out.append(f"cloth.pinned=[[0,0],[{n - 1},0]]")
    elif scene == "pinned4":
        out.append(f"cloth.pinned=[[0,0],[{n - 1},0],[0,{n - 1}],[{n - 1},{n - 1}]]")
    return out


def machine() -> dict:
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    import numba
    import numpy

    import clothsim
    from clothsim.solver.shared import DIVIDE
    from clothsim.solver.simd import has_compress

    try:
        from clothsim.vector_width import widen
    except ImportError:  # a tree from before it (an A/B run): LLVM's 256 bits
        def widen() -> bool:
            return False
    try:
        from clothsim.solver.spring_lanes import RSQRT14
    except ImportError:  # a tree from before it: the eights took the loops' inverse
        RSQRT14 = False
    inverse = "divide" if DIVIDE else "estimate"
    try:
        from clothsim.solver.springs import BY_LANES
        from clothsim.solver.spring_lanes import LANES
    except ImportError:  # a tree from before them: eight points a call with AVX-512, else the loops
        BY_LANES, LANES = has_compress(), 8

    # the CPU's name does not say which code the kernels were compiled to: two
    # "AMD EPYC" machines here differ in AVX-512, and the springs in how they
    # take a length's inverse (docs/performance.md); vector_bits: how wide LLVM
    # made the loops (clothsim.vector_width; 256 also on a CPU without AVX-512,
    # whose widest vectors those are); the grid's eights, where they run, and
    # the general path's pulls take AVX-512's estimate refined twice, the loops
    # the divide or the estimate; grid_springs: how the grid's springs walk the
    # cloth (spring_lanes' calls of so many points, or numba's loops)
    return {"cpu": cpu, "avx512_code": has_compress(), "vector_bits": 512 if widen() else 256,
            "inverse_length": (f"{inverse}, eights rsqrt14" if RSQRT14 else
                               f"{inverse}, lanes divide" if BY_LANES and not DIVIDE else inverse),
            "grid_springs": f"{LANES} points a call" if BY_LANES else "loops",
            "python": platform.python_version(), "numpy": numpy.__version__,
            "numba": numba.__version__, "clothsim": clothsim.__version__}


def peak_rss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def emit(record: dict) -> None:
    print(json.dumps(record), flush=True)
    sys.stdout.flush()
