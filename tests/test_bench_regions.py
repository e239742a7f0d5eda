"""benchmarks/bench_regions.py: the substep timed region by region inside a real run.

Its figures are sums of the time-stamp counter's reads, so they obey what
any correct timing of nested spans must: a region takes at least as long as
the slowest part inside it, and the stages, which do not overlap, add up to
no more than the substep the wall clock timed. The run is of ``pinned4``,
resized with its pins kept at the corners: any standard scene with
self-collision is timed the same way (``--scene``).
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parent.parent / "benchmarks"
sys.path.insert(0, str(BENCH))

import bench_regions  # noqa: E402


@pytest.fixture(scope="module")
def lines():
    done = subprocess.run([sys.executable, str(BENCH / "bench_regions.py"), "--size", "24", "--seconds", "0.2",
                           "--threads", "1,2", "--scene", "pinned4"], capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-2000:]
    return [json.loads(line) for line in done.stdout.splitlines()]


def test_every_stage_is_timed_on_each_thread_count(lines):
    assert {(d["scene"], d["grid"]) for d in lines} == {("pinned4", "24x24")}
    for threads, parts in ((1, 1), (2, 2)):
        stages = {d["stage"]: d for d in lines if d["threads"] == threads}
        assert set(stages) == {s for s, _ in bench_regions.STAGES.values()} | {"substep"}
        whole = stages.pop("substep")
        assert whole["parts"] == parts and whole["builds"] >= 1 and whole["substeps_per_s"] > 0
        for stage, (_, parted) in zip(stages.values(), bench_regions.STAGES.values()):
            assert stage["region_us"] >= 0.0
            if parted:
                assert len(stage["parts_us"]) == parts
                # a region holds its parts: the slowest cannot take longer
                assert stage["region_us"] >= max(stage["parts_us"]) - 0.01
        # the springs, the colliders and Provot run every substep and cost something
        assert stages["springs and Verlet"]["region_us"] > 0 and stages["colliders and Provot"]["region_us"] > 0
        # stages that do not overlap add up to no more than the substep (2% for the counter's rate)
        spans = ["springs and Verlet", "handles and wind (one thread)",
                 "colliders and Provot", "Provot across the cuts (one thread)"]
        total = sum(stages[s]["region_us"] for s in spans) + whole["self_collision_us"]
        assert total <= 1.02 * whole["us_per_substep"]
        inside = sum(stages[s]["region_us"] for s in stages if s.startswith("self-collision"))
        assert inside <= whole["self_collision_us"] + 0.01
    two = [d for d in lines if d["threads"] == 2 and d["stage"] != "substep"]
    assert all(d["half_of_one_thread_us"] >= 0 for d in two)


def test_a_moved_line_is_named_not_timed_wrong():
    with pytest.raises(SystemExit, match="solver/step.py no longer holds the line"):
        bench_regions._patch("nothing of the substep here", [("    while done < frames:\n", "")], "solver/step.py")


def test_a_scene_that_is_not_standard_is_refused_before_anything_compiles():
    done = subprocess.run([sys.executable, str(BENCH / "bench_regions.py"), "--scene", "flag"],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2
    assert "--scene" in done.stderr and "invalid choice: 'flag'" in done.stderr
