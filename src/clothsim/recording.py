"""Per-frame exports: an OBJ sequence for Blender/Houdini, and the whole-run files
(a NumPy trajectory, USD, a web player) written from the frames once the run ends."""

from __future__ import annotations

import io
import json
import queue
import threading
from pathlib import Path

import numpy as np

from .export.obj import model_objects
from .export.objseq import ObjSequence
from .outputs import OutputError, atomic_path, check_output_folder, check_writable
from .simulation import Simulation
from .trajectory import Trajectory, TrajectoryRecorder


def npz_arrays(traj: Trajectory) -> dict[str, np.ndarray]:
    """The arrays of the NumPy export (see :class:`FrameRecorder`)."""
    parts = traj.parts
    return {"positions": traj.positions, "times": traj.times, "triangles": traj.triangles, "uvs": traj.uvs,
            "scene": np.array(json.dumps(traj.scene)),
            "cloth_names": np.array([c.name for c in parts], dtype=str),
            "cloth_start": np.array([c.start for c in parts] + [parts[-1].stop], dtype=np.int64),
            "cloth_triangle_start": np.array([c.tri_start for c in parts] + [parts[-1].tri_stop], dtype=np.int64)}


def _write_npz(path: Path, traj: Trajectory) -> None:
    buf = io.BytesIO()
    # uncompressed: deflate shrank float positions by a sixth and took longer than the run
    np.savez(buf, **npz_arrays(traj))
    path.write_bytes(buf.getvalue())


def _write_usd(path: Path, traj: Trajectory) -> None:
    from .export.usd import write_usd

    write_usd(path, traj)


def _write_player(path: Path, traj: Trajectory) -> None:
    from .export.web import write_player

    write_player(path, traj)


WRITERS = {"npz": _write_npz, "usd": _write_usd, "html": _write_player}
"""the whole-run formats: each writer takes the (temporary) path to write and the trajectory"""

class _StageFeed:
    """A USD stage built in a thread while the run goes on: each frame's
    positions go in as they come (the substeps release the GIL), so that only
    the file itself is left to write when the run ends."""

    def __init__(self, start: Trajectory) -> None:
        self._queue: queue.Queue = queue.Queue()
        self._stage = None
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._work, args=(start,), daemon=True)
        self._thread.start()

    def _work(self, start: Trajectory) -> None:
        try:
            from .export.usd import StageBuilder

            self._stage = StageBuilder(start)
            while (positions := self._queue.get()) is not None:
                self._stage.add(positions)
        except BaseException as exc:  # raised again in the caller's thread by finish()
            self._error = exc

    def add(self, positions: np.ndarray) -> None:
        self._queue.put(positions)

    def finish(self, path: Path, traj: Trajectory) -> None:
        self._queue.put(None)
        self._thread.join()
        if self._error is not None:
            raise self._error
        self._stage.finish(path, traj)


class FrameRecorder:
    """Called after every frame; writes or collects what was asked for.

    ``sequence_dir`` gets ``frame_0000.obj`` (the start) onward. ``outputs`` maps
    a whole-run format of :data:`WRITERS` to its path: ``npz`` gets
    ``positions[frame, point, 3]`` [m] (frame 0 is the start; every cloth's
    points in scene order), ``times`` [s], ``triangles`` (model point
    indices), ``uvs``, the scene as JSON text (``scene``) and the cloths:
    ``cloth_names`` (K,), ``cloth_start`` (K+1,: cloth k's points are
    ``cloth_start[k]:cloth_start[k+1]``) and ``cloth_triangle_start`` (K+1,,
    likewise its triangles); ``usd`` a time-sampled USD stage (one mesh per
    cloth); ``html`` a self-contained web player. The OBJ sequence has one
    ``o`` object per cloth when there are several; each frame's file is
    written whole as the run goes and, without ``overwrite``, never placed
    over a file that appeared at its name meanwhile (OutputError, from the
    frame after or from :meth:`finish`). Every whole-run path is checked
    before the run and written whole, or not at all, after it.
    """

    def __init__(self, sim: Simulation, sequence_dir: str | None = None, npz_path: str | None = None,
                 overwrite: bool = False, outputs: dict[str, str] | None = None) -> None:
        self.sequence_dir = Path(sequence_dir) if sequence_dir else None
        self.overwrite = overwrite
        self.outputs = {kind: Path(p) for kind, p in (outputs or {}).items() if p}
        if npz_path:
            self.outputs["npz"] = Path(npz_path)
        for kind, path in self.outputs.items():
            if kind not in WRITERS:
                raise ValueError(f"no writer for {kind!r}")
            check_writable(path, overwrite)
        if self.sequence_dir:
            check_output_folder(self.sequence_dir)
            if self.sequence_dir.is_dir() and any(self.sequence_dir.glob("frame_*.obj")) and not overwrite:
                raise OutputError(f"{self.sequence_dir}: already holds frame_*.obj files; "
                                  "pass --overwrite to replace them")
            self.sequence_dir.mkdir(parents=True, exist_ok=True)
        self._frames = TrajectoryRecorder(sim) if self.outputs else None
        self._stage = _StageFeed(self._frames.trajectory(sim)) if "usd" in self.outputs else None
        if self._stage is not None:
            self._stage.add(self._frames.last)
        self.active = bool(self.sequence_dir or self.outputs)
        self._sequence = None
        if self.sequence_dir:
            self._sequence = ObjSequence(self.sequence_dir, sim.model.uvs, sim.model.triangles,
                                         objects=model_objects(sim.model), overwrite=overwrite)
            self._sequence.write(sim.frame, sim.positions)  # normals: computed by its thread

    def __call__(self, sim: Simulation) -> None:
        if self._sequence is not None:
            self._sequence.write(sim.frame, sim.positions)
        if self._frames is not None:
            self._frames(sim)
        if self._stage is not None:
            self._stage.add(self._frames.last)

    def finish(self, sim: Simulation) -> None:
        if self._sequence is not None:
            self._sequence.close()  # the OBJ files are written in the background: wait for them
        if self._frames is None:
            return
        traj = self._frames.trajectory(sim)
        for kind, path in self.outputs.items():
            with atomic_path(path, self.overwrite) as tmp:
                if kind == "usd":
                    self._stage.finish(tmp, traj)
                else:
                    WRITERS[kind](tmp, traj)
