"""Trajectory: the frames of a run, in memory, for the exporters that take a whole
run and for notebooks; :func:`record` runs a simulation and gives its frames."""

from __future__ import annotations

import copy
import html
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .mesh import compute_normals
from .scene_limits import run_frames


@dataclass
class Trajectory:
    """The positions of every frame of a run and what they need to be drawn elsewhere."""

    positions: np.ndarray
    """point positions [m] of each recorded frame, float64 (F, N, 3); frame 0 is the
    state when recording began (the start, for a fresh simulation)"""
    times: np.ndarray
    """simulated time of each frame [s], float64 (F,)"""
    triangles: np.ndarray
    """vertex indices, int32 (T, 3), counter-clockwise seen from the front"""
    uvs: np.ndarray
    """texture coordinates, float32 (N, 2)"""
    frames_per_sec: float
    """the frames per simulated second the times step by"""
    spheres: list = field(default_factory=list)
    """the spheres as they stood (``SphereSpec``: origin, radius, friction)"""
    planes: list = field(default_factory=list)
    """the planes as they stood (``PlaneSpec``: point, unit normal, friction)"""
    scene: dict = field(default_factory=dict)
    """the scene as JSON data"""
    name: str = "cloth"
    """the scene's name (its file's stem)"""
    description: str = ""
    """the parameters in one line"""
    cloths: tuple = ()
    """the model's cloths in scene order (:class:`~clothsim.model.Cloth`: ``name``,
    points ``start:stop``, triangles ``tri_start:tri_stop``); empty: one cloth of
    every point and triangle (see :attr:`parts`)"""

    @property
    def num_frames(self) -> int:
        return self.positions.shape[0]

    @property
    def parts(self) -> tuple:
        """:attr:`cloths`, or when it is empty one cloth named ``cloth`` holding
        every point and triangle: what the exporters split the frames by"""
        if self.cloths:
            return tuple(self.cloths)
        from .model import Cloth

        n, t = self.positions.shape[1], len(self.triangles)
        return (Cloth(0, n, 0.0, 0.0, None, 0.0, 0.0, 0, t, "cloth"),)

    def normals(self, frame: int) -> np.ndarray:
        """unit vertex normals of ``frame``, float64 (N, 3)"""
        return compute_normals(self.positions[frame], self.triangles)

    def show(self, width: int = 640, height: int = 400, **look) -> Player:
        """The web player of these frames, for a notebook (see :class:`Player`)."""
        return Player(self, width, height, **look)

    def _repr_html_(self) -> str:
        return self.show()._repr_html_()


class Player:
    """The web player of a :class:`Trajectory` (``clothsim.export.web``), as a
    notebook shows it: ``_repr_html_`` gives the page inside an ``<iframe
    srcdoc=...>`` of ``width`` x ``height`` CSS pixels, so that it keeps its own
    scripts, styles and element ids beside other players in the same notebook,
    and plays offline like the file ``clothsim render -o OUT.html`` writes.
    ``look``: the keywords of :func:`clothsim.export.web.player_html` (color,
    camera, phong, light, title)."""

    def __init__(self, trajectory: Trajectory, width: int = 640, height: int = 400, **look) -> None:
        for name, value in (("width", width), ("height", height)):
            if not isinstance(value, (int, np.integer)) or not 16 <= value <= 16384:
                raise ValueError(f"{name}: expected a whole number of CSS pixels in 16..16384, got {value!r}")
        self.trajectory = trajectory
        self.width = int(width)
        self.height = int(height)
        self.look = look
        self._html: str | None = None

    @property
    def html(self) -> str:
        """the player's self-contained page (made once)"""
        if self._html is None:
            from .export.web import player_html

            self._html = player_html(self.trajectory, **self.look)
        return self._html

    def save(self, path: str | Path) -> None:
        """Write the page to ``path`` (an ``.html`` that plays opened from disk)."""
        Path(path).write_text(self.html, encoding="utf-8")

    def _repr_html_(self) -> str:
        return (f'<iframe class="clothsim-player" srcdoc="{html.escape(self.html, quote=True)}" '
                f'width="{self.width}" height="{self.height}" style="border:0;max-width:100%" '
                f'sandbox="allow-scripts" title="{html.escape(self.trajectory.name, quote=True)}"></iframe>')


def _trajectory(sim, positions: np.ndarray, times: np.ndarray, frames_per_sec: float) -> Trajectory:
    """a Trajectory of ``sim``'s mesh, colliders (as they stand now) and scene"""
    source = sim.scene.source
    name = "cloth" if source is None else str(source).replace("\\", "/").rsplit("/", 1)[-1]
    return Trajectory(positions=positions, times=times,
                      triangles=np.asarray(sim.model.triangles), uvs=np.asarray(sim.model.uvs),
                      frames_per_sec=float(frames_per_sec),
                      spheres=copy.deepcopy(sim.spheres), planes=copy.deepcopy(sim.planes),
                      scene=sim.scene.to_dict(), name=name.removesuffix(".json"),
                      description=sim.params.describe(), cloths=tuple(sim.model.cloths))


def record(sim, seconds: float, every: int = 1) -> Trajectory:
    """Run ``sim`` (a :class:`~clothsim.Simulation`) ``seconds`` more of simulated time
    and return its frames.

    The run is ``round(seconds * frames_per_sec)`` whole frames, as
    :meth:`Simulation.run` counts them. The trajectory's frame 0 is the state
    when ``record`` was called (the start, for a fresh simulation); then comes
    every ``every``-th frame stepped, so there are ``frames // every + 1`` of
    them, ``every / frames_per_sec`` seconds apart (the last frames are left
    out when ``every`` does not divide the count; the simulation still runs
    them). ``positions``: float64 (F, N, 3) [m], every cloth's points in scene
    order (a grid's row-major, a mesh's in its file's order; ``cloths`` says
    which are whose);
    ``times``: float64 (F,) [s] of simulated time since the start;
    ``frames_per_sec``: the recorded frames per simulated second. The frames
    take F x N x 24 bytes (5 s of a 50x50 cloth at 90 frames/s: 27 MB).

    The simulation keeps the trajectory of its last ``record`` call (and no
    other frames) as ``sim.recording``: that is what a notebook shows for
    ``sim`` (``Simulation.show``). Stepping records nothing by itself.
    """
    if isinstance(every, bool) or not isinstance(every, (int, np.integer)) or every < 1:
        raise ValueError(f"every: expected a whole number >= 1, got {every!r}")
    every = int(every)
    fps = float(sim.params.frames_per_sec)
    frames = run_frames(seconds, fps)  # as Simulation.run counts them, and refuses what it refuses
    kept = frames // every
    positions = np.empty((kept + 1,) + sim.positions.shape)
    times = np.empty(kept + 1)
    positions[0] = sim.positions
    times[0] = sim.time
    stepped = [0]

    def on_frame(s) -> None:
        stepped[0] += 1
        k, rest = divmod(stepped[0], every)
        if rest == 0 and k <= kept:
            positions[k] = s.positions
            times[k] = s.time

    sim.run(seconds, on_frame)
    traj = _trajectory(sim, positions, times, fps / every)
    sim._recording = traj
    return traj


class TrajectoryRecorder:
    """Collects a simulation's frames; :meth:`trajectory` gives them as a :class:`Trajectory`."""

    def __init__(self, sim) -> None:
        self._frames: list[np.ndarray] = []
        self._times: list[float] = []
        self(sim)

    @property
    def last(self) -> np.ndarray:
        """the positions of the frame recorded last [m], (N, 3)"""
        return self._frames[-1]

    def __call__(self, sim) -> None:
        """Record the simulation's current frame."""
        self._frames.append(sim.positions.copy())
        self._times.append(sim.time)

    def trajectory(self, sim) -> Trajectory:
        return _trajectory(sim, np.stack(self._frames), np.array(self._times), sim.params.frames_per_sec)
