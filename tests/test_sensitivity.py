"""Sensitivity analysis (paper III-A): rollout Jacobians against central finite differences of
whole rollouts, and adjoint gradients against the forward mode.

Newton tolerance for these checks: 1e-13 m per step (NewtonOptions(tol=1e-13)); perturbations of ~3e-8 m of contraction (3e-5 N of tension):
central differences of them need states accurate to ~1e-12 m; larger ones meet the kinks of Q''
at the ends of its C2 blend. Required relative error <= 1e-4 for the paper's law (measured 5e-7 -
3e-5: central differences across the kinks of its blends), <= 1e-6 for the Coulomb law.
"""
from __future__ import annotations

import numpy as np
import pytest

from soft_envs.sim import NewtonOptions, Simulator, incline_gravity, load_robot
from .gradcheck import relative_error, rollout_jacobian_errors

from .conftest import small_robot

K = 40
TIGHT = NewtonOptions(tol=1e-13)


def gait(robot, control: str, K: int = K) -> np.ndarray:
    """Out-of-phase contractions that keep cables taut while legs swing and feet slide."""
    t = np.arange(K) * 0.033
    u = np.zeros((K, robot.n_motors))
    for m in range(robot.n_motors):
        wave = 0.5 * (1 - np.cos(2 * np.pi * t / 1.0 + 2.0 * m))
        u[:, m] = 0.5 * robot.u_bounds[m, 1] * wave if control == "length" else 0.5 + 3.5 * wave   # [N]
    return u


@pytest.mark.parametrize("name", ["tripod", "puppy"])
@pytest.mark.parametrize("control", ["length", "tension"])
@pytest.mark.parametrize("incline", [0.0, 12.0])
def test_rollout_jacobian_matches_finite_differences(name, control, incline):
    robot = load_robot(name)
    sim = Simulator(robot, control=control, gravity=incline_gravity(incline), newton=TIGHT)
    x0 = sim.rest_positions()
    u0 = gait(robot, control)
    rng = np.random.default_rng(42)
    nz = 6
    scale = 1e-3 if control == "length" else 1.0
    dudz = scale * rng.normal(size=(K, robot.n_motors, nz))
    # the regime the check covers: feet on the ground and sliding, cables taut
    traj = sim.rollout(u0, x0=x0)
    assert (traj.x[:, :, 1] < 0).any(axis=1).all()
    slide = np.abs(np.diff(traj.x[:, robot.mesh.boundary_nodes][:, :, [0, 2]], axis=0)).max()
    assert slide > 1e-5
    if control == "length":               # in tension mode every cable pulls with u > 0
        assert (traj.cable_deformation[1:] > 0).any()
    errs = rollout_jacobian_errors(sim, u0, dudz, x0=x0, n_dirs=2, h=3e-5, rng=rng,
                                   full_state=(name == "tripod"))
    assert max(errs.values()) <= 1e-4, errs


def test_jacobian_with_fixed_nodes():
    """A clamped bar (cable-driven finger): fixed dofs have zero sensitivity."""
    robot = small_robot(fixed_nodes=np.arange(6))
    sim = Simulator(robot, newton=TIGHT)
    x0 = sim.rest_positions()
    u0 = np.linspace(0, 0.004, K)[:, None]
    dudz = np.random.default_rng(1).normal(size=(K, 1, 3)) * 1e-3
    errs = rollout_jacobian_errors(sim, u0, dudz, x0=x0)
    assert max(errs.values()) <= 1e-4, errs
    traj = sim.rollout(u0, x0=x0, dudz=dudz, store_dxdz=True)
    fixed_dofs = (3 * robot.fixed_nodes[:, None] + np.arange(3)).ravel()
    assert np.abs(traj.dxdz[:, fixed_dofs]).max() == 0.0


@pytest.mark.parametrize("name,control", [("tripod", "length"), ("puppy", "tension")])
def test_adjoint_gradient_equals_forward_mode(name, control):
    robot = load_robot(name)
    sim = Simulator(robot, control=control, newton=NewtonOptions(tol=1e-12))
    x0 = sim.rest_positions()
    u0 = gait(robot, control, K=30)
    rng = np.random.default_rng(3)
    w = rng.normal(size=(31, robot.mesh.n_nodes, 3))           # O = sum_k w_k . x_k
    nz = 5
    dudz = rng.normal(size=(30, robot.n_motors, nz))
    traj = sim.rollout(u0, x0=x0, dudz=dudz, store_dxdz=True)
    forward = np.einsum("kd,kdz->z", w.reshape(31, -1)[1:], traj.dxdz[1:])
    adjoint = sim.rollout_gradient(u0, w, x0=x0, dudz=dudz, traj=traj)
    assert relative_error(adjoint, forward) <= 1e-8
    # per-step gradient dO/du as well (one parameter per step and motor)
    dOdu = sim.rollout_gradient(u0, w, x0=x0, traj=traj)
    assert dOdu.shape == u0.shape
    assert relative_error(np.einsum("km,kmz->z", dOdu, dudz), forward) <= 1e-8


def test_default_rollout_keeps_only_com_and_gamma_jacobians(puppy):
    robot, sim, x0 = puppy
    dudz = np.ones((10, robot.n_motors, 4)) * 1e-3
    traj = sim.rollout(np.full((10, robot.n_motors), 0.002), x0=x0, dudz=dudz)
    assert traj.dxdz is None
    assert traj.dcomdz.shape == (11, 3, 4) and traj.dgammadz.shape == (11, len(robot.tendons), 4)
    assert np.all(traj.dcomdz[0] == 0)


def coulomb(robot, **kw):
    import dataclasses
    return robot.replace(contact=dataclasses.replace(robot.contact, model="coulomb", **kw))


@pytest.mark.parametrize("name", ["tripod", "puppy"])
def test_rollout_jacobian_with_coulomb_friction(name):
    """The Coulomb law's stick anchors are state: their sensitivities travel through the
    recurrence (d grad/d anchors, d next anchors/dz). Feet both stick and slide in this gait."""
    robot = coulomb(load_robot(name))
    sim = Simulator(robot, newton=TIGHT)
    x0 = sim.rest_positions()
    u0 = gait(robot, "length")
    traj = sim.rollout(u0, x0=x0)
    c = sim.system.contact
    anchors, stick, slide = sim.initial_history(x0), 0, 0
    for k in range(K):
        nxt = sim.next_history(traj.x[k + 1], traj.x[k], anchors)
        moved = np.abs(nxt[2] - anchors[2]).max(axis=1) > 0
        touching = c.normal_forces(traj.x[k]) > 0
        stick += int((touching & ~moved).sum())
        slide += int((touching & moved).sum())
        anchors = nxt
    assert stick > 50 and slide > 50, (stick, slide)
    rng = np.random.default_rng(42)
    dudz = 1e-3 * rng.normal(size=(K, robot.n_motors, 6))
    errs = rollout_jacobian_errors(sim, u0, dudz, x0=x0, n_dirs=2, h=3e-5, rng=rng,
                                   full_state=(name == "tripod"))
    assert max(errs.values()) <= 1e-6, errs     # the Coulomb law: measured 2e-7 - 8e-7


def test_adjoint_gradient_with_coulomb_friction():
    robot = coulomb(load_robot("tripod"))
    sim = Simulator(robot, newton=NewtonOptions(tol=1e-12))
    x0 = sim.rest_positions()
    u0 = gait(robot, "length", K=30)
    rng = np.random.default_rng(5)
    w = rng.normal(size=(31, robot.mesh.n_nodes, 3))
    dudz = rng.normal(size=(30, robot.n_motors, 4))
    traj = sim.rollout(u0, x0=x0, dudz=dudz, store_dxdz=True)
    forward = np.einsum("kd,kdz->z", w.reshape(31, -1)[1:], traj.dxdz[1:])
    adjoint = sim.rollout_gradient(u0, w, x0=x0, dudz=dudz, traj=traj)
    assert relative_error(adjoint, forward) <= 1e-8
