"""Array kernels of one substep: integrate, collide, self-collide, constrain.

Every kernel takes NumPy arrays and plain numbers and is compiled with Numba;
:func:`clothsim.solver.step.advance` runs a whole frame of substeps in one call
so that Python is entered once per frame, not once per substep.
"""

from .. import kernel_cache
kernel_cache.configure()  # before any kernel is decorated: see kernel_cache

from .step import advance, advance_parallel, pack_planes, pack_spheres, parts_for

__all__ = ["advance", "advance_parallel", "pack_planes", "pack_spheres", "parts_for"]
