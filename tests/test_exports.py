"""--export-sequence and --export-npz from simulate and render."""

from __future__ import annotations

import json

import numpy as np

from clothsim import Simulation
from clothsim.cli import main

from .conftest import small_scene


def test_simulate_npz_trajectory(tmp_path, write_scene, capsys):
    """the npz holds positions[frame, point, 3] from the start, the mesh and the scene"""
    scene = write_scene(small_scene())
    out = tmp_path / "t.npz"
    assert main(["simulate", str(scene), "--seconds", "0.1", "--export-npz", str(out)]) == 0
    d = np.load(out)
    assert d["positions"].shape == (10, 256, 3) and d["times"][0] == 0.0
    sim = Simulation.from_file(scene)
    np.testing.assert_array_equal(d["positions"][0], sim.model.rest_positions)
    for _ in range(9):
        sim.step()
    np.testing.assert_array_equal(d["positions"][-1], sim.positions)
    assert d["triangles"].shape == (450, 3) and d["uvs"].shape == (256, 2)
    assert json.loads(str(d["scene"]))["cloth"]["num_width_points"] == 16


def test_obj_sequence_one_file_per_frame(tmp_path, write_scene, capsys):
    """render --export-sequence writes frame_0000.obj .. frame_NNNN.obj, and refuses to overwrite them"""
    scene = write_scene(small_scene())
    seq = tmp_path / "seq"
    args = ["render", str(scene), "-o", str(tmp_path / "x.png"), "--seconds", "0.1", "--size", "32x32",
            "--export-sequence", str(seq)]
    assert main(args) == 0
    files = sorted(p.name for p in seq.iterdir())
    assert files == [f"frame_{k:04d}.obj" for k in range(10)]
    first = seq.joinpath("frame_0000.obj").read_text()
    last = seq.joinpath("frame_0009.obj").read_text()
    assert first != last and first.count("\nv ") == 256
    assert main(args[:3] + [str(tmp_path / "y.png")] + args[4:]) == 2
    assert "already holds frame_" in capsys.readouterr().err


def test_outputs_get_the_mode_of_the_users_umask(tmp_path):
    """a finished output is readable as any file the user makes, not 0600 like a temp file"""
    import os
    import stat

    from clothsim.outputs import UMASK, write_atomic

    out = tmp_path / "out.txt"
    write_atomic(out, lambda tmp: tmp.write_text("x"))
    assert stat.S_IMODE(os.stat(out).st_mode) == 0o666 & ~UMASK
