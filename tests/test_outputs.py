"""Output files: never placed over a file that appeared during the run (without
--overwrite), and every output's folder checked before the run starts."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

from clothsim.cli import main
from clothsim.errors import ClothsimError
from clothsim.outputs import OutputError, atomic_path, check_output_folder, check_writable

from .conftest import small_scene


def _leftovers(folder: Path, keep: set[str]) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name not in keep)


def test_a_file_that_appeared_during_the_write_is_kept_without_overwrite(tmp_path):
    out = tmp_path / "out.txt"
    with pytest.raises(OutputError, match="appeared there"):
        with atomic_path(out, overwrite=False) as tmp:
            tmp.write_text("ours")
            out.write_text("theirs")  # another run, or the user, while ours ran
    assert out.read_text() == "theirs"
    assert _leftovers(tmp_path, {"out.txt"}) == []  # no temporary file left behind


def test_a_file_that_appeared_during_the_write_is_replaced_with_overwrite(tmp_path):
    out = tmp_path / "out.txt"
    with atomic_path(out, overwrite=True) as tmp:
        tmp.write_text("ours")
        out.write_text("theirs")
    assert out.read_text() == "ours"
    assert _leftovers(tmp_path, {"out.txt"}) == []


def test_an_output_placed_without_overwrite_where_nothing_appeared_is_written(tmp_path):
    out = tmp_path / "out.txt"
    with atomic_path(out, overwrite=False) as tmp:
        tmp.write_text("ours")
    assert out.read_text() == "ours"
    assert _leftovers(tmp_path, {"out.txt"}) == []


@pytest.mark.parametrize("option,name", [("--export", "out.obj"), ("--export-npz", "out.npz")])
def test_simulate_keeps_an_export_that_appeared_during_the_run(tmp_path, write_scene, monkeypatch, capsys,
                                                               option, name):
    """the export is checked at the start and placed exclusively at the end: a file
    made at its path while the simulation ran is neither replaced nor lost"""
    from clothsim.cli import simulate

    out = tmp_path / name
    real = simulate.run_with_progress

    def run_and_meanwhile(*args, **kwargs):
        result = real(*args, **kwargs)
        out.write_text("theirs")
        return result

    monkeypatch.setattr(simulate, "run_with_progress", run_and_meanwhile)
    argv = ["simulate", str(write_scene(small_scene())), "--seconds", "0.02", "--no-progress", option, str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("clothsim: error:") and "appeared there" in err[0], err
    assert out.read_text() == "theirs"
    assert _leftovers(tmp_path, {name, "scene.json"}) == []
    out.unlink()
    assert main(argv + ["--overwrite"]) == 0  # with --overwrite the run's own file replaces it
    assert out.read_bytes() != b"theirs"


def _parent_cases(tmp_path: Path) -> dict[str, Path]:
    (tmp_path / "a_file").write_text("x")
    cases = {"missing": tmp_path / "no_such_folder" / "out", "a file": tmp_path / "a_file" / "out"}
    if Path("/proc").is_dir() and sys.platform.startswith("linux"):
        cases["read-only"] = Path("/proc") / "clothsim-out"  # no file can be made there, even as root
    elif os.geteuid() != 0:
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(0o500)
        cases["read-only"] = ro / "out"
    return cases


OPTIONS = [("simulate", "--export", ".obj"), ("simulate", "--export-npz", ".npz"),
           ("simulate", "--export-usd", ".usda"), ("simulate", "--export-sequence", ""),
           ("render", "-o", ".png")]


@pytest.mark.parametrize("command,option,suffix", OPTIONS, ids=[f"{c} {o}" for c, o, _ in OPTIONS])
def test_every_output_option_checks_its_folder_before_the_run(tmp_path, write_scene, capsys, monkeypatch,
                                                              command, option, suffix):
    """a folder that is missing, is a file or cannot be written: one line and exit 2,
    before the scene is built (nothing is simulated)"""
    if option == "--export-usd":
        pytest.importorskip("pxr")
    import clothsim.simulation

    def no_run(*args, **kwargs):
        raise AssertionError("the simulation was built before the output was checked")

    monkeypatch.setattr(clothsim.simulation.Simulation, "__init__", no_run)
    scene = str(write_scene(small_scene()))
    for why, base in _parent_cases(tmp_path).items():
        path = str(base) + suffix
        if option == "--export-sequence" and why == "missing":
            path = str(tmp_path / "a_file" / "deeper" / "seq")  # its nearest existing parent is a file
        assert main([command, scene, "--seconds", "0.02", "--no-progress", option, path]) == 2, why
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("clothsim: error:") and path in err[0], (why, err)


def test_an_export_sequence_folder_that_does_not_exist_yet_is_accepted(tmp_path):
    assert check_output_folder(tmp_path / "new" / "seq") == tmp_path / "new" / "seq"


def test_check_writable_names_the_folder_that_is_a_file(tmp_path):
    (tmp_path / "f").write_text("x")
    with pytest.raises(ClothsimError, match="is not a folder"):
        check_writable(tmp_path / "f" / "out.obj")
