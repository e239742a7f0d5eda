"""The bounds on a scene's numbers, in one place.

Each keeps the arithmetic of a run inside what a float64 holds: nothing
downstream overflows to inf (sizes squared, the blow-up limit, spring forces)
or divides by a denormal (a width or density of 5e-324), and no count becomes
an allocation of absurd size. The messages of :mod:`clothsim.scene_reader`
name them; docs/physics.md lists them for users.
"""

from __future__ import annotations

import math
import numbers

LENGTH_MAX = 1e6
"""largest coordinate or size, in either direction: points, origins, widths, radii [m]"""
LENGTH_MIN = 1e-6
"""smallest size: width, height, radius, thickness [m]"""
GRAVITY_MAX = 1e6
"""largest gravity component, in either direction [m/s²]"""
KS_MAX = 1e12
"""largest spring constant [N/m]"""
DENSITY_MIN, DENSITY_MAX = 1e-6, 1e6
"""the range of density [g/cm²]"""
FPS_MIN, FPS_MAX = 1e-3, 1e4
"""the range of frames_per_sec"""
STEPS_MAX = 100_000
"""most substeps per frame, and of one ``Simulation.step(substeps)``"""
RUN_FRAMES_MAX = 10_000_000
"""most frames of one run: ``Simulation.run``, ``clothsim.record``, ``--seconds``"""
POINTS_MAX = 4_000_000
"""most points of a grid cloth (num_width_points x num_height_points)"""
SEED_MAX = 2**63 - 1
"""largest seed"""
DEPTH_MAX = 64
"""deepest nesting of lists and objects in a scene document (a scene needs 5)"""
SCALE_MAX = 1e6
"""largest scale factor of a mesh cloth's transform"""
FILE_COORD_MAX = 1e12
"""largest coordinate in a mesh file, before the transform (any unit that scales to metres)"""
ANGLE_MAX = 1e6
"""largest rotation angle of a box or an animation key, in either direction [degrees]"""
TIME_MAX = 1e9
"""latest time of an animation key [s]"""
MARGIN_MAX = 1.0
"""largest collision margin of a box or a mesh collider [m]"""
TRIANGLES_MAX = 4_000_000
"""most triangles of a mesh collider (quads and polygons split)"""
SPEED_MAX = 1e6
"""largest wind velocity component, in either direction [m/s]"""
COEFFICIENT_MAX = 1e3
"""largest wind drag coefficient, and lift coefficient in either direction"""


def run_frames(seconds: float, frames_per_sec: float) -> int:
    """The whole frames of ``seconds`` of simulated time at ``frames_per_sec``:
    ``round(seconds * frames_per_sec)``. ValueError unless ``seconds`` is a finite
    number >= 0 whose count is at most :data:`RUN_FRAMES_MAX`."""
    if isinstance(seconds, bool) or not isinstance(seconds, numbers.Real) \
            or not math.isfinite(seconds) or seconds < 0:
        raise ValueError(f"seconds: expected a finite number >= 0, got {seconds!r}")
    count = float(seconds) * float(frames_per_sec)
    if not count < RUN_FRAMES_MAX + 0.5:  # inf too
        raise ValueError(f"seconds: {float(seconds):g} s at {frames_per_sec:g} frames/s is {count:,.0f} frames; "
                         f"expected at most {RUN_FRAMES_MAX:,}")
    return max(0, int(round(count)))
