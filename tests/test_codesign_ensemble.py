"""The co-design problem on an ensemble of physics (trajopt.codesign.ensemble, issue #43): the
Jacobian of the stacked residuals (the default physics, 4 steps per control step, and 2x finer
steps, 8) against central differences, and the ensemble's constraints.

A short Tripod walk (4 prep steps, two 8-step cycles, Coulomb law, Newton tolerance 1e-12 m) with
a modulus, the routing and the legs as the design, the motors' speed limit alone (the finite
differences step through gaits beyond the torque-speed line). Along random directions in all of
w = [z; theta] (the via points moved inwards, along the clearance's gradient, so that both sides
are inside the body), step h = 1e-4: relative error |J d - fd| / |fd| measured 1.9e-8 and 3.3e-8
(seeds 0 and 1); asserted <= 1e-6.
"""
from __future__ import annotations

import numpy as np
import pytest

from soft_envs.envs import make_gradient_env
from soft_envs.sim.design import DesignParameters, LegMorph, RegionalModuli, TendonRouting, legs_below, region_from_boxes
from soft_envs.sim.integrator import NewtonOptions
from trajopt.codesign import CodesignProblem
from trajopt.codesign.ensemble import CodesignEnsemble
from trajopt.optim.gait import GaitSpec
from trajopt.optim.motor_limit import max_step_of_env

GAIT = GaitSpec(n_prep=4, n_cycle=8, n_cycles=2, n_keyframes=4, interpolation="linear")


def _problem(motor_model: str = "speed") -> CodesignProblem:
    env = make_gradient_env("tripod", contact="coulomb")
    robot = env.robot
    design = DesignParameters(robot, [
        RegionalModuli(robot, [region_from_boxes(robot, "middle_leg", [[0.055, 0.0, 0.0, 0.085, 0.03, 0.04]])]),
        TendonRouting(robot, tendons=["front_a", "back_a"]),
        LegMorph(robot, legs_below(robot, 0.03), 0.03)])
    return CodesignProblem(env, design, GAIT, 20.0, max_step=max_step_of_env(env), newton=NewtonOptions(tol=1e-12),
                           min_clearance=0.0, motor_model=motor_model)   # the via points sit at 2 mm: both sides


@pytest.fixture(scope="module")
def ensemble():
    return CodesignEnsemble(_problem(), (8,))


def _direction(problem: CodesignProblem, rng) -> np.ndarray:
    d = np.zeros(problem.nz + problem.ntheta)
    d[:problem.nz] = 1e-3 * rng.normal(size=problem.nz)
    for i, name in enumerate(problem.block.names):
        if name.startswith("stiffness:"):
            d[problem.nz + i] = 1e4 * rng.normal()
        elif name.startswith("legs:"):
            d[problem.nz + i] = 1e-3 * rng.normal()
    routing, sl = problem._routing()
    _, J = routing.clearance(problem.block.robot)
    step = J.T @ (1.0 + rng.random(len(J)))                  # inwards
    d[problem.nz + sl.start:problem.nz + sl.stop] = 1e-3 * step / np.abs(step).max()
    return d


def test_members_and_stacking(ensemble):
    assert ensemble.substeps == [4, 8]
    base = ensemble.base
    z0 = np.clip(base.param.initial_z(0.5), *base.param.bounds())
    w0 = base.start(z0)
    r, J, info = ensemble(w0, True)
    r0, J0, _ = base(w0, True)
    r1, J1, _ = ensemble.members[1](w0, True)
    np.testing.assert_allclose(r, np.concatenate([r0, r1]) / np.sqrt(2), rtol=1e-15, atol=0)
    np.testing.assert_allclose(J, np.vstack([J0, J1]) / np.sqrt(2), rtol=1e-15, atol=0)
    assert not np.allclose(r0, r1)                   # the finer steps are another physics
    assert set(info["terms"]) == {"com", "magnitude", "smoothness", "design"}


@pytest.mark.parametrize("seed", [0, 1])
def test_stacked_jacobian_matches_central_differences(ensemble, seed):
    base = ensemble.base
    rng = np.random.default_rng(seed)
    z0 = np.clip(base.param.initial_z(0.5), *base.param.bounds())
    w0 = base.start(z0)
    _, J, _ = ensemble(w0, True)
    d = _direction(base, rng)
    h = 1e-4
    rp, _, _ = ensemble(w0 + h * d, False)
    rm, _, _ = ensemble(w0 - h * d, False)
    fd = (rp - rm) / (2 * h)
    err = np.linalg.norm(J @ d - fd) / np.linalg.norm(fd)
    assert err <= 1e-6, f"direction {seed}: relative error {err:.2e}"


def test_constraints_add_every_members_torque_speed_rows():
    ens = CodesignEnsemble(_problem("torque-speed"), (8,))
    base = ens.base
    z0 = np.clip(base.param.initial_z(0.3), *base.param.bounds())
    w0 = base.start(z0)
    ens(w0, True)
    alone = base.linearised_constraints(w0)
    both = ens.linearised_constraints(w0)
    line = ens.members[1].line_constraints(w0)
    assert both.G.shape == (alone.G.shape[0] + line.G.shape[0], alone.G.shape[1])
    np.testing.assert_array_equal(both.G[len(alone.h):], line.G)
    assert line.G[:, base.nz:].any()                 # the line's rows are on w: the design loads the motors
