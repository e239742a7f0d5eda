"""The command line's value parsers and their bounds.

Each raises :class:`~clothsim.errors.UsageError` naming the option, so a bad
value is one line and exit code 2 before anything runs (``main`` parses the
arguments inside its error handling). A number is refused when it is not
finite or lies outside its bound: the bounds keep frame counts, image sizes,
tessellations and thread counts to what a run can allocate.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from ..errors import UsageError
from ..scene_limits import RUN_FRAMES_MAX

SECONDS_MAX = 1e6
"""longest simulated time of a run [s]"""
FRAMES_MAX = RUN_FRAMES_MAX
"""most frames of a run (--seconds times the scene's frames_per_sec), as the library's"""
VIDEO_FPS_MAX = 1000.0
"""highest --fps of a video"""
THREADS_MAX = 1024
"""most --threads and --workers"""
SIZE_MIN, SIZE_MAX = 16, 8192
"""the range of each side of an image or window [pixels]"""
SPHERE_RES_MAX = 1000
"""most latitude bands and longitude segments of a drawn sphere"""
LOOK_MAX = 1e6
"""largest magnitude of a look value: colour, light, camera, scalings"""


def _range(lo: float, hi: float, lo_open: bool) -> str:
    return f"a number {'>' if lo_open else '>='} {lo:g} and <= {hi:g}"


def check_number(value: float, option: str, lo: float, hi: float, lo_open: bool = False) -> float:
    """``value`` when finite and within ``lo..hi``, else a UsageError naming ``option``."""
    if not (math.isfinite(value) and lo <= value <= hi and not (lo_open and value == lo)):
        raise UsageError(f"{option}: expected {_range(lo, hi, lo_open)}, got {value:g}")
    return value


def bounded_float(option: str, lo: float, hi: float, lo_open: bool = False) -> Callable[[str], float]:
    """An argparse ``type``: a finite number within ``lo..hi``."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise UsageError(f"{option}: expected {_range(lo, hi, lo_open)}, got {text[:40]!r}") from None
        return check_number(value, option, lo, hi, lo_open)
    return parse


def bounded_int(option: str, lo: int, hi: int) -> Callable[[str], int]:
    """An argparse ``type``: a whole number within ``lo..hi``."""
    def parse(text: str) -> int:
        digits = text.strip().lstrip("+-")
        value = int(text) if digits.isascii() and digits.isdigit() and len(digits) <= 18 else None
        if value is None or not lo <= value <= hi:
            raise UsageError(f"{option}: expected a whole number from {lo} to {hi:,}, got {text[:40]!r}")
        return value
    return parse


def positive_int(text: str) -> int:
    """A whole number of at least 1 (and at most :data:`THREADS_MAX`: it counts threads)."""
    return bounded_int("--threads", 1, THREADS_MAX)(text)


def check_seconds(seconds: float) -> None:
    check_number(seconds, "--seconds", 0.0, SECONDS_MAX)


def frame_count(seconds: float, frames_per_sec: float) -> int:
    """The frames of ``seconds`` at the scene's rate, at most :data:`FRAMES_MAX`."""
    check_seconds(seconds)
    frames = max(0, round(seconds * frames_per_sec))
    if frames > FRAMES_MAX:
        raise UsageError(f"--seconds: {seconds:g} s at the scene's {frames_per_sec:g} frames/s is "
                         f"{frames:,} frames; expected at most {FRAMES_MAX:,}")
    return frames


def _whole(text: str) -> int | None:
    text = text.strip()
    return int(text) if text.isascii() and text.isdigit() and len(text) <= 6 else None


def parse_size(text: str, option: str = "--size") -> tuple[int, int]:
    """``WIDTHxHEIGHT`` in pixels, each 16..8192."""
    parts = [_whole(p) for p in text.lower().split("x")]
    if len(parts) != 2 or not all(p is not None and SIZE_MIN <= p <= SIZE_MAX for p in parts):
        raise UsageError(f"{option}: expected WIDTHxHEIGHT with each {SIZE_MIN}..{SIZE_MAX}, got {text[:40]!r}")
    return parts[0], parts[1]


def parse_floats(text: str, count: int, option: str) -> tuple[float, ...]:
    """``count`` comma-separated finite numbers within ±:data:`LOOK_MAX`, e.g. ``--color 0.8,0.2,0.2``."""
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != count or not all(math.isfinite(v) and abs(v) <= LOOK_MAX for v in values):
        raise UsageError(f"{option}: expected {count} comma-separated numbers within ±{LOOK_MAX:g}, "
                         f"got {text[:60]!r}")
    return values


def parse_sphere_res(text: str) -> tuple[int, int]:
    """``N`` or ``LAT,LON``: latitude bands 2.., longitude segments 3.., each at most :data:`SPHERE_RES_MAX`."""
    from ..render.geometry import parse_resolution

    parts = [p for p in text.replace("x", ",").split(",") if p.strip()]
    if not all(_whole(p) is not None and _whole(p) <= SPHERE_RES_MAX for p in parts):
        raise UsageError(f"--sphere-res: expected N or LAT,LON, each a whole number up to {SPHERE_RES_MAX}, "
                         f"got {text[:40]!r}")
    try:
        return parse_resolution(text)
    except ValueError as exc:
        raise UsageError(f"--sphere-res: {exc}") from None
