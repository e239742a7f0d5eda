"""The round trip of a cache line between the first two CPUs, for the threaded benchmarks.

On the two-core virtual machines here the host places the two virtual CPUs
near each other (a line goes there and back in about 55 ns) or far apart
(about 330 ns), and moves them now and then, for minutes at a time. The
substep's parts hand lines to each other every substep, so a threaded
figure means little without the placement it ran in (docs/performance.md,
"Two cores near and far"). :class:`CoreTrip` compiles ``core_trip.c`` once
with the C compiler on PATH and times a short bounce whenever asked.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

SOURCE = Path(__file__).resolve().parent / "core_trip.c"
BOUNCES = 200_000
"""round trips per probe: 10-70 ms"""


class CoreTrip:
    """``probe()``: nanoseconds a line takes between CPUs 0 and 1 and back, or None
    where it cannot be measured (one CPU, no C compiler, a failed build)."""

    def __init__(self) -> None:
        self._folder = tempfile.TemporaryDirectory(prefix="core_trip")
        self._exe = self._build()

    def _build(self) -> Path | None:
        cc = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
        if cc is None or not {0, 1} <= os.sched_getaffinity(0):
            return None
        exe = Path(self._folder.name) / "core_trip"
        done = subprocess.run([cc, "-O2", "-pthread", "-o", str(exe), str(SOURCE)], capture_output=True)
        return exe if done.returncode == 0 else None

    def probe(self) -> float | None:
        if self._exe is None:
            return None
        done = subprocess.run([str(self._exe), "0", "1", str(BOUNCES)], capture_output=True, text=True,
                              timeout=60)
        if done.returncode != 0:
            return None
        return float(json.loads(done.stdout)["round_trip_ns"])
