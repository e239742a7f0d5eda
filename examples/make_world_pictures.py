"""Render the pictures of the moving-world scenes in docs/: one still of each
(docs/scene_<name>.png) and a strip of six frames of the windy flag over one
second (docs/flag_strip.png). Headless; about a minute on one core.

    python examples/make_world_pictures.py [OUT_DIR]   (default: docs/)
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from clothsim import Simulation
from clothsim.render.camera import OrbitCamera
from clothsim.render.renderer import DrawSettings, Renderer
from clothsim.render.scene_view import SimulationView
from clothsim.standard_scenes import scene_path

SIZE = (480, 360)
STILLS = {
    # name: (seconds, target, azimuth, elevation, distance)
    "table_pull": (2.9, (1.3, 0.4, 0.5), 30.0, 25.0, 3.0),
    "spinning_sphere": (2.5, (0.5, 0.4, 0.5), 20.0, 30.0, 1.5),
    "torus_drape": (3.0, (0.5, 0.3, 0.5), 25.0, 25.0, 1.7),
    "windy_flag": (3.0, (0.5, 0.2, 0.0), 25.0, 15.0, 2.0),
    "curtain": (2.7, (0.8, 0.5, 0.0), 20.0, 12.0, 2.8),
}
STRIP = {"scene": "windy_flag", "start": 2.0, "frames": 6, "every": 15, "size": (240, 200),
         "camera": ((0.5, 0.3, 0.0), 25.0, 15.0, 1.7)}
"""six frames 15 simulation frames (1/6 s) apart, from 2 s on"""


def camera_for(target, azimuth: float, elevation: float, distance: float) -> OrbitCamera:
    return OrbitCamera(target=np.array(target, dtype=float), azimuth=azimuth, elevation=elevation,
                       distance=distance)


def still(renderer: Renderer, name: str, seconds: float, *view) -> np.ndarray:
    sim = Simulation.from_file(scene_path(name))
    sim.run(seconds)
    frame = SimulationView(renderer, sim)
    frame.sync()
    return renderer.render(camera_for(*view), DrawSettings())


def strip(renderer: Renderer) -> np.ndarray:
    sim = Simulation.from_file(scene_path(STRIP["scene"]))
    sim.run(STRIP["start"])
    view = SimulationView(renderer, sim)
    # one camera for every frame, so that the flag moves and the pole does not
    cam = camera_for(*STRIP["camera"])
    tiles = []
    for k in range(STRIP["frames"]):
        if k:
            for _ in range(STRIP["every"]):
                sim.step()
        view.sync()
        tiles.append(renderer.render(cam, DrawSettings()))
    gap = np.full((tiles[0].shape[0], 4, tiles[0].shape[2]), 255, dtype=tiles[0].dtype)
    row = [t for tile in tiles for t in (tile, gap)][:-1]
    return np.concatenate(row, axis=1)


def main(argv: list[str]) -> int:
    from PIL import Image

    out = Path(argv[0]) if argv else Path(__file__).resolve().parent.parent / "docs"
    out.mkdir(parents=True, exist_ok=True)
    renderer = Renderer(size=SIZE)
    for name, (seconds, *view) in STILLS.items():
        path = out / f"scene_{name}.png"
        Image.fromarray(still(renderer, name, seconds, *view)).save(path, optimize=True)
        print(path)
    renderer.release()
    renderer = Renderer(size=STRIP["size"])
    path = out / "flag_strip.png"
    Image.fromarray(strip(renderer)).save(path, optimize=True)
    renderer.release()
    print(path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
