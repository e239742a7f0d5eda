"""The sweep's output folder: per-run PNG/OBJ, records, runs.csv, sheet.png.

runs.csv has a row per run: the varied values, the measures of
:data:`METRIC_COLUMNS` and, for a scene of several cloths, each cloth's own
(``NAME.lowest_y``, ``NAME.sag``, ``NAME.max_stretch``).

A run is done when ``records/NAME.json`` holds its digest; re-running skips
it. Before a run's files are written its record says ``pending`` (with the
digest), so a sweep killed between a run's image and its record redoes that
run next time instead of taking its files for another's. Files the sweep did
not write, or wrote for different settings, are never replaced without
``--force``.

One sweep at a time writes into a folder: :meth:`SweepDir.lock` makes
``.sweep.lock`` exclusively, holding the sweep's process id; a lock whose
process is gone (a killed sweep) is taken over.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from ..outputs import OutputError, write_atomic
from .plan import RunSpec
from .runner import RunResult

METRIC_COLUMNS = ["lowest_y", "sag", "max_stretch", "mean_speed", "at_rest", "frames", "wall_s"]
MANIFEST = "sweep.json"
LOCK = ".sweep.lock"


class SweepDir:
    def __init__(self, path: str | Path, force: bool = False) -> None:
        self.path = Path(path)
        self.force = force
        if self.path.exists() and not self.path.is_dir():
            raise OutputError(f"{self.path}: exists and is not a folder")
        self.records = self.path / "records"

    def _record_path(self, spec: RunSpec) -> Path:
        return self.records / f"{spec.name}.json"

    def _read_record(self, spec: RunSpec) -> dict[str, Any] | None:
        try:
            record = json.loads(self._record_path(spec).read_text())
        except (OSError, json.JSONDecodeError, RecursionError):
            return None
        return record if isinstance(record, dict) else None

    def load_record(self, spec: RunSpec) -> dict[str, Any] | None:
        """the finished run's record, or None (not run, or stopped while its files were written)"""
        record = self._read_record(spec)
        return None if record is None or record.get("pending") else record

    @contextmanager
    def lock(self) -> Iterator[None]:
        """Hold the folder against a second sweep into it: ``.sweep.lock`` made
        exclusively with this process's id; OutputError when a live process holds
        it; a lock left by a process that is gone is taken over."""
        self.path.mkdir(parents=True, exist_ok=True)
        path = self.path / LOCK
        if not self._create_lock(path):
            self._take_over(path)
        try:
            yield
        finally:
            if _lock_pid(path) == os.getpid():
                path.unlink(missing_ok=True)

    def _create_lock(self, path: Path) -> bool:
        try:
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        except FileExistsError:
            return False
        with os.fdopen(fd, "w") as f:
            f.write(f"{os.getpid()}\n")
        return True

    def _take_over(self, path: Path) -> None:
        """a lock is there: refuse while its process lives, else replace it (the
        check and the replacement under a lock of the folder, so two sweeps
        that find the same stale lock do not both take it)"""
        fd = os.open(self.path, os.O_RDONLY)
        try:
            try:
                import fcntl
                fcntl.flock(fd, fcntl.LOCK_EX)
            except (ImportError, OSError):
                pass
            pid = _lock_pid(path)
            if pid is None and path.exists() and _age_s(path) < 10:
                pid = -1  # being written by the sweep that just made it
            if pid is not None and (pid == -1 or _alive(pid)):
                who = "another sweep" if pid == -1 else f"another sweep (process {pid})"
                raise OutputError(f"{self.path}: {who} is writing into this folder; wait for it or choose "
                                  f"another folder (remove {path} if no sweep is running)")
            path.unlink(missing_ok=True)
            if not self._create_lock(path):
                raise OutputError(f"{self.path}: another sweep is writing into this folder")
        finally:
            os.close(fd)

    def plan(self, specs: list[RunSpec]) -> tuple[list[RunSpec], list[RunSpec]]:
        """Split into (to run, already done); raise before anything runs on a conflict."""
        todo, done, conflicts = [], [], []
        ours = (self.path / MANIFEST).is_file()
        for name in ("runs.csv", "sheet.png"):
            if (self.path / name).exists() and not ours and not self.force:
                conflicts.append(self.path / name)
        for spec in specs:
            rec = self._read_record(spec)
            if rec is not None and rec.get("digest") == spec.digest() and not self.force:
                if not rec.get("pending"):
                    done.append(spec)
                else:  # stopped while its files were written: ours, redone
                    todo.append(spec)
                continue
            if not self.force:
                if rec is not None:
                    conflicts.append(self._record_path(spec))
                conflicts += [p for p in (self.path / f"{spec.name}.png", self.path / f"{spec.name}.obj")
                              if p.exists()]
            todo.append(spec)
        if conflicts:
            shown = ", ".join(str(p) for p in conflicts[:3]) + (" ..." if len(conflicts) > 3 else "")
            raise OutputError(f"{self.path}: holds files of other runs ({shown}); "
                              "pass --force to redo them or choose another folder")
        return todo, done

    def save(self, result: RunResult) -> None:
        """Write one finished run: images first, the record (the 'done' mark) last."""
        self.records.mkdir(parents=True, exist_ok=True)
        spec = result.spec
        pending = {"digest": spec.digest(), "name": spec.name, "pending": True}
        write_atomic(self._record_path(spec), lambda t: t.write_text(json.dumps(pending, indent=1)))
        if result.png is not None:
            write_atomic(self.path / f"{spec.name}.png", lambda t: t.write_bytes(result.png))
        if result.obj is not None:
            write_atomic(self.path / f"{spec.name}.obj", lambda t: t.write_text(result.obj))
        record = {"digest": spec.digest(), "name": spec.name, "values": dict(spec.values),
                  **result.record, "error": result.error}
        write_atomic(self._record_path(spec), lambda t: t.write_text(json.dumps(record, indent=1)))

    def write_summary(self, specs: list[RunSpec], source: str) -> None:
        """runs.csv and sheet.png over every planned run, and the manifest."""
        self.path.mkdir(parents=True, exist_ok=True)
        keys = [k for k, _ in specs[0].values] if specs else []
        records = [self.load_record(spec) or {"error": "not run"} for spec in specs]
        cloth_columns = cloth_metric_columns(records)
        rows = []
        for spec, rec in zip(specs, records):
            row = {"run": spec.index, "name": spec.name, **{k: v for k, v in spec.values}}
            for col in METRIC_COLUMNS + cloth_columns:
                row[col] = _cell(rec.get(col))
            row["error"] = rec.get("error") or ""
            row["png"] = f"{spec.name}.png" if (self.path / f"{spec.name}.png").exists() else ""
            row["obj"] = f"{spec.name}.obj" if (self.path / f"{spec.name}.obj").exists() else ""
            rows.append(row)
        buf = io.StringIO()
        writer = csv.DictWriter(buf, fieldnames=["run", "name", *keys, *METRIC_COLUMNS, *cloth_columns,
                                                 "error", "png", "obj"])
        writer.writeheader()
        writer.writerows(rows)
        write_atomic(self.path / "runs.csv", lambda t: t.write_text(buf.getvalue()))
        self._write_sheet(specs)
        manifest = {"scene": source, "runs": [s.name for s in specs]}
        write_atomic(self.path / MANIFEST, lambda t: t.write_text(json.dumps(manifest, indent=1)))

    def _write_sheet(self, specs: list[RunSpec]) -> None:
        from PIL import Image

        from ..render.sheet import contact_sheet

        images, labels = [], []
        size = specs[0].size if specs else (64, 64)
        for spec in specs:
            png = self.path / f"{spec.name}.png"
            rec = self.load_record(spec) or {}
            if png.exists() and not rec.get("error"):
                images.append(np.asarray(Image.open(png).convert("RGB")))
                labels.append(spec.label)
            else:
                images.append(np.full((size[1], size[0], 3), (60, 20, 24), np.uint8))
                labels.append(spec.label + "  FAILED")
        sheet = contact_sheet(images, labels)

        def save(tmp: Path) -> None:
            Image.fromarray(sheet).save(tmp, format="PNG")
        write_atomic(self.path / "sheet.png", save)


def _lock_pid(path: Path) -> int | None:
    try:
        text = path.read_text().strip()
    except OSError:
        return None
    return int(text) if text.isdigit() and len(text) < 12 else None


def _age_s(path: Path) -> float:
    import time

    try:
        return time.time() - path.stat().st_mtime
    except OSError:
        return 0.0


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's live process
        return True
    except OSError:
        return False
    return True


def cloth_metric_columns(records: list[dict[str, Any]]) -> list[str]:
    """The per-cloth measures of a scene of several cloths (``cloth_0.sag``, ...:
    :func:`clothsim.metrics.measure`), in the order the records hold them; none
    for a scene of one cloth."""
    out: dict[str, None] = {}
    for rec in records:
        for key, value in rec.items():
            if "." in key and key not in METRIC_COLUMNS and not isinstance(value, (dict, list)):
                out[key] = None
    return list(out)


def _cell(value: Any) -> Any:
    """CSV cell: floats to 9 significant digits so runs compare across machines"""
    if isinstance(value, float):
        return "" if math.isnan(value) else f"{value:.9g}"
    return "" if value is None else value
