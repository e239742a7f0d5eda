"""benchmarks/core_trip.c: it times a cache line's round trip between two CPUs,
and refuses CPUs it cannot bounce a line between (one it may not run on, or
the same one twice, where both threads would spin on one core for ever) with
one line and exit status 2, at once."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parent.parent / "benchmarks"
sys.path.insert(0, str(BENCH))

CC = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
pytestmark = pytest.mark.skipif(CC is None, reason="no C compiler")


@pytest.fixture(scope="module")
def exe(tmp_path_factory):
    out = tmp_path_factory.mktemp("core_trip") / "core_trip"
    subprocess.run([CC, "-O2", "-pthread", "-o", str(out), str(BENCH / "core_trip.c")], check=True)
    return out


@pytest.mark.parametrize("cpus", [("0", "0"), ("0", "100000"), ("-1", "0")])
def test_cpus_it_cannot_use_are_refused_at_once(exe, cpus):
    done = subprocess.run([str(exe), *cpus, "1000"], capture_output=True, text=True, timeout=10)
    assert done.returncode == 2
    assert done.stdout == ""
    assert len(done.stderr.strip().splitlines()) == 1 and "CPUs" in done.stderr


@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="one CPU")
def test_round_trip_between_two_cpus(exe):
    first, second = sorted(os.sched_getaffinity(0))[:2]
    done = subprocess.run([str(exe), str(first), str(second), "20000"], capture_output=True, text=True,
                          timeout=60, check=True)
    out = json.loads(done.stdout)
    assert out["cpus"] == [first, second] and out["rounds"] == 20000
    # a line cannot go to another core and back in under a nanosecond, and a
    # round trip of a millisecond would mean the two threads shared one core
    assert 1.0 < out["round_trip_ns"] < 1e6


def test_probe_gives_a_figure_or_none():
    from core_trip import CoreTrip

    trip = CoreTrip().probe()
    if {0, 1} <= os.sched_getaffinity(0):
        assert trip is not None and 1.0 < trip < 1e6
    else:
        assert trip is None
