"""The second compile process: it compiles exactly the kernels the substep calls, with
their argument types, so that a first run compiles none of them again."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

PROBE = """
import json, sys
from numba.core import event
compiled = set()
class Seen(event.Listener):
    def on_start(self, ev): pass
    def on_end(self, ev): compiled.add(ev.data["dispatcher"].py_func.__qualname__)
event.register("numba:compile", Seen())
from clothsim import Simulation
text = open(sys.argv[1]).read()
grid = "mesh" not in text and "handles" not in text  # handles name points of the full grid
sim = Simulation.from_file(sys.argv[1], ["cloth.num_width_points=12", "cloth.num_height_points=12"] if grid else [],
                           threads=1)
sim.step()
sim.normals
print(json.dumps({"compiled": sorted(k for k in compiled if "<locals>" not in k),
                  "variant": sim.solver.variant(sim.control, sim.params)}))
"""

BUILT_BY_THE_MODEL = {"bounds", "build_list", "query_points", "sort_into_cells"}
"""what the first process compiles itself while the second works, besides the
substep's own body: the list build, which the model's build runs to check the
rest layout of a fine cloth"""


@pytest.mark.parametrize("scene,variant", [("sphere", "serial+spheres"), ("plane", "serial+planes"),
                                           ("tablecloth", "mesh-serial+spheres"),
                                           ("table_pull", "serial+planes+boxes+handles"),
                                           ("windy_flag", "serial+planes+boxes+wind"),
                                           ("torus_drape", "serial+planes+meshes")])
def test_after_a_prewarm_the_first_run_compiles_only_the_model_build_and_the_substep(tmp_path, scene, variant):
    """grid and general path alike (a mesh cloth's model build compiles nothing), and
    the moving world's variants: boxes, handles, wind, mesh colliders"""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"), CLOTHSIM_PREWARM="0")
    subprocess.run([sys.executable, "-m", "clothsim.solver.prewarm", variant], env=env, check=True,
                   timeout=600)
    out = subprocess.run([sys.executable, "-c", PROBE, str(ROOT / "scenes" / f"{scene}.json")], env=env,
                         check=True, capture_output=True, text=True, timeout=600)
    seen = json.loads(out.stdout.splitlines()[-1])
    assert seen["variant"] == variant
    body = "advance_mesh" if variant.startswith("mesh") else "advance"
    assert set(seen["compiled"]) - BUILT_BY_THE_MODEL == {body}


def test_prewarm_starts_only_where_it_can_help(monkeypatch):
    from clothsim.solver import prewarm

    monkeypatch.setenv(prewarm.PREWARM, "0")
    assert prewarm.start("serial+spheres") is None
    monkeypatch.setenv(prewarm.PREWARM, "1")
    assert prewarm.start("parallel+spheres") is None  # the threaded body is not served
