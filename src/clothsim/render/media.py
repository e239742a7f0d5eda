"""Rendered frames into files: one image, or an animation stepped and drawn frame by frame.

Importing this module loads no GL, image or array library (each function
imports what it uses), so a front end may read the suffix sets at once.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from ..outputs import atomic_path

if TYPE_CHECKING:
    import numpy as np

    from ..simulation import Simulation
    from .camera import OrbitCamera
    from .renderer import DrawSettings
    from .scene_view import SimulationView

IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg"}
VIDEO_SUFFIXES = {".mp4", ".gif"}


def save_image(path: str | Path, image: np.ndarray, overwrite: bool = True) -> None:
    """Write an RGB image, shape (H, W, 3) uint8, as JPEG or PNG by the suffix; whole or not at all
    (without ``overwrite``, never over a file that appeared meanwhile)."""
    from PIL import Image

    with atomic_path(path, overwrite) as tmp:
        Image.fromarray(image).save(tmp, format="JPEG" if Path(path).suffix.lower() in {".jpg", ".jpeg"} else "PNG")


def write_animation(path: str | Path, sim: Simulation, view: SimulationView, camera: OrbitCamera,
                    settings: DrawSettings, frames: int, every: int,
                    on_frame: Callable[[Simulation], None] | None = None,
                    on_drawn: Callable[[], None] | None = None, overwrite: bool = True) -> int:
    """Step ``sim`` ``frames`` frames and write an MP4 or GIF (by the suffix) of the
    start and of every ``every``-th frame; return how many frames were drawn.

    The video plays at ``frames_per_sec / every`` frames a second, i.e. in real
    time. ``on_frame(sim)`` runs after each simulated frame, ``on_drawn()``
    after each drawn one. The file appears only once it is complete (without
    ``overwrite``, never over a file that appeared meanwhile).
    """
    import imageio.v2 as imageio

    every = max(1, int(every))
    fps = sim.params.frames_per_sec / every
    kwargs = {"fps": fps, "macro_block_size": 1} if Path(path).suffix.lower() == ".mp4" \
        else {"duration": 1000.0 / fps, "loop": 0}
    drawn = 0
    with atomic_path(path, overwrite) as tmp:
        writer = imageio.get_writer(tmp, **kwargs)
        try:
            def draw() -> None:
                nonlocal drawn
                view.sync()
                writer.append_data(view.renderer.render(camera, settings))
                drawn += 1
                if on_drawn is not None:
                    on_drawn()

            draw()
            for frame in range(1, frames + 1):
                sim.step()
                if on_frame is not None:
                    on_frame(sim)
                if frame % every == 0:
                    draw()
        finally:
            writer.close()
    return drawn
