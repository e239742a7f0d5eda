"""``clothsim scenes``: the standard scenes that ship with clothsim, one line each."""

from __future__ import annotations

import argparse
import math


def add_parser(sub) -> None:
    p = sub.add_parser("scenes", help="list the standard scenes (usable by name: clothsim render sphere ...)",
                       description="List the standard scenes shipped inside the package. Any command takes "
                                   "their name in place of a scene file; a file of that name in the working "
                                   "folder wins.")
    p.set_defaults(func=run)


def describe(scene) -> str:
    """One line saying what a scene holds, read from the scene itself: its
    cloth (a grid or a mesh) or each of its cloths, and what they fall onto."""
    cloths = scene.cloths
    texts = [_describe_cloth(c) for c in cloths]
    if len(cloths) == 1:
        head, sep, verb = texts[0], ", ", "falls"
    else:
        if len({c.ks for c in cloths}) > 1:
            texts = [f"{t}, ks {c.ks:g}" for t, c in zip(texts, cloths)]
        head, sep, verb = f"{len(cloths)} cloths: " + "; ".join(texts), "; ", "fall"
    moving = [c for c in [*scene.spheres, *scene.planes, *scene.boxes, *scene.mesh_colliders]
              if getattr(c, "animation", None) is not None]
    colliders = [_count(len(scene.spheres), "sphere"), _count(len(scene.planes), "plane"),
                 _count(len(scene.boxes), "box"), _count(len(scene.mesh_colliders), "mesh collider")]
    colliders = [c for c in colliders if c]
    if colliders and all(_pinned_count(c) for c in cloths):
        tail = ("hangs" if len(cloths) == 1 else "hang") + " above " + " and ".join(colliders)
    elif colliders:
        tail = f"{verb} onto " + " and ".join(colliders)
    elif not any(_pinned_count(c) for c in cloths):
        tail = f"{verb} freely"
    else:
        tail = ""
    text = head + sep + tail if tail else head
    handles = sum(len(c.handles) for c in cloths)
    if handles:
        text += f", {_count(handles, 'handle')} moving it"
    if moving:
        text += f", {_count(len(moving), 'collider')} moving"
    if scene.wind is not None:
        text += f", wind {math.hypot(*scene.wind.velocity):g} m/s"
    if not scene.simulation.self_collision:
        text += ", no self-collision"
    return text


def _describe_cloth(cloth) -> str:
    if getattr(cloth, "mesh", None) is not None:
        return _describe_mesh(cloth)
    nw, nh = cloth.num_width_points, cloth.num_height_points
    text = (f"{nw}×{nh} {'vertical' if cloth.orientation == 1 else 'horizontal'} cloth, "
            f"{cloth.width:g}×{cloth.height:g} m")
    corners = {(0, 0), (nw - 1, 0), (0, nh - 1), (nw - 1, nh - 1)}
    pinned = {tuple(p) for p in cloth.pinned}
    if pinned:
        what = "corner" if pinned <= corners else "point"
        text += f", pinned at {len(pinned)} {what}{'s' if len(pinned) > 1 else ''}"
    return text


def _describe_mesh(cloth) -> str:
    """``1951-point triangle mesh disc.obj, 1.54 m², horizontal``: points after the
    weld, the kind of faces, the file's name, the rest area, and its plane when
    it is flat along a coordinate axis (thinner than 1 % of its size)."""
    from pathlib import PurePath

    import numpy as np

    from ..mesh_cloth import mesh_cloth_parts

    parts = mesh_cloth_parts(cloth)
    quads = cloth.data.is_quad
    kind = "quad" if quads.all() else "triangle" if not quads.any() else "quad and triangle"
    text = f"{len(parts.positions)}-point {kind} mesh {PurePath(cloth.mesh).name}, {parts.area:.2g} m²"
    extent = np.ptp(parts.positions, axis=0)
    thin = int(np.argmin(extent))
    if extent[thin] < 0.01 * extent.max():
        text += ", horizontal" if thin == 1 else ", vertical"
    n = _pinned_count(cloth)
    if n:
        text += f", pinned at {n} point{'s' if n > 1 else ''}"
    return text


def _pinned_count(cloth) -> int:
    if getattr(cloth, "mesh", None) is None:
        return len({tuple(p) for p in cloth.pinned})
    from ..mesh_cloth import pinned_points

    return int(pinned_points(cloth).sum())


def _count(n: int, noun: str) -> str:
    return "" if n == 0 else f"a {noun}" if n == 1 else f"{n} {noun}s"


def run(args: argparse.Namespace) -> int:
    from ..errors import SceneError
    from ..scene import load_scene
    from ..standard_scenes import names, scene_path

    known = names()
    if not known:
        raise SceneError(None, None, "no standard scenes in this installation")
    width = max(len(n) for n in known)
    for name in known:
        try:
            line = describe(load_scene(scene_path(name)))
        except SceneError as exc:  # a scene this version cannot read is listed, not fatal
            line = f"(cannot be read: {exc.message})"
        print(f"{name:<{width}}  {line}")
    return 0
