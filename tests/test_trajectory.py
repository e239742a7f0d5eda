"""clothsim.record and what shows a run in a notebook; the OBJ text (the compiled
formatter against numpy's, a round trip through trimesh) and the OBJ sequence
written in the background."""

from __future__ import annotations

import io
import os
import subprocess
import sys

import numpy as np
import pytest

import clothsim
from clothsim import Simulation
from clothsim.export import obj_text, write_obj
from clothsim.export import objtext
from clothsim.export.obj import obj_bytes
from clothsim.export.objseq import ObjSequence

from .conftest import small_scene


@pytest.fixture
def scene(write_scene):
    return write_scene(small_scene())


# ------------------------------------------------------------------ record


def test_record_frames_and_times(scene):
    """frame 0 and then every frame: round(seconds * fps) + 1 of them, 1/fps apart"""
    sim = Simulation.from_file(scene)
    fps = sim.params.frames_per_sec
    traj = clothsim.record(sim, 0.2)
    frames = round(0.2 * fps)
    assert traj.positions.shape == (frames + 1, 256, 3) and traj.positions.dtype == np.float64
    assert traj.times.shape == (frames + 1,) and traj.times[0] == 0.0
    np.testing.assert_allclose(traj.times, np.arange(frames + 1) / fps, rtol=0, atol=1e-12)
    assert traj.frames_per_sec == fps and sim.frame == frames
    assert traj.triangles.shape == (450, 3) and traj.uvs.shape == (256, 2)
    assert traj.name == "scene" and traj.scene["cloth"]["num_width_points"] == 16


def test_record_every(scene):
    """every=k keeps the start and each k-th frame; the simulation runs them all"""
    sim = Simulation.from_file(scene)
    fps = sim.params.frames_per_sec
    frames = round(0.2 * fps)
    traj = clothsim.record(sim, 0.2, every=4)
    assert traj.num_frames == frames // 4 + 1 and sim.frame == frames
    np.testing.assert_allclose(traj.times, 4 * np.arange(traj.num_frames) / fps, rtol=0, atol=1e-12)
    assert traj.frames_per_sec == fps / 4
    ref = Simulation.from_file(scene)
    for k in range(1, traj.num_frames):
        for _ in range(4):
            ref.step()
        np.testing.assert_array_equal(traj.positions[k], ref.positions)


def test_record_starts_from_the_state_before_and_matches_a_separate_run(scene):
    """frame 0 is the state when record() is called (here after 3 frames), and each
    frame is bit for bit that of an identical run stepped by hand"""
    sim = Simulation.from_file(scene)
    for _ in range(3):
        sim.step()
    before = sim.positions.copy()
    traj = clothsim.record(sim, 0.1)
    np.testing.assert_array_equal(traj.positions[0], before)
    assert traj.times[0] == pytest.approx(3 / sim.params.frames_per_sec)
    ref = Simulation.from_file(scene)
    for _ in range(3):
        ref.step()
    for k in range(1, traj.num_frames):
        ref.step()
        np.testing.assert_array_equal(traj.positions[k], ref.positions)
        assert traj.times[k] == ref.time
    np.testing.assert_array_equal(sim.positions, ref.positions)


def test_record_zero_seconds_and_bad_arguments(scene):
    sim = Simulation.from_file(scene)
    traj = clothsim.record(sim, 0.0)
    assert traj.num_frames == 1 and sim.frame == 0
    for kwargs in ({"every": 0}, {"every": 1.5}, {"every": True}):
        with pytest.raises(ValueError, match="every"):
            clothsim.record(sim, 0.1, **kwargs)
    for seconds in (-1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="seconds"):
            clothsim.record(sim, seconds)
    assert sim.frame == 0


def test_import_clothsim_loads_no_numba_and_record_is_lazy():
    code = ("import sys, clothsim\n"
            "assert 'numba' not in sys.modules\n"
            "assert 'record' in clothsim.__all__ and 'Trajectory' in clothsim.__all__\n"
            "from clothsim.trajectory import record, Trajectory\n"
            "assert clothsim.record is record and clothsim.Trajectory is Trajectory\n"
            "print('ok')\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0 and r.stdout.strip() == "ok", r.stderr


# ------------------------------------------------------------------ notebooks


def test_simulation_shows_its_last_recording(scene):
    """a Simulation shows the frames of its last record() call, else its current frame;
    a Trajectory shows itself; both as the web player in an iframe"""
    pytest.importorskip("clothsim.export.web")
    sim = Simulation.from_file(scene)
    assert sim.recording is None
    player = sim.show()
    assert player.trajectory.num_frames == 1
    np.testing.assert_array_equal(player.trajectory.positions[0], sim.positions)
    first = clothsim.record(sim, 0.1)
    second = clothsim.record(sim, 0.05)
    assert sim.recording is second and first is not second  # the last one only
    assert sim.show().trajectory is second
    page = sim._repr_html_()
    assert page.startswith('<iframe class="clothsim-player" srcdoc="') and page.endswith("</iframe>")
    assert "&lt;html" in page and "clothsim-pos-0" in page and 'sandbox="allow-scripts"' in page
    assert second._repr_html_() == page
    small = second.show(320, 200, color=(0.2, 0.4, 0.8))
    assert 'width="320" height="200"' in small._repr_html_()
    with pytest.raises(ValueError, match="width"):
        second.show(0, 200)


def test_player_saves_the_page(scene, tmp_path):
    pytest.importorskip("clothsim.export.web")
    from clothsim.export.web import player_html

    sim = Simulation.from_file(scene)
    traj = clothsim.record(sim, 0.05)
    out = tmp_path / "run.html"
    traj.show().save(out)
    assert out.read_text(encoding="utf-8") == player_html(traj)


# ------------------------------------------------------------------ OBJ text


def _savetxt(values: np.ndarray, prefix: str, precision: int) -> bytes:
    buf = io.StringIO()
    np.savetxt(buf, values, fmt=prefix + " ".join([f"%.{precision}g"] * values.shape[1]))
    return buf.getvalue().encode()


def _hard_values(rng: np.random.Generator, precision: int) -> np.ndarray:
    """magnitudes over the whole double range, values next to rounding ties,
    powers of ten and their neighbours, exact (dyadic) ties, zeros, nan, inf"""
    spread = 10.0 ** rng.uniform(-320, 300, 30000) * rng.choice([-1.0, 1.0], 30000)
    digits = rng.integers(10 ** (precision - 1), 10 ** precision, 20000).astype(np.float64)
    ties = (digits + 0.5) / 10.0 ** rng.integers(-12, 30, 20000)
    near = np.concatenate([ties, np.nextafter(ties, np.inf), np.nextafter(ties, -np.inf)])
    p10 = 10.0 ** np.arange(-300, 300)
    edges = np.concatenate([p10, np.nextafter(p10, 0), np.nextafter(p10, np.inf),
                            p10 * (1 - 0.5 * 10.0 ** -precision)])
    dyadic = np.arange(1, 20000) / 1024.0
    special = np.array([0.0, -0.0, np.nan, -np.nan, np.inf, -np.inf, 5e-324, -5e-324, 1.7976931348623157e308,
                        1e-4, 9.9999999995e-5, 1e9, 123456789.5, 1234567895.0, 0.999999999, 1.0])
    values = np.concatenate([spread, rng.normal(0, 1, 20000), near, edges, -edges, dyadic, -dyadic, special])
    return values[: len(values) // 3 * 3].reshape(-1, 3)


@pytest.mark.parametrize("precision", [6, 9, 15])
def test_formatter_writes_what_numpy_writes(precision):
    """byte for byte np.savetxt's %.{P}g, on values chosen to trip a formatter up"""
    values = _hard_values(np.random.default_rng(precision), precision)
    assert objtext.format_rows(values, "v ", precision) == _savetxt(values, "v ", precision)


def test_formatter_falls_back_where_the_rounding_is_undecided():
    """1234567895 to 9 digits is an exact tie outside the exact range: the kernel
    says so and Python formats it (half to even: 1.2345679e+09)"""
    values = np.array([[1234567895.0, 1.0, 2.0]])
    out = np.empty(200, np.uint8)
    assert objtext._format_rows(values, np.frombuffer(b"v ", np.uint8), 9, out, 0) == objtext.UNDECIDED
    assert objtext.format_rows(values, "v ", 9) == b"v 1.2345679e+09 1 2\n" == _savetxt(values, "v ", 9)


def _cloth(scene, frames: int = 20) -> Simulation:
    sim = Simulation.from_file(scene)
    for _ in range(frames):
        sim.step()
    return sim


def _old_obj_text(positions, normals, uvs, triangles) -> str:
    """the writer this one replaced (np.savetxt)"""
    buf = io.StringIO()
    buf.write("# clothsim cloth mesh\n")
    np.savetxt(buf, positions, fmt="v %.9g %.9g %.9g")
    np.savetxt(buf, uvs, fmt="vt %.6g %.6g")
    np.savetxt(buf, normals, fmt="vn %.6g %.6g %.6g")
    np.savetxt(buf, np.repeat(triangles.astype(np.int64) + 1, 3, axis=1), fmt="f %d/%d/%d %d/%d/%d %d/%d/%d")
    return buf.getvalue()


def test_obj_text_round_trip(scene, tmp_path):
    """the same text as np.savetxt wrote; parsed back, the v lines are the positions
    to 9 digits, the vn lines the normals to 6, the f lines the triangles"""
    sim = _cloth(scene)
    p, n, uv, tri = sim.positions, sim.normals, sim.model.uvs, sim.model.triangles
    text = obj_text(p, n, uv, tri)
    assert text == _old_obj_text(p, n, uv, tri)
    rows = {"v": [], "vt": [], "vn": [], "f": []}
    for line in text.splitlines()[1:]:
        kind, *fields = line.split()
        rows[kind].append(fields)
    v = np.array(rows["v"], float)
    np.testing.assert_array_equal(v, np.vectorize(lambda x: float(f"{x:.9g}"))(p))
    np.testing.assert_allclose(v, p, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(np.array(rows["vn"], float), n, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(np.array(rows["vt"], float), uv, rtol=1e-5, atol=1e-6)
    faces = np.array([[int(c.split("/")[0]) for c in f] for f in rows["f"]]) - 1
    np.testing.assert_array_equal(faces, tri)
    assert all(len(set(c.split("/"))) == 1 for f in rows["f"] for c in f)  # v/vt/vn share the index


def test_obj_loads_in_trimesh(scene, tmp_path):
    trimesh = pytest.importorskip("trimesh")
    sim = _cloth(scene)
    path = tmp_path / "cloth.obj"
    sim.export_obj(path)
    mesh = trimesh.load(path, process=False, maintain_order=True)
    assert len(mesh.vertices) == sim.model.num_points
    np.testing.assert_array_equal(mesh.faces, sim.model.triangles)
    np.testing.assert_allclose(mesh.vertices, sim.positions, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(mesh.vertex_normals, sim.normals, atol=1e-5)


def test_write_obj_reuses_the_mesh_text_only_for_the_same_mesh(scene, tmp_path):
    sim = _cloth(scene, 2)
    p, n, uv, tri = sim.positions, sim.normals, sim.model.uvs, sim.model.triangles
    a = obj_bytes(p, n, uv, tri)
    flipped = tri[:, ::-1].copy()
    b = obj_bytes(p, n, uv, flipped)
    assert a != b and b.decode() == _old_obj_text(p, n, uv, flipped)
    write_obj(tmp_path / "x.obj", p, n, uv, tri)
    assert (tmp_path / "x.obj").read_bytes() == a


# ------------------------------------------------------------------ OBJ sequence


def _frames(scene, count: int = 12) -> tuple[Simulation, list[tuple[np.ndarray, np.ndarray]]]:
    sim = Simulation.from_file(scene)
    frames = [(sim.positions.copy(), sim.normals.copy())]
    for _ in range(count - 1):
        sim.step()
        frames.append((sim.positions.copy(), sim.normals.copy()))
    return sim, frames


@pytest.mark.parametrize("background", [True, False])
def test_obj_sequence_writes_every_frame(scene, tmp_path, background):
    """frame_NNNN.obj for each frame, each what write_obj writes, nothing else left
    (a ring of two frames makes write() wait for the thread)"""
    sim, frames = _frames(scene)
    out = tmp_path / "seq"
    out.mkdir()
    with ObjSequence(out, sim.model.uvs, sim.model.triangles, background=background, ring_bytes=1) as seq:
        assert seq.background == (background and objtext.NATIVE_WRITE)
        for k, (p, n) in enumerate(frames):
            seq.write(k, p, n if k % 2 else None)  # None: the normals are computed there
    assert sorted(os.listdir(out)) == [f"frame_{k:04d}.obj" for k in range(len(frames))]
    for k, (p, n) in enumerate(frames):
        assert (out / f"frame_{k:04d}.obj").read_bytes() == obj_bytes(p, n, sim.model.uvs, sim.model.triangles)
    with pytest.raises(ValueError, match="closed"):
        seq.write(99, *frames[0])


@pytest.mark.skipif(not objtext.NATIVE_WRITE, reason="the C library's write is called on 64-bit POSIX only")
def test_write_frames_kernel_writes_and_renames(scene, tmp_path):
    """the compiled writer itself (its failures would be hidden by the Python redo)"""
    sim, frames = _frames(scene, 3)
    tmp_path = tmp_path / "out"
    tmp_path.mkdir()
    seq = ObjSequence(tmp_path, sim.model.uvs, sim.model.triangles, background=False)
    positions = np.stack([p for p, _ in frames])
    normals = np.stack([n for _, n in frames])
    normals[2] = np.nan  # computed by the kernel (compute[0])
    names = [os.fsencode(tmp_path / f"t{k}") + b"\0" for k in range(4)]
    names[1] = os.fsencode(tmp_path / "b.obj") + b"\0"
    names[3] = os.fsencode(tmp_path / "a.obj") + b"\0"
    width = max(map(len, names))
    table = np.frombuffer(b"".join(n.ljust(width, b"\0") for n in names), np.uint8).reshape(4, width)
    status = np.full(2, -1, np.int64)
    u8 = lambda b: np.frombuffer(b, np.uint8)  # noqa: E731
    objtext.write_frames(positions, normals, np.array([2, 0]), np.array([True, False]),
                         sim.model.triangles.astype(np.int32), table, u8(b"# clothsim cloth mesh\n"),
                         u8(seq.mesh.vt), u8(seq.mesh.faces), u8(b"v "), u8(b"vn "),
                         np.empty(256 * 100, np.uint8), status, False)
    assert status.tolist() == [objtext.FRAME_OK, objtext.FRAME_OK]
    assert sorted(os.listdir(tmp_path)) == ["a.obj", "b.obj"]
    uv, tri = sim.model.uvs, sim.model.triangles
    assert (tmp_path / "b.obj").read_bytes() == obj_bytes(*frames[2], uv, tri)
    # the same function as Simulation.normals, compiled into the kernel: fastmath may
    # contract its arithmetic differently there, within the last bit or two
    np.testing.assert_allclose(normals[2], frames[2][1], rtol=1e-14, atol=1e-15)
    assert (tmp_path / "a.obj").read_bytes() == obj_bytes(*frames[0], uv, tri)


@pytest.mark.skipif(not objtext.NATIVE_WRITE, reason="the C library's write is called on 64-bit POSIX only")
def test_write_frames_kernel_exclusive_links_and_never_replaces(scene, tmp_path):
    """exclusive: a free name gets the file (and the temporary name is gone); a
    taken one keeps its file and the whole temporary file is left, FRAME_NOT_PLACED"""
    sim, frames = _frames(scene, 2)
    tmp_path = tmp_path / "out"
    tmp_path.mkdir()
    seq = ObjSequence(tmp_path, sim.model.uvs, sim.model.triangles, background=False)
    positions = np.stack([p for p, _ in frames])
    normals = np.stack([n for _, n in frames])
    (tmp_path / "taken.obj").write_text("theirs")
    paths = [tmp_path / "t0", tmp_path / "free.obj", tmp_path / "t1", tmp_path / "taken.obj"]
    names = [os.fsencode(p) + b"\0" for p in paths]
    width = max(map(len, names))
    table = np.frombuffer(b"".join(n.ljust(width, b"\0") for n in names), np.uint8).reshape(4, width)
    status = np.full(2, -1, np.int64)
    u8 = lambda b: np.frombuffer(b, np.uint8)  # noqa: E731
    objtext.write_frames(positions, normals, np.array([0, 1]), np.array([False, False]),
                         sim.model.triangles.astype(np.int32), table, u8(b"# clothsim cloth mesh\n"),
                         u8(seq.mesh.vt), u8(seq.mesh.faces), u8(b"v "), u8(b"vn "),
                         np.empty(256 * 100, np.uint8), status, True)
    assert status.tolist() == [objtext.FRAME_OK, objtext.FRAME_NOT_PLACED]
    assert sorted(os.listdir(tmp_path)) == ["free.obj", "t1", "taken.obj"]
    uv, tri = sim.model.uvs, sim.model.triangles
    assert (tmp_path / "free.obj").read_bytes() == obj_bytes(*frames[0], uv, tri)
    assert (tmp_path / "taken.obj").read_text() == "theirs"
    assert (tmp_path / "t1").read_bytes() == obj_bytes(*frames[1], uv, tri)


def test_obj_sequence_formats_an_undecided_frame_in_python(scene, tmp_path):
    sim, frames = _frames(scene, 3)
    odd = frames[1][0].copy()
    odd[5, 0] = 1234567895.0  # an exact tie the kernel leaves to Python
    with ObjSequence(tmp_path, sim.model.uvs, sim.model.triangles) as seq:
        for k, (p, n) in enumerate([frames[0], (odd, frames[1][1]), frames[2]]):
            seq.write(k, p, n)
    text = (tmp_path / "frame_0001.obj").read_text()
    assert "\nv 1.2345679e+09 " in text
    assert text == _old_obj_text(odd, frames[1][1], sim.model.uvs, sim.model.triangles)


@pytest.mark.parametrize("background", [True, False])
def test_obj_sequence_into_a_vanished_folder_raises(scene, tmp_path, background):
    """a folder gone during the run: the error of Python's own write, from write()
    or close(), and nothing written"""
    sim, frames = _frames(scene, 2)
    folder = tmp_path / "gone"
    seq = ObjSequence(folder, sim.model.uvs, sim.model.triangles, background=background)
    with pytest.raises(FileNotFoundError):
        for k, (p, n) in enumerate(frames * 40):
            seq.write(k, p, n)
        seq.close()
    seq.close()  # once raised, closing again is quiet
    assert not folder.exists()


def test_obj_sequence_left_open_is_written_at_exit(scene, tmp_path):
    """a run that stops without close() (say, on a SimulationError) keeps its frames"""
    code = ("import sys\nfrom clothsim import Simulation\nfrom clothsim.export.objseq import ObjSequence\n"
            f"sim = Simulation.from_file({str(scene)!r})\n"
            f"seq = ObjSequence({str(tmp_path / 'seq')!r}, sim.model.uvs, sim.model.triangles)\n"
            "for k in range(30):\n    seq.write(k, sim.positions, sim.normals)\n    sim.step()\n"
            "raise SystemExit(3)\n")
    (tmp_path / "seq").mkdir()
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 3, r.stderr
    assert sorted(os.listdir(tmp_path / "seq")) == [f"frame_{k:04d}.obj" for k in range(30)]


# ------------------------------------------------------------------ several cloths, mesh cloths


def test_trajectory_keeps_the_cloths_and_their_ranges():
    """a trajectory of a disc and a grid names both cloths with their point and
    triangle ranges; one made by hand without them is one cloth of everything"""
    from clothsim.trajectory import Trajectory, TrajectoryRecorder

    from .handmade import disc_and_grid, simulation_of

    sim = simulation_of(disc_and_grid())
    traj = TrajectoryRecorder(sim).trajectory(sim)
    assert [(c.name, c.start, c.stop, c.tri_start, c.tri_stop) for c in traj.parts] == [
        ("disc", 0, 217, 0, 384), ("grid", 217, 473, 384, 834)]
    bare = Trajectory(traj.positions, traj.times, traj.triangles, traj.uvs, 90.0)
    (whole,) = bare.parts
    assert (whole.name, whole.start, whole.stop, whole.tri_start, whole.tri_stop) == ("cloth", 0, 473, 0, 834)


def test_obj_sequence_writes_one_object_per_cloth(tmp_path):
    """ObjSequence with objects, in the background and not: the same bytes as
    obj_bytes with those objects, an o line before each cloth's faces"""
    from clothsim.export.obj import model_objects

    from .handmade import disc_and_grid, simulation_of

    sim = simulation_of(disc_and_grid())
    objects = model_objects(sim.model)
    assert objects == (("disc", 0, 384), ("grid", 384, 834))
    expected = obj_bytes(sim.positions, sim.normals, sim.model.uvs, sim.model.triangles, objects)
    for background in (True, False):
        folder = tmp_path / str(background)
        folder.mkdir()
        with ObjSequence(folder, sim.model.uvs, sim.model.triangles, background=background, objects=objects) as seq:
            seq.write(0, sim.positions)
        assert (folder / "frame_0000.obj").read_bytes() == expected
    lines = expected.decode().splitlines()
    o_at = [k for k, line in enumerate(lines) if line.startswith("o ")]
    assert [lines[k] for k in o_at] == ["o disc", "o grid"]
    assert o_at[1] - o_at[0] == 384 + 1 and len(lines) - o_at[1] == 450 + 1
    assert not any(line.startswith(("v", "vt", "vn")) for line in lines[o_at[0]:])  # vertices first


def test_obj_objects_must_cover_the_triangles_in_order():
    from clothsim.export.obj import MeshText

    uv, tri = np.zeros((4, 2)), np.array([[0, 1, 2], [1, 3, 2]])
    with pytest.raises(ValueError, match="follow each other"):
        MeshText(uv, tri, (("a", 0, 1),))
    with pytest.raises(ValueError, match="follow each other"):
        MeshText(uv, tri, (("a", 1, 2), ("b", 0, 1)))
    assert MeshText(uv, tri, (("a b", 0, 1), ("c", 1, 2))).faces.decode().splitlines()[::2] == ["o a_b", "o c"]
