"""Command-line values at their edges, through the real command in a subprocess:
one line on stderr and exit code 2 before anything runs, or a failed sweep's exit 1."""

from __future__ import annotations

import csv
import os
import subprocess
import sys

import pytest

from clothsim.cli.values import FRAMES_MAX

from .conftest import small_scene


def clothsim(*argv, timeout=300):
    env = dict(os.environ, CLOTHSIM_PREWARM="0")
    return subprocess.run([sys.executable, "-m", "clothsim", *map(str, argv)], capture_output=True, text=True,
                          timeout=timeout, env=env)


def assert_one_line_error(run, *words):
    assert run.returncode == 2, run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("clothsim: error:"), run.stderr
    assert "compiling" not in run.stderr and "Traceback" not in run.stderr
    for w in words:
        assert w in lines[0], lines[0]


BAD_RUN_VALUES = [("--seconds", v) for v in ("nan", "inf", "-1", "1e308", "-inf")] + \
                 [("--threads", v) for v in ("0", "-1", "1e308", "9" * 5000, "100000")]


@pytest.mark.parametrize("option,value", BAD_RUN_VALUES, ids=[f"{o}={v[:8]}" for o, v in BAD_RUN_VALUES])
def test_simulate_refuses_a_non_finite_or_absurd_number_in_one_line(write_scene, option, value):
    run = clothsim("simulate", write_scene(small_scene()), f"{option}={value}", "--no-progress")  # = for -inf
    assert_one_line_error(run, option)


BAD_RENDER_VALUES = [("--fps", "nan"), ("--fps", "inf"), ("--fps", "-1"), ("--fps", "1e308"), ("--fps", "0"),
                     ("--size", "1e308x400"), ("--size", "9" * 5000 + "x16"), ("--size", "²²x16"),
                     ("--sphere-res", "100000000"), ("--sphere-res", "40,1e308"), ("--sphere-res", "²"),
                     ("--normal-scaling", "nan"), ("--height-scaling", "inf"), ("--camera", "0,nan,2"),
                     ("--light", "1e308,0,0"), ("--color", "inf,0,0"), ("--phong", "0.1,0.5,0.5,nan"),
                     ("--seconds", "nan")]


@pytest.mark.parametrize("option,value", BAD_RENDER_VALUES, ids=[f"{o}={v[:10]}" for o, v in BAD_RENDER_VALUES])
def test_render_refuses_a_non_finite_or_absurd_number_in_one_line(tmp_path, write_scene, option, value):
    out = tmp_path / ("out.mp4" if option == "--fps" else "out.png")
    run = clothsim("render", write_scene(small_scene()), "-o", out, f"{option}={value}", "--no-progress")
    assert_one_line_error(run, option)
    assert not out.exists()


@pytest.mark.parametrize("argv,option", [(["--seconds", "nan"], "--seconds"), (["--workers", "-1"], "--workers"),
                                         (["--workers", "1e308"], "--workers"), (["--size", "1e308x4"], "--size")])
def test_sweep_refuses_a_non_finite_or_absurd_number_in_one_line(tmp_path, write_scene, argv, option):
    run = clothsim("sweep", write_scene(small_scene()), "--vary", "cloth.ks=100,200", "-o", tmp_path / "s", *argv)
    assert_one_line_error(run, option)
    assert not (tmp_path / "s").exists()


def test_view_refuses_an_absurd_frame_count_in_one_line(write_scene):
    assert_one_line_error(clothsim("view", write_scene(small_scene()), "--frames", "1e308"), "--frames")


def test_a_run_of_more_frames_than_the_bound_is_refused_before_it_starts(write_scene):
    scene = write_scene(small_scene(simulation={"frames_per_sec": 10_000}))
    run = clothsim("simulate", scene, "--seconds", 1e6, "--no-progress")
    assert_one_line_error(run, "--seconds", f"at most {FRAMES_MAX:,}")


def test_readme_override_of_the_lone_sphere_runs(tmp_path):
    run = clothsim("simulate", "sphere", "--seconds", "0.02", "--no-progress", "--set", "sphere[0].radius=0.3",
                   "--set", "cloth.num_width_points=8", "--set", "cloth.num_height_points=8")
    assert run.returncode == 0, run.stderr


@pytest.mark.parametrize("override,key", [
    ("sphere[1].radius=0.3", "sphere[1].radius"), ("simulation.gravity=9.8", "simulation.gravity"),
    ("cloth.width=1e308", "cloth.width"), ("sphere[0].radius=5e-324", "sphere.radius"),
    ("cloth.num_width_points=" + "9" * 5000, "cloth.num_width_points"),
    ("cloth.pinned=" + "[" * 50_000 + "]" * 50_000, "cloth.pinned"),
    ("simulation.gravity=[0,-1e308,0]", "simulation.gravity[1]"),
])
def test_a_bad_override_is_one_line_naming_file_and_key(override, key):
    run = clothsim("simulate", "sphere", "--seconds", "0.02", "--no-progress", "--set", override)
    assert_one_line_error(run, "sphere.json", key)


def test_very_deep_scene_file_is_one_line(write_scene):
    run = clothsim("simulate", write_scene('{"cloth": ' + "[" * 100_000 + "]" * 100_000 + "}"), "--seconds", "0.02",
                   "--no-progress", "--set", "cloth.ks=1")
    assert_one_line_error(run, "scene.json", "levels")


def test_sweep_with_a_failed_run_exits_1_and_says_how_many(tmp_path):
    out = tmp_path / "s"
    run = clothsim("sweep", "sphere", "--vary", "cloth.ks=5000,1e9", "--set", "simulation.simulation_steps=2",
                   "--set", "cloth.num_width_points=8", "--set", "cloth.num_height_points=8", "--seconds", "0.2",
                   "--size", "32x32", "--workers", "1", "--no-progress", "-o", out, timeout=600)
    assert run.returncode == 1, run.stderr
    assert "1 of 2 runs failed" in run.stderr and "Traceback" not in run.stderr
    with open(out / "runs.csv") as f:
        rows = list(csv.DictReader(f))
    assert rows[0]["error"] == "" and (out / rows[0]["png"]).is_file()  # the good run's results are kept
    assert "unstable" in rows[1]["error"]
