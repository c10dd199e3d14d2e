"""The co-design problem (trajopt.codesign.problem): its Jacobian over keyframes and design
against central differences, its linearised constraints, and Gauss-Newton with constraints
linearised at every iterate (issue #29 item 3).

The design columns of the whole-rollout Jacobian are checked at the simulator's level in
tests/test_design_derivatives.py (<= 1e-6 relative, Newton and rest tolerances 1e-12 / 1e-13);
here the objective's assembly is: the residuals of a short Tripod walk (4 prep steps and two
8-step cycles, Coulomb law, Newton tolerance 1e-12 m; the environments' rest relaxation stops
at 1e-9 m, which bounds the agreement) against central differences along a random direction per
kind, measured <= 6e-7 relative; asserted <= 1e-5.
"""
from __future__ import annotations

import numpy as np
import pytest

from soft_envs.envs import make_gradient_env
from soft_envs.sim.design import DesignParameters, LegMorph, RegionalModuli, TendonRouting, legs_below, region_from_boxes
from soft_envs.sim.integrator import NewtonOptions
from trajopt.codesign import CodesignProblem, InfeasibleDesign
from trajopt.optim.gait import GaitSpec
from trajopt.optim.gauss_newton import GaussNewtonOptions, gauss_newton
from trajopt.optim.motor_limit import gait_constraints, max_step_of_env, project_start
from trajopt.optim.qp import LinearConstraints

GAIT = GaitSpec(n_prep=4, n_cycle=8, n_cycles=2, n_keyframes=4, interpolation="linear")


def _problem(motor_model: str) -> CodesignProblem:
    env = make_gradient_env("tripod", contact="coulomb")
    robot = env.robot
    design = DesignParameters(robot, [
        RegionalModuli(robot, [region_from_boxes(robot, "middle_leg", [[0.055, 0.0, 0.0, 0.085, 0.03, 0.04]])]),
        TendonRouting(robot),
        LegMorph(robot, legs_below(robot, 0.03), 0.03)])
    return CodesignProblem(env, design, GAIT, 20.0, max_step=max_step_of_env(env), newton=NewtonOptions(tol=1e-12),
                           motor_model=motor_model)


@pytest.fixture(scope="module")
def problem():
    """The motors' speed limit alone: the finite differences below step through gaits beyond the
    torque-speed line, whose trials the line would refuse (its rows: the test after them)."""
    return _problem("speed")


def _direction(problem, kind: str, rng) -> np.ndarray:
    d = np.zeros(problem.nz + problem.ntheta)
    cols = [i for i, n in enumerate(problem.block.names) if n.startswith(kind + ":")]
    if kind == "z":
        d[:problem.nz] = 1e-3 * rng.normal(size=problem.nz)
    elif kind == "stiffness":
        d[problem.nz + np.array(cols)] = 1e4
    elif kind == "routing":                   # inwards: along the clearance's gradient
        routing, sl = problem._routing()
        _, J = routing.clearance(problem.block.robot)
        step = J.T @ (1.0 + rng.random(len(J)))
        d[problem.nz + sl.start:problem.nz + sl.stop] = 1e-3 * step / np.abs(step).max()
    else:
        d[problem.nz + np.array(cols)] = 1e-3 * rng.normal(size=len(cols))
    return d


@pytest.mark.parametrize("kind", ["z", "stiffness", "routing", "legs"])
def test_jacobian_matches_central_differences(problem, kind, monkeypatch):
    monkeypatch.setattr(problem, "min_clearance", 0.0)    # the shipped via points sit at 2 mm: both sides
    rng = np.random.default_rng(3)
    z0 = np.clip(problem.param.initial_z(0.5), *problem.param.bounds())
    w0 = problem.start(z0)
    _, J, _ = problem(w0, True)
    d = _direction(problem, kind, rng)
    h = 1e-4                 # truncation error O(h^2): 1e-3 gives 1.2e-4 for the legs' morph (4 sub-steps)
    rp, _, _ = problem(w0 + h * d, False)
    rm, _, _ = problem(w0 - h * d, False)
    fd = (rp - rm) / (2 * h)
    err = np.linalg.norm(J @ d - fd) / np.linalg.norm(fd)
    assert err <= 1e-5, f"{kind}: relative error {err:.2e}"


def test_linearised_constraints_hold_at_the_start_and_refuse_outward_moves(problem):
    z0 = np.clip(problem.param.initial_z(0.5), *problem.param.bounds())
    z0, _ = project_start(z0, problem.param, gait_constraints(problem.param, problem.max_step))   # the motors' limit
    w0 = problem.start(z0)
    problem(w0, True)
    lin = problem.linearised_constraints(w0)
    assert lin.feasible(w0)
    out = -_direction(problem, "routing", np.random.default_rng(0))       # outwards
    assert not lin.feasible(w0 + out)
    with pytest.raises(InfeasibleDesign, match="inside the body"):
        problem(w0 + out, False)


def test_the_motors_line_constrains_the_keyframes_and_refuses_trials_beyond_it():
    """Under the torque-speed model the line's rows are among the linearised constraints, on z and,
    through ``dgammadtheta``, on the design (its columns against central differences: relative
    error <= 1e-5, bounded by the rest relaxation's 1e-9 m; measured 7e-9, 1.8e-8 and 2.6e-6 for
    the moduli, the via points and the legs, whose morph has the largest truncation error). The
    start, moved into the line, obeys them; a gait beyond the line is a refused trial (#38)."""
    from trajopt.optim.motor_torque import LINE_TOLERANCE, project_into_line
    from trajopt.optim.motor_limit import rest_keyframes
    problem = _problem("torque-speed")
    assert problem.line is not None and problem.motor_model == "torque-speed"
    param = problem.param
    z0 = np.clip(param.initial_z(0.5), *param.bounds())
    base = gait_constraints(param, problem.max_step)
    z0, _ = project_start(z0, param, base)
    assert problem.line.worst(z0, problem.env.rollout(problem.controls(z0)).cable_deformation).excess > LINE_TOLERANCE
    with pytest.raises(InfeasibleDesign, match="exceeds its torque-speed line"):
        problem(problem.start(z0), False)
    z1, report = project_into_line(z0, problem.line, lambda z, s: problem.env.rollout(
        problem.controls(z), dudz=problem.dudz if s else None), base, rest_keyframes(param))
    assert report is not None
    w1 = problem.start(z1)
    problem(w1, True)
    lin = problem.linearised_constraints(w1)
    assert lin.feasible(w1)
    rows = problem.line.linearised(z1, problem.last_traj.cable_deformation, problem.last_traj.dgammadz)
    assert lin.G.shape[0] >= len(rows.h) + len(problem.motor_rows.h)
    line_rows = lin.G[len(problem.motor_rows.h):len(problem.motor_rows.h) + len(rows.h)]
    np.testing.assert_allclose(line_rows[:, :problem.nz], rows.G, rtol=1e-12, atol=1e-12)
    # the design columns: d(condition)/d theta against central differences of the conditions'
    # values (the moved designs' own rollouts) along a direction per kind
    _, theta1 = problem.split(w1)
    excess = problem.line.excess
    rng = np.random.default_rng(5)
    for kind in ("stiffness", "routing", "legs"):
        d = _direction(problem, kind, rng)
        h = 1e-4
        values = []
        for sgn in (1.0, -1.0):
            env = problem.env_of(problem.robot_at(theta1 + sgn * h * d[problem.nz:]))
            gam = env.rollout(problem.controls(z1)).cable_deformation
            values.append(np.concatenate([e.ravel() for e in excess(z1, gam).values()]))
        fd = (values[0] - values[1]) / (2 * h)
        assert np.linalg.norm(fd) > 0, f"{kind}: the conditions do not move"
        err = np.linalg.norm(line_rows @ d - fd) / np.linalg.norm(fd)
        assert err <= 1e-5, f"{kind}: the line's design columns, relative error {err:.2e}"


def test_gauss_newton_keeps_constraints_linearised_at_every_iterate():
    """min |w - a|^2 on the unit disc |w| <= 1 (a nonlinear constraint, linearised at each
    accepted iterate, trials outside refused): the answer is a / |a|."""
    from soft_envs.envs import SimulationError
    a = np.array([2.0, 1.0])

    def fun(w, need_jac=True):
        if not need_jac and w @ w > 1.0 + 1e-12:
            raise SimulationError("outside the disc")
        return w - a, np.eye(2), {}

    def linearise(w):              # |w|^2 + 2 w . dw <= 1  ->  2 w . w' <= 1 + |w|^2
        return LinearConstraints(2.0 * w[None, :], np.array([1.0 + w @ w]))

    out = gauss_newton(fun, np.zeros(2), -5 * np.ones(2), 5 * np.ones(2),
                       GaussNewtonOptions(max_iter=60, ftol=0.0, xtol=0.0), constraints=linearise)
    assert np.linalg.norm(out.z) <= 1.0 + 1e-12
    np.testing.assert_allclose(out.z, a / np.linalg.norm(a), atol=1e-3)


def test_screening_candidates_stay_inside_the_bounds_and_the_clearance():
    """The screening's candidates around the shipped Tripod (its [design] table): two moduli per
    region, each leg longer and shorter, the via points along the projected steepest descent;
    every one within the bounds, the routing ones outside by no more than the rounding."""
    from soft_envs.envs.design import load_design
    from trajopt.codesign.screen import ScreenSettings, candidates
    env = make_gradient_env("tripod", contact="coulomb")
    design = load_design(env.robot)
    p = CodesignProblem(env, design, GAIT, 20.0, max_step=max_step_of_env(env))
    z0 = np.clip(p.param.initial_z(0.5), *p.param.bounds())
    z0, _ = project_start(z0, p.param, gait_constraints(p.param, p.max_step))
    cands = candidates(p, p.anchor.copy(), z0, ScreenSettings())
    labels = [c[0] for c in cands]
    assert sum("modulus" in lb for lb in labels) == 8 and sum(" mm" in lb and "leg" in lb for lb in labels) == 6
    lo, hi = design.bounds[:, 0], design.bounds[:, 1]
    for label, th in cands:
        assert np.all(th >= lo) and np.all(th <= hi), label
        if label.startswith("via points"):
            assert p.design_violation(p.robot_at(th)) is None, label
