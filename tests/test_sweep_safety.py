"""A sweep's folder is safe: one sweep at a time writes into it, a killed sweep
stops its workers and keeps its finished runs, and a run stopped between its
image and its record is redone."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from clothsim.cli import main
from clothsim.outputs import OutputError
from clothsim.sweep.outdir import LOCK, SweepDir
from clothsim.sweep.plan import plan_runs
from clothsim.sweep.runner import RunResult

from .conftest import small_scene


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_a_second_sweep_into_a_locked_folder_is_refused(tmp_path):
    out = SweepDir(tmp_path / "sweep")
    with out.lock():
        assert (tmp_path / "sweep" / LOCK).read_text().strip() == str(os.getpid())
        with pytest.raises(OutputError, match=f"another sweep \\(process {os.getpid()}\\)"):
            with SweepDir(tmp_path / "sweep").lock():
                pass
    assert not (tmp_path / "sweep" / LOCK).exists()  # released at the end


def test_a_lock_left_by_a_dead_sweep_is_taken_over(tmp_path):
    folder = tmp_path / "sweep"
    folder.mkdir()
    (folder / LOCK).write_text(f"{_dead_pid()}\n")
    with SweepDir(folder).lock():
        assert (folder / LOCK).read_text().strip() == str(os.getpid())
    assert not (folder / LOCK).exists()


def test_the_sweep_command_refuses_a_folder_another_sweep_holds_in_one_line(tmp_path, write_scene, capsys):
    folder = tmp_path / "sweep"
    folder.mkdir()
    holder = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        (folder / LOCK).write_text(f"{holder.pid}\n")
        code = main(["sweep", str(write_scene(small_scene())), "--vary", "cloth.ks=500,5000", "--seconds", "0.05",
                     "--size", "64x64", "--workers", "1", "--no-progress", "-o", str(folder)])
    finally:
        holder.kill()
        holder.wait()
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("clothsim: error:") and f"process {holder.pid}" in err[0], err
    assert sorted(p.name for p in folder.iterdir()) == [LOCK]  # nothing written, the other's lock kept


def test_a_sweep_folder_under_a_file_is_refused_before_any_run(tmp_path, write_scene, capsys):
    (tmp_path / "f").write_text("x")
    code = main(["sweep", str(write_scene(small_scene())), "--vary", "cloth.ks=500,5000", "--no-progress",
                 "-o", str(tmp_path / "f" / "sweep")])
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "is not a folder" in err[0], err


def test_a_run_stopped_between_its_image_and_its_record_is_redone_not_refused(tmp_path, monkeypatch):
    specs = plan_runs(small_scene(), "s.json", ["cloth.ks=500,5000"], 0.1, "Phong", (64, 64))
    out = SweepDir(tmp_path / "sweep")
    import clothsim.sweep.outdir as outdir

    real = outdir.write_atomic

    def stop_at_the_record(path, writer, *args):
        if Path(path).suffix == ".json" and "pending" not in json.dumps(_written(writer)):
            raise KeyboardInterrupt  # killed after the image, before the record
        real(path, writer, *args)

    def _written(writer):
        class Probe:
            text = ""

            def write_text(self, text):
                self.text = text
        probe = Probe()
        writer(probe)
        return probe.text

    monkeypatch.setattr(outdir, "write_atomic", stop_at_the_record)
    with pytest.raises(KeyboardInterrupt):
        out.save(RunResult(specs[0], {"sag": 0.1}, png=b"png", obj="o"))
    monkeypatch.setattr(outdir, "write_atomic", real)
    assert (tmp_path / "sweep" / f"{specs[0].name}.png").exists()
    todo, done = SweepDir(tmp_path / "sweep").plan(specs)  # no "holds files of other runs"
    assert [s.name for s in todo] == [s.name for s in specs] and done == []
    out.save(RunResult(specs[0], {"sag": 0.1}, png=b"png", obj="o"))
    todo, done = SweepDir(tmp_path / "sweep").plan(specs)
    assert [s.name for s in done] == [specs[0].name] and [s.name for s in todo] == [specs[1].name]


def _children(pid: int) -> list[int]:
    out = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                out.append(int(entry.name))
    return out


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def _wait_for_first_record(proc, out: Path, limit_s: float = 240) -> dict:
    """the record of run 000 once it is finished (not pending), the sweep still running"""
    deadline = time.monotonic() + limit_s
    record = {}
    while ("frames" not in record or record.get("pending")) and time.monotonic() < deadline:
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.2)
        for path in (out / "records").glob("000_*.json"):
            try:
                record = json.loads(path.read_text())
            except (OSError, ValueError):
                pass
    return record


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="finds the workers through /proc")
@pytest.mark.parametrize("sig,code", [(signal.SIGTERM, 143), (signal.SIGINT, 130)], ids=["SIGTERM", "SIGINT"])
def test_a_killed_sweep_stops_its_workers_and_keeps_its_finished_runs(tmp_path, write_scene, sig, code):
    """the first run (a 16x4 cloth) finishes; the two others (16x400, 60 s) are still
    running when the sweep is killed: it exits with the signal's code, no worker
    is left, the finished run's record is kept, and a rerun skips it"""
    scene = write_scene(small_scene())
    out = tmp_path / "sweep"
    argv = [sys.executable, "-m", "clothsim", "sweep", str(scene), "--vary",
            "cloth.num_height_points=4,400,400",
            "--seconds", "60", "--size", "64x64", "--workers", "2", "--no-progress", "-o", str(out)]
    env = dict(os.environ, CLOTHSIM_PREWARM="0")
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                            start_new_session=True)  # a signal to the sweep alone, not to its group
    try:
        record = _wait_for_first_record(proc, out)
        workers = _children(proc.pid)
        assert workers and all(_alive(w) for w in workers)
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == code, err
    assert "clothsim: interrupted" in err and "Traceback" not in err, err
    deadline = time.monotonic() + 10
    while any(_alive(w) for w in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not [w for w in workers if _alive(w)], "a worker outlived the sweep"
    assert not record.get("pending") and record["frames"] > 0 and not record["error"], record
    assert not (out / LOCK).exists()
    names = sorted(p.name for p in (out / "records").glob("*.json"))
    assert names[0].startswith("000_")
    todo, done = SweepDir(out).plan(plan_runs(json.loads(scene.read_text()), str(scene),
                                              ["cloth.num_height_points=4,400,400"], 60.0, "Phong", (64, 64)))
    assert [s.index for s in done] == [0] and [s.index for s in todo] == [1, 2]


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="finds the workers through /proc")
def test_a_terminal_ctrl_c_stops_a_sweep_without_a_workers_traceback(tmp_path, write_scene):
    """a terminal's Ctrl-C reaches the whole process group: the sweep and its
    workers, one of them idle (its run done, none left to take). The workers leave
    the stop to the sweep: one line, exit code 130, no traceback, no worker left"""
    scene = write_scene(small_scene())
    out = tmp_path / "sweep"
    argv = [sys.executable, "-m", "clothsim", "sweep", str(scene), "--vary", "cloth.num_height_points=4,400",
            "--seconds", "60", "--size", "64x64", "--workers", "2", "--no-progress", "-o", str(out)]
    env = dict(os.environ, CLOTHSIM_PREWARM="0")
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                            start_new_session=True)  # its own group, as a terminal gives a command
    try:
        record = _wait_for_first_record(proc, out)
        assert record.get("frames"), "the first run did not finish"
        workers = _children(proc.pid)
        time.sleep(0.5)  # the first run's worker back waiting on the pool's queue
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 130, err
    lines = [line for line in err.strip().splitlines() if not line.startswith("clothsim: compiling")]
    assert lines == ["clothsim: interrupted"], err
    deadline = time.monotonic() + 10
    while any(_alive(w) for w in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not [w for w in workers if _alive(w)], "a worker outlived the sweep"


def _cluster_work(client) -> tuple[int, int]:
    """(tasks the scheduler holds, tasks executing on the workers)"""
    held = client.run_on_scheduler(lambda dask_scheduler: len(dask_scheduler.tasks))
    executing = sum(client.run(lambda dask_worker: dask_worker.state.executing_count).values())
    return held, executing


@pytest.mark.parametrize("sig,code", [(signal.SIGTERM, 143), (signal.SIGINT, 130)], ids=["SIGTERM", "SIGINT"])
def test_an_interrupted_dask_sweep_stops_its_runs_on_the_cluster_and_keeps_its_finished_ones(
        tmp_path, write_scene, dask_cluster, sig, code):
    """--scheduler: the cluster is the user's (its workers are not the sweep's to
    end), but the sweep's runs are: killed while two 60 s runs of a 16x400 cloth
    execute, it exits with the signal's code, its queued run leaves the
    scheduler, the running ones stop within seconds (they would run for
    minutes), the workers stay up, the finished run is kept and a rerun
    skips it"""
    from distributed import Client

    scene = write_scene(small_scene())
    out = tmp_path / "sweep"
    vary = "cloth.num_height_points=4,400,400,400"
    argv = [sys.executable, "-m", "clothsim", "sweep", str(scene), "--vary", vary, "--seconds", "60",
            "--size", "64x64", "--no-progress", "-o", str(out), "--scheduler", dask_cluster]
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    with Client(dask_cluster, timeout="30s") as client:
        try:
            record = _wait_for_first_record(proc, out)
            deadline = time.monotonic() + 60
            while _cluster_work(client)[1] < 2 and time.monotonic() < deadline:
                time.sleep(0.2)
            assert _cluster_work(client)[1] == 2, "both workers should be running a long run"
            proc.send_signal(sig)
            _, err = proc.communicate(timeout=60)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        assert proc.returncode == code, err
        assert "clothsim: interrupted" in err and "Traceback" not in err, err
        deadline = time.monotonic() + 20
        while _cluster_work(client) != (0, 0) and time.monotonic() < deadline:
            time.sleep(0.2)
        assert _cluster_work(client) == (0, 0), "a run of the stopped sweep went on on the cluster"
        assert len(client.scheduler_info()["workers"]) == 2  # the user's workers are still there
    assert not record.get("pending") and record["frames"] > 0 and not record["error"], record
    assert not (out / LOCK).exists()
    todo, done = SweepDir(out).plan(plan_runs(json.loads(scene.read_text()), str(scene), [vary], 60.0,
                                              "Phong", (64, 64)))
    assert [s.index for s in done] == [0] and [s.index for s in todo] == [1, 2, 3]
