"""Sweeps: the plan, the output folder, local workers and a real Dask cluster on loopback."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from PIL import Image

from clothsim.cli import main
from clothsim.errors import UsageError
from clothsim.sweep.plan import parse_vary, plan_runs

from .conftest import small_scene

SWEEP = ["--vary", "cloth.ks=500,5000,50000", "--seconds", "1.0", "--size", "96x96", "--no-progress"]


def test_parse_vary_lists_and_ranges():
    """lists keep their values; start:stop:count spreads count values evenly"""
    assert parse_vary("cloth.ks=500,5000") == ("cloth.ks", [500, 5000])
    assert parse_vary("cloth.damping=0:1:5") == ("cloth.damping", [0.0, 0.25, 0.5, 0.75, 1.0])
    assert parse_vary("simulation.gravity=[0,-9.8,0],[0,-1.6,0]")[1] == [[0, -9.8, 0], [0, -1.6, 0]]
    with pytest.raises(UsageError):
        parse_vary("cloth.ks")
    with pytest.raises(UsageError):
        parse_vary("cloth.ks=1:2:zero")


def test_plan_is_the_cross_product():
    """two --vary lists of 3 and 2 values give 6 runs with distinct names and digests"""
    specs = plan_runs(small_scene(), "s.json", ["cloth.ks=1,2,3", "cloth.damping=0,1"], 1.0, "Phong", (8, 8))
    assert len(specs) == 6
    assert [dict(s.values) for s in specs][:2] == [{"cloth.ks": 1, "cloth.damping": 0},
                                                   {"cloth.ks": 1, "cloth.damping": 1}]
    assert len({s.name for s in specs}) == 6 and len({s.digest() for s in specs}) == 6


def read_rows(path):
    with open(path) as f:
        return list(csv.DictReader(f))


def numbers(rows):
    return [(r["cloth.ks"], r["lowest_y"], r["sag"], r["max_stretch"], r["mean_speed"], r["at_rest"], r["frames"])
            for r in rows]


@pytest.fixture(scope="module")
def local_sweep(tmp_path_factory):
    scene = tmp_path_factory.mktemp("scene") / "small.json"
    scene.write_text(json.dumps(small_scene()))
    out = tmp_path_factory.mktemp("sweep") / "local"
    assert main(["sweep", str(scene), *SWEEP, "-o", str(out), "--workers", "2"]) == 0
    return scene, out


def test_local_sweep_outputs(local_sweep):
    """one PNG and OBJ per run, runs.csv with measured results, and a sheet of all runs"""
    _, out = local_sweep
    rows = read_rows(out / "runs.csv")
    assert [r["cloth.ks"] for r in rows] == ["500", "5000", "50000"]
    for r in rows:
        assert (out / r["png"]).is_file() and (out / r["obj"]).is_file() and r["error"] == ""
        assert float(r["wall_s"]) > 0 and r["frames"] == "90"
    lows = [float(r["lowest_y"]) for r in rows]
    assert lows[0] < lows[1] < lows[2]  # the softer the cloth, the lower it hangs
    sheet = np.asarray(Image.open(out / "sheet.png"))
    assert sheet.shape[1] == 3 * 96


def test_rerun_skips_and_protects(local_sweep, capsys):
    """a re-run skips finished runs; other settings into the same folder need --force"""
    scene, out = local_sweep
    before = (out / "000_ks=500.png").stat().st_mtime_ns
    assert main(["sweep", str(scene), *SWEEP, "-o", str(out)]) == 0
    assert "3 already done" in capsys.readouterr().out
    assert (out / "000_ks=500.png").stat().st_mtime_ns == before
    other = [a if a != "1.0" else "0.5" for a in SWEEP]
    assert main(["sweep", str(scene), *other, "-o", str(out)]) == 2
    assert "--force" in capsys.readouterr().err


def test_failed_run_is_recorded_and_others_go_on(tmp_path, write_scene, capsys):
    """a run the stability guard stops is recorded with its error; the rest complete; the sweep
    exits 1 and says how many failed, now and on a re-run that redoes nothing"""
    scene = write_scene(small_scene(simulation={"simulation_steps": 1}))
    out = tmp_path / "s"
    argv = ["sweep", str(scene), "--vary", "cloth.ks=100,1e9", "--seconds", "0.5", "--size", "32x32",
            "-o", str(out), "--workers", "1", "--no-progress"]
    assert main(argv) == 1
    assert "1 of 2 runs failed" in capsys.readouterr().err
    rows = read_rows(out / "runs.csv")
    assert rows[0]["error"] == "" and rows[0]["png"]
    assert "unstable" in rows[1]["error"] and rows[1]["png"] == ""
    assert main(argv) == 1
    assert "1 of 2 runs failed" in capsys.readouterr().err


def test_refuses_foreign_folder(tmp_path, write_scene, capsys):
    """a folder with a runs.csv the sweep did not write is left alone"""
    out = tmp_path / "mine"
    out.mkdir()
    (out / "runs.csv").write_text("my data")
    assert main(["sweep", str(write_scene(small_scene())), *SWEEP, "-o", str(out)]) == 2
    assert (out / "runs.csv").read_text() == "my data"


def test_dask_sweep_matches_local(local_sweep, dask_cluster, tmp_path, capsys):
    """the same sweep on a loopback Dask cluster gives the same runs.csv numbers, files on this side"""
    scene, local_out = local_sweep
    out = tmp_path / "dask"
    assert main(["sweep", str(scene), *SWEEP, "-o", str(out), "--scheduler", dask_cluster]) == 0
    assert dask_cluster in capsys.readouterr().out
    assert numbers(read_rows(out / "runs.csv")) == numbers(read_rows(local_out / "runs.csv"))
    assert len(list(out.glob("*.png"))) == 4  # three runs and the sheet


def test_unreachable_scheduler_is_one_line(tmp_path, write_scene, capsys):
    """a scheduler address nobody listens on gives a clear error, exit 2"""
    code = main(["sweep", str(write_scene(small_scene())), *SWEEP, "-o", str(tmp_path / "x"),
                 "--scheduler", "tcp://127.0.0.1:9"])
    assert code == 2 and "cannot reach the Dask scheduler" in capsys.readouterr().err


# ------------------------------------------------------------------ several cloths


def test_short_keys_tell_two_cloths_apart():
    """names and labels keep the last part of a key unless two keys share it"""
    specs = plan_runs({"cloth": [{}, {}]}, "s.json", ["cloth[0].ks=1,2", "cloth[1].ks=3", "sphere[0].radius=0.2"],
                      1.0, "Phong", (8, 8))
    assert specs[0].name == "000_cloth0.ks=1_cloth1.ks=3_radius=0.2"
    assert specs[1].label == "cloth[0].ks=2  cloth[1].ks=3  radius=0.2"
    assert plan_runs(small_scene(), "s.json", ["cloth.ks=1"], 1.0, "Phong", (8, 8))[0].name == "000_ks=1"


def test_sweep_of_one_cloth_of_two(tmp_path, write_scene, capsys):
    """--vary cloth[1].ks over a scene of two cloths (--set cloth[0].ks shared):
    runs.csv has each cloth's measures, the softer hanging cloth stretches more,
    each run's OBJ holds both cloths as objects"""
    import trimesh

    from clothsim import Simulation
    from clothsim.metrics import measure

    from .handmade import two_cloth_scene

    scene = write_scene(two_cloth_scene(), "two.json")
    out = tmp_path / "two"
    assert main(["sweep", str(scene), "--vary", "cloth[1].ks=100,20000", "--set", "cloth[0].ks=3000",
                 "--seconds", "0.3", "--size", "48x48", "-o", str(out), "--workers", "2", "--no-progress"]) == 0
    rows = read_rows(out / "runs.csv")
    assert [r["cloth[1].ks"] for r in rows] == ["100", "20000"] and all(r["error"] == "" for r in rows)
    for col in ("cloth_0.sag", "cloth_0.lowest_y", "cloth_0.max_stretch", "cloth_1.sag", "cloth_1.max_stretch"):
        assert all(r[col] for r in rows), col
    soft, stiff = (float(r["cloth_1.max_stretch"]) for r in rows)
    assert soft > stiff > 1.0
    # the numbers are measure() of the same run stepped here, to the csv's 9 digits
    sim = Simulation.from_file(scene, ["cloth[0].ks=3000", "cloth[1].ks=100"], threads=1)
    sim.run(0.3)
    expected = measure(sim)
    for col in ("sag", "max_stretch", "cloth_0.sag", "cloth_1.max_stretch", "cloth_1.lowest_y"):
        assert float(rows[0][col]) == pytest.approx(expected[col], rel=1e-8), col
    objects = trimesh.load(out / rows[0]["obj"], process=False, split_objects=True, group_material=False).geometry
    assert sorted(objects) == ["cloth_0", "cloth_1"] and len(objects["cloth_1"].vertices) == 96
    assert (out / "sheet.png").is_file()
