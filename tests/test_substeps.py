"""Physics sub-steps (soft_envs/sim/substeps.py): the controls joined by straight lines, exact
derivatives through the sub-steps, and agreement with a plain simulator at the fine step.

Finite differences: Newton tolerance 1e-13 m per step, central differences of whole rollouts in
random directions of z (tests/gradcheck.py), relative error <= 1e-6 under the Coulomb law
(measured 1e-8 - 1e-7)."""
from __future__ import annotations

import numpy as np
import pytest

from soft_envs.sim import NewtonOptions, Simulator, load_robot
from soft_envs.sim.substeps import (SUBSTEP_TOLERANCE, check_substeps, control_step_gradient, substep_controls,
                                    substep_jacobian, substep_weights)

from .gradcheck import relative_error, rollout_jacobian_errors

TIGHT = NewtonOptions(tol=1e-13)


def _gait(robot, K: int) -> np.ndarray:
    t = np.arange(1, K + 1) * 0.033
    return np.stack([0.5 * robot.u_bounds[m, 1] * 0.5 * (1 - np.cos(2 * np.pi * t / 0.5 + 2.0 * m))
                     for m in range(robot.n_motors)], axis=1)


def test_substep_controls_join_the_rows_by_straight_lines():
    u = np.array([[1.0, 2.0], [3.0, 2.0]])
    fine = substep_controls(u, np.array([0.0, 0.0]), 4)
    assert np.allclose(fine[:, 0], [0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 2.5, 3.0])
    assert np.allclose(fine[:, 1], [0.5, 1.0, 1.5, 2.0, 2.0, 2.0, 2.0, 2.0])
    assert substep_controls(u, np.zeros(2), 1) is u                  # one sub-step: the rows themselves
    assert np.allclose(substep_weights(3), [1 / 3, 2 / 3, 1.0])
    for bad in (0, -1, 1.5, True, "4"):
        with pytest.raises(ValueError, match="substeps"):
            check_substeps(bad)


def test_the_maps_are_each_others_transpose():
    """``control_step_gradient`` is the transpose of the linear map of ``substep_controls`` (with
    the start fixed), and ``substep_jacobian`` that map applied to du/dz."""
    rng = np.random.default_rng(0)
    K, M, n = 5, 3, 4
    A = np.zeros((K * n * M, K * M))          # the map u -> fine controls, column by column
    for c in range(K * M):
        e = np.zeros(K * M)
        e[c] = 1.0
        A[:, c] = substep_controls(e.reshape(K, M), np.zeros(M), n).ravel()
    g = rng.normal(size=(K * n, M))
    assert np.allclose(control_step_gradient(g, n).ravel(), A.T @ g.ravel())
    dudz = rng.normal(size=(K, M, 2))
    assert substep_jacobian(dudz[:, :, :0], n).shape == (K * n, M, 0)          # no parameters: empty
    assert substep_controls(np.zeros((0, M)), np.zeros(M), n).shape == (0, M)   # no steps
    fine = substep_jacobian(dudz, n)
    for j in range(2):
        assert np.allclose(fine[:, :, j].ravel(), A @ dudz[:, :, j].ravel())


def test_a_substepped_rollout_is_the_fine_simulator_on_interpolated_controls():
    """Simulator(dt, substeps=n) = Simulator(dt / n) on the straight-line controls, read at the
    ends of the control steps: bit for bit (the same steps in the same order, at the same Newton
    tolerance: a sub-stepped simulator's default is 1e-6 m, SUBSTEP_TOLERANCE)."""
    robot = load_robot("tripod")
    n, K = 4, 12
    coarse = Simulator(robot, substeps=n)
    assert coarse.newton.options.tol == SUBSTEP_TOLERANCE and Simulator(robot).newton.options.tol == 1e-8
    fine = Simulator(robot, dt=0.033 / n, newton=NewtonOptions(tol=SUBSTEP_TOLERANCE))
    u = _gait(robot, K)
    start = coarse.rest_state(robot.u_rest)
    t = coarse.rollout(u, x0=start)
    fine_start = fine.rest_state(robot.u_rest)
    assert np.array_equal(start.x, fine_start.x)                    # the rest state does not depend on dt
    tf = fine.rollout(substep_controls(u, robot.u_rest, n), x0=fine_start)
    assert np.array_equal(t.x, tf.x[::n])
    assert np.array_equal(t.com, tf.com[::n])
    assert np.array_equal(t.cable_deformation, tf.cable_deformation[::n])
    assert t.info["state"].k == K and np.array_equal(t.info["state"].u, u[-1])
    assert coarse.dt == 0.033 and coarse.physics_dt == pytest.approx(0.033 / n)


def test_steps_chain_into_the_rollout():
    """K control steps sharing a factorisation cache give the rollout bit for bit."""
    from soft_envs.sim import FactorCache
    robot = load_robot("puppy")
    sim = Simulator(robot, substeps=3)
    u = _gait(robot, 6)
    state = sim.rest_state(robot.u_rest)
    traj = sim.rollout(u, x0=state)
    cache = FactorCache()
    for k in range(len(u)):
        state = sim.step(state, u[k], factor_cache=cache)
        assert np.array_equal(state.x, traj.x[k + 1]) and state.k == k + 1
    assert np.array_equal(state.history[-1] if state.history[-1] is not None else 0,
                          traj.info["state"].history[-1] if traj.info["state"].history[-1] is not None else 0)


@pytest.mark.parametrize("name", ["tripod", "puppy"])
def test_jacobian_through_substeps_matches_finite_differences(name):
    robot = load_robot(name)
    sim = Simulator(robot, substeps=4, newton=TIGHT)
    K = 16
    u0 = _gait(robot, K)
    rng = np.random.default_rng(7)
    dudz = 1e-3 * rng.normal(size=(K, robot.n_motors, 5))
    errs = rollout_jacobian_errors(sim, u0, dudz, x0=sim.rest_state(robot.u_rest), n_dirs=2, h=3e-5, rng=rng,
                                   full_state=(name == "tripod"))
    assert max(errs.values()) <= 1e-6, errs


def test_adjoint_through_substeps_equals_forward_mode():
    robot = load_robot("tripod")
    sim = Simulator(robot, substeps=3, newton=NewtonOptions(tol=1e-12))
    K = 12
    u0 = _gait(robot, K)
    rng = np.random.default_rng(3)
    w = rng.normal(size=(K + 1, robot.mesh.n_nodes, 3))           # O = sum_k w_k . x_k
    dudz = rng.normal(size=(K, robot.n_motors, 4))
    start = sim.rest_state(robot.u_rest)
    traj = sim.rollout(u0, x0=start, dudz=dudz, store_dxdz=True)
    forward = np.einsum("kd,kdz->z", w[1:].reshape(K, -1), traj.dxdz[1:])
    adjoint = sim.rollout_gradient(u0, w, dudz=dudz, traj=traj)         # re-simulates with the sub-steps
    assert relative_error(adjoint, forward) <= 1e-8
    kept = sim.rollout(u0, x0=start, keep_substeps=True)
    assert kept.info["substep_x"].shape == (3 * K + 1, robot.mesh.n_nodes, 3)
    assert relative_error(sim.rollout_gradient(u0, w, dudz=dudz, traj=kept), forward) <= 1e-8
