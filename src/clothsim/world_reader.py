"""Reading the scene keys of the moving world: ``animation``, ``box``, ``mesh``
(colliders), ``wind`` and a cloth's ``handles`` (``shared/scene-format.md``,
"More colliders", "Motion", "Wind").

These keys are clothsim's own, so an unknown key inside any of them is an
error (not a warning as inside ``cloth``, ``sphere``, ``plane``), and so is a
handle point outside its cloth. Every fault is a
:class:`~clothsim.errors.SceneError` naming the file and the key path
(``box[1].size[2]``, ``sphere.animation.keys[2].t``).
"""

from __future__ import annotations

import os
from typing import Any

from .motion import Animation, Keyframe
from .scene_limits import (ANGLE_MAX, COEFFICIENT_MAX, LENGTH_MAX, LENGTH_MIN, MARGIN_MAX, SEED_MAX, SPEED_MAX,
                           TIME_MAX)
from .scene_reader import Reader, Vec3, as_list, describe
from .transform import parse_transform
from .world_spec import MARGIN_DEFAULT, BoxSpec, HandleSpec, MeshColliderSpec, WindSpec

_ZERO = (0.0, 0.0, 0.0)


# --------------------------------------------------------------------------
# animation


def parse_animation(r: Reader, raw: Any, key: str) -> Animation:
    """``{"keys": [{"t", "translate", "rotate"}, ...], "loop"}``: times [s] finite, >= 0 and
    strictly increasing; translations [m] within ±LENGTH_MAX; rotations [degrees] within ±ANGLE_MAX."""
    a = r.obj(raw, key)
    r.keys(a, key, {"keys", "loop"}, ("keys",))
    items = a["keys"]
    if not isinstance(items, list) or not items:
        raise r.fail(f"{key}.keys", f"expected a non-empty list of keys, got {describe(items)}")
    keys: list[Keyframe] = []
    for k, item in enumerate(items):
        kkey = f"{key}.keys[{k}]"
        obj = r.obj(item, kkey)
        r.keys(obj, kkey, {"t", "translate", "rotate"}, ("t",))
        t = r.number(obj["t"], f"{kkey}.t", lo=0, hi=TIME_MAX)
        if keys and t <= keys[-1].t:
            raise r.fail(f"{kkey}.t", f"expected a time after {keys[-1].t:g} (keys[{k - 1}].t), got {t:g}")
        keys.append(Keyframe(
            t=t,
            translate=r.vec3(obj["translate"], f"{kkey}.translate", LENGTH_MAX) if "translate" in obj else _ZERO,
            rotate=r.vec3(obj["rotate"], f"{kkey}.rotate", ANGLE_MAX) if "rotate" in obj else _ZERO,
        ))
    return Animation(keys=tuple(keys), loop=r.boolean(a.get("loop", False), f"{key}.loop"))


def optional_animation(r: Reader, obj: dict[str, Any], key: str) -> Animation | None:
    """The ``animation`` of the collider ``obj`` at ``key``, or None without one."""
    return parse_animation(r, obj["animation"], f"{key}.animation") if "animation" in obj else None


# --------------------------------------------------------------------------
# colliders


def _margin(r: Reader, obj: dict[str, Any], key: str) -> float:
    """``margin`` [m] in [0, MARGIN_MAX], default MARGIN_DEFAULT"""
    return r.number(obj.get("margin", MARGIN_DEFAULT), f"{key}.margin", lo=0, hi=MARGIN_MAX)


def _sizes(r: Reader, raw: Any, key: str) -> Vec3:
    """three lengths [m], each in [LENGTH_MIN, LENGTH_MAX]"""
    if not isinstance(raw, list) or len(raw) != 3:
        raise r.fail(key, f"expected a list of 3 numbers, got {describe(raw)}")
    x, y, z = (r.number(v, f"{key}[{k}]", lo=LENGTH_MIN, hi=LENGTH_MAX) for k, v in enumerate(raw))
    return (x, y, z)


BOX_KEYS = {"center", "size", "rotate", "friction", "margin", "animation"}


def parse_boxes(r: Reader, raw: Any) -> list[BoxSpec]:
    """``box``: one object or a list of them."""
    out = []
    for suffix, item in as_list(raw):
        key = "box" + suffix
        b = r.obj(item, key)
        r.keys(b, key, BOX_KEYS, ("center", "size", "friction"))
        out.append(BoxSpec(
            center=r.vec3(b["center"], f"{key}.center", LENGTH_MAX),
            size=_sizes(r, b["size"], f"{key}.size"),
            friction=r.number(b["friction"], f"{key}.friction", lo=0, hi=1),
            rotate=r.vec3(b["rotate"], f"{key}.rotate", ANGLE_MAX) if "rotate" in b else _ZERO,
            margin=_margin(r, b, key),
            animation=optional_animation(r, b, key),
        ))
    return out


MESH_COLLIDER_KEYS = {"path", "transform", "friction", "margin", "animation"}


def parse_mesh_colliders(r: Reader, raw: Any) -> list[MeshColliderSpec]:
    """``mesh``: one object or a list of them; each file is loaded (see :mod:`clothsim.collider_mesh`)."""
    # here, not at the top: the mesh readers only for a scene with a mesh
    from .collider_mesh import load_collider
    from .meshfile import MeshFileError

    out = []
    for suffix, item in as_list(raw):
        key = "mesh" + suffix
        m = r.obj(item, key)
        r.keys(m, key, MESH_COLLIDER_KEYS, ("path", "friction"))
        path = m["path"]
        if not isinstance(path, str) or not path:
            raise r.fail(f"{key}.path", f"expected the name of a mesh file, got {describe(path)}")
        shown = os.path.normpath(os.path.join(os.path.dirname(r.source), path)) if r.source else path
        transform = parse_transform(r, m.get("transform", {}), f"{key}.transform")
        friction = r.number(m["friction"], f"{key}.friction", lo=0, hi=1)
        margin = _margin(r, m, key)
        animation = optional_animation(r, m, key)
        try:
            vertices, triangles, closed = load_collider(os.path.abspath(shown), transform.apply)
        except MeshFileError as exc:
            raise r.fail(f"{key}.path", f"{shown}: {exc}") from None
        for arr in (vertices, triangles):
            arr.setflags(write=False)
        out.append(MeshColliderSpec(path=path, file=os.path.abspath(shown), friction=friction, transform=transform,
                                    margin=margin, animation=animation, vertices=vertices, triangles=triangles,
                                    closed=closed))
    return out


# --------------------------------------------------------------------------
# wind


WIND_KEYS = {"velocity", "turbulence", "drag", "lift", "seed"}


def parse_wind(r: Reader, raw: Any) -> WindSpec:
    """``wind``: one object; ``velocity`` [m/s] required."""
    w = r.obj(raw, "wind")
    r.keys(w, "wind", WIND_KEYS, ("velocity",))
    d = WindSpec(velocity=_ZERO)
    return WindSpec(
        velocity=r.vec3(w["velocity"], "wind.velocity", SPEED_MAX),
        turbulence=r.number(w.get("turbulence", d.turbulence), "wind.turbulence", lo=0, hi=1),
        drag=r.number(w.get("drag", d.drag), "wind.drag", lo=0, hi=COEFFICIENT_MAX),
        lift=r.number(w.get("lift", d.lift), "wind.lift", lo=-COEFFICIENT_MAX, hi=COEFFICIENT_MAX),
        seed=r.integer(w.get("seed", d.seed), "wind.seed", lo=0, hi=SEED_MAX),
    )


# --------------------------------------------------------------------------
# handles


def _handle_list(r: Reader, raw: Any, key: str, own: str, other: str) -> list[tuple[str, dict[str, Any], list]]:
    """(key, object, its ``own`` list) of each handle; ``other`` is the key of the other cloth kind."""
    if not isinstance(raw, list):
        raise r.fail(key, f"expected a list of handles, got {describe(raw)}")
    out = []
    for k, item in enumerate(raw):
        hkey = f"{key}[{k}]"
        h = r.obj(item, hkey)
        if other in h:
            kind = "grid" if own == "points" else "mesh"
            raise r.fail(f"{hkey}.{other}", f"expected '{own}' for a {kind} cloth's handle, not '{other}'")
        r.keys(h, hkey, {own, "animation"}, (own, "animation"))
        members = h[own]
        if not isinstance(members, list) or not members:
            raise r.fail(f"{hkey}.{own}", f"expected a non-empty list, got {describe(members)}")
        out.append((hkey, h, members))
    return out


def parse_grid_handles(r: Reader, raw: Any, key: str, nw: int, nh: int,
                       pinned: list[tuple[int, int]]) -> list[HandleSpec]:
    """A grid cloth's ``handles``: ``points`` [i, j] inside the nw x nh grid, each in one
    handle only and not pinned."""
    taken = {p: "pinned" for p in pinned}
    out = []
    for hkey, h, members in _handle_list(r, raw, key, "points", "vertices"):
        points = []
        for k, p in enumerate(members):
            pkey = f"{hkey}.points[{k}]"
            if not isinstance(p, list) or len(p) != 2:
                raise r.fail(pkey, f"expected a pair [i, j], got {describe(p)}")
            i, j = r.integer(p[0], pkey + "[0]"), r.integer(p[1], pkey + "[1]")
            if not (0 <= i < nw and 0 <= j < nh):
                raise r.fail(pkey, f"expected a point inside the {nw}x{nh} grid (i in 0..{nw - 1}, "
                                   f"j in 0..{nh - 1}), got [{i}, {j}]")
            if (i, j) in taken:
                raise r.fail(pkey, f"expected a point of no other handle and not pinned, got [{i}, {j}], "
                                   f"already {taken[(i, j)]}")
            taken[(i, j)] = f"in {hkey}"
            points.append((i, j))
        out.append(HandleSpec(animation=parse_animation(r, h["animation"], f"{hkey}.animation"), points=points))
    return out


def parse_mesh_handles(r: Reader, raw: Any, key: str, data: Any, shown: str,
                       pinned: list[int]) -> list[HandleSpec]:
    """A mesh cloth's ``handles``: ``vertices``, file vertex indices of faces of ``data``
    (:class:`~clothsim.meshfile.MeshData`), each point in one handle only and not pinned
    (two file vertices welded into one point are one point)."""
    n = data.num_file_vertices
    taken = {int(data.file_to_point[v]): "pinned" for v in pinned}
    out = []
    for hkey, h, members in _handle_list(r, raw, key, "vertices", "points"):
        vertices = []
        for k, item in enumerate(members):
            vkey = f"{hkey}.vertices[{k}]"
            index = r.integer(item, vkey)
            if not 0 <= index < n:
                raise r.fail(vkey, f"expected a vertex index of {shown} (0..{n - 1}), got {index}")
            point = int(data.file_to_point[index])
            if point < 0:
                raise r.fail(vkey, f"expected a vertex in a face, got vertex {index} of {shown}, in no face")
            if point in taken:
                raise r.fail(vkey, f"expected a vertex of no other handle and not pinned, got {index}, "
                                   f"already {taken[point]}")
            taken[point] = f"in {hkey}"
            vertices.append(index)
        out.append(HandleSpec(animation=parse_animation(r, h["animation"], f"{hkey}.animation"),
                              vertices=vertices))
    return out
