"""The columns every moving collider's row ends with: how the collider moved over a substep.

A collider's rows are float64 (T, K, C): slot s (row ``min(s, T-1)``) is
collider k at the end of substep s of the frame; T is 1 when no collider of
the kind moves. The last CARRY columns of a row are the rigid map
``x -> A @ x + b`` (A row-major) that takes a point fixed to the collider at
the start of the substep to where it is at the end: the CS184 friction rule
is applied to a point's last position carried so, which is how a moving
collider drags the cloth along.
"""

from __future__ import annotations

import numpy as np
from numba import njit

CARRY = 12
"""A (9, row-major) and b (3)"""


def carry_columns(R_now, o_now, R_before, o_before) -> np.ndarray:
    """(T, 12) carry columns from the poses of :func:`clothsim.motion.slot_poses`."""
    A = R_now @ np.swapaxes(R_before, 1, 2)
    b = o_now - np.einsum("tij,tj->ti", A, o_before)
    return np.concatenate([A.reshape(-1, 9), b], axis=1)


def stack_slots(per_collider: list[np.ndarray]) -> np.ndarray:
    """Rows (T, K, C) from each collider's (T_k, C) slots, T_k 1 or T: a still
    collider's one slot serves every substep."""
    T = max(r.shape[0] for r in per_collider)
    return np.ascontiguousarray(np.stack([np.broadcast_to(r, (T, r.shape[1])) for r in per_collider], axis=1))


@njit(cache=True, inline="always")
def carried(row, c, x, y, z):
    """The point (x, y, z) moved by the carry columns that start at column c of ``row``."""
    return (row[c] * x + row[c + 1] * y + row[c + 2] * z + row[c + 9],
            row[c + 3] * x + row[c + 4] * y + row[c + 5] * z + row[c + 10],
            row[c + 6] * x + row[c + 7] * y + row[c + 8] * z + row[c + 11])
