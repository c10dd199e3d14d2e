"""The Coulomb contact law against closed-form friction (issue #15's targets).

A soft cube on a slope with mu = 0.5: at 20 degrees (tan 20 = 0.36 < 0.5) it must stick
(< 0.1 mm in 3 s); at 35 degrees it slides with the acceleration g (sin a - mu cos a) within
5 %; both at h = 0.033 s and h = 0.0165 s (the law converges as h shrinks). Both shipped
robots standing on a 10-degree slope with mu = 0.8 move less than 0.1 mm in 3 s. The paper's
law is shown to creep in the same situation (what the Coulomb law fixes).
"""
from __future__ import annotations

import dataclasses
import math

import meshio
import numpy as np
import pytest

from soft_envs.sim import ContactParams, Robot, Simulator, incline_gravity, load_robot
from soft_envs.sim.meshgen import voxel_tet_mesh

G = 9.81


def soft_cube(mu: float, size: float = 0.02, n: int = 2) -> Robot:
    xs = np.linspace(0.0, size, n + 1)
    p, t = voxel_tet_mesh(xs, xs, xs, np.ones((n, n, n), bool))
    return Robot.from_mesh(meshio.Mesh(p, [("tetra", t)]), youngs_modulus=1e5, poisson_ratio=0.3,
                           density=200.0, contact=ContactParams(model="coulomb", friction_coefficient=mu))


def slide_along_slope(sim: Simulator, seconds: float, released: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Times and COM displacement along the downhill direction (+x: uphill is -x here), from
    the rest state on the slope with its anchors, or (``released``) from the rest state on
    flat ground, released on the slope (where the body cannot rest)."""
    K = int(round(seconds / sim.dt))
    if released:
        x0 = Simulator(sim.robot, dt=sim.dt).rest_positions()
        traj = sim.rollout(np.zeros((K, sim.n_motors)), x0=x0)
    else:
        traj = sim.rollout(np.zeros((K, sim.n_motors)))          # from the rest state and its anchors
    t = np.arange(K + 1) * sim.dt
    return t, traj.com[:, 0] - traj.com[0, 0]


@pytest.mark.parametrize("h", [0.033, 0.0165])
def test_cube_sticks_below_the_friction_angle(h):
    sim = Simulator(soft_cube(0.5), dt=h, gravity=incline_gravity(20.0, uphill=(-1.0, 0.0)))
    t, s = slide_along_slope(sim, 3.0)
    assert np.abs(s).max() < 1e-4, f"moved {1e3 * np.abs(s).max():.4f} mm"


@pytest.mark.parametrize("h", [0.033, 0.0165])
def test_cube_slides_with_coulomb_acceleration(h):
    a_deg, mu = 35.0, 0.5
    sim = Simulator(soft_cube(mu), dt=h, gravity=incline_gravity(a_deg, uphill=(-1.0, 0.0)))
    t, s = slide_along_slope(sim, 3.0, released=True)
    late = t >= 0.5                              # after the bristles and the body have loaded
    acc = 2.0 * np.polyfit(t[late], s[late], 2)[0]
    expected = G * (math.sin(math.radians(a_deg)) - mu * math.cos(math.radians(a_deg)))
    assert abs(acc - expected) <= 0.05 * expected, (acc, expected)


@pytest.mark.parametrize("name", ["tripod", "puppy"])
def test_shipped_robots_stand_on_a_10_degree_slope(name):
    base = load_robot(name)
    robot = base.replace(contact=dataclasses.replace(base.contact, model="coulomb", friction_coefficient=0.8))
    sim = Simulator(robot, gravity=incline_gravity(10.0))
    traj = sim.rollout(np.zeros((91, robot.n_motors)))          # 3 s from the rest state
    moved = np.linalg.norm(traj.com - traj.com[0], axis=1).max()
    assert moved < 1e-4, f"{name} moved {1e3 * moved:.4f} mm"


def test_the_paper_law_creeps_where_coulomb_sticks():
    """The reason for the second law: the paper's friction is viscous, so the same Puppy creeps
    down the 10-degree slope (DESIGN.md: about 1.2 BL/min)."""
    base = load_robot("puppy")                                   # the shipped file says Coulomb
    robot = base.replace(contact=dataclasses.replace(base.contact, model="paper"))
    sim = Simulator(robot, gravity=incline_gravity(10.0))
    traj = sim.rollout(np.zeros((91, robot.n_motors)), x0=sim.rest_state())
    assert np.linalg.norm(traj.com[-1] - traj.com[0]) > 1e-3
