"""bench_sim.py --against-soa: it builds the C yardstick, reads its figure, and
refuses a missing or broken source with one line and exit status 2."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parent.parent / "benchmarks"
sys.path.insert(0, str(BENCH))

CC = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")

# a stand-in for soa.c: it prints the JSON line the real one prints, with a
# figure worked out from its arguments, so a parser that read the wrong
# field or the wrong line would not get it
FAKE = r"""
#include <stdio.h>
#include <stdlib.h>
int main(int argc, char **argv) {
    printf("warming up\n");
    printf("{\"impl\": \"soa_list\", \"N\": %d, \"substeps_per_s\": %d.5}\n", atoi(argv[1]),
           atoi(argv[1]) * atoi(argv[3]));
    return 0;
}
"""


def run_bench(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(BENCH / "bench_sim.py"), *args], capture_output=True, text=True,
                          timeout=300)


def test_missing_source_is_refused_in_one_line(tmp_path):
    done = run_bench("--against-soa", str(tmp_path / "absent.c"))
    assert done.returncode == 2
    assert done.stdout == ""
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "absent.c" in lines[0] and "--against-soa" in lines[0]


@pytest.mark.skipif(CC is None, reason="no C compiler")
def test_source_that_does_not_compile_is_refused_in_one_line(tmp_path):
    bad = tmp_path / "broken.c"
    bad.write_text("int main( {\n")
    done = run_bench("--against-soa", str(bad))
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "did not compile" in lines[0] and "broken.c" in lines[0]


@pytest.mark.skipif(CC is None, reason="no C compiler")
def test_yardstick_is_built_and_its_figure_read(tmp_path):
    import bench_sim

    source = tmp_path / "soa.c"
    source.write_text(FAKE)
    exe = bench_sim.build_soa(source, tmp_path)
    assert exe.is_file()
    n, timed = int(bench_sim.SOA_ARGS[0]), int(bench_sim.SOA_ARGS[2])
    assert bench_sim.run_soa(exe) == n * timed + 0.5
