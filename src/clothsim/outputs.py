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
    or is a folder, or when its folder does not exist, is not a folder or
    cannot take a new file (tried with a probe file, removed at once)."""
    path = Path(path)
    if path.exists() and not overwrite:
        raise OutputError(f"{path}: already exists; pass --overwrite to replace it")
    if path.is_dir():
        raise OutputError(f"{path}: is a directory, expected a file name")
    check_folder_writable(path, path.parent)
    return path


def check_folder_writable(path: str | Path, folder: str | Path) -> None:
    """Fail when ``folder`` (where the output ``path`` goes) does not exist, is not a
    folder, or no file can be made in it (no permission, a read-only disk)."""
    folder = Path(folder)
    if not folder.exists():
        raise OutputError(f"{path}: folder {folder} does not exist")
    if not folder.is_dir():
        raise OutputError(f"{path}: {folder} is not a folder")
    try:
        fd, probe = tempfile.mkstemp(prefix=".clothsim-probe-", dir=folder)
    except OSError as exc:
        raise OutputError(f"{path}: cannot write in {folder} ({exc.strerror or exc})") from None
    os.close(fd)
    os.unlink(probe)


def check_output_folder(path: str | Path, what: str = "folder") -> Path:
    """Fail early when the output folder ``path`` cannot be used: it exists and is
    not a writable folder, or it does not exist and its nearest existing parent
    is not a writable folder (the folders in between are made at the start)."""
    path = Path(path)
    if path.exists():
        if not path.is_dir():
            raise OutputError(f"{path}: exists and is not a {what}")
        check_folder_writable(path, path)
        return path
    parent = path.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    check_folder_writable(path, parent)
    return path


def place(tmp: str | Path, path: str | Path, overwrite: bool = True) -> None:
    """Move the finished file ``tmp`` to ``path``. Without ``overwrite`` the final
    name is created exclusively (a hard link, then ``tmp`` removed), so a file
    that appeared at ``path`` while the work ran is kept and OutputError raised;
    ``tmp`` is removed either way."""
    if overwrite:
        os.replace(tmp, path)
        return
    try:
        os.link(tmp, path)
    except FileExistsError:
        os.unlink(tmp)
        raise OutputError(f"{path}: a file appeared there while the run went on; it was kept and nothing "
                          "was written (pass --overwrite to replace it)") from None
    except OSError:  # a file system without hard links: check, then rename (a narrow race remains)
        if os.path.lexists(path):
            os.unlink(tmp)
            raise OutputError(f"{path}: a file appeared there while the run went on; it was kept and "
                              "nothing was written (pass --overwrite to replace it)") from None
        os.rename(tmp, path)
        return
    os.unlink(tmp)


@contextmanager
def atomic_path(path: str | Path, overwrite: bool = True) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; move it into place only on success
    (:func:`place`: without ``overwrite``, never over a file that is there by then)."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}-", suffix=path.suffix, dir=path.parent or ".")
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, 0o666 & ~UMASK)  # mkstemp makes it 0600
        place(tmp, path, overwrite)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def write_atomic(path: str | Path, writer: Callable[[Path], None], overwrite: bool = True) -> None:
    with atomic_path(path, overwrite) as tmp:
        writer(tmp)
