"""Compiled kernels never read or write out of bounds, whatever the scene.

numba compiles the kernels without bounds checks (they would stop LLVM
vectorising); ``NUMBA_BOUNDSCHECK=1`` compiles them with the checks, so an
index out of bounds raises instead of corrupting memory. These scenes once
wrapped the cell grid's counts (a tiny thickness) and crashed the process or
corrupted its heap. Some are refused by the scene format now
(docs/physics.md, "Limits"); they are set on the parsed scene, past its
checks, so the kernels are still tried with them. They run in a subprocess
with a cache of their own: the checked code must not land in the cache of
the fast one.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

EXTREMES = {
    "tiny thickness 1e-8": {"cloth": {"thickness": 1e-8}},
    "tiny thickness 1e-10": {"cloth": {"thickness": 1e-10}},
    "smallest double thickness": {"cloth": {"thickness": 5e-324}},
    "thickness larger than the cloth": {"cloth": {"thickness": 3.0}},
    "a 2x2 cloth": {"cloth": {"num_width_points": 2, "num_height_points": 2}},
    "a single row": {"cloth": {"num_width_points": 40, "num_height_points": 2}},
    "every point pinned": {"cloth": {"pinned": [[i, j] for i in range(6) for j in range(6)]}},
    "a cloth of a kilometre": {"cloth": {"width": 1000.0, "height": 1000.0}},
    "a cloth of a micrometre": {"cloth": {"width": 1e-6, "height": 1e-6, "thickness": 1e-8}},
}

PROBE = """
import json, sys
import numpy as np
from clothsim import Simulation, SimulationError
from clothsim.scene import parse_scene
base = {"cloth": {"width": 1.0, "height": 1.0, "num_width_points": 6, "num_height_points": 6,
                  "thickness": 0.0095, "orientation": 1, "damping": 0.2, "density": 150, "ks": 5000},
        "sphere": {"origin": [0.5, 0.2, 0.0], "radius": 0.2, "friction": 0.3},
        "plane": {"point": [0, 0, 0], "normal": [0, 1, 0], "friction": 0.5}}
out = {}
for name, change in json.loads(sys.argv[1]).items():
    # set on the parsed scene: the kernels must hold even for values the scene format refuses
    scene = parse_scene(base, name)
    for key, value in change["cloth"].items():
        setattr(scene.cloth, key, [tuple(p) for p in value] if key == "pinned" else value)
    try:
        sim = Simulation(scene)
        sim.run(0.5)
        out[name] = "finite" if np.isfinite(sim.positions).all() else "not finite"
    except SimulationError:
        out[name] = "blew up, said so"
print(json.dumps(out))
"""


def test_extreme_scenes_run_with_every_index_checked(tmp_path):
    """every extreme scene ends in a result or a SimulationError, with bounds checks on"""
    env = dict(os.environ, NUMBA_BOUNDSCHECK="1", NUMBA_CACHE_DIR=str(tmp_path / "cache"),
               CLOTHSIM_PREWARM="0")
    run = subprocess.run([sys.executable, "-c", PROBE, json.dumps(EXTREMES)], env=env, capture_output=True,
                         text=True, timeout=900)
    assert run.returncode == 0, run.stderr[-3000:]
    outcomes = json.loads(run.stdout.splitlines()[-1])
    assert set(outcomes) == set(EXTREMES)
    assert set(outcomes.values()) <= {"finite", "blew up, said so"}, outcomes
    assert outcomes["tiny thickness 1e-10"] == "finite"
