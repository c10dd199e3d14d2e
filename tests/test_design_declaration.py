"""The ``[design]`` table of robot.toml (issue #29 item 1): what it declares, in the simulation
frame, and the errors that name the file and the field; a design written as a robot folder."""
from __future__ import annotations

import shutil
from pathlib import Path

import meshio
import numpy as np
import pytest

from soft_envs.sim import Simulator, load_robot
from soft_envs.sim.design import MIN_CLEARANCE, TendonRouting, load_design, region_from_boxes, write_designed_robot
from soft_envs.sim.fingerprint import robot_fingerprint
from soft_envs.sim.robot_file import read_robot_toml

DESIGN = """
[design]
routing = "all"
hip_height = 0.03
modulus_bounds = [0.5, 2.0]

[[design.regions]]
name = "middle_leg"
boxes = [[0.055, 0.0, 0.0, 0.085, 0.03, 0.04]]

[[design.regions]]
name = "tagged"
cell_tag = 7
cell_data = "region"
"""


def without_design(text: str) -> str:
    """A shipped robot.toml without its ``[design]`` table (the generator writes it last)."""
    return text.split("\n[design]")[0]


def with_design(robot_dir, text=DESIGN):
    path = robot_dir / "robot.toml"
    path.write_text(without_design(path.read_text()) + text)
    mesh = meshio.read(robot_dir / "tripod.vtu")
    centroid = mesh.points[mesh.cells_dict["tetra"]].mean(axis=1)
    tags = np.where(centroid[:, 1] > 0.046, 7, 0)             # the top layer of the body
    mesh.cell_data["region"] = [tags]
    meshio.write(robot_dir / "tripod.vtu", mesh)
    return load_robot(path)


def test_the_design_table_declares_every_kind(robot_dir):
    robot = with_design(robot_dir)
    design = load_design(robot)
    assert design.names[:2] == ("stiffness:middle_leg", "stiffness:tagged")
    assert np.allclose(design.bounds[:2], [[5e4, 2e5]] * 2)
    routing = design.kinds[1]
    assert [robot.tendon_names[t] for t in routing.leaders] == ["front_a", "back_a"]   # the b's mirror them
    assert len(routing.free) == 6 and design.names[-3:] == ("legs:leg0", "legs:leg1", "legs:leg2")
    tagged = design.kinds[0].regions[1].elements
    assert np.array_equal(tagged, region_from_boxes(robot, "top", [[-1, 0.046, -1, 1, 1, 1]]).elements)
    only = load_design(robot, vary=["routing"])
    assert only.names == routing.names
    moved = design.robot_at(design.values)
    assert np.allclose(moved.mesh.points, robot.mesh.points) and np.allclose(moved.element_lame()[0],
                                                                             robot.element_lame()[0])


@pytest.mark.parametrize("text, match", [
    ("\n[design]\nrouting = \"all\"\ncolour = 1\n", r"unknown key \[design\]\.colour"),
    ("\n[design]\nrouting = [\"front_z\"]\n", "unknown tendon 'front_z'"),
    ("\n[design]\nrouting = \"all\"\n", r"\[design\]\.hip_height is missing"),
    ("\n[design]\nhip_height = 0.03\n[[design.regions]]\nname = \"r\"\n", "needs either boxes or cell_tag"),
    ("\n[design]\nhip_height = 0.03\n[[design.regions]]\nname = \"r\"\nboxes = [[1, 2]]\n",
     r"boxes must be a list of \[x0"),
    ("\n[design]\nhip_height = 0.03\n[[design.regions]]\nname = \"r\"\ncell_tag = 1\ncell_data = \"mat\"\n",
     "has no cell data 'mat'"),
])
def test_design_table_errors_name_the_file_and_field(robot_dir, text, match):
    robot = with_design(robot_dir, text)
    vary = ["routing"] if "front_z" in text else ["stiffness", "routing", "legs"] if "colour" in text else \
        ["legs"] if "hip_height" not in text else ["stiffness"]
    with pytest.raises(ValueError, match=match) as err:
        load_design(robot, vary)
    assert str(robot_dir / "robot.toml") in str(err.value)


def test_a_robot_without_design_table_is_fixed(robot_dir):
    path = robot_dir / "robot.toml"
    path.write_text(without_design(path.read_text()))
    with pytest.raises(ValueError, match=r"no \[design\] table"):
        load_design(load_robot(path))


@pytest.mark.parametrize("file", ["robot.toml", "robot_fine.toml"])
def test_the_shipped_robots_declare_their_design(file):
    """The generator's ``[design]`` tables (assets/make_robots.py): every tendon routed (Tripod: 2
    leaders, each motor's _b mirrors its _a; Puppy: 4 leaders of 16), the legs below the hip
    (3 and 4, mirror legs tied on the Puppy), and regions that cover every tet once."""
    for name, regions, leaders, legs in (
            ("tripod", ["back_leg", "middle_leg", "front_leg", "body"], ["front_a", "back_a"],
             ["legs:leg0", "legs:leg1", "legs:leg2"]),
            ("puppy", ["hind_legs", "fore_legs", "body"], ["hind_left_front_a", "hind_left_back_a",
                                                             "fore_left_front_a", "fore_left_back_a"],
             ["legs:leg0+leg1", "legs:leg2+leg3"])):
        robot = load_robot(f"assets/{name}/{file}" if file != "robot.toml" else name)
        design = load_design(robot)
        moduli, routing, morph = design.kinds
        assert [r.name for r in moduli.regions] == regions
        covered = np.concatenate([r.elements for r in moduli.regions])
        assert np.array_equal(np.sort(covered), np.arange(robot.mesh.n_tets))
        assert [robot.tendon_names[t] for t in routing.leaders] == leaders
        assert len(routing.leaders) + len(routing.followers) == len(robot.tendons)
        assert morph.names == tuple(legs) and len(morph.legs) == (3 if name == "tripod" else 4)
        assert np.allclose(design.robot_at(design.values).mesh.points, robot.mesh.points)


@pytest.mark.parametrize("name", ["tripod", "puppy"])
def test_the_fingerprint_ignores_the_design_table(name, tmp_path):
    """Declaring what co-design may vary does not change the robot: the same fingerprint with the
    ``[design]`` table, without it or with another one (results made before still match)."""
    src = Path(load_robot(name).source)
    fingerprints = []
    for i, text in enumerate(["", "\n[design]\nrouting = [\"front_a\"]\n"]):
        folder = tmp_path / str(i)
        shutil.copytree(src.parent, folder)
        (folder / "robot.toml").write_text(without_design(src.read_text()) + text)
        fingerprints.append(robot_fingerprint(folder / "robot.toml"))
    shipped = robot_fingerprint(name)
    assert "design" in read_robot_toml(src) and "design" not in shipped["toml"]
    for fp in fingerprints:
        assert (fp["sha256"], fp["toml_sha256"], fp["mesh_sha256"]) == \
            (shipped["sha256"], shipped["toml_sha256"], shipped["mesh_sha256"])


def test_a_written_design_loads_back_and_is_another_robot(robot_dir, tmp_path):
    """Routing, regional moduli and leg lengths written as a robot folder: it loads with
    ``load_robot`` as the design's robot, simulates, and its fingerprint differs from the
    source's (so a result made on one refuses the other)."""
    robot = with_design(robot_dir)
    design = load_design(robot)
    theta = design.values.copy()
    theta[0] *= 1.7                                             # the middle leg stiffer
    theta[design.names.index("routing:front_a[1].y")] += 0.002
    theta[design.names.index("legs:leg1")] = 0.003             # the middle leg 3 mm longer
    path = write_designed_robot(design, theta, tmp_path / "designed")
    back = load_robot(path)
    want = design.robot_at(theta)
    assert np.allclose(back.mesh.points, want.mesh.points) and (path.parent / "mesh.vtu").is_file()
    assert np.allclose(back.element_lame()[0], want.element_lame()[0])
    assert np.allclose(back.tendons[1].points, want.tendons[1].points)      # front_b mirrors front_a
    assert back.total_mass > robot.total_mass
    traj = Simulator(back).rollout(np.full((3, back.n_motors), 0.002))
    assert np.isfinite(traj.x).all()
    assert robot_fingerprint(path)["sha256"] != robot_fingerprint(robot)["sha256"]
    assert load_design(back).names == design.names                   # it can be co-designed again
    with pytest.raises(ValueError, match="never overwrites"):
        write_designed_robot(design, theta, robot_dir)


def test_a_written_design_is_a_self_contained_folder(robot_dir, tmp_path):
    """Issue #40: a design that keeps the mesh pointed to the source's mesh by a relative path,
    so a copied (or moved) folder broke; its mesh is copied in, and any copy of the folder
    loads as the same robot."""
    robot = with_design(robot_dir)
    design = load_design(robot, ["stiffness"])
    theta = design.values.copy()
    theta[0] *= 1.7
    path = write_designed_robot(design, theta, tmp_path / "a" / "designed")
    assert read_robot_toml(path)["robot"]["mesh"] == "mesh.vtu" and (path.parent / "mesh.vtu").is_file()
    copy = Path(shutil.copytree(path.parent, tmp_path / "elsewhere" / "deeper" / "copy"))
    shutil.rmtree(path.parent)
    back = load_robot(copy / "robot.toml")
    assert np.allclose(back.element_lame()[0], design.robot_at(theta).element_lame()[0])
    assert robot_fingerprint(copy / "robot.toml")["mesh_sha256"] == robot_fingerprint(robot)["mesh_sha256"]


@pytest.mark.parametrize("name", ["tripod", "puppy"])
def test_shipped_via_points_sit_on_the_clearance_bound(name):
    """Every tendon point of the shipped robots lies at least 2 mm inside the body, most exactly
    at 2 mm: the co-design's clearance constraint starts active (it needs a tolerance of ~1e-12 m
    for round-off)."""
    robot = load_robot(name)
    d, J = TendonRouting(robot, fixed=()).clearance(robot)
    assert (d >= MIN_CLEARANCE - 1e-12).all() and np.isclose(d.min(), MIN_CLEARANCE, atol=1e-12)
    assert (np.linalg.norm(J, axis=1) > 0).all()          # each row: a unit gradient through its column
