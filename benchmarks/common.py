"""What every benchmark line carries: the machine and the library versions."""

from __future__ import annotations

import json
import platform
import resource
import sys


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

    return {"cpu": cpu, "python": platform.python_version(), "numpy": numpy.__version__,
            "numba": numba.__version__, "clothsim": clothsim.__version__}


def peak_rss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def emit(record: dict) -> None:
    print(json.dumps(record), flush=True)
    sys.stdout.flush()
