"""benchmarks/fma_rate.c: the core's multiply-add rate, the roof the springs'
vector code is held against (docs/performance.md). It prints one JSON object,
the independent chains finish a multiply-add far sooner than a dependent
chain waits for one, and a steps count that is not a positive number gets one
line and exit status 2."""

from __future__ import annotations

import json
import platform
import shutil
import subprocess
from pathlib import Path

import pytest

SOURCE = Path(__file__).resolve().parent.parent / "benchmarks" / "fma_rate.c"
CC = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
pytestmark = pytest.mark.skipif(CC is None or platform.machine() not in ("x86_64", "AMD64"),
                                reason="needs a C compiler for x86-64")


@pytest.fixture(scope="module")
def exe(tmp_path_factory):
    out = tmp_path_factory.mktemp("fma_rate") / "fma_rate"
    subprocess.run([CC, "-O2", "-march=native", "-o", str(out), str(SOURCE)], check=True)
    return out


def test_the_rates_are_timed_and_the_chains_kept_apart(exe):
    done = subprocess.run([str(exe), "200000"], capture_output=True, text=True, timeout=120, check=True)
    out = json.loads(done.stdout)
    assert out["ns_per_fma_256"] > 0.0
    assert out["ns_per_fma_512"] > 0.0 or out["ns_per_fma_512"] == -1.0  # -1: built without AVX-512
    # a dependent multiply-add waits out its latency (several cycles); twelve
    # chains side by side finish one or two a cycle: were the twelve folded
    # into one chain, or made to wait on each other, the two would be close
    assert out["ns_per_dependent_fma"] > 2.0 * out["ns_per_fma_256"]


@pytest.mark.parametrize("steps", ["0", "-5", "many", "12x"])
def test_a_steps_count_that_is_not_a_positive_number_is_refused(exe, steps):
    done = subprocess.run([str(exe), steps], capture_output=True, text=True, timeout=10)
    assert done.returncode == 2
    assert done.stdout == ""
    assert len(done.stderr.strip().splitlines()) == 1 and steps in done.stderr
