"""The compiled kernels are never stale: numba's cache folder is keyed on every
kernel source (clothsim.kernel_cache), proved end to end on a copy of the package."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numba
import numpy as np
import pytest

from clothsim import kernel_cache

PACKAGE = Path(kernel_cache.__file__).resolve().parent
ROOT = PACKAGE.parent.parent

SIMULATE = """
import hashlib, sys
import numpy as np
import clothsim
from clothsim import Simulation

sim = Simulation.from_file(sys.argv[1], ["cloth.num_width_points=16", "cloth.num_height_points=16"])
for _ in range(60):  # 0.67 s: the cloth lies on the sphere from about 0.35 s on
    sim.step()
positions = np.ascontiguousarray(sim.positions, dtype=np.float64)
np.save(sys.argv[2], positions)
print("module", clothsim.__file__)
print("checksum", hashlib.sha256(positions.tobytes()).hexdigest())
"""

SPHERE_EDITS = [
    (r"\b1\.0 - ", "1.0 - 0.5 * "),              # the friction factor: keep = 1.0 - friction
    (r"\br / np\.sqrt\(", "1.25 * r / np.sqrt("),  # the surface radius the points go to
]
"""textual edits of the sphere's rule, the first that matches is made"""

SPHERE_RULE = "_rule_of"
"""the function of the sphere's module that reads a sphere's row for its loops (the
friction factor among its numbers): the loops themselves are written as vector
code (colliders/sphere_lanes.py), so the edit goes where their numbers come from"""


def copy_package(dest: Path) -> Path:
    """src/clothsim copied under dest (without bytecode or caches); returns the copy's package folder"""
    shutil.copytree(PACKAGE, dest / "clothsim", ignore=shutil.ignore_patterns("__pycache__"))
    return dest / "clothsim"


def sphere_scene() -> Path:
    for path in (ROOT / "scenes" / "sphere.json", PACKAGE / "scenes" / "sphere.json"):
        if path.exists():
            return path
    raise AssertionError("no sphere.json in scenes/ or the package")


def edit_sphere_rule(package: Path) -> Path:
    """Change, in the copy, the body of SPHERE_RULE, which every sphere collision
    runs, so that its result surely changes; returns the file edited."""
    head = rf"^def {SPHERE_RULE}\("
    defining = [p for p in sorted(package.rglob("*.py")) if re.search(head, p.read_text(), re.MULTILINE)]
    assert len(defining) == 1, f"{SPHERE_RULE} defined in {defining}"
    path = defining[0]
    text = path.read_text()
    start = re.search(head, text, re.MULTILINE).start()
    after = re.search(r"\n(?=[^\s#)])", text[start:])  # the next top-level line
    end = start + after.start() + 1 if after else len(text)
    body = text[start:end]
    for pattern, replacement in SPHERE_EDITS:
        edited, count = re.subn(pattern, replacement, body, count=1)
        if count:
            path.write_text(text[:start] + edited + text[end:])
            return path
    raise AssertionError(f"none of SPHERE_EDITS matches {SPHERE_RULE} in {path}:\n{body}")


def simulate(copy_root: Path, cache: Path, script: Path, out: Path,
             debug_cache: bool = False) -> subprocess.Popen:
    """start the short sphere run of the package copied under copy_root, numba's cache
    in cache, the final positions saved to out (.npy)"""
    env = {**os.environ, "PYTHONPATH": str(copy_root), "NUMBA_CACHE_DIR": str(cache),
           "PYTHONDONTWRITEBYTECODE": "1"}
    env.pop("NUMBA_DEBUG_CACHE", None)
    if debug_cache:
        env["NUMBA_DEBUG_CACHE"] = "1"
    return subprocess.Popen([sys.executable, str(script), str(sphere_scene()), str(out)], env=env,
                            cwd=copy_root, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def result(process: subprocess.Popen, copy_root: Path, out: Path) -> tuple[np.ndarray, str, str]:
    """(positions, checksum, all output) of a finished simulate()"""
    stdout, stderr = process.communicate(timeout=600)
    assert process.returncode == 0, stdout[-3000:] + stderr[-3000:]
    module = re.search(r"^module (.*)$", stdout, re.MULTILINE).group(1)
    assert Path(module).resolve().is_relative_to(copy_root.resolve()), module
    checksum = re.search(r"^checksum (\w+)$", stdout, re.MULTILINE).group(1)
    return np.load(out), checksum, stdout + stderr


def test_an_edited_kernel_is_compiled_afresh_into_an_old_cache(tmp_path):
    """the sphere kernel, called by the cached advance from another file, edited in a
    copy of the package: the next run with the same cache gives another result, the
    same as a run with an empty cache. Three cold compiles, the last two side by side.

    Positions are compared with a tolerance where a compiled run meets one loaded from
    the cache: numba's cached machine code can round differently from the code it
    compiled in the process (here from the 45th frame on, by 1e-14 m)."""
    copy_root = tmp_path / "copy"
    package = copy_package(copy_root)
    script = tmp_path / "simulate.py"
    script.write_text(SIMULATE)
    cache, fresh = tmp_path / "cache", tmp_path / "fresh"
    cache.mkdir()
    fresh.mkdir()
    out = {name: tmp_path / f"{name}.npy" for name in ("before", "again", "after", "reference")}

    before, _, _ = result(simulate(copy_root, cache, script, out["before"]), copy_root, out["before"])
    again, _, log = result(simulate(copy_root, cache, script, out["again"], debug_cache=True),
                           copy_root, out["again"])
    assert re.search(r"data loaded from .*advance", log), "the unchanged sources did not load from the cache"
    assert "data saved" not in log, "the unchanged sources compiled again"
    assert np.allclose(again, before, rtol=0.0, atol=1e-9)

    edit_sphere_rule(package)
    old_cache = simulate(copy_root, cache, script, out["after"])
    new_cache = simulate(copy_root, fresh, script, out["reference"])
    after, after_sum, _ = result(old_cache, copy_root, out["after"])
    reference, reference_sum, _ = result(new_cache, copy_root, out["reference"])
    assert np.abs(after - before).max() > 1e-4, "the edited kernel did not change the result: stale code ran"
    assert after_sum == reference_sum, np.abs(after - reference).max()  # both compiled from the same sources
    folders = sorted(p.name for p in cache.iterdir())
    assert len(folders) == 2 and all(re.fullmatch(r"clothsim-[0-9a-f]{16}", f) for f in folders), folders


# ---------------------------------------------------------------- the key


def test_the_hash_follows_every_kernel_source_and_the_portable_switch(tmp_path):
    package = copy_package(tmp_path)
    h0 = kernel_cache.source_hash(package, environ={})
    assert re.fullmatch(r"[0-9a-f]{16}", h0)
    assert kernel_cache.source_hash(package, environ={}) == h0

    sources = kernel_cache.kernel_sources(package)
    assert "mesh.py" in sources
    solver = sorted(p.relative_to(package).as_posix() for p in (package / "solver").rglob("*.py")
                    if "__pycache__" not in p.parts)
    assert solver and set(solver) <= set(sources)
    for rel in sources:
        path = package / rel
        text = path.read_bytes()
        path.write_bytes(text + b"\n# edited\n")
        assert kernel_cache.source_hash(package, environ={}) != h0, rel
        path.write_bytes(text)
    assert kernel_cache.source_hash(package, environ={}) == h0

    # a file added anywhere under solver/, however deep, counts
    extra = package / "solver" / "newstage" / "kernel.py"
    extra.parent.mkdir()
    extra.write_text("X = 1\n")
    assert kernel_cache.source_hash(package, environ={}) != h0
    shutil.rmtree(extra.parent)
    assert kernel_cache.source_hash(package, environ={}) == h0

    # modules that are not kernels do not count; a module elsewhere that imports numba does
    (package / "notes_for_the_test.py").write_text('"""from numba import njit, in a docstring but indented"""\n'
                                                   "def f():\n    import numba\n")
    (package / "errors.py").write_text((package / "errors.py").read_text() + "\n# edited\n")
    (package / "__init__.py").write_text((package / "__init__.py").read_text() + "\n# edited\n")
    assert kernel_cache.source_hash(package, environ={}) == h0
    (package / "wind.py").write_text("from numba import njit\n")
    assert kernel_cache.source_hash(package, environ={}) != h0
    (package / "wind.py").unlink()

    flag = kernel_cache.FORCE_PORTABLE
    portable = kernel_cache.source_hash(package, environ={flag: "1"})
    assert portable != h0
    assert kernel_cache.source_hash(package, environ={flag: "1"}) == portable
    assert kernel_cache.source_hash(package, environ={"OTHER": "1"}) == h0


def test_hashing_is_fast():
    kernel_cache.source_hash()  # numba imported, files in the page cache
    start = time.perf_counter()
    for _ in range(10):
        kernel_cache.source_hash()
    assert (time.perf_counter() - start) / 10 < 0.02


# ---------------------------------------------------------------- the folder


@pytest.fixture
def fresh_config(monkeypatch, tmp_path):
    """configure() as in a new process, numba's config restored afterwards"""
    monkeypatch.setattr(numba.config, "CACHE_DIR", "")
    monkeypatch.setattr(kernel_cache, "_configured", {})
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    return tmp_path


def test_the_folder_is_under_numba_cache_dir_when_set(fresh_config, monkeypatch):
    user = fresh_config / "numba-cache"
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(user))
    path = kernel_cache.configure()
    assert path == user / f"clothsim-{kernel_cache.source_hash()}"
    assert path.is_dir() and (path / kernel_cache.STAMP).is_file()
    assert numba.config.CACHE_DIR == str(path)
    assert kernel_cache.configure() == path  # repeat calls find the same folder


def test_the_folder_is_per_user_otherwise(fresh_config):
    path = kernel_cache.configure()
    assert path == fresh_config / "xdg" / "clothsim" / f"kernels-{kernel_cache.source_hash()}"
    assert numba.config.CACHE_DIR == str(path)
    numba.config.CACHE_DIR = ""  # as numba's reload of its config would
    assert kernel_cache.configure() == path and numba.config.CACHE_DIR == str(path)


def test_the_portable_switch_gets_its_own_folder(fresh_config, monkeypatch):
    monkeypatch.delenv(kernel_cache.FORCE_PORTABLE, raising=False)
    native = kernel_cache.configure()
    monkeypatch.setenv(kernel_cache.FORCE_PORTABLE, "1")
    portable = kernel_cache.configure()
    assert portable != native and portable.is_dir()
    assert numba.config.CACHE_DIR == str(portable)


def test_an_unusable_folder_leaves_numba_its_own_choice(fresh_config, monkeypatch):
    blocker = fresh_config / "a-file"
    blocker.write_text("")
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(blocker))
    assert kernel_cache.configure() is None
    assert numba.config.CACHE_DIR == ""  # numba's own default locators apply
    assert not kernel_cache.is_warm("serial")
    kernel_cache.mark_warm("serial")  # no error, nothing written
    assert not kernel_cache.is_warm("serial")


def test_a_new_folder_removes_only_old_folders_made_here(fresh_config):
    parent = fresh_config / "xdg" / "clothsim"
    parent.mkdir(parents=True)
    old = time.time() - 2 * kernel_cache.KEEP_SECONDS

    def made(name: str, used: float | None, stamp: bool = True) -> Path:
        folder = parent / name
        folder.mkdir()
        (folder / "advance-1.py311.nbi").write_text("")
        if stamp:
            (folder / kernel_cache.STAMP).write_text("")
            os.utime(folder / kernel_cache.STAMP, (used, used))
        return folder

    stale = [made(f"kernels-{i:016x}", old - i) for i in range(4)]  # the two most recent of them are kept
    recent = made("kernels-" + "f" * 16, time.time() - 60)
    unstamped = made("kernels-" + "e" * 16, old, stamp=False)
    other_names = [made("kernels-notahash", old), made("kernels-" + "d" * 15, old), made("mine", old)]
    (parent / ("kernels-" + "c" * 16)).write_text("a file, not a folder")

    path = kernel_cache.configure()
    left = {p.name for p in parent.iterdir()}
    assert path.name in left
    assert {recent.name, unstamped.name, *(p.name for p in other_names), "kernels-" + "c" * 16} <= left
    # kept: the two most recently used of the others (recent and stale[0]); the rest were stale
    kept_stale = [p.name for p in stale if p.name in left]
    assert kept_stale == [stale[0].name], kept_stale

    # a folder already there is used without pruning
    again = made("kernels-" + "b" * 16, old - 100)
    kernel_cache._configured.clear()
    assert kernel_cache.configure() == path
    assert again.exists()


# ---------------------------------------------------------------- warm markers


def test_warm_markers(fresh_config, monkeypatch):
    assert not kernel_cache.is_warm("serial")
    kernel_cache.mark_warm("serial")
    assert kernel_cache.is_warm("serial")
    assert not kernel_cache.is_warm("parallel")
    # another key (here the portable switch turned the other way) starts cold;
    # the suite may itself run on the portable path
    if os.environ.get(kernel_cache.FORCE_PORTABLE):
        monkeypatch.delenv(kernel_cache.FORCE_PORTABLE)
    else:
        monkeypatch.setenv(kernel_cache.FORCE_PORTABLE, "1")
    assert not kernel_cache.is_warm("serial")
    for bad in ("", "a/b", "../x", "x" * 65, None):
        with pytest.raises(ValueError):
            kernel_cache.is_warm(bad)
