"""Shared helpers: small scenes built in code, so tests stay fast."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

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
