"""Derivatives with respect to the physical parameters (calibration, issue #19) against central
finite differences: per energy term (``d(dE_t/dx)/dtheta``, in every regime of
``test_energy_derivatives.CASES``), the mass matrix, the Coulomb anchors' update, the rest state
and whole rollouts under both contact laws.

Per term: relative step 1e-6 of the parameter, relative error <= 1e-6. Whole rollouts:
Newton tolerance 1e-12 m per step, rest states to 1e-13 m, relative step 1e-5, relative error
<= 2e-5 over all states (measured: at most 4.2e-6, the contact stiffness under the Coulomb law).
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from soft_envs.sim import NewtonOptions, Simulator, load_robot
from .gradcheck import relative_error
from soft_envs.sim.parameters import (PARAMETERS, check_parameters, node_mass_jacobian, parameter_values,
                                      with_parameters)
from soft_envs.sim.system import EnergySystem

from .conftest import small_robot
from .test_energy_derivatives import CASES, perturbed_state

RTOL_TERM = 1e-6
RTOL_ROLLOUT = 2e-5


def applicable(sim) -> list[str]:
    out = []
    for n in PARAMETERS:
        try:
            sim.system.check_parameters([n])
        except ValueError:
            continue
        out.append(n)
    return out


@pytest.mark.parametrize("case", CASES)
def test_every_term_parameter_jacobian_matches_finite_differences(case):
    """For every term and every parameter it owns: ``add_parameter_jacobian`` against central
    differences of the term's gradient in a system built from the robot with the parameter
    moved (so a new term, or a new parameter of a term, is checked without a new test)."""
    sim, x, x_prev, u, rng = perturbed_state(case)
    system = sim.system
    history = system.initial_history(x_prev)
    if case == "coulomb_stick_and_slip":
        c = system.contact
        history = list(history)
        history[system.terms.index(c)] = x[c.nodes][:, [0, 2]] + rng.normal(scale=2.5e-4, size=(len(c.nodes), 2))
        history = tuple(history)
    check_term_parameter_jacobians(sim, x, x_prev, u, history)


def check_term_parameter_jacobians(sim, x, x_prev, u, history) -> None:
    """The checks of :func:`test_every_term_parameter_jacobian_matches_finite_differences` for
    every term of ``sim.system`` and every parameter that applies to its robot, at one state."""
    system, robot = sim.system, sim.robot
    names = applicable(sim)
    assert {"youngs_modulus", "poisson_ratio", "density", "contact_stiffness"} <= set(names)
    values = parameter_values(robot, names)
    checked = 0
    for i, (term, hist) in enumerate(zip(system.terms, history)):
        J = np.zeros((system.n_dof, len(names)))
        term.add_parameter_jacobian(x, x_prev, u, hist, names, J)
        for j, n in enumerate(names):
            h = 1e-6 * abs(values[j])
            grads = []
            for s in (1.0, -1.0):
                moved = EnergySystem(with_parameters(robot, {n: values[j] + s * h}), gravity=system.gravity,
                                     control=system.control).terms[i]
                g = np.zeros(system.n_dof)
                moved.assemble(x, x_prev, u, hist, g, np.zeros(system.pattern.nnz + 1), False)
                grads.append(g)
            fd = (grads[0] - grads[1]) / (2 * h)
            if n not in term.parameters:
                assert np.abs(fd).max() <= 1e-9 * max(np.abs(grads[0]).max(), 1e-300) and not J[:, j].any(), \
                    f"{term.name} depends on {n} but does not own it"
                continue
            scale = max(np.linalg.norm(fd), 1e-300)
            assert np.linalg.norm(J[:, j] - fd) <= RTOL_TERM * scale + 1e-12, f"{term.name}: d grad / d {n}"
            checked += bool(np.linalg.norm(fd) > 0)
    assert checked >= 4


@pytest.mark.parametrize("case", ["taut_cable_contact_friction", "coulomb_stick_and_slip"])
def test_mass_matrix_and_anchor_update_parameter_derivatives(case):
    """``mass_jacobian`` is the derivative of the lumped masses; the Coulomb anchors' update does
    not depend on any parameter (the law's claim, no ``history_parameter_jacobian``)."""
    sim, x, x_prev, u, rng = perturbed_state(case)
    robot = small_robot(payload_mass=0.01, payload_nodes=np.arange(4), contact=sim.robot.contact)
    system = EnergySystem(robot)
    names = ["density", "payload_mass", "youngs_modulus"]
    J = system.mass_jacobian(names)
    values = parameter_values(robot, names)
    for j, n in enumerate(names):
        h = 1e-6 * values[j]
        fd = (EnergySystem(with_parameters(robot, {n: values[j] + h})).mass
              - EnergySystem(with_parameters(robot, {n: values[j] - h})).mass) / (2 * h)
        np.testing.assert_allclose(J[:, j], fd, rtol=1e-7, atol=1e-12 * np.abs(system.mass).max())
    assert np.allclose(J[::3], node_mass_jacobian(robot, names)) and not J[:, 2].any()
    if system.has_history:
        hist = system.initial_history(x_prev)
        cidx = system.terms.index(system.contact)
        assert system.history_parameter_jacobian(x, x_prev, hist, ["contact_stiffness"])[cidx] is None
        for n in ("contact_stiffness", "friction_coefficient"):
            v = parameter_values(robot, [n])[0]
            nxt = [EnergySystem(with_parameters(robot, {n: v * f})).next_history(x, x_prev, hist)[cidx]
                   for f in (1.01, 0.99)]
            assert np.array_equal(nxt[0], nxt[1])


def gait(robot, K: int) -> np.ndarray:
    t = np.arange(K) * 0.033
    return np.stack([0.5 * robot.u_bounds[m, 1] * (1 - np.cos(2 * np.pi * t + 2.0 * m))
                     for m in range(robot.n_motors)], axis=1)


@pytest.mark.parametrize("model", ["paper", "coulomb"])
def test_rollout_parameter_jacobian_matches_finite_differences(model):
    """Whole rollouts of the Tripod from its rest state (whose derivative comes from
    differentiating the relaxation, :meth:`Simulator.rest_sensitivity`) against central
    differences of rollouts of robots with each parameter moved, under both contact laws."""
    robot = load_robot("tripod")
    robot = robot.replace(contact=dataclasses.replace(robot.contact, model=model))
    friction = robot.contact.law.friction_parameter          # the law says which parameter is its friction
    names = ["youngs_modulus", "poisson_ratio", "density", "payload_mass", "contact_stiffness", friction,
             "cable_stiffness"]
    tight = NewtonOptions(tol=1e-12)
    K = 30
    u = gait(robot, K)
    sim = Simulator(robot, newton=tight)
    x0, h0, dx0, dh0 = sim.rest_sensitivity(names, tol=1e-13)
    traj = sim.rollout(u, x0=x0, history0=h0, params=names, dx0dtheta=dx0, dhistory0dtheta=dh0)
    assert traj.dxdtheta.shape == (K + 1, 3 * robot.mesh.n_nodes, len(names))
    assert traj.info["parameters"] == tuple(names)
    values = parameter_values(robot, names)
    for j, n in enumerate(names):
        h = 1e-5 * values[j]
        runs = []
        for s in (1.0, -1.0):
            moved = Simulator(with_parameters(robot, {n: values[j] + s * h}), newton=tight)
            runs.append(moved.rollout(u, x0=moved.rest_state(tol=1e-13)))
        fd = (runs[0].x - runs[1].x).reshape(K + 1, -1) / (2 * h)
        assert np.linalg.norm(fd) > 0, n
        assert relative_error(traj.dxdtheta[:, :, j], fd) <= RTOL_ROLLOUT, n
        fdc = (runs[0].com - runs[1].com) / (2 * h)
        assert relative_error(traj.dcomdtheta[:, :, j], fdc) <= RTOL_ROLLOUT, f"{n}: COM"


def test_rollout_from_rest_includes_the_rest_state_derivative():
    """``rollout(params=...)`` without x0 starts from the rest state with its derivative; from a
    given x0 without ``dx0dtheta`` the initial state is held fixed."""
    robot = small_robot()
    sim = Simulator(robot)
    u = np.full((5, 1), 0.002)
    names = ["youngs_modulus", "density"]
    traj = sim.rollout(u, params=names)
    _, _, dx0, _ = sim.rest_sensitivity(names)
    assert np.array_equal(traj.dxdtheta[0], dx0) and np.abs(dx0).max() > 0
    fixed = sim.rollout(u, x0=sim.rest_state(), params=names)
    assert not fixed.dxdtheta[0].any()
    assert not hasattr(traj, "dcomdz") and fixed.dxdz is None   # no dudz: no z-sensitivities


def test_parameter_names_are_checked():
    coulomb = small_robot(contact={"model": "coulomb"})
    with pytest.raises(ValueError, match="unknown physical parameter 'stiffnes'"):
        check_parameters(coulomb, ["stiffnes"])
    with pytest.raises(ValueError, match="friction_coefficient"):
        check_parameters(coulomb, ["friction"])
    with pytest.raises(ValueError, match="'friction'"):
        check_parameters(small_robot(), ["friction_coefficient"])
    with pytest.raises(ValueError, match="no payload"):
        check_parameters(small_robot(), ["payload_mass"])
    with pytest.raises(ValueError, match="tension control"):
        Simulator(small_robot(), control="tension").rollout(np.ones((2, 1)), params=["cable_stiffness"])
    with pytest.raises(ValueError, match="given twice"):
        check_parameters(small_robot(), ["density", "density"])


def test_with_parameters_round_trips_and_scales_tendons():
    robot = load_robot("puppy")
    names = list(PARAMETERS)
    names.remove("friction_coefficient")
    values = parameter_values(robot, names) * 1.1
    moved = with_parameters(robot, dict(zip(names, values)))
    np.testing.assert_allclose(parameter_values(moved, names), values, rtol=1e-14)
    ratios = [b.stiffness / a.stiffness for a, b in zip(robot.tendons, moved.tendons)]
    np.testing.assert_allclose(ratios, 1.1, rtol=1e-14)
    assert with_parameters(robot, {}) is robot
    with pytest.raises(ValueError, match="poisson_ratio"):
        with_parameters(robot, {"poisson_ratio": 0.5})
