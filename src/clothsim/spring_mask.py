"""Which springs act now: a spring belongs to the cloth its ends are in, and
acts while its kind is enabled in that cloth's live material
(``params.cloths[i].enable_*``). The renderer's wireframe and the stretch
metric read this; the solver keeps its own copy of the same rule."""

from __future__ import annotations

import numpy as np


def spring_cloth(model) -> np.ndarray:
    """index of each spring's cloth in ``model.cloths``, int64 (S,)"""
    starts = np.array([c.start for c in model.cloths], dtype=np.int64)
    return np.searchsorted(starts, model.spring_a, side="right") - 1


def enabled_kinds(params) -> np.ndarray:
    """which spring kinds act in each cloth, bool (K, 3), indexed by cloth then
    STRUCTURAL, SHEARING, BENDING"""
    return np.array([m.enabled for m in params.cloths], dtype=bool).reshape(-1, 3)


def active_springs(model, params) -> np.ndarray:
    """True for each spring whose kind is enabled in its own cloth's material, bool (S,)"""
    kinds = enabled_kinds(params)
    if len(model.cloths) == 1:
        return kinds[0][model.spring_kind]
    return kinds[spring_cloth(model), model.spring_kind]
