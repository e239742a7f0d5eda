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
