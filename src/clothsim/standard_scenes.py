"""The standard scenes that ship inside the package, found by name.

They are package data (``clothsim/scenes/*.json``), so an installed clothsim
has them wherever it runs: ``find_scene("sphere")`` gives the path of
``sphere.json`` there. A path that exists always wins over a name, so a
user's own ``sphere.json`` in the working folder is the one that loads.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from .errors import SceneError

SUFFIX = ".json"


def scenes_dir() -> Path:
    """The folder of the packaged scene files."""
    folder = resources.files("clothsim").joinpath("scenes")
    # an installed or editable package is a folder on disk; a zipped one has
    # no paths to hand to a loader that reads files
    return Path(str(folder))


def names() -> list[str]:
    """The standard scenes' names (file names without ``.json``), sorted case-blind."""
    folder = scenes_dir()
    if not folder.is_dir():
        return []
    return sorted((p.stem for p in folder.iterdir() if p.suffix == SUFFIX and p.is_file()), key=str.lower)


def scene_path(name: str) -> Path:
    """The file of the standard scene ``name`` (``.json`` optional, case-blind);
    a :class:`SceneError` naming the known scenes when there is none."""
    stem = name[:-len(SUFFIX)] if name.lower().endswith(SUFFIX) else name
    known = names()
    for candidate in [stem] + [n for n in known if n.lower() == stem.lower()]:
        if candidate in known:
            return scenes_dir() / f"{candidate}{SUFFIX}"
    raise SceneError(name, None, "no such file, nor a standard scene; the standard scenes are "
                     + (", ".join(known) or "missing from this installation"))


def is_bare_name(text: str | Path) -> bool:
    """True for text with no folder in it and no suffix other than ``.json``
    (``sphere``, ``sphere.json``), which may name a standard scene."""
    path = Path(text)
    return len(path.parts) == 1 and not path.is_absolute() and path.suffix.lower() in ("", SUFFIX)


def find_scene(text: str | Path) -> Path:
    """The scene file ``text`` means: the path itself when it exists or names a
    folder, else the standard scene of that bare name.

    A missing path with a folder in it is returned as it is, so that reading
    it reports "no such file" against what the user typed.
    """
    path = Path(text)
    if path.exists() or not is_bare_name(text):
        return path
    return scene_path(str(text))
