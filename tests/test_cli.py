"""The clothsim command: summaries, exports, and one-line errors with exit code 2."""

from __future__ import annotations

import subprocess
import sys

import pytest

import numpy as np

from clothsim import Simulation, __version__
from clothsim.cli import main
from clothsim.cli.common import run_with_progress

from .conftest import SCENES, small_scene


def run(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_version_and_help_from_installed_command():
    """the installed entry point answers --version and --help"""
    v = subprocess.run(["clothsim", "--version"], capture_output=True, text=True)
    assert v.returncode == 0 and __version__ in v.stdout
    h = subprocess.run(["clothsim", "--help"], capture_output=True, text=True)
    assert h.returncode == 0 and "simulate" in h.stdout and "render" in h.stdout


def test_simulate_writes_obj_and_summary(tmp_path, write_scene, capsys):
    """simulate prints frames, wall time and substeps/s, and writes the OBJ"""
    scene = write_scene(small_scene())
    out_obj = tmp_path / "cloth.obj"
    code, out, err = run(["simulate", scene, "--seconds", "0.5", "--export", out_obj], capsys)
    assert code == 0, err
    assert "45 frames" in out and "substeps/s" in out and "wall" in out
    assert out_obj.read_text().count("\nv ") == 256


def test_timed_run_loads_kernels_without_advancing():
    """the kernel load before the timer starts moves nothing: the timed run ends
    bit-identical to stepping the same frames directly"""
    timed = Simulation.from_file(SCENES / "selfCollision.json")
    frames, wall = run_with_progress(timed, 0.1, show=False)
    direct = Simulation.from_file(SCENES / "selfCollision.json")
    for _ in range(frames):
        direct.step()
    assert frames == 9 and wall > 0 and timed.state.frame == 9
    assert timed.state.time == direct.state.time
    np.testing.assert_array_equal(timed.positions, direct.positions)


def test_set_overrides_scene_values(tmp_path, capsys):
    """--set cloth.num_width_points=10 changes the grid the OBJ holds"""
    out_obj = tmp_path / "c.obj"
    code, out, _ = run(["simulate", SCENES / "pinned2.json", "--seconds", "0.1", "--set",
                        "cloth.num_width_points=10", "--set", "cloth.num_height_points=12",
                        "--set", "cloth.pinned=[[0,0],[9,0]]",
                        "--no-self-collision", "--export", out_obj], capsys)
    assert code == 0
    assert "120 points" in out
    assert out_obj.read_text().count("\nv ") == 120


@pytest.mark.parametrize("edit,key", [
    ({"cloth": {"pinned": [[0, 0], [99, 0]]}}, "cloth.pinned[1]"),
    ({"cloth": {"density": "heavy"}}, "cloth.density"),
    ({"wind": 1}, "wind"),
])
def test_bad_scene_one_line_exit_2(tmp_path, write_scene, capsys, edit, key):
    """a bad scene prints one line naming file and key, exits 2, and writes nothing"""
    data = small_scene()
    for k, v in edit.items():
        if k == "cloth":
            data["cloth"].update(v)
        else:
            data[k] = v
    scene = write_scene(data)
    out_obj = tmp_path / "never.obj"
    code, out, err = run(["simulate", scene, "--export", out_obj], capsys)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and str(scene) in lines[0] and key in lines[0]
    assert "Traceback" not in err
    assert not out_obj.exists()


def test_invalid_json_exit_2(write_scene, capsys):
    """invalid JSON reports line and column with exit 2"""
    code, _, err = run(["simulate", write_scene('{"cloth": }')], capsys)
    assert code == 2 and "line 1, column 11" in err


def test_existing_output_is_not_overwritten(tmp_path, write_scene, capsys):
    """an existing output file is kept unless --overwrite is given"""
    scene = write_scene(small_scene())
    target = tmp_path / "mine.obj"
    target.write_text("precious")
    code, _, err = run(["simulate", scene, "--seconds", "0.05", "--export", target], capsys)
    assert code == 2 and "already exists" in err and target.read_text() == "precious"
    code, _, _ = run(["simulate", scene, "--seconds", "0.05", "--export", target, "--overwrite"], capsys)
    assert code == 0 and target.read_text().startswith("# clothsim")


def test_unstable_run_leaves_no_output(tmp_path, write_scene, capsys):
    """when the stability guard fires, the error names the frame and no OBJ is written"""
    scene = write_scene(small_scene(cloth={"ks": 1e9}, simulation={"simulation_steps": 1}))
    target = tmp_path / "out.obj"
    code, _, err = run(["simulate", scene, "--export", target], capsys)
    assert code == 2 and "unstable at frame" in err and "ks=1e+09" in err
    assert not target.exists() and not list(tmp_path.glob(".out-*"))


def test_module_runs_without_traceback_on_missing_file(tmp_path):
    """a missing scene file is a one-line error from the real process too"""
    r = subprocess.run([sys.executable, "-m", "clothsim", "simulate", str(tmp_path / "x.json")],
                       capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "no such file" in r.stderr


@pytest.mark.parametrize("flag", ["--help", "--version"])
def test_help_and_version_load_no_numba(flag):
    """--help and --version answer without importing numba (nor numpy or a GL library)"""
    code = ("import sys\nfrom clothsim.cli import main\n"
            f"try:\n    main([{flag!r}])\nexcept SystemExit as e:\n    assert e.code == 0, e.code\n"
            "heavy = sorted({m.split('.')[0] for m in sys.modules} & {'numba', 'numpy', 'moderngl', 'PIL', 'tqdm'})\n"
            "print('HEAVY', heavy)\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip().splitlines()[-1] == "HEAVY []"


@pytest.mark.parametrize("flag", ["--help", "--version"])
def test_help_and_version_answer_in_half_a_second(flag):
    """the installed command answers --help and --version in under 0.5 s (best of three)"""
    import time

    walls = []
    for _ in range(3):
        start = time.perf_counter()
        r = subprocess.run(["clothsim", flag], capture_output=True, text=True)
        walls.append(time.perf_counter() - start)
        assert r.returncode == 0
    assert min(walls) < 0.5, walls


def test_every_subcommand_has_help(capsys):
    """each subcommand answers --help with exit 0 and names its scene argument"""
    for command in ("simulate", "render", "sweep", "view", "scenes"):
        with pytest.raises(SystemExit) as done:
            main([command, "--help"])
        assert done.value.code == 0
        out = capsys.readouterr().out
        assert out.startswith(f"usage: clothsim {command}")
        assert command == "scenes" or "standard scene" in out
