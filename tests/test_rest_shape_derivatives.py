"""Rest-shape derivatives (issue #29, geometry) against central finite differences: the elastic
energy and its gradient, the lumped masses, the cable embedding and the cable force, for a
random move of every rest node and tendon point. Relative step 1e-7 of the bar's size (moves of
0.1 um), relative error <= 1e-6 stated in each assertion message."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from soft_envs.sim.design.rest_shape import (cable_rest_derivative, elastic_rest_derivative,
                                             embedding_rest_derivative, lumped_mass_rest_derivative)
from soft_envs.sim.mesh import TetMesh
from soft_envs.sim.system import EnergySystem

from .gradcheck import relative_error
from .test_energy_derivatives import perturbed_state

RTOL = 1e-6
H = 1e-7
GENERIC = [[0.055, 0.016, 0.0042], [0.031, 0.0123, 0.0061], [0.0052, 0.0155, 0.0043]]


def moved(robot, dX, dq, s):
    mesh = TetMesh(robot.mesh.points + s * dX, robot.mesh.tets, robot.mesh.source)
    tendons = tuple(dataclasses.replace(t, points=np.asarray(t.points) + s * d) for t, d in zip(robot.tendons, dq))
    return robot.replace(mesh=mesh, tendons=tendons)


def random_move(robot, seed):
    rng = np.random.default_rng(seed)
    dX = rng.normal(size=robot.mesh.points.shape)
    dq = [rng.normal(size=np.shape(t.points)) for t in robot.tendons]
    return dX, dq


@pytest.mark.parametrize("case", ["taut_cable_contact_friction", "cable_in_blend", "tension_control", "fixed_nodes"])
def test_rest_shape_derivatives_match_finite_differences(case):
    sim, x, x_prev, u, _ = perturbed_state(case)
    # the bar's tendon through points off the tets' faces (there the embedding is smooth)
    robot = sim.robot.replace(tendons=(dataclasses.replace(sim.robot.tendons[0], points=GENERIC),))
    system = EnergySystem(robot, gravity=sim.system.gravity, control=sim.system.control)
    if system.control == "length":      # the same cable deformation Gamma as the case's
        u = u + (system.cables.alpha0 - sim.system.cables.alpha0) - (system.cables.lengths(x) - sim.system.cables.lengths(x))
    dX, dq = random_move(robot, 7)
    systems = [EnergySystem(moved(robot, dX, dq, s), gravity=system.gravity, control=system.control)
               for s in (H, -H)]

    dE, dg = elastic_rest_derivative(system.elastic, robot.mesh, x, dX)
    E = [s.elastic.energy(x, x_prev, u) for s in systems]
    fdE = (E[0] - E[1]) / (2 * H)
    assert abs(dE - fdE) <= RTOL * abs(fdE), f"elastic energy: relative error {abs(dE - fdE) / abs(fdE):.2e}"
    g = []
    for s in systems:
        gi = np.zeros(system.n_dof)
        s.elastic.assemble(x, x_prev, u, None, gi, np.zeros(1), False)
        g.append(gi)
    err = relative_error(dg, (g[0] - g[1]) / (2 * H))
    assert err <= RTOL, f"elastic gradient: relative error {err:.2e}"

    dm = lumped_mass_rest_derivative(robot.mesh, robot.density, dX)
    err = relative_error(dm, (systems[0].robot.node_masses - systems[1].robot.node_masses) / (2 * H))
    assert err <= RTOL, f"lumped masses: relative error {err:.2e}"

    cd = robot.cable_data
    for k in range(len(cd.pt_w)):
        t = int(np.searchsorted(cd.ptr, k, side="right") - 1)
        r = k - cd.ptr[t]
        tet = robot._binding[t][0][r]
        dw, dp = embedding_rest_derivative(robot.mesh, tet, cd.pt_w[k], x, dX, dq[t][r])
        w = [s.robot.cable_data.pt_w[k] for s in systems]
        assert all(np.array_equal(s.robot.cable_data.pt_nodes[k], cd.pt_nodes[k]) for s in systems)
        err = relative_error(dw, (w[0] - w[1]) / (2 * H))
        assert err <= RTOL, f"embedding weights of point {k}: relative error {err:.2e}"
        p = [wi @ x[cd.pt_nodes[k]] for wi in w]
        err = relative_error(dp, (p[0] - p[1]) / (2 * H))
        assert err <= RTOL, f"embedded point {k}: relative error {err:.2e}"

    dgc = cable_rest_derivative(system, x, u, dX, dq)
    gc = []
    for s in systems:
        gi = np.zeros(system.n_dof)
        s.cables.assemble(x, x_prev, u, None, gi, np.zeros(s.pattern.nnz + 1), False)
        gc.append(gi)
    err = relative_error(dgc, (gc[0] - gc[1]) / (2 * H))
    assert err <= RTOL, f"cable force: relative error {err:.2e}"

