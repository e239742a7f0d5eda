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
    err = [line for line in capsys.readouterr().err.strip().splitlines()
           if not line.startswith("clothsim: compiling")]  # said once, on a cold kernel cache
    assert len(err) == 1 and err[0].startswith("clothsim: error:") and "appeared there" in err[0], err
    assert out.read_text() == "theirs"
    assert _leftovers(tmp_path, {name, "scene.json"}) == []
    out.unlink()
    assert main(argv + ["--overwrite"]) == 0  # with --overwrite the run's own file replaces it
    assert out.read_bytes() != b"theirs"


@pytest.mark.parametrize("background", [True, False])
def test_export_sequence_keeps_a_frame_file_that_appeared_during_the_run(tmp_path, background):
    """each frame is placed exclusively, as every other output: a file made at a
    later frame's name after the run began is kept, the run stops with
    OutputError, and no temporary file is left; with overwrite it is replaced"""
    from clothsim import Simulation
    from clothsim.export.objseq import ObjSequence
    from clothsim.scene import parse_scene

    sim = Simulation(parse_scene(small_scene()))
    for overwrite in (False, True):
        folder = tmp_path / f"seq_{overwrite}"
        folder.mkdir()
        theirs = folder / "frame_0003.obj"
        seq = ObjSequence(folder, sim.model.uvs, sim.model.triangles, background=background, overwrite=overwrite)
        theirs.write_text("theirs")  # after the start, before frame 3 is written
        if overwrite:
            with seq:
                for k in range(6):
                    seq.write(k, sim.positions)
            assert theirs.read_text().startswith("# clothsim")
            assert sorted(os.listdir(folder)) == [f"frame_{k:04d}.obj" for k in range(6)]
            continue
        with pytest.raises(OutputError, match="frame_0003.obj: a file appeared there"):
            for k in range(40):  # the error comes from a later write() or from close()
                seq.write(k, sim.positions)
            seq.close()
        seq.close()  # once raised, closing again is quiet
        assert theirs.read_text() == "theirs"
        names = sorted(os.listdir(folder))
        assert not [n for n in names if n.startswith(".")], names  # no temporary file left
        assert names[:4] == [f"frame_{k:04d}.obj" for k in range(4)]  # the frames before it were written


def test_simulate_keeps_a_sequence_frame_that_appeared_during_the_run(tmp_path, write_scene, monkeypatch, capsys):
    """``--export-sequence``: a frame file made while the run goes is kept, the run
    ends with one line and exit 2; with --overwrite it is replaced"""
    from clothsim.cli import simulate

    folder = tmp_path / "seq"
    theirs = folder / "frame_0002.obj"
    real = simulate.run_with_progress

    def run_and_meanwhile(*args, **kwargs):
        theirs.write_text("theirs")  # the folder is checked and frame 0 is on its way
        return real(*args, **kwargs)

    monkeypatch.setattr(simulate, "run_with_progress", run_and_meanwhile)
    argv = ["simulate", str(write_scene(small_scene())), "--seconds", "0.1", "--no-progress",
            "--export-sequence", str(folder)]
    assert main(argv) == 2
    err = [line for line in capsys.readouterr().err.strip().splitlines()
           if not line.startswith("clothsim: compiling")]  # said once, on a cold kernel cache
    assert len(err) == 1 and err[0].startswith("clothsim: error:") and "frame_0002.obj" in err[0] \
        and "appeared there" in err[0] and "--overwrite" in err[0], err
    assert theirs.read_text() == "theirs"
    assert not [p.name for p in folder.iterdir() if p.name.startswith(".")]
    for p in folder.iterdir():
        if p != theirs:
            p.unlink()
    assert main(argv + ["--overwrite"]) == 0
    assert theirs.read_text().startswith("# clothsim")
    assert len(list(folder.glob("frame_*.obj"))) == 10  # frames 0..9: 0.1 s at 90 frames/s


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
