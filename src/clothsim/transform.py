"""Where a mesh file's vertices go in the scene: a cloth's or a collider's ``transform``."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from .scene_limits import LENGTH_MAX, SCALE_MAX
from .scene_reader import Reader, Vec3

if TYPE_CHECKING:  # numpy loads when a transform is applied, not with the command line's --help
    import numpy as np


@dataclass(frozen=True)
class MeshTransform:
    """Where the file's vertices go: scaled, then rotated, then translated."""

    scale: float | Vec3 = 1.0
    """a factor, or one per axis [x, y, z]"""
    rotate: Vec3 = (0.0, 0.0, 0.0)
    """degrees about x, then y, then z (right-handed, fixed axes)"""
    translate: Vec3 = (0.0, 0.0, 0.0)
    """[m]"""

    def matrix(self) -> np.ndarray:
        """The linear part, float64 (3, 3): ``Rz @ Ry @ Rx @ S``."""
        import numpy as np

        ax, ay, az = (math.radians(a) for a in self.rotate)
        cx, sx, cy, sy, cz, sz = math.cos(ax), math.sin(ax), math.cos(ay), math.sin(ay), math.cos(az), math.sin(az)
        rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
        ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
        rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
        return rz @ ry @ rx @ np.diag(np.broadcast_to(np.asarray(self.scale, dtype=np.float64), (3,)))

    def apply(self, points: np.ndarray) -> np.ndarray:
        """float64 (N, 3) positions [file units] to scene positions [m]."""
        import numpy as np

        return np.asarray(points, dtype=np.float64) @ self.matrix().T + np.asarray(self.translate)

    def to_dict(self) -> dict[str, Any]:
        scale = self.scale if isinstance(self.scale, float) else list(self.scale)
        return {"scale": scale, "rotate": list(self.rotate), "translate": list(self.translate)}


def parse_transform(r: Reader, raw: Any, key: str) -> MeshTransform:
    """``transform`` at key path ``key``: scale (> 0, one number or three), rotate, translate."""
    t = r.obj(raw, key)
    r.keys(t, key, {"scale", "rotate", "translate"}, ())
    scale: float | Vec3 = 1.0
    if "scale" in t:
        if isinstance(t["scale"], list):
            scale = r.vec3(t["scale"], f"{key}.scale", SCALE_MAX)
            for k, s in enumerate(scale):
                if s <= 0:
                    raise r.fail(f"{key}.scale[{k}]", f"expected a number > 0, got {s:g}")
        else:
            scale = r.number(t["scale"], f"{key}.scale", lo=0, lo_open=True, hi=SCALE_MAX)
    return MeshTransform(scale=scale,
                         rotate=r.vec3(t["rotate"], f"{key}.rotate") if "rotate" in t else (0.0, 0.0, 0.0),
                         translate=r.vec3(t["translate"], f"{key}.translate", LENGTH_MAX) if "translate" in t else (0.0, 0.0, 0.0))
