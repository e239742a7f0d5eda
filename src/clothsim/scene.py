"""Scene files: the CS184 ClothSim JSON format plus clothsim's extensions.

A scene is validated here once, completely, so that nothing downstream has
to guess: every bad value becomes a :class:`SceneError` naming the file, the
key path and what was expected. See ``shared/scene-format.md`` for the format.
"""

from __future__ import annotations

import copy
import json
import math
import re
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from .errors import SceneError
from .motion import Animation
from .world_spec import BoxSpec, HandleSpec, MeshColliderSpec, WindSpec, with_animation
from .mesh_spec import MeshClothSpec, MeshTransform, is_mesh_cloth, parse_mesh_cloth
from .scene_limits import (DENSITY_MAX, DENSITY_MIN, DEPTH_MAX, FPS_MAX, FPS_MIN, GRAVITY_MAX, KS_MAX, LENGTH_MAX,
                           LENGTH_MIN, POINTS_MAX, SEED_MAX, STEPS_MAX)
from .scene_reader import Reader as _Reader
from .scene_reader import Vec3
from .scene_reader import as_list as _as_list
from .scene_reader import describe as _describe
from .scene_reader import too_deep as _too_deep
from .world_reader import (optional_animation, parse_boxes, parse_grid_handles, parse_mesh_colliders,
                           parse_wind)

__all__ = ["ClothSpec", "MeshClothSpec", "MeshTransform", "PlaneSpec", "Scene", "SimulationSpec", "SphereSpec",
           "apply_overrides", "load_scene", "parse_scene", "read_scene_json"]


@dataclass
class ClothSpec:
    """The sheet of cloth: geometry, material and which springs act."""

    width: float
    """size along the width axis [m]"""
    height: float
    """size along the height axis [m]"""
    num_width_points: int
    num_height_points: int
    thickness: float
    """self-collision keeps points ``2*thickness`` apart [m]"""
    orientation: int
    """0 = horizontal (in the y=1 plane), 1 = vertical (in the z≈0 plane)"""
    pinned: list[tuple[int, int]] = field(default_factory=list)
    """grid indices ``(i, j)`` of point masses that never move"""
    damping: float = 0.2
    """percent of velocity removed per substep"""
    density: float = 150.0
    """g/cm² as in CS184; sets the mass of each point"""
    ks: float = 5000.0
    """spring constant [N/m]; bending springs use 0.2*ks"""
    enable_structural: bool = True
    enable_shearing: bool = True
    enable_bending: bool = True
    handles: list[HandleSpec] = field(default_factory=list)
    """groups of points moved by an animation"""


@dataclass
class SphereSpec:
    origin: Vec3
    radius: float
    friction: float
    animation: Animation | None = None


@dataclass
class PlaneSpec:
    point: Vec3
    normal: Vec3
    """unit normal (normalised on load)"""
    friction: float
    animation: Animation | None = None


@dataclass
class SimulationSpec:
    frames_per_sec: float = 90.0
    simulation_steps: int = 30
    """substeps per frame"""
    gravity: Vec3 = (0.0, -9.8, 0.0)
    """[m/s²]"""
    self_collision: bool = True
    seed: int = 0
    """seeds the small z jitter of vertical cloth"""


@dataclass
class Scene:
    cloths: list[ClothSpec | MeshClothSpec]
    """the cloths in scene order (the ``cloth`` key: one object or a list), each
    a grid or (with the key ``mesh``) a mesh cloth"""
    spheres: list[SphereSpec] = field(default_factory=list)
    planes: list[PlaneSpec] = field(default_factory=list)
    simulation: SimulationSpec = field(default_factory=SimulationSpec)
    boxes: list[BoxSpec] = field(default_factory=list)
    mesh_colliders: list[MeshColliderSpec] = field(default_factory=list)
    """the top-level key ``mesh``"""
    wind: WindSpec | None = None
    source: str | None = None
    """where the scene came from, used in messages"""

    @property
    def cloth(self) -> ClothSpec | MeshClothSpec:
        """the first cloth (the only one of a CS184 scene)"""
        return self.cloths[0]

    def to_dict(self) -> dict[str, Any]:
        """The scene as a JSON-ready dict that :func:`parse_scene` reads back."""
        cloths = [_cloth_dict(c) for c in self.cloths]
        out: dict[str, Any] = {"cloth": cloths[0] if len(cloths) == 1 else cloths}
        if self.spheres:
            out["sphere"] = [with_animation({"origin": list(s.origin), "radius": s.radius,
                                              "friction": s.friction}, s.animation) for s in self.spheres]
        if self.planes:
            out["plane"] = [with_animation({"point": list(p.point), "normal": list(p.normal),
                                             "friction": p.friction}, p.animation) for p in self.planes]
        if self.boxes:
            out["box"] = [b.to_dict() for b in self.boxes]
        if self.mesh_colliders:
            out["mesh"] = [m.to_dict() for m in self.mesh_colliders]
        if self.wind is not None:
            out["wind"] = self.wind.to_dict()
        out["simulation"] = asdict(self.simulation)
        return json.loads(json.dumps(out))


def _cloth_dict(spec: ClothSpec | MeshClothSpec) -> dict[str, Any]:
    if isinstance(spec, MeshClothSpec):
        return spec.to_dict()
    cloth = asdict(spec)
    cloth["pinned"] = [list(p) for p in spec.pinned]
    del cloth["handles"]
    if spec.handles:
        cloth["handles"] = [h.to_dict() for h in spec.handles]
    return cloth


_CLOTH_REQUIRED = ("width", "height", "num_width_points", "num_height_points", "thickness", "orientation")
_CLOTH_KEYS = set(_CLOTH_REQUIRED) | {"pinned", "damping", "density", "ks", "enable_structural",
                                     "enable_shearing", "enable_bending", "handles"}
_TOP_KEYS = {"cloth", "sphere", "plane", "simulation", "box", "mesh", "wind"}


def _parse_cloths(r: _Reader, raw: Any) -> list[ClothSpec | MeshClothSpec]:
    """``cloth``: one object, or (extension) a non-empty list of them; an object
    with the key ``mesh`` is a mesh cloth."""
    if isinstance(raw, list) and not raw:
        raise r.fail("cloth", "expected a cloth object or a non-empty list of them, got an empty list")
    return [parse_mesh_cloth(r, item, "cloth" + suffix) if is_mesh_cloth(item) else
            _parse_cloth(r, item, "cloth" + suffix) for suffix, item in _as_list(raw)]


def _parse_cloth(r: _Reader, raw: Any, key: str = "cloth") -> ClothSpec:
    c = r.obj(raw, key)
    r.keys(c, key, _CLOTH_KEYS, _CLOTH_REQUIRED, lenient=True)
    nw = r.integer(c["num_width_points"], f"{key}.num_width_points", lo=2, hi=POINTS_MAX // 2)
    nh = r.integer(c["num_height_points"], f"{key}.num_height_points", lo=2, hi=POINTS_MAX // 2)
    if nw * nh > POINTS_MAX:
        raise r.fail(key, f"expected at most {POINTS_MAX:,} points (num_width_points x num_height_points), "
                          f"got {nw} x {nh} = {nw * nh:,}")
    orientation = r.integer(c["orientation"], f"{key}.orientation")
    if orientation not in (0, 1):
        raise r.fail(f"{key}.orientation", f"expected 0 (horizontal) or 1 (vertical), got {orientation}")
    pinned_raw = c.get("pinned", [])
    if not isinstance(pinned_raw, list):
        raise r.fail(f"{key}.pinned", f"expected a list of [i, j] pairs, got {_describe(pinned_raw)}")
    pinned: list[tuple[int, int]] = []
    for k, p in enumerate(pinned_raw):
        pkey = f"{key}.pinned[{k}]"
        if not isinstance(p, list) or len(p) != 2:
            raise r.fail(pkey, f"expected a pair [i, j], got {_describe(p)}")
        i = r.integer(p[0], pkey + "[0]")
        j = r.integer(p[1], pkey + "[1]")
        if not (0 <= i < nw and 0 <= j < nh):  # CS184 pins nothing for it
            r.ignore(pkey, f"expected a point inside the {nw}x{nh} grid (i in 0..{nw - 1}, "
                           f"j in 0..{nh - 1}), got [{i}, {j}]")
            continue
        pinned.append((i, j))
    return ClothSpec(
        width=r.number(c["width"], f"{key}.width", lo=LENGTH_MIN, hi=LENGTH_MAX),
        height=r.number(c["height"], f"{key}.height", lo=LENGTH_MIN, hi=LENGTH_MAX),
        num_width_points=nw,
        num_height_points=nh,
        thickness=r.number(c["thickness"], f"{key}.thickness", lo=LENGTH_MIN, hi=LENGTH_MAX),
        orientation=orientation,
        pinned=pinned,
        damping=r.number(c.get("damping", 0.2), f"{key}.damping", lo=0, hi=100),
        density=r.number(c.get("density", 150.0), f"{key}.density", lo=DENSITY_MIN, hi=DENSITY_MAX),
        ks=r.number(c.get("ks", 5000.0), f"{key}.ks", lo=0, hi=KS_MAX),
        enable_structural=r.boolean(c.get("enable_structural", True), f"{key}.enable_structural"),
        enable_shearing=r.boolean(c.get("enable_shearing", True), f"{key}.enable_shearing"),
        enable_bending=r.boolean(c.get("enable_bending", True), f"{key}.enable_bending"),
        handles=parse_grid_handles(r, c["handles"], f"{key}.handles", nw, nh, pinned) if "handles" in c else [],
    )


def _parse_spheres(r: _Reader, raw: Any) -> list[SphereSpec]:
    out = []
    for suffix, item in _as_list(raw):
        key = "sphere" + suffix
        s = r.obj(item, key)
        r.keys(s, key, {"origin", "radius", "friction", "animation"}, ("origin", "radius", "friction"),
               lenient=True)
        out.append(SphereSpec(
            origin=r.vec3(s["origin"], key + ".origin", LENGTH_MAX),
            radius=r.number(s["radius"], key + ".radius", lo=LENGTH_MIN, hi=LENGTH_MAX),
            friction=r.number(s["friction"], key + ".friction", lo=0, hi=1),
            animation=optional_animation(r, s, key),
        ))
    return out


def _parse_planes(r: _Reader, raw: Any) -> list[PlaneSpec]:
    out = []
    for suffix, item in _as_list(raw):
        key = "plane" + suffix
        p = r.obj(item, key)
        r.keys(p, key, {"point", "normal", "friction", "animation"}, ("point", "normal", "friction"),
               lenient=True)
        out.append(PlaneSpec(
            point=r.vec3(p["point"], key + ".point", LENGTH_MAX),
            normal=_unit(r, r.vec3(p["normal"], key + ".normal"), key + ".normal"),
            friction=r.number(p["friction"], key + ".friction", lo=0, hi=1),
            animation=optional_animation(r, p, key),
        ))
    return out


def _unit(r: _Reader, v: Vec3, key: str) -> Vec3:
    """``v`` over its length, scaled by its largest component first so that neither
    squaring 1e200 (inf) nor squaring 1e-200 (0) loses it."""
    scale = max(abs(c) for c in v)
    if scale == 0:
        raise r.fail(key, "expected a non-zero vector, got [0, 0, 0]")
    x, y, z = (c / scale for c in v)
    length = math.sqrt(x * x + y * y + z * z)
    if not (math.isfinite(length) and length > 0):
        raise r.fail(key, f"expected a vector with a direction, got {list(v)}")
    return (x / length, y / length, z / length)


def _parse_simulation(r: _Reader, raw: Any) -> SimulationSpec:
    s = r.obj(raw, "simulation")
    r.keys(s, "simulation", {"frames_per_sec", "simulation_steps", "gravity", "self_collision", "seed"}, ())
    d = SimulationSpec()
    return SimulationSpec(
        frames_per_sec=r.number(s.get("frames_per_sec", d.frames_per_sec), "simulation.frames_per_sec",
                                lo=FPS_MIN, hi=FPS_MAX),
        simulation_steps=r.integer(s.get("simulation_steps", d.simulation_steps),
                                   "simulation.simulation_steps", lo=1, hi=STEPS_MAX),
        gravity=r.vec3(s.get("gravity", list(d.gravity)), "simulation.gravity", GRAVITY_MAX),
        self_collision=r.boolean(s.get("self_collision", d.self_collision), "simulation.self_collision"),
        seed=r.integer(s.get("seed", d.seed), "simulation.seed", lo=0, hi=SEED_MAX),
    )


def parse_scene(data: Any, source: str | None = None, strict: bool = False) -> Scene:
    """Validate a decoded JSON document; raise :class:`SceneError` on the first fault.

    What the CS184 program ignores (an unknown key inside ``cloth``, ``sphere`` or
    ``plane``, a pinned point outside the grid) is ignored here too, each item
    with a :class:`~clothsim.errors.SceneWarning`, or is a SceneError when ``strict``.
    """
    r = _Reader(source, strict)
    if not isinstance(data, dict):
        raise r.fail(None, f"expected a JSON object at the top level, got {_describe(data)}")
    for name in data:
        if name not in _TOP_KEYS:
            raise r.fail(name, f"unknown top-level key; expected one of {', '.join(sorted(_TOP_KEYS))}")
    if "cloth" not in data:
        raise r.fail("cloth", "missing required key")
    return Scene(
        cloths=_parse_cloths(r, data["cloth"]),
        spheres=_parse_spheres(r, data["sphere"]) if "sphere" in data else [],
        planes=_parse_planes(r, data["plane"]) if "plane" in data else [],
        simulation=_parse_simulation(r, data.get("simulation", {})),
        boxes=parse_boxes(r, data["box"]) if "box" in data else [],
        mesh_colliders=parse_mesh_colliders(r, data["mesh"]) if "mesh" in data else [],
        wind=parse_wind(r, data["wind"]) if "wind" in data else None,
        source=source,
    )


def read_scene_json(path: str | Path) -> dict[str, Any]:
    """Read the raw JSON of a scene file, turning I/O and syntax faults into SceneError."""
    source = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SceneError(source, None, "no such file") from None
    except IsADirectoryError:
        raise SceneError(source, None, "expected a scene file, got a directory") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError(source, None, f"cannot read: {exc}") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise SceneError(source, None, f"invalid JSON at line {exc.lineno}, column {exc.colno}: {exc.msg}") from None
    except RecursionError:
        raise SceneError(source, None, _TOO_DEEP) from None
    except ValueError as exc:  # an integer of more digits than Python converts
        raise SceneError(source, None, f"invalid JSON: {exc}".split("; use")[0]) from None
    if _too_deep(data, DEPTH_MAX):
        raise SceneError(source, None, _TOO_DEEP)
    return data


_TOO_DEEP = f"expected lists and objects nested at most {DEPTH_MAX} levels deep"


def load_scene(path: str | Path, overrides: list[str] | tuple[str, ...] = (), strict: bool = False) -> Scene:
    """Load and validate a scene file, applying ``key=value`` overrides first.

    Lenient as the CS184 loader is: an unknown key inside ``cloth``, ``sphere`` or
    ``plane`` (a student's extra key, a typo) and a pinned point outside the grid
    are ignored, one :class:`~clothsim.errors.SceneWarning` each, naming the file,
    the key (and the nearest known key); with ``strict`` they are
    :class:`SceneError` like any other fault.

    They are warnings of the :mod:`warnings` module, not log records, because
    that is what a library's caller already controls without setting anything
    up: shown once by default in a script or notebook, caught by
    ``warnings.catch_warnings``/``pytest.warns``, turned into exceptions by
    ``warnings.simplefilter("error", SceneWarning)``. The ``clothsim`` command
    prints each as one line ``clothsim: warning: FILE: KEY: ...`` on stderr.
    """
    data = read_scene_json(path)
    data = apply_overrides(data, overrides, str(path))
    return parse_scene(data, str(path), strict)


_PATH_PART = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)((?:\[\d+\])*)")


def apply_overrides(data: Any, overrides: list[str] | tuple[str, ...], source: str | None = None) -> Any:
    """Return a copy of ``data`` with each ``dotted.key[0]=value`` set.

    The value is read as JSON when it parses (``500``, ``true``, ``[0,-9.8,0]``)
    and as a string otherwise, so validation later names the key if it is wrong.
    """
    if _too_deep(data, DEPTH_MAX):
        raise SceneError(source, None, _TOO_DEEP)
    data = copy.deepcopy(data)
    for item in overrides:
        if "=" not in item:
            raise SceneError(source, None, f"--set expects key=value, got {item!r}")
        key, text = item.split("=", 1)
        key = key.strip()
        value = _override_value(text, source, key)
        steps: list[str | int] = []
        for part in key.split("."):
            m = _PATH_PART.fullmatch(part)
            if not m:
                raise SceneError(source, key, "--set expects a dotted key such as cloth.ks or sphere[0].radius")
            steps.append(m.group(1))
            steps.extend(int(k) for k in re.findall(r"\[(\d+)\]", m.group(2)))
        node, parent = data, None
        for depth, step in enumerate(steps[:-1]):
            nxt = steps[depth + 1]
            if isinstance(step, int):
                if _lone(node, depth, steps):
                    _check_lone(step, source, key, steps[0])
                    continue  # cloth[0] of a scene with one cloth object is that object
                if not isinstance(node, list) or step >= len(node):
                    raise SceneError(source, key, "--set names a list element that the scene does not have")
                parent, node = (node, step), node[step]
            else:
                if not isinstance(node, dict):
                    raise SceneError(source, key, "--set names a key inside something that is not an object")
                if step not in node:
                    node[step] = [] if isinstance(nxt, int) else {}
                parent, node = (node, step), node[step]
        last = steps[-1]
        if isinstance(last, int) and parent is not None and _lone(node, len(steps) - 1, steps):
            _check_lone(last, source, key, steps[0])
            parent[0][parent[1]] = value  # sphere[0]={...} replaces the lone sphere
            continue
        if isinstance(last, int):
            if not isinstance(node, list) or last >= len(node):
                raise SceneError(source, key, "--set names a list element that the scene does not have")
        elif not isinstance(node, dict):
            raise SceneError(source, key, "--set names a key inside something that is not an object")
        node[last] = value
    return data


_COLLIDER_KEYS = ("cloth", "sphere", "plane", "box", "mesh")
"""the top-level keys that hold one object or a list of them"""


def _lone(node: Any, depth: int, steps: list[str | int]) -> bool:
    """Whether ``node``, reached by ``steps[:depth]``, is the lone object of a key
    that may hold one object or a list (``sphere`` in ``sphere[0].radius``)."""
    return depth == 1 and steps[0] in _COLLIDER_KEYS and isinstance(node, dict)


def _check_lone(index: int, source: str | None, key: str, name: Any) -> None:
    if index != 0:
        raise SceneError(source, key, f"--set names {name}[{index}], but {name} holds one object "
                                      f"(its index is 0)")


def _override_value(text: str, source: str | None, key: str) -> Any:
    """An override's value: JSON where it parses, else the text itself."""
    try:
        value = json.loads(text)
    except json.JSONDecodeError:
        return text
    except RecursionError:
        raise SceneError(source, key, f"--set: {_TOO_DEEP}") from None
    except ValueError as exc:  # an integer of more digits than Python converts
        raise SceneError(source, key, f"--set: {exc}".split("; use")[0]) from None
    if _too_deep(value, DEPTH_MAX):
        raise SceneError(source, key, f"--set: {_TOO_DEEP}")
    return value
