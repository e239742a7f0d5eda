"""``clothsim scenes``: the standard scenes that ship with clothsim, one line each."""

from __future__ import annotations

import argparse


def add_parser(sub) -> None:
    p = sub.add_parser("scenes", help="list the standard scenes (usable by name: clothsim render sphere ...)",
                       description="List the standard scenes shipped inside the package. Any command takes "
                                   "their name in place of a scene file; a file of that name in the working "
                                   "folder wins.")
    p.set_defaults(func=run)


def describe(scene) -> str:
    """One line saying what a scene holds, read from the scene itself."""
    cloth = scene.cloth
    nw, nh = cloth.num_width_points, cloth.num_height_points
    text = (f"{nw}×{nh} {'vertical' if cloth.orientation == 1 else 'horizontal'} cloth, "
            f"{cloth.width:g}×{cloth.height:g} m")
    corners = {(0, 0), (nw - 1, 0), (0, nh - 1), (nw - 1, nh - 1)}
    pinned = {tuple(p) for p in cloth.pinned}
    if pinned:
        what = "corner" if pinned <= corners else "point"
        text += f", pinned at {len(pinned)} {what}{'s' if len(pinned) > 1 else ''}"
    colliders = [_count(len(scene.spheres), "sphere"), _count(len(scene.planes), "plane")]
    colliders = [c for c in colliders if c]
    if colliders:
        text += ", falls onto " + " and ".join(colliders)
    elif not pinned:
        text += ", falls freely"
    if not scene.simulation.self_collision:
        text += ", no self-collision"
    return text


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
