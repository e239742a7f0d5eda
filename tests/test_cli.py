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


@pytest.mark.parametrize("edit,key,strict", [
    ({"cloth": {"pinned": [[0, 0], [99, 0]]}}, "cloth.pinned[1]", ["--strict"]),
    ({"cloth": {"colour": [1, 1, 1]}}, "cloth.colour", ["--strict"]),
    ({"cloth": {"density": "heavy"}}, "cloth.density", []),
    ({"wind": 1}, "wind", []),
])
def test_bad_scene_one_line_exit_2(tmp_path, write_scene, capsys, edit, key, strict):
    """a bad scene (under --strict also what CS184 ignores) prints one line naming
    file and key, exits 2, and writes nothing"""
    data = small_scene()
    for k, v in edit.items():
        if k == "cloth":
            data["cloth"].update(v)
        else:
            data[k] = v
    scene = write_scene(data)
    out_obj = tmp_path / "never.obj"
    code, out, err = run(["simulate", scene, "--export", out_obj, *strict], capsys)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and str(scene) in lines[0] and key in lines[0]
    assert "Traceback" not in err
    assert not out_obj.exists()


def clothsim_process(*argv, timeout=300):
    env = {k: v for k, v in __import__("os").environ.items()}
    env["CLOTHSIM_PREWARM"] = "0"
    return subprocess.run([sys.executable, "-m", "clothsim", *map(str, argv)], capture_output=True, text=True,
                          timeout=timeout, env=env)


LENIENT = small_scene(cloth={"pinned": [[0, 0], [15, 0], [40, 0]], "colour": [1, 1, 1], "kss": 10},
                      sphere={"origin": [0.5, 0.2, 0.5], "radius": 0.2, "friction": 0.3, "fricton": 0.1},
                      plane={"point": [0, 0, 0], "normal": [0, 1, 0], "friction": 0.5, "offset": 0})
LENIENT_KEYS = ["cloth.colour", "cloth.kss", "cloth.pinned[2]", "sphere.fricton", "plane.offset"]


def test_what_cs184_ignores_runs_with_one_warning_line_each(tmp_path, write_scene):
    """simulate and render run a scene with keys CS184 ignores (exit 0), one warning
    line each on stderr naming the file, the key and the nearest known key; with
    --strict the first of them is one error line and exit 2"""
    scene = write_scene(LENIENT)
    out_obj = tmp_path / "c.obj"
    r = clothsim_process("simulate", scene, "--seconds", "0.02", "--no-progress", "--export", out_obj)
    assert r.returncode == 0, r.stderr
    warnings = [line for line in r.stderr.splitlines() if line.startswith("clothsim: warning:")]
    assert len(warnings) == len(LENIENT_KEYS), r.stderr
    for line, key in zip(warnings, LENIENT_KEYS):
        assert f"{scene}: {key}:" in line and "ignored" in line
    assert "nearest known key: 'ks'" in warnings[1] and "nearest known key: 'friction'" in warnings[3]
    assert "Traceback" not in r.stderr and out_obj.exists()
    for command in (["simulate", scene, "--seconds", "0.02"], ["render", scene, "-o", tmp_path / "x.png"]):
        s = clothsim_process(*command, "--strict")
        lines = s.stderr.strip().splitlines()
        assert s.returncode == 2 and len(lines) == 1, s.stderr
        assert lines[0].startswith("clothsim: error:") and f"{scene}: cloth.colour: unknown key" in lines[0]
    assert not (tmp_path / "x.png").exists()


def test_sweep_warns_once_per_ignored_key_and_strict_refuses(tmp_path, write_scene):
    """a sweep says each ignored key once (not once per run); --strict refuses before any run"""
    scene = write_scene(small_scene(cloth={"kss": 10}))
    r = clothsim_process("sweep", scene, "--vary", "cloth.ks=500,5000", "--seconds", "0.02", "--size", "64x64",
                         "--workers", "1", "--no-progress", "-o", tmp_path / "out")
    assert r.returncode == 0, r.stderr
    assert r.stderr.count("clothsim: warning:") == 1 and "cloth.kss: unknown key" in r.stderr, r.stderr
    s = clothsim_process("sweep", scene, "--vary", "cloth.ks=500,5000", "--strict", "-o", tmp_path / "out2")
    assert s.returncode == 2 and s.stderr.count("\n") == 1 and "cloth.kss: unknown key" in s.stderr
    assert not (tmp_path / "out2").exists()


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


USAGE_ERRORS = [
    (["simulate", "sphere", "--no-such-option"], "simulate: unrecognized arguments: --no-such-option"),
    (["simulate", "--no-such-option"], "simulate: the following arguments are required: scene"),
    (["render"], "render: the following arguments are required: scene, -o/--output"),
    (["render", "sphere", "-o"], "render: argument -o/--output: expected one argument"),
    (["sweep", "sphere", "-o", "out"], "sweep: the following arguments are required: --vary"),
    (["view", "sphere", "--shadr", "Phong"], "view: unrecognized arguments: --shadr Phong"),
    (["scenes", "extra"], "scenes: unrecognized arguments: extra"),
    (["no-such-command"], "argument COMMAND: invalid choice: 'no-such-command'"),
    ([], "the following arguments are required: COMMAND"),
]


@pytest.mark.parametrize("argv,message", USAGE_ERRORS, ids=[" ".join(a) or "(none)" for a, _ in USAGE_ERRORS])
def test_argparse_usage_errors_are_one_line_and_exit_2(argv, message):
    """argparse's own errors (unknown option, missing argument, bad choice): one
    line naming the subcommand and its --help, no usage block, exit 2"""
    r = subprocess.run([sys.executable, "-m", "clothsim", *argv], capture_output=True, text=True)
    assert r.returncode == 2, r.stderr
    assert r.stdout == ""
    lines = r.stderr.splitlines()
    assert len(lines) == 1 and r.stderr.endswith("\n"), r.stderr
    assert lines[0].startswith("clothsim: error: ") and message in lines[0], lines
    command = argv[0] if argv and argv[0] != "no-such-command" else None
    assert lines[0].endswith(f"(see 'clothsim {command} --help')" if command else "(see 'clothsim --help')")


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
