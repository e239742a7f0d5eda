"""The cloth model: grid geometry, spring topology, mesh and normals."""

from __future__ import annotations

import numpy as np
import pytest

from clothsim.mesh import compute_normals
from clothsim.model import BENDING, SHEARING, STRUCTURAL, build_model
from clothsim.scene import parse_scene

from .conftest import small_scene


def model_for(**cloth):
    return build_model(parse_scene(small_scene(cloth=cloth)).cloth)


@pytest.mark.parametrize("nw,nh", [(2, 2), (3, 5), (16, 16), (50, 40)])
def test_spring_counts(nw, nh):
    """a grid has (nw-1)nh+nw(nh-1) structural, 2(nw-1)(nh-1) shearing, (nw-2)nh+nw(nh-2) bending springs"""
    m = model_for(num_width_points=nw, num_height_points=nh, pinned=[])
    counts = np.bincount(m.spring_kind, minlength=3)
    assert counts[STRUCTURAL] == (nw - 1) * nh + nw * (nh - 1)
    assert counts[SHEARING] == 2 * (nw - 1) * (nh - 1)
    assert counts[BENDING] == max(nw - 2, 0) * nh + nw * max(nh - 2, 0)
    assert list(m.kind_start) == [0, counts[0], counts[0] + counts[1], counts.sum()]


def test_rest_lengths_match_grid_spacing():
    """structural springs rest at the grid spacing, shearing at the diagonal, bending at twice it"""
    m = model_for(width=2.0, height=2.0)
    d = 2.0 / 15
    for kind, length in ((STRUCTURAL, d), (SHEARING, d * np.sqrt(2)), (BENDING, 2 * d)):
        np.testing.assert_allclose(m.spring_rest[m.spring_kind == kind], length, rtol=1e-12)


def test_horizontal_and_vertical_geometry():
    """horizontal cloth lies at y=1 spanning x,z; vertical cloth spans x,y with |z| <= 0.001"""
    h = model_for(width=2.0, height=3.0)
    assert np.all(h.rest_positions[:, 1] == 1.0)
    assert h.rest_positions[:, 0].max() == pytest.approx(2.0) and h.rest_positions[:, 2].max() == pytest.approx(3.0)
    np.testing.assert_allclose(h.rest_positions[h.index(3, 7)], [3 * 2.0 / 15, 1.0, 7 * 3.0 / 15])
    v = model_for(orientation=1)
    assert v.rest_positions[:, 1].max() == pytest.approx(1.0)
    assert np.abs(v.rest_positions[:, 2]).max() <= 0.001
    assert np.abs(v.rest_positions[:, 2]).max() > 0  # the jitter is there


def test_vertical_jitter_is_seeded():
    """the same seed gives the same start; another seed another"""
    spec = parse_scene(small_scene(cloth={"orientation": 1})).cloth
    a, b, c = build_model(spec, 1), build_model(spec, 1), build_model(spec, 2)
    assert np.array_equal(a.rest_positions, b.rest_positions)
    assert not np.array_equal(a.rest_positions, c.rest_positions)


def test_pinned_mask():
    """pinned (i, j) marks row-major index j*nw + i"""
    m = model_for(pinned=[[0, 0], [15, 0], [3, 7]])
    assert set(np.flatnonzero(m.pinned)) == {0, 15, 7 * 16 + 3}


def test_mesh_topology_and_uvs():
    """two triangles per cell covering every vertex; uvs span [0,1]^2 in grid order"""
    m = model_for()
    assert m.triangles.shape == (2 * 15 * 15, 3)
    assert set(np.unique(m.triangles)) == set(range(256))
    assert m.uvs.min() == 0.0 and m.uvs.max() == 1.0
    np.testing.assert_allclose(m.uvs[m.index(15, 0)], [1.0, 0.0])
    np.testing.assert_allclose(m.uvs[m.index(0, 15)], [0.0, 1.0])


def test_flat_cloth_normals_point_up():
    """a flat horizontal cloth has unit normals along +y"""
    m = model_for()
    n = compute_normals(m.rest_positions, m.triangles)
    np.testing.assert_allclose(n, np.tile([0.0, 1.0, 0.0], (m.num_points, 1)), atol=1e-12)


def test_normals_are_area_weighted():
    """a vertex shared by a big and a small face leans toward the big face's normal"""
    pos = np.array([[0, 0, 0], [1, 0, 0], [0, 0, -1], [0, 0.1, 0.1]], dtype=float)
    tris = np.array([[0, 1, 2], [0, 3, 1]], dtype=np.int32)  # big face normal +y, small face tilted
    n = compute_normals(pos, tris)
    big = np.cross(pos[1] - pos[0], pos[2] - pos[0])
    small = np.cross(pos[3] - pos[0], pos[1] - pos[0])
    expected = (big + small) / np.linalg.norm(big + small)
    np.testing.assert_allclose(n[0], expected, atol=1e-12)
