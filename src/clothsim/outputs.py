"""Writing output files safely: never a partial file, never a silent overwrite."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from .errors import ClothsimError


def _read_umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


UMASK = _read_umask()
"""the process's umask, read once at import (setting it to read it is not
thread-safe): a finished output gets the mode a plain open() would give it"""


class OutputError(ClothsimError):
    """An output file cannot be written where the user asked."""


def check_writable(path: str | Path, overwrite: bool = False) -> Path:
    """Fail early, before any work, when ``path`` exists (without ``overwrite``)
    or its folder does not."""
    path = Path(path)
    if path.exists() and not overwrite:
        raise OutputError(f"{path}: already exists; pass --overwrite to replace it")
    if path.is_dir():
        raise OutputError(f"{path}: is a directory, expected a file name")
    if not path.parent.exists():
        raise OutputError(f"{path}: folder {path.parent} does not exist")
    return path


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; move it into place only on success."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}-", suffix=path.suffix, dir=path.parent or ".")
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, 0o666 & ~UMASK)  # mkstemp makes it 0600
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def write_atomic(path: str | Path, writer: Callable[[Path], None]) -> None:
    with atomic_path(path) as tmp:
        writer(tmp)
