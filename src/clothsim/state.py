"""State: what a substep changes."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .model import Model


@dataclass
class State:
    """What a substep changes."""

    positions: np.ndarray
    """point mass positions [m], float64 (N, 3)"""
    last_positions: np.ndarray
    """positions one substep ago [m], float64 (N, 3)"""
    frame: int = 0
    time: float = 0.0
    """simulated time [s]"""

    @classmethod
    def at_rest(cls, model: Model) -> State:
        return cls(model.rest_positions.copy(), model.rest_positions.copy())
