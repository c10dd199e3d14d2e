"""The Hexapod and the Inchworm (issue #39 item 3): robots made with the surface-mesh pipeline
(``assets/make_surfaces.py``, then ``trajopt mesh``) that load by name, pass the robot checks,
declare a [design] table, have an environment id and stand for 5 s under both contact laws."""
from __future__ import annotations

import dataclasses
import re
import sys
import tomllib

import gymnasium as gym
import numpy as np
import pytest

import soft_envs
from soft_envs.robot_check import check_robot
from soft_envs.sim import Simulator, load_robot
from soft_envs.sim.design import load_design
from soft_envs.sim.kinematics import BodyFrame, tilt_deg_of
from soft_envs.sim.robot_file import SHIPPED_ROBOTS, asset_path

from .test_gym_conventions import test_spec_tables_match_the_environment as spec_tables_match

#: per robot: motors, legs (connected parts below the hips), design regions, tet range
EXPECTED = {"hexapod": dict(motors=12, legs=6, regions=["hind_legs", "mid_legs", "fore_legs", "body"]),
            "inchworm": dict(motors=5, legs=2, regions=["hind_foot", "fore_foot", "strip"])}
NEW = sorted(EXPECTED)
#: standing still: the COM moves less than this [m] in 5 s from rest (0.1 mm) ...
STILL_TOL = 1e-4
#: ... and, put down undeformed, it never moves more than this (2 mm) and ends within STILL_TOL
#: of its rest COM; the body stays within this tilt [deg] throughout
SETTLE_TOL, TILT_TOL_DEG = 2e-3, 2.0
FIVE_SECONDS = 152          # control steps of 0.033 s


@pytest.fixture(scope="module", params=NEW)
def robot(request):
    return load_robot(request.param)


def test_shipped_by_name():
    assert set(NEW) <= set(SHIPPED_ROBOTS)
    for name in NEW:
        assert asset_path(name).parent.name == name


def test_loads_and_passes_the_robot_checks(robot):
    ref = EXPECTED[robot.name]
    check = check_robot(robot.name)
    assert check.warnings == [], check.warnings
    assert check.quality.min_dihedral_deg > 15 and check.quality.min_radius_ratio > 0.3
    assert 300 <= robot.mesh.n_tets <= 600 and robot.mesh.n_nodes <= 300        # the shipped robots' range
    assert np.ptp(robot.mesh.points[:, 0]) == pytest.approx(0.14) == robot.body_length
    assert robot.n_motors == ref["motors"] and all(len(m.tendons) == 2 for m in robot.motors)
    np.testing.assert_array_equal(robot.mirror_map[robot.mirror_map], np.arange(robot.n_motors))
    top = robot.mesh.points[:, 1].max()
    assert np.all(robot.mesh.points[robot.payload_nodes, 1] > top - 1e-6)
    assert 1.5 < robot.payload_mass / (robot.total_mass - robot.payload_mass) < 3.0     # top-heavy, as the Puppy


def test_every_motor_and_tendon_field_is_documented(robot):
    """The file parses, every motor carries its gearmotor's figures, and every motor and tendon
    field has its comment (units, source) as in the shipped robots' files."""
    text = asset_path(robot.name).read_text()
    doc = tomllib.loads(text)
    for m in doc["motors"]:
        assert {"u_min", "u_max", "spool_radius", "max_speed_rpm", "stall_torque", "max_torque"} <= set(m), m["name"]
    for key in ("u_min", "u_max", "spool_radius", "max_speed_rpm", "stall_torque", "max_torque", "stiffness",
                "mirror", "mass", "density", "hip_height", "routing"):
        lines = re.findall(rf"^{key} = .*$", text, flags=re.M)
        assert (lines or key == "mirror") and all("#" in line for line in lines), key   # the Inchworm has no mirrors
    assert doc["design"]["regions"] and doc["robot"]["name"] == robot.name


def test_the_design_table_loads(robot):
    ref = EXPECTED[robot.name]
    design = load_design(robot)
    moduli, routing, legs = design.kinds
    assert [r.name for r in moduli.regions] == ref["regions"]
    covered = np.concatenate([r.elements for r in moduli.regions])
    np.testing.assert_array_equal(np.sort(covered), np.arange(robot.mesh.n_tets))      # each tet once
    assert len(routing.leaders) + len(routing.followers) == len(robot.tendons)
    assert len(legs.legs) == ref["legs"]
    assert np.allclose(design.robot_at(design.values).mesh.points, robot.mesh.points)


@pytest.mark.parametrize("law", ["coulomb", "paper"])
def test_stands_still_for_five_seconds(robot, law):
    robot = robot.replace(contact=dataclasses.replace(robot.contact, model=law))
    sim = Simulator(robot)
    x0 = sim.rest_positions()
    frame = BodyFrame(x0, robot.node_masses)
    rest = sim.rollout(np.zeros((FIVE_SECONDS, robot.n_motors)), x0=x0)
    assert np.linalg.norm(rest.com - rest.com[0], axis=1).max() < STILL_TOL
    assert max(tilt_deg_of(frame.rotation(x)) for x in rest.x) < TILT_TOL_DEG
    assert x0[robot.payload_nodes, 1].min() > 0.9 * robot.mesh.points[:, 1].max()       # upright, hardly sagging
    dropped = sim.rollout(np.zeros((FIVE_SECONDS, robot.n_motors)), x0=robot.mesh.points.copy())
    moved = np.linalg.norm(dropped.com - rest.com[0], axis=1)
    assert moved.max() < SETTLE_TOL and moved[-1] < STILL_TOL
    assert max(tilt_deg_of(frame.rotation(x)) for x in dropped.x) < TILT_TOL_DEG


def test_the_belly_humps_the_inchworm():
    """The Inchworm's own motor: winding the belly tendons lifts the middle of the strip and
    draws the feet together."""
    robot = load_robot("inchworm")
    sim = Simulator(robot)
    x0 = sim.rest_positions()
    m = robot.motor_names.index("belly")
    u = np.zeros((30, robot.n_motors))
    u[:, m] = np.linspace(0.0, robot.u_bounds[m, 1], 30)
    x = sim.rollout(u, x0=x0).x[-1]
    P = robot.mesh.points
    mid, hind, fore = np.abs(P[:, 0] - 0.07) < 0.01, P[:, 0] < 0.025, P[:, 0] > 0.115
    assert x[mid, 1].max() - x0[mid, 1].max() > 0.01                              # humped by > 1 cm
    gap = lambda y: y[fore, 0].mean() - y[hind, 0].mean()                          # noqa: E731
    assert gap(x) - gap(x0) < -0.01                                               # feet > 1 cm closer


@pytest.mark.parametrize("name", NEW)
def test_the_environment_id(name):
    env_id = soft_envs.LATEST_ENV_IDS[name]
    assert env_id in soft_envs.ENV_IDS and soft_envs.ENV_ROBOTS[env_id] == name
    assert name not in soft_envs.ENV_IDS_BY_ROBOT            # no Table I ids (-v0, -v1) for them
    env = gym.make(env_id)
    obs, _ = env.reset(seed=0)
    assert env.action_space.shape == (EXPECTED[name]["motors"],) and env.observation_space.contains(obs)
    for _ in range(3):
        obs, _, terminated, truncated, _ = env.step(env.action_space.sample())
        assert not terminated and not truncated
    spec_tables_match(env_id)
    doc = type(env.unwrapped).__doc__
    assert "-v0" not in doc[:doc.index("## Version History")]     # no keyword or table names a -v0 of its


@pytest.mark.parametrize("name", NEW)
def test_the_surfaces_are_made_by_the_script(name, tmp_path, monkeypatch):
    """``assets/make_surfaces.py`` writes the committed surface, and ``trajopt mesh`` with the
    documented options makes the committed mesh from it (gmsh is deterministic here)."""
    monkeypatch.syspath_prepend(str(asset_path(name).parents[1]))
    sys.modules.pop("make_surfaces", None)
    import make_surfaces
    out = tmp_path / f"{name}.obj"
    make_surfaces.write_obj(out, name, *make_surfaces.surface(name))
    committed = asset_path(name).with_name(f"{name}.obj")
    assert out.read_text() == committed.read_text()
    pytest.importorskip("gmsh")
    from soft_envs.meshing import mesh_surface
    mesh = mesh_surface(committed, scale=1e-3, up="+z", forward="+x", remesh=False)
    robot = load_robot(name)
    assert (len(mesh.points), len(mesh.tets)) == (robot.mesh.n_nodes, robot.mesh.n_tets)
    np.testing.assert_allclose(mesh.points, robot.mesh.points, atol=1e-12)
