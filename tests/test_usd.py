"""--export-usd: the stage read back with pxr equals the run; bad paths fail early in one line."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("pxr")
from pxr import Gf, Usd, UsdGeom  # noqa: E402

from clothsim import Simulation  # noqa: E402
from clothsim.cli import main  # noqa: E402
from clothsim.cli.common import run_with_progress  # noqa: E402
from clothsim.mesh import compute_normals  # noqa: E402
from clothsim.recording import FrameRecorder  # noqa: E402

from .conftest import SCENES  # noqa: E402

SMALL = ["--set", "cloth.num_width_points=12", "--set", "cloth.num_height_points=12"]
SECONDS = 0.2  # 18 frames at 90 frames/s: 19 time samples with the start
TILTED = [0.2, 1.0, -0.1]


def sphere_and_plane_scene(tmp_path):
    """scenes/sphere.json with a 12x12 cloth, and a tilted floor below it"""
    data = json.loads((SCENES / "sphere.json").read_text())
    data["cloth"].update(num_width_points=12, num_height_points=12)
    data["plane"] = {"point": [0.0, -0.3, 0.0], "normal": TILTED, "friction": 0.5}
    path = tmp_path / "drape.json"
    path.write_text(json.dumps(data))
    return path


@pytest.fixture(scope="module", params=[".usda", ".usdc"])
def written(request, tmp_path_factory):
    """a 0.2 s run written through FrameRecorder, with the positions collected here"""
    tmp = tmp_path_factory.mktemp("usd")
    sim = Simulation.from_file(sphere_and_plane_scene(tmp))
    out = tmp / f"run{request.param}"
    recorder = FrameRecorder(sim, outputs={"usd": str(out)})
    frames = [sim.positions.copy()]

    def on_frame(s):
        recorder(s)
        frames.append(s.positions.copy())

    run_with_progress(sim, SECONDS, False, on_frame)
    recorder.finish(sim)
    return out, sim, np.stack(frames)


def test_topology_uvs_and_points_at_three_times(written):
    """faces are the model's triangles (once); points at frames 0, middle, last equal the run's"""
    out, sim, positions = written
    stage = Usd.Stage.Open(str(out))
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/World/Cloth"))
    assert mesh and stage.GetDefaultPrim().GetPath() == "/World"
    tris = np.asarray(sim.model.triangles)
    counts = mesh.GetFaceVertexCountsAttr()
    indices = mesh.GetFaceVertexIndicesAttr()
    assert counts.GetNumTimeSamples() == 0 and indices.GetNumTimeSamples() == 0
    assert np.array_equal(np.asarray(counts.Get()), np.full(len(tris), 3))
    assert np.array_equal(np.asarray(indices.Get()).reshape(-1, 3), tris)
    st = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("st")
    assert st.GetInterpolation() == UsdGeom.Tokens.vertex
    assert str(st.GetTypeName()) == "texCoord2f[]"
    np.testing.assert_array_equal(np.asarray(st.Get()), sim.model.uvs)

    frames = len(positions)
    assert frames == 19
    points = mesh.GetPointsAttr()
    assert points.GetTimeSamples() == [float(k) for k in range(frames)]
    for k in (0, frames // 2, frames - 1):
        np.testing.assert_allclose(np.asarray(points.Get(k)), positions[k], rtol=0, atol=1e-6)
        normals = np.asarray(mesh.GetNormalsAttr().Get(k))
        np.testing.assert_allclose(normals, compute_normals(positions[k], tris), rtol=0, atol=1e-6)
        lo, hi = np.asarray(mesh.GetExtentAttr().Get(k))
        np.testing.assert_allclose(lo, positions[k].min(axis=0), atol=1e-6)
        np.testing.assert_allclose(hi, positions[k].max(axis=0), atol=1e-6)
    assert not np.allclose(np.asarray(points.Get(frames - 1)), positions[0], atol=1e-3)  # it moved
    assert mesh.GetNormalsInterpolation() == UsdGeom.Tokens.vertex
    np.testing.assert_allclose(np.asarray(mesh.GetDisplayColorAttr().Get()), [[0.80, 0.22, 0.20]], atol=1e-6)


def test_orientation_matches_the_winding(written):
    """rightHanded: each triangle, counter-clockwise seen from the front, has its
    right-hand normal on the side the vertex normals (and the renderer's front) point to;
    the flat cloth at the start faces +y"""
    out, sim, positions = written
    stage = Usd.Stage.Open(str(out))  # kept: a prim is valid only while its stage lives
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/World/Cloth"))
    assert mesh.GetOrientationAttr().Get() == UsdGeom.Tokens.rightHanded
    assert mesh.GetSubdivisionSchemeAttr().Get() == UsdGeom.Tokens.none
    p = np.asarray(mesh.GetPointsAttr().Get(0), dtype=np.float64)
    n = np.asarray(mesh.GetNormalsAttr().Get(0))
    tri = np.asarray(mesh.GetFaceVertexIndicesAttr().Get()).reshape(-1, 3)
    face = np.cross(p[tri[:, 1]] - p[tri[:, 0]], p[tri[:, 2]] - p[tri[:, 0]])
    assert (np.einsum("ij,ij->i", face, n[tri[:, 0]]) > 0).all()
    assert (n[:, 1] > 0.99).all()


def test_stage_timing_units_and_layer_data(written):
    """plays at the run's frame rate over 0..F-1, metres, y up; scene in customLayerData"""
    out, sim, positions = written
    stage = Usd.Stage.Open(str(out))
    assert stage.GetTimeCodesPerSecond() == 90.0 and stage.GetFramesPerSecond() == 90.0
    assert stage.GetStartTimeCode() == 0.0 and stage.GetEndTimeCode() == len(positions) - 1
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y
    layer = stage.GetRootLayer()
    data = layer.customLayerData
    assert data["clothsim:scene"] == "drape" and "ks=5000" in data["clothsim:description"]
    assert json.loads(data["clothsim:sceneJson"])["cloth"]["num_width_points"] == 12
    assert "drape" in layer.documentation


def test_colliders_as_prims(written):
    """the sphere (radius, translate) and the tilted plane (normal, on its point's plane)"""
    out, sim, positions = written
    stage = Usd.Stage.Open(str(out))
    sphere = UsdGeom.Sphere(stage.GetPrimAtPath("/World/Colliders/Sphere_0"))
    assert sphere and sphere.GetRadiusAttr().Get() == pytest.approx(0.2)
    xf = sphere.ComputeLocalToWorldTransform(0)
    assert np.allclose(xf.ExtractTranslation(), [0.5, 0.2, 0.5])
    assert sphere.GetPrim().GetAttribute("clothsim:friction").Get() == pytest.approx(0.3)

    plane = UsdGeom.Plane(stage.GetPrimAtPath("/World/Colliders/Plane_0"))
    assert plane and plane.GetAxisAttr().Get() == UsdGeom.Tokens.y
    xf = plane.ComputeLocalToWorldTransform(0)
    normal = np.asarray(TILTED) / np.linalg.norm(TILTED)
    assert np.allclose(xf.TransformDir(Gf.Vec3d(0, 1, 0)), normal)
    center = np.asarray(xf.ExtractTranslation())
    assert np.dot(center - [0.0, -0.3, 0.0], normal) == pytest.approx(0.0, abs=1e-9)
    assert plane.GetWidthAttr().Get() == pytest.approx(2.5) == plane.GetLengthAttr().Get()
    assert plane.GetPrim().GetAttribute("clothsim:friction").Get() == pytest.approx(0.5)


def test_passes_usd_validators(written):
    """no error from any validator this usd-core ships (stage metadata, geometry, ...)"""
    validation = pytest.importorskip("pxr.UsdValidation")
    from pxr import UsdPhysics, UsdShade, UsdSkel  # noqa: F401  (registers their validators)

    out, sim, positions = written
    validators = validation.ValidationRegistry().GetOrLoadAllValidators()
    assert validators
    errors = validation.ValidationContext(validators).Validate(Usd.Stage.Open(str(out)))
    assert [e.GetMessage() for e in errors] == []


def test_usd_extension_is_binary_crate(tmp_path, capsys):
    """.usd is written as crate, .usdc too, .usda as text"""
    for ext in (".usd", ".usdc", ".usda"):
        out = tmp_path / f"c{ext}"
        assert main(["simulate", "sphere", "--seconds", "0.1", *SMALL, "--export-usd", str(out)]) == 0
        head = out.read_bytes()[:8]
        assert head == (b"#usda 1." if ext == ".usda" else b"PXR-USDC")
        assert Usd.Stage.Open(str(out)).GetEndTimeCode() == 9  # 0.1 s at 90 frames/s
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.usd", "c.usda", "c.usdc"]


def test_cli_simulate_end_to_end(tmp_path):
    """`clothsim simulate SCENE --seconds 0.2 --export-usd out.usda` in a subprocess"""
    out = tmp_path / "out.usda"
    r = subprocess.run(["clothsim", "simulate", str(SCENES / "sphere.json"), "--seconds", str(SECONDS),
                        *SMALL, "--no-progress", "--export-usd", str(out)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    stage = Usd.Stage.Open(str(out))
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/World/Cloth"))
    assert stage.GetEndTimeCode() == 18 and len(mesh.GetPointsAttr().Get(18)) == 144
    sim = Simulation.from_file(SCENES / "sphere.json", SMALL[1::2])
    for _ in range(18):
        sim.step()
    np.testing.assert_allclose(np.asarray(mesh.GetPointsAttr().Get(18)), sim.positions, atol=1e-6)
    assert UsdGeom.Sphere(stage.GetPrimAtPath("/World/Colliders/Sphere_0"))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.usda"]


def test_render_exports_usd(tmp_path, capsys):
    """render takes --export-usd too"""
    out = tmp_path / "r.usdc"
    assert main(["render", "sphere", "-o", str(tmp_path / "x.png"), "--seconds", "0.1", "--size", "32x32",
                 *SMALL, "--export-usd", str(out)]) == 0
    assert Usd.Stage.Open(str(out)).GetEndTimeCode() == 9


def test_help_lists_export_usd(capsys):
    for command in ("simulate", "render"):
        with pytest.raises(SystemExit):
            main([command, "--help"])
        assert "--export-usd" in capsys.readouterr().out


# ---------------------------------------------------------------------------
# bad input: one line, exit 2, before the simulation is built; nothing left behind


@pytest.fixture
def no_simulation(monkeypatch):
    """a Simulation that cannot be built: the checks must come first"""
    def refuse(*args, **kwargs):
        raise AssertionError("the simulation was built before the output was checked")

    monkeypatch.setattr("clothsim.simulation.Simulation.__init__", refuse)


def one_line_exit_2(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("clothsim: error: "), err
    return lines[0]


@pytest.mark.parametrize("command", ["simulate", "render"])
@pytest.mark.parametrize("name,expect", [
    ("out.obj", "unknown USD extension '.obj'"),
    ("out", "unknown USD extension '(none)'"),
    ("out.usdz", "unknown USD extension '.usdz'"),
    ("missing/out.usda", "does not exist"),
    ("afile/out.usda", "is not a folder"),
])
def test_bad_path_one_line(tmp_path, capsys, no_simulation, command, name, expect):
    (tmp_path / "afile").write_text("a file, not a folder")
    argv = [command, "sphere", "--seconds", "0.1", "--export-usd", tmp_path / name]
    if command == "render":
        argv[2:2] = ["-o", tmp_path / "x.png"]
    line = one_line_exit_2(argv, capsys)
    assert expect in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]


def test_existing_file_untouched_without_overwrite(tmp_path, capsys, no_simulation):
    out = tmp_path / "keep.usdc"
    out.write_bytes(b"precious")
    line = one_line_exit_2(["simulate", "sphere", "--export-usd", out], capsys)
    assert "already exists; pass --overwrite" in line
    assert out.read_bytes() == b"precious"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.usdc"]


def test_overwrite_replaces(tmp_path, capsys):
    out = tmp_path / "again.usda"
    out.write_text("old")
    assert main(["simulate", "sphere", "--seconds", "0.05", *SMALL, "--export-usd", str(out),
                 "--overwrite"]) == 0
    assert out.read_text().startswith("#usda 1.0")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["again.usda"]


def test_failed_write_leaves_nothing(tmp_path, monkeypatch):
    """a writer that fails half-way leaves neither the file nor its temporary"""
    import clothsim.export.usd as usd

    def broken(*args):
        raise RuntimeError("disk on fire")

    monkeypatch.setattr(usd, "_define_colliders", broken)
    sim = Simulation.from_file(SCENES / "sphere.json", SMALL[1::2])
    recorder = FrameRecorder(sim, outputs={"usd": str(tmp_path / "x.usdc")})
    sim.step()
    recorder(sim)
    with pytest.raises(RuntimeError, match="disk on fire"):
        recorder.finish(sim)
    assert list(tmp_path.iterdir()) == []


def _readonly_runner(folder):
    """how to run a command that sees ``folder`` read-only: directly after chmod
    when that holds (not root), else inside a mount namespace with a read-only
    bind mount (root in a container); None when neither works here"""
    folder.chmod(0o555)
    if not os.access(folder, os.W_OK):
        return []
    unshare = shutil.which("unshare")
    if unshare is None:
        return None
    script = 'mount --bind "$1" "$1" && mount -o remount,bind,ro "$1" && shift && exec "$@"'
    prefix = [unshare, "-m", "sh", "-c", script, "sh", str(folder)]
    probe = subprocess.run(prefix + ["sh", "-c", f'! touch "{folder}/probe" 2>/dev/null'],
                           capture_output=True)
    (folder / "probe").unlink(missing_ok=True)
    return prefix if probe.returncode == 0 else None


def test_read_only_folder_one_line(tmp_path):
    folder = tmp_path / "ro"
    folder.mkdir()
    prefix = _readonly_runner(folder)
    if prefix is None:
        folder.chmod(0o755)
        pytest.skip("no way to make a read-only folder here (root without mount namespaces)")
    try:
        r = subprocess.run(prefix + [sys.executable, "-m", "clothsim", "simulate", "sphere",
                                     "--export-usd", str(folder / "out.usda")],
                           capture_output=True, text=True)
    finally:
        folder.chmod(0o755)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    assert lines[0].startswith("clothsim: error: ") and "cannot write in" in lines[0]
    assert "compiling" not in r.stderr
    assert list(folder.iterdir()) == []


# ---------------------------------------------------------------------------
# several cloths, a mesh cloth


@pytest.fixture(scope="module")
def two_meshes(tmp_path_factory):
    """a hand-made disc (no grid) and a grid cloth, fed frame by frame to
    FrameRecorder's USD export (positions moved by hand: a wave of 6 frames)"""
    from .handmade import disc_and_grid, simulation_of

    out = tmp_path_factory.mktemp("usd2") / "two.usda"
    sim = simulation_of(disc_and_grid(), sphere={"origin": [2.0, 0.0, 0.5], "radius": 0.3, "friction": 0.2})
    recorder = FrameRecorder(sim, outputs={"usd": str(out)})
    rest = sim.positions.copy()
    frames = [rest.copy()]
    for k in range(1, 6):
        sim.state.positions[:] = rest + 0.05 * np.sin(rest[:, :1] * 3 + k)[:, [0, 0, 0]] * [0.0, 1.0, 0.2]
        sim.state.frame, sim.state.time, sim._normals = k, k / 90, None
        recorder(sim)
        frames.append(sim.positions.copy())
    recorder.finish(sim)
    return out, sim, np.stack(frames)


def test_one_mesh_prim_per_cloth_animated(two_meshes):
    """/World/Cloths/disc and /World/Cloths/grid (no /World/Cloth): each its own
    faces in its own indices, its uvs, and its points and normals at every frame"""
    out, sim, positions = two_meshes
    stage = Usd.Stage.Open(str(out))
    assert not stage.GetPrimAtPath("/World/Cloth")
    assert [p.GetName() for p in stage.GetPrimAtPath("/World/Cloths").GetChildren()] == ["disc", "grid"]
    for cloth in sim.cloths:
        mesh = UsdGeom.Mesh(stage.GetPrimAtPath(f"/World/Cloths/{cloth.name}"))
        assert mesh
        prim = mesh.GetPrim()
        assert prim.GetAttribute("clothsim:name").Get() == cloth.name
        assert prim.GetAttribute("clothsim:firstPoint").Get() == cloth.model.start
        np.testing.assert_array_equal(np.asarray(mesh.GetFaceVertexIndicesAttr().Get()).reshape(-1, 3),
                                      cloth.triangles)
        assert set(np.asarray(mesh.GetFaceVertexCountsAttr().Get()).tolist()) == {3}
        st = np.asarray(UsdGeom.PrimvarsAPI(mesh).GetPrimvar("st").Get())
        np.testing.assert_array_equal(st, sim.model.uvs[cloth.model.points])
        points, normals = mesh.GetPointsAttr(), mesh.GetNormalsAttr()
        assert points.GetTimeSamples() == [float(k) for k in range(len(positions))]
        for k in range(len(positions)):
            mine = positions[k][cloth.model.points]
            np.testing.assert_allclose(np.asarray(points.Get(k)), mine, rtol=0, atol=1e-6)
            expected = compute_normals(positions[k], sim.model.triangles)[cloth.model.points]
            np.testing.assert_allclose(np.asarray(normals.Get(k)), expected, atol=1e-6)
            lo, hi = np.asarray(mesh.GetExtentAttr().Get(k))
            np.testing.assert_allclose(lo, mine.min(axis=0), atol=1e-6)
            np.testing.assert_allclose(hi, mine.max(axis=0), atol=1e-6)
    assert UsdGeom.Sphere(stage.GetPrimAtPath("/World/Colliders/Sphere_0"))


def test_several_cloths_pass_usd_validators(two_meshes):
    validation = pytest.importorskip("pxr.UsdValidation")
    from pxr import UsdPhysics, UsdShade, UsdSkel  # noqa: F401  (registers their validators)

    out, _, _ = two_meshes
    validators = validation.ValidationRegistry().GetOrLoadAllValidators()
    errors = validation.ValidationContext(validators).Validate(Usd.Stage.Open(str(out)))
    assert [e.GetMessage() for e in errors] == []


def test_cloth_prim_names_are_valid_and_unique():
    from clothsim.export.usd import cloth_prim_paths

    assert cloth_prim_paths(["cloth"]) == ["/World/Cloth"]
    assert cloth_prim_paths(["cloth_0", "my flag", "my flag", "3d"]) == [
        "/World/Cloths/cloth_0", "/World/Cloths/my_flag", "/World/Cloths/my_flag_1", "/World/Cloths/_d"]
