"""What the exports cost on top of the simulation: a 5 s run of the 50x50 ``sphere``
scene (451 frames of 2,500 points) alone, and with each export of
``clothsim simulate``/``render``: the OBJ sequence (``--export-sequence``), NPZ
(``--export-npz``), USD (``--export-usd``, where ``clothsim.export.usd`` and
``pxr`` import) and the web player (``-o OUT.html``, where
``clothsim.export.web`` does).

Each run is timed as the front ends do it, from the recorder's creation
(``FrameRecorder``, which checks the paths) to the end of its ``finish()`` (the
whole-run files written, the last OBJ file renamed into place), stepping on one
thread. The rounds run every variant back to back, after a warm-up round that
compiles the kernels; each figure is the best of ``--repeats`` rounds, and the
overhead is the variant's best less the simulation's best. Beside the wall
time each line gives the CPU time of the main thread (what the simulation's
thread spent, the exports' share in it included: the overhead where a core is
free for the writing threads) and of the whole process.

Prints one JSON object per variant (``"bench": "export"``):

    python benchmarks/bench_export.py [--repeats 3] [--seconds 5] [--size 50] [--dir TMP] [--only obj,npz]
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import emit, machine, peak_rss_mib  # noqa: E402

from clothsim import Simulation  # noqa: E402
from clothsim.recording import FrameRecorder  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def _has(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is not None
    except ImportError:
        return False


def variants() -> dict[str, dict]:
    """name: FrameRecorder keyword arguments, with "OUT" for the output's path"""
    out = {"simulation": {}, "obj": {"sequence_dir": "OUT"}, "npz": {"outputs": {"npz": "OUT.npz"}}}
    if _has("clothsim.export.usd") and _has("pxr"):
        out["usd"] = {"outputs": {"usd": "OUT.usdc"}}
    if _has("clothsim.export.web"):
        out["html"] = {"outputs": {"html": "OUT.html"}}
    return out


def _fill(kwargs: dict, out: str) -> dict:
    def sub(v):
        if isinstance(v, dict):
            return {k: sub(x) for k, x in v.items()}
        return v.replace("OUT", out) if isinstance(v, str) else v
    return sub(kwargs)


def _size(path: Path) -> int:
    if path.is_dir():
        return sum(p.stat().st_size for p in path.iterdir())
    return path.stat().st_size if path.exists() else 0


def run_once(kwargs: dict, work: Path, size: int, seconds: float) -> tuple[float, float, float, int, int]:
    """(wall, main thread's CPU and the process's CPU seconds of the run with its
    exports, frames, bytes written)"""
    out = work / "out"
    sim = Simulation.from_file(ROOT / "scenes" / "sphere.json",
                               [f"cloth.num_width_points={size}", f"cloth.num_height_points={size}"], threads=1)
    start, cpu, main_cpu = time.perf_counter(), time.process_time(), time.thread_time()
    recorder = FrameRecorder(sim, **_fill(kwargs, str(out)), overwrite=True) if kwargs else None
    frames = sim.run(seconds, recorder)
    if recorder is not None:
        recorder.finish(sim)
    wall = time.perf_counter() - start
    main_cpu, cpu = time.thread_time() - main_cpu, time.process_time() - cpu
    written = sum(_size(p) for p in work.iterdir())
    for p in work.iterdir():
        shutil.rmtree(p) if p.is_dir() else p.unlink()
    return wall, main_cpu, cpu, frames, written


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=5.0)
    ap.add_argument("--size", type=int, default=50)
    ap.add_argument("--dir", default=None, help="where the files go (default: the system's temporary folder)")
    ap.add_argument("--only", default=None, help="comma-separated variants (the simulation alone always runs)")
    args = ap.parse_args()
    chosen = variants()
    if args.only:
        keep = {"simulation", *args.only.split(",")}
        chosen = {k: v for k, v in chosen.items() if k in keep}
    work = Path(tempfile.mkdtemp(prefix="clothsim-bench-export-", dir=args.dir))
    try:
        for kwargs in chosen.values():  # warm-up: compiles, imports pxr
            run_once(kwargs, work, args.size, 0.1)
        best = {k: [float("inf")] * 3 for k in chosen}
        info = {}
        for _ in range(args.repeats):
            for name, kwargs in chosen.items():
                *times, frames, written = run_once(kwargs, work, args.size, args.seconds)
                best[name] = [min(a, b) for a, b in zip(best[name], times)]
                info[name] = (frames, written)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    base, base_main, base_cpu = best["simulation"]
    common = machine()
    for name in chosen:
        frames, written = info[name]
        wall, main_cpu, cpu = best[name]
        emit({"bench": "export", "variant": name, "scene": "sphere", "grid": f"{args.size}x{args.size}",
              "points": args.size ** 2, "frames": frames + 1, "seconds_simulated": args.seconds,
              "wall_s": round(wall, 4), "overhead_s": round(wall - base, 4),
              "overhead_pct": round(100.0 * (wall - base) / base, 1),
              "main_thread_cpu_s": round(main_cpu, 4),
              "main_thread_overhead_pct": round(100.0 * (main_cpu - base_main) / base_main, 1),
              "process_cpu_s": round(cpu, 4), "cpus": os.cpu_count(), "bytes": written,
              "repeats": args.repeats, "peak_rss_mib": round(peak_rss_mib(), 1), **common})


if __name__ == "__main__":
    main()
