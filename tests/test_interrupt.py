"""Ctrl-C during a run ends it with one line and exit code 130, never a traceback.

The substep's compiled call releases the GIL and returns to Python once per
frame, where the interrupt is raised; before, a SIGINT that landed inside the
compiled call came back as "SystemError: ... returned a result with an
exception set" and exit code 1.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def test_ctrl_c_during_simulate_says_interrupted_and_exits_130():
    from clothsim import Simulation

    Simulation.from_file(ROOT / "scenes" / "sphere.json").step()  # the kernels compiled and cached
    env = dict(os.environ, CLOTHSIM_PREWARM="0")
    for delay in (1.0, 1.5, 2.0, 2.5):  # while the kernels load, and in and between compiled calls
        run = subprocess.Popen([sys.executable, "-m", "clothsim", "simulate", "sphere", "--seconds", "120",
                                "--no-progress"], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True)
        time.sleep(delay)
        run.send_signal(signal.SIGINT)
        out, err = run.communicate(timeout=60)
        lines = [line for line in err.splitlines() if not line.startswith("clothsim: compiling")]
        assert run.returncode == 130, err[-2000:]
        assert lines == ["clothsim: interrupted"], err[-2000:]


def test_sigterm_stops_a_run_with_143_and_leaves_no_partial_file(tmp_path):
    """SIGTERM (a killed job, a closed terminal) ends the run like Ctrl-C, with exit code
    143; the whole-run output is not written, and the OBJ sequence holds only whole
    frames: no temporary file is left"""
    from clothsim import Simulation

    Simulation.from_file(ROOT / "scenes" / "sphere.json").step()
    env = dict(os.environ, CLOTHSIM_PREWARM="0")
    frames, usd = tmp_path / "frames", tmp_path / "run.usdc"
    run = subprocess.Popen([sys.executable, "-m", "clothsim", "simulate", "sphere", "--seconds", "120",
                            "--no-progress", "--export-sequence", str(frames), "--export-usd", str(usd)],
                           env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # until the run writes frames (a cold start may take a while), then a moment more
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and run.poll() is None and not (
            frames.is_dir() and any(p.suffix == ".obj" for p in frames.iterdir())):
        time.sleep(0.2)
    time.sleep(1.0)
    run.send_signal(signal.SIGTERM)
    out, err = run.communicate(timeout=60)
    lines = [line for line in err.splitlines() if not line.startswith("clothsim: compiling")]
    assert run.returncode == 143, err[-2000:]
    assert lines == ["clothsim: interrupted"], err[-2000:]
    assert not usd.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["frames"]
    names = sorted(p.name for p in frames.iterdir())
    assert names and all(n.startswith("frame_") and n.endswith(".obj") for n in names), names
    assert names == [f"frame_{k:04d}.obj" for k in range(len(names))]
    last = (frames / names[-1]).read_text()
    assert last.count("\nf ") == 2 * 49 * 49  # whole: every face line is there
