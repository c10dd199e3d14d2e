"""Mesh loading: every format meshio writes, and a clear ValueError for each bad mesh."""
from __future__ import annotations

import meshio
import numpy as np
import pytest

from soft_envs.sim import TetMesh, load_mesh
from soft_envs.sim.mesh import boundary_faces

from .conftest import block_mesh


@pytest.mark.parametrize("suffix", [".vtu", ".vtk", ".msh", ".mesh"])
def test_round_trip_through_meshio_formats(tmp_path, suffix):
    m = block_mesh()
    path = tmp_path / f"bar{suffix}"
    meshio.write(path, m)
    tm = load_mesh(path)
    assert tm.n_tets == len(m.cells[0].data)
    assert np.allclose(tm.points, m.points)
    assert np.isclose(tm.volumes.sum(), 0.06 * 0.02 * 0.02)


def test_geometry_masses_and_boundary():
    tm = load_mesh(block_mesh(2, 2, 2, (0.02, 0.02, 0.02)))
    assert (tm.volumes > 0).all()
    assert np.isclose(tm.lumped_masses(100.0).sum(), 100.0 * 0.02**3)
    # a 2x2x2 grid of cubes has 27 nodes, only the centre one is interior
    assert len(tm.boundary_nodes) == 26 and 13 not in tm.boundary_nodes
    # outward normals: the divergence theorem gives the volume
    p = tm.points[tm.surface]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]) / 2
    assert np.isclose((n * p.mean(axis=1)).sum() / 3, 0.02**3)
    e, w = tm.locate(np.array([0.005, 0.007, 0.011]))
    assert np.allclose(w @ tm.points[tm.tets[e]], [0.005, 0.007, 0.011]) and (w >= -1e-12).all()
    assert tm.locate(np.array([1.0, 0, 0])) is None


def test_boundary_of_single_tet_is_outward():
    tets = np.array([[0, 1, 2, 3]])
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    f = boundary_faces(tets)
    assert len(f) == 4
    c = pts.mean(0)
    for tri in f:
        a, b, d = pts[tri]
        assert np.dot(np.cross(b - a, d - a), a - c) > 0


def write(tmp_path, points, tets, name="bad.vtu", cells=None):
    path = tmp_path / name
    meshio.write(path, meshio.Mesh(np.asarray(points, float), cells or [("tetra", np.asarray(tets))]))
    return path


GOOD_P = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]


def test_no_tetra_cells(tmp_path):
    path = write(tmp_path, GOOD_P, None, cells=[("triangle", np.array([[0, 1, 2]]))])
    with pytest.raises(ValueError, match=r"bad\.vtu.*no linear 'tetra' cells.*triangle"):
        load_mesh(path)


def test_inverted_element_is_not_flipped(tmp_path):
    path = write(tmp_path, GOOD_P, [[0, 2, 1, 3]])
    with pytest.raises(ValueError, match=r"bad\.vtu.*inverted elements"):
        load_mesh(path)


def test_degenerate_element(tmp_path):
    with pytest.raises(ValueError, match=r"bad\.vtu.*degenerate"):
        load_mesh(write(tmp_path, [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], [[0, 1, 2, 3]]))
    with pytest.raises(ValueError, match=r"repeated nodes"):
        load_mesh(write(tmp_path, GOOD_P, [[0, 1, 1, 3]]))


def test_unreferenced_nodes(tmp_path):
    with pytest.raises(ValueError, match=r"bad\.vtu.*1 unreferenced nodes.*\[4\]"):
        load_mesh(write(tmp_path, GOOD_P + [[5, 5, 5]], [[0, 1, 2, 3]]))


def test_nan_coordinates():
    with pytest.raises(ValueError, match=r"non-finite.*\[2\]"):
        TetMesh(np.array([[0, 0, 0], [1, 0, 0], [np.nan, 1, 0], [0, 0, 1]]), np.array([[0, 1, 2, 3]]),
                source="nan.vtu")


def test_missing_and_unreadable_files(tmp_path):
    with pytest.raises(ValueError, match="not found"):
        load_mesh(tmp_path / "nope.vtu")
    junk = tmp_path / "junk.vtu"
    junk.write_text("not a mesh")
    with pytest.raises(ValueError, match=r"junk\.vtu.*could not read"):
        load_mesh(junk)
