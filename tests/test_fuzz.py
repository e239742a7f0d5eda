"""Fuzzing the scene files and ``--set`` values: whatever the input, ``clothsim
simulate`` ends in one of the allowed outcomes.

Hypothesis mutates the standard scenes (keys dropped, types swapped, extreme
numbers, NaN and infinity literals and strings, integers of thousands of
digits, deep nesting, long lists, unicode keys) and draws ``--set`` values of
the same kinds. Every case runs through the command's own ``main()`` in a
batch process (``tests/fuzz_driver.py``), one process per batch so that a crash
is caught, and must end in:

- exit 0 with the summary on stdout, or
- exit 2 with exactly one stderr line ``clothsim: error: ...`` that names the
  scene file or the ``--set`` key, or says the simulation became unstable;

never a traceback, a death by a signal, or a run past the time limit.

``CLOTHSIM_FUZZ_EXAMPLES=N`` runs N cases (default 2,000, in batches of
:data:`BATCH`).
"""

from __future__ import annotations

import copy
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from .conftest import SCENES  # noqa: E402

DRIVER = Path(__file__).with_name("fuzz_driver.py")
EXAMPLES = int(os.environ.get("CLOTHSIM_FUZZ_EXAMPLES", "2000"))
BATCH = 100
"""cases per driver process: its start (imports, cached kernels) costs about a second"""
BATCH_TIMEOUT_S = 600
"""a whole batch, cold kernel cache included"""
GRID_POINTS = 5
"""each side of every grid cloth before mutation, so that a run takes milliseconds"""
COMPILING = "clothsim: compiling"


class Raw:
    """JSON text written as is: literals Python's json would not make (NaN, 1e999, a 5,000-digit integer)."""

    def __init__(self, text: str) -> None:
        self.text = text

    def __repr__(self) -> str:
        return f"Raw({self.text[:30]!r})"


def to_text(value) -> str:
    if isinstance(value, Raw):
        return value.text
    if isinstance(value, dict):
        return "{" + ", ".join(f"{json.dumps(k)}: {to_text(v)}" for k, v in value.items()) + "}"
    if isinstance(value, list):
        return "[" + ", ".join(to_text(v) for v in value) + "]"
    return json.dumps(value)


def standard_scenes() -> dict[str, dict]:
    out = {}
    for path in sorted(SCENES.glob("*.json")):
        data = json.loads(path.read_text())
        cloths = data["cloth"] if isinstance(data["cloth"], list) else [data["cloth"]]
        for cloth in cloths:  # tiny grids: a run takes milliseconds
            if "num_width_points" in cloth:
                cloth["num_width_points"] = cloth["num_height_points"] = GRID_POINTS
                cloth["pinned"] = [p for p in cloth.get("pinned", []) if max(p) < GRID_POINTS]
                # a handle point outside the grid is an error: keep the handles' points that remain
                handles = [dict(h, points=[p for p in h["points"] if max(p) < GRID_POINTS])
                           for h in cloth.get("handles", [])]
                handles = [h for h in handles if h["points"]]
                if "handles" in cloth:
                    cloth["handles"] = handles
        out[path.stem] = data
    return out


BASES = standard_scenes()

EXTREME_NUMBERS = [0, 0.0, -0.0, 1, -1, 2, 0.5, 5e-324, -5e-324, 1e-8, 1e-300, 1e308, -1e308,
                   2 ** 31, 2 ** 63, -(2 ** 63), 2 ** 64, 10 ** 30]
EXTREME_RAW = ["NaN", "Infinity", "-Infinity", "-0", "1e999", "-1e999", "9" * 5000, "-" + "9" * 400,
               "1e-400", "0.0000000000000000000000000000001"]
EXTREME_STRINGS = ["nan", "inf", "-inf", "NaN", "Infinity", "1e308", "", " ", "0", "true", "null",
                   "\u00e9\u4e2d\U0001f600", "a" * 3000]


def deep(depth: int, kind: str) -> Raw:
    if kind == "list":
        return Raw("[" * depth + "]" * depth)
    return Raw('{"a": ' * depth + "{}" + "}" * depth)


replacement = st.one_of(
    st.sampled_from(EXTREME_NUMBERS),
    st.sampled_from(EXTREME_RAW).map(Raw),
    st.sampled_from(EXTREME_STRINGS),
    st.sampled_from([None, True, False, [], {}, [0], [[]], {"": 0}]),
    st.floats(allow_nan=False, allow_infinity=False),
    st.integers(min_value=-(2 ** 70), max_value=2 ** 70),
    st.builds(deep, st.sampled_from([10, 60, 200, 5000]), st.sampled_from(["list", "dict"])),
    st.builds(lambda n, v: [v] * n, st.sampled_from([3, 4, 1000, 20000]), st.sampled_from([0, 0.5, [0, 0], "x"])),
    st.text(max_size=8),
).map(copy.deepcopy)  # a later mutation must not change the shared originals

unicode_key = st.one_of(st.sampled_from(["\u00e9", "\u4e2d\u6587", "\U0001f600", "", " ", "cloth ", "CLOTH",
                                         "num_width_points\u200b", "\x00"]), st.text(max_size=6))


def paths(value, prefix=()):
    """Every (path, value) in a JSON tree; a path is a tuple of keys and indices."""
    yield prefix, value
    if isinstance(value, dict):
        for k, v in value.items():
            yield from paths(v, prefix + (k,))
    elif isinstance(value, list) and len(value) <= 64:
        for i, v in enumerate(value):
            yield from paths(v, prefix + (i,))


def dotted(path) -> str:
    out = ""
    for part in path:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def swap_type(value):
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, (int, float)):
        return [value] if isinstance(value, int) else str(value)
    if isinstance(value, str):
        return {value: value}
    if isinstance(value, list):
        return {str(i): v for i, v in enumerate(value)}
    if isinstance(value, dict):
        return list(value.values())
    return 0


@st.composite
def mutated_scene(draw) -> dict:
    scene = copy.deepcopy(BASES[draw(st.sampled_from(sorted(BASES)))])
    for _ in range(draw(st.integers(0, 4))):
        found = list(paths(scene))
        path, value = found[draw(st.integers(0, len(found) - 1))]
        op = draw(st.sampled_from(["drop", "replace", "replace", "swap", "add_key", "wrap"]))
        if op == "add_key" and isinstance(value, dict):
            value[draw(unicode_key)] = draw(replacement)
            continue
        if not path:
            if op == "drop":
                scene = {}
            continue
        parent = scene
        for part in path[:-1]:
            parent = parent[part]
        last = path[-1]
        if op == "drop":
            if isinstance(parent, dict):
                del parent[last]
            else:
                parent.pop(last)
        elif op == "swap":
            parent[last] = swap_type(value)
        elif op == "wrap":
            parent[last] = [value]
        else:
            parent[last] = draw(replacement)
    sets = []
    if draw(st.booleans()):
        keys = [dotted(p) for p, _ in paths(scene) if p]
        for _ in range(draw(st.integers(1, 3))):
            key = draw(st.one_of(st.sampled_from(keys), unicode_key, st.sampled_from(
                ["cloth.ks", "cloth.thickness", "simulation.simulation_steps", "sphere[0].radius",
                 "cloth[1].density", "a..b", "cloth[", "cloth[-1].ks", "cloth[99999999999999999999].ks"]))) \
                if keys else draw(unicode_key)
            value = draw(replacement)
            sets.append(f"{key}={to_text(value)}")
    return {"scene": to_text(scene), "sets": sets}


def run_batch(cases: list[dict]) -> tuple[subprocess.CompletedProcess, list[dict]]:
    folder = Path(tempfile.mkdtemp(prefix="clothsim-fuzz-"))
    try:
        shutil.copytree(SCENES / "meshes", folder / "meshes")
        (folder / "cases.json").write_text(json.dumps(cases), encoding="utf-8")
        env = dict(os.environ, CLOTHSIM_PREWARM="0")
        try:
            proc = subprocess.run([sys.executable, str(DRIVER), str(folder / "cases.json"), str(folder / "report.jsonl")],
                                  capture_output=True, text=True, timeout=BATCH_TIMEOUT_S, env=env)
        except subprocess.TimeoutExpired as exc:
            raise AssertionError(f"a batch ran past {BATCH_TIMEOUT_S} s; last started: "
                                 f"{_last_case(exc.stderr, cases)}") from None
        report = folder / "report.jsonl"
        outcomes = [json.loads(line) for line in report.read_text().splitlines()] if report.exists() else []
        return proc, outcomes
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def _last_case(stderr, cases) -> str:
    if isinstance(stderr, bytes):
        stderr = stderr.decode(errors="replace")
    started = [line for line in (stderr or "").splitlines() if line.startswith("case ")]
    if not started:
        return "none"
    case = cases[int(started[-1].split()[1])]
    return f"case {started[-1]}: sets {case['sets']!r}, scene {case['scene'][:2000]}"


def check_outcome(case: dict, outcome: dict) -> None:
    """Assert that one case ended in an allowed way."""
    where = f"sets {case['sets']!r}, scene {case['scene'][:2000]}"
    assert outcome["exception"] is None, f"{outcome['exception']}\n{where}"
    lines = [line for line in outcome["stderr"].splitlines() if not line.startswith(COMPILING)]
    assert "Traceback" not in outcome["stderr"], f"{outcome['stderr']}\n{where}"
    # what the CS184 loader ignores is ignored with one warning line each, naming the file
    warned = [line for line in lines if line.startswith("clothsim: warning:")]
    for line in warned:
        assert f"scene_{outcome['case']}.json" in line and line.endswith("; ignored"), f"{line}\n{where}"
    lines = [line for line in lines if line not in warned]
    if outcome["rc"] == 0:
        assert outcome["stdout"].strip(), where
        assert not lines, f"{outcome['stderr']}\n{where}"
        return
    assert outcome["rc"] == 2, f"exit {outcome['rc']}: {outcome['stderr']}\n{where}"
    assert len(lines) == 1 and lines[0].startswith("clothsim: error:"), f"{outcome['stderr']!r}\n{where}"
    line = lines[0]
    named = f"scene_{outcome['case']}.json" in line or "--set" in line or "became unstable" in line
    assert named, f"the error names neither the file, the key nor the blow-up: {line}\n{where}"


def check_batch(cases: list[dict]) -> None:
    proc, outcomes = run_batch(cases)
    assert proc.returncode == 0 and len(outcomes) == len(cases), (
        f"the batch process ended with {proc.returncode} after {len(outcomes)} of {len(cases)} cases; "
        f"last started: {_last_case(proc.stderr, cases)}\n{proc.stderr[-3000:]}")
    for case, outcome in zip(cases, outcomes):
        check_outcome(case, outcome)


@settings(max_examples=max(1, math.ceil(EXAMPLES / BATCH)), deadline=None,
          derandomize="CLOTHSIM_FUZZ_EXAMPLES" not in os.environ,
          suppress_health_check=list(HealthCheck), print_blob=True)
@given(st.lists(mutated_scene(), min_size=BATCH, max_size=BATCH))
def test_any_mutated_scene_or_set_value_ends_in_a_result_or_one_error_line(cases):
    check_batch(cases)


def test_the_unmutated_small_standard_scenes_run():
    """The fuzz's starting points are themselves valid: each exits 0."""
    proc, outcomes = run_batch([{"scene": to_text(scene), "sets": []} for scene in BASES.values()])
    assert [o["rc"] for o in outcomes] == [0] * len(BASES), outcomes


def test_an_error_quoting_a_key_with_control_characters_is_one_line():
    """A key such as ``"\\x0b"`` or ``"\\u2028"`` is shown escaped: the error stays one line on a terminal."""
    scene = copy.deepcopy(BASES["sphere"])
    scene["cloth"]["a\x0bb\u2028c\x1c"] = 1
    cases = [{"scene": to_text(scene), "sets": [], "options": ["--strict"]},
             {"scene": to_text(BASES["sphere"]), "sets": ["cloth.\x0c\x85=1"], "options": ["--strict"]},
             {"scene": to_text(scene), "sets": []}]  # not strict: a warning, also one line
    proc, outcomes = run_batch(cases)
    for case, outcome in zip(cases, outcomes):
        check_outcome(case, outcome)
    assert [o["rc"] for o in outcomes] == [2, 2, 0]
    assert "a\\x0bb\\u2028c\\x1c" in outcomes[0]["stderr"] and "a\\x0bb\\u2028c\\x1c" in outcomes[2]["stderr"]
