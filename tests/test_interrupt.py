"""Ctrl-C during a run ends it with one line and exit code 130, never a traceback.

The substep's compiled call releases the GIL and returns to Python once per
frame, where the interrupt is raised; before, a SIGINT that landed inside the
compiled call came back as "SystemError: ... returned a result with an
exception set" and exit code 1. Two ways a Ctrl-C used to escape that are
pinned here without the timing of a real run: one landing in llvmlite's Python
code (called back from C while numba loads cached code, where an exception is
dropped and the process crashed), and one raised as a plain KeyboardInterrupt
inside ``eval`` of a string (the interpreter then ended itself by SIGINT after
``main`` had returned 130).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(autouse=True)
def python_answers_ctrl_c():
    """Python's own Ctrl-C handler in place, as in a terminal: a process started in
    the background by a script (``cmd &``) inherits SIGINT ignored, Python leaves
    it ignored, and the handlers these tests restore would be that"""
    before = signal.getsignal(signal.SIGINT)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, before)


def test_ctrl_c_during_simulate_says_interrupted_and_exits_130():
    from clothsim import Simulation

    Simulation.from_file(ROOT / "scenes" / "sphere.json").step()  # the kernels compiled and cached
    env = dict(os.environ, CLOTHSIM_PREWARM="0")
    # while numpy and numba import, while the kernels load, and in and between compiled calls
    for delay in (0.0, 0.1, 0.2, 0.3, 0.5, 0.8, 1.0, 1.25, 1.5, 2.0, 2.5):
        run = subprocess.Popen([sys.executable, "-m", "clothsim", "simulate", "sphere", "--seconds", "120",
                                "--no-progress"], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True)
        try:
            # from the moment clothsim's code runs (before it, the interpreter's own start
            # answers a signal): its handlers catch SIGTERM, which Python's do not
            _wait_for_handler(run.pid, signal.SIGTERM)
            time.sleep(delay)
            run.send_signal(signal.SIGINT)
            out, err = run.communicate(timeout=60)
        finally:
            run.kill()
            run.wait()
        lines = [line for line in err.splitlines() if not line.startswith("clothsim: compiling")]
        assert run.returncode == 130, err[-2000:]
        assert lines == ["clothsim: interrupted"], err[-2000:]


def _wait_for_handler(pid: int, signum: int, limit_s: float = 60.0) -> None:
    """until process ``pid`` catches ``signum`` (its SigCgt mask in /proc says so)"""
    deadline = time.monotonic() + limit_s
    while time.monotonic() < deadline:
        try:
            with open(f"/proc/{pid}/status") as f:
                caught = next(int(line.split()[1], 16) for line in f if line.startswith("SigCgt:"))
        except (OSError, StopIteration):
            return  # no /proc here, or the process has ended: the caller's checks say what happened
        if caught >> (signum - 1) & 1:
            return
        time.sleep(0.002)


def _llvmlite_frame_running(body: str):
    """``body`` run as code that says it is llvmlite's (its file is in llvmlite's folder)"""
    import llvmlite

    path = os.path.join(os.path.dirname(llvmlite.__file__), "callback_standin.py")
    namespace = {"signal": signal, "time": time}
    exec(compile(body, path, "exec"), namespace)
    return namespace


def test_a_signal_inside_llvmlite_code_waits_until_it_returns():
    from clothsim.cli.stopping import Interrupted, handling_stops

    body = ("def callback():\n"
            "    signal.raise_signal(signal.SIGINT)\n"
            "    end = time.monotonic() + 0.3\n"
            "    while time.monotonic() < end:\n"
            "        pass\n"
            "    return 'finished'\n")
    callback = _llvmlite_frame_running(body)["callback"]
    returned = None
    with pytest.raises(Interrupted):
        with handling_stops():
            returned = callback()  # the interrupt does not land in here
            end = time.monotonic() + 5.0
            while time.monotonic() < end:  # but here, within a retry or two
                pass
    assert returned == "finished"
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_a_signal_python_drops_in_a_weakref_callback_is_sent_again(capfd):
    """An exception raised in a weakref callback (importlib runs one as it drops a
    module's lock) is printed as "Exception ignored" and dropped; the run then went
    on as if there had been no Ctrl-C. It is raised again, outside the callback."""
    import weakref

    from clothsim.cli.stopping import Interrupted, handling_stops

    class Lock:
        pass

    def callback(_):
        signal.raise_signal(signal.SIGINT)
        end = time.monotonic() + 0.2
        while time.monotonic() < end:  # the interrupt lands in here and is dropped
            pass

    hook = sys.unraisablehook
    after = None
    with pytest.raises(Interrupted):
        with handling_stops():
            lock = Lock()
            ref = weakref.ref(lock, callback)
            del lock
            after = time.monotonic()
            end = after + 5.0
            while time.monotonic() < end:  # it comes back here, within a retry or two
                pass
    assert after is not None and ref() is None
    assert "Exception ignored" not in capfd.readouterr().err
    assert sys.unraisablehook is hook
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_a_second_ctrl_c_does_not_cut_the_first_ones_cleanup_short():
    """the first Ctrl-C raises; one more while its exception removes the outputs
    (an except or finally in the block) is let go; after the block, Python's own
    handler is back"""
    from clothsim.cli.stopping import Interrupted, handling_stops

    cleaned = False
    with pytest.raises(Interrupted):
        with handling_stops():
            try:
                signal.raise_signal(signal.SIGINT)
            finally:
                signal.raise_signal(signal.SIGINT)
                signal.raise_signal(signal.SIGTERM)
                cleaned = True
    assert cleaned
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    with pytest.raises(KeyboardInterrupt):
        signal.raise_signal(signal.SIGINT)


def test_a_signal_while_the_block_ends_is_raised_after_it_and_no_retry_follows():
    """a signal that lands while the block restores the handlers (a retry already on
    its way, say) is kept and raised after the block, not inside its exit, which
    would have left our handlers in place; a retry left for later sends nothing"""
    from clothsim.cli.stopping import RETRY_S, _Handler

    handler = _Handler()
    handler._again(signal.SIGINT)  # a retry on its way
    handler.close()
    handler(signal.SIGTERM, None)  # landing during the exit: kept, not raised
    assert handler.pending == signal.SIGTERM
    before = signal.getsignal(signal.SIGINT)
    got = []
    signal.signal(signal.SIGINT, lambda *a: got.append(a))
    try:
        time.sleep(4 * RETRY_S)
    finally:
        signal.signal(signal.SIGINT, before)
    assert got == []  # the cancelled retry sent nothing


def test_a_signal_outside_llvmlite_code_raises_at_once():
    from clothsim.cli.stopping import Interrupted, Terminated, handling_stops

    for signum, kind in ((signal.SIGINT, Interrupted), (signal.SIGTERM, Terminated)):
        reached = False
        with pytest.raises(kind):
            with handling_stops():
                signal.raise_signal(signum)
                reached = True
        assert not reached


def test_ctrl_c_inside_eval_leaves_the_interpreter_unmarked():
    """CPython marks the process as killed by Ctrl-C when an exception of exactly
    KeyboardInterrupt leaves code run by ``eval`` of a string; ours is a subclass."""
    import ctypes

    from clothsim.cli.stopping import handling_stops

    try:
        flag = ctypes.c_int.in_dll(ctypes.pythonapi, "_Py_UnhandledKeyboardInterrupt")
    except ValueError:
        pytest.skip("this Python keeps the mark elsewhere")
    before = flag.value
    try:
        with pytest.raises(KeyboardInterrupt):
            with handling_stops():
                eval("__import__('signal').raise_signal(2)")
        assert flag.value == 0
    finally:
        flag.value = before


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
