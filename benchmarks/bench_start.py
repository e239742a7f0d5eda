"""Start-up: wall time of whole ``clothsim`` commands, with numba's cache empty and full.

    python benchmarks/bench_start.py [--repeats 3] [--cold-repeats 1] [--commands render,version,help]

Each command runs as a subprocess, as a user would type it:

- ``clothsim render scenes/sphere.json -o OUT.png --overwrite`` (the first image);
- ``clothsim --version`` and ``clothsim --help`` (which should not import numba).

"cold" runs start with an empty ``NUMBA_CACHE_DIR`` (a fresh temporary folder
each time, so everything compiles); "warm" runs reuse the folder a cold run
filled. Each figure is the best of its runs (``--cold-repeats``, default 1;
``--repeats``, default 3, for warm). Prints one JSON object per command and
cache state, with whether the command said on stderr that it was compiling.
``CLOTHSIM_NO_AVX512`` and ``NUMBA_NUM_THREADS`` pass through to the commands.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import emit, machine

ROOT = Path(__file__).resolve().parent.parent
COMMANDS = ["render", "version", "help"]


def clothsim() -> list[str]:
    """the installed console script, else the package run as a module"""
    exe = shutil.which("clothsim")
    return [exe] if exe else [sys.executable, "-m", "clothsim"]


def arguments(command: str, out: Path) -> list[str]:
    if command == "render":
        scene = ROOT / "scenes" / "sphere.json"
        return ["render", str(scene) if scene.exists() else "sphere", "-o", str(out), "--overwrite"]
    return [f"--{command}"]


def timed(argv: list[str], cache: Path) -> tuple[float, str]:
    """(wall seconds, stderr) of one run with numba's cache in ``cache``"""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    start = time.perf_counter()
    run = subprocess.run(argv, check=False, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - start
    if run.returncode != 0:
        raise SystemExit(f"{' '.join(argv)} failed ({run.returncode}):\n{run.stdout[-2000:]}{run.stderr[-2000:]}")
    return wall, run.stderr


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeats", type=int, default=3, help="warm runs of each command (best kept)")
    parser.add_argument("--cold-repeats", type=int, default=1,
                        help="cold runs of each command, each with an empty cache (best kept)")
    parser.add_argument("--commands", default=",".join(COMMANDS), help=f"some of {','.join(COMMANDS)}")
    args = parser.parse_args()
    commands = [c for c in args.commands.split(",") if c]
    unknown = set(commands) - set(COMMANDS)
    if unknown:
        parser.error(f"unknown commands {sorted(unknown)}")

    info = machine()
    base = clothsim()
    portable = bool(os.environ.get("CLOTHSIM_NO_AVX512"))
    with tempfile.TemporaryDirectory(prefix="clothsim-bench-start-") as tmp:
        tmp = Path(tmp)
        for command in commands:
            argv = base + arguments(command, tmp / "out.png")
            runs = {"cold": [], "warm": []}
            notes = {"cold": [], "warm": []}
            cache = None
            for i in range(max(1, args.cold_repeats)):
                cache = tmp / f"cache-{command}-{i}"
                cache.mkdir()
                wall, err = timed(argv, cache)
                runs["cold"].append(wall)
                notes["cold"].append("compiling" in err)
            for _ in range(max(1, args.repeats)):
                wall, err = timed(argv, cache)
                runs["warm"].append(wall)
                notes["warm"].append("compiling" in err)
            for state in ("cold", "warm"):
                shown = [a.replace(str(ROOT) + os.sep, "") for a in arguments(command, Path("OUT.png"))]
                emit({"bench": "start", "command": "clothsim " + " ".join(shown),
                      "cache": state, "wall_s": round(min(runs[state]), 3),
                      "runs_s": [round(r, 3) for r in runs[state]],
                      "said_compiling": any(notes[state]), "portable": portable, **info})


if __name__ == "__main__":
    main()
