"""Writes ks_sweep.ipynb beside this file: a notebook that sweeps the spring
constant ks of the ``sphere`` scene on a 20x20 cloth, plots how low the cloth
hangs over time for each value with matplotlib, and shows one run in the web
player. The notebook is kept without outputs; ``tests/test_notebook.py`` runs
it headless.

    python examples/make_ks_sweep.py
"""

from __future__ import annotations

from pathlib import Path

import nbformat
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook

CELLS = [
    new_markdown_cell("""\
# A ks sweep in a notebook

The `sphere` scene drops a square cloth onto a sphere. Its spring constant
`ks` (N/m) sets how much the cloth stretches: a soft cloth sags far below the
sphere's top, a stiff one hardly bends. This notebook runs three values on a
small 20×20 cloth, plots the lowest point of the cloth over time for each, and
shows one run in the player (orbit with the mouse, play/pause, time slider)."""),
    new_code_cell("""\
%matplotlib inline
import matplotlib.pyplot as plt
import numpy as np

import clothsim
from clothsim.standard_scenes import find_scene

SIZE = 20          # points along each side of the cloth
SECONDS = 2.0      # simulated time per run
KS = [500, 5_000, 50_000]"""),
    new_code_cell("""\
runs = {}
for ks in KS:
    sim = clothsim.Simulation.from_file(find_scene("sphere"), [
        f"cloth.num_width_points={SIZE}", f"cloth.num_height_points={SIZE}", f"cloth.ks={ks}"])
    # record: frame 0 is the start, then every frame; positions (F, N, 3) in metres
    runs[ks] = (sim, clothsim.record(sim, SECONDS))

traj = runs[KS[0]][1]
print(f"{traj.num_frames} frames of {traj.positions.shape[1]} points, "
      f"{traj.frames_per_sec:g} frames per simulated second")"""),
    new_code_cell("""\
fig, ax = plt.subplots(figsize=(7, 4))
for ks, (sim, traj) in runs.items():
    lowest = traj.positions[:, :, 1].min(axis=1)   # y is up
    ax.plot(traj.times, lowest, label=f"ks = {ks:,} N/m")
top = sim.spheres[0].origin[1] + sim.spheres[0].radius
ax.axhline(top, color="grey", linestyle=":", label="top of the sphere")
ax.set_xlabel("simulated time [s]")
ax.set_ylabel("lowest point of the cloth [m]")
ax.set_title(f"sphere scene, {SIZE}×{SIZE} cloth")
ax.legend()
plt.show()"""),
    new_code_cell("""\
for ks, (sim, traj) in runs.items():
    sag = top - traj.positions[-1, :, 1].min()
    print(f"ks = {ks:>6,} N/m: the cloth hangs {sag:.3f} m below the sphere's top at the end")"""),
    new_markdown_cell("""\
The softest run in the web player. A `Simulation` shows the frames of its last
`clothsim.record` call (or its current frame when it has none); a
`Trajectory` shows itself too, and `traj.show(width, height, color=...)`
gives a player of another size or colour (`.save("run.html")` writes the
page)."""),
    new_code_cell("""\
sim, traj = runs[KS[0]]
sim"""),
]


def build() -> nbformat.NotebookNode:
    nb = new_notebook(cells=CELLS)
    for i, cell in enumerate(nb.cells):
        cell.id = f"cell-{i}"  # fixed ids: the file changes only when a cell does
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    nb.metadata["language_info"] = {"name": "python"}
    return nb


def main() -> None:
    out = Path(__file__).resolve().parent / "ks_sweep.ipynb"
    nb = build()
    nbformat.validate(nb)
    nbformat.write(nb, out)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
