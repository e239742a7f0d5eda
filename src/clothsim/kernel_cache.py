"""Where numba keeps clothsim's compiled kernels: a folder keyed on their sources.

numba stamps each cache entry with the source file that *defines* the function
and nothing else. A cached caller (``advance``) holds the machine code of every
kernel it calls or inlines from other files, so after one of those files is
edited numba would keep loading the old code. :func:`configure` closes that gap
by pointing ``numba.config.CACHE_DIR`` at a folder named after a hash of

- every ``*.py`` under ``clothsim/solver/`` (recursively: whatever files exist
  at import time), ``clothsim/mesh.py``, and any other module of the package
  that imports numba at top level (a kernel module wherever it lives);
- the numba and llvmlite versions;
- the value of ``CLOTHSIM_NO_AVX512``, which picks code paths at import time.

Any edit of a kernel source therefore lands in a fresh folder, where
everything compiles afresh; an unchanged tree finds its folder again. numba
reads ``config.CACHE_DIR`` when a ``cache=True`` dispatcher is created (its
``_UserProvidedCacheLocator``), so ``configure()`` must run before the first
kernel is decorated: ``clothsim/solver/__init__.py`` and ``clothsim/mesh.py``
call it before theirs. Code that creates dispatchers later (say, after an
``NUMBA_*`` variable changed, which makes numba reload its configuration)
calls it again first: repeat calls are cheap and re-apply the folder.

The folder is ``$NUMBA_CACHE_DIR/clothsim-<hash>`` when the user set
``NUMBA_CACHE_DIR`` (or numba's config file set ``cache_dir``), else
``$XDG_CACHE_HOME/clothsim/kernels-<hash>`` (``~/.cache`` by default;
``%LOCALAPPDATA%`` on Windows). If it cannot be created or written, numba
keeps its default behaviour (the folder the user gave, else ``__pycache__``
next to the sources) and nothing here fails.

Housekeeping: each folder holds a stamp file, ``.clothsim-kernels``, touched on
every use. When a new folder is made, older folders of *other* hashes under
the same parent are removed, but only those whose name is exactly
``kernels-<16 hex>`` / ``clothsim-<16 hex>``, that hold the stamp file, that
are not among the :data:`KEEP_RECENT` most recently used, and that have not
been used for :data:`KEEP_SECONDS` (so two checkouts in use side by side do not
evict each other). Nothing else is ever deleted.

Front ends learn whether compiling lies ahead with :func:`is_warm` and record
a finished compile with :func:`mark_warm`; the markers live in the keyed
folder (so an edit makes them cold too) and are per CPU model.

This module imports numba only when one of its functions is called.
"""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import time
from pathlib import Path

FORCE_PORTABLE = "CLOTHSIM_NO_AVX512"
"""the environment variable that switches the kernels to the portable path
(the same name as :data:`clothsim.solver.simd.FORCE_PORTABLE`)"""

PACKAGE = Path(__file__).resolve().parent
"""the clothsim package folder whose sources are hashed"""

STAMP = ".clothsim-kernels"
"""the file that marks a folder as made here, touched on every use"""

KEEP_RECENT = 2
"""folders of other hashes kept however old, the most recently used first"""

KEEP_SECONDS = 3600.0
"""folders of other hashes used more recently than this are kept [s]"""

_HASH_CHARS = 16
_NUMBA_IMPORT = re.compile(rb"^(?:import numba\b|from numba[. ])", re.MULTILINE)
_KEYED = re.compile(f"(?:kernels|clothsim)-[0-9a-f]{{{_HASH_CHARS}}}")
_VARIANT = re.compile(r"[A-Za-z0-9_.+-]{1,64}")

_configured: dict = {}
"""the last call's inputs ("key"), folder ("path", None when numba's default
applies) and numba's own cache folder before the first call ("original")"""


def kernel_sources(root: str | os.PathLike | None = None) -> dict[str, bytes]:
    """The kernel sources of the package at ``root`` (this one by default):
    {path relative to root, '/'-separated: contents}."""
    root = Path(root) if root is not None else PACKAGE
    out = {}
    for folder, dirs, files in os.walk(root):
        dirs[:] = [d for d in dirs if d != "__pycache__" and not d.startswith(".")]
        rel_folder = Path(folder).relative_to(root).as_posix()
        in_solver = rel_folder == "solver" or rel_folder.startswith("solver/")
        for name in files:
            if not name.endswith(".py"):
                continue
            rel = name if rel_folder == "." else f"{rel_folder}/{name}"
            try:
                with open(os.path.join(folder, name), "rb") as f:
                    data = f.read()
            except OSError:
                continue
            if in_solver or rel == "mesh.py" or _NUMBA_IMPORT.search(data):
                out[rel] = data
    return out


def source_hash(root: str | os.PathLike | None = None, environ=None) -> str:
    """The cache key: a hash of the kernel sources of the package at ``root``,
    the numba and llvmlite versions and ``environ[CLOTHSIM_NO_AVX512]``
    (``os.environ`` by default)."""
    import llvmlite
    import numba

    environ = os.environ if environ is None else environ
    h = hashlib.sha256()
    for part in ("numba", numba.__version__, "llvmlite", llvmlite.__version__,
                 FORCE_PORTABLE, repr(environ.get(FORCE_PORTABLE))):
        h.update(part.encode() + b"\0")
    for rel, data in sorted(kernel_sources(root).items()):
        h.update(b"%s\0%d\0" % (rel.encode(), len(data)))
        h.update(data)
    return h.hexdigest()[:_HASH_CHARS]


def _base(user_dir: str) -> tuple[Path, str] | None:
    """(parent folder, name prefix) of the keyed folders"""
    if user_dir:
        return Path(user_dir).expanduser(), "clothsim-"
    if os.name == "nt" and os.environ.get("LOCALAPPDATA"):
        cache = Path(os.environ["LOCALAPPDATA"])
    elif os.environ.get("XDG_CACHE_HOME"):
        cache = Path(os.environ["XDG_CACHE_HOME"])
    else:
        try:
            cache = Path.home() / ".cache"
        except RuntimeError:  # no home folder known
            return None
    return cache / "clothsim", "kernels-"


def configure() -> Path | None:
    """Point numba's cache at the folder keyed on the kernel sources (see the
    module's docstring) and return it; None where it cannot be made, numba's
    own choice then standing. Call before any clothsim kernel is decorated.
    Also asks numba for 512-bit vectors where the CPU has AVX-512
    (:func:`clothsim.vector_width.widen`), before anything compiles."""
    import numba

    from .vector_width import widen

    widen()

    if "original" not in _configured:
        original = numba.config.CACHE_DIR or ""
        if _KEYED.fullmatch(os.path.basename(os.path.normpath(original))):
            original = ""  # set by an earlier configure() (this module imported afresh)
        _configured["original"] = original
    user_dir = os.environ.get("NUMBA_CACHE_DIR") or _configured["original"]
    key = (user_dir, os.environ.get(FORCE_PORTABLE), os.environ.get("XDG_CACHE_HOME"),
           os.environ.get("LOCALAPPDATA"), os.environ.get("HOME"))
    if _configured.get("key") == key:
        path = _configured["path"]
        numba.config.CACHE_DIR = str(path) if path is not None else _configured["original"]
        return path

    path = None
    base = _base(user_dir)
    if base is not None:
        parent, prefix = base
        candidate = parent / (prefix + source_hash())
        try:
            path = _ensure(candidate, parent, prefix)
        except OSError:
            path = None
    numba.config.CACHE_DIR = str(path) if path is not None else _configured["original"]
    _configured.update(key=key, path=path)
    return path


def _ensure(path: Path, parent: Path, prefix: str) -> Path:
    """Make (or find) ``path`` writable and stamped; prune old folders if it is new."""
    stamp = path / STAMP
    try:
        os.utime(stamp)
        return path
    except OSError:
        pass
    os.makedirs(path, exist_ok=True)
    with open(stamp, "w") as f:
        f.write("compiled clothsim kernels (numba cache); safe to delete\n")
    _prune(parent, prefix, keep=path.name)
    return path


def _prune(parent: Path, prefix: str, keep: str) -> None:
    """Remove old keyed folders of other hashes under ``parent`` (see the module's docstring)."""
    pattern = re.compile(re.escape(prefix) + f"[0-9a-f]{{{_HASH_CHARS}}}")
    found = []
    try:
        entries = list(os.scandir(parent))
    except OSError:
        return
    for entry in entries:
        if entry.name == keep or not pattern.fullmatch(entry.name):
            continue
        try:
            if not entry.is_dir(follow_symlinks=False):
                continue
            used = os.stat(os.path.join(entry.path, STAMP), follow_symlinks=False).st_mtime
        except OSError:  # no stamp: not made here
            continue
        found.append((used, entry.path))
    found.sort(reverse=True)
    now = time.time()
    for used, folder in found[KEEP_RECENT:]:
        if now - used > KEEP_SECONDS:
            shutil.rmtree(folder, ignore_errors=True)


def cache_dir() -> Path | None:
    """The keyed folder numba caches into (None where numba's default applies)."""
    return configure()


def _marker(variant: str) -> Path | None:
    if not isinstance(variant, str) or not _VARIANT.fullmatch(variant):
        raise ValueError(f"a kernel variant is 1-64 of A-Z a-z 0-9 _ . + -, not {variant!r}")
    path = configure()
    if path is None:
        return None
    import llvmlite.binding as llvm
    import numba

    from .vector_width import target_cpu_name

    cpu = f"{target_cpu_name()};{numba.config.CPU_FEATURES or llvm.get_host_cpu_features().flatten()}"
    return path / f"warm-{variant}-{hashlib.sha256(cpu.encode()).hexdigest()[:8]}"


def is_warm(variant: str) -> bool:
    """Whether :func:`mark_warm` recorded ``variant`` (a name the caller picks for
    a set of kernels, e.g. "serial" or "parallel") for these sources and this
    CPU: False means the next call of those kernels compiles them. Always
    False where numba's default cache applies (nothing is known then)."""
    path = _marker(variant)
    return path is not None and path.exists()


def mark_warm(variant: str) -> None:
    """Record that ``variant``'s kernels are compiled and in the cache: call after
    their first call returned. Does nothing where the folder cannot be written."""
    path = _marker(variant)
    if path is not None:
        try:
            path.touch()
        except OSError:
            pass
