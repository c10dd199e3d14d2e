"""Surface -> tet mesh (soft_envs.meshing) and the robot.toml skeleton (soft_envs.skeleton)."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import meshio
import numpy as np
import pytest

from soft_envs.meshing import (Surface, SurfaceError, check_surface, frame_rotation, mesh_surface,
                               read_surface, tet_quality, to_robot_frame)
from soft_envs.sim import TetMesh, load_robot

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "data"
QUADRUPED = EXAMPLES / "quadruped.obj"

# a box's corners (bit i of the index selects the upper coordinate along axis i) and its 12
# outward triangles
_BOX_TRIS = np.array([[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
                      [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]])


def box(size=(40.0, 20.0, 30.0), origin=(0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    corners = np.array([[(i >> k) & 1 for k in range(3)] for i in range(8)], dtype=float)
    return np.asarray(origin) + corners * np.asarray(size), _BOX_TRIS.copy()


def write_surface(path: Path, points, tris) -> Path:
    meshio.write(path, meshio.Mesh(points, [("triangle", tris)]))
    return path


def test_box_is_outward_and_closed():
    p, t = box()
    s, warnings = check_surface(Surface(p, t, "box"))
    assert warnings == [] and np.isclose(s.volume, 40 * 20 * 30)


def test_quality_figures_of_known_tets():
    regular = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1.0]])
    q = tet_quality(regular, np.array([[0, 1, 2, 3]]))
    assert np.isclose(q.min_dihedral_deg, np.degrees(np.arccos(1 / 3))) and np.isclose(q.min_radius_ratio, 1.0)
    corner = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    q = tet_quality(corner, np.array([[0, 1, 2, 3]]))
    assert np.isclose(q.max_dihedral_deg, 90.0)
    assert np.isclose(q.min_dihedral_deg, np.degrees(np.arccos(1 / np.sqrt(3))))
    r_in = 3 * (1 / 6) / (1.5 + np.sqrt(3) / 2)            # 3 V / area
    assert np.isclose(q.min_radius_ratio, 3 * r_in / (np.sqrt(3) / 2))
    flat = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.3, 0.3, 1e-9]])
    q = tet_quality(flat, np.array([[0, 1, 2, 3]]))
    assert q.min_radius_ratio < 1e-6 and q.min_dihedral_deg < 1e-3 and q.warnings()


def test_frame_rotation_and_robot_frame():
    assert np.allclose(frame_rotation("+x", "+y"), np.eye(3))
    R = frame_rotation("-y", "+z")
    assert np.isclose(np.linalg.det(R), 1.0)
    p, t = box(size=(40.0, 20.0, 30.0))
    s = to_robot_frame(Surface(p, t), scale=1e-3, forward="-y", up="+z")
    assert np.allclose(np.ptp(s.points, axis=0), [0.020, 0.030, 0.040])    # x <- Y, y <- Z, z <- X
    assert np.isclose(s.points[:, 1].min(), 0) and np.isclose(s.points[:, 0].min(), 0)
    assert np.isclose(s.points[:, 2].min(), -s.points[:, 2].max())
    # the surface point with the smallest Y is the front (largest x) when forward is -y
    assert np.isclose(s.points[np.argmin(p[:, 1]), 0], 0.020)
    assert np.isclose(s.volume, 40 * 20 * 30 * 1e-9)                        # orientation kept
    with pytest.raises(ValueError, match="different axes"):
        frame_rotation("+z", "-z")
    with pytest.raises(ValueError, match="forward must be one of"):
        frame_rotation("x", "+y")


def test_mesh_box_in_the_robot_frame(tmp_path):
    pytest.importorskip("gmsh")
    path = write_surface(tmp_path / "box.stl", *box())
    r = mesh_surface(path, scale=1e-3, forward="+x", up="+z", edge_length=0.01)
    assert r.warnings == []
    assert np.allclose(r.points.min(axis=0), [0, 0, -0.010]) and np.allclose(r.points.max(axis=0), [0.04, 0.03, 0.01])
    mesh = TetMesh(r.points, r.tets)                      # the simulator's own validation
    assert (mesh.volumes > 0).all() and np.isclose(mesh.volumes.sum(), 24e-6, rtol=1e-9)
    q = r.quality
    assert q == tet_quality(r.points, r.tets) and q.n_tets == len(r.tets) > 24
    assert 5 < q.min_dihedral_deg < 70.6 and q.max_dihedral_deg < 175
    assert 0.1 < q.min_radius_ratio <= q.median_radius_ratio <= 1
    edges = np.linalg.norm(r.points[r.tets[:, 1]] - r.points[r.tets[:, 0]], axis=1)
    assert 0.004 < np.median(edges) < 0.013              # the target edge length is followed


SIGPIPE_AFTER_MESHING = """
import signal, sys
from pathlib import Path
sys.path.insert(0, sys.argv[2])
from test_meshing import box, write_surface
from soft_envs.meshing import mesh_surface
mesh_surface(write_surface(Path(sys.argv[1]) / "box.stl", *box()), scale=1e-3, edge_length=0.01)
line = next(ln for ln in Path("/proc/self/status").read_text().splitlines() if ln.startswith("SigIgn:"))
print(bool(int(line.split()[1], 16) >> (signal.SIGPIPE - 1) & 1), signal.getsignal(signal.SIGPIPE) == signal.SIG_IGN)
"""


@pytest.mark.skipif(not Path("/proc/self/status").is_file(), reason="reads the signal masks from /proc")
def test_meshing_leaves_sigpipe_ignored(tmp_path):
    """gmsh's first initialize() in a process sets SIGPIPE to its default action in C; meshing
    puts Python's disposition (ignored) back, as the kernel sees it: a later write to a closed
    pipe raises BrokenPipeError instead of ending the process (checked in a fresh process)."""
    pytest.importorskip("gmsh")
    proc = subprocess.run([sys.executable, "-c", SIGPIPE_AFTER_MESHING, str(tmp_path), str(Path(__file__).parent)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split() == ["True", "True"], proc.stdout + proc.stderr


def test_inward_surface_is_flipped_with_a_warning(tmp_path):
    pytest.importorskip("gmsh")
    p, t = box()
    path = write_surface(tmp_path / "inward.obj", p, t[:, ::-1])
    r = mesh_surface(path, scale=1e-3, edge_length=0.02)
    assert any("inward" in w and "inward.obj" in w for w in r.warnings)
    assert r.surface.volume > 0 and (TetMesh(r.points, r.tets).volumes > 0).all()


def _bad(name):
    p, t = box()
    if name == "open":
        return p, t[1:], "not closed: 3 boundary edges"
    if name == "two bodies":
        q, s = box(origin=(100.0, 0, 0))
        return np.vstack([p, q]), np.vstack([t, s + 8]), "2 separate bodies"
    if name == "inconsistent":
        t[3] = t[3, ::-1]
        return p, t, "not consistently oriented"
    if name == "degenerate":
        p = np.vstack([p, 0.5 * (p[0] + p[1])])            # a zero-area sliver in the bottom face
        return p, np.vstack([t, [[0, 1, 8], [0, 8, 1]]]), "degenerate"
    if name == "duplicated":
        return p, np.vstack([t, t[:1]]), "non-manifold"
    raise AssertionError(name)


@pytest.mark.parametrize("name", ["open", "two bodies", "inconsistent", "degenerate", "duplicated"])
def test_bad_surfaces_are_refused_by_name(tmp_path, name):
    p, t, message = _bad(name)
    path = write_surface(tmp_path / "bad.ply", p, t)
    with pytest.raises(SurfaceError, match=message) as info:
        check_surface(read_surface(path))
    assert str(path) in str(info.value)


def icosphere(subdivisions: int) -> tuple[np.ndarray, np.ndarray]:
    """A unit sphere: an icosahedron, each triangle split in four ``subdivisions`` times."""
    t = (1 + 5**0.5) / 2
    p = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t], [0, 1, -t],
         [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]]
    f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2],
         [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11],
         [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    p = [np.array(q) / np.linalg.norm(q) for q in p]
    for _ in range(subdivisions):
        mids: dict = {}

        def mid(a, b):
            if (min(a, b), max(a, b)) not in mids:
                m = p[a] + p[b]
                p.append(m / np.linalg.norm(m))
                mids[min(a, b), max(a, b)] = len(p) - 1
            return mids[min(a, b), max(a, b)]
        f = [q for a, b, c in f for q in ([a, mid(a, b), mid(c, a)], [b, mid(b, c), mid(a, b)],
                                          [c, mid(c, a), mid(b, c)], [mid(a, b), mid(b, c), mid(c, a)])]
    return np.array(p), np.array(f)


def test_a_fine_surface_is_coarsened_to_the_edge_length(tmp_path):
    pytest.importorskip("gmsh")
    p, t = icosphere(3)                                     # 642 vertices, 1280 triangles
    path = write_surface(tmp_path / "ball.stl", 50.0 * p, t)
    r = mesh_surface(path, scale=1e-3, edge_length=0.02)
    assert len(r.points) < 200 and (TetMesh(r.points, r.tets).volumes > 0).all()
    assert r.quality.min_dihedral_deg > 10
    keep = mesh_surface(path, scale=1e-3, edge_length=0.02, remesh=False)
    assert len(keep.points) >= 642 and np.isclose(keep.volume, keep.surface.volume)


def test_a_self_intersecting_surface_is_refused(tmp_path):
    pytest.importorskip("gmsh")
    p, t = box()
    p[7] = [-20, -10, -10]                                  # a corner pushed through the opposite faces
    path = write_surface(tmp_path / "knot.obj", p, t)
    with pytest.raises(SurfaceError, match=r"knot.obj: gmsh could not mesh the volume.*self-intersections"):
        mesh_surface(path, scale=1e-3, edge_length=0.01)


def test_unreadable_inputs(tmp_path):
    with pytest.raises(SurfaceError, match="not found"):
        read_surface(tmp_path / "missing.stl")
    tet = tmp_path / "solid.vtu"
    meshio.write(tet, meshio.Mesh(np.eye(4)[:, :3], [("tetra", np.array([[0, 1, 2, 3]]))]))
    with pytest.raises(SurfaceError, match="volume mesh already"):
        read_surface(tet)


def test_missing_gmsh_says_what_to_install(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "gmsh", None)
    path = write_surface(tmp_path / "box.stl", *box())
    with pytest.raises(ImportError, match=r"soft-envs\[mesh\]"):
        mesh_surface(path, scale=1e-3)


def test_shipped_quadruped_surface_is_what_its_script_makes(tmp_path):
    sys.path.insert(0, str(EXAMPLES))
    try:
        import make_quadruped
    finally:
        sys.path.remove(str(EXAMPLES))
    make_quadruped.write_obj(tmp_path / "q.obj", *make_quadruped.surface())
    assert (tmp_path / "q.obj").read_text() == QUADRUPED.read_text()
    assert QUADRUPED.stat().st_size < 16_000


def test_quadruped_to_robot_with_leg_tendons(tmp_path):
    pytest.importorskip("gmsh")
    from soft_envs.skeleton import find_legs, make_robot

    r, vtu, toml = make_robot(QUADRUPED, tmp_path / "out", scale=1e-3, up="+z", tendons="legs")
    assert np.allclose(np.ptp(r.points, axis=0), [0.13, 0.07, 0.08])
    legs = find_legs(r.points, r.tets)
    assert [g.name for g in legs] == ["fore_left", "fore_right", "hind_left", "hind_right"]
    assert all(g.centre[1] < 0 for g in legs if "left" in g.name)          # left is -z
    robot = load_robot(toml)                                                 # loads as written
    assert robot.n_motors == 8 and len(robot.tendons) == 16
    assert robot.motors[robot.motor_names.index("fore_left_front")].mirror == "fore_right_front"
    assert np.array_equal(robot.mirror_map[robot.mirror_map], np.arange(8))
    for t in robot.tendons:                                                  # vertical, foot to body
        assert np.ptp(t.points[:, 0]) < 1e-9 and t.points[0, 1] < 0.01 and t.points[-1, 1] > 0.045
    assert np.isclose(robot.body_mass, 220.0 * robot.mesh.volumes.sum())
    assert np.isclose(robot.payload_mass, 1.5 * robot.body_mass, rtol=1e-3) and len(robot.payload_nodes) >= 4
    assert (robot.mesh.points[robot.payload_nodes, 1] > 0.0699).all()
    with pytest.raises(ValueError, match="exists already"):
        make_robot(QUADRUPED, tmp_path / "out", scale=1e-3, up="+z")
    r2, _, _ = make_robot(QUADRUPED, tmp_path / "out", scale=1e-3, up="+z", overwrite=True)
    assert len(load_robot(toml).tendons) == 2                                 # the one worked example


def test_element_estimate_is_volume_over_the_regular_tet():
    """``6 sqrt(2) V / a^3`` (+ 2 per kept surface triangle), pinned on a unit cube."""
    from soft_envs.meshing import estimate_elements
    cube = Surface(*box(size=(1.0, 1.0, 1.0)))
    assert estimate_elements(cube, 0.5) == round(6 * np.sqrt(2) / 0.125) == 68
    assert estimate_elements(cube, 0.1) == round(6 * np.sqrt(2) * 1000)
    assert estimate_elements(cube, 0.5, remesh=False) == round(6 * np.sqrt(2) / 0.125 + 24)
    with pytest.raises(ValueError, match="edge_length"):
        estimate_elements(cube, 0.0)


def test_element_estimate_is_near_what_gmsh_makes(tmp_path):
    pytest.importorskip("gmsh")
    from soft_envs.meshing import estimate_elements
    r = mesh_surface(QUADRUPED, scale=1e-3, up="+z", edge_length=0.01)
    assert 0.5 < len(r.tets) / estimate_elements(r.surface, 0.01) < 2.0


def _no_gmsh(monkeypatch):
    import soft_envs.meshing as meshing

    def refuse(*_):
        raise AssertionError("gmsh was started")
    monkeypatch.setattr(meshing, "_gmsh", refuse)


def test_a_runaway_edge_length_is_refused_before_gmsh_starts(tmp_path, monkeypatch, capsys):
    """``trajopt mesh --edge-length 0.0005`` (issue #26 item 7: ran for hours with no output) is
    refused from the estimate, exit 2 and one line naming the cap and what to pass; nothing written."""
    from trajopt.cli import main
    _no_gmsh(monkeypatch)
    out = tmp_path / "robot"
    code = main(["mesh", str(QUADRUPED), "--scale", "0.001", "--up", "+z", "--edge-length", "0.0005",
                 "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    n = round(6 * np.sqrt(2) * 390_080e-9 / 0.0005**3)     # the quadruped encloses 390,080 mm^3
    assert "edge length 0.0005 m" in err[0] and f"about {n:.3g} tets" in err[0], err
    assert "cap of 200000" in err[0] and "--max-elements" in err[0] and "--edge-length 0.0" in err[0]
    assert not out.exists()
    with pytest.raises(SurfaceError, match="cap of 1000;"):
        mesh_surface(QUADRUPED, scale=1e-3, up="+z", edge_length=0.01, max_elements=1000)


def test_max_elements_moves_the_cap_and_the_estimate_is_printed_first(tmp_path, capsys):
    pytest.importorskip("gmsh")
    from soft_envs.meshing import MAX_ELEMENTS
    from trajopt.cli import build_parser, main
    argv = ["mesh", str(QUADRUPED), "--scale", "0.001", "--up", "+z", "--edge-length", "0.02",
            "--out", str(tmp_path / "robot")]
    assert main([*argv, "--max-elements", "100"]) == 2                  # about 414 tets expected
    assert "more than the cap of 100;" in capsys.readouterr().err
    assert main([*argv, "--max-elements", "1000"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "meshing at edge length 0.02 m: about 414 tets expected" and out[1].startswith("meshed ")
    mesh_help = build_parser()._subparsers._group_actions[0].choices["mesh"].format_help()
    assert f"default {MAX_ELEMENTS}" in mesh_help.replace("\n", " ").replace("  ", " ")
