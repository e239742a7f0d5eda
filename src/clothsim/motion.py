"""Keyframed rigid motion: the ``animation`` of a collider or a cloth's handle.

An animation is a list of keys, each a time [s] with a rigid offset from the
rest pose: a translation [m] and a rotation (degrees about x, then y, then z,
fixed axes, as a mesh's ``transform``) about a pivot (a collider's centre,
the centroid of a handle's points). Between keys the translation and the
angles are interpolated linearly; before the first key the first holds,
after the last the last holds, unless ``loop`` repeats the keys' span.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # numpy loads when an animation is sampled, not with the command line's --help
    import numpy as np

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class Keyframe:
    """One key of an animation."""

    t: float
    """[s] since the start of the run"""
    translate: Vec3 = (0.0, 0.0, 0.0)
    """offset from the rest pose [m]"""
    rotate: Vec3 = (0.0, 0.0, 0.0)
    """degrees about x, then y, then z, about the pivot"""


@dataclass(frozen=True)
class Animation:
    """Keys in increasing time (at least one), and whether they repeat."""

    keys: tuple[Keyframe, ...]
    loop: bool = False

    @property
    def is_still(self) -> bool:
        """True when no key moves anything away from the first key's pose"""
        still = self.__dict__.get("_still")
        if still is None:  # kept: the keys of a frozen animation never change
            first = self.keys[0]
            still = all(k.translate == first.translate and k.rotate == first.rotate for k in self.keys)
            self.__dict__["_still"] = still
        return still

    def offsets(self, times) -> tuple[np.ndarray, np.ndarray]:
        """(translation [m], angles [degrees]) at each of ``times`` [s], float64 (T, 3) each."""
        import numpy as np

        times = np.atleast_1d(np.asarray(times, dtype=np.float64))
        kt = np.array([k.t for k in self.keys])
        if self.loop and len(kt) > 1 and kt[-1] > kt[0]:
            span = kt[-1] - kt[0]
            times = np.where(times > kt[-1], kt[0] + np.mod(times - kt[0], span), times)
        tr = np.array([k.translate for k in self.keys], dtype=np.float64)
        rot = np.array([k.rotate for k in self.keys], dtype=np.float64)
        lerp = lambda v: np.stack([np.interp(times, kt, v[:, c]) for c in range(3)], axis=1)  # noqa: E731
        return lerp(tr), lerp(rot)

    def rigid(self, times, pivot) -> tuple[np.ndarray, np.ndarray]:
        """The pose at each of ``times``: (R float64 (T, 3, 3), o float64 (T, 3)) with
        ``x_now = R @ x_rest + o`` for a point ``x_rest`` of the rest pose, the
        rotation taken about ``pivot`` [m], (3,)."""
        import numpy as np

        tr, rot = self.offsets(times)
        R = rotation_matrices(rot)
        pivot = np.asarray(pivot, dtype=np.float64)
        return R, pivot + tr - R @ pivot

    def to_dict(self) -> dict[str, Any]:
        """The scene keys of this animation (what the scene reader reads back)."""
        return {"keys": [{"t": k.t, "translate": list(k.translate), "rotate": list(k.rotate)} for k in self.keys],
                "loop": self.loop}


def slot_poses(animation: Animation | None, pivot, t0: float, dt: float, substeps: int):
    """The rigid poses of one frame's substeps: (R_now, o_now, R_before, o_before),
    float64 (T, 3, 3) and (T, 3), where slot s holds the pose at the end of substep s
    (time ``t0 + (s+1) dt``) and at its start. T is ``substeps`` for a moving
    animation and 1 for none or a still one (the rest pose, or the still offset)."""
    import numpy as np

    if animation is None:
        R, o = np.eye(3)[None], np.zeros((1, 3))
        return R, o, R, o
    if animation.is_still:
        R, o = animation.rigid([animation.keys[0].t], pivot)
        return R, o, R, o
    steps = np.arange(substeps + 1, dtype=np.float64)
    R, o = animation.rigid(t0 + steps * dt, pivot)
    return R[1:], o[1:], R[:-1], o[:-1]


def rotation_matrices(degrees) -> np.ndarray:
    """``Rz @ Ry @ Rx`` for angles [degrees] about x, y, z, float64 (..., 3) -> (..., 3, 3):
    the convention of a mesh's ``transform.rotate``."""
    import numpy as np

    a = np.radians(np.asarray(degrees, dtype=np.float64))
    c, s = np.cos(a), np.sin(a)
    cx, cy, cz = c[..., 0], c[..., 1], c[..., 2]
    sx, sy, sz = s[..., 0], s[..., 1], s[..., 2]
    R = np.empty(a.shape[:-1] + (3, 3))
    R[..., 0, 0] = cz * cy
    R[..., 0, 1] = cz * sy * sx - sz * cx
    R[..., 0, 2] = cz * sy * cx + sz * sx
    R[..., 1, 0] = sz * cy
    R[..., 1, 1] = sz * sy * sx + cz * cx
    R[..., 1, 2] = sz * sy * cx - cz * sx
    R[..., 2, 0] = -sy
    R[..., 2, 1] = cy * sx
    R[..., 2, 2] = cy * cx
    return R
