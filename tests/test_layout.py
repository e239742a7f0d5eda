"""How the package's modules depend on each other: every module imports on its own,
no two modules import each other, and the libraries under the front ends know
nothing of the command line."""

from __future__ import annotations

import ast
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import clothsim

PACKAGE = Path(clothsim.__file__).resolve().parent

LIBRARIES_UNDER_FRONT_ENDS = ("clothsim.render", "clothsim.sweep", "clothsim.viewer")
FRONT_END = "clothsim.cli"
OWN_LAZY_CIRCLES_ALLOWED = ("clothsim.solver",)
"""packages whose function-level imports are not checked for circles here
(only their module-level ones are): the solver keeps its own house"""


def _modules() -> dict[str, Path]:
    """Every module of the package by dotted name (packages by their ``__init__``)."""
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = path
    return out


MODULES = _modules()


def _type_checking_only(tree: ast.Module) -> set[int]:
    """ids of the import nodes under ``if TYPE_CHECKING:``, which never run."""
    skip = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            skip.update(id(n) for stmt in node.body for n in ast.walk(stmt))
    return skip


def _imports(name: str) -> list[tuple[str, bool]]:
    """(imported module, at module level) for each import of the package that ``name`` runs."""
    path = MODULES[name]
    tree = ast.parse(path.read_text(encoding="utf-8"))
    skip = _type_checking_only(tree)
    top = {id(n) for n in tree.body}
    for node in tree.body:  # imports in a top-level try/if still run on import
        if isinstance(node, (ast.Try, ast.If)):
            top.update(id(n) for n in ast.walk(node))
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    found = []
    for node in ast.walk(tree):
        if id(node) in skip or not isinstance(node, (ast.Import, ast.ImportFrom)):
            continue
        targets = []
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        else:
            base = package[:len(package) - node.level + 1] if node.level else []
            module = ".".join(base + ([node.module] if node.module else []))
            for alias in node.names:  # `from . import render` names a module, `from .x import f` a value
                sub = f"{module}.{alias.name}"
                targets.append(sub if sub in MODULES else module)
        for target in targets:
            if target in MODULES and target != name:
                found.append((target, id(node) in top))
    return found


def _circles(edges: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected groups of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    groups = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in edges.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                groups.append(sorted(group))

    for v in MODULES:
        if v not in index:
            visit(v)
    return groups


def _within(name: str, packages) -> bool:
    return any(name == p or name.startswith(p + ".") for p in packages)


def test_no_module_level_import_circles():
    """no two modules import each other, directly or round a loop, when they load"""
    edges = {m: {t for t, top in _imports(m) if top} for m in MODULES}
    assert _circles(edges) == []


def test_no_import_circles_even_inside_functions():
    """outside the solver, not even a deferred import closes a loop (the front end
    and the renderer once called into each other)"""
    edges = {m: {t for t, _ in _imports(m) if not _within(t, OWN_LAZY_CIRCLES_ALLOWED)}
             for m in MODULES if not _within(m, OWN_LAZY_CIRCLES_ALLOWED)}
    assert _circles(edges) == []


def test_libraries_import_no_front_end_and_no_argparse():
    """render/, sweep/ and viewer/ import neither argparse nor anything of clothsim.cli"""
    offenders = []
    for name, path in MODULES.items():
        if not _within(name, LIBRARIES_UNDER_FRONT_ENDS):
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, ast.Import) and any(a.name.split(".")[0] == "argparse" for a in node.names):
                offenders.append(f"{name}: import argparse")
            if isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "") == "argparse":
                offenders.append(f"{name}: from argparse")
        offenders += [f"{name}: {t}" for t, _ in _imports(name) if _within(t, (FRONT_END,))]
    assert offenders == []


def test_every_module_imports_alone():
    """each module imports in a fresh interpreter by itself, whatever was imported before"""
    names = [m for m in MODULES if m != "clothsim.__main__"]

    def load(name: str):
        r = subprocess.run([sys.executable, "-c", f"import {name}"], capture_output=True, text=True)
        return name, r.returncode, r.stderr.strip().splitlines()[-1:]

    with ThreadPoolExecutor(4) as pool:
        failed = [(n, err) for n, code, err in pool.map(load, names) if code != 0]
    assert failed == []
