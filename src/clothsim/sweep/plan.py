"""Turning ``--vary key=v1,v2`` / ``key=start:stop:count`` into a list of runs."""

from __future__ import annotations

import hashlib
import itertools
import json
import re
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import UsageError


@dataclass(frozen=True)
class RunSpec:
    """Everything one run needs; picklable, so it travels to any worker."""

    index: int
    scene: dict[str, Any]
    """the scene JSON before overrides"""
    source: str
    """scene file name, for messages"""
    values: tuple[tuple[str, Any], ...]
    """(dotted key, value) pairs this run sets"""
    seconds: float
    shader: str = "Phong"
    size: tuple[int, int] = (400, 400)
    extra: tuple[str, ...] = field(default_factory=tuple)
    """further --set overrides shared by every run"""

    @property
    def overrides(self) -> list[str]:
        return list(self.extra) + [f"{k}={json.dumps(v)}" for k, v in self.values]

    @property
    def name(self) -> str:
        """file stem: index plus the varied values, safe for any file system"""
        keys = short_keys([k for k, _ in self.values])
        parts = [f"{_INDEX.sub(_unbracket, key)}={_short(v)}" for key, (_, v) in zip(keys, self.values)]
        stem = re.sub(r"[^A-Za-z0-9=._-]+", "_", "_".join(parts)) or "run"
        return f"{self.index:03d}_{stem}"[:120]

    @property
    def label(self) -> str:
        keys = short_keys([k for k, _ in self.values])
        return "  ".join(f"{key}={_short(v)}" for key, (_, v) in zip(keys, self.values)) or "run"

    def digest(self) -> str:
        """changes whenever anything that affects this run's outputs changes"""
        key = json.dumps([self.scene, self.values, self.seconds, self.shader, self.size, self.extra],
                         sort_keys=True, default=str)
        return hashlib.sha256(key.encode()).hexdigest()[:16]


_INDEX = re.compile(r"\[(\d+)\]")
"""a list index in a key: ``cloth[1]`` is named ``cloth1`` in file names"""


def _unbracket(match: re.Match) -> str:
    return match.group(1)


def short_keys(keys: list[str]) -> list[str]:
    """What names and labels call each varied key: its last part (``ks`` for
    ``cloth.ks``), or the whole key where two keys share that part (two cloths'
    ``cloth[0].ks`` and ``cloth[1].ks``)."""
    last = [k.split(".")[-1] for k in keys]
    return [k if last.count(t) > 1 else t for k, t in zip(keys, last)]


def _short(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:g}"
    return json.dumps(v) if not isinstance(v, str) else v


def _number(text: str, what: str) -> Any:
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        raise UsageError(f"--vary {what}: {text!r} is not a number or JSON value") from None


def parse_vary(item: str) -> tuple[str, list[Any]]:
    """'cloth.ks=500,5000' -> ('cloth.ks', [500, 5000]); 'cloth.damping=0:1:5' -> 5 values from 0 to 1."""
    if "=" not in item:
        raise UsageError(f"--vary: expected key=v1,v2,... or key=start:stop:count, got {item!r}")
    key, text = (s.strip() for s in item.split("=", 1))
    if not key or not text:
        raise UsageError(f"--vary: expected key=v1,v2,... or key=start:stop:count, got {item!r}")
    if ":" in text and not text.startswith("["):
        parts = text.split(":")
        if len(parts) != 3:
            raise UsageError(f"--vary {key}: a range is start:stop:count, got {text!r}")
        start, stop, count = (_number(p, key) for p in parts)
        if not isinstance(count, int) or count < 1 or isinstance(count, bool):
            raise UsageError(f"--vary {key}: count must be a positive integer, got {parts[2]!r}")
        values = [float(v) for v in np.linspace(float(start), float(stop), count)]
        return key, [int(v) if float(v).is_integer() and isinstance(start, int) and isinstance(stop, int)
                     else v for v in values]
    return key, [_number(v.strip(), key) for v in _split_top_level(text)]


def _split_top_level(text: str) -> list[str]:
    """split on commas outside brackets, so [0,-9.8,0] stays one value"""
    out, depth, cur = [], 0, ""
    for ch in text:
        if ch == "," and depth == 0:
            out.append(cur)
            cur = ""
            continue
        depth += ch in "[{"
        depth -= ch in "]}"
        cur += ch
    out.append(cur)
    return [v for v in out if v.strip()]


def plan_runs(scene: dict[str, Any], source: str, varies: list[str], seconds: float, shader: str,
              size: tuple[int, int], extra: tuple[str, ...] = ()) -> list[RunSpec]:
    """The cross product of every --vary list, in the order given."""
    axes = [parse_vary(v) for v in varies]
    keys = [k for k, _ in axes]
    if len(set(keys)) != len(keys):
        raise UsageError("--vary: the same key is given twice")
    combos = itertools.product(*[vals for _, vals in axes]) if axes else [()]
    return [RunSpec(i, scene, source, tuple(zip(keys, combo)), seconds, shader, size, tuple(extra))
            for i, combo in enumerate(combos)]
