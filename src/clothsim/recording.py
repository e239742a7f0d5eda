"""Per-frame exports: an OBJ sequence for Blender/Houdini, a NumPy trajectory."""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np

from .export import write_obj
from .outputs import OutputError, atomic_path, check_writable
from .simulation import Simulation


class FrameRecorder:
    """Called after every frame; writes or collects what was asked for.

    ``sequence_dir`` gets ``frame_0000.obj`` (the start) onward; ``npz_path``
    gets ``positions[frame, point, 3]`` (frame 0 is the start), ``times``,
    ``triangles``, ``uvs`` and the scene as JSON text.
    """

    def __init__(self, sim: Simulation, sequence_dir: str | None = None, npz_path: str | None = None,
                 overwrite: bool = False) -> None:
        self.sequence_dir = Path(sequence_dir) if sequence_dir else None
        self.npz_path = Path(npz_path) if npz_path else None
        if self.npz_path:
            check_writable(self.npz_path, overwrite)
        if self.sequence_dir:
            if self.sequence_dir.exists() and not self.sequence_dir.is_dir():
                raise OutputError(f"{self.sequence_dir}: exists and is not a folder")
            if self.sequence_dir.is_dir() and any(self.sequence_dir.glob("frame_*.obj")) and not overwrite:
                raise OutputError(f"{self.sequence_dir}: already holds frame_*.obj files; "
                                  "pass --overwrite to replace them")
            self.sequence_dir.mkdir(parents=True, exist_ok=True)
        self._frames: list[np.ndarray] = []
        self._times: list[float] = []
        self.active = bool(self.sequence_dir or self.npz_path)
        if self.active:
            self(sim)

    def __call__(self, sim: Simulation) -> None:
        if self.sequence_dir:
            write_obj(self.sequence_dir / f"frame_{sim.frame:04d}.obj", sim.positions, sim.normals,
                      sim.model.uvs, sim.model.triangles)
        if self.npz_path:
            self._frames.append(sim.positions.copy())
            self._times.append(sim.time)

    def finish(self, sim: Simulation) -> None:
        if not self.npz_path:
            return
        buf = io.BytesIO()
        np.savez_compressed(buf, positions=np.stack(self._frames), times=np.array(self._times),
                            triangles=np.asarray(sim.model.triangles), uvs=np.asarray(sim.model.uvs),
                            scene=np.array(json.dumps(sim.scene.to_dict())))
        with atomic_path(self.npz_path) as tmp:
            tmp.write_bytes(buf.getvalue())
