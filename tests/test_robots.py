"""The shipped Tripod and Puppy (paper IV) and the robot.toml format."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from soft_envs.sim import load_robot
from soft_envs.sim.robot_file import asset_path

PAPER = {"tripod": dict(length=0.14, body=0.024, payload=0.044, motors=2),
         "puppy": dict(length=0.13, body=0.090, payload=0.140, motors=8)}


@pytest.mark.parametrize("name", ["tripod", "puppy"])
def test_mass_and_size_match_the_paper(name):
    robot = load_robot(name)
    ref = PAPER[name]
    assert abs(robot.total_mass - ref["body"] - ref["payload"]) < 0.01 * (ref["body"] + ref["payload"])
    assert abs(np.ptp(robot.mesh.points[:, 0]) - ref["length"]) < 0.05 * ref["length"]
    assert abs(robot.body_length - ref["length"]) < 0.05 * ref["length"]
    assert robot.n_motors == ref["motors"] and robot.mesh.n_nodes <= 300
    top = robot.mesh.points[:, 1].max()
    assert np.all(robot.mesh.points[robot.payload_nodes, 1] > top - 1e-6)
    assert robot.u_bounds.shape == (ref["motors"], 2)
    np.testing.assert_array_equal(robot.mirror_map[robot.mirror_map], np.arange(robot.n_motors))


def test_puppy_tendon_pairs_and_mirrors():
    robot = load_robot("puppy")
    for m in robot.motors:
        assert len(m.tendons) == 2                          # each motor a tendon pair
        a, b = (robot.tendons[robot.tendon_names.index(t)].points for t in m.tendons)
        assert np.allclose(a[:, :2], b[:, :2])              # parallel, in the sagittal plane
        mirror = robot.motors[robot.motor_names.index(m.mirror)]
        assert mirror.mirror == m.name and ("left" in m.name) != ("left" in mirror.name)


@pytest.mark.parametrize("name", ["tripod", "puppy"])
def test_stands_still_for_five_seconds(name, request):
    robot, sim, x0 = request.getfixturevalue(name)
    traj = sim.rollout(np.zeros((152, robot.n_motors)), x0=x0)     # 5 s at h = 0.033 s
    drift = np.linalg.norm(traj.com - traj.com[0], axis=1).max()
    assert drift < 2e-3
    assert x0[robot.payload_nodes, 1].min() > 0.5 * robot.mesh.points[:, 1].max()   # upright


def leg_nodes(robot, motor: int):
    """Foot corner under a motor's first eyelet and the leg's hip nodes, in the rest mesh."""
    P = robot.mesh.points
    t = np.flatnonzero(robot.tendon_motor == motor)[0]
    pts = robot.tendons[t].points
    foot = (np.linalg.norm(P - pts[0], axis=1) < 0.012) & (P[:, 1] < 1e-9)
    hip = ((np.abs(P[:, 0] - pts[0][0]) < 0.02) & (np.abs(P[:, 2] - pts[0][2]) < 0.012)
           & (np.abs(P[:, 1] - pts[-1][1]) < 0.013))
    return foot, hip


@pytest.mark.parametrize("name", ["tripod", "puppy"])
def test_each_motor_bends_its_leg_the_expected_way(name, request):
    """A 'front' motor pulls the foot forward (+x) relative to the hip, a 'back' motor backward."""
    robot, sim, x0 = request.getfixturevalue(name)
    for m, mname in enumerate(robot.motor_names):
        u = np.zeros((30, robot.n_motors))
        u[:, m] = np.linspace(0, robot.u_bounds[m, 1], 30)
        x = sim.rollout(u, x0=x0).x[-1]
        foot, hip = leg_nodes(robot, m)
        rel = (x[foot, 0].mean() - x[hip, 0].mean()) - (x0[foot, 0].mean() - x0[hip, 0].mean())
        sign = 1 if mname.endswith("front") else -1
        assert sign * rel > 2e-3, f"{mname}: foot moved {rel * 1e3:.2f} mm relative to the hip"


def test_tripod_cocontraction_lifts_middle_foot(tripod):
    robot, sim, x0 = tripod
    P = robot.mesh.points
    middle = (P[:, 0] > 0.059) & (P[:, 0] < 0.081)
    middle_foot = middle & (P[:, 1] < P[middle, 1].min() + 1e-9)
    outer_foot = ~middle & (P[:, 1] < P[~middle, 1].min() + 1e-9)
    u = np.linspace(0, 1, 30)[:, None] * robot.u_bounds[:, 1]
    x = sim.rollout(u, x0=x0).x[-1]
    assert x0[middle_foot, 1].min() < 0 < x[middle_foot, 1].min() - 1e-3   # off the ground by > 1 mm
    assert x[outer_foot, 1].min() < 0          # the outer feet carry the robot


def test_fine_variants_load():
    for name in ("tripod", "puppy"):
        fine = load_robot(asset_path(name).with_name("robot_fine.toml"))
        coarse = load_robot(name)
        assert fine.mesh.n_nodes > 3 * coarse.mesh.n_nodes
        assert np.isclose(fine.total_mass, coarse.total_mass)


# ---------------------------------------------------------------- bad robot files
def edit(path: Path, old: str, new: str, count: int = 1) -> Path:
    text = path.read_text()
    assert old in text, old
    path.write_text(text.replace(old, new, count))
    return path


@pytest.mark.parametrize("old,new,message", [
    ("youngs_modulus = ", "young = ", r"unknown key \[material\]\.young"),
    ("density = ", "# density = ", r"\[material\]\.density is missing"),
    ("[payload]", "[payloads]", r"unknown table \[payloads\]"),
    ('mesh = "tripod.vtu"', 'mesh = "nope.vtu"', r"\[robot\]\.mesh file .*nope\.vtu.* not found"),
    ('tendons = ["front_a", "front_b"]', 'tendons = ["front_a", "frnt_b"]',
     r"motors\[0\] \('front'\)\.tendons names unknown tendon 'frnt_b'"),
    ("points = [[0.0780, 0.0040", "points = [[0.0780, -0.0200", r"tendons\[0\] \('front_a'\)\.points\[0\].*outside the body"),
    ("u_max = ", 'u_max = "big" # ', r"motors\[0\]\.u_max has the wrong type"),
    ('forward_axis = "+x"', 'forward_axis = "+q"', r"\[robot\]\.forward_axis must be one of"),
    ("poisson_ratio = 0.3", "poisson_ratio = 0.5", r"poisson_ratio must lie in"),
])
def test_bad_robot_files_name_file_and_field(robot_dir, old, new, message):
    path = edit(robot_dir / "robot.toml", old, new)
    with pytest.raises(ValueError, match=message) as err:
        load_robot(path)
    assert str(path) in str(err.value)


def test_mirror_map_must_be_an_involution(robot_dir):
    path = robot_dir / "robot.toml"
    text = path.read_text()
    text = text.replace('name = "front"\n', 'name = "front"\nmirror = "back"\n')
    path.write_text(text)
    with pytest.raises(ValueError, match=r"robot\.toml.*motors\[0\] \('front'\)\.mirror: the mirror map is not an involution"):
        load_robot(path)


def test_invalid_toml_and_unknown_name(tmp_path):
    bad = tmp_path / "robot.toml"
    bad.write_text("[robot\nname=")
    with pytest.raises(ValueError, match=re.escape(str(bad)) + ".*not valid TOML"):
        load_robot(bad)
    with pytest.raises(ValueError, match="unknown robot 'kitten'"):
        load_robot("kitten")


def test_overrides_and_frames(robot_dir):
    """Mesh in millimetres with z up, facing -y: loaded into the simulation frame."""
    import meshio
    m = meshio.read(robot_dir / "tripod.vtu")
    p = m.points * 1000.0
    # sim (x, y, z) -> mesh: forward -y, up +z => mesh = (z_sim?,...) build explicitly
    mesh_pts = np.stack([-p[:, 2], -p[:, 0], p[:, 1]], axis=1)   # mesh x = -z, y = -x, z = y
    meshio.write(robot_dir / "tripod_mm.vtu", meshio.Mesh(mesh_pts, m.cells))
    text = (robot_dir / "robot.toml").read_text()
    text = text.replace('mesh = "tripod.vtu"', 'mesh = "tripod_mm.vtu"\nscale = 0.001')
    text = text.replace('forward_axis = "+x"', 'forward_axis = "-y"').replace('up_axis = "+y"', 'up_axis = "+z"')
    import tomllib
    doc = tomllib.loads(text)
    for t in doc["tendons"]:
        q = np.array(t["points"]) * 1000.0
        new = np.stack([-q[:, 2], -q[:, 0], q[:, 1]], axis=1)
        text = text.replace("points = " + _fmt(t["points"]), "points = " + _fmt(new.tolist()))
    (robot_dir / "robot.toml").write_text(text)
    robot = load_robot(robot_dir / "robot.toml", youngs_modulus=2e5)
    ref = load_robot("tripod")
    assert robot.youngs_modulus == 2e5
    assert np.allclose(robot.mesh.points, ref.mesh.points, atol=1e-12)
    for a, b in zip(robot.tendons, ref.tendons):
        assert np.allclose(a.points, b.points, atol=1e-12)


def _fmt(pts) -> str:
    return "[" + ", ".join("[" + ", ".join(f"{c:.4f}" for c in p) + "]" for p in pts) + "]"


@pytest.mark.parametrize("old,new,message", [
    ("body_length = 0.14", "body_length = -0.14", r"body_length must be positive"),
    ("blend = 2e-4", "blend = -2e-4", r"cables\.blend must be >= 0"),
    ("stiffness = 2000.0", "stiffness = -1.0", r"\[contact\] contact\.stiffness must be positive"),
    ("[cables]", '[fixed]\nbox = [[0, 1]]\n\n[cables]', r"\[fixed\]\.box must be"),
])
def test_more_bad_values_name_file_and_field(robot_dir, old, new, message):
    path = edit(robot_dir / "robot.toml", old, new)
    with pytest.raises(ValueError, match=message) as err:
        load_robot(path)
    assert str(path) in str(err.value)


def test_robot_keeps_its_own_tendon_points(bar_robot):
    pts = np.array([[0.055, 0.015, 0.01], [0.005, 0.015, 0.01]])
    from soft_envs.sim import Robot
    from .conftest import block_mesh
    r = Robot.from_mesh(block_mesh(), youngs_modulus=1e5, poisson_ratio=0.3, density=100.0,
                        tendons=[dict(name="t", points=pts, rest_length=0.05)],
                        motors=[dict(name="m", tendons=["t"])])
    pts[0, 0] = 99.0
    assert r.tendons[0].points[0, 0] == 0.055
    with pytest.raises(ValueError, match="rest_length must be positive"):
        Robot.from_mesh(block_mesh(), youngs_modulus=1e5, poisson_ratio=0.3, density=100.0,
                        tendons=[dict(name="t", points=pts, rest_length=float("nan"))])


@pytest.mark.parametrize("radius", [float("inf"), float("nan"), 0.0, -0.005])
def test_a_spool_radius_that_is_not_finite_and_positive_is_refused(radius):
    """``Robot.from_mesh`` checks what a robot.toml would: a spool radius of inf would turn
    every motor command into an angle of 0."""
    from soft_envs.sim import Robot
    from .conftest import block_mesh
    pts = np.array([[0.055, 0.015, 0.01], [0.005, 0.015, 0.01]])
    with pytest.raises(ValueError, match=r"motors\[0\].*spool_radius must be a finite positive number"):
        Robot.from_mesh(block_mesh(), youngs_modulus=1e5, poisson_ratio=0.3, density=100.0,
                        tendons=[dict(name="t", points=pts, rest_length=0.05)],
                        motors=[dict(name="m", tendons=["t"], spool_radius=radius)])
