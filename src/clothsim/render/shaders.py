"""Shader programs loaded by name from folders of ``Name.vert`` / ``Name.frag`` files.

As in CS184, ``Name.frag`` pairs with ``Name.vert`` when that exists and with
``Default.vert`` otherwise. A user's folder is searched before ours, so a
course student's shader files run unchanged and may replace ours; a user's
``.frag`` takes the user's own ``.vert`` files first (CS184's folder holds
every one of them), so a user's ``Wireframe.frag`` without a ``Wireframe.vert``
pairs with the user's ``Default.vert``, not with our ``Wireframe.vert``.
"""

from __future__ import annotations

import re
from importlib import resources
from pathlib import Path

from ..errors import RenderError

BUILTIN_DIR = Path(str(resources.files("clothsim.render") / "shaders"))
ORDER = ("Wireframe", "Normal", "Diffuse", "Phong", "Texture", "Bump", "Displacement", "Mirror", "Custom")


class ShaderLibrary:
    def __init__(self, user_dirs: list[str | Path] | tuple = ()) -> None:
        self.dirs = [Path(d) for d in user_dirs] + [BUILTIN_DIR]
        for d in self.dirs[:-1]:
            if not d.is_dir():
                raise RenderError(f"{d}: shader folder does not exist")

    def names(self) -> list[str]:
        """Every shader with a .frag file, ours in their usual order, then the user's."""
        found = {p.stem for d in self.dirs for p in d.glob("*.frag")}
        return [n for n in ORDER if n in found] + sorted(found - set(ORDER))

    def _find(self, filename: str) -> Path | None:
        for d in self.dirs:
            if (d / filename).is_file():
                return d / filename
        return None

    def sources(self, name: str) -> tuple[Path, Path]:
        """Paths of the vertex and fragment files for ``name``."""
        frag = self._find(f"{name}.frag")
        if frag is None:
            raise RenderError(f"unknown shader {name!r}; available: {', '.join(self.names())}")
        # a .vert beside the .frag wins; a user's .frag then takes the user's Name.vert or
        # Default.vert (any user folder, in order), as CS184 pairs within its one folder;
        # then any folder's Name.vert, then Default.vert
        vert: Path | None = frag.with_suffix(".vert")
        if not vert.is_file():
            vert = None
            if frag.parent != BUILTIN_DIR:
                user = self.dirs[:-1]
                vert = _first(user, f"{name}.vert") or _first(user, "Default.vert")
            vert = vert or self._find(f"{name}.vert") or self._find("Default.vert")
        if vert is None:
            raise RenderError(f"no {name}.vert or Default.vert found for shader {name!r}")
        return vert, frag

    def compile(self, ctx, name: str):
        """A moderngl Program, or a RenderError quoting the compiler with file and line."""
        import moderngl

        vert, frag = self.sources(name)
        try:
            return ctx.program(vertex_shader=vert.read_text(), fragment_shader=frag.read_text())
        except moderngl.Error as exc:
            raise RenderError(_compile_message(str(exc), vert, frag)) from None


def _first(dirs: list[Path], filename: str) -> Path | None:
    return next((d / filename for d in dirs if (d / filename).is_file()), None)


def _compile_message(log: str, vert: Path, frag: Path) -> str:
    """One line: the file at fault, the line number and the compiler's words."""
    lower = log.lower()
    if "vertex_shader" in lower or "vertex shader" in lower:
        path = vert
    elif "fragment_shader" in lower or "fragment shader" in lower:
        path = frag
    else:
        path = None
    # Mesa prints "0:12(5): error: ..." ; others "ERROR: 0:12: ..."
    m = re.search(r"0:(\d+)(?:\((\d+)\))?:?\s*(error:?\s*)?(.*)", log, re.IGNORECASE)
    detail = " ".join(log.split())
    if m:
        where = f"line {m.group(1)}"
        detail = m.group(4).strip() or detail
        detail = detail.split("\n")[0]
        return f"{path or f'{vert} / {frag}'}: {where}: shader does not compile: {detail}"
    return f"{path or f'{vert} / {frag}'}: shader does not compile or link: {detail}"
