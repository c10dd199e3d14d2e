"""Static solutions: a clamped neo-Hookean cantilever under gravity against beam theory and
against FElupe (an independent implementation of the same energy), and a block at rest."""
from __future__ import annotations

import meshio
import numpy as np
import pytest

from soft_envs.sim import NewtonOptions, Robot, Simulator
from soft_envs.sim.meshgen import voxel_tet_mesh


def cantilever(n_len=20, n_side=3, L=0.1, a=0.01, E=1e5, nu=0.3, rho=100.0):
    xs = np.linspace(0, L, n_len + 1)
    ys = 0.05 + np.linspace(0, a, n_side + 1)         # well above the ground: no contact
    zs = np.linspace(0, a, n_side + 1)
    p, t = voxel_tet_mesh(xs, ys, zs, np.ones((n_len, n_side, n_side), bool))
    robot = Robot.from_mesh(meshio.Mesh(p, [("tetra", t)]), youngs_modulus=E, poisson_ratio=nu,
                            density=rho, fixed_nodes=np.flatnonzero(p[:, 0] < 1e-12))
    return robot


def tip_deflection(robot, x):
    tip = robot.mesh.points[:, 0] > robot.mesh.points[:, 0].max() - 1e-12
    return float((robot.mesh.points[tip, 1] - x[tip, 1]).mean())


def test_cantilever_small_load_close_to_beam_theory():
    """Euler-Bernoulli: tip deflection q L^4 / (8 E I), q = rho g A (here 1.5 % of L). Linear
    tets lock in bending, so the FEM deflection approaches the theory from below as the mesh
    is refined (ratios measured: 0.25, 0.55, 0.83): it must increase monotonically under
    uniform refinement and be within 20 % on the finest mesh (40 x 4 x 4 cells)."""
    E, nu, rho, L, a = 1e6, 0.0, 100.0, 0.1, 0.01
    theory = rho * 9.81 * a * a * L**4 / (8 * E * a**4 / 12)
    ratios = []
    for n_len, n_side in [(10, 1), (20, 2), (40, 4)]:
        robot = cantilever(n_len, n_side, L, a, E, nu, rho)
        x = Simulator(robot).rest_positions()
        ratios.append(tip_deflection(robot, x) / theory)
    assert ratios[0] < ratios[1] < ratios[2] < 1.02
    assert ratios[2] > 0.8, f"tip deflection {ratios[2]:.2f} x beam theory ({theory * 1e3:.3f} mm)"


def test_cantilever_matches_felupe():
    """Large-deflection static solution equals FElupe's NeoHookeCompressible to 1e-6 relative."""
    fem = pytest.importorskip("felupe")
    E, nu, rho = 2e4, 0.3, 100.0             # soft: tip deflection ~ 15 % of the length
    robot = cantilever(8, 2, E=E, nu=nu, rho=rho)
    sim = Simulator(robot, newton=NewtonOptions(tol=1e-12))
    x = sim.rest_positions(tol=1e-13)
    assert tip_deflection(robot, x) > 0.01

    mesh = fem.Mesh(np.array(robot.mesh.points), np.array(robot.mesh.tets), "tetra")
    region = fem.RegionTetra(mesh)
    field = fem.FieldContainer([fem.Field(region, dim=3)])
    mask = np.zeros(len(mesh.points), bool)
    mask[robot.fixed_nodes] = True
    boundaries = {"clamp": fem.Boundary(field[0], mask=mask)}
    mu, lam = robot.element_lame()
    solid = fem.SolidBody(fem.NeoHookeCompressible(mu=mu[0], lmbda=lam[0]), field)
    gravity = fem.SolidBodyForce(field, scale=rho)
    ramp = np.outer(np.linspace(0, 1, 6)[1:], [0.0, -9.81, 0.0])   # gravity vector per substep
    step = fem.Step(items=[solid, gravity], ramp={gravity: ramp}, boundaries=boundaries)
    fem.Job(steps=[step]).evaluate(tol=1e-12)
    u_felupe = field[0].values
    u_ours = x - robot.mesh.points
    err = np.abs(u_ours - u_felupe).max() / np.abs(u_felupe).max()
    assert err < 1e-6, f"relative difference to FElupe {err:.2e}"


def test_static_solution_is_an_equilibrium_and_converges():
    robot = cantilever(6, 2, E=3e4)
    sim = Simulator(robot)
    x = sim.rest_positions(tol=1e-12)
    g = sim.gradient(x, x, np.zeros(0)).copy()
    g[robot.fixed_nodes] = 0.0
    weight = robot.total_mass * 9.81
    assert np.abs(g).max() < 1e-8 * weight
