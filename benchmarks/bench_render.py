"""Rendering speed: milliseconds per 800x800 frame (simulation excluded) and per video frame.

    python benchmarks/bench_render.py [--frames 30]

Prints one JSON object per measurement: the Phong shader on the 50x50 and
200x200 cloth draped over the sphere (upload + draw + read back), and the
wall time per frame of a GIF/MP4 render (simulation, drawing and encoding).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import emit, machine, peak_rss_mib  # noqa: E402

from clothsim import Simulation  # noqa: E402
from clothsim.cli import main as cli  # noqa: E402
from clothsim.render.renderer import DrawSettings, Renderer  # noqa: E402
from clothsim.render.scene_view import SimulationView, default_camera  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def frame_ms(n: int, frames: int, shader: str) -> float:
    sim = Simulation.from_file(ROOT / "scenes" / "sphere.json",
                               [f"cloth.num_width_points={n}", f"cloth.num_height_points={n}"])
    sim.step()
    renderer = Renderer(size=(800, 800))
    view = SimulationView(renderer, sim)
    cam = default_camera(sim)
    settings = DrawSettings(shader=shader)
    view.sync()
    renderer.render(cam, settings)  # compile and warm up
    times = []
    for _ in range(frames):
        start = time.perf_counter()
        view.sync()
        renderer.render(cam, settings)
        times.append(time.perf_counter() - start)
    renderer.release()
    return 1e3 * statistics.median(times)


def video_ms(suffix: str, seconds: float) -> float:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / f"v.{suffix}"
        start = time.perf_counter()
        cli(["render", str(ROOT / "scenes" / "sphere.json"), "-o", str(out), "--seconds", str(seconds),
             "--fps", "30", "--no-progress"])
        wall = time.perf_counter() - start
    return 1e3 * wall / (round(seconds * 30) + 1)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=30)
    args = ap.parse_args()
    info = machine()
    import moderngl

    for n in (50, 200):
        emit({"bench": "render_frame", "shader": "Phong", "grid": f"{n}x{n}", "size": "800x800",
              "ms_per_frame": round(frame_ms(n, args.frames, "Phong"), 2), "moderngl": moderngl.__version__,
              "peak_rss_mib": round(peak_rss_mib(), 1), **info})
    for suffix in ("mp4", "gif"):
        emit({"bench": "render_video", "format": suffix, "size": "800x800", "scene": "sphere",
              "ms_per_video_frame": round(video_ms(suffix, 1.0), 1), "peak_rss_mib": round(peak_rss_mib(), 1),
              **info})


if __name__ == "__main__":
    main()
