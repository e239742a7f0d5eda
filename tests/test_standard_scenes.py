"""The standard scenes ship inside the package and every command finds them by name."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import pytest

from clothsim import SceneError, load_scene
from clothsim.cli import main
from clothsim.standard_scenes import find_scene, names, scene_path, scenes_dir

from .conftest import ROOT, SCENES, small_scene

GRID = ["pinned2", "pinned4", "plane", "selfCollision", "sphere"]
"""the CS184 scenes: one 50x50 grid cloth each"""
MESH = ["drape", "flag", "tablecloth", "two_cloths"]
"""clothsim's scenes of mesh cloths and of several cloths (tests/test_mesh_scenes.py)"""
WORLD = ["curtain", "spinning_sphere", "table_pull", "torus_drape", "windy_flag"]
"""clothsim's scenes of the moving world: boxes, mesh colliders, motion, handles, wind
(tests/test_world_scenes.py)"""
STANDARD = sorted(GRID + MESH + WORLD, key=str.lower)


def test_standard_scenes_inside_the_package():
    """the standard scenes are files of the installed package, and each one loads:
    the CS184 ones a 50x50 grid, the others at least one mesh cloth"""
    import clothsim

    assert names() == STANDARD
    assert scenes_dir().resolve() == (Path(clothsim.__file__).resolve().parent / "scenes")
    for name in GRID:
        scene = load_scene(scene_path(name))
        assert scene.cloth.num_width_points == 50 and scene.cloth.num_height_points == 50
    for name in MESH:
        assert any(hasattr(c, "mesh") for c in load_scene(scene_path(name)).cloths)


def test_package_data_matches_the_scenes():
    """pyproject's package data names the scene files, so a wheel carries them"""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    globs = config["tool"]["setuptools"]["package-data"]["clothsim"]
    package = ROOT / "src" / "clothsim"
    shipped = {p.name for g in globs for p in package.glob(g) if p.parent.name == "scenes"}
    assert shipped == {f"{n}.json" for n in STANDARD}


def test_root_scenes_folder_is_the_packaged_one():
    """scenes/ at the repository root is the package's folder (a link), so old paths still work"""
    assert SCENES.is_symlink() and SCENES.resolve() == (ROOT / "src" / "clothsim" / "scenes").resolve()
    assert (SCENES / "sphere.json").read_bytes() == scene_path("sphere").read_bytes()


def test_bare_name_finds_a_standard_scene(tmp_path, monkeypatch):
    """'sphere', 'sphere.json' and 'SPHERE' mean the packaged sphere scene when no such file is here"""
    monkeypatch.chdir(tmp_path)
    for text in ("sphere", "sphere.json", "SPHERE"):
        assert find_scene(text) == scenes_dir() / "sphere.json"


def test_real_file_wins_over_a_name(tmp_path, monkeypatch):
    """a file of that exact name in the working folder is the one that loads"""
    monkeypatch.chdir(tmp_path)
    for name in ("sphere.json", "sphere"):
        (tmp_path / name).write_text(json.dumps(small_scene()))
        assert find_scene(name) == Path(name)
        assert load_scene(find_scene(name)).cloth.num_width_points == 16


def test_missing_path_with_a_folder_is_not_looked_up(tmp_path):
    """a path with a folder in it is never taken for a name: reading it says 'no such file'"""
    missing = tmp_path / "sphere.json"
    assert find_scene(missing) == missing
    assert find_scene("sub/sphere") == Path("sub/sphere")


def test_unknown_name_names_the_known_scenes(tmp_path, monkeypatch):
    """an unknown bare name is a SceneError that lists the standard scenes"""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SceneError) as err:
        find_scene("spher")
    assert all(n in str(err.value) for n in STANDARD) and "spher" in str(err.value)


def test_simulate_and_render_by_name(tmp_path, monkeypatch, capsys):
    """`clothsim simulate pinned2` and `clothsim render sphere -o out.png` run the packaged scenes"""
    monkeypatch.chdir(tmp_path)
    grid = ["--set", "cloth.num_width_points=8", "--set", "cloth.num_height_points=8"]
    assert main(["simulate", "pinned2", "--seconds", "0.1", *grid, "--set", "cloth.pinned=[[0,0],[7,0]]"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("pinned2.json: 9 frames") and "64 points" in out
    assert main(["render", "sphere", "-o", "out.png", "--seconds", "0", "--size", "32x32", *grid]) == 0
    assert "sphere.json" in capsys.readouterr().out and (tmp_path / "out.png").stat().st_size > 0


def test_unknown_name_is_one_line_exit_2(tmp_path, monkeypatch, capsys):
    """`clothsim render spher -o x.png` fails on one line naming the standard scenes, exit 2, no file"""
    monkeypatch.chdir(tmp_path)
    assert main(["render", "spher", "-o", "x.png"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("clothsim: error: spher: ")
    assert all(n in err for n in STANDARD) and not (tmp_path / "x.png").exists()


def test_scenes_command_lists_each_with_a_description(capsys):
    """`clothsim scenes` prints one line per standard scene saying what it holds"""
    assert main(["scenes"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert [line.split()[0] for line in lines] == STANDARD
    described = dict(line.split(None, 1) for line in lines)
    assert described["pinned2"] == "50×50 horizontal cloth, 1×1 m, pinned at 2 corners"
    assert described["pinned4"].endswith("pinned at 4 corners")
    assert described["sphere"].endswith("falls onto a sphere")
    assert described["selfCollision"].startswith("50×50 vertical cloth") and "plane" in described["selfCollision"]
    assert described["tablecloth"] == "1951-point triangle mesh disc.obj, 1.5 m², horizontal, falls onto a sphere"
    assert described["flag"] == "800-point quad mesh flag.obj, 0.5 m², vertical, pinned at 20 points, hangs above a plane"
    assert described["drape"].startswith("2500-point triangle mesh delaunay_square.obj, 1 m²")
    assert described["two_cloths"] == ("2 cloths: 40×40 horizontal cloth, 1×1 m, ks 500; "
                                       "1024-point quad mesh sheet.obj, 0.64 m², horizontal, ks 5000; "
                                       "fall onto a plane")


def test_sweep_by_name(tmp_path, monkeypatch, capsys):
    """`clothsim sweep pinned2 --vary ...` sweeps the packaged scene"""
    monkeypatch.chdir(tmp_path)
    small = ["--set", "cloth.num_width_points=8", "--set", "cloth.num_height_points=8",
             "--set", "cloth.pinned=[[0,0],[7,0]]"]
    assert main(["sweep", "pinned2", "--vary", "cloth.ks=500,5000", *small, "--seconds", "0.1",
                 "--size", "32x32", "--workers", "1", "--no-progress", "-o", "out"]) == 0
    assert "2 runs" in capsys.readouterr().out
    assert len(list((tmp_path / "out").glob("*.png"))) == 3  # two runs and the sheet
