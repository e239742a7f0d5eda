"""The solver: a model's substeps as compiled kernels, one stage per module.

:class:`ClothSolver` steps a model's state under its control and params;
:mod:`.step` runs the substeps of one frame or of many in one compiled
call, so that Python is entered at most once per frame, never once per
substep. The stages:
:mod:`.springs` (forces and Verlet), :mod:`.selfcollide`, :mod:`.colliders`,
:mod:`.provot`; the groups they take are in :mod:`.groups`.
"""

from .. import kernel_cache
kernel_cache.configure()  # before any kernel is decorated: see kernel_cache

from .cloth_solver import ClothSolver  # noqa: E402
from .groups import Control, Knobs, Points, Scratch  # noqa: E402
from .step import parts_for  # noqa: E402

__all__ = ["ClothSolver", "Control", "Knobs", "Points", "Scratch", "parts_for"]
