"""Reading a scene's values: each check takes the key path so that its
:class:`~clothsim.errors.SceneError` names it (``cloth[1].pinned[2]``)."""

from __future__ import annotations

import difflib
import math
import warnings
from typing import Any

from .errors import SceneError, SceneWarning

Vec3 = tuple[float, float, float]


class Reader:
    """``strict``: the items the CS184 program ignores (see :meth:`ignore`) are
    errors too."""

    def __init__(self, source: str | None, strict: bool = False) -> None:
        self.source = source
        self.strict = strict

    def fail(self, key: str | None, message: str) -> SceneError:
        return SceneError(self.source, key, message)

    def ignore(self, key: str, message: str) -> None:
        """An item that CS184 ignores: a :class:`SceneWarning` (``message`` and ", ignored"),
        or under ``strict`` the SceneError of ``message``."""
        if self.strict:
            raise self.fail(key, message)
        warnings.warn(SceneWarning(self.source, key, message + "; ignored"), stacklevel=2)

    def obj(self, value: Any, key: str) -> dict[str, Any]:
        if not isinstance(value, dict):
            raise self.fail(key, f"expected an object, got {describe(value)}")
        return value

    def number(self, value: Any, key: str, *, lo: float | None = None, hi: float | None = None,
               lo_open: bool = False) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(key, f"expected a number, got {describe(value)}")
        try:
            value = float(value)
        except OverflowError:  # an integer beyond a float's range
            value = math.inf if value > 0 else -math.inf
        if not math.isfinite(value):
            raise self.fail(key, f"expected a {_range(lo, hi, lo_open) or 'number'}, got {describe(value)}")
        if (lo is not None and (value < lo or (lo_open and value == lo))) or (hi is not None and value > hi):
            raise self.fail(key, f"expected a {_range(lo, hi, lo_open)}, got {value:g}")
        return value

    def integer(self, value: Any, key: str, *, lo: int | None = None, hi: int | None = None) -> int:
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.fail(key, f"expected an integer, got {describe(value)}")
        if (lo is not None and value < lo) or (hi is not None and value > hi):
            wanted = " and ".join(([f">= {lo}"] if lo is not None else []) + ([f"<= {hi:,}"] if hi is not None else []))
            raise self.fail(key, f"expected an integer {wanted}, got {describe(value)}")
        return value

    def boolean(self, value: Any, key: str) -> bool:
        if not isinstance(value, bool):
            raise self.fail(key, f"expected true or false, got {describe(value)}")
        return value

    def vec3(self, value: Any, key: str, bound: float | None = None) -> Vec3:
        """three numbers, each within ``±bound`` where given"""
        if not isinstance(value, list) or len(value) != 3:
            raise self.fail(key, f"expected a list of 3 numbers, got {describe(value)}")
        lo = None if bound is None else -bound
        x, y, z = (self.number(v, f"{key}[{k}]", lo=lo, hi=bound) for k, v in enumerate(value))
        return (x, y, z)

    def keys(self, obj: dict[str, Any], key: str, allowed: set[str], required: tuple[str, ...],
             lenient: bool = False) -> None:
        """Every key of ``obj`` in ``allowed`` and every ``required`` one there. ``lenient``
        (``cloth``, ``sphere``, ``plane``, whose unknown keys CS184 ignores): an unknown key
        is ignored with a warning naming the nearest known key, an error only under ``strict``."""
        for name in obj:
            if name not in allowed:
                if lenient:
                    # a hint only where one is near: 'colour' is like no key of a cloth
                    nearest = difflib.get_close_matches(name, sorted(allowed), n=1, cutoff=0.6)
                    self.ignore(f"{key}.{name}", "unknown key" + (f" (nearest known key: {nearest[0]!r})"
                                                                 if nearest else "; known keys: "
                                                                 + ", ".join(sorted(allowed))))
                    continue
                raise self.fail(f"{key}.{name}", f"unknown key; expected one of {', '.join(sorted(allowed))}")
        for name in required:
            if name not in obj:
                raise self.fail(f"{key}.{name}", "missing required key")


def describe(value: Any) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f"the string {value!r}" if len(value) <= 60 else f"a string of {len(value)} characters"
    if isinstance(value, list):
        return f"a list of {len(value)}"
    if isinstance(value, dict):
        return "an object"
    if isinstance(value, int) and abs(value) >= 10**15:
        return f"an integer of {len(str(abs(value)))} digits"
    return repr(value)


def _range(lo: float | None, hi: float | None, lo_open: bool) -> str:
    """'number > 0 and <= 1e+06', or '' without bounds"""
    parts = ([f"{'>' if lo_open else '>='} {lo:g}"] if lo is not None else []) + \
        ([f"<= {hi:g}"] if hi is not None else [])
    return "number " + " and ".join(parts) if parts else ""


def as_list(raw: Any) -> list[tuple[str, Any]]:
    """A key that holds one object or (extension) a list of them: (key suffix, item) pairs,
    the suffix ``""`` for a lone object and ``"[k]"`` for the k-th of a list."""
    if isinstance(raw, list):
        return [(f"[{k}]", v) for k, v in enumerate(raw)]
    return [("", raw)]


def too_deep(value: Any, limit: int) -> bool:
    """Whether lists and objects nest more than ``limit`` levels in ``value``
    (walked without recursion, so any depth can be asked about)."""
    stack = [(value, 1)]
    while stack:
        node, depth = stack.pop()
        if isinstance(node, (list, dict)):
            if depth > limit:
                return True
            stack.extend((v, depth + 1) for v in (node.values() if isinstance(node, dict) else node))
    return False
