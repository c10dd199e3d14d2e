"""Meshes and robot files that must be refused with a clear error (issue #16 item 8): a crack
(coincident duplicate nodes), several bodies, a robot.toml that is not UTF-8, infinite or NaN
numbers in any field; and the robot fingerprint that ties a result to its robot (item 6)."""
from __future__ import annotations

import re

import meshio
import numpy as np
import pytest

from soft_envs.sim import load_robot
from soft_envs.sim.mesh import TetMesh, load_mesh
from soft_envs.sim.meshgen import voxel_tet_mesh


def block(origin=(0.0, 0.0, 0.0), n=(2, 1, 1), size=(0.04, 0.02, 0.02)):
    xs, ys, zs = (o + np.linspace(0, s, k + 1) for o, s, k in zip(origin, size, n))
    return voxel_tet_mesh(xs, ys, zs, np.ones(n, bool))


def test_a_crack_of_duplicate_nodes_is_refused(tmp_path):
    """Two blocks that touch along a face but do not share its nodes: a crack."""
    p1, t1 = block()
    p2, t2 = block(origin=(0.04, 0.0, 0.0))
    points, tets = np.vstack([p1, p2]), np.vstack([t1, t2 + len(p1)])
    meshio.write(tmp_path / "crack.vtu", meshio.Mesh(points, [("tetra", tets)]))
    with pytest.raises(ValueError, match=r"crack\.vtu: \d+ pairs of coincident nodes, e\.g\. nodes \d+ and \d+.*crack"):
        load_mesh(tmp_path / "crack.vtu")
    # the same blocks with their shared face merged are one valid body
    merged = block(n=(4, 1, 1), size=(0.08, 0.02, 0.02))
    assert TetMesh(*merged).n_nodes == len(np.unique(points.round(12), axis=0))


def test_two_bodies_apart_are_refused(tmp_path):
    p1, t1 = block()
    p2, t2 = block(origin=(0.68, 0.0, 0.0))              # 0.64 m beyond the first block's end
    meshio.write(tmp_path / "two.vtu", meshio.Mesh(np.vstack([p1, p2]), [("tetra", np.vstack([t1, t2 + len(p1)]))]))
    with pytest.raises(ValueError, match=r"two\.vtu: the mesh is 2 disconnected bodies .* are 0\.64 apart\); a robot "
                                         r"must be one connected body"):
        load_mesh(tmp_path / "two.vtu")


def test_a_robot_file_that_is_not_utf8_names_the_file(robot_dir):
    path = robot_dir / "robot.toml"
    path.write_bytes(path.read_text().replace("# Tripod", "# Tripod \u00e9t\u00e9").encode("latin-1"))
    with pytest.raises(ValueError, match=rf"{re.escape(str(path))}: not UTF-8 text .*byte 0xe9"):
        load_robot(path)


# every number of the shipped Tripod's robot.toml, and the optional ones, one at a time
FLOAT_FIELDS = [
    ("body_length = 0.14", "body_length = {}", r"\[robot\]\.body_length"),
    ('up_axis = "+y"', 'up_axis = "+y"\nscale = {}', r"\[robot\]\.scale"),
    ("youngs_modulus = 1e+05", "youngs_modulus = {}", r"\[material\]\.youngs_modulus"),
    ("poisson_ratio = 0.3", "poisson_ratio = {}", r"\[material\]\.poisson_ratio"),
    ("density = 127.12", "density = {}", r"\[material\]\.density"),
    ("mass = 0.044", "mass = {}", r"\[payload\]\.mass"),
    ('nodes = "top"', 'nodes = "top"\ntop_tolerance = {}', r"\[payload\]\.top_tolerance"),
    ("stiffness = 2000.0", "stiffness = {}", r"\[contact\]\.stiffness"),
    ("friction = 1000.0", "friction = {}", r"\[contact\]\.friction"),
    ("blend = 0.0005", "blend = {}", r"\[contact\]\.blend"),
    ("friction_coefficient = 0.8", "friction_coefficient = {}", r"\[contact\]\.friction_coefficient"),
    ("slip_distance = 0.0003", "slip_distance = {}", r"\[contact\]\.slip_distance"),
    ("blend = 2e-4", "blend = {}", r"\[cables\]\.blend"),
    ("points = [[0.0780, 0.0040,", "points = [[{}, 0.0040,", r"tendons\[0\]\.points\[0\]\[0\]"),
    ("stiffness = 1e+05", "stiffness = {}", r"tendons\[0\]\.stiffness"),
    ("stiffness = 1e+05", "stiffness = 1e+05\nrest_length = {}", r"tendons\[0\]\.rest_length"),
    ("u_min = 0.0", "u_min = {}", r"motors\[0\]\.u_min"),
    ("u_max = 0.02", "u_max = {}", r"motors\[0\]\.u_max"),
    ("spool_radius = 0.005", "spool_radius = {}", r"motors\[0\]\.spool_radius"),
    ("[cables]", "[fixed]\nbox = [[0.0, 0.01], [0.0, {}], [0.0, 0.04]]\n\n[cables]", r"\[fixed\]\.box\[1\]\[1\]"),
]


@pytest.mark.parametrize("value", ["inf", "-inf", "nan"])
@pytest.mark.parametrize("old,new,field", FLOAT_FIELDS, ids=[f[2].replace("\\", "") for f in FLOAT_FIELDS])
def test_non_finite_numbers_are_refused_naming_the_field(robot_dir, old, new, field, value):
    path = robot_dir / "robot.toml"
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new.format(value), 1))
    with pytest.raises(ValueError, match=rf"{re.escape(str(path))}: {field} must be a finite number, got {value}"):
        load_robot(path)


def test_a_rest_state_that_fails_names_the_material(tmp_path):
    """Issue #40: a Puppy with E = 5 Pa failed with "rest_state of robot 'puppy' failed (u = ...,
    gravity = ...): Newton did not converge", naming no material: a unit mistake did not show."""
    import shutil

    from soft_envs.sim import Simulator, SimulationError
    from soft_envs.sim.robot_file import asset_path
    src = asset_path("puppy").parent
    shutil.copy(src / "puppy.vtu", tmp_path / "puppy.vtu")
    text = (src / "robot.toml").read_text()
    line = next(ln for ln in text.splitlines() if ln.startswith("youngs_modulus ="))
    (tmp_path / "robot.toml").write_text(text.replace(line, "youngs_modulus = 5"))
    robot = load_robot(tmp_path / "robot.toml")
    with pytest.raises(SimulationError) as err:
        Simulator(robot).rest_state()
    text = str(err.value)
    assert "Young's modulus 5 Pa" in text and f"Poisson ratio {robot.poisson_ratio:g}" in text
    assert f"density {robot.density:g} kg/m^3" in text and "puppy" in text
