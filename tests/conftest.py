"""Shared helpers: small scenes built in code, so tests stay fast."""

from __future__ import annotations

import copy
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

# no background compile (solver/prewarm.py) started by the tests' own runs and the
# commands they start: on a two-core machine it takes a core for tens of seconds
# and slows whatever the tests time; tests/test_prewarm.py sets it itself
os.environ.setdefault("CLOTHSIM_PREWARM", "0")

ROOT = Path(__file__).resolve().parent.parent
SCENES = ROOT / "scenes"

SMALL_CLOTH = {
    "width": 1.0, "height": 1.0, "num_width_points": 16, "num_height_points": 16,
    "thickness": 0.0095, "orientation": 0, "pinned": [[0, 0], [15, 0]],
    "damping": 0.2, "density": 150, "ks": 5000,
}


def small_scene(**sections) -> dict:
    """A 16x16 horizontal cloth pinned at two corners; keyword args replace or add sections."""
    scene = {"cloth": copy.deepcopy(SMALL_CLOTH)}
    for key, value in sections.items():
        if key == "cloth":
            scene["cloth"].update(value)
        else:
            scene[key] = value
    return scene


@pytest.fixture
def write_scene(tmp_path):
    """Write a scene dict (or raw text) to a file and return its path."""
    def write(data, name: str = "scene.json") -> Path:
        path = tmp_path / name
        path.write_text(data if isinstance(data, str) else json.dumps(data))
        return path
    return write


@pytest.fixture
def dask_cluster(tmp_path):
    """a real distributed scheduler and two single-threaded workers on 127.0.0.1"""
    sched_file = tmp_path / "scheduler.json"
    env = {**os.environ, "DASK_DISTRIBUTED__WORKER__DAEMON": "False"}
    dask = [sys.executable, "-m", "distributed.cli.dask_scheduler"]
    procs = [subprocess.Popen([*dask, "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                               "--scheduler-file", str(sched_file)], env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        deadline = time.time() + 60
        while not sched_file.exists() and time.time() < deadline:
            time.sleep(0.2)
        address = json.loads(sched_file.read_text())["address"]
        for _ in range(2):
            procs.append(subprocess.Popen(
                [sys.executable, "-m", "distributed.cli.dask_worker", address, "--nthreads", "1",
                 "--no-dashboard", "--host", "127.0.0.1"], env=env,
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        from distributed import Client

        with Client(address, timeout="30s") as client:
            client.wait_for_workers(2, timeout=60)
        yield address
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
