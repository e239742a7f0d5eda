"""An OBJ sequence: one file per frame (the format of :mod:`.obj`), written in a
background thread whose work holds no GIL (see :class:`ObjSequence`)."""

from __future__ import annotations

import atexit
import os
import threading
from pathlib import Path

import numpy as np

from ..outputs import place
from .obj import HEADER, MeshText, Objects, _frame_parts, _objtext, compute_normals


def _write_file(path: Path, parts: list[bytes]) -> None:
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o666)
    try:
        for part in parts:
            view = memoryview(part)
            while view:
                view = view[os.write(fd, view):]
    finally:
        os.close(fd)


class ObjSequence:
    """Writes ``folder/frame_NNNN.obj`` for each frame given to :meth:`write`;
    :meth:`close` waits for the last and raises the first error. ``objects``:
    one ``o`` per cloth (:func:`model_objects`), as :func:`obj_bytes`.

    Each file is written under a hidden temporary name (``.frame_NNNN.obj.tmp``)
    and moved to its name when whole, so a ``frame_*.obj`` is never partial.
    Without ``overwrite`` it is placed exclusively (a hard link, as
    :func:`clothsim.outputs.place`): a file that appeared at a frame's name
    while the run went on is kept, and :meth:`write` or :meth:`close` raises
    :class:`~clothsim.outputs.OutputError`; with ``overwrite`` it is renamed
    over whatever is there.

    ``background`` (default: on 64-bit POSIX): :meth:`write` copies the frame
    into a ring of at most ``ring_bytes`` (at least two frames) and returns; a
    thread takes the queued frames (when ``BATCH`` of them are waiting, the ring
    is full, :meth:`close` is called, or every ``WAKE_S`` seconds) and
    computes the normals where none were given, formats and writes them, file
    by file with the C library's creat/write/close/rename (link/unlink without
    ``overwrite``), in one compiled call that holds no GIL
    (:func:`.objtext.write_frames`): it needs the GIL only
    to pick up a batch and hand it back, and asks for it seldom (a simulation
    stepped by kernels that keep the GIL lets it go only between frames).
    :meth:`write` waits when the ring is full. Without ``background`` each file is written before
    :meth:`write` returns. The files are the same either way.

    Frames still queued when the interpreter exits are written then (an
    ``atexit`` hook), so a run that stops on an error keeps the frames it made.
    """

    BATCH = 8
    """frames queued before the thread is woken"""
    WAKE_S = 0.05
    """the longest a queued frame waits for the thread [s]"""

    def __init__(self, folder: str | Path, uvs: np.ndarray, triangles: np.ndarray,
                 background: bool | None = None, ring_bytes: int = 64 << 20,
                 name: str = "frame_{:04d}.obj", objects: Objects | None = None,
                 overwrite: bool = False) -> None:
        self.folder = Path(folder)
        self.name = name
        self.overwrite = bool(overwrite)
        self.mesh = MeshText(uvs, triangles, objects)
        ot = _objtext()
        self.background = ot.NATIVE_WRITE if background is None else bool(background and ot.NATIVE_WRITE)
        self._error: BaseException | None = None
        self._closed = False
        if not self.background:
            return
        n = len(self.mesh.uvs)
        self._slots = int(max(2, min(64, ring_bytes // max(1, 48 * n))))
        self._batch = max(1, min(self.BATCH, self._slots // 2))
        self._positions = np.empty((self._slots, n, 3))
        self._normals = np.empty((self._slots, n, 3))
        self._free = list(range(self._slots))
        self._queued: list[tuple[int, Path, bool]] = []  # (slot, path, normals to compute) for the thread
        self._done: list[tuple[int, Path, bool, int]] = []  # the same and the status, back from it
        self._busy = 0
        self._cond = threading.Condition()
        self._flush = False
        self._stop = False
        self._triangles = np.ascontiguousarray(self.mesh.triangles, dtype=np.int32)
        self._head = np.frombuffer(HEADER, np.uint8)
        self._vt = np.frombuffer(self.mesh.vt, np.uint8)
        self._faces = np.frombuffer(self.mesh.faces, np.uint8)
        self._v_prefix = np.frombuffer(b"v ", np.uint8)
        self._vn_prefix = np.frombuffer(b"vn ", np.uint8)
        self._copy = ot.copy_frame
        self._scratch = np.empty(n * (ot.line_width(3, 2, 9) + ot.line_width(3, 3, 6)), np.uint8)
        self._thread = threading.Thread(target=self._work, name="clothsim-obj-sequence", daemon=True)
        self._thread.start()
        atexit.register(self._at_exit)

    # ------------------------------------------------------------ main thread

    def path(self, frame: int) -> Path:
        return self.folder / self.name.format(frame)

    @staticmethod
    def _tmp(path: Path) -> Path:
        return path.with_name(f".{path.name}.tmp")

    def write(self, frame: int, positions: np.ndarray, normals: np.ndarray | None = None) -> None:
        """Write (or queue) frame number ``frame``: positions [m], (N, 3), and the unit
        vertex normals; when None, ``clothsim.mesh.vertex_normals`` computes them
        (in the thread: compiled into its kernel, where fastmath may contract the
        arithmetic differently from ``Simulation.normals``, within 1e-15, which
        the 6 digits of a vn line do not show)."""
        if self._closed:
            raise ValueError("the OBJ sequence is closed")
        path = self.path(frame)
        if not self.background:
            if normals is None:
                normals = compute_normals(np.asarray(positions, np.float64), self.mesh.triangles)
            tmp = self._tmp(path)
            try:
                _write_file(tmp, _frame_parts(positions, normals, self.mesh))
                place(tmp, path, self.overwrite)
            except BaseException:
                tmp.unlink(missing_ok=True)
                raise
            return
        with self._cond:
            while not self._free and self._error is None:
                self._reap_locked()
                if not self._free:
                    self._flush = True
                    self._cond.notify_all()
                    self._cond.wait()
            self._reap_locked()
            self._raise_locked()
            slot = self._free.pop()
        positions = np.asarray(positions, np.float64)
        self._copy(self._positions, self._normals, slot, positions,
                   positions if normals is None else np.asarray(normals, np.float64))
        with self._cond:
            self._queued.append((slot, path, normals is None))
            self._busy += 1
            if len(self._queued) >= self._batch:
                self._cond.notify_all()

    def _reap_locked(self) -> None:
        """take back the slots of the frames the thread finished, and write again in
        Python those it could not (with the lock held)"""
        done, self._done = self._done, []
        ot = _objtext()
        for slot, path, compute, status in done:
            tmp = self._tmp(path)
            try:
                if status == ot.FRAME_NOT_PLACED:  # written whole; the link failed: place() says why
                    place(tmp, path, self.overwrite)
                elif status != ot.FRAME_OK:  # FRAME_WRITE_FAILED learns why, FRAME_UNDECIDED formats in Python
                    positions = self._positions[slot]
                    normals = compute_normals(positions, self._triangles) if compute else self._normals[slot]
                    _write_file(tmp, _frame_parts(positions, normals, self.mesh))
                    place(tmp, path, self.overwrite)
            except BaseException as e:
                tmp.unlink(missing_ok=True)
                if self._error is None:
                    self._error = e
            finally:
                # in this order: Python runs a signal handler after a call such as the
                # append, not between these two lines, and a Ctrl-C raised between them
                # in the other order left _busy one too high, and close() waiting forever
                self._busy -= 1
                self._free.append(slot)

    def _raise_locked(self) -> None:
        if self._error is not None:
            error, self._error = self._error, None
            self._shutdown_locked()
            raise error

    def _shutdown_locked(self) -> None:
        self._stop = True
        self._closed = True
        self._busy -= len(self._queued)  # never handed to the thread
        self._queued = []
        self._cond.notify_all()

    def close(self) -> None:
        """Wait until every frame is written; raise the first error met."""
        if not self.background:
            self._closed = True
            return
        with self._cond:
            if self._closed and self._busy == 0:
                return
            self._closed = True
            self._flush = True
            self._cond.notify_all()
            while self._busy > 0:
                self._reap_locked()
                if self._busy > 0:
                    self._cond.wait()
            self._stop = True
            self._cond.notify_all()
            error, self._error = self._error, None
        self._thread.join()
        atexit.unregister(self._at_exit)
        if error is not None:
            raise error

    def _at_exit(self) -> None:
        try:
            self.close()
        except Exception:  # noqa: BLE001 - the run has already failed or ended
            pass

    def __enter__(self) -> ObjSequence:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ------------------------------------------------------------ the thread

    def _work(self) -> None:
        ot = _objtext()
        while True:
            with self._cond:
                while not self._stop and not (self._queued and (self._flush or len(self._queued) >= self._batch)):
                    if not self._cond.wait(self.WAKE_S) and self._queued:
                        break  # a frame waited WAKE_S: take what there is
                if not self._queued:
                    return
                batch, self._queued = self._queued, []
                self._flush = False
            slots = np.array([slot for slot, _, _ in batch], np.int64)
            compute = np.array([c for _, _, c in batch], np.bool_)
            names = []
            for _, path, _ in batch:
                names += [os.fsencode(self._tmp(path)), os.fsencode(path)]
            width = max(map(len, names)) + 1  # NUL-terminated, in rows of one width
            table = np.frombuffer(b"".join(n.ljust(width, b"\0") for n in names), np.uint8)
            table = table.reshape(len(names), width)
            status = np.full(len(batch), ot.FRAME_WRITE_FAILED, np.int64)
            try:
                ot.write_frames(self._positions, self._normals, slots, compute, self._triangles, table,
                                self._head, self._vt, self._faces, self._v_prefix, self._vn_prefix,
                                self._scratch, status, not self.overwrite)
            except BaseException:  # noqa: BLE001 - each frame is written again by the main thread
                pass
            with self._cond:
                self._done.extend((slot, path, c, int(st)) for (slot, path, c), st in zip(batch, status))
                self._cond.notify_all()
